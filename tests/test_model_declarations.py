"""A model declares its parameters once (``parameters``: Param rows) and the
scene's ``[params]`` table, its checks and the scene reference follow from
that declaration, for a built-in and for a user's model alike."""
import json
import subprocess
import sys
import textwrap
from pathlib import Path

import pandas as pd
import pytest

from rk4h.models import (BUILTIN_CLASSES, MODELS, Param, declared, example_parameters, make_model,
                            model_parameters, register_model)
from rk4h.validation import scene_schema
from rk4h.validation.run_all import main
from rk4h.validation.scenes import SceneError, load_scene

REPO = Path(__file__).resolve().parent.parent

#: One file: a 1-DOF Morse oscillator, declared, defined by its potential.
MORSE_FILE = '''
"""A particle in a Morse well: V = D (1 - exp(-a x))^2."""
from rk4h import Defined, PotentialModel
from rk4h.models import Param, ParamRule


class Morse(Defined):
    name = "morse-test"
    summary = "A particle in a Morse well V = D (1 - exp(-a x))^2."
    parameters = (
        Param("m", "normal", "kg", "the particle's mass", 1.0),
        Param("D", "normal", "J", "depth of the well", 2.0),
        Param("a", "normal", "1/m", "inverse width of the well", 1.5, default=1.0),
    )

    @classmethod
    def check_parameters(cls, values):
        if values["D"] > 1e6:
            raise ParamRule("D", "must be at most 1e6 (a test rule)", values["D"])

    def __init__(self, m, D, a=1.0):
        self.m, self.D, self.a = float(m), float(D), float(a)
        self._adopt(lambda: PotentialModel(["x"], [self.m], "D*(1 - exp(-a*x))^2", {"D": self.D, "a": self.a}),
                    "D")
        self.coord_names = ["x"]

    def params(self):
        return {"m": self.m, "D": self.D, "a": self.a}
'''

SCENE = '''
name = "morse"
model = "{model}"
[params]
{params}
[initial]
x = [0.2]
[run]
t_end = 4.0
h = [0.04, 0.02]
tolerances = [1e-8]
solvers = ["rk4", "dop853"]
outputs = ["state", "energy"]
'''


@pytest.fixture
def morse_module(tmp_path, monkeypatch):
    pkg = tmp_path / "usermods"
    pkg.mkdir()
    (pkg / "morse_model.py").write_text(MORSE_FILE)
    monkeypatch.syspath_prepend(str(pkg))
    yield "morse_model"
    MODELS.pop("morse-test", None)
    sys.modules.pop("morse_model", None)


def _scene(tmp_path, model, params="m = 1.0\nD = 2.0\na = 1.5"):
    path = tmp_path / "morse.toml"
    path.write_text(SCENE.format(model=model, params=params))
    return path


def test_a_registered_declared_model_runs_a_scene_through_the_pipeline(tmp_path, morse_module, capsys):
    import importlib

    cls = register_model(importlib.import_module(morse_module).Morse)
    assert model_parameters("morse-test") == (["m", "D"], ["a"])
    out = tmp_path / "out"
    rc = main(["--scene", str(_scene(tmp_path, "morse-test")), "--out", str(out), "--repeats", "1",
               "--no-figures", "--allow-code"])
    assert rc == 0, capsys.readouterr()
    acc = pd.read_csv(out / "accuracy.csv")
    assert set(acc["status"]) == {"ok"}
    rk4 = acc[acc.solver == "rk4"].set_index("setting")["error_max"]
    # fourth order: halving h divides the error by about 16
    assert 12 < rk4[0.04] / rk4[0.02] < 20
    table = scene_schema.params_table(cls)
    assert list(table.model_fields) == ["m", "D", "a"]
    assert [table.model_fields[k].json_schema_extra["unit"] for k in table.model_fields] == ["kg", "J", "1/m"]


@pytest.mark.parametrize("params, field, says", [
    ("m = 1.0\nD = -2.0", "params.D", "must be >= 1e-300"),
    ("m = 1.0\nD = \"deep\"", "params.D", "must be a number"),
    ("m = 1.0", "params.D", "is missing"),
    ("m = 1.0\nD = 2.0\nwidth = 1.0", "params.width", "unknown key (known: D, a, m)"),
    ("m = 1.0\nD = 2e7", "params.D", "must be at most 1e6 (a test rule)"),
])
def test_a_user_models_declaration_checks_its_params(tmp_path, morse_module, params, field, says):
    path = _scene(tmp_path, f"{morse_module}:Morse", params)
    with pytest.raises(SceneError) as e:
        load_scene(path, allow_code=True)
    assert f"`{field}`" in str(e.value) and says in str(e.value), str(e.value)


def test_an_undeclared_model_is_read_from_its_constructor():
    """A subclass with its own constructor and no declaration is read from
    its signature, not from the declaration it inherits (which describes
    another constructor)."""
    class Bare(MODELS["oscillator2d"]):
        def __init__(self, m, kx, ky=2.0):
            super().__init__(m, kx, ky)

    class Same(MODELS["oscillator2d"]):
        pass

    assert declared(Same) == MODELS["oscillator2d"].parameters

    ps = declared(Bare)
    assert [(p.name, p.kind, p.required) for p in ps] == [("m", "any", True), ("kx", "any", True),
                                                          ("ky", "any", False)]
    assert ps[2].default == 2.0
    assert scene_schema.params_error(Bare, {"m": 1.0}) == ("params.kx", "is missing", None)


