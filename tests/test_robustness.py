"""Faults are rows, not crashes; runaway scenes are refused up front or decimated;
the report directory is swapped into place atomically and leftovers of killed
runs are cleaned up."""
import math
import os
import re
import subprocess
import sys

import numpy as np
import pandas as pd
import pytest

from rk4h.validation import atomic, budget
from rk4h.validation.run_all import main, run
from rk4h.validation.scenes import SceneError, load_scene, output_stride

from _scenes import one_mass


def _scene(tmp_path, name="tiny", t_end=2.0, h="[0.1, 0.05]", solvers='["rk4", "dop853"]',
           outputs='["state"]', extra=""):
    p = tmp_path / f"{name}.toml"
    p.write_text(one_mass(name, t_end=t_end, h=h, solvers=solvers, outputs=outputs, extra=extra))
    return p


def _main(argv):
    # in this process (--workers 1): the faults these tests inject by monkeypatching
    # do not reach worker processes
    try:
        return main([*argv, "--workers", "1"])
    except SystemExit as e:
        return e.code


def _failures_section(index: str) -> str:
    return index[index.index("## Failures"):index.index("## Main findings")]


# -- faults are rows ------------------------------------------------------------------
def _raise_for(solver_name, exc):
    from rk4h.references import solvers

    real = solvers.integrate

    def integrate(solver, *args, **kw):
        if getattr(solver, "name", solver) == solver_name:  # a name or a registry Method
            raise exc
        return real(solver, *args, **kw)
    return integrate


def test_solver_raising_is_a_failed_row_and_the_run_completes(tmp_path, monkeypatch, capsys):
    import rk4h.references.solvers

    monkeypatch.setattr(rk4h.references.solvers, "integrate",
                        _raise_for("dop853", RuntimeError("injected fault\nsecond line")))
    out = tmp_path / "out"
    rc = _main(["--scene", str(_scene(tmp_path)), "--out", str(out), "--repeats", "1", "--no-figures"])
    assert rc == 1  # a fault is a failed expectation, listed; nothing crashed
    acc = pd.read_csv(out / "accuracy.csv")
    dop = acc[acc.solver == "dop853"]
    assert len(dop) == 2 and set(dop.status) == {"failed"}
    assert all(m == "RuntimeError: injected fault" for m in dop.message)  # first line only
    rk4 = acc[acc.solver == "rk4"]
    assert set(rk4.status) == {"ok"} and rk4.error_max.notna().all()
    fails = _failures_section((out / "index.md").read_text())
    assert "tiny: dop853 at 1e-06 raised RuntimeError: injected fault" in fails
    assert "FAILED: tiny: dop853 at 1e-09" in capsys.readouterr().out


def test_cvode_error_is_a_failed_row(tmp_path, monkeypatch):
    import sksundae.cvode

    class BrokenCVODE:
        def __init__(self, *args, **kw):
            raise RuntimeError("CVODE flag -4 (injected)")

    monkeypatch.setattr(sksundae.cvode, "CVODE", BrokenCVODE)
    scene = load_scene(_scene(tmp_path, solvers='["rk4", "cvode-adams"]'))
    results, failures = run([scene], tmp_path, repeats=1, figures=False)
    rows = {(r["solver"], r["setting"]): r for r in results[0].tables["accuracy"]}
    assert rows[("cvode-adams", 1e-6)]["status"] == "failed"
    assert "CVODE flag -4 (injected)" in rows[("cvode-adams", 1e-6)]["message"]
    assert rows[("rk4", 0.1)]["status"] == "ok"
    assert len([f for f in failures if "cvode-adams" in f]) == 2


def test_heyoka_failure_is_a_failed_row(tmp_path, monkeypatch):
    from rk4h.references.solvers import taylor

    def broken(*args, **kw):
        raise RuntimeError("heyoka exploded (injected)")

    monkeypatch.setattr(taylor, "propagate", broken)
    scene = load_scene(_scene(tmp_path, solvers='["rk4", "heyoka"]'))
    results, failures = run([scene], tmp_path, repeats=1, figures=False)
    hey = [r for r in results[0].tables["accuracy"] if r["solver"] == "heyoka"]
    assert [r["status"] for r in hey] == ["failed", "failed"]
    assert all("heyoka exploded (injected)" in r["message"] for r in hey)
    assert any("heyoka" in f for f in failures)


