"""The runner: convergence orders on every linear scene, reference solvers
improving with tolerance, and the command line's exit codes and atomic output."""
import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from rk4h.references import registry
from rk4h.references.exact import modal_solution
from rk4h.references.solvers import integrate
import dataclasses

from rk4h.validation import execute as X
from rk4h.validation import measure as M
from rk4h.validation import plan as P
from rk4h.validation.scenes import SCENE_DIR, load_scene, load_scenes

from _scenes import one_mass

REPO = Path(__file__).resolve().parent.parent
# the linear scenes whose convergence the runner checks (not the stability study's own scenes)
LINEAR = [s for s in load_scenes() if s.build_model().linear and "convergence" in s.outputs]


# RK4 (the system under test) on every linear scene; the two Euler contrasts on
# two scenes in the default run (a 2-DOF chain: the straight-line loop; the
# 100-mass lattice: the array loop) and on every scene with -m slow -- each
# (method, model structure) pair compiles its own loop on a cold cache.
_EULER_DEFAULT = {"thesis-2dof-case1", "lattice100"}
ORDER_CASES = [pytest.param(s, m, id=f"{s.name}-{m}",
                            marks=() if m == registry.UNDER_TEST or s.name in _EULER_DEFAULT else pytest.mark.slow)
               for s in LINEAR for m in registry.CONVERGENCE_ALWAYS]
# Every other fixed-step method of a scene (Stormer-Verlet, a scene's own
# tableaux and Python stepper): observed order = the computed/declared one.
ORDER_CASES += [pytest.param(s, m, id=f"{s.name}-{m}") for s in LINEAR for m in s.fixed_solvers
                if m not in registry.CONVERGENCE_ALWAYS]


@pytest.mark.parametrize("scene, method", ORDER_CASES)
def test_observed_order_on_every_linear_scene(scene, method):
    # Sweeps of h = theta / omega_max over one period of the fastest mode, against
    # the exact modal solution; classical orders: RK4 4, explicit and symplectic Euler 1.
    # Through the pipeline: the plan's order specs of this method, executed, measured.
    conv = dataclasses.replace(scene, outputs=["convergence"])
    specs = [s for s in P.plan(conv, figures=False)
             if s.solver == method or (s.purpose == "truth" and s.grid == "order")]
    assert [s.setting for s in specs if s.purpose == "order"] == list(
        P.RK4_THETAS if scene.method(method).order >= 3 else P.EULER_THETAS)
    records = {s.key: X.execute(conv, s) for s in specs}
    res = M.measure(conv, specs, records, figures=False)
    (row,) = [r for r in res.tables["convergence"] if r["solver"] == method]
    assert row["n_points"] >= 3, row
    assert row["observed_order"] == pytest.approx(scene.method(method).order, abs=0.1)
    assert row["passed"] is True


@pytest.mark.parametrize("scene", LINEAR, ids=lambda s: s.name)
def test_dop853_error_decreases_with_tolerance(scene):
    # Over two periods of the slowest vibrating mode; each 1000x tighter tolerance
    # must lower the error against the exact solution.
    model = scene.build_model()
    y0 = scene.y0()
    omega = model.modes()[0]
    T = 2 * 2 * math.pi / omega[omega > 0].min()
    t = np.linspace(0.0, T, 51)
    exact = modal_solution(model, y0)(t)
    errs = []
    for rtol in (1e-4, 1e-7, 1e-10):
        run = integrate("dop853", model, y0, t, rtol)
        assert run.ok, run.message
        errs.append(np.max(np.abs(run.y - exact)))
    assert errs[0] > errs[1] > errs[2], errs


def _cli(args, *, module=False, cwd=REPO):
    cmd = [sys.executable, "-m", "rk4h.validation.run_all"] if module else [sys.executable, "validation/run_all.py"]
    env = {**os.environ, "MPLBACKEND": "Agg"}
    return subprocess.run(cmd + args, cwd=cwd, capture_output=True, text=True, timeout=300, env=env)


@pytest.fixture
def previous_report(tmp_path):
    """An output directory that already holds a report this tool wrote, to check
    it is not damaged (and that it may be replaced)."""
    from rk4h.validation import atomic

    out = tmp_path / "reports"
    tmp = atomic.fresh_dir(out)
    (tmp / "index.md").write_text("previous report\n")
    (tmp / "accuracy.csv").write_text("scene\nold\n")
    atomic.swap_into_place(tmp, out, scope="subset", scenes=["old"])
    return out


def _snapshot(d: Path):
    return {p.relative_to(d).as_posix(): p.read_bytes() for p in sorted(d.rglob("*")) if p.is_file()}


