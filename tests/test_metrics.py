"""Metrics: definitions on hand-made arrays, the RK4 energy theory against a
real RK4 run, the order fit on synthetic power laws, the cheapest-solver pick."""
import math

import numpy as np
import pytest

import rk4h
from rk4h.references.exact import modal_solution
from rk4h.validation import metrics


def test_error_max_and_final_definitions():
    y_ref = np.zeros((2, 3))
    y = np.array([[0.0, -3.0, 1.0], [2.0, 0.0, -0.5]])
    assert metrics.error_max(y, y_ref) == 3.0          # over times and components
    assert metrics.error_final(y, y_ref) == 1.0        # last column only
    y[0, 1] = np.nan
    assert math.isnan(metrics.error_max(y, y_ref))     # a run that did not get there


@pytest.mark.parametrize("theta", [0.01, 0.3, 1.0, 2.0, 2.8])
def test_rk4_energy_factor_is_abs_R_squared(theta):
    # |R(i theta)|^2 with R(z) = 1 + z + z^2/2 + z^3/6 + z^4/24, the RK4 stability polynomial
    z = 1j * theta
    R = 1 + z + z**2 / 2 + z**3 / 6 + z**4 / 24
    assert metrics.rk4_energy_factor(theta) == pytest.approx(abs(R) ** 2, rel=1e-14)


@pytest.mark.parametrize("h", [0.1, 0.05, 0.02])
def test_rk4_drift_theory_matches_an_rk4_run(h):
    # Thesis case 1 (two modes): RK4 multiplies each mode's energy by g(omega_j h) per step,
    # so the total relative change after n steps is sum_j f_j (g_j^n - 1) exactly.
    model = rk4h.make_model("chain", {"masses": [0.815, 3.099], "springs": [41.5, 138.0, 157.8]})
    y0 = model.state([0.005, 0.005])
    T = 20.0
    res = rk4h.solve(model.rhs, (0.0, T), y0, h=h)
    ms = modal_solution(model, y0)
    theory = metrics.rk4_drift_theory(ms.omega, ms.eta0, ms.deta0, res.h, res.n_steps, T)
    measured = metrics.drift_per_time(model, res.t, res.y)
    assert measured == pytest.approx(theory, rel=1e-8)


def test_modal_energy_fractions_sum_to_one_and_weight_by_energy():
    f = metrics.modal_energy_fractions(np.array([1.0, 2.0]), np.array([1.0, 1.0]), np.array([0.0, 0.0]))
    # E_j = omega_j^2 eta_j^2 / 2: 1/2 and 2, so fractions 0.2, 0.8
    np.testing.assert_allclose(f, [0.2, 0.8], rtol=1e-15)


@pytest.mark.parametrize("p", [1.0, 2.0, 4.0])
def test_fit_order_recovers_a_power_law(p):
    h = 0.1 / 2.0 ** np.arange(5)
    err = 3e-3 * (h / h[0]) ** p
    fit = metrics.fit_order(h, err, scale=1.0)
    assert fit.order == pytest.approx(p, abs=1e-12)
    assert fit.n_points == 5 and fit.h_min == h.min() and fit.h_max == h.max()


def test_fit_order_leaves_out_round_off_and_pre_asymptotic_points():
    h = np.array([0.8, 0.4, 0.2, 0.1, 0.05, 0.025, 0.0125])
    err = 1e-4 * (h / 0.2) ** 4
    err[0] = 0.5                 # pre-asymptotic: above PREASYMPTOTIC_REL
    err[-1] = 1e-13              # round-off floor: below ROUNDOFF_REL
    fit = metrics.fit_order(h, err, scale=1.0)
    assert fit.used.tolist() == [False, True, True, True, True, True, False]
    assert fit.order == pytest.approx(4.0, abs=1e-12)
    assert (fit.h_min, fit.h_max) == (0.025, 0.4)


def test_fit_order_with_too_few_points_is_nan_and_fails():
    fit = metrics.fit_order([0.1, 0.05], [1e-4, 6e-6], scale=1.0)
    assert math.isnan(fit.order) and not fit.passed(4.0)


def test_cheapest_picks_lowest_cost_reaching_each_target():
    rows = [
        {"solver": "rk4", "setting": 0.01, "error_rel": 1e-4, "status": "ok", "wall_s": 0.01},
        {"solver": "rk4", "setting": 0.001, "error_rel": 1e-8, "status": "ok", "wall_s": 0.1},
        {"solver": "dop853", "setting": 1e-10, "error_rel": 1e-10, "status": "ok", "wall_s": 0.05},
        {"solver": "heyoka", "setting": 1e-12, "error_rel": 1e-13, "status": "failed", "wall_s": 0.001},
    ]
    best = metrics.cheapest(rows, [1e-3, 1e-6, 1e-9, 1e-12])
    assert [b["solver"] for b in best] == ["rk4", "dop853", "dop853", None]
    assert [b["rk4_setting"] for b in best] == [0.01, 0.001, None, None]
