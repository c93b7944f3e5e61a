"""The method registry: every method is data (kind, order, cost, style); a
scene brings its own tableaux and Python steppers; bad definitions are one
line naming ``methods.NAME.KEY``; the harness runs them like the built-ins."""
import subprocess
import sys
from fractions import Fraction
from pathlib import Path

import numpy as np
import pytest

from rk4h.references import registry
from rk4h.references.registry import Kind
from rk4h.references.solvers import Status, integrate
from rk4h import make_model
from rk4h.validation import metrics
from rk4h.validation.scenes import SceneError, scene_from_dict

REPO = Path(__file__).resolve().parent.parent


@pytest.mark.parametrize("name, kind, order, cost", [
    ("rk4", Kind.TABLEAU, 4, 4), ("euler", Kind.TABLEAU, 1, 1), ("symplectic-euler", Kind.PARTITIONED, 1, 1),
    ("stormer-verlet", Kind.PARTITIONED, 2, 1), ("dop853", Kind.REFERENCE, None, None),
    ("cvode-bdf", Kind.REFERENCE, None, None), ("heyoka", Kind.REFERENCE, None, None)])
def test_builtin_methods_know_kind_order_and_cost(name, kind, order, cost):
    m = registry.BUILTIN[name]
    assert (m.kind, m.order, m.nfev_per_step) == (kind, order, cost)
    assert m.setting_name == ("rtol" if kind is Kind.REFERENCE else "h")


def test_every_builtin_has_its_own_style():
    styles = [(m.style.color, m.style.marker) for m in registry.BUILTIN.values()]
    assert len(set(styles)) == len(styles)


def _doc(methods, solvers):
    return {"name": "reg", "model": "chain",
            "params": {"masses": [1.0, 2.0], "springs": [3.0, 4.0, 5.0], "walls": "both"},
            "initial": {"x": [0.01, 0.0]},
            "run": {"t_end": 1.0, "h": [0.01], "tolerances": [1e-8], "solvers": solvers, "outputs": ["state"]},
            "methods": methods}


RK38 = {"c": ["0", "1/3", "2/3", "1"], "b": ["1/8", "3/8", "3/8", "1/8"],
        "A": [["0", "0", "0", "0"], ["1/3", "0", "0", "0"], ["-1/3", "1", "0", "0"], ["1", "-1", "1", "0"]]}


def test_scene_tableau_from_rationals_has_computed_order_and_exact_coefficients():
    scene = scene_from_dict(_doc({"rk38": RK38}, ["rk4", "rk38"]))
    m = scene.method("rk38")
    assert m.kind is Kind.TABLEAU and m.order == 4 and m.nfev_per_step == 4
    assert m.tableau.b_exact == (Fraction(1, 8), Fraction(3, 8), Fraction(3, 8), Fraction(1, 8))
    assert scene.fixed_solvers == ["rk4", "rk38"]


@pytest.mark.parametrize("methods, field", [
    ({"mid": {"A": [["1/2"]], "b": ["1"]}}, "methods.mid.A"),                       # implicit midpoint
    ({"two": {"A": [["0", "0"], ["1", "0"]], "b": ["1"]}}, "methods.two.b"),        # one weight for 2 stages
    ({"bad": {"A": [["0", "0"], ["1/x", "0"]], "b": ["1/2", "1/2"]}}, "methods.bad.A"),
    ({"rows": {"A": [["0", "0"], ["1", "0"]], "b": ["1/2", "1/2"], "c": ["0", "1/2"]}}, "methods.rows.c"),
    ({"rk4": RK38}, "methods.rk4"),                                                  # a built-in's name
    ({"x": {"A": [["0"]], "b": ["1"], "order": 1}}, "methods.x.order"),             # computed, not declared
    ({"x": {"python": "rk4h.steppers:rk4_step"}}, "methods.x.order"),            # python needs an order
    ({"x": {"python": "no.such.module:f", "order": 4}}, "methods.x.python"),
    ({"x": {"python": "not a target", "order": 4}}, "methods.x.python"),
    ({"x": {"command": "octave-cli run.m", "order": 4}}, "methods.x.command"),     # argv is a list
    ({"x": {"A": [["0"]], "b": ["1"], "python": "rk4h.steppers:rk4_step"}}, "methods.x.A"),
    ({"x": {"A": [["0"]], "b": ["1"], "colour": "red"}}, "methods.x.colour"),
])
def test_bad_method_definitions_are_one_line_naming_the_key(methods, field):
    with pytest.raises(SceneError) as e:
        scene_from_dict(_doc(methods, ["rk4"]))
    assert e.value.field == field, str(e.value)
    assert "\n" not in str(e.value)


