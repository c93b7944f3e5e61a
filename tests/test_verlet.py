"""Stormer-Verlet (velocity Verlet), the built-in partitioned tableau
``"stormer-verlet"``, on both paths.

Theory (HLW sec. I.1.4 and I.5): second order; symplectic and symmetric;
on ``q'' = -w^2 q`` it conserves exactly the modified energy
``v^2/2 + w^2 q^2 (1 - (h w)^2/4) / 2``, so the energy error stays below
``(h w)^2/4 / (1 - (h w)^2/4)`` relative forever (no drift); one force
evaluation per step after the first (the acceleration at ``q_{n+1}`` is the
next step's first, FSAL on ``q``): ``nfev = n_steps + 1``.
"""
import math

import numpy as np
import pytest

import rk4h
import rk4h.fast as fast
from rk4h.methods import METHODS

VERLET = METHODS["stormer-verlet"]


def oscillator(t, y):
    """q'' = -q (w = 1 rad/s), y = [q, v]."""
    return np.array([y[1], -y[0]])


def _max_error(n_steps, t_end=10.0):
    res = rk4h.solve(oscillator, (0.0, t_end), [1.0, 0.0], n_steps=n_steps, method="stormer-verlet")
    exact = np.vstack([np.cos(res.t), -np.sin(res.t)])
    return float(np.max(np.abs(res.y - exact)))


def test_observed_order_is_two():
    e1, e2 = _max_error(500), _max_error(1000)  # h = 0.02 s, 0.01 s
    slope = math.log(e1 / e2) / math.log(2.0)
    assert abs(slope - 2.0) < 0.1, (e1, e2, slope)
    assert VERLET.order == 2


def test_equals_textbook_velocity_verlet():
    # v_{1/2} = v + h/2 a(q); q1 = q + h v_{1/2}; v1 = v_{1/2} + h/2 a(q1)
    h, n = 0.05, 400
    q, v = 1.0, 0.0
    for _ in range(n):
        v_half = v + h / 2 * -q
        q = q + h * v_half
        v = v_half + h / 2 * -q
    res = rk4h.solve(oscillator, (0.0, n * h), [1.0, 0.0], n_steps=n, method="stormer-verlet")
    np.testing.assert_allclose(res.y[:, -1], [q, v], rtol=0, atol=1e-13)


def test_symmetric_a_step_back_undoes_a_step():
    y0 = np.array([0.3, -0.7])
    k = np.empty((2, 2))
    y1 = rk4h.rk_step(oscillator, 0.0, y0, 0.1, VERLET, k)
    back = rk4h.rk_step(oscillator, 0.1, y1, -0.1, VERLET, k)
    np.testing.assert_allclose(back, y0, rtol=0, atol=1e-15)


def test_energy_error_bounded_over_1e5_periods():
    # The compiled path: 3.2 million steps in well under a second once compiled.
    model = rk4h.make_model("oscillator2d", {"m": 1.0, "kx": 1.0, "ky": 1.0})  # w = 1 rad/s
    y0 = model.state([1.0, 0.0], [0.0, 0.5])
    periods, per_period = 100_000, 32
    hw = 2 * math.pi / per_period
    res = fast.solve_model(model, (0.0, periods * 2 * math.pi), y0, n_steps=periods * per_period,
                           method="stormer-verlet", record_every=1009)
    assert res.success and res.n_steps == periods * per_period
    assert res.nfev == res.n_steps + 1
    e0 = model.energy(y0)
    err = np.abs(model.energy(res.y) - e0) / e0
    bound = (hw**2 / 4) / (1 - hw**2 / 4)
    assert err.max() <= bound
    tenth = err.size // 10
    first, last = err[:tenth].max(), err[-tenth:].max()
    assert last <= 1.01 * first and last >= 0.5 * first  # neither drift nor decay


MODELS = [
    ("oscillator2d", {"m": 1.0, "kx": 2.0, "ky": 4.0}, [0.005, 0.002], [0.0, 0.01]),  # straight-line loop
    ("chain", {"masses": [1.0, 2.0, 1.5], "springs": [3.0, 5.0], "walls": "none"},  # straight-line, 3 masses
     [0.003, -0.001, 0.002], [0.01, 0.0, -0.02]),
    ("chain", {"masses": [1.0, 2.0, 1.5, 0.7, 1.2, 0.9, 1.8, 1.1, 0.6],  # array loop (above 8 masses)
               "springs": [3.0, 5.0, 4.0, 2.5, 6.0, 3.5, 4.5, 5.5], "walls": "none"},
     [0.003, -0.001, 0.002, 0.0, -0.002, 0.001, 0.0, 0.004, -0.003],
     [0.01, 0.0, -0.02, 0.005, 0.0, 0.0, -0.01, 0.0, 0.02]),
]


@pytest.mark.parametrize("name, params, x0, v0", MODELS, ids=[m[0] for m in MODELS])
@pytest.mark.parametrize("t_eval", [None, np.array([0.0, 0.013, 0.25, 0.2501, 0.7, 1.5])], ids=["grid", "hermite"])
def test_nfev_is_steps_plus_one_on_both_paths(name, params, x0, v0, t_eval):
    model = rk4h.make_model(name, params)
    y0 = model.state(x0, v0)
    calls = []

    def fun(t, y):
        calls.append(t)
        return model.rhs(t, y)

    kw = dict(h=0.01, method="stormer-verlet", t_eval=t_eval)
    gen = rk4h.solve(fun, (0.0, 1.5), y0, **kw)
    res = fast.solve_model(model, (0.0, 1.5), y0, **kw)
    # first step: both stages' accelerations; every later step: only a(q_{n+1});
    # dense output takes its end slopes from the stages (no extra call).
    assert gen.n_steps == res.n_steps == 150
    assert gen.nfev == res.nfev == len(calls) == 150 + 1
    assert rk4h.nfev_count(VERLET, 150) == 151
    np.testing.assert_array_equal(res.t, gen.t)
    np.testing.assert_array_equal(res.y, gen.y)
