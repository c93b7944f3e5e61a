"""Any ODE: a typed ``model = "ode"`` (rk4h.models.OdeModel) and a plain
``fun(t, y)`` (FunctionOde) go through the solvers, the truth, the
convergence study, the work-precision and trust tables and the advisor."""
import math

import numpy as np
import pytest

from rk4h.references import ode_truth
from rk4h.references.solvers import integrate
from rk4h.references.truth import reference_solution
from rk4h.models import FunctionOde, OdeModel
from rk4h.validation.metrics import energy_drift_max
from rk4h.validation.scenes import SCENE_DIR, SceneError, load_scene, scene_from_dict

A, B, C, D = 1.5, 1.0, 3.0, 1.0
LV = dict(variables=["u", "v"], equations=["a*u - b*u*v", "-c*v + d*u*v"], constants=dict(a=A, b=B, c=C, d=D),
          invariant="d*u - c*log(u) + b*v - a*log(v)")


def lv(t, y):
    u, v = y
    return [A * u - B * u * v, -C * v + D * u * v]


def lv_invariant(y):
    return D * y[0] - C * math.log(y[0]) + B * y[1] - A * math.log(y[1])


# -- the model ------------------------------------------------------------------------------
def test_the_typed_model_is_the_plain_function():
    m = OdeModel(**LV)
    y = np.array([[1.0, 2.0, 0.5], [1.0, 0.3, 4.0]])
    assert m.n_state == 2 and m.first_order
    np.testing.assert_allclose(m.rhs(0.0, y), np.array([lv(0.0, y[:, j]) for j in range(3)]).T, rtol=1e-15)
    np.testing.assert_allclose(m.energy(y), [lv_invariant(y[:, j]) for j in range(3)], rtol=1e-15)


def test_time_may_appear_in_the_equations():
    m = OdeModel(["x"], ["cos(t)"])  # x = sin(t) from 0
    run = integrate("rk4", m, [0.0], np.linspace(0.0, 1.0, 11), 0.01)
    assert abs(run.y[0, -1] - math.sin(1.0)) < 1e-9


@pytest.mark.parametrize("kw, message", [
    (dict(variables=["u", "v"], equations=["u"]), "`equations` must have 2 entries"),
    (dict(variables=["u"], equations=["w*u"]), "`equations[0]`: unknown name `w`"),
    (dict(variables=["t"], equations=["1"]), "`variables` may not hold `t`"),
    (dict(variables=["u"], equations=["__import__('os')"]), "`equations[0]`"),
    (dict(variables=["u"], equations=["u"], invariant="u +"), "`invariant`"),
    (dict(variables=["u"], equations=["u"], exact=["exp(t)", "1"]), "`exact` must be a list of 1"),
    (dict(variables=["u"], equations=["u"], constants={"u": 1.0}), "`constants.u`"),
])
def test_bad_definitions_are_one_line_naming_the_field(kw, message):
    with pytest.raises(ValueError, match=re_escape(message)) as e:
        OdeModel(**kw)
    assert "\n" not in str(e.value)


def re_escape(text):
    import re

    return re.escape(text)


# -- solvers and truth on a plain function ---------------------------------------------------
def test_integrate_accepts_a_plain_function():
    t = np.linspace(0.0, 5.0, 51)
    ref = integrate("dop853", lv, [1.0, 1.0], t, 1e-12)
    assert ref.ok and ref.y.shape == (2, 51)
    for solver, setting in (("rk4", 0.005), ("cvode-adams", 1e-10)):
        run = integrate(solver, lv, [1.0, 1.0], t, setting)
        assert run.ok and np.max(np.abs(run.y - ref.y)) < 1e-7, solver


@pytest.mark.parametrize("solver", ["heyoka", "symplectic-euler"])
def test_methods_for_mechanical_models_are_refused(solver):
    setting = 1e-6 if solver == "heyoka" else 0.01
    with pytest.raises(ValueError, match="needs a mechanical model"):
        integrate(solver, lv, [1.0, 1.0], np.linspace(0.0, 1.0, 3), setting)


def test_the_truth_is_the_exact_solution_when_given():
    m = FunctionOde(lambda t, y: [y[1], -y[0]], 2, exact=lambda t: np.array([np.cos(t), -np.sin(t)]))
    t = np.linspace(0.0, 3.0, 31)
    truth = reference_solution(m, [1.0, 0.0], t)
    assert truth.ok and truth.kind == ode_truth.KIND_EXACT
    np.testing.assert_array_equal(truth.y, np.array([np.cos(t), -np.sin(t)]))


def test_without_exact_two_references_must_agree(monkeypatch):
    t = np.linspace(0.0, 5.0, 51)
    truth = reference_solution(OdeModel(**LV), [1.0, 1.0], t)
    assert truth.ok and truth.kind == ode_truth.KIND_CONFIRMED
    agree = truth.extra["agreement_rel"]
    assert 0 < agree <= ode_truth.AGREE_REL and "confirmed by cvode-adams" in truth.message
    ode_truth._MEMORY.clear()
    monkeypatch.setattr(ode_truth, "AGREE_REL", agree / 10)  # the same runs, a tighter demand: no truth
    failed = reference_solution(OdeModel(**LV), [1.0, 1.0], t)
    ode_truth._MEMORY.clear()
    assert not failed.ok and "references disagree" in failed.message and np.isnan(failed.y).all()


