"""CVODE through ctypes with compiled callbacks (``references/solvers/cvode_compiled.py``)
against scikit-sundae's run (``references/solvers/cvode.py``): the same library,
configuration, states, steps and evaluations; failures, the fallback, no Python
call per evaluation, every SUNDIALS object freed, and the timed path untouched."""
import numpy as np
import pytest

from _cvode_cases import CASES, T, case
from rk4h.references.solvers import COMPILED_RUNNERS, absolute_tolerance, integrate, integrate_compiled
from rk4h.references.solvers import cvode_compiled as cc
from rk4h.references.solvers.cvode import run_cvode

pytest.importorskip("sksundae")
pytestmark = pytest.mark.skipif(cc.sundials_library()[0] is None,
                                reason=f"compiled CVODE unavailable: {cc.sundials_library()[1]}")

SOLVERS = ("cvode-adams", "cvode-bdf")
COUNTERS = ("njev", "nfev_cvode", "nfev_jac_dq", "linsolver", "lband", "uband")


def _pair(solver, model, y0, t, rtol, max_steps=5_000_000):
    atol = absolute_tolerance(model, y0, rtol)
    ref = run_cvode(solver, model, y0, t, rtol, atol, max_steps)
    new = cc.run_cvode_compiled(solver, model, y0, t, rtol, atol, max_steps)
    return ref, new


def _assert_same(ref, new):
    assert new.extra["implementation"] == "compiled", new.extra.get("compiled_error")
    assert new.status == ref.status, (ref.message, new.message)
    assert new.message == ref.message
    assert (new.n_steps, new.nfev) == (ref.n_steps, ref.nfev)
    for key in COUNTERS:
        assert new.extra.get(key) == ref.extra.get(key), key
    # the same library, options and arithmetic: bit for bit
    np.testing.assert_array_equal(new.y, ref.y)
    assert new.t_fail == ref.t_fail


@pytest.mark.parametrize("name", sorted(CASES))
@pytest.mark.parametrize("solver", SOLVERS)
@pytest.mark.parametrize("rtol", [1e-4, 1e-7, 1e-11])
def test_equal_to_scikit_sundae_on_the_shared_cases(name, solver, rtol):
    model, y0 = case(name)
    ref, new = _pair(solver, model, y0, T, rtol)
    assert ref.status.value == "ok" and ref.n_steps > 10
    _assert_same(ref, new)


def _scene_problem(scene_name, t_end=None):
    from rk4h.validation.execute import problem
    from rk4h.validation.scenes import load_scenes

    scene = load_scenes([scene_name])[0]
    model, y0 = problem(scene)
    t = np.asarray(scene.t_eval(), dtype=float)
    if t_end is not None:
        t = t[t <= t[0] + t_end]
    return model, y0, t


@pytest.mark.parametrize("scene_name, t_end", [("planar4_case2", 20.0), ("network_web", 5.0),
                                               ("chain10_mode2", 10.0)])
@pytest.mark.parametrize("solver", SOLVERS)
@pytest.mark.parametrize("rtol", [1e-6, 1e-10])
def test_equal_to_scikit_sundae_on_scene_models(scene_name, t_end, solver, rtol):
    model, y0, t = _scene_problem(scene_name, t_end)
    ref, new = _pair(solver, model, y0, t, rtol)
    assert ref.status.value == "ok"
    _assert_same(ref, new)


@pytest.mark.parametrize("solver", SOLVERS)
def test_two_output_times(solver):
    """scikit-sundae's solve steps one by one for two times; run_cvode adds a
    midpoint (it moves CVODE's first-step estimate), and so does this runner."""
    model, y0 = case("pendulums")
    ref, new = _pair(solver, model, y0, np.array([0.0, 3.0]), 1e-8)
    _assert_same(ref, new)
    assert new.y.shape == (4, 2)


@pytest.mark.parametrize("name", ["chain-2dof", "chain-12", "pendulums"])
@pytest.mark.parametrize("max_steps", [1, 37, 150])
def test_step_cap_as_scikit_sundae(name, max_steps):
    """The total step cap: FAILED at step max_steps, the same outputs, t_fail
    and message (the evaluations spent failing differ: scikit-sundae's run
    returns NaN until CVODE gives up)."""
    model, y0 = case(name)
    ref, new = _pair("cvode-adams", model, y0, T, 1e-9, max_steps=max_steps)
    assert ref.status.value == "failed" and "step cap" in ref.message
    assert new.status == ref.status and new.message == ref.message
    assert new.n_steps == ref.n_steps == max_steps
    assert new.t_fail == ref.t_fail
    np.testing.assert_array_equal(new.y, ref.y)


