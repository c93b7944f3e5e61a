"""The local worker processes (``rk4h.validation.engine.LocalPools``) as the CLI
uses them: started and warmed before planning, handed to ``run_all.run``
(which then leaves them open for their owner), drawing figures however
``run_all`` was started, and ending without the interpreter's teardown."""
from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

from rk4h.validation import engine, run_all
from rk4h.validation.scenes import load_scene

from _scenes import one_mass

REPO = Path(__file__).resolve().parent.parent
OUTPUTS = '["state", "energy", "figures"]'


def _scenes(tmp_path):
    paths = []
    for name in ("pool-a", "pool-b"):
        paths.append(tmp_path / f"{name}.toml")
        paths[-1].write_text(one_mass(name, outputs=OUTPUTS))
    return paths


def _pids(pools):
    return {p.pid for pool in (pools.lane, pools.general) for p in pool._processes.values()}


@pytest.mark.slow
def test_warm_starts_every_worker_and_run_uses_the_callers_pools_and_leaves_them_open(tmp_path, monkeypatch):
    pools = engine.LocalPools(2).warm()
    try:
        started = _pids(pools)
        assert len(started) == 2  # the lane and one general worker, before any spec was submitted

        def no_new_pools(*args, **kwargs):
            raise AssertionError("run() started pools of its own")

        monkeypatch.setattr(engine, "LocalPools", no_new_pools)
        out = tmp_path / "out"
        out.mkdir()
        results, failures = run_all.run([load_scene(p) for p in _scenes(tmp_path)], out, repeats=1, workers=2,
                                        pools=pools)
        assert failures == []
        assert {r.scene for r in results} == {"pool-a", "pool-b"}
        assert sorted(p.name for p in out.glob("*.png")) == sorted(
            f"pool_{s}_{f}.png" for s in "ab" for f in ("displacement", "velocity", "energy_error"))
        # run() used these processes and did not close them: their owner does
        assert pools.general is not None and pools.lane is not None
        assert _pids(pools) == started
    finally:
        pools.close()
    assert pools.general is None and pools.lane is None


@pytest.mark.slow
def test_figures_are_drawn_in_workers_when_run_all_is_not_the_main_module(tmp_path):
    """Under ``python -m cProfile`` the main module is cProfile's: a figure
    job submitted as a function of ``run_all`` run as a script could not be
    pickled (every figure failed); ``rk4h.validation.draw.draw_job`` pickles by
    module name."""
    args = [a for p in _scenes(tmp_path) for a in ("--scene", str(p))]
    out = tmp_path / "out"
    p = subprocess.run([sys.executable, "-m", "cProfile", "-o", os.devnull, "validation/run_all.py", *args,
                        "--out", str(out), "--workers", "2", "--repeats", "1"],
                       cwd=REPO, capture_output=True, text=True, timeout=300,
                       env={**os.environ, "MPLBACKEND": "Agg"})
    assert p.returncode == 0, p.stdout + p.stderr
    assert "all expectations held" in p.stdout, p.stdout
    assert len(list(out.glob("*.png"))) == 6


def test_draw_job_draws_nothing_into_a_directory_that_is_gone(tmp_path):
    from rk4h.validation.draw import draw_job
    from rk4h.validation.measure import FigureJob

    gone = tmp_path / "gone"
    with pytest.raises(FileNotFoundError, match="gone"):
        draw_job(FigureJob("x", "state", {}), gone, None)
    assert not gone.exists()


@pytest.mark.parametrize("stream", ["stdout", "stderr"])
def test_exit_now_flushes_what_the_worker_wrote(stream):
    """``_exit_now`` ends the process with ``os._exit``, which skips the
    flush of buffered output: it must flush first (a pipe is block-buffered
    unless PYTHONUNBUFFERED is set, so the child runs without it)."""
    env = {k: v for k, v in os.environ.items() if k != "PYTHONUNBUFFERED"}
    code = (f"import sys; from rk4h.validation import engine; sys.{stream}.write('unterminated'); "
            "engine._exit_now(); print('not reached')")
    p = subprocess.run([sys.executable, "-c", code], cwd=REPO, capture_output=True, text=True, timeout=60, env=env)
    assert p.returncode == 0
    assert getattr(p, stream) == "unterminated"


