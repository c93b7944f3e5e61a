"""``rk4h.solve`` as a superset of ``scipy.integrate.solve_ivp`` (issue 15).

The problems, exact solutions and event functions are scipy's own, from
``scipy/integrate/_ivp/tests/test_ivp.py`` (scipy 1.17.1, the installed copy:
``python -c "import scipy, os; print(os.path.dirname(scipy.__file__))"``, then
``integrate/_ivp/tests/test_ivp.py``): ``fun_zero``, ``fun_linear`` /
``sol_linear``, ``fun_rational`` / ``fun_rational_vectorized`` /
``sol_rational``, ``fun_complex`` / ``sol_complex``,
``fun_event_dense_output_LSODA`` / ``sol_event_dense_output_LSODA``, the
event functions of ``test_events``, ``test_event_terminal_integer``,
``test_args`` and ``test_t_eval_early_event``. The tests adapted from there
keep scipy's names (``test_integration``, ``test_events``, ``test_args``,
``test_t_eval``, ``test_t_eval_dense_output``, ``test_no_integration``,
``test_OdeSolution``, ...) with ``h`` added; scipy's ``rtol``/``atol``-based
checks are replaced by error bounds of the fixed-step method, derived below.

Error bounds (no tolerance is fitted to the results)
----------------------------------------------------
* Grid values: the "Lady Windermere's fan" bound (Hairer, Norsett, Wanner,
  *Solving ODEs I*, sec. II.3, Thm. 3.4): ``|y_j - y(t_j)| <= sum_{i<j}
  exp(L |t_j - t_{i+1}|) le_i + j 4 eps max|y|``, where ``le_i`` is the local
  error of one classical RK4 step (implemented here independently, from the
  thesis' formula) started on the exact solution -- ``O(h^5)``, so the bound
  is ``C h^4`` with ``C`` made of the problem's derivatives --, ``L = 1.1 x
  max ||J||_inf`` along the exact solution (the 10 % covers the tube, of
  width far below 1e-6, the numerical solution stays in), and ``4 eps`` per
  step of round-off.
* Dense output inside step ``i`` (:mod:`rk4h.dense`): ``max(E_i, E_{i+1})
  (1 + |h| L / 4) + h^4 max|y''''| / 384``: the node errors (the Hermite
  weights of the states sum to 1, those of the slopes to at most 1/4), plus
  the cubic Hermite interpolation error of the exact solution.
* Event times: ``|t_e - t*| <= 1.01 |grad_y g|_1 D / |dG/dt| + 8 eps
  max(1, |t*|)`` with ``G(t) = g(t, y(t))``, ``D`` the dense bound at ``t*``
  (the 1 % covers the second-order term of the linearisation, of relative
  size ``|t_e - t*|`` < 1e-6), the last term brentq's tolerance.

Each bound is ``O(h^4)`` -- the order of the dense output's global error with
RK4 (continuous extension of order 3, local error ``O(h^4)``). Separate
tests check that order directly (the error ratio when ``h`` halves).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pytest
from numpy.testing import assert_allclose, assert_array_equal
from scipy.integrate import DenseOutput, OdeSolution
from scipy.optimize import brentq

import rk4h
from rk4h.dense import HermiteSolution
from rk4h.solver import REFUSED_OPTIONS, ArgsError

EPS = np.finfo(float).eps


# -- scipy's problems (scipy/integrate/_ivp/tests/test_ivp.py) -----------------------------------

def fun_zero(t, y):
    return np.zeros_like(y)


def fun_linear(t, y):
    return np.array([-y[0] - 5 * y[1], y[0] + y[1]])


def jac_linear(t=None, y=None):
    return np.array([[-1, -5], [1, 1]])


def sol_linear(t):
    return np.vstack((-5 * np.sin(2 * t), 2 * np.cos(2 * t) + np.sin(2 * t)))


def fun_rational(t, y):
    return np.array([y[1] / t, y[1] * (y[0] + 2 * y[1] - 1) / (t * (y[0] - 1))])


def fun_rational_vectorized(t, y):
    return np.vstack((y[1] / t, y[1] * (y[0] + 2 * y[1] - 1) / (t * (y[0] - 1))))


def jac_rational(t, y):
    return np.array([[0, 1 / t],
                     [-2 * y[1] ** 2 / (t * (y[0] - 1) ** 2), (y[0] + 4 * y[1] - 1) / (t * (y[0] - 1))]])


def sol_rational(t):
    return np.asarray((t / (t + 10), 10 * t / (t + 10) ** 2))


def fun_complex(t, y):
    return -y


def sol_complex(t):
    y = (0.5 + 1j) * np.exp(-t)
    return y.reshape((1, -1))


def fun_event_dense_output_LSODA(t, y):
    return y * (t - 2)


def sol_event_dense_output_LSODA(t):
    return np.exp(t ** 2 / 2 - 2 * t + np.log(0.05) - 6)


# -- the fourth derivatives the dense bound needs (by hand from the exact solutions) ------------

def d4_linear(t):  # every term of sol_linear has angular frequency 2
    return 16 * sol_linear(t)


def d4_rational(t):  # y0 = 1 - 10/(t+10), y1 = 10/(t+10) - 100/(t+10)^2
    s = t + 10
    return np.asarray((-240 / s ** 5, 240 / s ** 5 - 12000 / s ** 6))


def d4_complex(t):
    return sol_complex(t)


def d4_lsoda(t):  # y = exp(u^2/2 + c), u = t - 2: y'''' = (u^4 + 6 u^2 + 3) y
    u = t - 2
    return (u ** 4 + 6 * u ** 2 + 3) * sol_event_dense_output_LSODA(t)


@dataclass(frozen=True)
class Problem:
    name: str
    fun: object
    sol: object   # t (m,) -> (n, m)
    jac: object   # (t, y) -> (n, n)
    d4: object    # t (m,) -> (n, m)


RATIONAL = Problem("rational", fun_rational, sol_rational, jac_rational, d4_rational)
LINEAR = Problem("linear", fun_linear, sol_linear, jac_linear, d4_linear)
COMPLEX = Problem("complex", fun_complex, sol_complex, lambda t, y: -np.eye(1), d4_complex)
LSODA = Problem("lsoda", fun_event_dense_output_LSODA, lambda t: np.atleast_2d(sol_event_dense_output_LSODA(t)),
                lambda t, y: np.array([[t - 2.0]]), lambda t: np.atleast_2d(d4_lsoda(t)))


def exact(p: Problem, t) -> np.ndarray:
    """Exact solution at the times ``t`` (shape (m,)): shape (n, m)."""
    t = np.atleast_1d(np.asarray(t, dtype=float))
    return np.asarray(p.sol(t)).reshape(-1, t.shape[0])


def rk4_step(fun, t, y, h):
    """Classical RK4 as in the thesis: stages at t, t + h/2, t + h/2, t + h;
    weights 1/6, 1/3, 1/3, 1/6 (independent of rk4core's tableau code)."""
    k1 = np.asarray(fun(t, y))
    k2 = np.asarray(fun(t + h / 2, y + h / 2 * k1))
    k3 = np.asarray(fun(t + h / 2, y + h / 2 * k2))
    k4 = np.asarray(fun(t + h, y + h * k3))
    return y + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)


