"""A record counts only if it is the one this code made, and records never
vanish silently: the spec key covers user code and libraries, one digest
covers a record's JSON and arrays, only regular files are read, and a run
over an earlier run's records resumes, moves them aside or refuses."""
import os
import re
import secrets
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from rk4h.validation import engine, plan, provenance, records, run_all
from rk4h.validation.scenes import load_scenes

from _scenes import one_mass
from test_pipeline import _deterministic as _tables

REPO = Path(__file__).resolve().parent.parent

RK4 = '''
def step(fun, t, y, h):
    k1 = fun(t, y)
    k2 = fun(t + h / 2, y + h / 2 * k1)
    k3 = fun(t + h / 2, y + h / 2 * k2)
    k4 = fun(t + h, y + h * k3)
    return y + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
'''
#: The same module after an edit: Heun's second-order method under the same name.
HEUN = '''
def step(fun, t, y, h):
    k1 = fun(t, y)
    k2 = fun(t + h, y + h * k1)
    return y + h / 2 * (k1 + k2)
'''
ARGS = ["--workers", "1", "--no-figures", "--repeats", "1"]


def _allow_code():
    # a scene naming a user's python stepper runs only with the flag
    return ["--allow-code"]


def _env(tmp_path):
    path = os.pathsep.join([str(tmp_path), os.environ.get("PYTHONPATH", "")])
    return {**os.environ, "MPLBACKEND": "Agg", "PYTHONPATH": path, "RK4H_ALLOW_CODE": "1"}


def _cli(tmp_path, args, timeout=300):
    return subprocess.run([sys.executable, "validation/run_all.py", *args], cwd=REPO, env=_env(tmp_path),
                          capture_output=True, text=True, timeout=timeout)


def _scenes(tmp_path):
    """A scene using a user's stepper module (``tmp_path / <name>.py``, a name
    of its own: this process imports it) and a plain one."""
    module = f"usersteps_{secrets.token_hex(4)}"
    (tmp_path / "usersteps").write_text(module)
    (tmp_path / f"{module}.py").write_text(RK4)
    user = tmp_path / "user.toml"
    user.write_text(one_mass("trust-user", t_end=4.0, h="[0.1, 0.05]", solvers='["mine", "dop853"]',
                             outputs='["state", "convergence"]',
                             extra=f'[methods.mine]\npython = "{module}:step"\norder = 4\n'))
    plain = tmp_path / "plain.toml"
    plain.write_text(one_mass("trust-plain", t_end=4.0, h="[0.1, 0.05]", outputs='["state", "convergence"]'))
    return [str(user), str(plain)]


def _stepper(tmp_path) -> Path:
    return tmp_path / f"{(tmp_path / 'usersteps').read_text()}.py"


def _store_of_earlier_run(tmp_path, paths, monkeypatch, out):
    """Execute the plan of ``paths`` in this process into the store of ``out``,
    as a run that stopped before its report would leave it; returns
    ``{scene name: [spec, ...]}``."""
    monkeypatch.syspath_prepend(str(tmp_path))
    scenes = load_scenes(paths, allow_code=True)
    jobs = plan.plan_all(scenes, quick=False, figures=False, repeats=1)
    store = records.RecordStore(out, resume=False)
    engine.run_plan(jobs, store=store)
    assert store.keys() == {s.key for _, s in jobs}
    by_scene = {}
    for sc, s in jobs:
        by_scene.setdefault(sc.name, []).append(s)
    return by_scene


def _summary(stdout):
    m = re.search(r"(\d+) runs planned, (\d+) resumed, (\d+) executed", stdout)
    r = re.search(r"records: (\d+) resumed, (\d+) rerun \((\d+) digest mismatch, (\d+) stale", stdout)
    assert m and r, stdout
    return tuple(int(x) for x in m.groups()), tuple(int(x) for x in r.groups())


# -- the spec key: user code and libraries ------------------------------------------------------
def test_editing_a_user_stepper_changes_its_scenes_keys_only(tmp_path, monkeypatch):
    monkeypatch.syspath_prepend(str(tmp_path))
    paths = _scenes(tmp_path)
    user, plain = load_scenes(paths, allow_code=True)
    before = ([s.key for s in plan.plan(user)], [s.key for s in plan.plan(plain)])
    _stepper(tmp_path).write_text(HEUN)
    after = ([s.key for s in plan.plan(user)], [s.key for s in plan.plan(plain)])
    assert not set(before[0]) & set(after[0])
    assert before[1] == after[1]


