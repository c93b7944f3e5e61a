"""The scene schema declared once (rk4h.validation.scene_schema): the generated
reference and the schema hold the same keys, every documented example loads,
the committed reference and JSON Schema are current, the shipped scenes pass
the JSON Schema, an unknown key at any level is one line naming it, and
``run.outputs`` defaults to what applies to the model."""
import copy
import inspect
import json
import re
import tomllib
from pathlib import Path
from typing import Annotated, get_args, get_origin

import numpy as np
import pytest
from pydantic import BaseModel

import rk4h
from rk4h.models import MODELS, model_parameters
from rk4h.validation import scene_schema
from rk4h.validation import outputs as registry
from rk4h.validation.scenes import SCENE_DIR, SceneError, default_outputs, scene_from_dict, scene_points_from_dict

REPO = Path(__file__).resolve().parent.parent
BASE = {"name": "ref", "model": "chain",
        "params": {"masses": [0.815, 3.099], "springs": [41.5, 138.0, 157.8]},
        "initial": {"x": [0.005, 0.005]},
        "run": {"t_end": 1.0, "h": [0.1, 0.05], "tolerances": [1e-6, 1e-8], "solvers": ["rk4", "dop853"]}}
HEADER = "| key | type | unit | default | example | description |"


# -- the reference, read as a user reads it ---------------------------------------------
def _section(heading: str):
    """A heading of the reference -> the section its key table documents (None: no key table)."""
    if heading == "Top level":
        return "top"
    m = re.fullmatch(r'`\[params\]` of `model = "(\w+)"`', heading)
    if m:
        return f"params:{m.group(1)}"
    m = re.fullmatch(r"`\[(initial|run|convergence|energy_work_precision|methods\.NAME|stability)\]`", heading)
    return m.group(1).split(".")[0] if m else None


def reference_rows(text: str) -> dict:
    """``{(section, key): example}`` of every key table of the Markdown reference."""
    rows, section, in_table = {}, None, False
    for line in text.splitlines():
        if line.startswith("#"):
            section, in_table = _section(line.lstrip("#").strip()), False
        elif line == HEADER:
            in_table = section is not None
        elif in_table and line.startswith("| `"):
            cells = [c.strip() for c in re.split(r"(?<!\\)\|", line)[1:-1]]
            key, example = cells[0].strip("`"), cells[4]
            assert example.startswith("`") and example.endswith("`"), line
            rows[(section, key)] = tomllib.loads(f"v = {example[1:-1]}")["v"]
        elif not line.startswith("|"):
            in_table = False
    return rows


def _nested(annotation):
    """The pydantic table an annotation holds (a ``dict``'s value table too), else None."""
    while get_origin(annotation) is Annotated:
        annotation = get_args(annotation)[0]
    if get_origin(annotation) is dict:
        return _nested(get_args(annotation)[1])
    return annotation if isinstance(annotation, type) and issubclass(annotation, BaseModel) else None


def schema_keys() -> set:
    """``(section, key)`` of every key the schema accepts, walked from the top-level variants."""
    keys = set()
    for tag, variant in scene_schema.SCENE_MODELS.items():
        for name, info in variant.model_fields.items():
            keys.add(("top", name))
            table = _nested(info.annotation)
            if table is None:
                continue
            section = f"params:{tag}" if name == "params" else name
            keys |= {(section, k) for k in table.model_fields}
    return keys


REFERENCE = reference_rows(scene_schema.reference_markdown())


def test_the_reference_lists_every_key_the_schema_accepts_and_no_other():
    documented, accepted = set(REFERENCE), schema_keys()
    assert accepted - documented == set(), "keys the schema accepts that the reference does not list"
    assert documented - accepted == set(), "keys the reference lists that the schema does not declare"
    assert len(documented) > 70  # every section was read


def test_the_key_comparison_can_fail():
    text = scene_schema.reference_markdown()
    row = next(line for line in text.splitlines() if line.startswith("| `output_dt` |"))
    assert ("run", "output_dt") in schema_keys() - set(reference_rows(text.replace(row + "\n", "")))
    doc = _with_key("run", "colour", "red")  # a row the schema would not accept
    with pytest.raises(SceneError, match="field `run.colour`: unknown key"):
        scene_points_from_dict(doc, "ref.toml")


def _params_base(model: str) -> dict:
    """The scene of ``model`` built from the reference's examples of its required keys."""
    required, _ = model_parameters(model)
    params = {k: copy.deepcopy(REFERENCE[(f"params:{model}", k)]) for k in required}
    m = rk4h.make_model(model, dict(params))
    n = m.n_dof
    if getattr(m, "first_order", False):  # any ODE: [initial] y, only the methods of a first-order system
        return {**copy.deepcopy(BASE), "model": model, "params": params,
                "initial": {"y": copy.deepcopy(REFERENCE[("initial", "y")])}}
    return {**copy.deepcopy(BASE), "model": model, "params": params, "initial": {"x": [1e-3] + [0.0] * (n - 1)}}