@dataclass
class Bounds:
    """Error bounds of one RK4 run on the grid ``t`` (module docstring)."""
    t: np.ndarray      # the run's grid
    E: np.ndarray      # bound at each grid point
    L: float           # Lipschitz constant used
    M4: float          # max |y''''| over the span
    p: Problem

    def dense(self, tc) -> np.ndarray:
        """Bound on the dense output's error at the times ``tc``."""
        tc = np.atleast_1d(tc)
        t = self.t
        asc = t[-1] >= t[0]
        ts = t if asc else t[::-1]
        i = np.clip(np.searchsorted(ts, tc) - 1, 0, t.shape[0] - 2)
        if not asc:
            i = t.shape[0] - 2 - i
        d = np.abs(t[i + 1] - t[i])
        return np.maximum(self.E[i], self.E[i + 1]) * (1 + d * self.L / 4) + d ** 4 * self.M4 / 384

    def event(self, g, t_star) -> float:
        """Bound on ``|t_e - t*|`` for the event function ``g`` at the exact
        event time ``t_star``."""
        y = exact(self.p, t_star)[:, 0]
        n = y.shape[0]
        step = 1e-6 * max(1.0, float(np.max(np.abs(y))))
        grad = [(g(t_star, y + step * e) - g(t_star, y - step * e)) / (2 * step) for e in np.eye(n)]
        dt = 1e-6 * max(1.0, abs(t_star))
        dG = (g(t_star + dt, exact(self.p, t_star + dt)[:, 0]) - g(t_star - dt, exact(self.p, t_star - dt)[:, 0])) / (
            2 * dt)
        D = float(self.dense(np.array([t_star]))[0])
        return 1.01 * float(np.sum(np.abs(grad))) * D / abs(dG) + 8 * EPS * max(1.0, abs(t_star))


def bounds(p: Problem, t) -> Bounds:
    """Fan bound of an RK4 run on the grid ``t`` (module docstring)."""
    Y = exact(p, t)
    m = t.shape[0]
    le = np.zeros(m - 1)
    for i in range(m - 1):
        y1 = rk4_step(p.fun, t[i], Y[:, i], t[i + 1] - t[i])
        le[i] = np.max(np.abs(y1 - Y[:, i + 1]))
    tt = np.linspace(min(t[0], t[-1]), max(t[0], t[-1]), 2001)
    YY = exact(p, tt)
    L = 1.1 * max(np.max(np.sum(np.abs(np.atleast_2d(p.jac(ti, YY[:, j]))), axis=1)) for j, ti in enumerate(tt))
    ymax = float(np.max(np.abs(YY)))
    E = np.zeros(m)
    for j in range(1, m):
        E[j] = np.sum(np.exp(L * np.abs(t[j] - t[1: j + 1])) * le[:j]) + j * 4 * EPS * ymax
    M4 = float(np.max(np.abs(p.d4(tt))))
    return Bounds(t=np.asarray(t, dtype=float), E=E, L=L, M4=M4, p=p)


def exact_events(p: Problem, g, t_span, direction=0) -> np.ndarray:
    """Zeros of ``G(t) = g(t, y(t))`` on the exact solution, in the direction
    of integration, by brentq on a scan of 4001 points (independent of rk4core)."""
    lo, hi = sorted(t_span)
    tt = np.linspace(lo, hi, 4001)
    Y = exact(p, tt)
    G = np.array([g(ti, Y[:, j]) for j, ti in enumerate(tt)])
    roots = []
    for j in range(tt.shape[0] - 1):
        if G[j] == 0 or G[j] * G[j + 1] < 0:
            # rising in time t if G goes up; "direction" refers to the direction of integration
            rising = G[j + 1] > G[j]
            if t_span[1] < t_span[0]:
                rising = not rising
            if direction == 0 or (direction > 0) == rising:
                roots.append(brentq(lambda s: g(s, exact(p, s)[:, 0]), tt[j], tt[j + 1], xtol=1e-15, rtol=4 * EPS))
    roots = np.array(roots)
    return roots if t_span[1] >= t_span[0] else roots[::-1]


# -- test_integration and friends ------------------------------------------------------------------

@pytest.mark.parametrize("h", [0.1, 0.05])
@pytest.mark.parametrize("t_span", [(5.0, 9.0), (5.0, 1.0)], ids=["forward", "backward"])
@pytest.mark.parametrize("vectorized", [False, True], ids=["scalar-fun", "vectorized"])
def test_integration(vectorized, t_span, h):
    fun = fun_rational_vectorized if vectorized else fun_rational
    calls = []

    def counted(t, y):
        calls.append(t)
        return fun(t, y)

    y0 = [1 / 3, 2 / 9]
    res = rk4h.solve(counted, t_span, y0, h=h, dense_output=True, vectorized=vectorized)
    assert res.t[0] == t_span[0] and res.t[-1] == t_span[1]
    assert res.t_events is None and res.y_events is None
    assert res.success and res.status == 0
    assert res.njev == 0 and res.nlu == 0
    n = res.n_steps
    assert n == round(abs(t_span[1] - t_span[0]) / h)
    # 4 calls per step and the end slope f(t1, y_N) of the last interpolant
    assert res.nfev == len(calls) == 4 * n + 1
    assert min(calls) >= min(t_span) and max(calls) <= max(t_span)

    b = bounds(RATIONAL, res.t)
    err = np.max(np.abs(res.y - sol_rational(res.t)), axis=0)
    assert np.all(err <= b.E), f"grid error {err.max():.3g} over the fan bound {b.E.max():.3g}"
    tc = np.linspace(*t_span)
    err_c = np.max(np.abs(res.sol(tc) - sol_rational(tc)), axis=0)
    assert np.all(err_c <= b.dense(tc)), f"dense error {err_c.max():.3g} over {b.dense(tc).max():.3g}"
    tm = (t_span[0] + t_span[-1]) / 2
    assert np.max(np.abs(res.sol(tm) - sol_rational(tm))) <= b.dense(tm)[0]
    assert_array_equal(res.sol(res.t), res.y)  # the interpolant passes through the grid values, bit for bit


