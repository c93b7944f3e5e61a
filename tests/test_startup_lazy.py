"""What a process imports and builds before its first run (issue 29, start-up):
the scene module without pydantic (a worker unpickling its jobs never loads
it), the scene schema's variants built per model on first use, and the
per-variant validation giving the same answers and errors as the union."""
import copy
import pickle
import subprocess
import sys
import tomllib
from fractions import Fraction

import pytest
from pydantic import ValidationError

from rk4h.validation import scene_schema as SS
from rk4h.validation import scenes as S


def _fresh(code: str) -> str:
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=180, check=True)
    return out.stdout.strip().splitlines()[-1]


# -- the scene module and the schema: imported when a scene is validated ----------------------------------------
def test_importing_the_scene_module_loads_neither_pydantic_nor_the_schema():
    code = ("import sys, rk4h.validation.scenes, rk4h.validation.sweeps; "
            "print(sorted(m for m in ('pydantic', 'rk4h.validation.scene_schema', 'scipy.sparse') "
            "if m in sys.modules))")
    assert _fresh(code) == "[]"


def test_unpickling_a_scene_loads_neither_pydantic_nor_the_schema(tmp_path):
    """What a worker process pays to receive a job's scene."""
    scene = S.load_scenes(["three_blocks"])[0]
    blob = tmp_path / "scene.pkl"
    blob.write_bytes(pickle.dumps(scene))
    code = (f"import pickle, sys; s = pickle.loads(open({str(blob)!r}, 'rb').read()); "
            "print(s.name, sorted(m for m in ('pydantic', 'rk4h.validation.scene_schema') if m in sys.modules))")
    assert _fresh(code) == "three-blocks []"


def test_loading_a_scene_builds_only_its_models_variant():
    """... and a scene without an [ensemble] table does not import the ensemble module."""
    code = ("import sys; from rk4h.validation.scenes import load_scenes; "
            "from rk4h.validation import scene_schema as SS; load_scenes(['thesis-2dof-case1']); "
            "print(sorted(SS.SCENE_MODELS._built), sorted(SS.BUILTIN_MODELS._built), "
            "'rk4h.validation.ensemble' in sys.modules)")
    assert _fresh(code) == "['chain'] ['chain'] False"


def test_the_lazy_names_are_those_of_the_schema():
    assert S.OUTPUTS == SS.OUTPUTS
    assert set(SS.TOP_KEYS) == set(SS.SCENE_MODELS["user"].model_fields)
    assert S._name_pattern().pattern == SS.NAME_PATTERN.strip("^$")
    assert list(SS.SCENE_MODELS) == [*SS.BUILTIN_MODELS, "user"]
    assert "chain" in SS.BUILTIN_MODELS and "user" not in SS.BUILTIN_MODELS and 3 not in SS.SCENE_MODELS
    with pytest.raises(KeyError):
        SS.SCENE_MODELS["no-such-model"]
    with pytest.raises(AttributeError):
        S.no_such_name  # noqa: B018


# -- validation by the one variant = validation by the union ----------------------------------------------------
def _shipped_docs():
    return [tomllib.loads(f.read_text(encoding="utf-8")) for f in sorted(S.SCENE_DIR.glob("*.toml"))]


def _broken(doc):
    """Documents each breaking ``doc`` in one place (and ``doc`` itself)."""
    out = [doc]
    for edit in (lambda d: d.update(colour="red"),                      # unknown top-level key
                 lambda d: d.pop("model"),                               # missing key
                 lambda d: d.update(model=3),                            # wrong type, no variant of its own
                 lambda d: d.update(model="no_such_pkg.mod:Model"),      # the user's variant
                 lambda d: d["run"].update(t_end=-1.0),                  # bound
                 lambda d: d["run"].update(h=[0.1, "x"]),                # list entry
                 lambda d: d["run"].update(solvers=["rk4", "rk4"]),      # a rule
                 lambda d: d["run"].update(outputs=["nope"]),            # the output registry
                 lambda d: d["run"].update(tolerances=[1.5]),            # open unit interval
                 lambda d: d.setdefault("initial", {}).update(amplitude=2.0, colour=1),
                 lambda d: d.update(params={**d.get("params", {}), "masses": [-1.0]}),
                 lambda d: d.update(params=7),
                 lambda d: d.update(stability={"studies": ["nope"]}),
                 lambda d: d.update(name="Bad Name")):
        d = copy.deepcopy(doc)
        try:
            edit(d)
        except (KeyError, TypeError, AttributeError):
            continue
        out.append(d)
    return out


def _by_union(doc):
    try:
        return "ok", SS.SCENE.validate_python(doc).model_dump(warnings=False)
    except ValidationError as e:
        return "error", SS.first_error(e, doc)


def _by_variant(doc):
    try:
        return "ok", SS.validate(doc).model_dump(warnings=False)
    except ValidationError as e:
        return "error", SS.validation_error(e, doc)


@pytest.mark.parametrize("doc", [d for doc in _shipped_docs() for d in _broken(doc)])
def test_validating_by_the_variant_answers_as_the_union(doc):
    assert _by_variant(doc) == _by_union(doc)



# -- the shipped geometric methods' irrational coefficients: data, checked here ---------------------------------
def test_importing_rk4h_does_not_load_mpmath():
    assert _fresh("import sys, rk4h, rk4h.references.registry; print('mpmath' in sys.modules)") == "False"


def test_stored_irrational_coefficients_are_those_evaluated(monkeypatch):
    from rk4h import geometric as G

    stored = dict(G._EVALUATED)
    assert len(stored) == 6
    with_table = {text: G.coefficient(text) for text in stored}
    monkeypatch.setattr(G, "_EVALUATED", {})
    for text, scaled in stored.items():
        value, bound = G.coefficient(text)  # parsed and evaluated with mpmath
        assert value == Fraction(scaled, 2**G.BITS) and (value, bound) == with_table[text], text
        assert value.denominator != 1 and bound > 0  # irrational: kept to BITS bits, with a bound


def test_every_irrational_coefficient_of_the_shipped_methods_is_stored():
    """Building the shipped methods evaluates no expression (mpmath cannot even be
    imported here): each irrational coefficient they hold is stored, so with the test
    above they are the tableaux evaluated before."""
    code = ("import sys; sys.modules['mpmath'] = None; import rk4h; "
            "from rk4h.geometric import GEOMETRIC; print(sorted(GEOMETRIC))")
    assert _fresh(code) == str(sorted(["yoshida4", "yoshida6", "suzuki4", "forest-ruth", "blanes-moan4",
                                       "blanes-moan6"]))
