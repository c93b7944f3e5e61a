"""The solver interface (rk4h.references.solvers): accuracy against exact and real128
references, tolerance behaviour, counters, validation and failure reporting."""
import math

import numpy as np
import pytest

import rk4h
from rk4h.references.exact import modal_solution
from rk4h.references.solvers import (ADAPTIVE, FIXED_STEP, SOLVER_NAMES, SolverRun, Status, check_setting,
                                integrate)
from rk4h.references.solvers.cvode import interleave, linear_jacobian
from rk4h.references.solvers.taylor import _pars, scaled_system
from rk4h.references.solvers.tolerances import omega_bound, state_scale
from rk4h.references.truth import reference_solution

# name -> (model, params, x0, v0)
LINEAR = {
    "chain-2dof": ("chain", {"masses": [0.815, 3.099], "springs": [41.5, 138.0, 157.8]},
                   [0.005, 0.005], [0.0, 0.0]),
    "chain-free": ("chain", {"masses": [1.0, 2.0, 1.0, 3.0], "springs": [10.0, 20.0, 15.0], "walls": "none"},
                   [0.01, 0.0, -0.01, 0.0], [0.1, 0.0, 0.0, 0.0]),
    "chain-12": ("chain", {"masses": [1.0 + 0.1 * i for i in range(12)],
                           "springs": [40.0 + 3.0 * i for i in range(13)]},
                 [0.004 * math.sin(0.5 * i) for i in range(12)], [0.0] * 12),
    "oscillator2d": ("oscillator2d", {"m": 0.815, "kx": 41.5, "ky": 20.75}, [0.005, 0.003], [0.0, 0.02]),
    "planar4-linear": ("planar4", {"m": 0.815, "k": 41.5, "l": 0.01, "linear": True}, [0.005, 0.0], [0.0, 0.0]),
    "pendulums-linear": ("pendulums", {"m": 1.0, "length": 1.0, "g": 9.81, "k": 2.0, "linear": True},
                         [0.1, 0.0], [0.0, 0.0]),
}
NONLINEAR = {
    "planar4": ("planar4", {"m": 0.815, "k": 41.5, "l": 0.01}, [0.005, 0.0], [0.0, 0.0]),  # Table 4.4
    "pendulums": ("pendulums", {"m": 1.0, "length": 1.0, "g": 9.81, "k": 2.0}, [0.3, 0.0], [0.0, 0.5]),
    "triangle": ("triangle", {"m": 1.0, "k": 10.0, "side": 1.0},
                 [0.05, 0.0, -0.02, 0.01, 0.0, 0.03], [0.0, 0.01, 0.0, 0.0, 0.02, 0.0]),
}
ALL = {**LINEAR, **NONLINEAR}
# Tightest tolerance per adaptive solver (scipy floors DOP853's rtol at 100 eps = 2.2e-14).
TIGHTEST = {"dop853": 1e-13, "cvode-adams": 1e-14, "cvode-bdf": 1e-14, "heyoka": 1e-14}


def tightest(solver: str) -> float:
    """:data:`TIGHTEST`, or for a reference added to the registry since, the
    harness' own floor for it (``rk4h.validation.confirm.rtol_floor``)."""
    from rk4h.validation.confirm import rtol_floor

    return TIGHTEST.get(solver) or rtol_floor(solver)


def scene(name):
    model_name, params, x0, v0 = ALL[name]
    model = rk4h.make_model(model_name, params)
    return model, model.state(x0, v0)


def rel_error(model, y, y_ref):
    """Largest error over time relative to the reference's amplitude, positions
    and velocities each against their own amplitude."""
    n = model.n_dof
    eq = np.max(np.abs(y[:n] - y_ref[:n])) / np.max(np.abs(y_ref[:n]))
    ev = np.max(np.abs(y[n:] - y_ref[n:])) / np.max(np.abs(y_ref[n:]))
    return max(eq, ev)


@pytest.fixture(scope="module")
def truth_dir(tmp_path_factory):
    # A fresh cache: a truth cached by an older build must not hide a bug.
    return tmp_path_factory.mktemp("truth")


