"""scipy's own ``solve_ivp`` driving rk4core's methods (:mod:`rk4h.ivp`),
and the ``solve_ivp`` gaps of :func:`rk4h.solve` found by scipy's
``test_ivp.py`` (issue 28, item 5): an infinite ``t_span`` end with a
terminal event, and an empty ``res.t``.

The problems, exact solutions and error bounds are those of
``tests/test_solve_ivp.py`` (scipy's ``test_ivp.py`` problems, with bounds
derived there, none fitted). The checks named after scipy's tests run
against both drivers; scipy's tests that only concern adaptive or implicit
solvers are listed in :data:`ADAPTIVE_ONLY` and skipped by name, with the
reason.
"""
from __future__ import annotations

import numpy as np
import pytest
import test_solve_ivp as base
from numpy.testing import assert_allclose, assert_array_equal, assert_equal
from scipy.integrate import OdeSolver, solve_ivp

import rk4h
from rk4h import ivp
from rk4h.methods import rk_step
from rk4h.solver import REFUSED_OPTIONS

EPS = np.finfo(float).eps
CLASSICAL = sorted(m for m in rk4h.METHODS if not rk4h.METHODS[m].partitioned)
PARTITIONED = sorted(m for m in rk4h.METHODS if rk4h.METHODS[m].partitioned)


def via_scipy(fun, t_span, y0, method="rk4", **kw):
    """scipy's solve_ivp with rk4core's method as its OdeSolver."""
    return solve_ivp(fun, t_span, y0, method=ivp.solver_class(method), **kw)


def via_rk4core(fun, t_span, y0, method="rk4", **kw):
    return rk4h.solve(fun, t_span, y0, method=method, **kw)


DRIVERS = {"solve_ivp+rk4h.ivp": via_scipy, "rk4h.solve": via_rk4core}


def close(a, b, scale=1.0):
    """Equal to 1e-12 relative to ``scale`` (the size of the state)."""
    assert_allclose(np.asarray(a), np.asarray(b), rtol=0, atol=1e-12 * scale)


def oscillator(t, y):  # y = [q, v], a = -q: for the partitioned methods too
    return np.array([y[1], -y[0]])


# -- the two drivers agree -----------------------------------------------------------------------

SCIPY_PROBLEMS = [
    ("rational-forward", base.fun_rational, (5.0, 9.0), [1 / 3, 2 / 9], 0.01),
    ("rational-backward", base.fun_rational, (5.0, 1.0), [1 / 3, 2 / 9], 0.01),
    ("linear", base.fun_linear, (0.0, 10.0), [0.0, 2.0], 0.01),
    ("complex", base.fun_complex, (0.0, 1.0), [0.5 + 1j], 0.05),
    ("lsoda", base.fun_event_dense_output_LSODA, (-2.0, 2.0), [np.exp(2.0)], 0.05),
]


@pytest.mark.parametrize("method", CLASSICAL)
@pytest.mark.parametrize("fun, t_span, y0, h", [c[1:] for c in SCIPY_PROBLEMS], ids=[c[0] for c in SCIPY_PROBLEMS])
def test_scipy_driver_equals_rk4core_solve(fun, t_span, y0, h, method):
    a = via_scipy(fun, t_span, y0, method, h=h)
    b = via_rk4core(fun, t_span, y0, method, h=h)
    assert a.status == b.status == 0
    assert a.t.shape == b.t.shape
    close(a.t, b.t, max(abs(t_span[0]), abs(t_span[1])))
    close(a.y, b.y, np.max(np.abs(b.y)))
    assert a.nfev == b.nfev == rk4h.nfev_count(rk4h.METHODS[method], b.n_steps)


