"""The advisor over a horizon with an energy target (rk4h.validation.advise_energy)."""
import json
import math

import numpy as np
import pytest

from rk4h.validation import advise, advise_energy, energy_time
from rk4h.validation.execute import problem
from rk4h.validation.scenes import load_scenes

pytest.importorskip("numba")

SCENE = "thesis-2dof-case1"


@pytest.mark.parametrize("argv, says", [
    (["--periods", "1e5"], "--energy-target: needs --periods"),
    (["--energy-target", "1e-6"], "--energy-target: needs --periods"),
    (["--periods", "x", "--energy-target", "1e-6"], "--periods: must be a positive number, got 'x'"),
    (["--periods", "-3", "--energy-target", "1e-6"], "--periods: must be a positive number, got '-3'"),
    (["--horizon", "inf", "--energy-target", "1e-6"], "--horizon: must be a positive number of seconds"),
    (["--periods", "10", "--energy-target", "2"], "--energy-target: must be a number in (0, 1), got '2'"),
    ([], "--target: required"),
    (["--target", "1e-6", "--periods", "10", "--energy-target", "1e-6"], "--target: not with --energy-target"),
    (["--periods", "x", "--energy-target", "2"], "--energy-target: must be a number in (0, 1), got '2'"),
])
def test_bad_input_is_one_line_exit_2(argv, says, capsys):
    assert advise.main([SCENE, *argv]) == 2
    err = capsys.readouterr().err.strip()
    assert says in err and len(err.splitlines()) == 1 and "Traceback" not in err


def _recheck(scene, adv):
    """Run the recommendation again, independently, over the full horizon: its energy error."""
    from rk4h.references.solvers import integrate
    from rk4h.energy import relative_energy_error
    from rk4h.methods import METHODS

    model, y0 = problem(scene)
    T = adv.horizon_s
    n = energy_time.dense_samples(model, T)
    if adv.setting_name == "h":
        tab = METHODS.get(adv.method) or scene.method(adv.method).tableau
        res, _ = energy_time.long_run(model, y0, tab, adv.setting, T, n)
        assert res.success and res.t[-1] == pytest.approx(T)
        y = res.y
    else:
        y = integrate(adv.method, model, y0, np.linspace(0.0, T, n), adv.setting).y
    return float(np.max(np.abs(relative_energy_error(model, y))))


def _advise(periods, target):
    scene = load_scenes([SCENE])[0]
    adv = advise_energy.advise_energy(scene, target, periods=periods)
    return scene, adv


def test_short_horizon_recommendation_meets_the_target_when_rerun():
    scene, adv = _advise(100, 1e-5)
    assert adv.status == "ok" and adv.method
    assert adv.periods == 100 and adv.horizon_s == pytest.approx(100 * energy_time.slowest_period(problem(scene)[0]))
    assert adv.confirmed_energy_error <= 1e-5
    # the fewest calls among the listed candidates, and every listed one confirmed
    assert adv.cost_rhs == min(c["rhs"] for c in adv.candidates)
    assert all(c["energy_error"] <= 1e-5 for c in adv.candidates)
    assert "rk4" in {c["method"] for c in adv.candidates} | {c["method"] for c in adv.not_listed}
    assert _recheck(scene, adv) <= 1e-5
    assert f"{adv.method}" in adv.why and "RHS calls" in adv.why
    assert json.loads(adv.to_json())["method"] == adv.method


@pytest.mark.slow
def test_1e5_periods_energy_target_1e6_on_the_2dof_chain(capsys):
    """About 1-2 minutes: calibration of every tableau, full-horizon confirmations."""
    assert advise.main([SCENE, "--periods", "1e5", "--energy-target", "1e-6", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["status"] == "ok" and out["method"] and out["periods"] == 1e5
    assert out["confirmed_energy_error"] <= 1e-6
    scene = load_scenes([SCENE])[0]
    adv = advise_energy.EnergyAdvice(**{k: out[k] for k in ("scene", "energy_target", "horizon_s", "periods")})
    adv.method, adv.setting, adv.setting_name = out["method"], out["setting"], out["setting_name"]
    measured = _recheck(scene, adv)
    assert math.isfinite(measured) and measured <= 1e-6, (out["method"], out["setting"], measured)


def test_horizon_in_seconds_or_periods_of_the_slowest_mode():
    scene = load_scenes([SCENE])[0]
    model, _ = problem(scene)
    P = 2 * math.pi / float(np.min(model.modes()[0]))
    assert advise_energy.horizon_seconds(model, periods=10) == pytest.approx((10 * P, 10))
    assert advise_energy.horizon_seconds(model, horizon=5.0) == pytest.approx((5.0, 5.0 / P))


def test_a_reference_climbs_its_rtol_ladder_cheapest_first():
    """dop853 on the 2-DOF chain over 100 periods, energy within 1e-9: rtol
    1e-8 and 1e-10 lose (their calibration over 20 periods extrapolates above
    the target; rerun over the whole horizon they do miss it), 1e-12 is
    confirmed; the advice's text says which rtols were tried and why they lost."""
    from rk4h.references.solvers import integrate
    from rk4h.energy import relative_energy_error

    scene = load_scenes([SCENE])[0]
    model, y0 = problem(scene)
    P = energy_time.slowest_period(model)
    T, target = 100 * P, 1e-9
    assert advise_energy.REFERENCE_RTOLS == (1e-8, 1e-10, 1e-12)
    c, miss = advise_energy._reference(model, y0, "dop853", T, 20 * P, target)
    assert miss is None and c["setting"] == 1e-12 and c["energy_error"] <= target
    assert [t["setting"] for t in c["tried"]] == [1e-8, 1e-10]
    assert all("above the target" in t["reason"] for t in c["tried"])
    t = np.linspace(0.0, T, energy_time.dense_samples(model, T))
    for rtol in (1e-10, 1e-12):  # the ladder's verdicts, rerun independently
        e = float(np.max(np.abs(relative_energy_error(model, integrate("dop853", model, y0, t, rtol).y))))
        assert (e <= target) == (rtol == 1e-12), (rtol, e)
    adv = advise_energy.EnergyAdvice(scene.name, target, T, 100.0, candidates=[c])
    assert "tried first rtol = 1e-08: energy error" in adv.text()
    c, miss = advise_energy._reference(model, y0, "dop853", T, 20 * P, 1e-11)  # none of the three suffices
    assert c is None and [t["setting"] for t in miss["tried"]] == [1e-8, 1e-10, 1e-12]
    assert miss["reason"].startswith("rtol 1e-08: ") and "rtol 1e-12: " in miss["reason"]
