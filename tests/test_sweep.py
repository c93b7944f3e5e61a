"""[sweep] tables (rk4h.validation.sweeps): a swept scene expands to the
Cartesian product of its lists, in key order; each point is the scene one
would write by hand with that value; its name and sweep columns follow the
documented rules; a bad sweep key is refused with one line naming it."""
import copy
import dataclasses
import re

import pytest

from rk4h.validation import scenes as scenes_mod
from rk4h.validation import sweeps as sweeps_mod
from rk4h.validation.scenes import (MAX_SWEEP_POINTS, SCENE_DIR, Scene, SceneError, load_scene, load_scene_points,
                               load_scenes, resolve_scene, scene_from_dict, scene_points_from_dict)

CHAIN = {
    "name": "tiny",
    "description": "a valid 2-DOF scene the sweeps below vary",
    "model": "chain",
    "params": {"masses": [0.815, 3.099], "springs": [41.5, 138.0, 157.8], "walls": "both"},
    "initial": {"x": [0.005, 0.005], "v": [0.0, 0.0]},
    "run": {"t_end": 1.0, "h": [0.1, 0.05], "tolerances": [1e-6, 1e-8],
            "solvers": ["rk4", "dop853"], "outputs": ["state", "energy"]},
}
PLANAR = {
    "name": "flat",
    "model": "planar4",
    "params": {"m": 0.815, "k": 41.5, "l": 0.01, "linear": False},
    "initial": {"x": [0.001, 0.0]},
    "run": {"t_end": 1.0, "h": [0.1], "solvers": ["rk4"], "outputs": ["state"]},
}
MODE = {**copy.deepcopy(CHAIN), "name": "moded", "initial": {"mode": 1, "amplitude": 1e-3}}
BASES = {"chain": CHAIN, "planar": PLANAR, "mode": MODE}


def _doc(base, sweep, **changes):
    doc = copy.deepcopy(BASES[base])
    for dotted, value in changes.items():
        node = doc
        *parents, last = dotted.split("__")
        for k in parents:
            node = node[k]
        if value is _DELETE:
            del node[last]
        else:
            node[last] = value
    if sweep is not _DELETE:
        doc["sweep"] = sweep
    return doc


_DELETE = object()


def _set(doc, table, steps, value):
    node = doc[table]
    for s in steps[:-1]:
        node = node[s]
    node[steps[-1]] = value