def test_model_raising_inside_the_rhs_is_a_failed_row(tmp_path, monkeypatch):
    # A right-hand side patched onto the class is the model's right-hand side:
    # the compiled path (printed from the definition) stands aside, so every
    # solver calls it and every row fails; the run goes on (the exact modal
    # reference does not call it).
    from rk4h.models.chain import Chain

    def rhs(self, t, y):
        raise FloatingPointError("model fault (injected)")

    monkeypatch.setattr(Chain, "rhs", rhs)
    scene = load_scene(_scene(tmp_path))
    results, failures = run([scene], tmp_path, repeats=1, figures=False)
    status = {(r["solver"], r["setting"]): r["status"] for r in results[0].tables["accuracy"]}
    assert status == {("rk4", 0.1): "failed", ("rk4", 0.05): "failed",
                      ("dop853", 1e-6): "failed", ("dop853", 1e-9): "failed"}


def test_scene_raising_is_a_failure_line_and_other_scenes_run(tmp_path, monkeypatch):
    from rk4h.validation.scenes import Scene

    real = Scene.build_model

    def build_model(self):
        if self.name == "broken":
            raise RuntimeError("model constructor fault (injected)")
        return real(self)

    monkeypatch.setattr(Scene, "build_model", build_model)
    scenes = [load_scene(_scene(tmp_path, name="broken")), load_scene(_scene(tmp_path, name="fine"))]
    out = tmp_path / "out"
    out.mkdir()
    completed = []
    results, failures = run(scenes, out, repeats=1, figures=False, completed=completed)
    assert failures == ["broken: the scene raised RuntimeError: model constructor fault (injected)"]
    assert completed == ["broken", "fine"]
    acc = pd.read_csv(out / "accuracy.csv")
    assert set(acc.scene) == {"fine"} and set(acc.status) == {"ok"}
    index = (out / "index.md").read_text()
    assert "model constructor fault" in _failures_section(index)


@pytest.mark.parametrize("h, theta", [(10.0, 20.0), (1.45, 2.9)], ids=["theta-20", "theta-2.9"])
def test_rk4_blow_up_is_an_unstable_row_at_the_predicted_step(tmp_path, capsys, h, theta):
    # theta = omega h beyond RK4's boundary 2.83. Per step the scaled state
    # (q / s_q, v / s_v), s_q = 0.01 m, s_v = omega s_q, turns and grows by |R(i theta)|,
    # R(z) = 1 + z + z^2/2 + z^3/6 + z^4/24: it passes MAX_GROWTH (1e6) after
    # log(1e6) / log|R| steps; a component lags its amplitude by its phase, so
    # the crossing may come up to two steps later (theta = 20: |R| = 6.6e3;
    # theta = 2.9: |R| = 1.04, ~350 steps).
    from rk4h.references.solvers.fixed import MAX_GROWTH

    t_end = round(h * 2000, 6)
    p = _scene(tmp_path, t_end=t_end, h=f"[{h}, {h / 10:g}]", solvers='["rk4"]', outputs='["state"]',
               extra=f"output_dt = {h}")
    out = tmp_path / "out"
    rc = _main(["--scene", str(p), "--out", str(out), "--repeats", "1", "--no-figures"])
    assert rc == 0  # a blow-up is a measured result, not a failed expectation
    acc = pd.read_csv(out / "accuracy.csv").set_index("setting")
    assert acc.loc[h, "status"] == "unstable" and acc.loc[float(f"{h / 10:g}"), "status"] == "ok"
    z = 1j * theta
    R = abs(1 + z + z ** 2 / 2 + z ** 3 / 6 + z ** 4 / 24)
    predicted = math.ceil(math.log(MAX_GROWTH) / math.log(R))
    message = acc.loc[h, "message"]
    step = int(re.search(r"step (\d+) of", message).group(1))
    assert "grew past" in message and predicted <= step <= predicted + 2, (predicted, message)
    assert f"tiny: rk4 at {h:g} became unstable" in (out / "index.md").read_text()


def test_explicit_euler_growth_is_unstable_not_ok(tmp_path):
    """Explicit Euler grows by sqrt(1 + theta^2) per step on an oscillator: a run
    that grew 1e6-fold (here theta = 0.2: after ~700 steps) is `unstable`."""
    p = _scene(tmp_path, t_end=1000.0, h="[0.1]", solvers='["euler", "symplectic-euler"]',
               outputs='["state", "energy"]', extra="output_dt = 1.0")
    out = tmp_path / "out"
    assert _main(["--scene", str(p), "--out", str(out), "--repeats", "1", "--no-figures"]) == 0
    acc = pd.read_csv(out / "accuracy.csv").set_index("solver")
    assert acc.loc["euler", "status"] == "unstable" and "grew past" in acc.loc["euler", "message"]
    step = int(re.search(r"step (\d+) of", acc.loc["euler", "message"]).group(1))
    predicted = math.log(1e6) / math.log(math.sqrt(1 + 0.2 ** 2))
    assert predicted <= step <= predicted + 20
    assert acc.loc["symplectic-euler", "status"] == "ok"  # bounded: |R| = 1 inside its region