#: [methods.NAME] keys that need others beside them: a tableau needs A and b, a partitioned one
#: both halves, a python or command method its order.
_METHOD_COMPANIONS = {"A": ("b",), "b": ("A",), "c": ("A", "b"), "A_v": ("A", "b", "b_v"), "b_v": ("A", "b", "A_v"),
                      "description": ("A", "b"), "python": ("order",), "order": ("python",),
                      "nfev_per_step": ("python", "order"), "command": ("order",),
                      "kind": ("a", "b"), "a": ("kind", "b"), "base": ("kind", "gamma"), "gamma": ("kind", "base")}


def _with_key(section: str, key: str, value) -> dict:
    """A minimal valid scene plus ``key`` of ``section`` set to ``value``."""
    ex = lambda s, k: copy.deepcopy(REFERENCE[(s, k)])  # noqa: E731
    if section.startswith("params:"):
        doc = _params_base(section.split(":")[1])
        doc["params"][key] = value
        return doc
    doc = copy.deepcopy(BASE)
    if section == "top":
        doc[key] = value
    elif section == "initial" and key == "y":  # the state of a first-order ODE (model `ode`)
        doc = _params_base("ode")
        doc["initial"] = {"y": value}
    elif section == "initial" and key in ("mode", "amplitude"):
        doc["initial"] = {"mode": ex("initial", "mode"), key: value}
    elif section == "methods":
        doc["methods"] = {"mine": {**{k: ex("methods", k) for k in _METHOD_COMPANIONS[key]}, key: value}}
        if key in ("base", "gamma"):  # the example kind is a splitting's
            doc["methods"]["mine"]["kind"] = "composition"
    elif section == "stability":
        doc["stability"] = {"studies": ex("stability", "studies"), key: value}
    else:
        doc.setdefault(section, {})[key] = value
    return doc


@pytest.mark.parametrize("section, key", sorted(REFERENCE), ids=[f"{s}.{k}" for s, k in sorted(REFERENCE)])
def test_every_documented_key_is_accepted_with_its_example(section, key):
    doc = _with_key(section, key, REFERENCE[(section, key)])
    points = scene_points_from_dict(doc, "ref.toml")  # the sweep row's example gives two points
    assert len(points) == (2 if (section, key) == ("top", "sweep") else 1)


def test_the_builtin_tables_are_the_model_registry():
    from rk4h.models import BUILTIN_CLASSES

    assert list(scene_schema.BUILTIN_MODELS) == [cls.name for cls in BUILTIN_CLASSES]
    assert all(c.parameters is not None and c.summary for c in BUILTIN_CLASSES)


@pytest.mark.parametrize("model", sorted(scene_schema.BUILTIN_MODELS))
def test_each_params_table_matches_the_models_constructor(model):
    """The table generated from the declaration, the declaration and the
    constructor's signature agree: names in order, required, defaults."""
    table = scene_schema.BUILTIN_MODELS[model]
    required, optional = model_parameters(model)
    assert list(table.model_fields) == required + optional
    sig = {k: v for k, v in inspect.signature(MODELS[model].__init__).parameters.items() if k != "self"}
    assert list(sig) == required + optional
    for name, info in table.model_fields.items():
        assert info.is_required() == (name in required) == (sig[name].default is inspect.Parameter.empty), name
        if not info.is_required():
            default = sig[name].default
            assert info.default == (list(default) if isinstance(default, tuple) else default), name
        assert (info.json_schema_extra or {}).get("unit"), name


def test_method_keys_are_the_registrys():
    from rk4h.references.registry import _KEYS

    assert set(scene_schema.MethodTable.model_fields) == _KEYS


def test_stability_keys_are_the_params_table():
    from rk4h.validation.stability.params import PARAMS

    assert list(scene_schema.Stability.model_fields) == [p.name for p in PARAMS]


# -- the committed files are what the generator prints ------------------------------------
@pytest.mark.parametrize("flag, path", [("--markdown", "docs/scene-reference.md"),
                                        ("--json-schema", "docs/scene.schema.json")], ids=["markdown", "json"])
def test_committed_reference_is_current(capsys, flag, path):
    assert scene_schema.main([flag]) == 0
    printed = capsys.readouterr().out
    assert (REPO / path).read_text(encoding="utf-8") == printed, \
        f"stale: run python -m rk4h.validation.scene_schema {flag} > {path}"


