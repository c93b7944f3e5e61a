"""Scene files: the shipped scenes load with the thesis' parameters, and a bad
scene is refused before anything runs with one line naming the file and field."""
import copy
import math

import numpy as np
import pytest

from rk4h.validation.scenes import SCENE_DIR, SceneError, load_scene, load_scene_points, load_scenes, scene_from_dict

SHIPPED = sorted(SCENE_DIR.glob("*.toml"))

VALID = {
    "name": "tiny",
    "description": "a valid scene the bad cases below break one field at a time",
    "model": "chain",
    "params": {"masses": [0.815, 3.099], "springs": [41.5, 138.0, 157.8], "walls": "both"},
    "initial": {"x": [0.005, 0.005], "v": [0.0, 0.0]},
    "run": {"t_end": 1.0, "h": [0.1, 0.05], "tolerances": [1e-6, 1e-8],
            "solvers": ["rk4", "dop853"], "outputs": ["state", "energy"]},
}


@pytest.mark.parametrize("path", SHIPPED, ids=lambda p: p.stem)
def test_shipped_scene_loads(path):
    points = load_scene_points(path)  # one scene per [sweep] point; [scene] without a sweep
    assert points
    for s in points:
        model = s.build_model()
        assert s.y0().shape == (model.n_state,)
        # every output time is a step of every fixed-step run
        for h in s.h:
            assert abs(s.output_dt / h - round(s.output_dt / h)) < 1e-9
        assert s.t_eval()[-1] == s.t_end


def test_quick_subset_is_a_proper_subset():
    full, quick = load_scenes(), load_scenes(quick=True)
    assert 0 < len(quick) < len(full)
    assert {s.name for s in quick} <= {s.name for s in full}


@pytest.mark.parametrize("name, masses, springs, x0", [
    # Tables 4.1, sec. 4.1.2 and 4.2 of the thesis (quoted)
    ("thesis_2dof_case1", [0.815, 3.099], [41.5, 138.0, 157.8], [0.005, 0.005]),
    ("thesis_2dof_case2", [0.815, 3.099], [41.5, 138.0, 157.8], [0.005, 0.0]),
    ("thesis_2dof_case3", [0.815, 0.815], [41.5, 41.5, 41.5], [0.005, 0.0]),
])
def test_two_dof_scenes_carry_the_thesis_tables(name, masses, springs, x0):
    s = load_scene(SCENE_DIR / f"{name}.toml")
    assert s.params["masses"] == masses and s.params["springs"] == springs
    assert s.initial_x == x0 and s.initial_v == [0.0, 0.0] and s.t_end == 100.0
    assert 0.1 in s.h  # the thesis' step


def test_mode2_scene_starts_in_mode_2():
    # Code 02: x0 = phi[:, 1]. For N equal masses between walls the n-th mode is
    # x_j ~ sin(j n pi / (N + 1)); mass-normalised: sum m x_j^2 = 1.
    s = load_scene(SCENE_DIR / "chain10_mode2.toml")
    N, m = len(s.initial_x), s.params["masses"][0]
    j = np.arange(1, N + 1)
    expected = np.sin(2 * j * np.pi / (N + 1))
    expected /= math.sqrt(m * np.sum(expected**2))
    np.testing.assert_allclose(s.initial_x, expected, rtol=1e-10, atol=1e-12)


@pytest.mark.parametrize("delta_name, delta", [("delta0", 0.0), ("delta-pi4", math.pi / 4),
                                               ("delta-pi2", math.pi / 2), ("delta-3pi4", 3 * math.pi / 4)])
def test_isotropic_scenes_start_on_the_thesis_trajectory(delta_name, delta):
    # x = A cos(w t), y = B cos(w t - Delta), A = B = 1 m, w = sqrt(2k/m) (eqs. 2.86-2.87, Table 4.6)
    s = load_scene(SCENE_DIR / f"oscillator_iso_{delta_name}.toml")
    w = math.sqrt(2 * 41.5 / 0.815)
    assert math.sqrt(s.params["kx"] / s.params["m"]) == pytest.approx(w, rel=1e-15)
    np.testing.assert_allclose(s.y0(), [1.0, math.cos(delta), 0.0, w * math.sin(delta)], atol=1e-15)


def _mutate(path_keys, value):
    doc = copy.deepcopy(VALID)
    node = doc
    for k in path_keys[:-1]:
        node = node[k]
    if value is _DELETE:
        del node[path_keys[-1]]
    else:
        node[path_keys[-1]] = value
    return doc


_DELETE = object()