@pytest.mark.parametrize("t_span", [(0.0, 1.0), (1.0, 0.0)], ids=["forward", "backward"])
def test_integration_complex(t_span):
    h = 0.05
    y0 = sol_complex(np.array([t_span[0]]))[:, 0]
    res = rk4h.solve(fun_complex, t_span, y0, h=h, dense_output=True)
    assert res.y.dtype == np.complex128 and res.sol(0.5).dtype == np.complex128
    assert res.success and res.status == 0 and res.njev == 0 and res.nlu == 0
    assert res.t_events is None and res.y_events is None
    b = bounds(COMPLEX, res.t)
    err = np.abs(res.y - sol_complex(res.t))[0]
    assert np.all(err <= b.E)
    assert np.all(np.abs(res.y.imag) > 0.1)  # the imaginary part is integrated, not dropped
    tc = np.linspace(*t_span)
    assert np.all(np.abs(res.sol(tc) - sol_complex(tc))[0] <= b.dense(tc))
    # RK4 on y' = -y is y_N = R(-h)^N y0 exactly, R(z) = 1 + z + z^2/2 + z^3/6 + z^4/24
    z = -res.h
    R = 1 + z + z ** 2 / 2 + z ** 3 / 6 + z ** 4 / 24
    assert_allclose(res.y[0], y0[0] * R ** np.arange(res.t.shape[0]), rtol=50 * EPS * res.n_steps, atol=0)


@pytest.mark.parametrize("kw", [{}, {"dense_output": True}, {"t_eval": [0.0, 3.3, 10.0]}], ids=["grid", "dense", "t_eval"])
def test_integration_zero_rhs(kw):
    result = rk4h.solve(fun_zero, [0, 10], np.ones(3), h=0.5, **kw)
    assert result.success and result.status == 0
    assert_array_equal(result.y, 1.0)
    if result.sol is not None:
        assert_array_equal(result.sol(np.linspace(-1, 11, 7)), 1.0)


def test_integration_const_jac():
    # scipy's problem (y0 = [0, 2] on [0, 2]); for a linear problem RK4 is
    # y_N = R(h A)^N y0 exactly, so the grid is checked to round-off as well.
    h = 0.02
    res = rk4h.solve(fun_linear, [0, 2], [0, 2], h=h, dense_output=True)
    assert res.success and res.njev == 0 and res.nlu == 0
    A = jac_linear() * res.h
    R = np.eye(2) + A + A @ A / 2 + A @ A @ A / 6 + A @ A @ A @ A / 24
    ys = [np.array([0.0, 2.0])]
    for _ in range(res.n_steps):
        ys.append(R @ ys[-1])
    assert_allclose(res.y, np.array(ys).T, rtol=0, atol=100 * EPS * res.n_steps)
    b = bounds(LINEAR, res.t)
    assert np.all(np.max(np.abs(res.y - sol_linear(res.t)), axis=0) <= b.E)
    tc = np.linspace(0, 2)
    assert np.all(np.max(np.abs(res.sol(tc) - sol_linear(tc)), axis=0) <= b.dense(tc))
    assert_array_equal(res.sol(res.t), res.y)


@pytest.mark.parametrize("t_span", [(-2.0, 2.0), (2.0, -2.0)], ids=["forward", "backward"])
def test_event_dense_output_LSODA(t_span):
    def event_lsoda(t, y):
        return y[0] - 2.02e-5

    h = 0.05
    y0 = [float(sol_event_dense_output_LSODA(t_span[0]))]
    res = rk4h.solve(fun_event_dense_output_LSODA, t_span, y0, h=h, dense_output=True, events=event_lsoda)
    assert res.t[0] == t_span[0] and res.t[-1] == t_span[-1]
    assert abs(res.t[1] - res.t[0]) == pytest.approx(h, rel=1e-12)
    assert res.success and res.status == 0
    b = bounds(LSODA, res.t)
    assert np.all(np.abs(res.y - sol_event_dense_output_LSODA(res.t))[0] <= b.E)
    tc = np.linspace(*t_span)
    assert np.all(np.abs(res.sol(tc) - sol_event_dense_output_LSODA(tc))[0] <= b.dense(tc))
    assert_array_equal(res.sol(res.t), res.y)
    t_star = exact_events(LSODA, event_lsoda, t_span)
    assert t_star.shape == (1,) and res.t_events[0].shape == (1,)
    assert abs(res.t_events[0][0] - t_star[0]) <= b.event(event_lsoda, t_star[0])


# -- events -----------------------------------------------------------------------------------------

def event_rational_1(t, y):
    return y[0] - y[1] ** 0.7


def event_rational_2(t, y):
    return y[1] ** 0.6 - y[0]


def event_rational_3(t, y):
    return t - 7.4


def _with(fun, **attrs):
    """A copy of the event function with attributes (scipy's tests set them
    on the module functions in turn)."""
    def ev(t, y):
        return fun(t, y)
    ev.__name__ = fun.__name__
    for k, v in attrs.items():
        setattr(ev, k, v)
    return ev


# (direction of events 1 and 2, t_span, y0, expected counts (e1, e2)): scipy's test_events
EVENT_CASES = [
    ("both-forward", 0, (5.0, 8.0), [1 / 3, 2 / 9], (1, 1)),
    ("rising-forward", 1, (5.0, 8.0), [1 / 3, 2 / 9], (1, 0)),
    ("falling-forward", -1, (5.0, 8.0), [1 / 3, 2 / 9], (0, 1)),
    ("both-backward", 0, (8.0, 5.0), [4 / 9, 20 / 81], (1, 1)),
    ("falling-backward", -1, (8.0, 5.0), [4 / 9, 20 / 81], (1, 0)),
    ("rising-backward", 1, (8.0, 5.0), [4 / 9, 20 / 81], (0, 1)),
]


@pytest.mark.parametrize("h", [0.1, 0.05])
@pytest.mark.parametrize("direction, t_span, y0, counts", [c[1:] for c in EVENT_CASES],
                         ids=[c[0] for c in EVENT_CASES])
def test_events(direction, t_span, y0, counts, h):
    e1 = _with(event_rational_1, direction=direction)
    e2 = _with(event_rational_2, direction=direction)
    res = rk4h.solve(fun_rational, t_span, y0, h=h, events=(e1, e2))
    assert res.status == 0 and res.success
    b = bounds(RATIONAL, res.t)
    for i, (ev, count) in enumerate(zip((e1, e2), counts)):
        assert res.t_events[i].size == count
        assert res.y_events[i].shape == ((count, 2) if count else (0,))
        t_star = exact_events(RATIONAL, ev, t_span, direction)
        assert t_star.size == count
        for te, ye, ts in zip(res.t_events[i], res.y_events[i], t_star):
            assert abs(te - ts) <= b.event(ev, ts), f"event {i}: |{te!r} - {ts!r}| over the bound"
            assert abs(ev(te, ye)) <= 1e-12  # y_events is the interpolant at the located root
            assert np.max(np.abs(ye - sol_rational(te))) <= b.dense(te)[0]


