"""The stability study past its boundary part integrates any classical tableau
(``[stability] method``): drift and phase theory from the method's own R(z),
round-off and long runs with its steps, bad values refused naming the key."""
from fractions import Fraction

import mpmath as mp
import numpy as np
import pytest

from rk4h.methods import METHODS
from rk4h.stability_function import stability_polynomial
from rk4h.validation import metrics
from rk4h.validation import stability as S
from rk4h.validation.scenes import SCENE_DIR, SceneError, load_scene, scene_from_dict

CLASSICAL = ["rk4", "rk38", "heun3", "ralston", "euler"]


def _lag_mp(tab, theta):
    """``theta - arg R(i theta)`` at 40 digits, the argument continued from 0
    along a fine grid (exact rational coefficients of R)."""
    mp.mp.dps = 40
    r = [mp.mpf(Fraction(a).numerator) / Fraction(a).denominator for a in stability_polynomial(tab)]
    R = lambda x: sum(c * (1j * x) ** k for k, c in enumerate(r))  # noqa: E731
    arg, prev = mp.mpf(0), mp.mpc(1)
    for x in mp.linspace(0, theta, 400)[1:]:
        cur = R(x)
        arg += mp.arg(cur / prev)  # each increment is far below pi on this grid
        prev = cur
    return theta - arg


@pytest.mark.parametrize("theta", [1e-3, 0.05, 0.5, 1.9, 2.5])
@pytest.mark.parametrize("name", CLASSICAL)
def test_phase_lag_of_any_tableau_equals_high_precision(name, theta):
    tab = METHODS[name]
    ref = _lag_mp(tab, mp.mpf(theta))
    got = metrics.phase_lag(tab, theta)
    assert abs((mp.mpf(float(got)) - ref) / ref) < 1e-12, (got, ref)
    assert metrics.phase_lag(tab, -theta) == pytest.approx(-got, rel=1e-15)  # odd


@pytest.mark.parametrize("name, loss, lag", [
    ("rk4", (Fraction(1, 72), 6), (Fraction(1, 120), 5)),
    ("rk38", (Fraction(1, 72), 6), (Fraction(1, 120), 5)),
    ("heun3", (Fraction(1, 12), 4), (Fraction(-1, 30), 5)),
    ("ralston", (Fraction(-1, 4), 4), (Fraction(-1, 6), 3)),
    ("euler", (Fraction(-1), 2), (Fraction(1, 3), 3)),
])
def test_leading_terms_are_the_small_theta_limits(name, loss, lag):
    tab = METHODS[name]
    (a, p), (b, q) = metrics.leading_terms(tab)
    assert (p, q) == (loss[1], lag[1])
    assert a == pytest.approx(float(loss[0]), rel=1e-15) and b == pytest.approx(float(lag[0]), rel=1e-15)
    th = 1e-3  # the next terms are theta^2 smaller
    assert metrics.energy_loss(tab, th) / th**p == pytest.approx(a, rel=1e-5)
    assert metrics.phase_lag(tab, th) / th**q == pytest.approx(b, rel=1e-5)


@pytest.fixture(scope="module")
def methods_scene():
    return load_scene(SCENE_DIR / "methods_2dof.toml")


def test_the_shipped_scene_studies_heun3(methods_scene):
    assert methods_scene.stability["method"] == "heun3"
    assert "long_horizon:method" in S.units(methods_scene, True)


def test_drift_and_phase_of_the_scene_method_meet_its_own_theory(methods_scene):
    rows = S.run_unit(methods_scene, "long_horizon:drift", True).rows
    got = [r for r in rows if r["quantity"] in ("energy_loss_per_step", "phase_lag_per_step")]
    assert got and {r["solver"] for r in got} == {"heun3"}
    heun3, rk4 = methods_scene.method("heun3").tableau, METHODS["rk4"]
    for r in got:
        f = metrics.energy_loss if r["quantity"] == "energy_loss_per_step" else metrics.phase_lag
        assert r["theory"] == pytest.approx(float(f(heun3, r["theta"])), rel=1e-12)
        if r["theta"] <= 0.5:
            assert r["passed"] is True, r
            # RK4's theory is not what was measured: the rows would fail under it
            assert abs(r["measured"] / float(f(rk4, r["theta"])) - 1) > 0.5


def test_roundoff_runs_the_scene_method_at_its_order(methods_scene):
    res = S.run_unit(methods_scene, "roundoff", True)
    rows = [r for r in res.rows if r["quantity"] == "error_at_t_end"]
    assert {r["solver"] for r in rows} == {"heun3"}
    (plot,) = [p for p in res.plots if p["kind"] == "roundoff"]
    assert plot["data"]["method"] == "heun3" and plot["data"]["order"] == 3
    th = np.array([r["theta"] for r in rows])
    err = np.array([r["measured"] for r in rows])
    big = (th >= 0.05) & (th <= 0.5)  # truncation-dominated: the slope is the method's order
    slope = np.polyfit(np.log(th[big]), np.log(err[big]), 1)[0]
    assert abs(slope - 3) <= 0.1, slope


def _doc(stability, solvers=("rk4", "dop853")):
    return {"name": "sm", "model": "chain",
            "params": {"masses": [1.0, 2.0], "springs": [3.0, 4.0, 5.0], "walls": "both"},
            "initial": {"x": [0.01, 0.0]},
            "run": {"t_end": 1.0, "h": [0.01], "tolerances": [1e-8], "solvers": list(solvers),
                    "outputs": ["stability"]},
            "methods": {"ralston2": {"A": [["0", "0"], ["2/3", "0"]], "b": ["1/4", "3/4"]},
                        "py4": {"python": "rk4h.steppers:rk4_step", "order": 4}},
            "stability": stability}


@pytest.mark.parametrize("solvers, expected", [
    (("rk4", "dop853"), "rk4"), (("dop853", "ralston2", "rk4"), "ralston2"),
    (("symplectic-euler", "py4", "dop853"), "rk4"),  # no classical tableau listed: the default
])
def test_the_default_method_is_the_first_classical_tableau(solvers, expected):
    scene = scene_from_dict(_doc({"studies": ["roundoff"]}, solvers))
    assert scene.stability["method"] == expected


@pytest.mark.parametrize("value, words", [
    ("rk5", "must be one of"), ("stormer-verlet", "partitioned"), ("py4", "python"), (4, "non-empty string"),
])
def test_a_bad_stability_method_is_one_line_naming_the_key(value, words):
    with pytest.raises(SceneError) as e:
        scene_from_dict(_doc({"studies": ["roundoff"], "method": value}))
    assert e.value.field == "stability.method", str(e.value)
    assert words in str(e.value) and "\n" not in str(e.value)
