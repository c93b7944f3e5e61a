"""The ``energy_work_precision`` output: a small Henon-Heiles scene through
run_all, its table read back; its scene key validated; its check able to fail;
never a default output."""
import copy
import math

import pandas as pd
import pytest

from rk4h.validation import outputs, run_all
from rk4h.validation.measure import SceneTables
from rk4h.validation.outputs import energy_work_precision as ewp
from rk4h.validation.scenes import SceneError, default_outputs, scene_from_dict

HH = {
    "name": "ewp-hh",
    "model": "potential",
    "params": {"coordinates": ["x", "y"], "masses": 1.0, "potential": "(x^2 + y^2)/2 + lam*(x^2*y - y^3/3)",
               "constants": {"lam": 1.0}},
    "initial": {"x": [0.0, 0.1], "v": [0.39665266081716044, 0.0]},
    "energy_work_precision": {"periods": [100.0, 1000.0], "steps": [16, 32]},
    "run": {"t_end": 1.0, "h": [0.05], "tolerances": [1e-9], "solvers": ["rk4", "stormer-verlet", "heyoka"],
            "outputs": ["energy_work_precision"]},
}


def test_a_small_scene_through_run_all_writes_its_table(tmp_path):
    scene = scene_from_dict(copy.deepcopy(HH))
    out = tmp_path / "out"
    out.mkdir()
    results, failures = run_all.run([scene], out, repeats=1, figures=False, workers=1)
    assert failures == []
    df = pd.read_csv(out / "energy_work_precision.csv")
    # 2 horizons x (2 fixed-step methods x 2 steps + heyoka at 1 rtol)
    assert len(df) == 2 * (2 * 2 + 1)
    assert set(df["status"]) == {"ok"}
    assert sorted(df["periods"].unique()) == [100.0, 1000.0]
    t_slow = 2 * math.pi  # omega = 1 rad/s for both coordinates of the linearization
    assert df["t_end"].to_numpy() == pytest.approx(df["periods"].to_numpy() * t_slow, rel=1e-12)
    fixed = df[df["solver"] != "heyoka"]
    assert sorted(fixed["h"].unique()) == pytest.approx([t_slow / 32, t_slow / 16], rel=1e-12)
    sv = df[df["solver"] == "stormer-verlet"]
    rk4 = df[df["solver"] == "rk4"]
    assert sv["symplectic"].all() and not rk4["symplectic"].any()
    assert (sv["energy_growth_exponent"] < ewp.BOUNDED_EXPONENT).all()
    # RK4 loses energy secularly: exponent near 1 over 1000 periods at 32 steps per period
    fine = rk4[(rk4["periods"] == 1000.0) & (rk4["h"] < t_slow / 20)]
    assert fine["energy_growth_exponent"].iloc[0] == pytest.approx(1.0, abs=0.1)
    # cost: RK4 makes 4 calls per step, ceil(t_end / h) steps
    n = (rk4["t_end"] / rk4["h"]).round().astype(int)
    assert (rk4["nfev"] == 4 * n).all()
    # the symplectic error is bounded: the same at 100 and 1000 periods (within 10 %)
    e1 = sv[sv["periods"] == 100.0].sort_values("h")["energy_drift_max"].to_numpy()
    e2 = sv[sv["periods"] == 1000.0].sort_values("h")["energy_drift_max"].to_numpy()
    assert e2 == pytest.approx(e1, rel=0.1)
    checks = [c for r in results for c in r.checks if c.name == "symplectic energy bounded"]
    assert len(checks) == 2 and all(c.passed for c in checks)  # stormer-verlet at each horizon


def test_the_bounded_check_fails_on_secular_growth():
    rows = [{"solver": "sv", "symplectic": True, "periods": 100.0, "status": "ok", "h": 0.1,
             "energy_growth_exponent": 0.02},
            {"solver": "sv", "symplectic": True, "periods": 100.0, "status": "ok", "h": 0.2,
             "energy_growth_exponent": 0.9},
            {"solver": "bad", "symplectic": True, "periods": 100.0, "status": "unstable", "h": 0.2,
             "energy_growth_exponent": math.nan},
            {"solver": "rk4", "symplectic": False, "periods": 100.0, "status": "ok", "h": 0.2,
             "energy_growth_exponent": 1.0}]
    m = outputs.Measuring(scene=type("S", (), {"name": "s"})(), by={}, records={}, res=SceneTables("s"),
                          quick=False, draw=False)
    short = [dict(r, periods=10.0) for r in rows]  # under CHECK_MIN_PERIODS: not checked, said so
    ewp._bounded_checks(m, rows + short)
    assert len(m.res.findings) == 1 and "skips the horizons under 100 periods (10)" in m.res.findings[0]
    by = {c.message.split(":")[1].split(" over")[0].strip(): c for c in m.res.checks}
    assert set(by) == {"sv", "bad"}  # rk4 is not symplectic: no check
    assert not by["sv"].passed and by["sv"].measured == pytest.approx(0.9)
    assert "0.900" in by["sv"].message and "h = 0.2" in by["sv"].message
    assert not by["bad"].passed and "no stable run" in by["bad"].message