# -- runaway work -----------------------------------------------------------------------
def test_step_estimate_is_the_sum_of_the_fixed_step_runs(tmp_path):
    # rk4 at h = 0.1 and 0.05 over 2 s: 20 + 40 steps; nothing else asked for.
    s = load_scene(_scene(tmp_path, solvers='["rk4"]'))
    est = budget.estimate(s)
    assert est.steps == 60
    assert est.output_points == 21 and est.trajectory_bytes == 8 * 2 * 21


def test_runaway_steps_are_refused_with_the_estimate(tmp_path, capsys):
    # 1e10 s at h = 1: 1e10 rk4 steps > 1e9
    p = _scene(tmp_path, t_end=1e10, h="[1.0]", solvers='["rk4"]', extra="output_dt = 1e7")
    out = tmp_path / "out"
    rc = _main(["--scene", str(p), "--out", str(out)])
    err = capsys.readouterr().err.strip()
    assert rc == 2 and len(err.splitlines()) == 1
    assert err.startswith(f"{p}: field `run`:") and "about 1e+10 integration steps" in err
    assert not out.exists()


def test_runaway_memory_is_refused_then_runs_decimated(tmp_path, capsys):
    # DOP853 only (few steps per period), 3e8 output points: 8 B x 2 x 3e8 = 4.5 GiB > 4 GiB.
    p = _scene(tmp_path, t_end=3e7, h="[0.1]", solvers='["dop853"]', outputs='["modes"]',
               extra="output_dt = 0.1")
    with pytest.raises(SceneError, match=r"needs about 54 GiB of memory \(12 trajectories of 8 B x 2 states x 3e\+08 output points\).* decimate"):
        budget.check(load_scene(p))
    p2 = _scene(tmp_path, name="dec", t_end=3e7, h="[0.1]", solvers='["dop853"]', outputs='["modes"]',
                extra="output_dt = 0.1\nmax_output_points = 1000")
    s = load_scene(p2)
    est = budget.check(s)
    assert est.output_points <= 1000
    t = s.t_eval()
    assert t.size == est.output_points and t[0] == 0.0 and t[-1] == 3e7


def _long_chain(tmp_path, n, outputs='["state"]', initial="x"):
    p = tmp_path / f"chain{n}.toml"
    x = "mode = 1" if initial == "mode" else "x = [" + ", ".join(["0.001"] + ["0.0"] * (n - 1)) + "]"
    p.write_text(f"""name = "chain{n}"
model = "chain"
[params]
masses = [{", ".join(["0.815"] * n)}]
springs = [{", ".join(["41.5"] * (n + 1))}]
walls = "both"
[initial]
{x}
[run]
t_end = 1.0
h = [0.01]
solvers = ["rk4"]
outputs = {outputs}
""")
    return p


@pytest.mark.parametrize("n", [2000, 10000])
def test_the_estimate_needs_no_eigensolve(tmp_path, n):
    """budget.check on 10,000 masses took ~15 min (a dense eigh); it must answer at once."""
    import time

    s = load_scene(_long_chain(tmp_path, n))
    start = time.perf_counter()
    if n > budget.MAX_DENSE_DOF:
        with pytest.raises(SceneError, match=f"dense eigensolve of {n} degrees of freedom"):
            budget.check(s)
    else:
        est = budget.check(s)
        assert est.dense_dof == n and est.steps == 100
        # the Gershgorin bound is an upper bound of the spectrum: 2 sqrt(k/m) for a uniform chain
        assert math.isclose(est.omega_max, 2 * math.sqrt(41.5 / 0.815) * (1 if n > 1 else 0), rel_tol=1e-12)
    assert time.perf_counter() - start < 2.0


def test_a_mode_start_of_a_huge_chain_is_refused_at_load(tmp_path):
    with pytest.raises(SceneError, match="initial.mode.*dense eigensolve of 6000"):
        load_scene(_long_chain(tmp_path, 6000, initial="mode"))


def test_the_quadruple_precision_reference_is_in_the_estimate(tmp_path):
    # a nonlinear pendulum pair: its reference is heyoka real128 over the output grid
    p = tmp_path / "pend.toml"
    p.write_text("""name = "pend"
model = "pendulums"
[params]
m = 1.0
length = 1.0
g = 9.81
k = 0.5
linear = false
[initial]
x = [0.1, 0.0]
[run]
t_end = 100.0
tolerances = [1e-8]
solvers = ["heyoka"]
outputs = ["state"]
""")
    s = load_scene(p)
    est = budget.estimate(s)
    periods = 100.0 * est.omega_max / (2 * math.pi)
    assert est.truth_steps == pytest.approx(budget.TRUTH_STEPS_PER_PERIOD * periods)
    with pytest.raises(SceneError, match="quadruple-precision steps"):
        budget.check(s, max_truth_steps=est.truth_steps / 2)