# -- the heyoka equations are the numpy equations ---------------------------------------
@pytest.mark.parametrize("name", sorted(ALL))
def test_heyoka_system_matches_model_rhs(name):
    import heyoka as hy

    model, y0 = scene(name)
    n2 = model.n_state
    rng = np.random.default_rng(1)
    Y = y0[:, None] + state_scale(model, y0)[:, None] * rng.uniform(-1.0, 1.0, (n2, 50))
    ref = model.rhs(0.0, Y)
    vs, exprs = model.heyoka_system()
    got = hy.cfunc(exprs, vs)(Y)
    # What heyoka integrates: the scaled system z' = f(s z) / s with the masses as parameters.
    zs, sys = scaled_system(model)
    s = state_scale(model, y0)
    scales = (s[0], s[-1])
    got_scaled = hy.cfunc([e for _, e in sys], zs)(Y / s[:, None], pars=np.repeat(
        _pars(model, scales)[:, None], Y.shape[1], axis=1)) * s[:, None]
    # Same formula, different association order: agreement to a few ulps of the
    # largest term (the force sums several spring terms of either sign).
    scale = np.max(np.abs(ref), axis=1, keepdims=True) + 1e-300
    assert np.max(np.abs(got - ref) / scale) < 1e-13
    assert np.max(np.abs(got_scaled - ref) / scale) < 1e-13


# -- accuracy on linear models against the exact modal solution --------------------------
@pytest.mark.parametrize("solver", ADAPTIVE)
@pytest.mark.parametrize("name", sorted(LINEAR))
def test_adaptive_tightest_matches_exact(name, solver):
    model, y0 = scene(name)
    t = np.linspace(0.0, 3.0, 61)
    run = integrate(solver, model, y0, t, tightest(solver))
    assert run.status is Status.OK, run.message
    assert rel_error(model, run.y, modal_solution(model, y0)(t)) < 1e-9


@pytest.mark.parametrize("name", sorted(LINEAR))
def test_rk4_error_within_phase_error_bound(name):
    model, y0 = scene(name)
    ex = modal_solution(model, y0)
    h = 0.1 / np.max(ex.omega)  # theta_max = omega_max h = 0.1
    t = np.linspace(0.0, 3.0, 301)
    run = integrate("rk4", model, y0, t, h)
    assert run.status is Status.OK, run.message
    # Per step RK4 advances each mode with R(i theta) = exp(i(theta - theta^5/120 + O(theta^7)))
    # (|R| = 1 - theta^6/144), so after n steps mode j has a phase error n theta_j^5/120
    # and coordinate i an error <= sum_j |phi_ij| A_j n theta_j^5/120; zero modes are exact.
    # Output between grid points is a cubic Hermite interpolant: its own error is
    # h^4/384 max|y''''| <= h^4/384 sum_j |phi_ij| A_j omega_j^4.
    theta = ex.omega * run.extra["h_used"]
    with np.errstate(divide="ignore", invalid="ignore"):
        amp = np.hypot(ex.eta0, np.where(ex.zero, 0.0, ex.deta0 / np.where(ex.zero, 1.0, ex.omega)))
    amp = np.where(ex.zero, 0.0, amp)
    n = run.n_steps
    bound = np.abs(ex.phi) @ (amp * (n * theta**5 / 120 + theta**4 / 384))
    err = np.max(np.abs(run.y[: model.n_dof] - ex(t)[: model.n_dof]), axis=1)
    assert np.all(err <= 1.05 * bound + 1e-14)
    # ... and it is RK4's error, not a more accurate method's: the bound is reached
    # to within the phase mixing of several modes.
    assert np.max(err) >= 0.1 * np.max(bound)


# -- accuracy on nonlinear models against the real128 truth ------------------------------
@pytest.mark.parametrize("solver", ADAPTIVE)
@pytest.mark.parametrize("name", sorted(NONLINEAR))
def test_adaptive_tightest_matches_real128(name, solver, truth_dir):
    model, y0 = scene(name)
    t = np.linspace(0.0, 2.0, 41)
    truth = reference_solution(model, y0, t, path=truth_dir)
    assert truth.ok and truth.kind == "heyoka-real128"
    run = integrate(solver, model, y0, t, tightest(solver))
    assert run.status is Status.OK, run.message
    assert rel_error(model, run.y, truth.y) < 1e-10


@pytest.mark.parametrize("name", sorted(NONLINEAR))
def test_rk4_converges_at_order_4_to_real128(name, truth_dir):
    model, y0 = scene(name)
    t = np.linspace(0.0, 2.0, 41)
    truth = reference_solution(model, y0, t, path=truth_dir)
    h = 0.05 / omega_bound(model)
    e1 = rel_error(model, integrate("rk4", model, y0, t, h).y, truth.y)
    e2 = rel_error(model, integrate("rk4", model, y0, t, h / 2).y, truth.y)
    # Global error C h^4: halving h divides it by 2^4 = 16 (asymptotic range, far above round-off).
    assert e1 > 1e-11
    assert 12.0 < e1 / e2 < 20.0


# -- tolerance sweep: a mis-set atol shows as a plateau or a reversal --------------------
SWEEP = [1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10]