# -- the JSON Schema accepts the shipped scenes -----------------------------------------------
SHIPPED = sorted(SCENE_DIR.glob("*.toml"))


@pytest.fixture(scope="module")
def validator():
    jsonschema = pytest.importorskip("jsonschema", reason="jsonschema is not installed (an optional check)")
    schema = json.loads((REPO / "docs" / "scene.schema.json").read_text(encoding="utf-8"))
    jsonschema.Draft202012Validator.check_schema(schema)
    return jsonschema.Draft202012Validator(schema)


@pytest.mark.parametrize("path", SHIPPED, ids=lambda p: p.stem)
def test_shipped_scene_passes_the_json_schema(validator, path):
    doc = tomllib.loads(path.read_text(encoding="utf-8"))
    errors = [f"{list(e.absolute_path)}: {e.message}" for e in validator.iter_errors(doc)]
    assert errors == []


@pytest.mark.parametrize("change", [
    lambda d: d.update(colour="red"), lambda d: d["run"].update(t_end=-1.0), lambda d: d.update(model="spring"),
    lambda d: d["params"].update(walls="ceiling"), lambda d: d["run"].update(outputs=["plots"]),
], ids=["unknown-key", "negative-t_end", "unknown-model", "bad-walls", "unknown-output"])
def test_json_schema_refuses_what_the_harness_refuses(validator, change):
    doc = copy.deepcopy(BASE)
    change(doc)
    assert not validator.is_valid(doc)
    with pytest.raises(SceneError):
        scene_from_dict(doc, "bad.toml")


# -- one line naming the unknown key, at every level ----------------------------------------
UNKNOWN = [
    ("top", lambda d: d.update(colour="red"), "colour"),
    ("params-chain", lambda d: d["params"].update(mass=1.0), "params.mass"),
    ("params-planar4", lambda d: d.update(_params_base("planar4"), params={**_params_base("planar4")["params"],
                                                                           "masses": 1.0}), "params.masses"),
    ("params-network", lambda d: d.update(_params_base("network"), params={**_params_base("network")["params"],
                                                                           "walls": "both"}), "params.walls"),
    ("params-potential", lambda d: d.update(_params_base("potential"),
                                            params={**_params_base("potential")["params"], "V": "x^2"}), "params.V"),
    ("initial", lambda d: d["initial"].update(w=1.0), "initial.w"),
    ("run", lambda d: d["run"].update(steps=10), "run.steps"),
    ("convergence", lambda d: d.update(convergence={"thetas": [0.1, 0.05, 0.025]}), "convergence.thetas"),
    ("methods", lambda d: d.update(methods={"mine": {"A": [["0"]], "b": ["1"], "colour": "red"}}),
     "methods.mine.colour"),
    ("stability", lambda d: d.update(stability={"studies": ["boundary"], "colour": "red"}), "stability.colour"),
]


@pytest.mark.parametrize("level, change, field", UNKNOWN, ids=[u[0] for u in UNKNOWN])
def test_unknown_key_is_one_line_naming_it(level, change, field):
    doc = copy.deepcopy(BASE)
    change(doc)
    with pytest.raises(SceneError) as info:
        scene_from_dict(doc, "bad.toml")
    msg = str(info.value)
    assert "\n" not in msg and info.value.field == field, msg
    assert msg.startswith(f"bad.toml: field `{field}`: ") and "known" in msg, msg


@pytest.mark.parametrize("key, value, field, shown", [
    ("run.t_end", "1.0", "run.t_end", "must be a number (got '1.0')"),
    ("run.h", [0.1, True], "run.h[1]", "must be a number (got True)"),
    ("quick", 1, "quick", "must be true or false (got 1)"),
    ("initial.mode", 1.0, "initial.mode", "must be an integer (got 1.0)"),
    ("params.masses", {"a": 1.0}, "params.masses", "must be a number or a list of numbers (got {'a': 1.0})"),
    ("run.solvers", "rk4", "run.solvers", "must be a list (got 'rk4')"),
], ids=["string-number", "bool-in-list", "int-for-bool", "float-for-int", "table-for-number", "string-for-list"])
def test_toml_types_are_kept_strict(key, value, field, shown):
    doc = copy.deepcopy(BASE)
    table, _, name = key.rpartition(".")
    if name == "mode":
        doc["initial"] = {}
    (doc[table] if table else doc)[name] = value
    with pytest.raises(SceneError) as info:
        scene_from_dict(doc, "bad.toml")
    assert info.value.field == field and str(info.value) == f"bad.toml: field `{field}`: {shown}"


