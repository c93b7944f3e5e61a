"""Workers that pay (``rk4h.validation.workers``) and the runner's report value
(``rk4h.validation.runner.execute``): the number of worker processes comes from
the plan's estimated work, a small scene starts no pool, and the runner
returns what happened instead of keeping it on function attributes."""
from __future__ import annotations

from types import SimpleNamespace

import pytest

from rk4h.validation import engine, plan, runner, workers
from rk4h.validation.scenes import load_scenes

from _scenes import one_mass


def _jobs(seconds_each, scene="s"):
    """Fake plan entries: one (scene, spec) per estimate, the estimate carried on the spec."""
    sc = SimpleNamespace(name=scene)
    return [(sc, SimpleNamespace(key=f"k{i}", sec=s)) for i, s in enumerate(seconds_each)]


def _by_spec(scene, spec):
    return spec.sec


def test_little_work_starts_no_pool_and_much_work_uses_every_core():
    start, share = workers.WORKER_START_SECONDS, workers.MAX_EXTRA_CPU
    enough = 2 * start / share  # the least total two workers repay
    small = _jobs([enough / 100 * 0.9] * 100)
    big = _jobs([enough / 100 * 1.1] * 100)
    assert workers.choose_workers(small, figures=False, cores=2, seconds=_by_spec)[0] == 1
    assert workers.choose_workers(big, figures=False, cores=2, seconds=_by_spec)[0] == 2
    # three workers need 1.5 times as much work as two
    assert workers.choose_workers(big, figures=False, cores=4, seconds=_by_spec)[0] == 2
    huge = _jobs([3 * start / share / 100 * 1.1] * 100)
    assert workers.choose_workers(huge, figures=False, cores=4, seconds=_by_spec)[0] == 3
    assert workers.choose_workers(huge, figures=False, cores=1, seconds=_by_spec)[0] == 1


def test_work_that_cannot_be_shared_and_resumed_work_do_not_count():
    start, share = workers.WORKER_START_SECONDS, workers.MAX_EXTRA_CPU
    total = 10 * start / share
    one_long = _jobs([0.6 * total] + [0.4 * total / 50] * 50)  # one spec is more than half the work
    assert workers.choose_workers(one_long, figures=False, cores=2, seconds=_by_spec)[0] == 1
    even = _jobs([total / 100] * 100)
    assert workers.choose_workers(even, figures=False, cores=2, seconds=_by_spec)[0] == 2
    done = {f"k{i}" for i in range(95)}  # resumed from records: 5% of the work is left
    n, why = workers.choose_workers(even, figures=False, cores=2, seconds=_by_spec, done=done)
    assert n == 1 and "too little to repay a pool" in why


def test_a_small_shipped_scene_is_estimated_below_a_pool_and_the_full_plan_above():
    small = load_scenes(["three-blocks"], quick=True)  # a 3-mass chain, default-like outputs
    jobs = plan.plan_all(small, quick=True, figures=True, repeats=1)
    total, _ = workers.plan_seconds(jobs, quick=True)
    assert 0 < total < 2 * workers.WORKER_START_SECONDS / workers.MAX_EXTRA_CPU
    assert workers.choose_workers(jobs, quick=True, cores=2)[0] == 1
    full = load_scenes(None)
    jobs = plan.plan_all(full, quick=False, figures=True, repeats=3)
    assert workers.choose_workers(jobs, quick=False, cores=2)[0] == 2


def test_execute_chooses_one_worker_for_a_small_scene_and_returns_a_report_value(tmp_path, monkeypatch):
    monkeypatch.delenv("RK4H_WORKERS", raising=False)
    monkeypatch.setattr(engine, "default_workers", lambda: 2)

    def no_pool(*args, **kwargs):
        raise AssertionError("a pool was started for a small scene")

    monkeypatch.setattr(engine, "LocalPools", no_pool)
    scene = tmp_path / "small.toml"
    scene.write_text(one_mass("small"))
    notes, bars = [], []

    def progress(total):
        bars.append(total)
        return lambda message: None

    report = runner.execute(runner.RunOptions(scenes=[str(scene)], out=str(tmp_path / "out"), repeats=1,
                                              figures=False), progress=progress,
                            notify=lambda line, err=False: notes.append(line))
    assert report.status == 0 and report.message is None, report
    assert report.out == tmp_path / "out" and (report.out / "index.md").is_file()
    assert report.workers == 1 and "too little to repay a pool" in report.workers_why
    assert report.scenes == ["small"] and report.completed == ["small"]
    assert report.planned == report.executed == bars[0] > 0 and report.resumed == 0
    assert report.failures == [] and set(report.phases) >= {"runs", "measure", "write"}
    assert not hasattr(runner.run, "completed")  # no state on function attributes


def test_execute_honours_explicit_workers_and_reports_bad_input_as_a_status(tmp_path, monkeypatch):
    monkeypatch.delenv("RK4H_WORKERS", raising=False)
    started = []

    class Pools:
        def __init__(self, n):
            started.append(n)
            self.workers = n

        def warm(self):
            return self

        def close(self, kill=False):
            pass

    monkeypatch.setattr(engine, "LocalPools", Pools)
    monkeypatch.setattr(engine, "run_plan", lambda *a, **k: (_ for _ in ()).throw(KeyboardInterrupt()))
    scene = tmp_path / "small.toml"
    scene.write_text(one_mass("small"))
    report = runner.execute(runner.RunOptions(scenes=[str(scene)], out=str(tmp_path / "out"), repeats=1,
                                              figures=False, workers=2))
    assert started == [2]  # --workers 2 is honoured, however small the plan
    assert report.status == 130 and report.message.startswith("run_all: interrupted (SIGINT)")
    assert report.out is None and not (tmp_path / "out").exists()
    bad = runner.execute(runner.RunOptions(scenes=[str(tmp_path / "missing.toml")], out=str(tmp_path / "o")))
    assert bad.status == 2 and "missing.toml" in bad.message and bad.out is None


@pytest.mark.parametrize("value", ["0", "x"])
def test_rk4h_workers_is_checked_by_the_runner(tmp_path, monkeypatch, value):
    monkeypatch.setenv("RK4H_WORKERS", value)
    scene = tmp_path / "small.toml"
    scene.write_text(one_mass("small"))
    report = runner.execute(runner.RunOptions(scenes=[str(scene)], out=str(tmp_path / "o")))
    assert report.status == 2
    assert report.message == f"run_all: RK4H_WORKERS: must be an integer from 1 to 1024, got {value!r}"