def test_invariant_drift_is_relative_to_the_initial_invariant():
    m = FunctionOde(lv, 2, invariant=lv_invariant)
    run = integrate("rk4", m, [1.0, 1.0], np.linspace(0.0, 10.0, 101), 0.1)
    inv = np.array([lv_invariant(run.y[:, j]) for j in range(run.y.shape[1])])
    expected = np.max(np.abs(inv - inv[0])) / abs(inv[0])
    assert expected > 1e-6  # h = 0.1 drifts: the check can fail
    assert energy_drift_max(m, run.y) == pytest.approx(expected, rel=1e-12)


# -- the pipeline on a plain function ------------------------------------------------------
@pytest.fixture(scope="module")
def lv_study():
    from rk4h.validation.ode import ode_scene, study

    scene = ode_scene(lv, (0.0, 10.0), [1.0, 1.0], h=[0.1, 0.05, 0.02], tolerances=[1e-6, 1e-9],
                      invariant=lv_invariant, name="lv-python")
    return scene, study(scene)


def test_a_plain_function_gives_rk4_order_4_and_a_work_precision_table(lv_study):
    scene, res = lv_study
    conv = {r["solver"]: r for r in res.tables["convergence"]}
    assert abs(conv["rk4"]["observed_order"] - 4.0) <= 0.1 and conv["rk4"]["passed"]
    assert abs(conv["euler"]["observed_order"] - 1.0) <= 0.1
    assert "symplectic-euler" not in conv  # a partitioned method is no method for a first-order ODE
    wp = res.tables["work_precision"]
    assert {(r["solver"], r["setting"]) for r in wp} == {("rk4", 0.1), ("rk4", 0.05), ("rk4", 0.02),
                                                         ("dop853", 1e-6), ("dop853", 1e-9)}
    assert all(r["status"] == "ok" and 0 < r["error_rel"] < 1e-2 and r["nfev"] > 0 for r in wp)
    rk4 = sorted((r for r in wp if r["solver"] == "rk4"), key=lambda r: r["setting"])
    assert rk4[0]["error_rel"] < rk4[-1]["error_rel"] / 100  # h / 5: error / 625, at least / 100
    assert all(0 < r["energy_drift_max"] < 1e-2 for r in res.tables["energy"])
    assert res.tables["cheapest"] and not res.failures


def test_the_advisor_accepts_a_plain_function(lv_study):
    from rk4h.validation.advise import advise

    adv = advise(lv_study[0], 1e-6)
    best = adv.to_json()
    assert "fewest" in best or "rk4" in best or "dop853" in best
    assert "a first-order ODE without a closed form" in best


# -- the scene form --------------------------------------------------------------------------
def test_the_shipped_scene_loads_with_its_invariant():
    scene = load_scene(SCENE_DIR / "lotka_volterra.toml")
    model = scene.build_model()
    assert scene.model == "ode" and model.has_invariant()
    np.testing.assert_array_equal(scene.y0(), [1.0, 1.0])
    assert {"state", "energy", "convergence", "work_precision"} <= set(scene.outputs)


def _doc(**over):
    doc = {"name": "ode-x", "model": "ode", "params": dict(LV), "initial": {"y": [1.0, 1.0]},
           "run": {"t_end": 1.0, "h": [0.1], "tolerances": [1e-6], "solvers": ["rk4", "dop853"]}}
    for key, value in over.items():
        table, _, field = key.partition(".")
        if field:
            doc[table] = {**doc[table], field: value}
        else:
            doc[table] = value
    return doc


@pytest.mark.parametrize("over, message", [
    ({"initial": {"x": [1.0, 1.0]}}, "field `initial`: needs `y`"),
    ({"initial": {"y": [1.0]}}, "field `initial.y`: must have 2 entries"),
    ({"initial": {"y": [1.0, 1.0], "v": [0.0, 0.0]}}, "give `y` alone"),
    ({"initial": {"y": [0.0, 1.0]}}, "field `initial.y`: is no state to start from: the invariant is not finite"),
    ({"run.solvers": ["rk4", "heyoka"]}, "field `run.solvers[1]`: needs a mechanical model"),
    ({"run.solvers": ["stormer-verlet"]}, "field `run.solvers[0]`: needs a mechanical model"),
    ({"run.outputs": ["state", "modes"]}, "field `run.outputs[1]`: does not apply to model 'ode'"),
    ({"params.exact": ["exp(t)", "2"]}, "field `params.exact`: `exact` at t = 0 is [1.0, 2.0], not the initial"),
    ({"params.equations": ["a*u", "v/"]}, "field `params`: `equations[1]`"),
])
def test_bad_ode_scenes_are_one_line_naming_the_field(over, message):
    with pytest.raises(SceneError) as e:
        scene_from_dict(_doc(**over), "ode.toml")
    assert message in str(e.value) and "\n" not in str(e.value)