@pytest.mark.parametrize("t_span, y0, t_terminal", [((5.0, 8.0), [1 / 3, 2 / 9], 7.4),
                                                     ((8.0, 5.0), [4 / 9, 20 / 81], 7.4)],
                         ids=["forward", "backward"])
def test_events_terminal_with_dense_output(t_span, y0, t_terminal):
    e3 = _with(event_rational_3, terminal=True)
    h = 0.07  # 7.4 is not a grid point: the run stops inside a step
    calls = []

    def counted(t, y):
        calls.append(t)
        return fun_rational(t, y)

    res = rk4h.solve(counted, t_span, y0, h=h, events=(event_rational_1, event_rational_2, e3),
                        dense_output=True)
    assert res.status == 1 and res.success and res.message == "A termination event occurred."
    assert res.reason == "event"
    assert res.t_events[2].shape == (1,) and abs(res.t_events[2][0] - t_terminal) <= 8 * EPS * t_terminal
    assert res.t[-1] == res.t_events[2][0]  # the run ends at the event, as solve_ivp
    assert_array_equal(res.y[:, -1], res.y_events[2][0])
    assert np.all(np.abs(np.diff(res.t)[:-1]) == pytest.approx(abs(res.h), rel=1e-9))
    assert 0 < abs(res.t[-1] - res.t[-2]) < abs(res.h)
    # The last interpolant ends at the event; nothing was evaluated past the step that holds it.
    assert res.sol.t_max == max(res.t[0], res.t[-1]) and res.sol.t_min == min(res.t[0], res.t[-1])
    assert res.sol.n_segments == res.n_steps
    assert res.nfev == len(calls) == 4 * res.n_steps + 1
    past = [t for t in calls if (t - t_terminal) * (t_span[1] - t_span[0]) > 0]
    assert max(abs(t - t_terminal) for t in past) < h if past else True
    # Termination does not break the interpolants (scipy: "Also test that
    # termination by event doesn't break interpolants").
    b = bounds(RATIONAL, np.append(res.t[:-1], res.t[-2] + np.sign(t_span[1] - t_span[0]) * abs(res.h)))
    tc = np.linspace(res.t[0], res.t[-1])
    assert np.all(np.max(np.abs(res.sol(tc) - sol_rational(tc)), axis=0) <= b.dense(tc))
    for i, ev in enumerate((event_rational_1, event_rational_2)):
        t_star = exact_events(RATIONAL, ev, (t_span[0], res.t[-1]))
        assert res.t_events[i].size == t_star.size
        for te, ts in zip(res.t_events[i], t_star):
            assert abs(te - ts) <= b.event(ev, ts)


def _harmonic_oscillator():
    def f(t, y):
        return [y[1], -y[0]]

    def event(t, y):
        return y[0]

    def sol(t):
        t = np.atleast_1d(t)
        return np.vstack((np.cos(t), -np.sin(t)))

    return f, event, Problem("oscillator", f, sol, lambda t, y: np.array([[0.0, 1.0], [-1.0, 0.0]]), sol)


@pytest.mark.parametrize("n_events", [3, 4])
def test_event_terminal_integer(n_events):
    f, event, p = _harmonic_oscillator()
    event.terminal = n_events
    res = rk4h.solve(f, (0, 100), [1, 0], events=event, h=0.05)
    assert res.status == 1
    assert len(res.t_events[0]) == n_events and len(res.y_events[0]) == n_events
    assert_allclose(res.y_events[0][:, 0], 0, atol=1e-14)
    t_star = (np.arange(n_events) + 0.5) * np.pi
    b = bounds(p, res.t)
    for te, ts in zip(res.t_events[0], t_star):
        assert abs(te - ts) <= b.event(event, ts)
    assert res.t[-1] == res.t_events[0][-1]


def test_event_terminal_iv():
    f, event, _ = _harmonic_oscillator()
    call = (f, (0, 100), [1, 0])
    event.terminal = None
    res = rk4h.solve(*call, events=event, h=0.1)
    event.terminal = 0
    ref = rk4h.solve(*call, events=event, h=0.1)
    assert_allclose(res.t_events, ref.t_events)
    assert res.t_events[0].size == 32  # every zero of cos on [0, 100]
    for bad in (-1, 3.5, "yes"):
        event.terminal = bad
        with pytest.raises(ValueError, match="The `terminal` attribute...") as info:
            rk4h.solve(*call, events=event, h=0.1)
        assert "\n" not in str(info.value)


def test_event_on_a_grid_point_is_recorded_once():
    # A fixed grid lands on zeros: t - 5 is zero at grid point 10 of h = 0.5.
    # solve_ivp's find_active_events would record it at the end of one step
    # and again at the start of the next; rk4core records it once.
    def at_five(t, y):
        return t - 5.0

    res = rk4h.solve(fun_zero, (0.0, 10.0), [1.0], h=0.5, events=at_five)
    assert_array_equal(res.t_events[0], [5.0])
    # Backward, and as a terminal event: the run ends on the grid point, not duplicated.
    at_five.terminal = True
    res = rk4h.solve(fun_zero, (10.0, 0.0), [1.0], h=0.5, events=at_five, dense_output=True)
    assert_array_equal(res.t_events[0], [5.0])
    assert res.status == 1 and res.t[-1] == 5.0 and np.all(np.diff(res.t) < 0)
    assert res.sol.ts[-1] == 5.0 and np.all(np.diff(res.sol.ts) < 0)


def test_t_eval_early_event():
    def early_event(t, y):
        return t - 7

    early_event.terminal = True
    t_eval = np.linspace(7.5, 9, 16)
    res = rk4h.solve(fun_rational, [5, 9], [1 / 3, 2 / 9], h=0.1, t_eval=t_eval, events=early_event)
    assert res.success and res.status == 1
    assert res.message == "A termination event occurred."
    assert res.t.size == 0 and res.y.shape == (2, 0)
    assert len(res.t_events) == 1 and res.t_events[0].size == 1
    assert abs(res.t_events[0][0] - 7) <= 4 * EPS * 7


# -- t_eval -----------------------------------------------------------------------------------------

T_EVAL_CASES = [
    ("linspace-forward", (5.0, 9.0), list(np.linspace(5, 9, 10))),
    ("linspace-backward", (5.0, 1.0), list(np.linspace(5, 1, 10))),
    ("scipy-forward", (5.0, 9.0), [5, 5.01, 7, 8, 8.01, 9]),
    ("scipy-backward", (5.0, 1.0), [5, 4.99, 3, 1.5, 1.1, 1.01, 1]),
    ("inside-forward", (5.0, 9.0), [5.01, 7, 8, 8.01]),
    ("inside-backward", (5.0, 1.0), [4.99, 3, 1.5, 1.1, 1.01]),
]