# (case, base, sweep table, expected point names in order, expected sweep dicts in order,
#  where each key lands: key -> (table, steps))
EXPANSIONS = [
    ("one-index", "chain", {"params.masses[1]": [0.5, 1.0, 3.099, 10.0]},
     ["tiny@masses1=0.5", "tiny@masses1=1", "tiny@masses1=3.099", "tiny@masses1=10"],
     [{"masses[1]": v} for v in (0.5, 1.0, 3.099, 10.0)]),
    ("product-first-key-slowest", "chain", {"params.masses[1]": [0.5, 2.0], "run.t_end": [1.0, 2.0, 3.0]},
     [f"tiny@masses1={m}@t_end={t}" for m in ("0.5", "2") for t in ("1", "2", "3")],
     [{"masses[1]": m, "t_end": t} for m in (0.5, 2.0) for t in (1.0, 2.0, 3.0)]),
    ("product-in-key-order", "chain", {"run.t_end": [1.0, 2.0, 3.0], "params.masses[1]": [0.5, 2.0]},
     [f"tiny@t_end={t}@masses1={m}" for t in ("1", "2", "3") for m in ("0.5", "2")],
     [{"t_end": t, "masses[1]": m} for t in (1.0, 2.0, 3.0) for m in (0.5, 2.0)]),
    ("three-keys", "chain", {"params.springs[0]": [40.0, 50.0], "params.springs[2]": [150.0, 160.0],
                             "initial.v[1]": [0.0, 0.1]},
     [f"tiny@springs0={a}@springs2={b}@v1={c}" for a in ("40", "50") for b in ("150", "160")
      for c in ("0", "0.1")],
     [{"springs[0]": a, "springs[2]": b, "v[1]": c} for a in (40.0, 50.0) for b in (150.0, 160.0)
      for c in (0.0, 0.1)]),
    ("negative-values-get-m", "chain", {"initial.x[0]": [-0.01, 0.01]},
     ["tiny@x0=m0.01", "tiny@x0=0.01"], [{"x[0]": -0.01}, {"x[0]": 0.01}]),
    ("unwritten-param", "chain", {"params.alpha": [0.0, 10.0]},
     ["tiny@alpha=0", "tiny@alpha=10"], [{"alpha": 0.0}, {"alpha": 10.0}]),
    ("whole-list-param-by-number", "chain", {"params.springs": [41.5, 100.0]},
     ["tiny@springs=41.5", "tiny@springs=100"], [{"springs": 41.5}, {"springs": 100.0}]),
    ("booleans", "planar", {"params.linear": [True, False]},
     ["flat@linear=true", "flat@linear=false"], [{"linear": True}, {"linear": False}]),
    ("exponents", "planar", {"params.k": [1e-06, 1e+06, 41.5]},
     ["flat@k=1e-06", "flat@k=1e06", "flat@k=41.5"], [{"k": 1e-06}, {"k": 1e+06}, {"k": 41.5}]),
    ("alike-under-g-use-repr", "planar", {"params.k": [1.0000001, 1.0000002, 2.0]},
     ["flat@k=1.0000001", "flat@k=1.0000002", "flat@k=2"], [{"k": 1.0000001}, {"k": 1.0000002}, {"k": 2.0}]),
    ("amplitude-with-mode", "mode", {"initial.amplitude": [1e-4, 1e-3]},
     ["moded@amplitude=0.0001", "moded@amplitude=0.001"], [{"amplitude": 1e-4}, {"amplitude": 1e-3}]),
    ("mode-integers", "mode", {"initial.mode": [1, 2]},
     ["moded@mode=1", "moded@mode=2"], [{"mode": 1}, {"mode": 2}]),
    ("string-values", "chain", {"params.walls": ["both"], "params.masses[0]": [1.0, 2.0]},
     ["tiny@walls=both@masses0=1", "tiny@walls=both@masses0=2"],
     [{"walls": "both", "masses[0]": 1.0}, {"walls": "both", "masses[0]": 2.0}]),
]


@pytest.mark.parametrize("case, base, sweep, names, columns", EXPANSIONS, ids=[e[0] for e in EXPANSIONS])
def test_sweep_expands_to_the_product_in_key_order(case, base, sweep, names, columns):
    points = scene_points_from_dict(_doc(base, sweep), "s.toml")
    n = 1
    for values in sweep.values():
        n *= len(values)
    assert len(points) == n == len(names)
    assert [p.name for p in points] == names
    assert [p.sweep for p in points] == columns
    for p in points:
        assert list(p.sweep) == [k.split(".", 1)[1] for k in sweep]  # columns in key order
        assert p.base == BASES[base]["name"]
        assert isinstance(p, Scene)


@pytest.mark.parametrize("case, base, sweep, names, columns", EXPANSIONS, ids=[e[0] for e in EXPANSIONS])
def test_each_point_is_the_scene_written_by_hand(case, base, sweep, names, columns):
    points = scene_points_from_dict(_doc(base, sweep), "s.toml")
    for p in points:
        hand = copy.deepcopy(BASES[base])
        for key, value in zip(sweep, p.sweep.values()):
            m = re.fullmatch(r"(\w+)\.(\w+)(?:\[(\d+)\])?", key)
            table, name, index = m.groups()
            steps = [name] if index is None else [name, int(index)]
            _set(hand, table, steps, value)
        expected = scene_from_dict(hand, "s.toml")
        got, want = dataclasses.asdict(p), dataclasses.asdict(expected)
        for fld in ("name", "base", "sweep"):
            got.pop(fld), want.pop(fld)
        assert got == want, p.name
        assert p.params == expected.params and p.initial_x == expected.initial_x


