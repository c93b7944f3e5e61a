"""Tests of ``rk4h.solve`` and the methods' tableaux.

Expected values come from theory, stated beside each test: the order of each
method, the amplification factor of RK4 and Euler on a harmonic mode, the
quadrature rule RK4 reduces to on ``y' = p(t)`` (Simpson's rule), and the
contract of docs/user-guide.md (scipy ``solve_ivp`` conventions).
"""
import math
import warnings

import numpy as np
import pytest

import rk4h
from rk4h.references.exact import modal_solution

# -- observed order on every linear model ------------------------------------

# (id, model name, params, x0, v0). The free chain has a net momentum, so its
# zero mode translates; the others start from a generic (non-modal) state.
LINEAR_CASES = [
    ("chain-2dof-case1", "chain", {"masses": [0.815, 3.099], "springs": [41.5, 138.0, 157.8]},
     [0.005, 0.005], [0.0, 0.0]),
    ("chain-N5-walls", "chain", {"masses": [0.5] * 5, "springs": [20.0] * 6},
     [0.01, -0.02, 0.0, 0.015, 0.005], [0.0, 0.1, -0.05, 0.0, 0.02]),
    ("chain-free-translating", "chain", {"masses": [1.0, 2.0, 1.5], "springs": [10.0, 20.0], "walls": "none"},
     [0.01, 0.0, -0.02], [0.3, 0.1, 0.05]),
    ("three-blocks", "chain", {"masses": [1.0] * 3, "springs": [4.0] * 4},
     [0.02, 0.0, 0.01], [0.0, 0.05, 0.0]),
    ("co2", "chain", {"masses": [16.0, 12.0, 16.0], "springs": [5.0, 5.0], "walls": "none"},
     [0.01, 0.0, -0.005], [0.0, 0.02, 0.0]),
    ("oscillator2d-isotropic", "oscillator2d", {"m": 0.5, "kx": 20.0, "ky": 20.0},
     [0.01, 0.0], [0.0, 0.1]),
    ("oscillator2d-anisotropic", "oscillator2d", {"m": 0.5, "kx": 80.0, "ky": 20.0},
     [0.01, 0.005], [0.05, 0.1]),
    ("planar4-linear", "planar4", {"m": 0.5, "k": 25.0, "l": 0.01, "linear": True},
     [0.003, -0.002], [0.0, 0.05]),
    ("pendulums-linear", "pendulums", {"m": 0.2, "length": 0.5, "g": 9.81, "k": 1.0, "linear": True},
     [0.1, 0.0], [0.0, 0.0]),
]

# Step ranges in theta = omega_max * h over one period of the fastest mode.
# RK4: global error ~ (2 pi / theta) theta^5 / 120 ~ 0.05 theta^4 of the
# amplitude, from 5e-6 at theta = 0.1 down to 1e-9 at 0.0125: asymptotic (the
# next term is relative O(theta^2)) and far above round-off (~1e-15).
# Euler / symplectic Euler: global error ~ (2 pi) theta / 2; the next term is
# relative O(2 pi theta), below 7% for theta <= 0.01, so the slope is 1 +- 0.05.
THETA_MAX = {"rk4": 0.1, "euler": 0.01, "symplectic-euler": 0.01}
EXPECTED_ORDER = {"rk4": 4, "euler": 1, "symplectic-euler": 1}


def fitted_order(hs, errs):
    """Least-squares slope of log(err) against log(h)."""
    return np.polyfit(np.log(hs), np.log(errs), 1)[0]


@pytest.mark.parametrize("method", ["rk4", "euler", "symplectic-euler"])
@pytest.mark.parametrize("case", LINEAR_CASES, ids=[c[0] for c in LINEAR_CASES])
def test_observed_order_on_linear_models(case, method):
    _, name, params, x0, v0 = case
    model = rk4h.make_model(name, params)
    y0 = model.state(x0, v0)
    exact = modal_solution(model, y0)
    w_max = exact.omega.max()
    t_end = 2 * np.pi / w_max
    hs = THETA_MAX[method] / w_max / 2.0 ** np.arange(4)
    used, errs = [], []
    for h in hs:
        res = rk4h.solve(model.rhs, (0.0, t_end), y0, h=h, method=method)
        assert res.success
        used.append(res.h)  # the step actually used, t_end / ceil(t_end / h)
        errs.append(np.max(np.abs(res.y - exact(res.t))))
    p = fitted_order(used, errs)
    assert abs(p - EXPECTED_ORDER[method]) < 0.1, (p, errs)