@pytest.mark.parametrize("dense_output", [False, True])
@pytest.mark.parametrize("t_span, t_eval", [c[1:] for c in T_EVAL_CASES], ids=[c[0] for c in T_EVAL_CASES])
def test_t_eval(t_span, t_eval, dense_output):
    h = 0.1
    res = rk4h.solve(fun_rational, t_span, [1 / 3, 2 / 9], h=h, t_eval=t_eval, dense_output=dense_output)
    assert_array_equal(res.t, t_eval)
    assert res.t_events is None and res.success and res.status == 0
    grid = rk4h.solve(fun_rational, t_span, [1 / 3, 2 / 9], h=h)
    b = bounds(RATIONAL, grid.t)
    err = np.max(np.abs(res.y - sol_rational(res.t)), axis=0)
    assert np.all(err <= b.dense(res.t))


@pytest.mark.parametrize("t_eval, message", [([4, 6], "within"), ([9, 5], "increasing"), ([5.0, np.nan], "finite")])
def test_t_eval_refused(t_eval, message):
    with pytest.raises(ValueError, match=message):
        rk4h.solve(fun_rational, [5, 9], [1 / 3, 2 / 9], h=0.1, t_eval=t_eval)
    with pytest.raises(ValueError, match="decreasing"):
        rk4h.solve(fun_rational, [5, 1], [1 / 3, 2 / 9], h=0.1, t_eval=[2, 3])


@pytest.mark.parametrize("t_span", [(5.0, 9.0), (9.0, 5.0)], ids=["forward", "backward"])
@pytest.mark.parametrize("method", ["rk4", "rk38", "euler", "stormer-verlet"])
def test_t_eval_dense_output(t_span, method):
    # As scipy's test: with and without dense_output, the t_eval values are identical.
    t_eval = np.linspace(t_span[0], t_span[1], 10)
    y0 = list(sol_rational(t_span[0]))
    f = fun_rational if method != "stormer-verlet" else (lambda t, y: np.array([y[1], -y[0]]))
    res = rk4h.solve(f, t_span, y0, h=0.1, t_eval=t_eval, method=method)
    res_d = rk4h.solve(f, t_span, y0, h=0.1, t_eval=t_eval, dense_output=True, method=method)
    assert_array_equal(res.t, t_eval)
    assert_array_equal(res.t, res_d.t)
    assert_array_equal(res.y, res_d.y)
    assert res.dense == res_d.dense == "hermite"
    assert res_d.t_events is None and res_d.success and res_d.status == 0


# -- no integration, zero interval ------------------------------------------------------------------

@pytest.mark.parametrize("step", [{"h": 0.1}, {"h": -0.1}, {"n_steps": 5}], ids=["h", "h-negative", "n_steps"])
def test_no_integration(step):
    calls = []
    sol = rk4h.solve(lambda t, y: calls.append(t) or -y, [4, 4], [2, 3], dense_output=True, **step)
    assert_array_equal(sol.sol(4), [2, 3])
    assert_array_equal(sol.sol([4, 5, 6]), [[2, 2, 2], [3, 3, 3]])
    assert calls == [] and sol.nfev == 0 and sol.n_steps == 0 and sol.h == 0.0
    assert_array_equal(sol.t, [4.0]) and sol.success and sol.status == 0
    res = rk4h.solve(lambda t, y: 2 * y, (0.0, 0.0), np.array([1.0]), t_eval=[0.0, 0.0], **step)
    assert res.success and res.y[0, -1] == 1.0 and res.y.shape == (1, 2)  # scipy's test_zero_interval


# -- args, vectorized, complex ----------------------------------------------------------------------

def test_args():
    # scipy's test_args: (x, y) a linear oscillator, z a logistic equation;
    # the terminal event zfinal stops the run at tfinal.
    def sys3(t, w, omega, k, zfinal):
        x, y, z = w
        return [-omega * y, omega * x, k * z * (1 - z)]

    def sys3_jac(t, w, omega, k, zfinal):
        x, y, z = w
        return np.array([[0, -omega, 0], [omega, 0, 0], [0, 0, k * (1 - 2 * z)]])

    def sys3_x0decreasing(t, w, omega, k, zfinal):
        return w[0]

    def sys3_y0increasing(t, w, omega, k, zfinal):
        return w[1]

    def sys3_zfinal(t, w, omega, k, zfinal):
        return w[2] - zfinal

    sys3_x0decreasing.direction = -1
    sys3_y0increasing.direction = 1
    sys3_zfinal.terminal = True
    omega, k, tfinal, zfinal = 2, 4, 5, 0.99
    z0 = np.exp(-k * tfinal) / ((1 - zfinal) / zfinal + np.exp(-k * tfinal))
    w0 = [0, -1, z0]
    args = (omega, k, zfinal)
    tend = 2 * tfinal
    h = 0.01
    sol = rk4h.solve(sys3, [0, tend], w0, events=[sys3_x0decreasing, sys3_y0increasing, sys3_zfinal],
                        dense_output=True, args=args, h=h)
    assert sol.status == 1
    assert_allclose(sol.t_events[2], [tfinal], rtol=0, atol=1e-6)

    def exact_w(t):
        t = np.atleast_1d(t)
        return np.vstack((np.sin(omega * t), -np.cos(omega * t), 1 / (((1 - z0) / z0) * np.exp(-k * t) + 1)))

    def d4(t):
        t = np.atleast_1d(t)
        zz = exact_w(t)[2]
        # z' = k z (1 - z): z'''' = k^4 z (1 - z)(1 - 14 z + 36 z^2 - 24 z^3)
        return np.vstack((omega ** 4 * exact_w(t)[:2], k ** 4 * zz * (1 - zz) * (1 - 14 * zz + 36 * zz ** 2 - 24 * zz ** 3)))

    p = Problem("sys3", lambda t, w: np.array(sys3(t, w, *args)), exact_w, lambda t, w: sys3_jac(t, w, *args), d4)
    b = bounds(p, np.append(sol.t[:-1], sol.t[-2] + h))
    g_x = lambda t, w: sys3_x0decreasing(t, w, *args)  # noqa: E731
    g_y = lambda t, w: sys3_y0increasing(t, w, *args)  # noqa: E731
    g_z = lambda t, w: sys3_zfinal(t, w, *args)  # noqa: E731
    for te, ts in zip(sol.t_events[0], [0.5 * np.pi, 1.5 * np.pi], strict=True):
        assert abs(te - ts) <= b.event(g_x, ts)
    for te, ts in zip(sol.t_events[1], [0.25 * np.pi, 1.25 * np.pi], strict=True):
        assert abs(te - ts) <= b.event(g_y, ts)
    assert abs(sol.t_events[2][0] - tfinal) <= b.event(g_z, tfinal)
    t = np.linspace(0, sol.t_events[2][0], 250)
    assert np.all(np.max(np.abs(sol.sol(t) - exact_w(t)), axis=0) <= b.dense(t))
    assert_allclose(sol.sol(sol.t_events[0])[0], 0, atol=5e-14)
    assert_allclose(sol.sol(sol.t_events[1])[1], 0, atol=5e-14)
    assert_allclose(sol.sol(sol.t_events[2])[2], [zfinal], rtol=4 * EPS)