def test_cvode_error_flag_as_scikit_sundae():
    """A tolerance CVODE refuses (flag -2, too much accuracy): FAILED with CVODE's message."""
    model, y0 = case("chain-2dof")
    atol = np.full(4, 1e-300)
    ref = run_cvode("cvode-bdf", model, y0, T, 1e-30, atol)
    new = cc.run_cvode_compiled("cvode-bdf", model, y0, T, 1e-30, atol)
    assert ref.status.value == "failed" and "flag -2" in ref.message
    assert (new.status, new.message, new.t_fail) == (ref.status, ref.message, ref.t_fail)
    np.testing.assert_array_equal(new.y, ref.y)


def test_non_finite_start_is_unstable():
    model, y0 = case("chain-2dof")
    y0 = y0.copy()
    run = cc.run_cvode_compiled("cvode-adams", model, y0, T, 1e-6, np.full(4, 1e-9))
    assert run.status.value == "ok"
    model.rhs = lambda t, y: np.full(4, np.nan)  # only the initial check calls model.rhs
    run = cc.run_cvode_compiled("cvode-adams", model, y0, T, 1e-6, np.full(4, 1e-9))
    assert run.status.value == "unstable" and "no step taken" in run.message
    assert np.all(np.isnan(run.y[:, 1:]))


@pytest.mark.parametrize("name", sorted(CASES))
def test_no_python_call_per_evaluation(name, monkeypatch):
    """CVODE calls only the compiled callbacks: model.rhs runs once (the
    initial finiteness check), model.jacobian never."""
    model, y0 = case(name)
    calls = {"rhs": 0, "jacobian": 0}
    rhs, jac = model.rhs, model.jacobian

    def count_rhs(t, y):
        calls["rhs"] += 1
        return rhs(t, y)

    def count_jac(t=None, y=None):
        calls["jacobian"] += 1
        return jac(t, y)

    run_cvode("cvode-bdf", model, y0, T, 1e-8, absolute_tolerance(model, y0, 1e-8))  # builds what both share
    monkeypatch.setattr(model, "rhs", count_rhs, raising=False)
    monkeypatch.setattr(model, "jacobian", count_jac, raising=False)
    run = cc.run_cvode_compiled("cvode-bdf", model, y0, T, 1e-8, absolute_tolerance(model, y0, 1e-8))
    assert run.extra["implementation"] == "compiled" and run.nfev > 100
    assert calls == {"rhs": 1, "jacobian": 0}
    if name == "pendulums":
        assert run.extra["njev"] > 0  # the Jacobian callback ran, compiled


def test_fallback_when_the_library_is_not_usable(monkeypatch):
    model, y0 = case("chain-2dof")
    monkeypatch.setattr(cc, "_load_sundials", lambda: (None, "libsundials_cvode: 0 candidates"))
    atol = absolute_tolerance(model, y0, 1e-8)
    run = cc.run_cvode_compiled("cvode-adams", model, y0, T, 1e-8, atol)
    ref = run_cvode("cvode-adams", model, y0, T, 1e-8, atol)
    assert run.extra["implementation"] == "scikit-sundae"
    assert run.extra["compiled_error"] == "libsundials_cvode: 0 candidates"
    np.testing.assert_array_equal(run.y, ref.y)
    assert (run.n_steps, run.nfev) == (ref.n_steps, ref.nfev)


def test_fallback_on_another_sundials_version(monkeypatch):
    monkeypatch.setattr(cc, "SUNDIALS_ABI", (6, 7))
    cc._load_sundials.cache_clear()
    try:
        lib, why = cc._load_sundials()
        assert lib is None and "written for 6.7.x" in why
        model, y0 = case("chain-2dof")
        run = cc.run_cvode_compiled("cvode-bdf", model, y0, T, 1e-6, absolute_tolerance(model, y0, 1e-6))
        assert run.extra["implementation"] == "scikit-sundae" and "6.7.x" in run.extra["compiled_error"]
        assert run.status.value == "ok"
    finally:
        monkeypatch.undo()
        cc._load_sundials.cache_clear()
    assert cc._load_sundials()[0] is not None


def test_libraries_come_from_the_installed_scikit_sundae():
    import os

    import sksundae

    paths, version = cc.sundials_library()
    site = os.path.dirname(os.path.dirname(os.path.realpath(sksundae.__file__)))
    assert version[:2] == cc.SUNDIALS_ABI
    assert set(paths) == set(cc._LIBS)
    assert all(os.path.realpath(p).startswith(site + os.sep) for p in paths.values())