@pytest.mark.parametrize("method", PARTITIONED)
@pytest.mark.parametrize("t_span", [(0.0, 3.0), (3.0, 0.0)], ids=["forward", "backward"])
def test_scipy_driver_equals_rk4core_solve_partitioned(method, t_span):
    a = via_scipy(oscillator, t_span, [1.0, 0.0], method, h=0.01, dense_output=True)
    b = via_rk4core(oscillator, t_span, [1.0, 0.0], method, h=0.01, dense_output=True)
    close(a.t, b.t, 3.0)
    close(a.y, b.y)
    tc = np.linspace(*t_span, 37)
    close(a.sol(tc), b.sol(tc))


@pytest.mark.parametrize("method", ["rk4", "rk38", "euler", "stormer-verlet"])
@pytest.mark.parametrize("t_span", [(5.0, 9.0), (9.0, 5.0)], ids=["forward", "backward"])
def test_dense_output_and_events_equal_rk4core_solve(method, t_span):
    fun = base.fun_rational
    y0 = [1 / 3, 2 / 9] if t_span[0] == 5.0 else [4 / 9, 20 / 81]
    if rk4h.METHODS[method].partitioned:
        fun, y0 = oscillator, [1.0, 0.0]
    events = (base.event_rational_1, base.event_rational_2) if fun is base.fun_rational else (
        lambda t, y: y[0], lambda t, y: y[1])
    a = via_scipy(fun, t_span, y0, method, h=0.05, dense_output=True, events=events)
    b = via_rk4core(fun, t_span, y0, method, h=0.05, dense_output=True, events=events)
    close(a.y, b.y)
    tc = np.linspace(*t_span, 101)
    close(a.sol(tc), b.sol(tc))
    assert [te.size for te in a.t_events] == [te.size for te in b.t_events]
    assert sum(te.size for te in b.t_events) > 0
    for ta, tb, ya, yb in zip(a.t_events, b.t_events, a.y_events, b.y_events):
        close(ta, tb, 9.0)
        close(ya, yb)


def test_uneven_h_lands_on_t_bound_with_a_shorter_last_step():
    # 1 / 0.3: three steps of 0.3, then one of 0.1 (rk4h.solve would take 4 steps of 0.25)
    calls = []

    def fun(t, y):
        calls.append(t)
        return base.fun_linear(t, y)

    a = via_scipy(fun, (0.0, 1.0), [0.0, 2.0], h=0.3)
    assert_array_equal(a.t, [0.0, 0.3, 0.6, 0.8999999999999999, 1.0])
    assert max(calls) == 1.0
    y = np.array([0.0, 2.0])
    k = np.empty((4, 2))
    for t, t_next in zip(a.t[:-1], a.t[1:]):
        step = 0.3 if t_next < 1.0 else 1.0 - t
        y = rk_step(base.fun_linear, t, y, step, rk4h.RK4, k)
    assert_array_equal(a.y[:, -1], y)


# -- infinite t_span ---------------------------------------------------------------------------------

def _hit_ground(t, y):
    return y[0]


_hit_ground.terminal = True
_hit_ground.direction = -1


def _ball(t, y):
    return np.array([y[1], -9.81])


@pytest.mark.parametrize("driver", DRIVERS)
@pytest.mark.parametrize("dense_output", [False, True])
def test_infinite_span_ends_at_the_terminal_event(driver, dense_output):
    # A ball thrown up at 10 m/s lands at t* = 20 / 9.81; RK4 is exact on a quadratic.
    res = DRIVERS[driver](_ball, (0.0, np.inf), [0.0, 10.0], h=0.01, events=_hit_ground, dense_output=dense_output)
    t_star = 20 / 9.81
    assert res.status == 1 and res.success
    assert res.t[-1] == res.t_events[0][0]
    assert abs(res.t_events[0][0] - t_star) <= 8 * EPS * t_star
    assert_allclose(res.y_events[0][0], [0.0, -10.0], atol=1e-12)
    # the grid points 0, 0.01, ..., 2.03 (t* / h = 203.9), then t*
    assert np.all(np.diff(res.t) > 0) and res.t.shape == (204 + 1,)
    if dense_output:
        close(res.sol(1.0), [10 - 9.81 / 2, 10 - 9.81], 10.0)