def test_the_key_covers_library_versions_and_the_blas_kernel(monkeypatch):
    scene = load_scenes(["thesis-2dof-case1"])[0]
    keys = [s.key for s in plan.plan(scene)]
    assert dict(provenance.library_versions()).keys() == {"numpy", "scipy", "heyoka", "scikit-sundae", "numba"}
    import rk4h.validation.report

    monkeypatch.setattr(provenance, "library_versions", lambda: (("numpy", "0.0-other"),))
    provenance.environment_digest.cache_clear()
    try:
        assert not set(keys) & {s.key for s in plan.plan(scene)}
        monkeypatch.undo()
        monkeypatch.setattr(rk4h.validation.report, "blas_kernel", lambda: "SomeOtherKernel")
        provenance.environment_digest.cache_clear()
        assert not set(keys) & {s.key for s in plan.plan(scene)}
    finally:
        monkeypatch.undo()
        provenance.environment_digest.cache_clear()
    assert keys == [s.key for s in plan.plan(scene)]


def test_the_key_covers_the_files_a_command_names(tmp_path):
    prog = tmp_path / "prog.sh"
    prog.write_text("#!/bin/sh\nexit 0\n")
    script = tmp_path / "solver.m"
    script.write_text("% v1\n")
    scene = load_scenes(["thesis-2dof-case1"])[0]
    import dataclasses

    scene = dataclasses.replace(scene, methods={"ext": {"command": [str(prog), str(script), "{problem}",
                                                                    "{trajectory}"], "order": 4}})
    d1 = provenance.user_code_digest(scene)
    script.write_text("% v2\n")
    d2 = provenance.user_code_digest(scene)
    prog.write_text("#!/bin/sh\nexit 1\n")
    d3 = provenance.user_code_digest(scene)
    assert len({d1, d2, d3}) == 3


# -- the store: one digest, regular files only --------------------------------------------------
def _one_record(tmp_path):
    rec = records.RunRecord("c" * 24, values={"error_max": 1.2345e-9}, arrays={"t": np.linspace(0, 1, 5)})
    store = records.RecordStore(tmp_path / "out", resume=False)
    store.put(rec)
    assert store.get(rec.key).values["error_max"] == 1.2345e-9
    return store, rec


def test_a_record_json_edited_by_one_digit_does_not_verify(tmp_path):
    store, rec = _one_record(tmp_path)
    path = store.path / f"{rec.key}.json"
    text = path.read_text()
    assert "1.2345e-09" in text
    path.write_text(text.replace("1.2345e-09", "1.2346e-09"))
    assert store.get(rec.key) is None


def test_a_fifo_as_a_record_is_not_read(tmp_path):
    store, rec = _one_record(tmp_path)
    path = store.path / f"{rec.key}.json"
    path.unlink()
    os.mkfifo(path)
    # in a child: a blocking open of the FIFO would hang, not fail
    code = (f"from rk4h.validation import records; s = records.RecordStore({str(tmp_path / 'out')!r}, resume=True); "
            f"print(s.get({rec.key!r}), sorted(s.keys()))")
    r = subprocess.run([sys.executable, "-c", code], cwd=REPO, capture_output=True, text=True, timeout=60)
    assert r.returncode == 0 and r.stdout.strip() == "None []", r.stderr


def test_an_arrays_file_linked_to_dev_zero_is_not_read(tmp_path):
    store, rec = _one_record(tmp_path)
    path = store.path / f"{rec.key}.npz"
    path.unlink()
    path.symlink_to("/dev/zero")
    # in a child under a 3 GiB address-space limit: reading /dev/zero would end in MemoryError
    code = ("import resource; resource.setrlimit(resource.RLIMIT_AS, (2**30 * 3, 2**30 * 3)); "
            f"from rk4h.validation import records; s = records.RecordStore({str(tmp_path / 'out')!r}, resume=True); "
            f"print(s.get({rec.key!r}))")
    r = subprocess.run([sys.executable, "-c", code], cwd=REPO, capture_output=True, text=True, timeout=60)
    assert r.returncode == 0 and r.stdout.strip() == "None", r.stderr
    with pytest.raises(ValueError, match="not a regular file|Too many levels"):
        records.read_regular("/dev/zero", 2**20)


