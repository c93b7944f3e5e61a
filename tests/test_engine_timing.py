"""Where the engine places timed runs (``rk4h.validation.engine._pool``).

The pools are thread pools standing in for the worker processes and the
execution is a stub that records which pool ran a spec and when, so the tests
check the schedule itself: timed specs start only after every untimed spec
has finished; by default they run on every worker at once; with
``exclusive_timing`` one at a time in the timing lane.
"""
from __future__ import annotations

import threading
import time
from concurrent.futures import ThreadPoolExecutor
from types import SimpleNamespace

import pytest

from rk4h.validation import engine


class _ThreadPools:
    """``LocalPools``' interface on two thread pools (lane, general)."""

    def __init__(self):
        self.workers = 2
        self.lane = ThreadPoolExecutor(1, thread_name_prefix="lane")
        self.general = ThreadPoolExecutor(1, thread_name_prefix="general")

    def start(self):
        return self

    def close(self, kill=False):
        self.lane.shutdown(wait=True)
        self.general.shutdown(wait=True)


def _spec(i, purpose, timed):
    return SimpleNamespace(key=f"k{i}", purpose=purpose, timed=timed, label=lambda i=i: f"spec {i}")


@pytest.fixture
def schedule(monkeypatch):
    """Run a plan of 2 truth, 6 untimed and 6 timed stub specs; returns
    ``[(spec, pool, start, end), ...]``."""
    log, lock = [], threading.Lock()

    def fake_execute(scene, spec, quick):
        start = time.perf_counter()
        time.sleep(0.05)
        with lock:
            log.append((spec, threading.current_thread().name.split("_")[0], start, time.perf_counter()))
        return SimpleNamespace(key=spec.key)

    monkeypatch.setattr(engine, "_execute", fake_execute)

    def run(exclusive):
        specs = ([_spec(i, "truth", False) for i in range(2)] + [_spec(i, "order", False) for i in range(2, 8)]
                 + [_spec(i, "run", True) for i in range(8, 14)])
        jobs = [(None, s) for s in specs[::-1]]  # timed ones listed first: the engine must still hold them back
        stats = engine.PlanStats()
        pools = _ThreadPools()
        try:
            recs = engine.run_plan(jobs, workers=2, pools=pools, stats=stats, exclusive_timing=exclusive)
        finally:
            pools.close()
        assert set(recs) == {s.key for s in specs} and stats.executed == len(specs)
        return log, stats

    return run


def _overlap(a, b):
    return a[2] < b[3] and b[2] < a[3]


@pytest.mark.parametrize("exclusive", [False, True], ids=["shared", "exclusive"])
def test_timed_runs_start_after_every_untimed_run_has_finished(schedule, exclusive):
    log, _ = schedule(exclusive)
    last_untimed = max(end for spec, _, _, end in log if not spec.timed)
    assert min(start for spec, _, start, _ in log if spec.timed) >= last_untimed


def test_by_default_timed_runs_use_every_worker_at_once(schedule):
    log, stats = schedule(False)
    timed = [e for e in log if e[0].timed]
    assert {pool for _, pool, _, _ in timed} == {"lane", "general"}
    assert any(_overlap(a, b) for i, a in enumerate(timed) for b in timed[i + 1:])
    assert "2 at a time" in stats.timing


def test_exclusive_timing_runs_timed_runs_alone_in_the_lane(schedule):
    log, stats = schedule(True)
    timed = [e for e in log if e[0].timed]
    assert {pool for _, pool, _, _ in timed} == {"lane"}
    assert not any(_overlap(a, b) for a in timed for b in log if b is not a)
    assert "idle" in stats.timing
    # the untimed work still used both workers
    assert {pool for spec, pool, _, _ in log if not spec.timed} == {"lane", "general"}


def test_exclusive_timing_with_a_scheduler_is_refused(tmp_path, capsys):
    from rk4h.validation import run_all

    rc = run_all.main(["--quick", "--out", str(tmp_path / "r"), "--exclusive-timing",
                       "--scheduler", "tcp://127.0.0.1:1"])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1 and "--exclusive-timing" in err[0]
    assert not (tmp_path / "r").exists()


def test_pool_map_keeps_the_order_returns_exceptions_and_balances_by_cost():
    """``LocalPools.map``: results in item order, an exception in place of its
    result, and a process that finishes takes the next item (the costly item
    first): the lane holds the one long item while the other worker does all
    the short ones (round-robin would give the lane every other item)."""
    class Pools(engine.LocalPools):
        def __init__(self):
            super().__init__(2)
            self.lane = ThreadPoolExecutor(1, thread_name_prefix="lane")
            self.general = ThreadPoolExecutor(1, thread_name_prefix="general")

    def work(i, seconds):
        time.sleep(seconds)
        if i == 3:
            raise ValueError("item 3")
        return i, threading.current_thread().name.split("_")[0]

    items = [(0, 0.01), (1, 0.01), (2, 0.6), (3, 0.01), (4, 0.01), (5, 0.01)]
    pools = Pools()
    try:
        out = pools.map(work, items, cost=[s for _, s in items])
    finally:
        pools.close()
    assert isinstance(out[3], ValueError)
    assert [o[0] for i, o in enumerate(out) if i != 3] == [0, 1, 2, 4, 5]
    assert out[2][1] == "lane"
    assert {o[1] for i, o in enumerate(out) if i not in (2, 3)} == {"general"}