@pytest.mark.parametrize("driver", DRIVERS)
@pytest.mark.parametrize("method", ["rk4", "stormer-verlet"])
def test_infinite_span_with_t_eval(driver, method):
    # output times past the event are not reached; those before it are the interpolant's
    t_eval = [0.5, 1.005, 2.0, 3.0, 100.0]
    res = DRIVERS[driver](_ball, (0.0, np.inf), [0.0, 10.0], method, h=0.01, events=_hit_ground, t_eval=t_eval)
    assert res.status == 1
    assert_array_equal(res.t, t_eval[:3])
    exact = np.array([[10 * t - 9.81 * t * t / 2 for t in t_eval[:3]], [10 - 9.81 * t for t in t_eval[:3]]])
    # RK4 and Stormer-Verlet are exact under a constant acceleration, and so is the cubic Hermite interpolant
    assert_allclose(res.y, exact, rtol=0, atol=1e-12)
    other = via_rk4core if driver != "rk4h.solve" else via_scipy
    close(res.y, other(_ball, (0.0, np.inf), [0.0, 10.0], method, h=0.01, events=_hit_ground, t_eval=t_eval).y)


@pytest.mark.parametrize("driver", DRIVERS)
def test_infinite_span_backward(driver):
    def at_minus_1_5(t, y):
        return t + 1.5

    at_minus_1_5.terminal = True
    res = DRIVERS[driver](_ball, (0.0, -np.inf), [0.0, 10.0], h=0.01, events=at_minus_1_5)
    assert res.status == 1
    assert abs(res.t[-1] + 1.5) <= 8 * EPS * 1.5 and np.all(np.diff(res.t) < 0)
    assert_allclose(res.y[:, -1], [-15 - 9.81 * 1.5 ** 2 / 2, 10 + 9.81 * 1.5], rtol=1e-12)


@pytest.mark.parametrize("driver", DRIVERS)
def test_infinite_span_without_an_event_stops_at_max_steps(driver):
    never = (lambda t, y: 1.0)
    never.terminal = True
    res = DRIVERS[driver](_ball, (0.0, np.inf), [0.0, 10.0], h=0.01, events=never, max_steps=250)
    assert res.status == -1 and not res.success
    assert "max_steps = 250" in res.message
    assert res.t[-1] == pytest.approx(2.5, abs=1e-12)
    assert res.t.shape == (251,)


def test_infinite_span_refused_without_a_terminal_event():
    with pytest.raises(ValueError, match="terminal event") as info:
        rk4h.solve(_ball, (0.0, np.inf), [0.0, 10.0], h=0.01)
    assert "\n" not in str(info.value)
    with pytest.raises(ValueError, match="`h`"):
        rk4h.solve(_ball, (0.0, np.inf), [0.0, 10.0], n_steps=10, events=_hit_ground)
    with pytest.raises(ValueError, match="`max_steps`"):
        rk4h.solve(_ball, (0.0, np.inf), [0.0, 10.0], h=0.01, events=_hit_ground, max_steps=0)


# -- empty results -------------------------------------------------------------------------------------

@pytest.mark.parametrize("driver", DRIVERS)
@pytest.mark.parametrize("dense_output", [False, True])
def test_t_eval_early_event(driver, dense_output):
    # scipy's test_t_eval_early_event: no t_eval point is reached
    def early_event(t, y):
        return t - 7

    early_event.terminal = True
    res = DRIVERS[driver](base.fun_rational, [5, 9], [1 / 3, 2 / 9], h=0.01, t_eval=np.linspace(7.5, 9, 16),
                          events=early_event, dense_output=dense_output)
    assert res.success and res.status == 1
    assert res.message == "A termination event occurred."
    assert not res.t and not res.y  # scipy's own assertion
    assert len(res.t) == 0
    assert len(res.t_events) == 1 and res.t_events[0].size == 1
    assert abs(res.t_events[0][0] - 7) <= 8 * EPS * 7