class _Recorder:
    """The SUNDIALS functions, with every constructor and destructor call
    recorded; ``CVode`` raises at its ``fail_at``-th call."""

    MAKE = ("SUNContext_Create", "N_VNew_Serial", "SUNDenseMatrix", "SUNBandMatrix", "SUNLinSol_Dense",
            "SUNLinSol_Band", "CVodeCreate")
    FREE = ("SUNContext_Free", "N_VDestroy", "SUNMatDestroy", "SUNLinSolFree", "CVodeFree")

    def __init__(self, lib, fail_at=None):
        self._lib, self.fail_at, self.log, self.cvode_calls = lib, fail_at, [], 0

    def __getattr__(self, name):
        fn = getattr(self._lib, name)
        if name == "CVode":
            def cvode(*a):
                self.cvode_calls += 1
                if self.cvode_calls == self.fail_at:
                    raise RuntimeError("injected")
                return fn(*a)
            return cvode
        if name in self.MAKE or name in self.FREE:
            def logged(*a):
                out = fn(*a)
                self.log.append(name)
                return out
            return logged
        return fn


@pytest.mark.parametrize("name", ["chain-2dof", "chain-12", "pendulums"])
@pytest.mark.parametrize("fail_at", [None, 3])
def test_every_sundials_object_is_freed(name, fail_at, monkeypatch):
    lib = cc._load_sundials()[0]
    rec = _Recorder(lib, fail_at)
    monkeypatch.setattr(cc, "_load_sundials", lambda: (rec, None))
    model, y0 = case(name)
    run = cc.run_cvode_compiled("cvode-adams", model, y0, T, 1e-8, absolute_tolerance(model, y0, 1e-8))
    if fail_at is None:
        assert run.status.value == "ok"
    else:
        assert run.status.value == "failed" and "injected" in run.message
        assert np.all(np.isnan(run.y[:, 2:]))
    made = {k: rec.log.count(k) for k in rec.MAKE}
    freed = {k: rec.log.count(k) for k in rec.FREE}
    assert made["SUNContext_Create"] == freed["SUNContext_Free"] == 1
    assert made["N_VNew_Serial"] == freed["N_VDestroy"] == 2
    assert made["SUNDenseMatrix"] + made["SUNBandMatrix"] == freed["SUNMatDestroy"] == 1
    assert made["SUNLinSol_Dense"] + made["SUNLinSol_Band"] == freed["SUNLinSolFree"] == 1
    assert made["CVodeCreate"] == freed["CVodeFree"] == 1
    assert rec.log[-1] == "SUNContext_Free"


def test_every_compiled_runner_names_the_loop_it_steps():
    """warm.py prepares COMPILED_LOOPS' loops: each compiled runner has one,
    and CVODE's two methods share their callbacks (one compile)."""
    from rk4h.references.solvers import COMPILED_LOOPS

    assert set(COMPILED_LOOPS) == set(COMPILED_RUNNERS)
    assert {COMPILED_LOOPS[s] for s in SOLVERS} == {"cvode"}


def test_registered_for_untimed_work_only(monkeypatch):
    """integrate_compiled runs the compiled CVODE; integrate (the timed rows)
    still runs scikit-sundae's."""
    assert set(SOLVERS) <= set(COMPILED_RUNNERS)
    model, y0 = case("chain-12")
    untimed = integrate_compiled("cvode-bdf", model, y0, T, 1e-8)
    timed = integrate("cvode-bdf", model, y0, T, 1e-8)
    assert untimed.extra["implementation"] == "compiled"
    assert timed.extra.get("implementation") is None
    np.testing.assert_array_equal(untimed.y, timed.y)

    def boom(*a, **k):
        raise AssertionError("the timed path must not reach the compiled runner")

    monkeypatch.setattr(cc, "_solve", boom)
    assert integrate("cvode-adams", model, y0, T, 1e-8).status.value == "ok"
    assert integrate_compiled("cvode-adams", model, y0, T, 1e-8).status.value == "failed"


@pytest.mark.parametrize("solver, how, timed", [("cvode-bdf", "compiled callbacks", "scikit-sundae's"),
                                                ("dop853", "compiled loop", "scipy's")])
def test_the_trust_note_names_what_the_scene_runs_time(solver, how, timed):
    import math

    from rk4h.references.registry import BUILTIN
    from rk4h.validation import trust

    rk4 = [dict(solver="rk4", setting=h, error_rel=1e3 * h**4, nfev=4 * round(100 / h), n_steps=round(100 / h),
                wall_s=1e-3, wall_min=1e-3, wall_max=1e-3, compile_s=0.0, status="ok", taylor_order=0)
           for h in (0.1, 0.05, 0.025, 0.0125)]
    alt = dict(solver=solver, setting=1e-12, error_rel=4e-13, nfev=5000, n_steps=400, wall_s=1e-3, wall_min=1e-3,
               wall_max=1e-3, compile_s=0.0, status="ok", taylor_order=0, implementation="compiled")
    note = trust.trust_rows("s", rk4, BUILTIN["rk4"], 100.0, math.inf, [1e-12], confirmations=[alt])[0]["note"]
    assert f"(its {how}, a confirmation run; the scene's runs time {timed})" in note