@pytest.mark.parametrize("cls", BUILTIN_CLASSES, ids=lambda c: c.name)
def test_every_builtin_model_builds_from_its_declared_examples(cls):
    """The declaration's examples are a valid [params] table (schema and
    constructor agree on it) and give a model whose force is finite."""
    import numpy as np

    params = example_parameters(cls.name)
    scene_schema.BUILTIN_MODELS[cls.name].model_validate(params)
    model = make_model(cls.name, params)
    if cls.first_order:  # dy/dt = f(t, y): no coordinates, no force
        assert type(model) is cls and model.n_state >= 1
        assert np.all(np.isfinite(model.rhs(0.0, np.full(model.n_state, 0.5))))
        return
    assert type(model) is cls and len(model.coord_names) == model.n_dof >= 1
    assert np.all(np.isfinite(model.force(np.full(model.n_dof, 1e-3))))


def test_a_bad_declaration_is_refused():
    with pytest.raises(ValueError, match="`kind` of parameter 'm'"):
        Param("m", "float", "kg", "mass", 1.0)
    with pytest.raises(ValueError, match="`choices`"):
        Param("walls", "choice", "-", "walls", "both")


def test_a_new_builtin_model_is_one_file_and_one_registry_line(tmp_path):
    """Adding the class to BUILTIN_CLASSES (what the registry line does)
    gives it a scene-schema variant, a reference section with its units and
    a JSON Schema entry; run in a fresh interpreter, so the registry the
    schema is generated from is the extended one."""
    (tmp_path / "morse_model.py").write_text(MORSE_FILE)
    code = textwrap.dedent("""
        import json, sys
        import rk4h.models as M
        from morse_model import Morse
        M.BUILTIN_CLASSES = M.BUILTIN_CLASSES + (Morse,)
        M.register_model(Morse)
        from rk4h.validation import scene_schema as S
        from rk4h.validation.scenes import scene_points_from_dict
        doc = {"name": "m", "model": "morse-test", "params": {"m": 1.0, "D": 2.0}, "initial": {"x": [0.1]},
               "run": {"t_end": 1.0, "h": [0.1], "solvers": ["rk4"], "outputs": ["state"]}}
        scene_points_from_dict(doc, "m.toml")
        bad = dict(doc, params={"m": 1.0, "D": 0.0})
        try:
            scene_points_from_dict(bad, "m.toml")
            err = None
        except Exception as e:
            err = str(e)
        print(json.dumps({"builtin": list(S.BUILTIN_MODELS), "md": S.reference_markdown(),
                          "schema": "MorseParams" in json.dumps(S.json_schema()), "err": err}))
    """)
    env = {"PYTHONPATH": f"{tmp_path}:{REPO}", "PATH": "/usr/bin:/bin"}
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=300)
    assert done.returncode == 0, done.stderr
    got = json.loads(done.stdout)
    assert got["builtin"] == [c.name for c in BUILTIN_CLASSES] + ["morse-test"]
    assert '### `[params]` of `model = "morse-test"`' in got["md"]
    assert "| `D` | number >= 1e-300 | J | required | `2.0` | depth of the well |" in got["md"]
    assert "| `a` | number >= 1e-300 | 1/m | `1.0` | `1.5` | inverse width of the well |" in got["md"]
    assert got["schema"]
    assert "params.D" in got["err"] and "must be >= 1e-300" in got["err"]


@pytest.mark.parametrize("params, expected", [
    ({"masses": 0.815, "springs": 41.5, "n": 10}, (0.815, 41.5)),
    ({"masses": 0.815, "springs": 41.5, "n": 10, "walls": "left"}, None),
    ({"masses": [1.0, 2.0], "springs": [3.0, 3.0, 3.0]}, None),
    ({"masses": [1.0, 1.0], "springs": [3.0, 4.0, 3.0]}, None),
    ({"masses": 2.0, "springs": 5.0, "n": 4, "beta": 1.0}, (2.0, 5.0)),  # the linearization counts
])
def test_uniform_chain_is_read_from_the_mechanics(params, expected):
    assert make_model("chain", params).uniform_chain() == expected


def test_uniform_chain_of_a_network_on_a_line_and_of_a_plane_model():
    # masses 1 kg at 0, 1, 2 (m) between anchors at -1 and 3, springs of 7 N/m: a uniform chain
    net = make_model("network", {"dim": 1, "masses": [1.0, 1.0, 1.0], "positions": [0.0, 1.0, 2.0],
                                 "anchors": [-1.0, 3.0], "springs": [[3, 0, 7.0], [0, 1, 7.0], [1, 2, 7.0],
                                                                     [2, 4, 7.0]]})
    assert net.drawing().layout == "line"
    assert net.uniform_chain() == pytest.approx((1.0, 7.0), rel=1e-12)
    assert make_model("oscillator2d", {"m": 1.0, "kx": 2.0, "ky": 2.0}).uniform_chain() is None
