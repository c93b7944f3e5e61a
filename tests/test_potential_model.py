"""Tests of the `potential` model (rk4h.models.potential.PotentialModel):
a potential typed as text, parsed by rk4h.expr, everything else derived.

Henon-Heiles (V = (x^2 + y^2)/2 + x^2 y - y^3/3) is the nonlinear case; two
masses on three springs written as text must equal rk4core's Chain model.
"""
import math
import re
import tomllib
from pathlib import Path

import numpy as np
import pytest

import rk4h
from rk4h.models import Chain
from rk4h.models.potential import PotentialModel

HH = {"coordinates": ["x", "y"], "masses": 1.0,
      "potential": "(x^2 + y^2)/2 + lam*(x^2*y - y^3/3)", "constants": {"lam": 1.0}}
# Thesis 2-DOF case 1 as text: wall - k1 - m1 - k2 - m2 - k3 - wall.
SPRINGS = {"coordinates": ["x1", "x2"], "masses": [0.815, 3.099],
           "potential": "k1*x1^2/2 + k2*(x2 - x1)^2/2 + k3*x2^2/2",
           "constants": {"k1": 41.5, "k2": 138.0, "k3": 157.8}}
SCENE = Path(__file__).resolve().parents[1] / "validation" / "scenes" / "henon_heiles.toml"


def hh():
    return PotentialModel(**HH)


def hh_force(q):
    """-grad V of Henon-Heiles, by hand."""
    x, y = q
    return np.array([-x - 2 * x * y, -y - x * x + y * y])


def random_q(seed, n=2, scale=0.4, m=None):
    rng = np.random.default_rng(seed)
    return scale * rng.uniform(-1.0, 1.0, (n,) if m is None else (n, m))


# -- derived quantities --------------------------------------------------------
@pytest.mark.parametrize("seed", [0, 1, 2, 3])
def test_force_is_minus_finite_difference_gradient(seed):
    # Central differences, step 1e-5: truncation ~ d^2 V'''/6 ~ 3e-11,
    # round-off ~ eps V / d ~ 1e-12: agreement to 1e-9.
    model = hh()
    q = random_q(seed)
    d = 1e-5
    fd = np.array([(model.potential(q + d * e) - model.potential(q - d * e)) / (2 * d) for e in np.eye(2)])
    np.testing.assert_allclose(model.force(q), -fd, rtol=0, atol=1e-9)
    np.testing.assert_allclose(model.force(q), hh_force(q), rtol=1e-15, atol=1e-16)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_hessian_is_finite_difference_of_force(seed):
    model = hh()
    H = np.array(model._H_fn(*random_q(seed)), dtype=float).reshape(2, 2)
    q = random_q(seed)
    d = 1e-6
    fd = np.column_stack([(model.force(q + d * e) - model.force(q - d * e)) / (2 * d) for e in np.eye(2)])
    np.testing.assert_allclose(H, -fd, rtol=0, atol=1e-8)
    # At the reference state q = 0: the stiffness matrix, here the identity.
    K = model.stiffness_matrix()
    d0 = np.column_stack([(model.force(d * e) - model.force(-d * e)) / (2 * d) for e in np.eye(2)])
    np.testing.assert_allclose(K, -d0, rtol=0, atol=1e-9)
    np.testing.assert_array_equal(K, np.eye(2))


def test_vectorised_force_and_energy_equal_per_state_values():
    model = hh()
    Q = random_q(5, m=7)
    F = model.force(Q)
    assert F.shape == (2, 7)
    for j in range(7):
        np.testing.assert_array_equal(F[:, j], model.force(Q[:, j]))
        assert model.potential(Q)[j] == model.potential(Q[:, j])
    Y = np.vstack([Q, random_q(6, m=7)])
    np.testing.assert_array_equal(model.energy(Y), [model.energy(Y[:, j]) for j in range(7)])