def test_args_single_value():
    def fun_with_arg(t, y, a):
        return a * y

    message = "Supplied 'args' cannot be unpacked."
    with pytest.raises(TypeError, match=message):
        rk4h.solve(fun_with_arg, (0, 0.1), [1], args=-1, h=0.01)
    with pytest.raises(ValueError, match="`args`") as info:  # ArgsError is both
        rk4h.solve(fun_with_arg, (0, 0.1), [1], args=-1, h=0.01)
    assert isinstance(info.value, ArgsError) and "\n" not in str(info.value)
    for args in ((-1,), [-1]):  # any iterable is unpacked, as solve_ivp
        sol = rk4h.solve(fun_with_arg, (0, 0.1), [1], args=args, h=0.01)
        # RK4 on y' = -y: y_N = R(-h)^N, |R(-h) - e^-h| <= h^5 / 120
        assert abs(sol.y[0, -1] - np.exp(-0.1)) <= 10 * 0.01 ** 5 / 120 + 10 * EPS


@pytest.mark.parametrize("kw", [{}, {"dense_output": True}, {"t_eval": [5.0, 6.05, 9.0]}],
                         ids=["grid", "dense", "t_eval"])
def test_vectorized_calls_fun_with_one_column(kw):
    shapes = []

    def fun(t, y):
        shapes.append(y.shape)
        return fun_rational_vectorized(t, y)

    res_v = rk4h.solve(fun, [5, 9], [1 / 3, 2 / 9], h=0.1, vectorized=True, **kw)
    res = rk4h.solve(fun_rational, [5, 9], [1 / 3, 2 / 9], h=0.1, **kw)
    assert set(shapes) == {(2, 1)}
    assert_array_equal(res_v.y, res.y)
    assert res_v.nfev == res.nfev
    # a vectorized fun may also return shape (n,); anything else is refused naming `fun`
    res_1d = rk4h.solve(lambda t, y: fun_rational(t, y[:, 0]), [5, 9], [1 / 3, 2 / 9], h=0.1, vectorized=True)
    assert_array_equal(res_1d.y, rk4h.solve(fun_rational, [5, 9], [1 / 3, 2 / 9], h=0.1).y)
    with pytest.raises(ValueError, match="`fun`"):
        rk4h.solve(lambda t, y: np.zeros((1, 2)), [5, 9], [1 / 3, 2 / 9], h=0.1, vectorized=True)


@pytest.mark.parametrize("kw", [{}, {"dense_output": True}, {"t_eval": [0.0, 0.37, 1.0]}],
                         ids=["grid", "dense", "t_eval"])
def test_complex_y0_kept_with_events_and_backward(kw):
    def real_part_crosses(t, y):
        return y[0].real - 0.25

    for t_span in [(0.0, 1.0), (1.0, 0.0)]:
        t_ev = dict(kw)
        if "t_eval" in t_ev and t_span[0] > t_span[1]:
            t_ev["t_eval"] = t_ev["t_eval"][::-1]
        y0 = sol_complex(np.array([t_span[0]]))[:, 0]
        res = rk4h.solve(fun_complex, t_span, y0, h=0.02, events=real_part_crosses, **t_ev)
        assert res.y.dtype == np.complex128 and res.y_events[0].dtype == np.complex128
        ts = np.log(2.0)  # 0.5 e^-t = 0.25
        grid = rk4h.solve(fun_complex, t_span, y0, h=0.02)
        b = bounds(COMPLEX, grid.t)
        assert res.t_events[0].shape == (1,)
        assert abs(res.t_events[0][0] - ts) <= b.event(real_part_crosses, ts)
        assert np.all(np.abs(res.y - sol_complex(res.t))[0] <= b.dense(res.t))


# -- backward integration ---------------------------------------------------------------------------

def _oscillator(t, y):
    """q'' = -4 q: autonomous and reversible (f(rho y) = -rho f(y), rho (q, v) = (q, -v))."""
    return np.array([y[1], -4.0 * y[0]])


def _forced(t, y):
    """A t-dependent, non-reversible right-hand side for the time-reversal map."""
    return np.array([y[1], -4.0 * y[0] - 0.3 * y[1] + np.cos(1.7 * t)])


@pytest.mark.parametrize("kw", [{}, {"dense_output": True}, {"t_eval": [3.0, 2.2, 1.1, 0.0]}],
                         ids=["grid", "dense", "t_eval"])
@pytest.mark.parametrize("method", sorted(m for m in rk4h.METHODS if not rk4h.METHODS[m].partitioned))
def test_backward_equals_time_reversed_forward(method, kw):
    # y' = f(t, y) from T down to 0 is z' = -f(-s, z) from -T up to 0 with
    # s = -t: the same arithmetic with every sign flipped, so the runs agree to
    # round-off (bit for bit in practice). (Not for a partitioned method: the
    # reversed problem's position slope is -v, not the dq/dt = v it assumes;
    # those are checked by the reversibility test below.)
    T, y0 = 3.0, np.array([0.3, -0.2])
    back = rk4h.solve(_forced, (T, 0.0), y0, h=0.01, method=method, **kw)

    def reversed_f(s, z):
        return -_forced(-s, z)

    kw_f = dict(kw)
    if "t_eval" in kw_f:
        kw_f["t_eval"] = [-t for t in kw_f["t_eval"]]
    fwd = rk4h.solve(reversed_f, (-T, 0.0), y0, h=0.01, method=method, **kw_f)
    assert back.h == -fwd.h and back.n_steps == fwd.n_steps and back.nfev == fwd.nfev
    assert_allclose(back.t, -fwd.t, rtol=0, atol=2 * EPS * T)
    assert_allclose(back.y, fwd.y, rtol=0, atol=4 * EPS * np.max(np.abs(fwd.y)))
    if back.sol is not None:
        tc = np.linspace(T, 0.0, 37)
        assert_allclose(back.sol(tc), fwd.sol(-tc), rtol=0, atol=8 * EPS * np.max(np.abs(fwd.y)))