# -- energy on a single harmonic mode ----------------------------------------

def single_mode(m=2.0, k1=8.0, k2=10.0):
    """One mass between two walls: x'' = -omega^2 x, omega^2 = (k1 + k2) / m."""
    return rk4h.make_model("chain", {"masses": [m], "springs": [k1, k2]}), math.sqrt((k1 + k2) / m)


def harmonic_energy(y, omega):
    """Scaled energy (omega^2 x^2 + v^2) / 2 (= E / m)."""
    return 0.5 * (omega**2 * y[0] ** 2 + y[1] ** 2)


# For x'' = -omega^2 x, one step maps z = omega x + i v to R(i theta) z, so (omega x, v)
# is rotated and scaled by |R(i theta)| and the energy is multiplied by
# |R(i theta)|^2, every step, exactly:
# * RK4: R(w) = 1 + w + w^2/2 + w^3/6 + w^4/24, |R|^2 = (1 - theta^2/2 + theta^4/24)^2
#   + (theta - theta^3/6)^2 = 1 - theta^6/72 + theta^8/576 (below 2 sqrt 2 it decays,
#   above it grows: theta = 3.0 is past RK4's stability limit);
# * explicit Euler: R(w) = 1 + w, |R|^2 = 1 + theta^2 (it grows for every h).
ENERGY_FACTOR = {
    "rk4": lambda theta: 1 - theta**6 / 72 + theta**8 / 576,
    "euler": lambda theta: 1 + theta**2,
}
ENERGY_CASES = [("rk4", th) for th in (0.05, 0.3, 1.0, 2.0, 2.8, 3.0)] + [("euler", th) for th in (0.05, 0.5, 1.5)]


@pytest.mark.parametrize("method, theta", ENERGY_CASES)
def test_energy_follows_amplification_factor(method, theta):
    model, omega = single_mode()
    h, n = theta / omega, 200
    y0 = model.state([0.3], [0.7])
    # The growing cases (RK4 at theta = 3, Euler) pass 1e8 times the initial
    # amplitude within 200 steps; the growth test is off so the run follows
    # the amplification factor all the way (the factor, not the stop, is tested).
    res = rk4h.solve(model.rhs, (0.0, n * h), y0, n_steps=n, method=method, max_growth=None)
    assert res.success
    expected = harmonic_energy(y0, omega) * ENERGY_FACTOR[method](theta) ** np.arange(n + 1)
    np.testing.assert_allclose(harmonic_energy(res.y, omega), expected, rtol=1e-9, atol=0)


@pytest.mark.parametrize("theta", [0.05, 0.5, 1.5])
def test_symplectic_euler_conserves_modified_energy(theta):
    # v' = v - h omega^2 x, x' = x + h v' has step matrix M = [[1 - theta^2, h],
    # [-h omega^2, 1]] (det 1) and M^T Q M = Q for Q = [[omega^2, -h omega^2 / 2],
    # [-h omega^2 / 2, 1]]: the modified energy omega^2 x^2 + v^2 - h omega^2 x v
    # is conserved exactly, so the true energy stays bounded (|theta| < 2).
    model, omega = single_mode()
    h, n = theta / omega, 2000
    y0 = model.state([0.3], [0.7])
    res = rk4h.solve(model.rhs, (0.0, n * h), y0, n_steps=n, method="symplectic-euler")
    x, v = res.y
    q_mod = omega**2 * x**2 + v**2 - h * omega**2 * x * v
    np.testing.assert_allclose(q_mod, q_mod[0], rtol=1e-12, atol=0)
    # Q_mod is within a factor (1 +- theta/2) of 2E, so E stays in that band.
    e = harmonic_energy(res.y, omega)
    e0 = q_mod[0] / 2
    assert np.all(e <= e0 / (1 - theta / 2) * (1 + 1e-12))
    assert np.all(e >= e0 / (1 + theta / 2) * (1 - 1e-12))


# -- stage times: y' = p(t) ----------------------------------------------------

CUBICS = [(1.0, 0.0, 0.0, 0.0), (0.0, 1.0, 0.0, 0.0), (0.0, 0.0, 1.0, 0.0), (0.0, 0.0, 0.0, 1.0),
          (0.3, -1.2, 2.5, -0.7)]