def test_heyoka_rhs_agrees_with_numpy_rhs():
    hy = pytest.importorskip("heyoka")
    model = hh()
    vs, rhs = model.heyoka_system()
    cf = hy.cfunc(rhs, vs)
    rng = np.random.default_rng(11)
    Y = rng.uniform(-0.5, 0.5, (4, 50))
    got = cf(Y)
    want = np.column_stack([model.rhs(0.0, Y[:, j]) for j in range(50)])
    scale = np.max(np.abs(want), axis=0)
    assert np.all(np.abs(got - want) <= 1e-14 * scale)
    # The energy heyoka's truth uses: the same V.
    ce = hy.cfunc([model.heyoka_energy(vs)], vs)
    np.testing.assert_allclose(ce(Y)[0], model.energy(Y), rtol=1e-14)


def test_quadratic_potential_equals_chain_model():
    pm = PotentialModel(**SPRINGS)
    ch = Chain(SPRINGS["masses"], [41.5, 138.0, 157.8], "both")
    assert pm.linear is True
    np.testing.assert_allclose(pm.stiffness_matrix(), ch.stiffness_matrix(), rtol=1e-13, atol=0)
    rng = np.random.default_rng(3)
    Q = 0.01 * rng.uniform(-1, 1, (2, 20))
    V = 0.3 * rng.uniform(-1, 1, (2, 20))
    np.testing.assert_allclose(pm.force(Q), ch.force(Q), rtol=1e-13, atol=1e-13 * np.abs(ch.force(Q)).max())
    Y = np.vstack([Q, V])
    np.testing.assert_allclose(pm.energy(Y), ch.energy(Y), rtol=1e-13)
    np.testing.assert_allclose(pm.modes()[0], ch.modes()[0], rtol=1e-13)
    for j in range(3):
        np.testing.assert_allclose(pm.rhs(0.0, Y[:, j]), ch.rhs(0.0, Y[:, j]), rtol=1e-13, atol=1e-14)


@pytest.mark.parametrize("potential, linear", [
    ("k1*x1^2/2 + k2*(x2 - x1)^2/2 + k3*x2^2/2", True),
    ("(x1 - x2)^2/2", True),                      # semidefinite: a free translation mode
    ("0", True),                                   # free particles
    ("x1^2/2 + x2^2/2 + x1", False),               # a constant force: F(0) != 0
    ("-x1^2/2 + x2^2/2", False),                   # indefinite: no oscillating modes
    ("x1^2/2 + x2^4/4", False),                    # quartic
    ("x1^2/2 + x2^2/2 + x1^2*x2", False),          # Henon-Heiles-like
    ("1 - cos(x1) + x2^2", False),                 # pendulum
], ids=["springs", "semidefinite", "zero", "linear-term", "indefinite", "quartic", "cubic", "pendulum"])
def test_linear_only_for_positive_semidefinite_quadratic_forms(potential, linear):
    model = PotentialModel(["x1", "x2"], 1.0, potential, {"k1": 1.0, "k2": 2.0, "k3": 3.0})
    assert model.linear is linear


def test_rk4_converges_at_order_four_on_henon_heiles():
    # Error at T = 20 against heyoka at tol 1e-15 (its error ~1e-15, far below
    # RK4's 3e-9 at the smallest step); least-squares slope of log error vs log h.
    from rk4h.references.solvers import integrate

    model = hh()
    y0 = model.state([0.0, 0.1], [math.sqrt(59 / 375), 0.0])
    T = 20.0
    ref = integrate("heyoka", model, y0, np.array([0.0, T]), 1e-15)
    assert ref.status.name == "OK"
    hs = np.array([0.1, 0.05, 0.025, 0.0125])
    errs = [np.max(np.abs(rk4h.solve(model.rhs, (0.0, T), y0, h=h).y[:, -1] - ref.y[:, -1])) for h in hs]
    assert min(errs) > 1e3 * 1e-15
    order = np.polyfit(np.log(hs), np.log(errs), 1)[0]
    assert abs(order - 4.0) <= 0.1, (order, errs)


# -- parameters ------------------------------------------------------------------
def test_scalar_mass_broadcasts():
    model = PotentialModel(["x", "y", "z"], 2.0, "x^2 + y^2 + z^2")
    np.testing.assert_array_equal(model.mass, [2.0, 2.0, 2.0])
    assert model.params()["masses"] == [2.0, 2.0, 2.0]
    q = np.array([0.1, -0.2, 0.3])
    np.testing.assert_allclose(model.acceleration(q), -2 * q / 2.0, rtol=1e-15)
    assert model.n_dof == 3 and model.coord_names == ["x", "y", "z"]