# -- run.outputs defaults to every output that applies to the model -------------------------
class NoLinearization(rk4h.Model):
    """A model without a stiffness matrix: nothing modal applies."""

    name = "no-linearization-test"
    linear = False

    def __init__(self, m, k):
        self.m, self.k = float(m), float(k)
        self.n_dof, self.mass, self.coord_names = 1, np.array([self.m]), ["x"]

    def params(self):
        return {"m": self.m, "k": self.k}

    def _potential(self, q, ops):
        return 0.25 * self.k * q[0] ** 4

    def _force(self, q, ops):
        f = -self.k * q[0] ** 3
        return np.array([f], dtype=object) if q.dtype == object else np.asarray(f)[None]


@pytest.fixture
def no_linearization():
    rk4h.register_model(NoLinearization)
    yield NoLinearization.name
    MODELS.pop(NoLinearization.name, None)


#: The built-in rules: outputs every model gets, those a linearization adds.
EVERY = ["state", "energy", "work_precision", "figures"]
MODAL = EVERY + ["convergence", "modes", "modal_energy"]
#: Built-ins only some models (or no default) get.
SPECIAL = ["dispersion", "linearization", "stability", "thesis_code", "trajectory"]


def _defaults_hold(outputs, including):
    """``outputs`` (a scene's default) holds ``including``, no other output of
    :data:`SPECIAL`, and is in the registry's order. Outputs the test does not
    name (a later registration) are left to their own ``applies``."""
    assert set(including) <= set(outputs), sorted(set(including) - set(outputs))
    assert not (set(SPECIAL) - set(including)) & set(outputs)
    assert outputs == [o for o in registry.names() if o in outputs]


def test_the_rules_name_registered_outputs():
    assert set(MODAL + SPECIAL) <= set(registry.names())


OUTPUT_CASES = [
    ("chain", lambda d: None, MODAL),
    ("uniform-chain-has-dispersion", lambda d: d["params"].update(masses=1.0, springs=1.0, n=2),
     MODAL + ["dispersion"]),
    ("nonlinear-planar4-has-linearization", lambda d: d.update(_params_base("planar4")),
     MODAL + ["linearization"]),
    ("linear-planar4", lambda d: d.update(_params_base("planar4"), params={**_params_base("planar4")["params"],
                                                                           "linear": True}), MODAL),
    ("stability-table", lambda d: d.update(stability={"studies": ["boundary"]}), MODAL + ["stability"]),
]


@pytest.mark.parametrize("case, change, expected", OUTPUT_CASES, ids=[c[0] for c in OUTPUT_CASES])
def test_outputs_default_to_what_applies(case, change, expected):
    doc = copy.deepcopy(BASE)
    change(doc)
    scene = scene_from_dict(doc, "ok.toml")
    _defaults_hold(scene.outputs, expected)


def test_explicit_outputs_are_kept():
    doc = copy.deepcopy(BASE)
    doc["run"].update(outputs=["energy"])
    assert scene_from_dict(doc, "ok.toml").outputs == ["energy"]


def test_a_model_without_linearization_gets_no_modal_output(no_linearization):
    doc = {**copy.deepcopy(BASE), "model": no_linearization, "params": {"m": 1.0, "k": 4.0},
           "initial": {"x": [0.1]}}
    got = scene_from_dict(doc, "ok.toml").outputs
    _defaults_hold(got, EVERY)
    assert not set(MODAL[len(EVERY):]) & set(got)


def test_each_sweep_point_gets_its_own_default():
    doc = {**copy.deepcopy(BASE), "params": {"masses": [0.815, 0.815], "springs": 41.5},
           "sweep": {"params.masses[1]": [0.815, 1.0]}}
    uniform, other = scene_points_from_dict(doc, "ok.toml")
    assert "dispersion" in uniform.outputs and "dispersion" not in other.outputs


def test_a_huge_chain_defaults_to_stability_only():
    n = 6000
    doc = {**copy.deepcopy(BASE), "params": {"masses": 1.0, "springs": 1.0, "n": n},
           "initial": {"x": [1e-3] + [0.0] * (n - 1)}}
    with pytest.raises(SceneError) as info:
        scene_from_dict(copy.deepcopy(doc), "big.toml")
    assert info.value.field == "run.outputs" and "[stability]" in str(info.value)
    doc["stability"] = {"studies": ["large_n"]}
    assert scene_from_dict(doc, "big.toml").outputs == ["stability"]


def test_default_outputs_reads_the_model_not_its_name():
    chain = rk4h.make_model("chain", {"masses": [1.0, 1.0, 1.0], "springs": [2.0] * 4})
    assert "dispersion" in default_outputs(chain) and "stability" in default_outputs(chain, stability=True)
    assert "dispersion" not in default_outputs(rk4h.make_model("chain", {"masses": [1.0, 2.0, 1.0],
                                                                            "springs": [2.0] * 4}))