@pytest.mark.parametrize("coef", CUBICS, ids=[str(c) for c in CUBICS])
def test_rk4_integrates_cubics_exactly(coef):
    # On y' = p(t), RK4 is Simpson's rule on each step (stages at t, t+h/2,
    # t+h/2, t+h with weights 1/6, 1/3, 1/3, 1/6): exact for cubics. With wrong
    # stage times (e.g. all at t) a linear p would already fail.
    p = np.polynomial.Polynomial(coef)
    t0, t1, n = 0.3, 2.1, 7
    res = rk4h.solve(lambda t, y: np.array([p(t)]), (t0, t1), [0.5], n_steps=n)
    expected = 0.5 + p.integ()(res.t) - p.integ()(t0)
    np.testing.assert_allclose(res.y[0], expected, rtol=1e-13, atol=1e-13)


@pytest.mark.parametrize("n", [1, 4, 16])
def test_rk4_quartic_error_is_simpson_error(n):
    # Simpson's rule error on one step: S - I = h^5 / 2880 * p''''; for
    # p = t^4, p'''' = 24, so each step adds h^5 / 120 and n steps n h^5 / 120.
    t0, t1 = 0.0, 1.5
    h = (t1 - t0) / n
    res = rk4h.solve(lambda t, y: np.array([t**4]), (t0, t1), [0.0], n_steps=n)
    err = res.y[0, -1] - (t1**5 - t0**5) / 5
    assert err == pytest.approx(n * h**5 / 120, rel=1e-10)


def test_euler_exact_for_constants_only():
    # Euler is the left Riemann sum: exact for p = c; for p = t it misses
    # sum over steps of h^2 / 2, i.e. n h^2 / 2 = (t1 - t0) h / 2.
    t0, t1, n = 0.0, 2.0, 8
    h = (t1 - t0) / n
    const = rk4h.solve(lambda t, y: np.array([3.0]), (t0, t1), [1.0], n_steps=n, method="euler")
    np.testing.assert_allclose(const.y[0], 1.0 + 3.0 * const.t, rtol=1e-14)
    lin = rk4h.solve(lambda t, y: np.array([t]), (t0, t1), [0.0], n_steps=n, method="euler")
    assert t1**2 / 2 - lin.y[0, -1] == pytest.approx((t1 - t0) * h / 2, rel=1e-12)


def test_rk4_step_is_fourth_order_taylor_polynomial():
    # On y' = lam y, one RK4 step multiplies by R(lam h) = sum_{j<=4} (lam h)^j / j!:
    # checks that stage states use A (not only stage times use c).
    lam, h = -1.7, 0.4
    res = rk4h.solve(lambda t, y: lam * y, (0.0, h), [1.0], n_steps=1)
    z = lam * h
    assert res.y[0, -1] == pytest.approx(sum(z**j / math.factorial(j) for j in range(5)), rel=1e-15)


# -- contract -----------------------------------------------------------------

def decay(t, y):
    return -y


@pytest.mark.parametrize("t_span, h, n_expected, h_used", [
    ((0.0, 1.0), 0.1, 10, 0.1),
    ((0.0, 1.0), 0.3, 4, 0.25),          # ceil(3.33) = 4, step actually used 1/4
    ((0.0, 1.0), 1.0 / 3.0, 3, 1.0 / 3.0),
    ((0.0, 1.0), 2.0, 1, 1.0),           # larger than the span: one step
    ((0.1, 0.4), 0.1, 3, 0.1),           # (0.4 - 0.1) / 0.1 = 3.0000000000000004: slack
    ((0.0, 16.1), 0.001, 16100, 0.001),  # 16.1 / 0.001 = 16100.000000000002: slack
    ((0.0, 1.0), 0.1 * (1 - 1e-13), 10, 0.1),   # ratio 10 (1 + 1e-13), within the slack
])
def test_step_count_from_h(t_span, h, n_expected, h_used):
    res = rk4h.solve(decay, t_span, [1.0], h=h, method="euler")  # cheapest; the count is method-independent
    assert res.n_steps == n_expected
    assert res.h == pytest.approx(h_used, rel=1e-12)
    assert res.t.shape == (n_expected + 1,)
    assert res.t[0] == t_span[0] and res.t[-1] == t_span[1]