def test_params_rebuild_the_same_model():
    model = hh()
    again = PotentialModel(**model.params())
    assert again.digest == model.digest
    q = random_q(9)
    np.testing.assert_array_equal(again.force(q), model.force(q))
    assert model.params() == {"coordinates": ["x", "y"], "masses": [1.0, 1.0],
                              "potential": HH["potential"], "constants": {"lam": 1.0}}


def test_the_text_is_never_evaluated_by_python(monkeypatch):
    import builtins

    def refuse(*a, **k):
        raise AssertionError("eval called")

    monkeypatch.setattr(builtins, "eval", refuse)
    model = hh()
    assert model.force(np.array([0.1, 0.2])).shape == (2,)
    with pytest.raises(ValueError, match=re.escape("`potential`: unknown function `eval` at column 1")):
        PotentialModel(["x"], 1.0, "eval(x)")


BAD = [
    ("coordinates-string", {"coordinates": "x"}, "`coordinates` must be a list of names"),
    ("coordinates-empty", {"coordinates": []}, "`coordinates` must have 1 to 100 names"),
    ("coordinates-duplicate", {"coordinates": ["x", "x"]}, "`coordinates` must be distinct names"),
    ("coordinates-bad-name", {"coordinates": ["x", "1y"]}, "`coordinates[1]` must be a name"),
    ("coordinates-keyword", {"coordinates": ["x", "lambda"]}, "`coordinates[1]` must be a name"),
    ("coordinates-function", {"coordinates": ["x", "sin"]}, "`coordinates[1]` must be a name"),
    ("coordinates-not-string", {"coordinates": ["x", 3]}, "`coordinates[1]` must be a name"),
    ("masses-length", {"masses": [1.0, 2.0, 3.0]}, "`masses` must have 2 entries"),
    ("masses-negative", {"masses": [1.0, -2.0]}, "`masses[1]` must be > 0"),
    ("masses-zero-scalar", {"masses": 0.0}, "`masses` must be > 0"),
    ("masses-nan", {"masses": float("nan")}, "`masses` must be a finite number"),
    ("masses-string", {"masses": "1"}, "`masses`"),
    ("masses-bool", {"masses": True}, "`masses` must be a finite number"),
    ("masses-subnormal", {"masses": 5e-324}, "`masses"),
    ("potential-not-string", {"potential": 3.0}, "`potential` must be a string"),
    ("potential-unknown-name", {"potential": "x^2 + y*z"},
     "`potential`: unknown name `z` at column 9 (known: x, y, lam)"),
    ("potential-eval", {"potential": "eval(x)"}, "`potential`: unknown function `eval` at column 1"),
    ("potential-attribute", {"potential": "x.__class__"}, "`potential`: unexpected `.` at column 2"),
    ("potential-import", {"potential": "__import__('os')"}, "`potential`: name `__import__` at column 1"),
    ("potential-empty", {"potential": ""}, "`potential`: empty expression"),
    ("potential-trailing", {"potential": "x^2 +"}, "`potential`: missing operand after `+` at column 5"),
    ("potential-unbalanced", {"potential": "(x^2 + y"}, "`potential`: unbalanced parenthesis at column 1"),
    ("potential-too-long", {"potential": "x+" * 5001}, "`potential`: expression longer than 10000"),
    ("potential-too-deep", {"potential": "(" * 1000 + "x" + ")" * 1000}, "`potential`: nesting deeper than 200"),
    ("potential-singular-at-0", {"potential": "1/x + y^2"}, "`potential`: its Hessian at the reference state"),
    ("potential-cone-at-0", {"potential": "sqrt(x^2 + y^2)"}, "`potential`: its Hessian at the reference state"),
    ("potential-log-at-0", {"potential": "log(x) + y"}, "`potential`: its Hessian at the reference state"),
    ("constants-not-table", {"constants": [1.0]}, "`constants` must be a table"),
    ("constants-nan", {"constants": {"lam": float("nan")}}, "`constants.lam` must be a finite number"),
    ("constants-string", {"constants": {"lam": "1"}}, "`constants.lam` must be a finite number"),
    ("constants-bool", {"constants": {"lam": True}}, "`constants.lam` must be a finite number"),
    ("constants-coordinate", {"constants": {"lam": 1.0, "x": 2.0}}, "`constants.x`: `x` is both a coordinate"),
    ("constants-bad-name", {"constants": {"lam": 1.0, "a.b": 2.0}}, "`constants` must have names as keys"),
    ("constants-missing", {"constants": {}}, "`potential`: unknown name `lam` at column 17"),
]


