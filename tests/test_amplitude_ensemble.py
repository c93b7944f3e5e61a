"""The ``amplitude_ensemble`` output: the exact planar4 model against its
linearization over an [ensemble] of initial amplitudes, through run_all (its
table read back, the cubic slope), the integration-error check can fail, and
the batched linearized solution equals the per-instance modal solution."""
import copy

import numpy as np
import pandas as pd
import pytest

from rk4h.validation import run_all
from rk4h.validation.outputs.amplitude_ensemble import linearized_batch
from rk4h.validation.scenes import SceneError, scene_from_dict

pytest.importorskip("numba", reason="numba is not installed (the fast extra)")

L = 0.01  # m
DOC = {
    "name": "amp-small", "model": "planar4",
    "params": {"m": 0.815, "k": 41.5, "l": L, "linear": False},
    "initial": {"x": [0.001, 0.0], "v": [0.0, 0.0]},
    "run": {"t_end": 1.0, "h": [0.0005], "output_dt": 0.01, "solvers": ["rk4"],
            "outputs": ["amplitude_ensemble"]},
    "ensemble": {"size": 200, "seed": 5,
                 "initial.x[0]": {"dist": "log-uniform", "low": 1e-4 * L, "high": 0.3 * L}},
}


@pytest.fixture(scope="module")
def small_run(tmp_path_factory):
    """``DOC`` through run_all once: (output directory, failures); the tests
    below read the same run."""
    out = tmp_path_factory.mktemp("amp-small")
    results, failures = run_all.run([scene_from_dict(copy.deepcopy(DOC))], out, workers=1)
    return out, failures


def test_a_small_amplitude_ensemble_through_run_all(small_run):
    tmp_path, failures = small_run
    assert failures == []
    t = pd.read_csv(tmp_path / "amplitude_ensemble.csv")
    assert len(t) == 10 and t.instances.sum() == 200 and (t.failed == 0).all()
    assert (t.amplitude_low.iloc[0] >= 1e-4 * L) and (t.amplitude_high.iloc[-1] <= 0.3 * L)
    assert (t.deviation_median <= t.deviation_p95).all() and (t.deviation_p95 <= t.deviation_max).all()
    # the deviation grows with the amplitude, and the integration error stays far below it in every bin
    assert (np.diff(t.deviation_median) > 0).all()
    assert (t.error_over_deviation < 1e-2).all()
    assert (tmp_path / "amp-small-amplitude-ensemble.png").stat().st_size > 0


def test_the_slope_is_the_cubic_nonlinearity(small_run):
    # displaced along x, the x springs stay linear and the y springs (no pretension at l) add k x^3 / l^2:
    # a frequency shift ~ (x/l)^2, so over a fixed time the deviation ~ x (x/l)^2 = x^3 while it is small
    tmp_path, _ = small_run
    t = pd.read_csv(tmp_path / "amplitude_ensemble.csv")
    small = t[(t.amplitude_high < 0.03 * L) & t.slope.notna()]
    assert len(small) >= 5
    assert np.allclose(small.slope, 3.0, atol=0.05), small.slope.tolist()
    # a least-squares fit over the instances' bin medians agrees
    fit = np.polyfit(np.log(small.amplitude_median), np.log(small.deviation_median), 1)[0]
    assert abs(fit - 3.0) < 0.05


def test_the_integration_error_check_can_fail(tmp_path):
    # omega h = 0.5: RK4's error swamps the tiny deviation of the smallest amplitudes
    doc = copy.deepcopy(DOC)
    doc["run"]["h"] = [0.05]
    doc["run"]["output_dt"] = 0.05
    results, failures = run_all.run([scene_from_dict(doc)], tmp_path, workers=1)
    assert any("integration error estimate at h=0.05 s" in f for f in failures)


def test_the_batched_linearization_equals_the_modal_solution():
    from rk4h.references.exact import modal_solution

    scene = scene_from_dict(copy.deepcopy(DOC))
    model = scene.build_model()
    rng = np.random.default_rng(0)
    y0 = rng.normal(scale=1e-3, size=(5, 4))
    t = np.linspace(0.0, 2.0, 31)
    got = linearized_batch(model, y0, t)
    for b in range(5):
        np.testing.assert_allclose(got[b], modal_solution(model, y0[b])(t).T, rtol=0, atol=1e-15)


def test_it_needs_an_ensemble_table():
    doc = copy.deepcopy(DOC)
    doc.pop("ensemble")
    with pytest.raises(SceneError) as info:
        scene_from_dict(doc)
    assert info.value.field == "run.outputs" and "\n" not in str(info.value)


def test_the_stability_map_still_needs_a_linear_model():
    # `ensemble` takes a nonlinear model (its batch reference); the map needs omega_max
    doc = copy.deepcopy(DOC)
    doc["run"]["outputs"] = ["amplitude_ensemble", "ensemble"]
    assert scene_from_dict(copy.deepcopy(doc)).ensemble
    doc["run"]["outputs"] = ["amplitude_ensemble", "ensemble", "stability_map"]
    doc["ensemble"].update(map_h={"low": 0.01, "high": 0.1, "n": 3},
                           **{"params.k": {"dist": "grid", "low": 40.0, "high": 42.0, "n": 2}})
    with pytest.raises(SceneError) as info:
        scene_from_dict(doc)
    assert info.value.field == "run.outputs" and "`stability_map` needs a linear model" in str(info.value)
