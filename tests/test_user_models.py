"""A model a user brings: one Python file named in a scene as
``model = "module:Class"``, or registered with ``rk4h.register_model``."""
import sys

import numpy as np
import pandas as pd
import pytest

import rk4h
from rk4h.models import MODELS, resolve_model
from rk4h.validation.run_all import main
from rk4h.validation.scenes import SceneError, load_scene

USER_FILE = '''
"""A Duffing oscillator: m x'' = -k x - eps x^3 (one file, nothing else touched)."""
import numpy as np

from rk4h import Model


class Duffing(Model):
    name = "duffing-test"
    linear = False

    def __init__(self, m, k, eps=0.0):
        self.m, self.k, self.eps = float(m), float(k), float(eps)
        self.n_dof = 1
        self.mass = np.array([self.m])
        self.coord_names = ["x"]

    def params(self):
        return {"m": self.m, "k": self.k, "eps": self.eps}

    def _potential(self, q, ops):
        x = q[0]
        return 0.5 * self.k * x * x + 0.25 * self.eps * x * x * x * x

    def _force(self, q, ops):
        x = q[0]
        f = -self.k * x - self.eps * x * x * x
        return np.array([f], dtype=object) if q.dtype == object else np.asarray(f)[None]

    def stiffness_matrix(self, sparse=False):
        return np.array([[self.k]])
'''

DEFINED_FILE = '''
"""The same Duffing oscillator, defined by its potential: force, Hessian,
compiled kernels and heyoka's equations are derived from the one text."""
from rk4h import Defined, PotentialModel


class DuffingV(Defined):
    name = "duffing-defined-test"

    def __init__(self, m, k, eps=0.0):
        self.m, self.k, self.eps = float(m), float(k), float(eps)
        self._adopt(lambda: PotentialModel(["x"], [self.m], "k*x^2/2 + eps*x^4/4", {"k": self.k, "eps": self.eps}),
                    "k")
        self.coord_names = ["x"]

    def params(self):
        return {"m": self.m, "k": self.k, "eps": self.eps}
'''

SCENE = '''
name = "duffing"
model = "{model}"
[params]
m = 1.0
k = 4.0
eps = 0.5
[initial]
x = [0.1]
[run]
t_end = 5.0
h = [0.05, 0.025]
tolerances = [1e-8]
solvers = ["rk4", "dop853"]
outputs = ["state", "energy"]
'''


@pytest.fixture
def user_module(tmp_path, monkeypatch):
    pkg = tmp_path / "usermods"
    pkg.mkdir()
    (pkg / "duffing_model.py").write_text(USER_FILE + DEFINED_FILE)
    monkeypatch.syspath_prepend(str(pkg))
    yield "duffing_model"
    MODELS.pop("duffing-test", None)
    MODELS.pop("duffing-defined-test", None)
    sys.modules.pop("duffing_model", None)


def test_a_defined_user_model_gets_the_derived_and_compiled_paths(user_module):
    import importlib

    import rk4h.fast as fast

    mod = importlib.import_module(user_module)
    hand = mod.Duffing(1.0, 4.0, 0.5)
    defined = mod.DuffingV(1.0, 4.0, 0.5)
    assert not fast.supports(hand) and fast.supports(defined)
    x = np.array([0.3])
    np.testing.assert_allclose(defined.force(x), hand.force(x), rtol=1e-15)
    np.testing.assert_array_equal(defined.stiffness_matrix(), [[4.0]])
    y0 = defined.state([0.3], [0.1])
    res = fast.solve_model(defined, (0.0, 2.0), y0, h=0.01)
    gen = rk4h.solve(defined.rhs, (0.0, 2.0), y0, h=0.01)
    np.testing.assert_array_equal(res.y, gen.y)


def test_a_scene_runs_a_model_from_one_user_file(tmp_path, user_module, capsys):
    scene = tmp_path / "duffing.toml"
    scene.write_text(SCENE.format(model=f"{user_module}:Duffing"))
    out = tmp_path / "out"
    rc = main(["--scene", str(scene), "--out", str(out), "--repeats", "1", "--no-figures", "--allow-code"])
    assert rc == 0, capsys.readouterr()
    acc = pd.read_csv(out / "accuracy.csv")
    assert set(acc["status"]) == {"ok"}
    rk4 = acc[acc.solver == "rk4"].set_index("setting")["error_max"]
    # fourth order against the quadruple-precision reference: halving h divides the error by ~16
    assert 12 < rk4[0.05] / rk4[0.025] < 20


def test_register_model_adds_and_guards_names(user_module):
    import importlib

    cls = importlib.import_module(user_module).Duffing
    assert rk4h.register_model(cls) is cls and MODELS["duffing-test"] is cls
    m = rk4h.make_model("duffing-test", {"m": 1.0, "k": 4.0, "eps": 0.5})
    np.testing.assert_allclose(m.force([0.1]), [-0.4 - 0.5e-3])

    class Impostor(cls):
        pass

    with pytest.raises(ValueError, match="model name 'duffing-test' is taken"):
        rk4h.register_model(Impostor)
    with pytest.raises(ValueError, match="must be a subclass of rk4h.models.Model"):
        rk4h.register_model(dict)


@pytest.mark.parametrize("model, says", [
    ("no_such_module_xyz:Thing", "cannot import 'no_such_module_xyz'"),
    ("os:path", "must be a subclass"),
    ("os.path; rm -rf /:X", "must be one of"),
    ("__import__('os')", "must be one of"),
], ids=["missing-module", "not-a-model", "shell-text", "python-text"])
def test_bad_model_references_are_refused(model, says):
    with pytest.raises(ValueError, match=None) as info:
        resolve_model(model)
    assert says in str(info.value)


def test_a_bad_model_reference_in_a_scene_names_the_field(tmp_path):
    scene = tmp_path / "bad.toml"
    scene.write_text(SCENE.format(model="no_such_module_xyz:Thing"))
    with pytest.raises(SceneError) as info:
        load_scene(scene, allow_code=True)
    assert info.value.field == "model" and "no_such_module_xyz:Thing" in str(info.value)