@pytest.mark.parametrize("change, fragment", [c[1:] for c in BAD], ids=[c[0] for c in BAD])
def test_bad_parameters_are_refused_naming_the_field(change, fragment):
    params = {**HH, **change}
    with pytest.raises(ValueError) as info:
        PotentialModel(**params)
    msg = str(info.value)
    assert fragment in msg
    assert "\n" not in msg and len(msg) < 400


@pytest.mark.parametrize("potential, y0, fragment", [
    ("1/(x - 1) + y^2", [1.0, 0.0, 0.0, 0.0], "the potential is not finite there"),
    ("sqrt(1 - x) + y^2", [1.0, 0.0, 0.0, 0.0], "the force is not finite there (-dV/dx"),
    ("exp(x) + y^2", [800.0, 0.0, 0.0, 0.0], "the potential is not finite there"),
    ("x^2 + y^2", [1e200, 0.0, 0.0, 0.0], "the potential is not finite there"),
    ("x^2 + y^2", [0.0, 0.0, 1e200, 0.0], "its energy is not finite"),
    ("x^2 + y^2", [0.0, float("nan"), 0.0, 0.0], "it is not finite"),
    ("x^2 + y^2", [0.0, 0.0, 0.0], "it has shape (3,)"),
], ids=["pole", "infinite-force", "overflow-exp", "overflow-square", "overflow-kinetic", "nan", "wrong-length"])
def test_check_state_refuses_non_finite_states_naming_y0(potential, y0, fragment):
    model = PotentialModel(["x", "y"], 1.0, potential)
    with pytest.raises(ValueError) as info:
        model.check_state(y0)
    msg = str(info.value)
    assert msg.startswith("`y0` ") and fragment in msg and "\n" not in msg


def test_check_state_accepts_finite_states_and_coordinates_alone():
    model = hh()
    y = model.check_state([0.0, 0.1, 0.3, 0.0])
    assert isinstance(y, np.ndarray) and y.dtype == float
    model.check_state([0.2, 0.1])            # q alone
    with pytest.raises(ValueError, match="`initial` must"):
        PotentialModel(["x"], 1.0, "1/(x-1)").check_state([1.0, 0.0], "initial")


# -- the scene ---------------------------------------------------------------------
def test_henon_heiles_scene_builds_the_model_at_energy_one_twelfth():
    doc = tomllib.loads(SCENE.read_text())
    assert doc["model"] == "potential" and doc["name"] == "henon-heiles"
    model = PotentialModel(**doc["params"])
    y0 = model.state(doc["initial"]["x"], doc["initial"]["v"])
    assert model.energy(y0) == pytest.approx(1 / 12, rel=1e-15, abs=0)
    assert doc["run"] == {"t_end": 100.0, "h": [0.1, 0.05, 0.02], "tolerances": [1e-6, 1e-9, 1e-12],
                          "solvers": ["rk4", "dop853", "heyoka"],
                          "outputs": ["state", "energy", "convergence", "work_precision"]}
    # Same keys, in the same tables, as a shipped scene.
    other = tomllib.loads((SCENE.parent / "pendulums_beats.toml").read_text())
    assert set(doc) == set(other) and set(doc["initial"]) == set(other["initial"])
    assert set(doc["run"]) == set(other["run"])


def test_henon_heiles_scene_loads_once_the_model_is_registered(monkeypatch):
    from rk4h.models import MODELS
    from rk4h.validation.scenes import load_scene

    monkeypatch.setitem(MODELS, "potential", PotentialModel)
    scene = load_scene(SCENE)
    assert scene.model == "potential" and scene.params["potential"] == HH["potential"]