def test_unswept_scene_has_empty_sweep_and_base_equal_to_name():
    s = scene_from_dict(copy.deepcopy(CHAIN), "s.toml")
    assert s.sweep == {} and s.base == s.name == "tiny"
    assert [p.name for p in scene_points_from_dict(copy.deepcopy(CHAIN), "s.toml")] == ["tiny"]


def test_one_point_sweep_is_a_scene_and_more_points_are_refused_by_scene_from_dict():
    s = scene_from_dict(_doc("chain", {"params.masses[1]": [2.0]}), "s.toml")
    assert s.name == "tiny@masses1=2" and s.params["masses"] == [0.815, 2.0]
    with pytest.raises(SceneError) as info:
        scene_from_dict(_doc("chain", {"params.masses[1]": [2.0, 3.0]}), "s.toml")
    assert info.value.field == "sweep" and "gives 2 scenes" in str(info.value)


def test_quick_marks_every_point():
    doc = _doc("chain", {"params.masses[1]": [1.0, 2.0, 3.0]})
    doc["quick"] = True
    assert [p.quick for p in scene_points_from_dict(doc, "s.toml")] == [True] * 3
    doc["quick"] = False
    assert [p.quick for p in scene_points_from_dict(doc, "s.toml")] == [False] * 3


def test_points_do_not_share_mutable_parameters():
    a, b = scene_points_from_dict(_doc("chain", {"params.masses[1]": [1.0, 2.0]}), "s.toml")
    assert a.params["masses"] is not b.params["masses"]
    assert (a.params["masses"], b.params["masses"]) == ([0.815, 1.0], [0.815, 2.0])


# -- refused keys -------------------------------------------------------------------
def _wide_keys():
    vals = [1.0 + i / 10 for i in range(11)]
    return {"params.masses[0]": vals, "params.masses[1]": vals, "params.springs[0]": [40.0 + i for i in range(11)]}


