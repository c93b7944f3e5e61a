"""Weak errors of an ensemble and the batch reference of a nonlinear one
(``rk4h.validation.ensemble``, the ``ensemble`` output): the weak error is
the numpy formula; a linear model's batch reference agrees with its exact
modal solutions to the reference bound; a too-coarse reference fails the
check; RK4's strong and weak errors on the shipped nonlinear scene fall at
order 4."""
import copy
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

import rk4h
from rk4h.validation import run_all
from rk4h.validation.ensemble import EnsembleSums, batch_reference, reference_refinement
from rk4h.validation.outputs import ensemble as ens_output
from rk4h.validation.plan import plan
from rk4h.validation.scenes import load_scene, scene_from_dict

pytest.importorskip("numba", reason="numba is not installed (the fast extra)")

SCENE = Path(rk4h.validation.__file__).parent / "scenes" / "ensemble_planar4_weak.toml"

LINEAR = {
    "name": "ens-weak-linear", "model": "chain",
    "params": {"masses": [0.815, 3.099], "springs": [41.5, 138.0, 157.8], "walls": "both"},
    "initial": {"x": [0.005, 0.005], "v": [0.0, 0.0]},
    "run": {"t_end": 1.0, "h": [0.02, 0.01], "output_dt": 0.02, "solvers": ["rk4"], "outputs": ["ensemble"]},
    "ensemble": {"size": 12, "seed": 2,
                 "initial.x[0]": {"dist": "uniform", "low": 0.0, "high": 0.01},
                 "params.masses[1]": {"dist": "grid", "low": 0.5, "high": 4.0, "n": 3}},
}


def _small_nonlinear(size=24):
    scene = load_scene(SCENE)
    scene.ensemble = dict(scene.ensemble, size=size)
    return scene


def test_weak_error_is_the_numpy_formula_over_chunks():
    # a nonlinear batch (planar4 exact) against a finer run of the same batch, added in two chunks
    model = rk4h.make_model("planar4", {"m": 0.815, "k": 41.5, "l": 0.01, "linear": False})
    rng = np.random.default_rng(5)
    y0 = np.zeros((7, 4))
    y0[:, 0] = rng.uniform(1e-3, 3e-3, 7)
    y0[:, 1] = rng.uniform(-2e-3, 2e-3, 7)
    t = np.linspace(0.0, 1.0, 26)
    res = rk4h.ensemble(model, y0, (0.0, 1.0), h=0.02, t_eval=t, backend="numba")
    ref = rk4h.ensemble(model, y0, (0.0, 1.0), h=0.004, t_eval=t, backend="numba")
    sums = EnsembleSums()
    for sl in (slice(0, 3), slice(3, 7)):
        part = type(res)(**{**res.__dict__, "y": res.y[sl], "status": res.status[sl]})
        sums.add(model, part, y0[sl], y_ref=ref.y[sl], ref_status=ref.status[sl])
    weak, weak_e, _ = sums.weak()
    d = res.y - ref.y                                              # (B, m, n)
    direct = np.max(np.abs(d.mean(axis=0))) / np.max(np.abs(ref.y).max(axis=2).mean(axis=0))
    E = np.array([model.energy(res.y[b].T) for b in range(7)])    # (B, m)
    direct_e = np.max(np.abs((E - E[:, :1]).mean(axis=0))) / E[:, 0].mean()
    assert weak == pytest.approx(direct, rel=1e-12) and weak_e == pytest.approx(direct_e, rel=1e-12)
    strong = np.max(np.abs(d), axis=(1, 2)) / np.max(np.abs(ref.y), axis=(1, 2))
    np.testing.assert_allclose(sums.errors, strong, rtol=1e-13)
    # the mean of the errors, not of the states' norms: the weak error lies below the largest strong one
    assert weak < strong.max()


def test_a_linear_batch_reference_agrees_with_the_modal_solutions(monkeypatch):
    scene = scene_from_dict(copy.deepcopy(LINEAR))
    specs = [s for s in plan(scene) if s.purpose == "ensemble"]
    modal = {s.setting: ens_output.execute(scene, s, False).values for s in specs}
    # A reference step where the reference's truncation error, not its round-off, sets the bound:
    # blanes-moan6 at 0.005 s confirmed at 0.01 s (the default rule's step gives a round-off-level bound).
    monkeypatch.setattr(ens_output, "REFERENCE", "batch")
    monkeypatch.setattr(ens_output, "reference_step", lambda scene, model: 0.01)
    for s in specs:
        v = ens_output.execute(scene, s, False).values
        m = modal[s.setting]
        assert m["reference"] == "modal" and m["reference_bound"] == 0.0
        assert v["reference"] == "blanes-moan6 h=0.005" and v["reference_failed"] == 0
        bound, wbound = v["reference_bound"], v["weak_reference_bound"]
        assert 0 < bound < 1e-3 * v["error_median"]
        for k in ("median", "p95", "max"):
            assert abs(v[f"error_{k}"] - m[f"error_{k}"]) <= bound
            assert v[f"energy_error_{k}"] == m[f"energy_error_{k}"]  # the energy needs no reference
        assert abs(v["weak_error"] - m["weak_error"]) <= wbound
        assert v["weak_energy_error"] == m["weak_energy_error"]