def test_step_count_just_beyond_slack_adds_a_step():
    # (t1 - t0) / h = 10 * (1 + 1e-9): more than the 1e-12 slack, so 11 steps.
    res = rk4h.solve(decay, (0.0, 1.0), [1.0], h=0.1 / (1 + 1e-9))
    assert res.n_steps == 11


# Symplectic Euler's second stage only supplies the velocity v_{n+1}: its
# acceleration is used by nothing and is not evaluated (one call per step).
@pytest.mark.parametrize("method, stages", [("rk4", 4), ("euler", 1), ("symplectic-euler", 1)])
def test_nfev_counts_every_call(method, stages):
    calls = []

    def fun(t, y):
        calls.append(t)
        return np.array([y[1], -y[0]])

    res = rk4h.solve(fun, (0.0, 2.0), [1.0, 0.0], n_steps=25, method=method)
    assert res.nfev == len(calls) == stages * 25


def test_nfev_counts_dense_output_calls():
    # Off-grid outputs need the slope at the step's end: one extra call per step
    # that holds one or more of them.
    calls = []

    def fun(t, y):
        calls.append(t)
        return -y

    t_eval = [0.05, 0.07, 0.35, 1.0]  # h = 0.1: steps 0 (two points) and 3 hold off-grid points
    res = rk4h.solve(fun, (0.0, 1.0), [1.0], h=0.1, t_eval=t_eval)
    assert res.dense == "hermite"
    assert res.nfev == len(calls) == 4 * 10 + 2


@pytest.mark.parametrize("n_dim", [1, 3])
def test_shapes_follow_solve_ivp(n_dim):
    res = rk4h.solve(lambda t, y: -y, (0.0, 1.0), np.ones(n_dim), n_steps=8)
    assert res.t.shape == (9,)
    assert res.y.shape == (n_dim, 9)
    assert res.success and res.status == 0
    np.testing.assert_allclose(res.t, np.linspace(0.0, 1.0, 9), rtol=0, atol=1e-15)


def test_t_eval_on_grid_returns_grid_values_exactly():
    model, _ = single_mode()
    y0 = model.state([0.3], [0.7])
    full = rk4h.solve(model.rhs, (0.0, 2.0), y0, h=0.02)
    t_eval = [0.0, 0.1, 0.5, 1.3, 2.0]  # multiples of 0.02 up to representation error
    res = rk4h.solve(model.rhs, (0.0, 2.0), y0, h=0.02, t_eval=t_eval)
    assert res.dense == "grid"
    np.testing.assert_array_equal(res.t, t_eval)
    idx = np.rint(np.array(t_eval) / 0.02).astype(int)
    np.testing.assert_array_equal(res.y, full.y[:, idx])


def test_t_eval_off_grid_hermite_error_is_fourth_order():
    # Between steps the cubic Hermite interpolant has local error h^4/384 y''''
    # on top of RK4's O(h^4) global error: the error at mid-step points is O(h^4).
    model, omega = single_mode()
    y0 = model.state([0.3], [0.7])
    exact = modal_solution(model, y0)
    t_end = 2 * np.pi / omega
    hs = 0.2 / omega / 2.0 ** np.arange(4)
    t_eval = np.linspace(0.0, t_end, 4)[1:-1] + 0.37 * hs[0]  # off every grid
    used, errs = [], []
    for h in hs:
        res = rk4h.solve(model.rhs, (0.0, t_end), y0, h=h, t_eval=t_eval)
        assert res.dense == "hermite"
        np.testing.assert_array_equal(res.t, t_eval)
        used.append(res.h)
        errs.append(np.max(np.abs(res.y - exact(t_eval))))
    assert abs(fitted_order(used, errs) - 4) < 0.15, errs


def test_blow_up_is_a_status_not_an_exception():
    # y' = y^2, y(0) = 1 has y = 1 / (1 - t): infinite at t = 1. RK4 follows it
    # until y h ~ 1, then y_{n+1} ~ (h y_n)^3 y_n / 24 overflows within a few steps.
    h = 0.01
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        res = rk4h.solve(lambda t, y: y * y, (0.0, 2.0), [1.0], h=h)
    assert not res.success
    assert res.status == -1
    assert 1.0 - 5 * h <= res.t_fail <= 1.0 + 10 * h
    assert f"{res.t_fail:.6g}" in res.message
    assert np.all(np.isfinite(res.y))
    assert res.y.shape == (1, res.n_steps + 1)
    assert res.t[-1] == pytest.approx(res.t_fail - h, rel=1e-12)
    assert res.n_steps < 200