# (case, doc, field named, text in the message)
BAD = [
    ("unknown-table", _doc("chain", {"colour.red": [1.0]}), 'sweep."colour.red"', "cannot be swept"),
    ("model-not-sweepable", _doc("chain", {"model.name": ["chain"]}), 'sweep."model.name"', "cannot be swept"),
    ("stability-not-sweepable", _doc("chain", {"stability.studies": [1]}), 'sweep."stability.studies"',
     "cannot be swept"),
    ("convergence-not-sweepable", _doc("chain", {"convergence.t_end": [0.5]}), 'sweep."convergence.t_end"',
     "cannot be swept"),
    ("unknown-param", _doc("chain", {"params.nope": [1.0]}), 'sweep."params.nope"',
     "is not a parameter of model 'chain'"),
    ("param-of-another-model", _doc("planar", {"params.masses[0]": [1.0]}), 'sweep."params.masses[0]"',
     "is not a parameter of model 'planar4'"),
    ("unknown-initial-key", _doc("chain", {"initial.w": [1.0]}), 'sweep."initial.w"', "not a sweepable key"),
    ("run-h-not-sweepable", _doc("chain", {"run.h": [0.1]}), 'sweep."run.h"', "not a sweepable key"),
    ("index-out-of-range", _doc("chain", {"params.masses[2]": [1.0]}), 'sweep."params.masses[2]"',
     "index 2 is out of range"),
    ("index-of-a-number", _doc("planar", {"params.k[0]": [1.0]}), 'sweep."params.k[0]"', "which is not a list"),
    ("index-of-a-string", _doc("chain", {"params.walls[0]": ["left"]}), 'sweep."params.walls[0]"',
     "which is not a list"),
    ("index-of-unwritten-list", _doc("chain", {"initial.v[0]": [1.0]}, initial__v=_DELETE),
     'sweep."initial.v[0]"', "is not in the file"),
    ("key-of-a-list", _doc("chain", {"params.masses.first": [1.0]}), 'sweep."params.masses.first"',
     "which is not a table"),
    ("empty-list", _doc("chain", {"params.masses[1]": []}), 'sweep."params.masses[1]"', "must not be empty"),
    ("not-a-list", _doc("chain", {"params.masses[1]": 1.0}), 'sweep."params.masses[1]"', "must be a list"),
    ("string-not-a-list", _doc("chain", {"params.masses[1]": "1.0"}), 'sweep."params.masses[1]"',
     "must be a list"),
    ("list-element", _doc("chain", {"params.masses": [[1.0, 2.0]]}), 'sweep."params.masses"[0]',
     "must be a number, true/false or a string"),
    ("table-element", _doc("chain", {"params.masses[1]": [1.0, {"a": 1}]}), 'sweep."params.masses[1]"[1]',
     "must be a number, true/false or a string"),
    ("repeated-value", _doc("chain", {"params.masses[1]": [1.0, 2.0, 1]}), 'sweep."params.masses[1]"[2]',
     'repeats sweep."params.masses[1]"[0]'),
    ("string-not-a-word", _doc("chain", {"params.walls": ["both walls"]}), 'sweep."params.walls"[0]',
     "must be a word"),
    ("key-not-a-string", _doc("chain", {1: [1.0]}), "sweep.1", "must be a string path"),
    ("no-dot", _doc("chain", {"params": [1.0]}), 'sweep."params"', "must be a dotted path"),
    ("unquoted-dotted-key", _doc("chain", {"params": {"k": [1.0]}}), 'sweep."params"', "quote the dotted path"),
    ("leading-zero-index", _doc("chain", {"params.masses[01]": [1.0]}), 'sweep."params.masses[01]"',
     "must be a dotted path"),
    ("negative-index", _doc("chain", {"params.masses[-1]": [1.0]}), 'sweep."params.masses[-1]"',
     "must be a dotted path"),
    ("space-in-path", _doc("chain", {"params.masses [1]": [1.0]}), 'sweep."params.masses [1]"',
     "must be a dotted path"),
    ("index-on-table", _doc("chain", {"params[0]": [1.0]}), 'sweep."params[0]"', "must name a key of `params`"),
    ("empty-key", _doc("chain", {"": [1.0]}), 'sweep.""', "must be a dotted path"),
    ("newline-in-key", _doc("chain", {"params.k\n": [1.0]}), "sweep.'params.k\\n'", "must be a dotted path"),
    ("overlapping-keys", _doc("chain", {"params.masses": [1.0], "params.masses[1]": [2.0]}),
     'sweep."params.masses[1]"', 'overlaps sweep."params.masses"'),
    ("sweep-not-a-table", _doc("chain", [1.0]), "sweep", "must be a table"),
    ("sweep-empty", _doc("chain", {}), "sweep", "is empty"),
    ("too-many-points", _doc("chain", _wide_keys()), "sweep", f"above the cap of {MAX_SWEEP_POINTS}"),
    ("missing-model", _doc("chain", {"params.k": [1.0]}, model=_DELETE), "model", "is missing"),
    ("unknown-model", _doc("chain", {"params.k": [1.0]}, model="spring"), "model", "must be one of"),
    # an error in one point names the sweep key, the point's index and value, and the field
    ("point-error", _doc("chain", {"params.masses[1]": [0.5, 1.0, -1.0]}), 'sweep."params.masses[1]"[2]',
     "at params.masses[1] = -1.0: field `params.masses[1]`"),
    ("point-error-two-keys", _doc("chain", {"params.masses[1]": [0.5, 1.0], "run.t_end": [1.0, 0.01]}),
     'sweep."params.masses[1]"[0], sweep."run.t_end"[1]', "at params.masses[1] = 0.5, run.t_end = 0.01: "
     "field `run.h[0]`"),
    ("point-error-amplitude-with-x", _doc("chain", {"initial.amplitude": [1.0]}), 'sweep."initial.amplitude"[0]',
     "field `initial.amplitude`: only goes with `mode`"),
    # ... unless every point fails alike: then it is the file's own error, read as without the sweep
    ("shared-error-is-the-files", _doc("chain", {"params.masses[1]": [0.5, 1.0]}, run__solvers=["rk4", "rk45"]),
     "run.solvers[1]", "must be one of"),
    ("shared-missing-name", _doc("chain", {"params.masses[1]": [0.5, 1.0]}, name=_DELETE), "name", "is missing"),
    ("one-point-error-names-the-point", _doc("chain", {"params.masses[1]": [-1.0]}),
     'sweep."params.masses[1]"[0]', "at params.masses[1] = -1.0: field `params.masses[1]`"),
    ("point-error-unwritten-param", _doc("chain", {"params.alpha": [0.0, float("nan")]}),
     'sweep."params.alpha"[1]', "field `params.alpha`"),
]


