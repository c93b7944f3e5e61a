"""Drawing reads records only: the state figures take what they need of the
model (coordinates, masses, its drawing) from the run's record
(rk4h.validation.look), so drawing builds no model; and the recorded
look draws the same figures, with the same sentences, as the model itself."""
from __future__ import annotations

import pytest

from rk4h.validation import draw, execute, measure, plan
from rk4h.validation.look import ModelLook
from rk4h.validation.scenes import Scene, load_scene, scene_from_dict

pytest.importorskip("matplotlib")

#: One scene per drawing layout: line, plane (one point, several points), angles, a first-order ODE.
SHIPPED = ["thesis_2dof_case1", "planar4_case1", "triangle", "pendulums_beats", "lotka_volterra"]

#: Adaptive references only: the state figure draws the reference trajectory (a truth record).
REFERENCE_ONLY = {"name": "reference-only", "model": "chain",
                  "params": {"masses": [1.0, 2.0], "springs": [1.0, 1.0, 1.0]},
                  "initial": {"x": [0.5, 0.0]},
                  "run": {"t_end": 10.0, "tolerances": [1e-8], "solvers": ["dop853"],
                          "outputs": ["state", "figures"]}}


def _state_jobs(scene):
    specs = [s for s in plan.plan(scene) if s.purpose == "figure" or (s.purpose == "truth" and s.grid == "figure")]
    assert specs
    records = {s.key: execute.execute(scene, s) for s in specs}
    res = measure.SceneTables(scene.name)
    measure.measure_state_figure(scene, specs, records, res)
    jobs = [j for j in res.figures if j.kind == "state"]
    assert len(jobs) == 1
    return specs, records, jobs[0]


def _scenes():
    return [load_scene(f"validation/scenes/{n}.toml") for n in SHIPPED] + [
        scene_from_dict(REFERENCE_ONLY, "reference-only.toml")]


@pytest.mark.parametrize("scene", _scenes(), ids=lambda s: s.name)
def test_drawing_builds_no_model_and_matches_the_model(scene, tmp_path, monkeypatch):
    from rk4h.validation import figures

    specs, records, job = _state_jobs(scene)
    model = scene.build_model()
    d = job.data
    want = figures.scene_figures(tmp_path / "model", scene.name, model, d["t"], d["y"], title=d["title"],
                                 thesis=f"thesis {d['thesis']}" if d.get("thesis") else None, modal=d.get("modal"))

    def refuse(self):
        raise AssertionError("drawing built the model")

    execute.clear_problems()
    monkeypatch.setattr(Scene, "build_model", refuse)
    got = draw.draw_job(job, tmp_path, scene)
    assert [(p.name, str(s), s.kind) for p, s in got] == [(p.name, str(s), s.kind) for p, s in want]
    assert all(p.stat().st_size > 0 for p, _ in got)


def test_the_look_holds_what_the_figures_read():
    scene = load_scene("validation/scenes/triangle.toml")
    _, records, job = _state_jobs(scene)
    model = scene.build_model()
    look = ModelLook(job.data["look"])
    assert (look.name, look.n_dof, look.n_state, look.first_order, look.linear) == (
        model.name, model.n_dof, model.n_state, model.first_order, model.linear)
    assert list(look.coord_names) == list(model.coord_names)
    assert look.mass.tolist() == list(map(float, model.mass))
    assert look.drawing() == model.drawing()


def test_a_record_without_a_look_is_refused_in_one_line():
    with pytest.raises(ValueError, match="holds no model look"):
        ModelLook({})