def test_blow_up_with_t_eval_returns_points_before_failure():
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        res = rk4h.solve(lambda t, y: y * y, (0.0, 2.0), [1.0], h=0.01, t_eval=[0.5, 0.905, 1.5, 2.0])
    assert res.status == -1
    np.testing.assert_array_equal(res.t, [0.5, 0.905])
    assert np.all(np.isfinite(res.y))


def test_division_by_zero_in_fun_is_a_blow_up():
    # planar4 with the mass on an anchor: spring length 0, direction undefined.
    model = rk4h.make_model("planar4", {"m": 1.0, "k": 1.0, "l": 1.0})
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        res = rk4h.solve(model.rhs, (0.0, 1.0), model.state([1.0, 0.0]), n_steps=4)
    assert res.status == -1 and res.t_fail == 0.25 and res.n_steps == 0


BAD_ARGS = [
    ("h and n_steps", dict(h=0.1, n_steps=10), "n_steps"),
    ("neither", dict(), "n_steps"),
    ("h zero", dict(h=0.0), "`h`"),
    ("h negative", dict(h=-0.1), "`h`"),
    ("h nan", dict(h=float("nan")), "`h`"),
    ("h bool", dict(h=True), "`h`"),
    ("n_steps zero", dict(n_steps=0), "`n_steps`"),
    ("n_steps float", dict(n_steps=2.5), "`n_steps`"),
    ("y0 nan", dict(h=0.1, y0=[1.0, np.nan]), "`y0`"),
    ("y0 inf", dict(h=0.1, y0=[np.inf]), "`y0`"),
    ("y0 2-D", dict(h=0.1, y0=[[1.0, 2.0]]), "`y0`"),
    ("y0 empty", dict(h=0.1, y0=[]), "`y0`"),
    ("y0 text", dict(h=0.1, y0="ab"), "`y0`"),
    # t1 == t0 (no step) and t1 < t0 (backward) are valid since issue 15: tests/test_solve_ivp.py
    ("h negative, span forward", dict(h=-0.1, t_span=(0.0, 1.0)), "`h` = -0.1 is negative"),
    ("t_span three items", dict(h=0.1, t_span=(0.0, 1.0, 2.0)), "`t_span`"),
    ("t_span inf", dict(h=0.1, t_span=(0.0, np.inf)), "t_span"),
    ("t_span scalar", dict(h=0.1, t_span=1.0), "`t_span`"),
    ("t_eval below", dict(h=0.1, t_eval=[-0.1, 0.5]), "`t_eval`"),
    ("t_eval above", dict(h=0.1, t_eval=[0.5, 1.1]), "`t_eval`"),
    ("t_eval decreasing", dict(h=0.1, t_eval=[0.5, 0.2]), "`t_eval`"),
    ("t_eval nan", dict(h=0.1, t_eval=[np.nan]), "`t_eval`"),
    ("method unknown", dict(h=0.1, method="rk45"), "`method`"),
    ("symplectic odd length", dict(h=0.1, method="symplectic-euler", y0=[1.0, 2.0, 3.0]), "`y0`"),
]


@pytest.mark.parametrize("kwargs, name", [c[1:] for c in BAD_ARGS], ids=[c[0] for c in BAD_ARGS])
def test_bad_arguments_raise_value_error_naming_them(kwargs, name):
    kwargs = dict(kwargs)
    y0 = kwargs.pop("y0", [1.0, 0.0])
    t_span = kwargs.pop("t_span", (0.0, 1.0))
    with pytest.raises(ValueError, match=name.replace("[", r"\[")) as info:
        rk4h.solve(lambda t, y: -y, t_span, y0, **kwargs)
    assert "\n" not in str(info.value)


@pytest.mark.parametrize("name", sorted(rk4h.METHODS))
def test_methods_are_consistent_tableaux(name):
    # Row sums of A equal c (a stage's time matches its state) and each set of
    # weights sums to 1 (consistency: order >= 1). For the partitioned method
    # the velocity rows need not sum to c: stage 2's velocity slope has weight 0.
    tab = rk4h.METHODS[name]
    np.testing.assert_allclose(tab.A.sum(axis=1), tab.c, atol=0)
    assert tab.b.sum() == pytest.approx(1.0, rel=1e-15)
    if tab.partitioned:
        assert tab.b_v.sum() == pytest.approx(1.0, rel=1e-15)