@pytest.mark.parametrize("n, max_points", [(10, 2), (10, 3), (10, 6), (10, 11), (97, 10), (1000, 7),
                                           (12345, 100)])
def test_decimation_stride_is_the_smallest_that_fits(n, max_points):
    k = output_stride(n, max_points)

    def points(k):  # 0, k, 2k, ... <= n, plus n itself
        return len(set(range(0, n + 1, k)) | {n})

    assert points(k) <= max_points
    assert k == 1 or points(k - 1) > max_points


def test_decimated_grid_is_a_subset_with_the_same_final_error(tmp_path):
    # Decimation keeps every k-th output point of the same step grid, so the RK4
    # values there are the same numbers: the final error is identical and the
    # largest error can only be smaller.
    full = load_scene(_scene(tmp_path, name="full", solvers='["rk4"]', extra="output_dt = 0.1"))
    dec = load_scene(_scene(tmp_path, name="dec", solvers='["rk4"]',
                            extra="output_dt = 0.1\nmax_output_points = 6"))
    tf, td = full.t_eval(), dec.t_eval()
    np.testing.assert_array_equal(tf, np.linspace(0.0, 2.0, 21))
    assert td.size <= 6 and set(td) <= set(tf) and td[-1] == 2.0
    rows = {}
    for s in (full, dec):
        out = tmp_path / s.name
        out.mkdir()
        results, failures = run([s], out, repeats=1, figures=False)
        assert failures == []
        rows[s.name] = {r["setting"]: r for r in results[0].tables["accuracy"]}
    for h in (0.1, 0.05):
        assert rows["dec"][h]["error_final"] == rows["full"][h]["error_final"]
        assert rows["dec"][h]["error_max"] <= rows["full"][h]["error_max"]


def test_cli_max_output_points_lets_a_large_scene_through(tmp_path, capsys, monkeypatch):
    p = _scene(tmp_path, t_end=3e7, h="[0.1]", solvers='["dop853"]', outputs='["modes"]',
               extra="output_dt = 0.1")
    out = tmp_path / "out"
    # only the modes output: nothing integrates, the check is what is tested
    rc = _main(["--scene", str(p), "--out", str(out), "--no-figures", "--max-output-points", "100"])
    assert rc == 0, capsys.readouterr().err
    assert pd.read_csv(out / "modes.csv")["omega_rad_s"].tolist() == pytest.approx([2.0], rel=1e-14)


# -- atomic swap and recovery ----------------------------------------------------------------
def _tree(d):
    return {p.relative_to(d).as_posix(): p.read_bytes() for p in sorted(d.rglob("*")) if p.is_file()}


def _make(d, files):
    d.mkdir(exist_ok=True)
    for name, text in files.items():
        (d / name).write_text(text)
    return d


@pytest.mark.parametrize("exchange", [True, False], ids=["renameat2-exchange", "two-renames"])
def test_swap_replaces_the_whole_directory(tmp_path, monkeypatch, exchange):
    target = tmp_path / "reports"
    old = _make(atomic.fresh_dir(target), {"index.md": "old", "stale.csv": "old"})
    atomic.swap_into_place(old, target, scope="full", scenes=["a"])
    new = _make(atomic.fresh_dir(target), {"index.md": "new", "accuracy.csv": "new"})
    if not exchange:
        monkeypatch.setattr(atomic, "_exchange", lambda a, b: False)
    swap = atomic.swap_into_place(new, target, scope="full", scenes=["a"])
    how = swap.how
    assert swap.kept is None and swap.why is None  # the verified previous report was removed
    if exchange and not atomic.exchange_supported(tmp_path):
        pytest.skip("this filesystem has no renameat2(RENAME_EXCHANGE)")
    assert how == ("exchange" if exchange else "two renames")
    tree = _tree(target)
    assert tree.pop(atomic.MARKER)  # the ownership marker, with the manifest of the rest
    assert tree == {"index.md": b"new", "accuracy.csv": b"new"}
    assert set(atomic.read_marker(target)["manifest"]) == {"index.md", "accuracy.csv"}
    assert sorted(p.name for p in tmp_path.iterdir()) == ["reports"]


def test_fresh_dir_has_plain_mkdir_permissions(tmp_path):
    d = atomic.fresh_dir(tmp_path / "reports")
    umask = os.umask(0)
    os.umask(umask)
    assert d.stat().st_mode & 0o777 == 0o777 & ~umask
    st = os.lstat(d)
    assert atomic.read_marker(d) == {"magic": "rk4h-report v1", "state": "incomplete", "target": "reports",
                                     "dir": d.name, "dev": st.st_dev, "ino": st.st_ino}