# -- the command line ---------------------------------------------------------------------------
@pytest.mark.slow
def test_resume_reruns_what_changed_and_equals_a_fresh_run(tmp_path, monkeypatch):
    paths = _scenes(tmp_path)
    out = tmp_path / "out"
    by_scene = _store_of_earlier_run(tmp_path, paths, monkeypatch, out)
    user, plain = by_scene["trust-user"], by_scene["trust-plain"]
    store = tmp_path / ".out.records"
    # the user's stepper changes after the records were made
    _stepper(tmp_path).write_text(HEUN)
    # one record of the plain scene edited by one digit, one a FIFO, one with its arrays linked to /dev/zero
    runs = [s for s in plain if s.purpose == "run"]
    edited, fifo, zero = runs[0].key, runs[1].key, runs[2].key
    text = (store / f"{edited}.json").read_text()
    i = re.search(r"\d\.\d+e-\d+", text).start() + 2  # the first decimal of the first measured value
    (store / f"{edited}.json").write_text(text[:i] + str((int(text[i]) + 1) % 10) + text[i + 1:])
    (store / f"{fifo}.json").unlink()
    os.mkfifo(store / f"{fifo}.json")
    (store / f"{zero}.npz").unlink()
    (store / f"{zero}.npz").symlink_to("/dev/zero")
    args = sum((["--scene", p] for p in paths), []) + ARGS + _allow_code()
    r = _cli(tmp_path, args + ["--out", str(out), "--resume"], timeout=240)
    (planned, resumed, executed), (resumed2, rerun, mismatch, stale) = _summary(r.stdout)
    assert planned == len(user) + len(plain), r.stdout
    assert resumed == resumed2 == len(plain) - 3 and executed == len(user) + 3, r.stdout
    assert (rerun, mismatch, stale) == (len(user) + 3, 3, len(user)), r.stdout
    # Heun is not of order 4: the resumed run fails as a fresh one does, with the same numbers
    assert r.returncode == 1 and "FAILED" in r.stdout, r.stdout + r.stderr
    fresh = _cli(tmp_path, args + ["--out", str(tmp_path / "fresh")])
    assert fresh.returncode == 1, fresh.stderr
    a, b = _tables(out), _tables(tmp_path / "fresh")
    assert a.keys() == b.keys() and "convergence" in a
    for name in a:
        pd.testing.assert_frame_equal(a[name], b[name], check_exact=True, obj=name)
    assert not store.exists()


@pytest.mark.slow
def test_leftover_records_refuse_a_plain_rerun_and_fresh_moves_them_aside(tmp_path, monkeypatch):
    paths = _scenes(tmp_path)[1:]  # the plain scene
    out = tmp_path / "out"
    _store_of_earlier_run(tmp_path, paths, monkeypatch, out)
    store = tmp_path / ".out.records"
    before = sorted(p.name for p in store.iterdir())
    args = sum((["--scene", p] for p in paths), []) + ARGS + ["--out", str(out)]
    r = _cli(tmp_path, args, timeout=120)
    assert r.returncode == 2 and r.stderr.count("\n") == 1, r.stderr
    assert "--resume" in r.stderr and "--fresh" in r.stderr and str(store) in r.stderr, r.stderr
    assert sorted(p.name for p in store.iterdir()) == before and not out.exists()
    r = _cli(tmp_path, args + ["--resume", "--fresh"], timeout=120)
    assert r.returncode == 2 and "not allowed with" in r.stderr and r.stderr.count("\n") == 1, r.stderr
    r = _cli(tmp_path, args + ["--fresh"])
    assert r.returncode == 0, r.stderr
    m = re.search(r"moved (\d+) record\(s\) of an earlier run aside to (\S+)", r.stderr)
    assert m and int(m.group(1)) == len(before) // 2, r.stderr
    aside = Path(m.group(2))
    assert aside.parent == tmp_path and aside.name.startswith(".out.records-aside-")
    assert sorted(p.name for p in aside.iterdir()) == before
    planned = int(re.search(r"(\d+) runs planned, 0 resumed, (\d+) executed", r.stdout).group(1))
    assert planned == len(before) // 2 and not store.exists()


def test_a_crash_keeps_the_records_and_says_where(tmp_path, monkeypatch):
    # a run that dies of an error (here: a spec raising a non-Exception in the
    # main process) keeps what it recorded for --resume
    paths = _scenes(tmp_path)[1:]
    out = tmp_path / "out"
    code = (
        "import sys; from rk4h.validation import execute, run_all\n"
        "real, n = execute.execute, [0]\n"
        "def boom(scene, spec, quick=False):\n"
        "    n[0] += 1\n"
        "    if n[0] > 3: raise SystemError('boom')\n"
        "    return real(scene, spec, quick)\n"
        "execute.execute = boom\n"
        f"sys.exit(run_all.main({['--scene', paths[0], *ARGS, '--out', str(out)]!r}))\n")
    r = subprocess.run([sys.executable, "-c", code], cwd=REPO, env=_env(tmp_path), capture_output=True,
                       text=True, timeout=120)
    assert r.returncode != 0 and "SystemError" in r.stderr, r.stderr
    store = tmp_path / ".out.records"
    kept = {p.name for p in store.glob("*.json")}
    assert len(kept) == 3 and f"3 record(s) kept in {store}" in r.stderr, r.stderr
