"""The measurement reads records only: once the runs are recorded,
``measure`` builds no model (no eigensolve, no ``execute.problem``); the
modal numbers it needs (the fastest mode of the trust table's stability
cap, the model's linearity for the FPUT finding) come from the records."""
import math

import pytest

from rk4h.validation import execute, measure, plan
from rk4h.validation.scenes import Scene, scene_from_dict

#: A nonlinear (FPUT alpha) chain: modal energies exchange, so the
#: recurrence finding applies; RK4's trust table is capped by its fastest mode.
DOC = {"name": "records-only", "model": "chain",
       "params": {"masses": [1.0, 1.0, 1.0], "springs": [1.0, 1.0, 1.0, 1.0], "alpha": 0.25},
       "initial": {"x": [0.5, 0.0, -0.3]},
       "run": {"t_end": 20.0, "h": [0.4, 0.2, 0.1], "tolerances": [1e-6, 1e-9], "solvers": ["rk4", "dop853"],
               "outputs": ["state", "work_precision", "modal_energy"]}}


@pytest.fixture(scope="module")
def recorded():
    scene = scene_from_dict(DOC, "records-only.toml")
    specs = plan.plan(scene, figures=False)
    return scene, specs, {s.key: execute.execute(scene, s) for s in specs}


def test_measure_builds_no_model(recorded, monkeypatch):
    scene, specs, records = recorded
    want = measure.measure(scene, specs, records, figures=False)

    def refuse(self):
        raise AssertionError("measure built the model")

    execute.clear_problems()
    monkeypatch.setattr(Scene, "build_model", refuse)
    got = measure.measure(scene, specs, records, figures=False)
    assert got.tables == want.tables and got.findings == want.findings and got.failures == want.failures


def test_the_recorded_modal_numbers_are_used(recorded):
    scene, specs, records = recorded
    res = measure.measure(scene, specs, records, figures=False)
    model = scene.build_model()
    omega_max = float(max(model.modes()[0]))
    assert res.omega_max == pytest.approx(omega_max, rel=1e-12)
    # a nonlinear model: the recurrence finding, once per solver's modal run
    assert sum("(FPUT recurrence)" in f for f in res.findings) == len(DOC["run"]["solvers"])
    assert res.tables["cheapest"] and all(r["scene"] == scene.name for r in res.tables["cheapest"])
    truth = next(records[s.key] for s in specs if s.purpose == "truth" and s.grid == "scene")
    assert truth.values["omega_max"] == pytest.approx(omega_max, rel=1e-12)
    modal = [records[s.key] for s in specs if s.purpose == "modal"]
    assert modal and all(r.values["linear"] is False for r in modal)
    assert math.isfinite(res.omega_max)


def test_no_eigensolve_for_a_scene_without_the_trust_table(monkeypatch):
    """Only the work_precision output's trust table uses the fastest mode:
    a scene without it records none, and its truth run solves no eigenproblem
    (a large model's dense eigensolve would cost more than its runs)."""
    from rk4h.models.base import Model

    solved = []
    compute = Model._compute_modes

    def counted(self):
        solved.append(self)
        return compute(self)

    monkeypatch.setattr(Model, "_compute_modes", counted)
    doc = {**DOC, "run": {**DOC["run"], "outputs": ["state"]}}
    scene = scene_from_dict(doc, "records-only.toml")
    execute.clear_problems()
    truth = [s for s in plan.plan(scene, figures=False) if s.purpose == "truth"]
    assert truth
    for s in truth:
        rec = execute.execute(scene, s)
        assert rec.status == "ok", rec.message
        assert math.isnan(rec.values["omega_max"])
    assert not solved


ODE = {"name": "ode-records-only", "model": "ode",
       "params": {"variables": ["u", "v"], "equations": ["u - u*v", "-v + u*v"], "invariant": "u - log(u) + v - log(v)"},
       "initial": {"y": [1.5, 0.5]},
       "run": {"t_end": 1.0, "h": [0.1], "tolerances": [1e-6], "solvers": ["rk4", "dop853"],
               "outputs": ["trajectory"]}}
CHAIN = {**DOC, "name": "chain-records-only", "run": {**DOC["run"], "outputs": ["trajectory"]}}


@pytest.mark.parametrize("doc, first_order", [(ODE, True), (CHAIN, False)], ids=["ode", "chain"])
def test_the_trajectory_output_builds_no_model(doc, first_order, monkeypatch):
    """The trajectory file job (its component naming included) comes from
    the records: measure with ``build_model`` refused gives the same job."""
    scene = scene_from_dict(doc, f"{doc['name']}.toml")
    specs = plan.plan(scene, figures=False)
    records = {s.key: execute.execute(scene, s) for s in specs}

    def refuse(self):
        raise AssertionError("measure built the model")

    execute.clear_problems()
    monkeypatch.setattr(Scene, "build_model", refuse)
    res = measure.measure(scene, specs, records, figures=False)
    jobs = [j for j in res.files if j.output == "trajectory"]
    assert len(jobs) == 1 and jobs[0].data["first_order"] is first_order
    assert all(r["names"] for r in jobs[0].data["runs"])