@pytest.mark.parametrize("solver", ADAPTIVE)
def test_tighter_tolerance_never_much_worse(solver):
    # Thesis case 1: millimetre amplitudes, where an absolute atol of 1e-6 (scikit-sundae's
    # default) or heyoka's unscaled absolute tol would stall the error.
    model, y0 = scene("chain-2dof")
    t = np.linspace(0.0, 5.0, 101)
    ex = modal_solution(model, y0)(t)
    errs = [rel_error(model, integrate(solver, model, y0, t, tol).y, ex) for tol in SWEEP]
    for i in range(len(SWEEP)):
        for j in range(i + 1, len(SWEEP)):
            assert errs[j] <= 10 * errs[i], (SWEEP[j], errs[j], SWEEP[i], errs[i])
    # Five decades of tolerance buy at least 2.5 decades of error for any method of
    # order >= 1 under tolerance proportionality (error ~ tol^(p/(p+1))).
    assert errs[-1] < 10**-2.5 * errs[0]


# -- counters ------------------------------------------------------------------------------
#: RHS calls (first step, each later step): stages, less the accelerations a
#: partitioned method never uses and the first-same-as-last reuse of Verlet.
CALLS = {"rk4": (4, 4), "euler": (1, 1), "symplectic-euler": (1, 1), "stormer-verlet": (2, 1),
         # the geometric built-ins (docs/geometric.md): first same as last saves one call per step
         "yoshida4": (4, 3), "yoshida6": (8, 7), "suzuki4": (6, 5), "forest-ruth": (3, 3), "blanes-moan4": (6, 6),
         "blanes-moan6": (10, 10)}


@pytest.mark.parametrize("solver", SOLVER_NAMES)
def test_stats_populated_and_plausible(solver):
    model, y0 = scene("chain-2dof")
    t = np.linspace(0.0, 1.0, 11)
    setting = 0.001 if solver in FIXED_STEP else 1e-8
    run = integrate(solver, model, y0, t, setting)
    assert isinstance(run, SolverRun) and run.status is Status.OK and run.ok
    assert run.y.shape == (4, 11) and np.all(np.isfinite(run.y))
    np.testing.assert_array_equal(run.y[:, 0], y0)
    np.testing.assert_array_equal(run.t, t)
    assert run.n_steps > 0 and run.wall_s >= 0.0 and run.message
    if solver in FIXED_STEP:
        assert run.n_steps == 1000  # ceil(1.0 / 0.001)
        first, per_step = CALLS[solver]
        assert run.nfev == first + per_step * (run.n_steps - 1)
        assert run.atol is None
    elif solver == "heyoka":
        assert run.nfev == 0 and run.taylor_order >= 10
        assert run.atol > 0
    else:
        # One RHS call per step at least (CVODE's Newton iteration / DOP853's 12 stages).
        assert run.nfev >= (12 if solver == "dop853" else 1) * run.n_steps
        assert run.atol == pytest.approx(1e-8 * 0.005)  # rtol * max|q0|, the documented rule


def test_heyoka_compiles_once_and_reuses():
    model, y0 = scene("oscillator2d")
    t = np.linspace(0.0, 1.0, 11)
    first = integrate("heyoka", model, y0, t, 3e-11)
    again = integrate("heyoka", model, 2 * y0, t, 3e-11)
    # the cached integrator's compile time, not 0: a run's one-run cost does not
    # depend on what ran before it in the process
    assert not first.extra["cached"] and again.extra["cached"]
    assert again.compile_s == first.compile_s > 0.0
    # The reused integrator is reset: a rerun reproduces the first run bit for bit.
    rerun = integrate("heyoka", model, y0, t, 3e-11)
    np.testing.assert_array_equal(rerun.y, first.y)
    assert rerun.n_steps == first.n_steps


def test_cvode_chain_jacobian_is_banded_and_exact():
    model, y0 = scene("chain-12")
    perm = interleave(model.n_dof)
    rows, cols, vals, lband, uband = linear_jacobian(model, perm)
    assert (lband, uband) == (3, 1)  # interleaved [x1, v1, x2, v2, ...]
    J = np.zeros((model.n_state, model.n_state))
    J[rows, cols] = vals
    np.testing.assert_allclose(J, model.jacobian()[np.ix_(perm, perm)], rtol=1e-15, atol=0)
    run = integrate("cvode-bdf", model, y0, np.linspace(0.0, 1.0, 5), 1e-8)
    assert run.extra["linsolver"] == "band" and run.status is Status.OK


