"""The pipeline as data: the plan is the single source of the work, records
round-trip and are trusted only when they verify, and an interrupted run
resumes with only the missing runs."""
import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from rk4h.validation.trust import TIMING_COLUMNS as TRUST_TIMING

from rk4h.validation import budget, engine, execute, plan, records
from rk4h.validation.scenes import SCENE_DIR, load_scene_points, load_scenes

from _scenes import one_mass

REPO = Path(__file__).resolve().parent.parent
SHIPPED = [s for f in sorted(SCENE_DIR.glob("*.toml")) for s in load_scene_points(f)]
#: Columns that hold timings (the only ones two runs may disagree on).
TIMING_COLUMNS = {"wall_s", "compile_s", "wall_min", "wall_max", "seconds"} | TRUST_TIMING


@pytest.mark.parametrize("scene", SHIPPED, ids=lambda s: s.name)
def test_plan_budget_and_progress_agree(scene, monkeypatch):
    # The budget is a sum over the plan; the engine runs each spec of the plan
    # exactly once and ticks the progress once per spec.
    specs = plan.plan(scene)
    assert len({s.key for s in specs}) == len(specs)
    assert budget.estimate(scene).runs == len(specs)
    ran, ticks = [], []
    monkeypatch.setattr(execute, "execute",
                        lambda sc, spec, quick=False: ran.append(spec.key) or records.RunRecord(spec.key))
    stats = engine.PlanStats()
    out = engine.run_plan([(scene, s) for s in specs], progress=ticks.append, stats=stats)
    assert sorted(ran) == sorted(s.key for s in specs)
    assert len(ticks) == len(specs) == stats.planned == stats.executed == len(out)
    truths = {s.key for s in specs if s.purpose == "truth"}
    assert set(ran[:len(truths)]) == truths  # the references run first


def test_plan_keys_are_stable_and_sensitive():
    a = load_scenes(["thesis-2dof-case1"])[0]
    k1 = [s.key for s in plan.plan(a)]
    assert k1 == [s.key for s in plan.plan(a)]
    import dataclasses

    b = dataclasses.replace(a, t_end=a.t_end / 2)
    assert not set(k1) & {s.key for s in plan.plan(b)}
    c = dataclasses.replace(a, description="another text")
    assert k1 == [s.key for s in plan.plan(c)]  # the description is no part of the physics