@pytest.mark.parametrize("case, doc, fld, text", BAD, ids=[b[0] for b in BAD])
def test_bad_sweep_is_refused_with_one_line_naming_the_key(case, doc, fld, text):
    with pytest.raises(SceneError) as info:
        scene_points_from_dict(copy.deepcopy(doc), "bad.toml")
    msg = str(info.value)
    assert "\n" not in msg, msg
    assert msg.startswith(f"bad.toml: field `{fld}`: "), msg
    assert info.value.field == fld, msg
    assert text in msg, msg


def test_colliding_columns_and_tokens_are_refused(monkeypatch):
    # no built-in model has a parameter named like an [initial] key: give one to the chain
    real = sweeps_mod._model_keys
    monkeypatch.setattr(sweeps_mod, "_model_keys", lambda name: set(real(name)) | {"amplitude", "masses1"})
    with pytest.raises(SceneError) as info:
        scene_points_from_dict(_doc("mode", {"initial.amplitude": [1.0], "params.amplitude": [2.0]}), "bad.toml")
    assert info.value.field == 'sweep."params.amplitude"' and "column `amplitude`" in str(info.value)
    with pytest.raises(SceneError) as info:
        scene_points_from_dict(_doc("chain", {"params.masses[1]": [1.0], "params.masses1": [2.0]}), "bad.toml")
    assert info.value.field == 'sweep."params.masses1"' and "token `masses1`" in str(info.value)


def test_point_names_colliding_as_figure_stems_are_refused(monkeypatch):
    # 'a.b' and 'a-b' are both words; the figure stem turns '.' and '-' alike into '_'. No built-in
    # string parameter takes such words: let each point validate as walls = "both".
    real = scenes_mod._scene_from_dict

    def lenient(doc, path):
        doc["params"]["walls"] = "both"
        return real(doc, path)

    monkeypatch.setattr(scenes_mod, "_scene_from_dict", lenient)
    with pytest.raises(SceneError) as info:
        scene_points_from_dict(_doc("chain", {"params.walls": ["a.b", "a-b"]}), "bad.toml")
    assert info.value.field == 'sweep."params.walls"[1]' and "figure-file stem" in str(info.value)


def test_bad_sweep_in_a_file_is_refused_by_load_scenes(tmp_path):
    p = tmp_path / "bad.toml"
    p.write_text((SCENE_DIR / "sweep_2dof_mass_ratio.toml").read_text()
                 .replace('"params.masses[1]" =', '"params.masses[2]" ='))
    with pytest.raises(SceneError) as info:
        load_scenes([p])
    assert str(info.value).startswith(f'{p}: field `sweep."params.masses[2]"`: index 2 is out of range')