def test_an_unknown_solver_names_the_scene_methods_too():
    with pytest.raises(SceneError) as e:
        scene_from_dict(_doc({"rk38": RK38}, ["rk4", "rk39"]))
    assert e.value.field == "run.solvers[1]" and "rk38" in str(e.value)


def test_invalid_method_in_a_scene_file_is_exit_2_without_traceback(tmp_path):
    p = tmp_path / "mid.toml"
    p.write_text('name = "mid"\nmodel = "chain"\n[params]\nmasses = [1.0]\nsprings = [1.0, 1.0]\nwalls = "both"\n'
                 '[initial]\nx = [0.1]\n[methods.mid]\nA = [["1/2"]]\nb = ["1"]\n'
                 '[run]\nt_end = 1.0\nh = [0.1]\nsolvers = ["mid"]\noutputs = ["state"]\n')
    r = subprocess.run([sys.executable, "validation/run_all.py", "--scene", str(p), "--out", str(tmp_path / "o")],
                       cwd=REPO, capture_output=True, text=True, timeout=120)
    assert r.returncode == 2, r.stderr
    assert "Traceback" not in r.stderr and r.stderr.count("\n") == 1
    assert "field `methods.mid.A`" in r.stderr and "lower triangular" in r.stderr
    assert not (tmp_path / "o").exists()


# -- python steppers -------------------------------------------------------------------
def _chain():
    model = make_model("chain", {"masses": [0.815, 3.099], "springs": [41.5, 138.0, 157.8], "walls": "both"})
    return model, np.array([0.005, 0.005, 0.0, 0.0])


def _python_method(target, order=4):
    return registry.method_from_table("mine", {"python": target, "order": order})


def test_a_python_rk4_stepper_equals_the_tableau_rk4_to_round_off():
    model, y0 = _chain()
    t = np.linspace(0.0, 2.0, 21)
    mine = integrate(_python_method("rk4h.steppers:rk4_step"), model, y0, t, 0.01)
    ref = integrate("rk4", model, y0, t, 0.01)
    assert mine.status is Status.OK and mine.n_steps == 200
    assert mine.nfev == 4 * 200  # every call of fun counted
    assert np.max(np.abs(mine.y - ref.y)) <= 1e-14 * np.max(np.abs(ref.y))


def _boom(fun, t, y, h):
    raise RuntimeError("my stepper broke")


def _wrong_shape(fun, t, y, h):
    return y[:1]


def _explode(fun, t, y, h):
    return 10.0 * y


@pytest.mark.parametrize("target, status, words", [
    ("test_registry:_boom", Status.FAILED, "my stepper broke"),
    ("test_registry:_wrong_shape", Status.FAILED, "shape"),
    ("test_registry:_explode", Status.UNSTABLE, "scale"),
])
def test_a_failing_python_stepper_is_a_status_not_an_exception(target, status, words):
    model, y0 = _chain()
    run = integrate(_python_method(target), model, y0, np.linspace(0.0, 1.0, 11), 0.01)
    assert run.status is status and words in run.message
    assert np.all(np.isnan(run.y[:, -1]))


# -- energy theory for any tableau -----------------------------------------------------
@pytest.mark.parametrize("name", ["rk4", "rk38", "heun3", "ralston", "euler"])
def test_energy_loss_per_step_is_one_minus_abs_R_squared(name):
    from rk4h import get_method
    from rk4h.stability_function import R

    tab = get_method(name)
    theta = np.array([0.01, 0.1, 0.5, 1.0, 1.5])
    direct = 1.0 - np.abs(R(tab, 1j * theta)) ** 2
    np.testing.assert_allclose(metrics.energy_loss(tab, theta), direct, rtol=1e-6, atol=1e-15)