def _job(i, seconds, die, marker):
    """A job for the worker processes: sleeps ``seconds``; item ``die``
    kills its own process with SIGKILL (only the first time when ``marker``,
    a file path, is given: it is created then)."""
    import signal as _signal
    import time as _time

    if i == die and not (marker and os.path.exists(marker)):
        if marker:
            open(marker, "w").close()
        os.kill(os.getpid(), _signal.SIGKILL)
    _time.sleep(seconds)
    return i, os.getpid()


@pytest.mark.process
@pytest.mark.parametrize("once", [False, True], ids=["dies-twice", "dies-once"])
def test_a_worker_that_dies_is_replaced_and_its_job_retried_once(tmp_path, capsys, once):
    """Item 2 kills its worker while the other general worker holds item 1
    (0.5 s): the broken pool is replaced, item 1 runs again without charge;
    item 2 runs once more, then (if it dies again) is a ``WorkerDied``
    naming the signal. Every other item has its result."""
    marker = str(tmp_path / "died") if once else None
    items = [(i, 0.5 if i == 1 else 0.05, 2, marker) for i in range(6)]
    pools = engine.LocalPools(3)
    try:
        out = pools.map(_job, items)
    finally:
        pools.close()
    err = capsys.readouterr().err
    if once:
        assert [o[0] for o in out] == list(range(6))
        assert err.count("died (SIGKILL)") == 1
    else:
        assert isinstance(out[2], engine.WorkerDied) and str(out[2]) == "worker died (SIGKILL) twice"
        assert [o[0] for i, o in enumerate(out) if i != 2] == [0, 1, 3, 4, 5]
        assert err.count("died (SIGKILL)") == 2
    assert "Traceback" not in err


def _kill_self():
    os.kill(os.getpid(), __import__("signal").SIGSEGV)


@pytest.mark.process
def test_a_worker_that_dies_idle_charges_no_job(capsys):
    """A worker that dies before it takes a job (as one whose start-up
    imports an extension that segfaults would) leaves a broken pool behind:
    the next submission replaces it and every job gets its result."""
    pools = engine.LocalPools(2).start()
    try:
        with pytest.raises(Exception):
            pools.general.submit(_kill_self).result(timeout=120)  # untracked, like the warm-up job
        out = pools.map(_job, [(i, 0.01, -1, None) for i in range(4)])
    finally:
        pools.close()
    assert [o[0] for o in out] == list(range(4))
    err = capsys.readouterr().err
    assert "died (SIGSEGV)" in err and "0 of the 0 job(s)" in err, err


@pytest.mark.slow
def test_a_heyoka_that_segfaults_on_import_makes_failed_rows_not_a_traceback(tmp_path):
    """Every worker that imports heyoka (its warm-up, a heyoka run) dies
    with SIGSEGV: the heyoka runs become failed rows naming the signal, the
    other runs are recorded, the report is written (exit 1)."""
    fake = tmp_path / "fake" / "heyoka"
    fake.mkdir(parents=True)
    (fake / "__init__.py").write_text("import os, signal\nos.kill(os.getpid(), signal.SIGSEGV)\n")
    scene = tmp_path / "s.toml"
    scene.write_text(one_mass("segv", solvers='["rk4", "dop853", "heyoka"]'))
    out = tmp_path / "out"
    env = {**os.environ, "MPLBACKEND": "Agg",
           "PYTHONPATH": os.pathsep.join([str(fake.parent), str(REPO), os.environ.get("PYTHONPATH", "")])}
    p = subprocess.run([sys.executable, "validation/run_all.py", "--scene", str(scene), "--out", str(out),
                        "--workers", "2", "--repeats", "1", "--no-figures"], cwd=REPO, capture_output=True,
                       text=True, timeout=300, env=env)
    assert p.returncode == 1, p.stderr
    assert "Traceback" not in p.stderr, p.stderr
    failed = sorted(line for line in p.stdout.splitlines() if line.startswith("FAILED"))
    # each heyoka run is a failed row naming the worker's death; a run whose
    # worker the executor ended beside the crashed one may say SIGTERM second
    assert [f[:f.index(" raised")] for f in failed] == [f"FAILED: segv: heyoka at {tol}" for tol in ("1e-06", "1e-09")]
    assert all(re.search(r"raised WorkerDied: worker died (\(SIGSEGV\) twice|twice \(SIGSEGV, then SIGTERM\))$", f)
               for f in failed), p.stdout
    import pandas as pd

    acc = pd.read_csv(out / "accuracy.csv")
    assert set(acc["solver"]) == {"rk4", "dop853", "heyoka"}, acc