def test_empty_t_is_an_ndarray_that_is_false():
    def early_event(t, y):
        return t - 7

    early_event.terminal = True
    res = rk4h.solve(base.fun_rational, [5, 9], [1 / 3, 2 / 9], h=0.01, t_eval=[8.0], events=early_event)
    assert isinstance(res.t, np.ndarray) and res.t.shape == (0,) and res.y.shape == (2, 0)
    assert not bool(res.t)
    full = rk4h.solve(base.fun_rational, [5, 9], [1 / 3, 2 / 9], h=0.01, t_eval=[6.0])
    assert type(full.t) is np.ndarray  # a non-empty output is a plain ndarray


# -- options -----------------------------------------------------------------------------------------

@pytest.mark.parametrize("name", sorted(REFUSED_OPTIONS))
def test_tolerance_options_refused_by_name(name):
    with pytest.raises(ValueError, match=f"`{name}` does not apply to rk4h.ivp") as info:
        solve_ivp(base.fun_linear, (0, 1), [0.0, 2.0], method=ivp.RK4, h=0.1, **{name: 1e-3})
    assert "\n" not in str(info.value)


@pytest.mark.parametrize("kw, match", [({}, "`h` is required"), ({"h": 0.1, "colour": 1}, "`colour`"),
                                       ({"h": -0.1}, "`h` = -0.1 is negative"), ({"h": 0.0}, "`h`"),
                                       ({"h": 0.1, "max_steps": 0}, "`max_steps`")])
def test_bad_options_refused(kw, match):
    t_span = (0.0, np.inf) if "max_steps" in kw else (0.0, 1.0)
    with pytest.raises(ValueError, match=match):
        solve_ivp(base.fun_linear, t_span, [0.0, 2.0], method=ivp.RK4, **kw)


def test_factory_names_and_tableaux():
    assert ivp.RK4.tableau is rk4h.RK4
    assert issubclass(ivp.RK4, OdeSolver)
    for name, tab in rk4h.METHODS.items():
        assert ivp.solver_class(name).tableau is tab
    with pytest.raises(ValueError, match="`method`"):
        ivp.solver_class("rk45")
    with pytest.raises(ValueError, match="even length"):
        solve_ivp(oscillator, (0, 1), [1.0, 0.0, 2.0], method=ivp.STORMER_VERLET, h=0.1)


# -- scipy's test_ivp.py, test by test -------------------------------------------------------------

#: scipy's tests (scipy/integrate/_ivp/tests/test_ivp.py, 1.17.1) that only
#: concern adaptive or implicit solvers, with the reason they do not apply.
ADAPTIVE_ONLY = {
    "test_integration_sparse_difference": "jac_sparsity of the implicit solvers (refused: explicit methods)",
    "test_integration_const_jac": "passes jac (refused); the problem runs without it in tests/test_solve_ivp.py",
    "test_integration_stiff": "Robertson / van der Pol with Radau, BDF, LSODA: stiff, for implicit methods",
    "test_max_step": "max_step steers an adaptive step (refused)",
    "test_first_step": "first_step of an adaptive step (refused)",
    "test_array_rtol": "rtol (refused): no error estimate",
    "test_inital_maxstep": "scipy's initial step-size selection (adaptive)",
    "test_num_jac": "scipy's numerical Jacobian helper; no solver runs",
    "test_num_jac_sparse": "scipy's numerical Jacobian helper; no solver runs",
    "test_ConstantDenseOutput": "scipy's ConstantDenseOutput class alone; no solver runs",
    "test_initial_state_finiteness": "solve_ivp's own y0 check, before any solver is built",
    "test_classes": "checks step_size and the error-controlled attributes of RK23 ... LSODA",
}