def test_rk4_energy_loss_is_the_closed_form():
    theta = np.array([1e-3, 0.05, 0.3, 2.0, np.sqrt(8.0)])
    # the same expression, evaluated from the exact integer coefficients: a few ulp apart at most
    np.testing.assert_allclose(metrics.rk4_energy_loss(theta), theta**6 * (8.0 - theta**2) / 576.0,
                               rtol=1e-15, atol=0)
    assert metrics.rk4_energy_loss(np.sqrt(8.0) * (1 + 1e-15)) < 0 < metrics.rk4_energy_loss(np.sqrt(8.0) * (1 - 1e-15))


def test_stability_boundaries_from_runs_equal_the_tableaux_boundaries():
    # methods-2dof's boundary study: bisection on the runs' one-step maps against
    # the boundary computed from each tableau (0.5 %), its own tableaux included.
    from rk4h.validation import stability as S
    from rk4h.validation.scenes import SCENE_DIR, load_scene

    scene = load_scene(SCENE_DIR / "methods_2dof.toml")
    rows = S.run_unit(scene, "boundary", True).rows
    got = {r["solver"]: r for r in rows if r["quantity"] == "largest_stable_h_s"}
    assert set(got) == {"rk4", "symplectic-euler", "stormer-verlet", "euler", "rk38", "heun3", "ralston2"}
    for name, r in got.items():
        assert r["passed"] is True, (name, r)
        if r["theory"] > 0:
            assert abs(r["measured"] / r["theory"] - 1) <= 0.005, name


def test_a_command_method_whose_program_is_missing_is_a_status_and_a_finding():
    # GNU Octave (or any program) absent on a user's machine: the row says
    # "unavailable" with the message, the report says so, nothing fails or raises.
    from rk4h.validation import execute as X
    from rk4h.validation import measure as M
    from rk4h.validation import plan as P

    doc = _doc({"prog": {"command": ["no-such-program-rk4h", "{problem}", "{trajectory}"], "order": 4}},
               ["rk4", "prog"])
    doc["run"]["outputs"] = ["state"]
    scene = scene_from_dict(doc)
    specs = P.plan(scene, figures=False)
    records = {s.key: X.execute(scene, s) for s in specs}
    res = M.measure(scene, specs, records, figures=False)
    rows = {r["solver"]: r for r in res.tables["accuracy"]}
    assert rows["prog"]["status"] == "unavailable" and "no-such-program-rk4h not found" in rows["prog"]["message"]
    assert rows["rk4"]["status"] == "ok"
    assert not res.failures
    assert any("prog at 0.01 did not run" in f for f in res.findings)


def test_a_reference_without_an_adapter_is_an_error_not_another_solver():
    import dataclasses

    import rk4h
    from rk4h.references.registry import BUILTIN
    from rk4h.references.solvers import REFERENCE_RUNNERS, integrate

    fake = dataclasses.replace(BUILTIN["heyoka"], name="radau-fake", adapter="radau")
    assert fake.adapter not in REFERENCE_RUNNERS
    model = rk4h.make_model("chain", {"masses": [1.0], "springs": [1.0, 1.0]})
    with pytest.raises(ValueError, match="no adapter runs the reference 'radau-fake' \\(adapter 'radau'"):
        integrate(fake, model, model.state([0.01]), np.linspace(0.0, 1.0, 5), 1e-8)


def test_a_reference_runs_on_its_adapter_whatever_its_name():
    import dataclasses

    import rk4h
    from rk4h.references.registry import BUILTIN
    from rk4h.references.solvers import REFERENCE_RUNNERS, integrate

    assert {m.adapter for m in BUILTIN.values() if m.adaptive} <= set(REFERENCE_RUNNERS)
    renamed = dataclasses.replace(BUILTIN["dop853"], name="my-explicit-ref")
    model = rk4h.make_model("chain", {"masses": [1.0], "springs": [1.0, 1.0]})
    t = np.linspace(0.0, 1.0, 5)
    got = integrate(renamed, model, model.state([0.01]), t, 1e-8)
    want = integrate("dop853", model, model.state([0.01]), t, 1e-8)
    assert got.ok and np.array_equal(got.y, want.y) and got.nfev == want.nfev