# -- validation ------------------------------------------------------------------------------
@pytest.mark.parametrize("solver, setting, named", [
    ("rk5", 0.01, "solver"),
    ("rk4", 0.0, "h"),
    ("euler", -0.01, "h"),
    ("symplectic-euler", float("nan"), "h"),
    ("rk4", float("inf"), "h"),
    ("dop853", 0.0, "rtol"),
    ("cvode-adams", -1e-6, "rtol"),
    ("cvode-bdf", 1.0, "rtol"),
    ("heyoka", 2.0, "rtol"),
    ("heyoka", "1e-6", "rtol"),
])
def test_bad_setting_raises_naming_it(solver, setting, named):
    with pytest.raises(ValueError, match=named):
        check_setting(solver, setting)
    model, y0 = scene("chain-2dof")
    with pytest.raises(ValueError, match=named):
        integrate(solver, model, y0, [0.0, 1.0], setting)


@pytest.mark.parametrize("kwargs, named", [
    ({"y0": [0.0, 0.0, 0.0]}, "y0"),
    ({"t_eval": [0.0]}, "t_eval"),
    ({"t_eval": [0.0, 1.0, 1.0]}, "t_eval"),
    ({"t_eval": [[0.0, 1.0]]}, "t_eval"),
    ({"t_eval": ["start", "end"]}, "t_eval"),
    ({"t_eval": [0.0, float("nan")]}, "t_eval"),
    ({"y0": [float("nan"), 0.0, 0.0, 0.0]}, "y0"),
    ({"y0": "origin"}, "y0"),
    ({"atol": -1.0}, "atol"),
    ({"max_steps": 0}, "max_steps"),
])
def test_bad_arguments_raise_naming_them(kwargs, named):
    model, y0 = scene("chain-2dof")
    args = {"y0": y0, "t_eval": [0.0, 1.0], **kwargs}
    with pytest.raises(ValueError, match=named):
        integrate("cvode-bdf", model, args.pop("y0"), args.pop("t_eval"), 1e-6, **args)


# -- failures are statuses ---------------------------------------------------------------------
@pytest.mark.parametrize("solver", ["cvode-adams", "cvode-bdf"])
def test_cvode_step_cap_is_a_failed_status(solver):
    model, y0 = scene("chain-2dof")
    t = np.linspace(0.0, 10.0, 11)
    run = integrate(solver, model, y0, t, 1e-10, max_steps=20)
    assert run.status is Status.FAILED and "max_steps" in run.message
    assert run.n_steps == 20 and 0.0 < run.t_fail < 10.0
    assert np.all(np.isnan(run.y[:, -1])) and np.all(np.isfinite(run.y[:, 0]))


@pytest.mark.parametrize("solver", ["rk4", "euler"])
def test_fixed_step_blow_up_is_unstable(solver):
    # RK4 is stable on y'' = -w^2 y for w h <= 2 sqrt(2); explicit Euler never is.
    # w h = 20 makes |R| ~ 1e4 (RK4) or 20 (Euler) per step: overflow within ~80 / 240 steps.
    model, y0 = scene("chain-2dof")
    h = 20.0 / modal_solution(model, y0).omega.max()
    t = h * np.arange(0, 401)
    run = integrate(solver, model, y0, t, h)
    assert run.status is Status.UNSTABLE and run.t_fail is not None
    assert np.all(np.isnan(run.y[:, -1])) and np.all(np.isfinite(run.y[:, 0]))


class _Broken(rk4h.models.Chain):
    """A model whose equations raise (stand-in for any exception inside a solver)."""

    def rhs(self, t, y):
        if t > 0.25:
            raise ArithmeticError("broken rhs")
        return super().rhs(t, y)

    def _force(self, q, ops):
        if q.dtype == object:
            raise ArithmeticError("broken heyoka force")
        return super()._force(q, ops)


@pytest.mark.parametrize("solver", SOLVER_NAMES)
def test_exception_inside_is_a_failed_status(solver):
    model = _Broken(masses=[1.0, 2.0], springs=[10.0, 20.0, 30.0])
    y0 = model.state([0.01, 0.0])
    run = integrate(solver, model, y0, np.linspace(0.0, 1.0, 5), 0.01 if solver in FIXED_STEP else 1e-6)
    assert run.status is Status.FAILED and "broken" in run.message
    assert np.all(np.isnan(run.y[:, -1]))


def test_dop853_records_scipy_rtol_floor():
    model, y0 = scene("oscillator2d")
    run = integrate("dop853", model, y0, np.linspace(0.0, 0.5, 3), 1e-15)
    assert run.status is Status.OK
    assert run.extra["rtol_used"] == 100 * np.finfo(float).eps  # scipy.integrate._ivp.rk: rtol >= 100 EPS
    assert "clipped" in run.message