def _scipy_test_integration(drive):
    for t_span in ([5, 9], [5, 1]):
        res = drive(base.fun_rational, t_span, [1 / 3, 2 / 9], h=0.05, dense_output=True)
        assert_equal(res.t[0], t_span[0]) and assert_equal(res.t[-1], t_span[-1])
        assert res.t_events is None and res.success and res.status == 0
        assert res.njev == 0 and res.nlu == 0
        b = base.bounds(base.RATIONAL, res.t)
        assert np.all(np.max(np.abs(res.y - base.sol_rational(res.t)), axis=0) <= b.E)
        tc = np.linspace(*t_span)
        assert np.all(np.max(np.abs(res.sol(tc) - base.sol_rational(tc)), axis=0) <= b.dense(tc))


def _scipy_test_integration_complex(drive):
    for t_span in ([0, 1], [1, 0]):
        res = drive(base.fun_complex, t_span, base.exact(base.COMPLEX, t_span[0])[:, 0], h=0.05, dense_output=True)
        assert res.success and res.y.dtype == np.complex128
        b = base.bounds(base.COMPLEX, res.t)
        assert np.all(np.abs(res.y[0] - base.sol_complex(res.t)[0]) <= b.E)


def _scipy_test_duplicate_timestamps(drive):
    def upward_cannon(t, y):
        return [y[1], -9.80665]

    res = drive(upward_cannon, [0, np.inf], [0, 0.01], h=1e-4, events=_with_dir(-1), dense_output=True)
    assert_allclose(res.sol(0.01), np.asarray([-0.00039033, -0.08806632]), rtol=1e-5, atol=1e-8)
    assert_allclose(res.t_events, np.asarray([[0.00203943]]), rtol=1e-5, atol=1e-8)
    assert_allclose(res.y_events, [np.asarray([[0.0, -0.01]])], atol=1e-9)
    assert res.success and res.status == 1


def _with_dir(direction):
    def hit_ground(t, y):
        return y[0]

    hit_ground.terminal = True
    hit_ground.direction = direction
    return hit_ground


def _scipy_test_events(drive):
    for direction, t_span, y0, counts in [c[1:] for c in base.EVENT_CASES]:
        e1 = base._with(base.event_rational_1, direction=direction)
        e2 = base._with(base.event_rational_2, direction=direction)
        res = drive(base.fun_rational, t_span, y0, h=0.05, events=(e1, e2))
        assert res.status == 0
        b = base.bounds(base.RATIONAL, res.t)
        for ev, te, count in zip((e1, e2), res.t_events, counts):
            assert te.size == count
            for t_e, t_star in zip(te, base.exact_events(base.RATIONAL, ev, t_span, direction)):
                assert abs(t_e - t_star) <= b.event(ev, t_star)


def _scipy_test_event_terminal_integer(drive):
    for n_events in (3, 4):
        def event(t, y):
            return y[0]

        event.terminal = n_events
        res = drive(lambda t, y: np.array([y[1], -y[0]]), (0, 100), [1.0, 0.0], h=0.01, events=event)
        assert len(res.t_events[0]) == n_events and res.status == 1


def _scipy_test_event_terminal_iv(drive):
    def event(t, y):
        return y[0]

    for terminal in (-1, "1", 1.5):
        event.terminal = terminal
        with pytest.raises(ValueError, match="The `terminal` attribute"):
            drive(lambda t, y: np.array([y[1], -y[0]]), (0, 1), [1.0, 0.0], h=0.01, events=event)


def _scipy_test_t_eval(drive):
    for t_span, t_eval in [([5, 9], [5, 6, 7, 8, 9]), ([5, 9], [5.5, 6.3, 8.9]), ([9, 5], [8.5, 6.1, 5])]:
        y0 = [1 / 3, 2 / 9] if t_span[0] == 5 else [4 / 9, 20 / 81]
        res = drive(base.fun_rational, t_span, y0, h=0.05, t_eval=t_eval)
        assert_equal(res.t, t_eval) and res.success
        assert res.y.shape == (2, len(t_eval))