def test_a_mechanical_model_refuses_initial_y():
    doc = {"name": "c", "model": "chain", "params": {"masses": [1.0], "springs": [1.0, 1.0]},
           "initial": {"y": [0.1, 0.0]}, "run": {"t_end": 1.0, "h": [0.1], "solvers": ["rk4"]}}
    with pytest.raises(SceneError, match="field `initial.y`: is the state of a first-order ODE"):
        scene_from_dict(doc, "c.toml")


@pytest.mark.slow
def test_the_shipped_scene_runs_end_to_end_with_every_expectation_held(tmp_path):
    from rk4h.validation.run_all import main as run_all

    out = tmp_path / "out"
    assert run_all(["--scene", "lotka-volterra", "--out", str(out), "--workers", "1", "--repeats", "1"]) == 0
    text = (out / "index.md").read_text()
    assert "None: every expectation held" in text  # exit 0 already says it; the report says it too
    assert (out / "lotka_volterra_variables.png").is_file()


def test_fun_is_never_called_outside_the_span():
    calls = []

    def f(t, y):
        calls.append(t)
        return [1.0 / t]  # x' = 1/t: not finite at t = 0

    run = integrate("rk4", f, [0.0], np.linspace(1.0, 2.0, 11), 0.01)
    assert run.ok and min(calls) >= 1.0
    assert abs(run.y[0, -1] - math.log(2.0)) < 1e-9


def test_a_scene_whose_rhs_is_not_finite_at_the_start_is_refused():
    doc = _doc(params={"variables": ["x"], "equations": ["1/t"]}, initial={"y": [0.0]})
    with pytest.raises(SceneError, match=r"field `initial.y`: is no state to start from: the right-hand side is "
                                         r"not finite there \(dx/dt = inf\)"):
        scene_from_dict(doc, "ode.toml")


def test_a_typed_exact_solution_is_the_truth_of_a_scene():
    doc = _doc(params={"variables": ["x", "v"], "equations": ["v", "-w^2*x"], "constants": {"w": 2.0},
                       "exact": ["cos(w*t)", "-w*sin(w*t)"], "invariant": "w^2*x^2 + v^2"},
               initial={"y": [1.0, 0.0]})
    scene = scene_from_dict(doc, "ode.toml")
    t = scene.t_eval()
    truth = reference_solution(scene.build_model(), scene.y0(), t)
    assert truth.kind == ode_truth.KIND_EXACT
    np.testing.assert_allclose(truth.y, [np.cos(2 * t), -2 * np.sin(2 * t)], rtol=0, atol=1e-15)
    assert truth.energy_drift < 1e-15


def test_an_ode_scene_exports_its_trajectories_to_netcdf(tmp_path):
    """``outputs = ["trajectory"]`` on a first-order ODE: the variables by name and the invariant,
    read back through xarray (issue 28: it was refused as "does not apply to model 'ode'")."""
    import contextlib
    import io

    import xarray as xr

    from rk4h.validation.run_all import main as run_all

    scene = tmp_path / "lv.toml"
    scene.write_text("\n".join(['name = "lv-trajectory"', 'model = "ode"', "[params]",
                                'variables = ["u", "v"]', 'equations = ["a*u - b*u*v", "-c*v + d*u*v"]',
                                f"constants = {{ a = {A}, b = {B}, c = {C}, d = {D} }}",
                                f'invariant = "{LV["invariant"]}"', "[initial]", "y = [1.0, 1.0]", "[run]",
                                "t_end = 2.0", "h = [0.1, 0.05]", "tolerances = [1e-6]",
                                'solvers = ["rk4", "dop853"]', 'outputs = ["state", "trajectory"]', ""]))
    out = tmp_path / "out"
    log = io.StringIO()
    with contextlib.redirect_stdout(log), contextlib.redirect_stderr(log):
        rc = run_all(["--scene", str(scene), "--out", str(out), "--workers", "1", "--repeats", "1",
                      "--no-figures"])
    assert rc == 0, log.getvalue()
    with xr.open_dataset(out / "trajectory-lv-trajectory.nc") as ds:
        assert list(ds["component"].values) == ["u", "v"]
        assert ds.sizes["run"] == 3 and ds.sizes["time"] >= 2
        assert "invariant" in ds["energy"].attrs["long_name"] and "[q, v]" not in ds.attrs["units"]
        rk4 = ds["solver"].values == "rk4"
        y = ds["y"].values[rk4]  # (run, time, component)
        np.testing.assert_array_equal(y[:, 0, :], 1.0)  # the initial state
        assert np.isfinite(y).all() and not np.allclose(y[:, -1, :], 1.0)
        energy = ds["energy"].values[rk4]
        for run_y, run_e in zip(y, energy):  # energy is the invariant of the stored state
            np.testing.assert_allclose(run_e, [lv_invariant(s) for s in run_y], rtol=1e-12)
        assert abs(energy[:, 0] - 2.0).max() < 1e-12  # I(1, 1) = d + b = 2