def test_a_first_order_model_runs_scikit_sundae():
    """A plain fun(t, y) has no compiled right-hand side: scikit-sundae's run, said so."""
    y0 = np.array([1.0, 0.5, -0.25])
    run = integrate_compiled("cvode-bdf", lambda t, y: -y, y0, T, 1e-8)
    ref = integrate("cvode-bdf", lambda t, y: -y, y0, T, 1e-8)
    assert run.status.value == "ok" and run.extra["implementation"] == "scikit-sundae"
    assert "compiled right-hand side" in run.extra["compiled_error"]
    np.testing.assert_array_equal(run.y, ref.y)
    np.testing.assert_allclose(run.y[:, -1], y0 * np.exp(-T[-1]), rtol=1e-5)


def test_the_benchmark_compares_both_on_one_scene():
    import subprocess
    import sys
    from pathlib import Path

    root = Path(__file__).resolve().parent.parent
    proc = subprocess.run([sys.executable, str(root / "benchmarks" / "bench_cvode.py"), "--compiled", "--tiny",
                           "--compiled-scenes", "thesis_2dof_case1"], capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr[-2000:]
    out = proc.stdout
    assert out.count("thesis-2dof-case1 ") == 4  # two methods x rtol 1e-8, 1e-12
    assert "ratio compiled/scikit-sundae whole run (sum of the medians): " in out
    assert "check same states (bit for bit), n_steps, nfev and status: True" in out
    assert "fell back" not in out and "DIFFERENT" not in out


def _stiff_quartic():
    """A chain whose quartic springs blow up: CVODE warns "t + h = t" on its way down."""
    from rk4h.models import make_model

    model = make_model("chain", {"masses": [1.0, 1.0], "springs": [10.0, 10.0, 10.0], "beta": -1e6})
    return model, np.array([1.0, -0.5, 0.0, 0.0]), np.linspace(0.0, 10.0, 101)


def test_sundials_warnings_do_not_reach_stdout(capfd):
    """The advisor's --json and the report's progress share stdout: the
    library's own logger is switched off (the file descriptor is checked,
    as SUNDIALS writes from C)."""
    model, y0, t = _stiff_quartic()
    run = integrate_compiled("cvode-adams", model, y0, t, 1e-8)
    assert run.extra["implementation"] == "compiled" and run.status.value != "ok"
    out, err = capfd.readouterr()
    assert out == "" and "WARNING" not in err


def test_a_raising_right_hand_side_is_a_status_not_an_exception(monkeypatch):
    """As scikit-sundae's run: the model's error is the run's FAILED status."""
    bad, y0 = case(sorted(CASES)[0])
    assert cc.compiled_rhs(bad) is not None

    def raising(t, y):
        raise ValueError("no force here")

    monkeypatch.setattr(bad, "rhs", raising)
    atol = absolute_tolerance(bad, y0, 1e-8)
    ref = run_cvode("cvode-bdf", bad, y0, T, 1e-8, atol, 10_000)
    new = cc.run_cvode_compiled("cvode-bdf", bad, y0, T, 1e-8, atol, 10_000)
    assert ref.status.value == "failed" and "no force here" in ref.message
    assert (new.status, new.message) == (ref.status, ref.message)
    assert "no force here" in new.extra["compiled_error"]


def test_two_threads_on_one_model_give_the_serial_runs(monkeypatch):
    """CVODE runs without the GIL: each run has its own work array (not the
    model's shared one), so two threads integrating one model concurrently
    get the serial results."""
    from concurrent.futures import ThreadPoolExecutor

    model, y0 = case(sorted(CASES)[-1])
    seen, solve = [], cc._solve
    monkeypatch.setattr(cc, "_solve", lambda *a: seen.append(int(a[14][6])) or solve(*a))
    integrate_compiled("cvode-bdf", model, y0, T, 1e-6)
    assert seen and seen[0] != cc.compiled_rhs(model).w.ctypes.data
    monkeypatch.setattr(cc, "_solve", solve)
    serial = [integrate_compiled(s, model, y0, T, 1e-10) for s in SOLVERS * 2]
    with ThreadPoolExecutor(2) as pool:
        threaded = list(pool.map(lambda s: integrate_compiled(s, model, y0, T, 1e-10), SOLVERS * 2))
    for a, b in zip(serial, threaded):
        assert b.extra["implementation"] == "compiled"
        np.testing.assert_array_equal(a.y, b.y)
        assert (a.n_steps, a.nfev) == (b.n_steps, b.nfev)