BAD = [
    # (case id, keys to change, new value, field the message must name)
    ("unknown-model", ["model"], "spring", "model"),
    ("unknown-top-key", ["colour"], "red", "colour"),
    ("unknown-param", ["params", "mass"], 1.0, "params.mass"),
    ("unknown-run-key", ["run", "steps"], 10, "run.steps"),
    ("missing-run", ["run"], _DELETE, "run"),
    ("missing-t_end", ["run", "t_end"], _DELETE, "run.t_end"),
    ("negative-mass", ["params", "masses"], [0.815, -1.0], "params.masses[1]"),
    ("zero-stiffness", ["params", "springs"], [41.5, 0.0, 157.8], "params.springs[1]"),
    ("wrong-spring-count", ["params", "springs"], [41.5, 138.0], "params.springs"),
    ("nan-mass", ["params", "masses"], [float("nan"), 3.099], "params.masses[0]"),
    ("inf-x", ["initial", "x"], [float("inf"), 0.0], "initial.x[0]"),
    ("short-x", ["initial", "x"], [0.005], "initial.x"),
    ("long-v", ["initial", "v"], [0.0, 0.0, 0.0], "initial.v"),
    ("string-x", ["initial", "x"], "0.005", "initial.x"),
    ("zero-t_end", ["run", "t_end"], 0.0, "run.t_end"),
    ("negative-t_end", ["run", "t_end"], -5.0, "run.t_end"),
    ("bool-t_end", ["run", "t_end"], True, "run.t_end"),
    ("zero-h", ["run", "h"], [0.1, 0.0], "run.h[1]"),
    ("negative-h", ["run", "h"], [-0.1], "run.h[0]"),
    ("h-above-t_end", ["run", "h"], [2.0], "run.h[0]"),
    ("h-not-dividing", ["run", "h"], [0.1, 0.03], "run.h[1]"),
    ("empty-h", ["run", "h"], [], "run.h"),
    ("tolerance-one", ["run", "tolerances"], [1.0], "run.tolerances[0]"),
    ("tolerance-zero", ["run", "tolerances"], [0.0, 1e-6], "run.tolerances[0]"),
    ("tolerance-negative", ["run", "tolerances"], [-1e-6], "run.tolerances[0]"),
    ("empty-tolerances", ["run", "tolerances"], [], "run.tolerances"),
    ("unknown-solver", ["run", "solvers"], ["rk4", "rk45"], "run.solvers[1]"),
    ("empty-solvers", ["run", "solvers"], [], "run.solvers"),
    ("duplicate-solver", ["run", "solvers"], ["rk4", "rk4"], "run.solvers"),
    ("unknown-output", ["run", "outputs"], ["state", "plots"], "run.outputs[1]"),
    ("empty-outputs", ["run", "outputs"], [], "run.outputs"),
    ("bad-walls", ["params", "walls"], "ceiling", "params.walls"),
    ("bad-name", ["name"], "Has Spaces", "name"),
    ("quick-not-bool", ["quick"], "yes", "quick"),
    ("mode-and-x", ["initial", "mode"], 1, "initial"),
    ("output_dt-not-dividing", ["run", "output_dt"], 0.3, "run.output_dt"),
    ("convergence-too-few", ["convergence"], {"theta": [0.2, 0.1]}, "convergence.theta"),
]


@pytest.mark.parametrize("case, keys, value, field", BAD, ids=[b[0] for b in BAD])
def test_bad_scene_is_refused_naming_the_field(case, keys, value, field):
    with pytest.raises(SceneError) as info:
        scene_from_dict(_mutate(keys, value), "bad.toml")
    msg = str(info.value)
    assert "\n" not in msg
    assert msg.startswith("bad.toml: field `")
    assert info.value.field == field, msg


def test_valid_base_scene_is_accepted():
    # guards the table above: each bad case differs from an accepted scene in one field
    s = scene_from_dict(copy.deepcopy(VALID), "ok.toml")
    assert s.t_eval().tolist() == pytest.approx([0.0, 0.1 * 1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9, 1.0])


def test_toml_syntax_error_names_the_file(tmp_path):
    bad = tmp_path / "broken.toml"
    bad.write_text('name = "x"\nmodel = \n')
    with pytest.raises(SceneError, match=r"broken\.toml: field `file`: is not valid TOML"):
        load_scene(bad)


def test_two_scenes_with_one_name_are_refused(tmp_path):
    src = (SCENE_DIR / "three_blocks.toml").read_text()
    a, b = tmp_path / "a.toml", tmp_path / "b.toml"
    a.write_text(src)
    b.write_text(src)
    with pytest.raises(SceneError, match="field `name`: is also used by"):
        load_scenes([a, b])