def test_unquoted_dotted_key_in_a_file_is_refused(tmp_path):
    p = tmp_path / "bad.toml"
    p.write_text((SCENE_DIR / "sweep_2dof_mass_ratio.toml").read_text()
                 .replace('"params.masses[1]" =', 'params.springs ='))
    with pytest.raises(SceneError) as info:
        load_scene_points(p)
    assert info.value.field == 'sweep."params"' and "quote" in str(info.value)


# -- names ------------------------------------------------------------------------
@pytest.mark.parametrize("name", ["tiny@masses1=0.5", "tiny@x0=m0.01", "flat@k=1e-06", "flat@k=1e06",
                                  "a-b_c@springs1_2=1e-300@t_end=3.5", "flat@linear=true"])
def test_point_stem_agrees_with_the_figure_slug(name):
    from rk4h.validation.figures import slug

    assert scenes_mod._figure_stem(name) == slug(name)
    assert re.fullmatch(r"[a-z0-9_]+", slug(name))


@pytest.mark.parametrize("values", [[-0.5, 0.5], [1e-05, 1e+05, -1e-05, -1e+05], [1.5, 15.0, 0.15, -1.5],
                                    [1, 1.0000001, 1.0000002, -1]])
def test_point_names_and_figure_stems_are_unique(values):
    points = scene_points_from_dict(_doc("chain", {"initial.x[0]": values}), "s.toml")
    names = [p.name for p in points]
    assert len(set(names)) == len(set(map(scenes_mod._figure_stem, names))) == len(values)
    for n in names:
        assert re.fullmatch(r"tiny@x0=[a-z0-9.-]+", n), n
        assert not scenes_mod._name_pattern().fullmatch(n)  # never a name a file may hold
    # the name's value reads back as the value
    for p, v in zip(points, values):
        text = p.name.split("=", 1)[1]
        assert float(text.replace("m", "-", 1) if text.startswith("m") else text) == pytest.approx(v, rel=1e-5)


def test_names_in_files_keep_their_rule():
    with pytest.raises(SceneError) as info:
        scene_points_from_dict(_doc("chain", {"params.masses[1]": [1.0]}, name="tiny@masses1=1"), "bad.toml")
    assert "field `name`" in str(info.value)


# -- loading ------------------------------------------------------------------------
def _write(tmp_path, fname, doc_text):
    p = tmp_path / fname
    p.write_text(doc_text)
    return p


def test_load_scene_refuses_a_sweep_and_load_scene_points_expands_it(tmp_path):
    path = SCENE_DIR / "sweep_2dof_mass_ratio.toml"
    with pytest.raises(SceneError) as info:
        load_scene(path)
    assert info.value.field == "sweep" and "load_scene_points" in str(info.value)
    assert len(load_scene_points(path)) == 5
    unswept = SCENE_DIR / "thesis_2dof_case1.toml"
    assert [s.name for s in load_scene_points(unswept)] == [load_scene(unswept).name] == ["thesis-2dof-case1"]


def test_load_scenes_flattens_points_in_file_order():
    a, b = SCENE_DIR / "sweep_2dof_mass_ratio.toml", SCENE_DIR / "three_blocks.toml"
    names = [s.name for s in load_scenes([a, b])]
    assert names == [s.name for s in load_scene_points(a)] + ["three-blocks"]
    everything = load_scenes()
    assert len({s.name for s in everything}) == len(everything)
    assert sum(s.base == "sweep-2dof-mass-ratio" for s in everything) == 5
    assert sum(s.base == "sweep-planar4-amplitude" for s in everything) == 5


def test_same_sweep_twice_is_refused(tmp_path):
    text = (SCENE_DIR / "sweep_2dof_mass_ratio.toml").read_text()
    a, b = _write(tmp_path, "a.toml", text), _write(tmp_path, "b.toml", text)
    with pytest.raises(SceneError, match="field `name`: is also used by"):
        load_scenes([a, b])