@pytest.mark.parametrize("key, value, field", [
    ("periods", [1e2, 1e7], "energy_work_precision.periods[1]"),
    ("periods", [0.5], "energy_work_precision.periods[0]"),
    ("steps", [1], "energy_work_precision.steps[0]"),
    ("horizon", 3, "energy_work_precision.horizon"),
])
def test_its_scene_key_is_validated(key, value, field):
    doc = copy.deepcopy(HH)
    doc["energy_work_precision"] = {key: value}
    with pytest.raises(SceneError) as info:
        scene_from_dict(doc)
    assert info.value.field == field
    assert "\n" not in str(info.value)


def test_defaults_and_never_a_default_output():
    doc = copy.deepcopy(HH)
    del doc["energy_work_precision"]
    scene = scene_from_dict(doc)
    assert ewp.settings(scene) == ([1e2, 1e4], [8, 16, 32, 64])
    del doc["run"]["outputs"]
    assert "energy_work_precision" not in scene_from_dict(doc).outputs
    assert "energy_work_precision" not in default_outputs(scene.build_model())


# -- a reference's step cap, sized from the horizon -----------------------------------------------------
def _hh_problem():
    from rk4h.validation.execute import problem

    return problem(scene_from_dict(copy.deepcopy(HH)))


def test_a_reference_step_cap_is_sized_from_the_horizon():
    """heyoka on Henon-Heiles at rtol 1e-8: the cap over 1000 periods is 2x
    the steps estimated from 100 (at least the 5e6 default); the estimate is
    within 5 % of the steps the full run takes; within 100 periods the default
    cap stays, without a calibration run."""
    import numpy as np

    from rk4h.references.solvers import DEFAULT_MAX_STEPS, integrate
    from rk4h.validation import energy_time as et

    model, y0 = _hh_problem()
    T = 1000 * et.slowest_period(model)
    sized = et.reference_step_cap(model, y0, "heyoka", 1e-8, T)
    full = integrate("heyoka", model, y0, np.array([0.0, T]), 1e-8)
    assert sized["estimate"] == pytest.approx(full.n_steps, rel=0.05)
    assert sized["cap"] == max(DEFAULT_MAX_STEPS, math.ceil(et.STEP_CAP_MARGIN * sized["estimate"]))
    short = et.reference_step_cap(model, y0, "heyoka", 1e-8, 50 * et.slowest_period(model))
    assert short["cap"] == DEFAULT_MAX_STEPS and math.isnan(short["estimate"])


def test_a_too_small_step_cap_is_a_failure_not_a_truncated_run(monkeypatch):
    from rk4h.validation import energy_time as et

    model, y0 = _hh_problem()
    (row,) = et.work_precision_rows("ewp-hh", model, y0, [], (16,), (200.0,), references=["heyoka"],
                                    rtols=(1e-8,), max_steps=50)
    assert row["status"] == et.STEP_CAP_STATUS and math.isnan(row["energy_drift_max"]) and row["max_steps"] == 50
    assert "step cap max_steps = 50 reached at t = " in row["message"]
    # over the ceiling: not run at all, and said why
    monkeypatch.setattr(et, "STEP_CAP_CEILING", 1000)
    (row,) = et.work_precision_rows("ewp-hh", model, y0, [], (16,), (1000.0,), references=["heyoka"],
                                    rtols=(1e-8,))
    assert row["status"] == et.STEP_CAP_STATUS and row["max_steps"] == 0 and row["nfev"] == 0
    assert "above the ceiling 1e+03: not run" in row["message"]
    # the output turns such a row into a failed check, an ok one into a passed one
    m = outputs.Measuring(scene=type("S", (), {"name": "s"})(), by={}, records={}, res=SceneTables("s"),
                          quick=False, draw=False)
    ok = dict(row, status="ok", rtol=1e-6)
    fixed = dict(row, status="ok", rtol=math.nan, solver="rk4")
    ewp._step_cap_checks(m, [row, ok, fixed])
    assert [c.passed for c in m.res.checks] == [False, True]
    assert "heyoka at rtol 1e-08 over 1000 periods" in m.res.checks[0].message
    assert "not run" in m.res.checks[0].message