def _scipy_test_t_eval_dense_output(drive):
    t_eval = np.linspace(5, 9, 10)
    res = drive(base.fun_rational, [5, 9], [1 / 3, 2 / 9], h=0.05, t_eval=t_eval)
    res_d = drive(base.fun_rational, [5, 9], [1 / 3, 2 / 9], h=0.05, t_eval=t_eval, dense_output=True)
    assert_equal(res.t, t_eval)
    close(res.y, res_d.y)
    close(res_d.sol(t_eval), res.y)


def _scipy_test_t_eval_early_event(drive):
    def early_event(t, y):
        return t - 7

    early_event.terminal = True
    res = drive(base.fun_rational, [5, 9], [1 / 3, 2 / 9], h=0.01, t_eval=np.linspace(7.5, 9, 16),
                events=early_event)
    assert res.success and res.status == 1 and res.message == "A termination event occurred."
    assert not res.t and not res.y
    assert len(res.t_events) == 1 and res.t_events[0].size == 1 and abs(res.t_events[0][0] - 7) <= 8 * EPS * 7


def _scipy_test_event_dense_output_LSODA(drive):
    def event_lsoda(t, y):
        return y[0] - 2.02e-5

    t_span = [-2, 2]
    y0 = base.exact(base.LSODA, t_span[0])[:, 0]  # scipy's [0.05], to the last bit
    res = drive(base.fun_event_dense_output_LSODA, t_span, y0, h=0.05, dense_output=True, events=event_lsoda)
    assert_equal(res.t[0], t_span[0]) and assert_equal(res.t[-1], t_span[-1])
    assert res.success and res.status == 0
    b = base.bounds(base.LSODA, res.t)
    assert np.all(np.abs(res.y[0] - base.sol_event_dense_output_LSODA(res.t)) <= b.E)
    tc = np.linspace(*t_span)
    assert np.all(np.abs(res.sol(tc)[0] - base.sol_event_dense_output_LSODA(tc)) <= b.dense(tc))
    assert_allclose(res.sol(res.t), res.y, rtol=1e-15, atol=1e-15)


def _scipy_test_no_integration(drive):
    res = drive(lambda t, y: -y, [4, 4], [2, 3], h=0.1, dense_output=True)
    assert_equal(res.sol(4), [2, 3])
    assert_equal(res.sol([4, 5, 6]), [[2, 2, 2], [3, 3, 3]])


def _scipy_test_no_integration_class(drive):
    if drive is via_rk4core:
        pytest.skip("an OdeSolver class test: only the rk4h.ivp classes are OdeSolvers")
    solver = ivp.RK4(lambda t, y: -y, 0.0, [10.0, 0.0], 0.0, h=0.1)
    solver.step()
    assert_equal(solver.status, "finished")
    sol = solver.dense_output()
    assert_equal(sol(0.0), [10.0, 0.0])
    assert_equal(sol([0, 1, 2]), [[10, 10, 10], [0, 0, 0]])


def _scipy_test_empty(drive):
    if drive is via_rk4core:
        pytest.skip("rk4h.solve refuses an empty y0 (documented difference)")
    for t_span in ([0, 10], [0, np.inf]):
        kw = {"events": _never_terminal(), "max_steps": 5} if np.isinf(t_span[1]) else {}
        res = drive(lambda t, y: np.zeros((0,)), t_span, np.zeros((0,)), h=1.0, dense_output=True, **kw)
        assert_equal(res.sol(10), np.zeros((0,)))
        assert_equal(res.sol([1, 2, 3]), np.zeros((0, 3)))


def _never_terminal():
    def never(t, y):
        return 1.0

    never.terminal = True
    return never


def _scipy_test_OdeSolution(drive):
    res = drive(base.fun_linear, (0, 2), [0.0, 2.0], h=0.1, dense_output=True)
    sol = res.sol
    assert sol.t_min == 0 and sol.t_max == 2
    assert_allclose(sol(res.t), res.y, rtol=0, atol=1e-15)
    assert sol(np.array([0.35, 1.42])).shape == (2, 2) and sol(0.35).shape == (2,)