def test_an_unknown_method_name_is_an_error_naming_the_known_ones():
    """No fall-through to some default solver: an unknown name is refused,
    by integrate and by a scene, with the registry's names."""
    from rk4h.references.registry import BUILTIN
    from rk4h.validation.scenes import SceneError, scene_from_dict

    model = make_model("chain", {"masses": [1.0], "springs": [1.0, 1.0]})
    with pytest.raises(ValueError, match="`solver` must be one of") as info:
        integrate("radau", model, model.state([0.01]), np.linspace(0.0, 1.0, 3), 1e-6)
    assert "'radau'" in str(info.value) and all(repr(n) in str(info.value) for n in BUILTIN)
    with pytest.raises(SceneError, match="run.solvers") as info:
        scene_from_dict(_doc({}, ["rk4", "radau"]))
    assert "radau" in str(info.value)


def test_a_renamed_reference_keeps_its_adapters_rules():
    """What a reference needs is read from its adapter, not its name: heyoka
    under another name still refuses a first-order ODE."""
    import dataclasses

    from rk4h.references.registry import BUILTIN
    from rk4h.references.solvers import mechanical_only

    renamed = dataclasses.replace(BUILTIN["heyoka"], name="my-taylor")
    assert mechanical_only(BUILTIN["heyoka"]) and mechanical_only(renamed)
    assert not mechanical_only(dataclasses.replace(BUILTIN["dop853"], name="my-taylor"))


def test_every_method_declares_what_its_nfev_counts():
    """The cost unit is data: a Taylor method's cost is steps x order, the
    others' their nfev; CVODE's nfev includes its Jacobian's difference
    quotients (its extra counters add up to it)."""
    import rk4h
    from rk4h.references.registry import BUILTIN, CostUnit
    from rk4h.references.solvers import integrate

    assert all(isinstance(m.cost_unit, CostUnit) and m.cost_unit.text for m in BUILTIN.values())
    assert BUILTIN["heyoka"].cost(0, 10, 20) == 200.0 and BUILTIN["dop853"].cost(77, 10, 0) == 77.0
    assert BUILTIN["cvode-bdf"].cost_unit is CostUnit.RHS_WITH_JACOBIAN_DQ
    model = rk4h.make_model("chain", {"masses": [1.0, 2.0], "springs": [1.0, 3.0, 1.0]})
    run = integrate("cvode-bdf", model, model.state([0.01, 0.0]), np.linspace(0.0, 2.0, 5), 1e-8)
    assert run.ok and run.nfev == run.extra["nfev_cvode"] + run.extra["nfev_jac_dq"]
    assert BUILTIN["cvode-bdf"].cost(run.nfev, run.n_steps, run.taylor_order or 0) == run.nfev


def test_growth_figures_leave_out_only_a_method_whose_curve_another_draws():
    """GROWTH_ALWAYS is BOUNDARY_ALWAYS less the methods whose growth factor
    on a harmonic mode equals a drawn one's at every theta (Stormer-Verlet:
    symplectic Euler's)."""
    from rk4h.references.registry import BOUNDARY_ALWAYS, BUILTIN, GROWTH_ALWAYS
    from rk4h.validation.stability.boundary import theory_growth

    assert set(GROWTH_ALWAYS) <= set(BOUNDARY_ALWAYS)
    thetas = (0.1, 0.5, 1.0, 1.9, 2.1, 3.0)

    def curve(name):
        return np.array([theory_growth(BUILTIN[name].tableau, th) for th in thetas])

    for left_out in set(BOUNDARY_ALWAYS) - set(GROWTH_ALWAYS):
        assert any(np.allclose(curve(left_out), curve(m), rtol=1e-12) for m in GROWTH_ALWAYS), left_out
    for a in GROWTH_ALWAYS:
        assert not any(np.allclose(curve(a), curve(b), rtol=1e-12) for b in GROWTH_ALWAYS if b != a), a