@pytest.mark.parametrize("kw", [{}, {"dense_output": True}], ids=["grid", "dense"])
@pytest.mark.parametrize("method", sorted(rk4h.METHODS))
def test_backward_run_of_a_reversible_system_is_the_forward_run_reversed(method, kw):
    # For y' = f(y) with f(rho y) = -rho f(y), rho (q, v) = (q, -v), every RK
    # method, partitioned ones included, has Phi_{-h}(y) = rho Phi_h(rho y)
    # (the stages map as Q_i -> Q_i, V_i -> -V_i): the backward run from y_T
    # is rho of the forward run from rho y_T, point for point, to round-off.
    T, h = 4.0, 0.02
    yT = np.array([0.7, 0.4])
    rho = np.array([1.0, -1.0])
    back = rk4h.solve(_oscillator, (T, 0.0), yT, h=h, method=method, **kw)
    fwd = rk4h.solve(_oscillator, (0.0, T), rho * yT, h=h, method=method, **kw)
    assert_allclose(back.t, T - fwd.t, rtol=0, atol=4 * EPS * T)
    assert_allclose(back.y, rho[:, None] * fwd.y, rtol=0, atol=4 * EPS)
    if kw:
        tc = np.linspace(0.0, T, 41)
        assert_allclose(back.sol(tc), rho[:, None] * fwd.sol(T - tc), rtol=0, atol=16 * EPS)


def test_symmetric_method_returns_along_its_own_path():
    # Stormer-Verlet is symmetric (Phi_{-h} = Phi_h^{-1}): integrating forward
    # then backward from the end retraces the forward states, reversed, to
    # round-off (a random-walk sum of N steps' round-off, bounded here by
    # N x 8 eps). RK4 is not symmetric: the same retrace misses by its
    # truncation error, over 100 times that round-off bound -- the check can fail.
    T, h = 10.0, 0.01
    y0 = np.array([1.0, 0.0])
    n = round(T / h)
    fwd = rk4h.solve(_oscillator, (0.0, T), y0, h=h, method="stormer-verlet")
    back = rk4h.solve(_oscillator, (T, 0.0), fwd.y[:, -1], h=h, method="stormer-verlet")
    assert_allclose(back.t, fwd.t[::-1], rtol=0, atol=4 * EPS * T)
    assert np.max(np.abs(back.y - fwd.y[:, ::-1])) <= n * 8 * EPS
    fwd4 = rk4h.solve(_oscillator, (0.0, T), y0, h=h)
    back4 = rk4h.solve(_oscillator, (T, 0.0), fwd4.y[:, -1], h=h)
    assert np.max(np.abs(back4.y - fwd4.y[:, ::-1])) > 100 * n * 8 * EPS


def test_backward_h_sign_and_n_steps():
    a = rk4h.solve(fun_rational, (5.0, 1.0), [1 / 3, 2 / 9], h=0.1)
    b = rk4h.solve(fun_rational, (5.0, 1.0), [1 / 3, 2 / 9], h=-0.1)
    c = rk4h.solve(fun_rational, (5.0, 1.0), [1 / 3, 2 / 9], n_steps=40)
    assert a.h == b.h == c.h and a.h < 0 and a.n_steps == 40
    assert_array_equal(a.y, b.y)
    assert_array_equal(a.y, c.y)
    assert a.t[-1] == 1.0 and np.all(np.diff(a.t) < 0)
    with pytest.raises(ValueError, match="`h` = -0.1 is negative but .* runs forward") as info:
        rk4h.solve(fun_rational, (5.0, 9.0), [1 / 3, 2 / 9], h=-0.1)
    assert "\n" not in str(info.value)


@pytest.mark.parametrize("kw", [{}, {"dense_output": True}, {"t_eval": [1.0, 0.9995, 0.0]},
                                {"events": lambda t, y: y[0] - 0.5}], ids=["grid", "dense", "t_eval", "events"])
@pytest.mark.parametrize("method", ["rk4", "euler", "symplectic-euler", "stormer-verlet"])
def test_tbound_respected_backward(method, kw):
    # scipy gh-17341 for a backward run: fun is never called below t1.
    t0, t1 = 1.0, 1.0 - 1e-13

    def fun(t, y):
        assert t1 <= t <= t0, f"fun evaluated at t = {t!r}, outside [{t1!r}, {t0!r}]"
        return 2 * y

    kw = dict(kw)
    if "t_eval" in kw:
        kw["t_eval"] = [t0, t0 - 0.4e-13, t1]
    res = rk4h.solve(fun, (t0, t1), [1.0, 0.5], h=1e-13 / 7, method=method, **kw)
    assert res.success and res.t[-1] == t1


# -- refused options, bad arguments -----------------------------------------------------------------

@pytest.mark.parametrize("name, value", [("rtol", 1e-3), ("atol", 1e-6), ("first_step", 0.1), ("max_step", 0.5),
                                         ("min_step", 1e-6), ("jac", jac_rational), ("jac_sparsity", np.ones((2, 2))),
                                         ("lband", 1), ("uband", 1)])
def test_refused_options_name_themselves_and_say_why(name, value):
    assert name in REFUSED_OPTIONS
    with pytest.raises(ValueError) as info:
        rk4h.solve(fun_rational, [5, 9], [1 / 3, 2 / 9], h=0.1, **{name: value})
    msg = str(info.value)
    assert msg.startswith(f"`{name}` does not apply to rk4h.solve: ")
    assert REFUSED_OPTIONS[name] in msg and msg.endswith("(fixed step: give h or n_steps)")
    assert "\n" not in msg


def test_refused_options_table_is_complete():
    assert set(REFUSED_OPTIONS) == {"rtol", "atol", "first_step", "max_step", "min_step", "jac", "jac_sparsity",
                                    "lband", "uband"}


def test_unknown_options_refused_naming_them():
    with pytest.raises(ValueError, match=r"unknown option\(s\) `foo`, `rtoll` for rk4h.solve") as info:
        rk4h.solve(fun_rational, [5, 9], [1 / 3, 2 / 9], h=0.1, foo=1, rtoll=1e-3)
    assert "refuses" in str(info.value) and "\n" not in str(info.value)


@pytest.mark.parametrize("kw, name", [
    ({"method": "RK45"}, "method"), ({"method": "LSODA"}, "method"), ({"method": OdeSolution}, "method"),
    ({"dense_output": "yes"}, "dense_output"), ({"vectorized": 1}, "vectorized"),
    ({"events": 5}, "events"), ({"events": [event_rational_1, 3]}, "events[1]"),
    ({"events": _with(event_rational_1, direction="up")}, "events[0].direction"),
    ({"events": lambda t, y: [1.0, 2.0]}, "events[0]"),
    ({"h": None}, "n_steps"),
])
def test_bad_arguments_raise_value_error_naming_them(kw, name):
    kw = {"h": 0.1, **kw}
    if kw["h"] is None:
        del kw["h"]
    with pytest.raises(ValueError, match=f"`{name}".replace("[", r"\[")) as info:
        rk4h.solve(fun_rational, [5, 9], [1 / 3, 2 / 9], **kw)
    assert "\n" not in str(info.value)


# -- the result and the dense output as scipy's objects -----------------------------------------------