def _scipy_test_args(drive):
    def fun(t, y, a, b):
        return np.array([-a * y[0], -b * y[1]])

    def ev(t, y, a, b):
        return y[0] - 0.5

    ev.terminal = True
    res = drive(fun, (0, 5), [1.0, 1.0], h=0.01, args=(1.0, 2.0), events=ev, dense_output=True)
    assert res.status == 1
    assert abs(res.t_events[0][0] - np.log(2)) <= 1e-9


def _scipy_test_integration_zero_rhs(drive):
    res = drive(base.fun_zero, [0, 10], np.ones(3), h=0.5)
    assert res.success and res.status == 0
    assert_allclose(res.y, 1.0, rtol=0, atol=0)


def _scipy_test_args_single_value(drive):
    def fun_with_arg(t, y, a):
        return a * y

    res = drive(fun_with_arg, (0, 0.1), [1], h=0.01, args=(-1,))
    assert_allclose(res.y[0, -1], np.exp(-0.1), rtol=1e-9)


def _scipy_test_zero_interval(drive):
    res = drive(lambda t, y: 2 * y, (0.0, 0.0), np.array([1.0]), h=0.1)
    assert res.success
    assert_allclose(res.y[0, -1], 1.0)


def _scipy_test_tbound_respected_small_interval(drive):
    small = 1e-4

    def f(t, y):
        if t > small:
            raise ValueError("Function was evaluated outside interval")
        return 2 * y

    assert drive(f, (0.0, small), np.array([1.0]), h=3e-5).success


def _scipy_test_tbound_respected_oscillator(drive):
    def reactions(t, y):
        if t > 205:
            raise ValueError("Called outside interval")
        return np.array([1.73307544e-02, 6.49376470e-06, 0.0, 0.0])

    res = drive(reactions, (100.0, 200.0), np.array([134.08298555, 138.82348612, 100.0, 0.0]), h=7.0,
                dense_output=True)
    assert res.success


def _scipy_test_tbound_respected_larger_interval(drive):
    def V(r):
        return -11 / r + 10 * r / (0.05 + r ** 2)

    def func(t, p):
        if t < -17 or t > 2:
            raise ValueError("Function was evaluated outside interval")
        r = np.exp(t)
        return np.array([r * p[1], -2.0 * r * ((-0.2 - V(r)) * p[0] + 1 / r * p[1])])

    assert drive(func, (-17, 2), np.array([1.0, -11.0]), h=0.03).success


SCIPY_CHECKS = {name[len("_scipy_"):]: fn for name, fn in dict(globals()).items() if name.startswith("_scipy_test_")}


@pytest.mark.parametrize("driver", DRIVERS)
@pytest.mark.parametrize("name", sorted(SCIPY_CHECKS) + sorted(ADAPTIVE_ONLY))
def test_scipy_test_ivp(name, driver):
    if name in ADAPTIVE_ONLY:
        pytest.skip(f"scipy's {name}: {ADAPTIVE_ONLY[name]}")
    SCIPY_CHECKS[name](DRIVERS[driver])


def test_every_scipy_test_is_run_or_listed():
    """Every test function of the installed scipy's test_ivp.py is adapted
    here or listed in ADAPTIVE_ONLY (so a new scipy test is noticed)."""
    import ast
    import importlib.util
    import pathlib

    spec = importlib.util.find_spec("scipy.integrate._ivp")
    path = pathlib.Path(spec.submodule_search_locations[0]) / "tests" / "test_ivp.py"
    if not path.exists():
        pytest.skip("scipy installed without its tests")
    names = {n.name for n in ast.parse(path.read_text()).body
             if isinstance(n, ast.FunctionDef) and n.name.startswith("test_")}
    missing = names - set(SCIPY_CHECKS) - set(ADAPTIVE_ONLY)
    assert not missing, f"scipy tests neither adapted nor listed: {sorted(missing)}"
    assert not set(SCIPY_CHECKS) & set(ADAPTIVE_ONLY)