def test_the_batch_reference_is_within_its_bound_of_the_exact_solution():
    from rk4h.references.exact import modal_solution

    model = rk4h.make_model("chain", LINEAR["params"])
    y0 = np.array([[0.005, 0.005, 0.0, 0.0], [0.01, -0.002, 0.1, 0.0]])
    t = np.linspace(0.0, 1.0, 51)
    y_ref, bound, delta, status = batch_reference(model, y0, None, t, 1.0, 0.01)
    assert (status == 0).all()
    for b in range(2):
        exact = modal_solution(model, y0[b])(t).T
        err = np.max(np.abs(y_ref[b] - exact)) / np.max(np.abs(exact))
        assert 0 < err <= bound[b]
    assert 0 < np.max(np.abs(y_ref - np.stack([modal_solution(model, y)(t).T for y in y0]))) <= delta.max()


def test_a_too_coarse_reference_fails_the_check(tmp_path, monkeypatch):
    # blanes-moan6 at 0.02 s confirmed at 0.04 s (off the 0.02 s output grid: cubic Hermite values there)
    monkeypatch.setattr(ens_output, "reference_step", lambda scene, model: 0.04)
    results, failures = run_all.run([_small_nonlinear()], tmp_path, workers=1, figures=False)
    bad = [f for f in failures if "the reference (blanes-moan6 h=0.02) disagrees" in f]
    assert len(bad) == 2, failures  # both steps: the bound is not 10x below the errors


def test_rk4_strong_and_weak_errors_fall_at_order_4_on_the_nonlinear_scene(tmp_path):
    scene = load_scene(SCENE)
    assert not scene.build_model().linear and scene.h == [0.02, 0.01]
    results, failures = run_all.run([scene], tmp_path, workers=1, figures=False)
    assert failures == []
    ens = pd.read_csv(tmp_path / "ensemble.csv").set_index("h_s")
    assert (ens.instances == 256).all() and (ens.failed == 0).all() and (ens.reference_failed == 0).all()
    assert (ens.reference == "blanes-moan6 h=0.0025").all()
    # Halving h divides an order-4 error by 2^4 = 16 up to the next term of its expansion; a window of
    # half an order either side (observed order 3.5 to 4.5, ratio 11.3 to 22.6) tells order 4 from 3 and 5.
    for col in ("error_median", "error_p95", "error_max", "weak_error"):
        order = np.log2(ens[col][0.02] / ens[col][0.01])
        assert abs(order - 4.0) < 0.5, (col, order)
    assert (ens.reference_bound * 10 <= ens.error_median).all()
    assert (ens.weak_reference_bound * 10 <= ens.weak_error).all()


@pytest.mark.parametrize("h, order, omega, r", [(0.01, 4, 10.09, 2), (0.1, 4, 10.0, 4), (0.05, 4, 10.0, 3), (0.05, 2, 10.0, 2),
                                                (0.001, 4, 10.0, 2), (0.1, 4, float("nan"), 4)])
def test_reference_refinement(h, order, omega, r):
    # r = ceil(1e3^(1/6) z^(1 - p/6)), at least 2; z = omega h, at most 1, and 1 when omega is unknown
    assert reference_refinement(h, order, omega) == r


def test_the_budget_counts_the_batch_reference():
    from rk4h.validation import budget

    # RK4 at 0.02 and 0.01 s over 2 s (100 + 200 steps) and, per spec, the reference at 0.0025 s (800
    # steps) with its confirmation at 0.005 s (400), for each of the 256 instances
    assert budget.estimate(load_scene(SCENE)).steps == 256 * (100 + 200 + 2 * (800 + 400))


@pytest.mark.parametrize("column", ["error_median", "error_p95", "error_max", "reference_bound", "weak_error",
                                    "weak_reference_bound"])
def test_a_nan_in_the_reference_check_fails_it(column):
    """Every NaN in the numbers the reference check compares fails it (a NaN
    error statistic other than the first used to drop out of ``min``)."""
    from rk4h.validation.outputs.ensemble import reference_check

    row = {"error_median": 1e-3, "error_p95": 2e-3, "error_max": 3e-3, "reference_bound": 1e-6,
           "weak_error": 1e-4, "weak_reference_bound": 1e-7, "reference_failed": 0}
    assert reference_check(row)[0]
    row[column] = float("nan")
    ok, worst = reference_check(row)
    assert not ok and worst == float("inf")