@pytest.mark.parametrize("module", [False, True], ids=["script", "module"])
def test_bad_scene_exits_2_with_one_line_and_leaves_out_dir_alone(tmp_path, previous_report, module):
    bad = tmp_path / "bad.toml"
    text = (SCENE_DIR / "three_blocks.toml").read_text().replace("masses = [0.815, 0.815, 0.815]",
                                                                 "masses = [0.815, -1.0, 0.815]")
    bad.write_text(text)
    before = _snapshot(previous_report)
    r = _cli(["--scene", str(bad), "--out", str(previous_report)], module=module)
    assert r.returncode == 2
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in r.stderr
    assert "bad.toml" in lines[0] and "field `params.masses[1]`" in lines[0]
    assert _snapshot(previous_report) == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bad.toml", "reports"]  # no temp dir, no lock file


def test_bad_flag_exits_2_with_one_line(tmp_path):
    r = _cli(["--repeats", "many"])
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1 and "Traceback" not in r.stderr


TINY = one_mass("tiny-oscillator", tolerances="[1e-5, 1e-9]",
                outputs='["state", "energy", "convergence", "work_precision", "modes", "figures"]')


def test_small_run_writes_tables_and_index(tmp_path, previous_report):
    scene = tmp_path / "tiny.toml"
    scene.write_text(TINY)
    r = _cli(["--scene", str(scene), "--out", str(previous_report), "--repeats", "1"])
    assert r.returncode == 0, r.stdout + r.stderr
    out = previous_report
    acc = pd.read_csv(out / "accuracy.csv")
    assert list(acc.columns[:13]) == ["scene", "solver", "setting", "h", "rtol", "error_max", "error_rel",
                                      "error_final", "energy_drift_max", "nfev", "cost_unit", "n_steps", "wall_s"]
    assert set(acc["cost_unit"]) == {"rhs"}  # rk4 and dop853 count every right-hand-side call
    assert len(acc) == 4 and set(acc["status"]) == {"ok"}
    rk4 = acc[acc.solver == "rk4"].set_index("setting")
    # RK4: 4 stages per step, h = 0.1 over 2 s is 20 steps
    assert rk4.loc[0.1, "n_steps"] == 20 and rk4.loc[0.1, "nfev"] == 80
    modes = pd.read_csv(out / "modes.csv")
    assert modes["omega_rad_s"].tolist() == pytest.approx([2.0], rel=1e-14)  # sqrt((2 + 2) / 1)
    conv = pd.read_csv(out / "convergence.csv")
    assert set(conv[conv.quantity == "order in h"]["solver"]) == set(registry.CONVERGENCE_ALWAYS)
    index = (out / "index.md").read_text()
    assert index.index("## Failures") < index.index("## Main findings") < index.index("## Errata")
    for name in ("accuracy.csv", "convergence.csv", "modes.csv", "work_precision.csv", "energy.csv",
                 "cheapest.csv"):
        assert f"]({name})" in index and (out / name).exists()
    pngs = sorted(p.name for p in out.glob("*.png"))
    assert pngs and all(f"]({p})" in index for p in pngs)   # every figure linked
    assert "numpy" in index and "heyoka" in index            # versions recorded
    assert "previous report" not in index
    assert [p.name for p in tmp_path.iterdir() if p.name.startswith(".")] == [".reports.lock"]  # no temp dir; the lock file stays
    # the phase line benchmarks/bench_user_scene.py quotes
    sys.path.insert(0, str(REPO / "benchmarks"))
    try:
        import bench_user_scene
    finally:
        sys.path.remove(str(REPO / "benchmarks"))
    assert bench_user_scene.PHASES.search(r.stdout + r.stderr), r.stdout[-1000:]


def test_failed_expectation_exits_1_and_is_listed_first(tmp_path):
    # Steps far outside RK4's asymptotic range (theta = omega h up to 2.4) cannot give
    # order 4 within 0.1: the runner must say so and exit 1.
    scene = tmp_path / "tiny.toml"
    scene.write_text(TINY.replace('outputs = ["state", "energy", "convergence", "work_precision", "modes", "figures"]',
                                  'outputs = ["convergence"]\n[convergence]\ntheta = [2.4, 1.2, 0.6]\n'
                                  'theta_euler = [0.01, 0.005, 0.0025]\nt_end = 2.0'))
    out = tmp_path / "out"
    r = _cli(["--scene", str(scene), "--out", str(out), "--repeats", "1"])
    assert r.returncode == 1, r.stdout + r.stderr
    index = (out / "index.md").read_text()
    failures = index[index.index("## Failures"):index.index("## Main findings")]
    assert "tiny-oscillator: rk4 observed order" in failures
    assert "euler observed order" not in failures