def test_file_whose_name_is_a_points_figure_stem_is_refused(tmp_path):
    text = (SCENE_DIR / "sweep_2dof_mass_ratio.toml").read_text()
    a = _write(tmp_path, "a.toml", text)
    other = text.split("[sweep]")[0].replace('name = "sweep-2dof-mass-ratio"',
                                             'name = "sweep-2dof-mass-ratio-masses1-0-815"')
    b = _write(tmp_path, "b.toml", other)
    with pytest.raises(SceneError, match="figure files would collide"):
        load_scenes([a, b])


def test_one_point_by_name_and_swept_scene_by_name():
    [s] = load_scenes(["sweep-2dof-mass-ratio@masses1=0.815"])
    assert s.sweep == {"masses[1]": 0.815} and s.params["masses"] == [0.815, 0.815]
    with pytest.raises(SceneError) as info:
        load_scenes(["sweep-2dof-mass-ratio@masses1=0.9"])
    assert "has no point 'sweep-2dof-mass-ratio@masses1=0.9'" in str(info.value)
    assert resolve_scene("sweep-2dof-mass-ratio") == SCENE_DIR / "sweep_2dof_mass_ratio.toml"
    assert resolve_scene("sweep_planar4_amplitude") == SCENE_DIR / "sweep_planar4_amplitude.toml"
    assert len(load_scenes(["sweep-planar4-amplitude"])) == 5


# -- the shipped sweeps -------------------------------------------------------------
def test_shipped_mass_ratio_sweep():
    points = load_scene_points(SCENE_DIR / "sweep_2dof_mass_ratio.toml")
    m1 = 0.815
    m2 = [0.0815, 0.2445, 0.815, 3.099, 8.15]
    assert [p.sweep for p in points] == [{"masses[1]": v} for v in m2]
    assert [p.params["masses"] for p in points] == [[m1, v] for v in m2]
    assert [p.name for p in points] == [f"sweep-2dof-mass-ratio@masses1={v:g}" for v in m2]
    assert min(m2) / m1 == pytest.approx(0.1) and max(m2) / m1 == pytest.approx(10.0)
    assert {p.base for p in points} == {"sweep-2dof-mass-ratio"} and not any(p.quick for p in points)
    # the thesis' point is thesis-2dof-case1's physics
    thesis = load_scene(SCENE_DIR / "thesis_2dof_case1.toml")
    [p] = [p for p in points if p.sweep["masses[1]"] == 3.099]
    assert (p.model, p.params, p.initial_x, p.initial_v) == (thesis.model, thesis.params, thesis.initial_x,
                                                            thesis.initial_v)
    for p in points:  # cheap: few steps and tolerances, a short horizon
        assert p.t_end <= 10 and len(p.h) <= 3 and len(p.tolerances) <= 2
        assert {"state", "energy", "work_precision", "convergence", "modes"} <= set(p.outputs)


def test_shipped_amplitude_sweep():
    points = load_scene_points(SCENE_DIR / "sweep_planar4_amplitude.toml")
    assert len(points) == 5
    l = points[0].params["l"]
    amplitudes = [p.sweep["x[0]"] for p in points]
    assert amplitudes == sorted(amplitudes)
    assert amplitudes[0] == pytest.approx(1e-4 * l) and amplitudes[-1] == pytest.approx(0.3 * l)
    for p, a in zip(points, amplitudes):
        assert p.model == "planar4" and p.params["linear"] is False
        assert p.initial_x == [a, 0.0] and p.initial_v == [0.0, 0.0]
        assert p.name == f"sweep-planar4-amplitude@x0={a:g}" and p.base == "sweep-planar4-amplitude"
        assert not p.quick and p.t_end <= 10 and len(p.h) <= 3 and len(p.tolerances) <= 2