def test_result_is_an_ode_result():
    res = rk4h.solve(fun_rational, [5, 9], [1 / 3, 2 / 9], h=0.1)
    keys = ["t", "y", "sol", "t_events", "y_events", "nfev", "njev", "nlu", "status", "message", "success"]
    assert list(res.keys())[: len(keys)] == keys  # solve_ivp's keys first, in its order
    assert {"h", "n_steps", "t_fail", "dense", "method", "reason"} <= set(res.keys())
    assert res["t"] is res.t and res["y"] is res.y and "sol" in res and res["sol"] is None
    assert dict(res)["nfev"] == res.nfev == 160 and res.get("njev") == 0 and res["nlu"] == 0
    assert res.t_events is None and res.y_events is None
    with pytest.raises(KeyError):
        res["rtol"]
    assert res.message == "The solver successfully reached the end of the integration interval."
    # no events given -> None; an empty list of events -> an empty list, as solve_ivp
    assert rk4h.solve(fun_rational, [5, 9], [1 / 3, 2 / 9], h=0.1, events=[]).t_events == []


@pytest.mark.parametrize("t_span", [(5.0, 9.0), (9.0, 5.0)], ids=["forward", "backward"])
def test_OdeSolution(t_span):
    res = rk4h.solve(fun_rational, t_span, list(sol_rational(t_span[0])), h=0.25, dense_output=True)
    sol = res.sol
    assert isinstance(sol, OdeSolution) and isinstance(sol, HermiteSolution)
    assert sol.order == 3
    assert sol.n_segments == len(sol.interpolants) == res.n_steps == 16
    assert_array_equal(sol.ts, res.t)
    assert sol.t_min == min(t_span) and sol.t_max == max(t_span)
    assert sol.ascending == (t_span[1] > t_span[0])
    # scalar -> (n,), array -> (n, m), any order of the times
    assert sol(6.3).shape == (2,) and sol([6.3]).shape == (2, 1)
    tt = np.array([8.7, 5.0, 6.1, 9.0, 7.25, 5.5, 5.5])
    assert_array_equal(sol(tt), np.column_stack([sol(t) for t in tt]))
    with pytest.raises(ValueError, match="1-D"):
        sol(np.ones((2, 2)))
    # the interpolants are scipy DenseOutputs; scipy's own OdeSolution over them selects the same segments
    for i in (0, 7, -1):
        it = sol.interpolants[i]
        assert isinstance(it, DenseOutput)
        mid = (it.t_old + it.t) / 2
        assert it.t_min <= mid <= it.t_max
        assert_array_equal(it(mid), sol(mid))
        assert it([mid, it.t]).shape == (2, 2)
    ref = OdeSolution(sol.ts, list(sol.interpolants))
    probe = np.concatenate((np.linspace(4.0, 10.0, 101), sol.ts))  # breakpoints and extrapolation included
    assert_allclose(sol(probe), ref(probe), rtol=0, atol=0)
    # outside [t_min, t_max] the end polynomials are extrapolated, as scipy
    lo_seg = 0 if sol.ascending else -1
    assert_array_equal(sol(4.0), sol.interpolants[lo_seg](4.0))
    # at a breakpoint the value is the grid value, bit for bit
    assert_array_equal(sol(res.t[5]), res.y[:, 5])


def test_dense_output_is_continuously_differentiable():
    # C^1 across every breakpoint: one-sided difference quotients of the two
    # neighbouring polynomials agree to O(delta) (both equal f(t_i, y_i)).
    res = rk4h.solve(fun_rational, [5, 9], [1 / 3, 2 / 9], h=0.25, dense_output=True)
    delta = 1e-7
    for i in range(1, res.n_steps):
        t = res.t[i]
        left = (res.sol.interpolants[i - 1](t) - res.sol.interpolants[i - 1](t - delta)) / delta
        right = (res.sol.interpolants[i](t + delta) - res.sol.interpolants[i](t)) / delta
        assert_allclose(left, fun_rational(t, res.y[:, i]), rtol=1e-5, atol=1e-8)
        assert_allclose(right, fun_rational(t, res.y[:, i]), rtol=1e-5, atol=1e-8)


@pytest.mark.parametrize("method, per_step, first, extra", [
    ("rk4", 4, 4, 1), ("euler", 1, 1, 1), ("stormer-verlet", 1, 2, 0), ("heun3", 3, 3, 1)])
def test_nfev_counts_every_call_with_dense_output(method, per_step, first, extra):
    # FSAL (Stormer-Verlet) gives the end slope for free; others pay one call, f(t1, y_N).
    calls = []

    def fun(t, y):
        calls.append(t)
        return np.array([y[1], -y[0]])

    res = rk4h.solve(fun, (0.0, 2.0), [1.0, 0.0], h=0.1, method=method, dense_output=True)
    assert res.nfev == len(calls) == first + (res.n_steps - 1) * per_step + extra
    plain = rk4h.solve(fun, (0.0, 2.0), [1.0, 0.0], h=0.1, method=method)
    assert plain.nfev == first + (plain.n_steps - 1) * per_step


def test_events_reuse_the_slope_they_needed():
    # An event in a step needs f(t_{i+1}, y_{i+1}) before step i+1 computes it
    # as its first stage; that call is made once and reused.
    f, event, _ = _harmonic_oscillator()
    calls = []

    def fun(t, y):
        calls.append(t)
        return f(t, y)

    res = rk4h.solve(fun, (0.0, 20.0), [1.0, 0.0], h=0.1, events=event)
    assert res.t_events[0].size == 6
    assert res.nfev == len(calls) == 4 * res.n_steps


# -- order of the dense output and of the event times ---------------------------------------------

def test_dense_output_and_event_times_are_fourth_order():
    # The Hermite extension has local order 3 (local error O(h^4)); with RK4
    # nodes the global error of the dense output, and so of located events, is
    # O(h^4): halving h divides both by about 16 (accepted: 2^3.5 to 2^4.5).
    # Maxima over many points and many events: one event's error depends on
    # where in its step it falls (the Hermite error is ~ theta^2 (1 - theta)^2),
    # which is not the same on the two grids.
    tc = np.linspace(5, 9, 1001)
    dense_err = []
    for h in (0.2, 0.1):
        res = rk4h.solve(fun_rational, [5, 9], [1 / 3, 2 / 9], h=h, dense_output=True)
        dense_err.append(np.max(np.abs(res.sol(tc) - sol_rational(tc))))
    f, event, _ = _harmonic_oscillator()  # zeros of cos t at (k + 1/2) pi: 32 events on [0, 100]
    event_err = []
    for h in (0.2, 0.1):
        res = rk4h.solve(f, (0.0, 100.0), [1.0, 0.0], h=h, events=event)
        assert res.t_events[0].size == 32
        event_err.append(np.max(np.abs(res.t_events[0] - (np.arange(32) + 0.5) * np.pi)))
    for name, e in (("dense output", dense_err), ("event time", event_err)):
        order = math.log2(e[0] / e[1])
        assert 3.5 <= order <= 4.5, f"{name}: observed order {order:.2f} ({e})"
