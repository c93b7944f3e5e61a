"""The stability-region figure in the report (issue 30): every scene with a
stability study gets one complex-plane figure of the methods it is about,
drawn by the stability output, with a caption computed from the drawn
function (the imaginary-axis crossings: RK4 2.8284271, Heun3 sqrt 3)."""
import math
from types import SimpleNamespace

import pytest

from rk4h.methods import METHODS
from rk4h.validation import outputs
from rk4h.validation.figures import GENERIC_CAPTIONS
from rk4h.validation.measure import FigureJob
from rk4h.validation.scenes import load_scene, resolve_scene
from rk4h.validation.stability import draw
from rk4h.validation.stability.region import region_plot


def test_region_plot_holds_each_method_once_with_its_exact_interval():
    plot = region_plot("s", [METHODS[n] for n in ("rk4", "heun3", "stormer-verlet")], n=41)
    d = plot["data"]
    assert [r["name"] for r in d["classical"]] == ["rk4", "heun3"]
    assert [r["name"] for r in d["partitioned"]] == ["stormer-verlet"]
    rk4, heun3 = d["classical"]
    assert abs(rk4["crossing"] - 2 * math.sqrt(2)) < 1e-6 and abs(heun3["crossing"] - math.sqrt(3)) < 1e-6
    assert rk4["amp"].shape == (41, 41) and d["im_max"] >= 1.2 * 2 * math.sqrt(2)


def test_the_caption_quotes_the_crossings(tmp_path):
    path, caption = draw(region_plot("my-scene", [METHODS[n] for n in ("rk4", "heun3", "euler", "yoshida4")],
                                     n=61), tmp_path)
    assert path.name == "my_scene_stability_region.png" and path.stat().st_size > 5_000
    assert caption.kind == "stability_region" and caption.kind in GENERIC_CAPTIONS
    assert "rk4 stable for |Im z| <= 2.8284271" in caption and "heun3 stable for |Im z| <= 1.7320508" in caption
    assert "euler on no interval of the imaginary axis" in caption
    assert "yoshida4 stable for |Im z| <= 1.5734019 and nowhere off it" in caption


@pytest.mark.parametrize("scene, expected", [
    ("stability_2dof", ["rk4", "symplectic-euler", "stormer-verlet", "euler"]),
    ("geometric-2dof", ["rk4", "stormer-verlet", "forest-ruth-as-data", "yoshida4-as-data", "symplectic-euler",
                        "euler"]),
])
def test_region_methods_of_shipped_scenes(scene, expected):
    from rk4h.validation.outputs.stability import region_methods

    assert region_methods(load_scene(resolve_scene(scene))) == expected


def test_the_stability_output_draws_the_region_of_the_scenes_own_methods(tmp_path):
    """The output's drawer resolves the scene's own tableaux (geometric-2dof's
    float-coefficient yoshida4-as-data) and the built-ins (forest-ruth among them)."""
    scene = load_scene(resolve_scene("geometric-2dof"))
    fn = outputs.drawer("stability_region")
    assert fn is not None and outputs.get("stability").draw["stability_region"] is fn
    job = FigureJob(scene.name, "stability_region", {"methods": ["rk4", "yoshida4-as-data", "forest-ruth"]})
    ((path, caption),) = fn(tmp_path, job, scene)
    assert path.name == "geometric_2dof_stability_region.png"
    assert "yoshida4-as-data stable for |Im z| <= 1.573401" in caption
    assert "rk4 stable for |Im z| <= 2.8284271" in caption
    with pytest.raises(ValueError, match="solver"):
        fn(tmp_path, FigureJob(scene.name, "stability_region", {"methods": ["nope"]}), scene)


def test_measure_adds_one_region_job_per_stability_scene(monkeypatch):
    import rk4h.validation.measure as M
    from rk4h.validation.outputs import stability as out

    studied = []
    monkeypatch.setattr(M, "measure_stability", lambda scene, specs, *a: studied.append(specs))
    scene = load_scene(resolve_scene("stability_2dof"))
    added = []
    runs = {"stability": []}
    m = SimpleNamespace(scene=scene, specs=lambda purpose: runs.get(purpose, []), res=SimpleNamespace(figures=added),
                        records={}, quick=True)
    out.measure(m)  # no stability runs: no study, no figure
    assert added == [] and studied == []
    runs["stability"] = ["a unit"]
    out.measure(m)
    assert studied == [["a unit"]]
    assert added == [FigureJob("stability_2dof", "stability_region",
                               {"methods": ["rk4", "symplectic-euler", "stormer-verlet", "euler"]})]