def test_record_roundtrip_and_tampering(tmp_path):
    rec = records.RunRecord("a" * 24, values={"error_max": 1.5e-9, "nan": float("nan"), "n": 3},
                            timing={"wall_s": 0.1}, arrays={"t": np.linspace(0, 1, 5)},
                            result={"rows": [{"x": 1.0, "p": True}], "plots": [("k", {"y": np.ones(3)})]})
    store = records.RecordStore(tmp_path / "out", resume=False)
    store.put(rec)
    back = store.get(rec.key)
    assert back.values["error_max"] == 1.5e-9 and np.isnan(back.values["nan"]) and back.values["n"] == 3
    assert np.array_equal(back.arrays["t"], rec.arrays["t"])
    assert back.result["rows"] == [{"x": 1.0, "p": True}]
    assert isinstance(back.result["plots"][0], tuple) and np.array_equal(back.result["plots"][0][1]["y"], np.ones(3))
    # an edited arrays file is not trusted
    npz = store.path / f"{rec.key}.npz"
    data = bytearray(npz.read_bytes())
    data[len(data) // 2] ^= 0xFF
    npz.write_bytes(bytes(data))
    assert store.get(rec.key) is None


def test_store_refuses_a_directory_it_did_not_write(tmp_path):
    (tmp_path / ".out.records").mkdir()
    (tmp_path / ".out.records" / "precious.txt").write_text("mine")
    with pytest.raises(ValueError, match="not written by this tool"):
        records.RecordStore(tmp_path / "out", resume=True)
    assert (tmp_path / ".out.records" / "precious.txt").read_text() == "mine"


def test_store_remove_keeps_foreign_files(tmp_path):
    store = records.RecordStore(tmp_path / "out", resume=False)
    store.put(records.RunRecord("b" * 24))
    (store.path / "notes.txt").write_text("a user's file")
    store.remove()
    assert (store.path / "notes.txt").read_text() == "a user's file"


# -- the command line: --resume after a kill ---------------------------------------------------
def _scenes(tmp_path):
    paths = []
    for i in range(3):
        p = tmp_path / f"s{i}.toml"
        p.write_text(one_mass(f"resume-{i}", t_end=40.0 + 10 * i, h="[0.1, 0.05, 0.02, 0.01]",
                              tolerances="[1e-6, 1e-8, 1e-10]", solvers='["rk4", "dop853", "euler"]',
                              outputs='["state", "energy", "work_precision", "convergence", "modes"]'))
        paths.append(str(p))
    return paths


def _cli(args, **kw):
    env = {**os.environ, "MPLBACKEND": "Agg"}
    return subprocess.Popen([sys.executable, "validation/run_all.py", *args], cwd=REPO, env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, **kw)


def _counts(stdout):
    m = re.search(r"(\d+) runs planned, (\d+) resumed, (\d+) executed", stdout)
    assert m, stdout
    return tuple(int(x) for x in m.groups())


def _deterministic(out):
    tables = {}
    for p in sorted(Path(out).glob("*.csv")):
        df = pd.read_csv(p)
        tables[p.stem] = df.drop(columns=[c for c in df.columns if c in TIMING_COLUMNS])
    return tables


@pytest.mark.slow
def test_resume_after_kill_runs_only_the_missing_specs(tmp_path):
    scenes = _scenes(tmp_path)
    args = sum((["--scene", s] for s in scenes), []) + ["--workers", "1", "--no-figures", "--repeats", "1"]
    out = tmp_path / "out"
    store = tmp_path / ".out.records"
    proc = _cli(args + ["--out", str(out)])
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline and proc.poll() is None:
        if store.is_dir() and len(list(store.glob("*.json"))) >= 12:
            break
        time.sleep(0.05)
    assert proc.poll() is None, "the run ended before it could be killed: make the scenes longer"
    proc.send_signal(signal.SIGKILL)
    proc.wait(timeout=30)
    kept = {p.stem for p in store.glob("*.json")}
    assert len(kept) >= 12 and not out.exists()
    proc = _cli(args + ["--out", str(out), "--resume"])
    stdout, stderr = proc.communicate(timeout=300)
    assert proc.returncode == 0, stderr
    planned, resumed, executed = _counts(stdout)
    assert resumed == len(kept) and executed == planned - resumed
    assert not store.exists()  # removed with the report in place
    fresh = tmp_path / "fresh"
    proc = _cli(args + ["--out", str(fresh)])
    stdout, stderr = proc.communicate(timeout=300)
    assert proc.returncode == 0, stderr
    assert _counts(stdout) == (planned, 0, planned)
    a, b = _deterministic(out), _deterministic(fresh)
    assert a.keys() == b.keys() and "accuracy" in a
    for name in a:
        pd.testing.assert_frame_equal(a[name], b[name], check_exact=True, obj=name)


@pytest.mark.parametrize("value", ["0", "two"])
def test_a_bad_workers_environment_variable_is_exit_2_naming_it(tmp_path, value):
    p = tmp_path / "s.toml"
    p.write_text(one_mass("env-workers"))
    env = {**os.environ, "MPLBACKEND": "Agg", "RK4H_WORKERS": value}
    r = subprocess.run([sys.executable, "validation/run_all.py", "--scene", str(p), "--out", str(tmp_path / "o")],
                       cwd=REPO, env=env, capture_output=True, text=True, timeout=120)
    assert r.returncode == 2 and r.stderr.startswith("run_all: RK4H_WORKERS: must be an integer")
    assert r.stderr.count("\n") == 1 and not (tmp_path / "o").exists()
