"""The ``ensemble`` and ``stability_map`` outputs: a small [ensemble] scene
through run_all, its tables read back; one-line errors naming the field; the
map's boundary check can fail."""
import copy
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from rk4h.validation import run_all
from rk4h.validation.outputs import stability_map as smap_output
from rk4h.validation.scenes import SceneError, scene_from_dict

pytest.importorskip("numba", reason="numba is not installed (the fast extra)")

DOC = {
    "name": "ens-small", "model": "chain",
    "params": {"masses": [0.815, 3.099], "springs": [41.5, 138.0, 157.8], "walls": "both"},
    "initial": {"x": [0.005, 0.005], "v": [0.0, 0.0]},
    "run": {"t_end": 1.0, "h": [0.02, 0.01], "solvers": ["rk4", "stormer-verlet"],
            "outputs": ["ensemble", "stability_map"]},
    "ensemble": {"size": 40, "seed": 2,
                 "initial.x[0]": {"dist": "uniform", "low": -0.01, "high": 0.01},
                 "params.masses[1]": {"dist": "grid", "low": 0.0815, "high": 8.15, "n": 8, "scale": "log"},
                 "map_h": {"low": 0.03, "high": 0.25, "n": 30}, "map_steps": 1000},
}


def test_a_small_ensemble_scene_through_run_all(tmp_path):
    scene = scene_from_dict(copy.deepcopy(DOC))
    results, failures = run_all.run([scene], tmp_path, workers=1)
    assert failures == []
    ens = pd.read_csv(tmp_path / "ensemble.csv")
    assert set(zip(ens.solver, ens.h_s)) == {(s, h) for s in ("rk4", "stormer-verlet") for h in (0.02, 0.01)}
    assert (ens.instances == 40).all() and (ens.failed == 0).all()
    assert (ens.error_median <= ens.error_p95).all() and (ens.error_p95 <= ens.error_max).all()
    # a linear model: each instance's exact modal solution, no batch reference and no bound
    assert (ens.reference == "modal").all() and (ens.reference_bound == 0).all() and (ens.reference_h_s == 0).all()
    assert np.isfinite(ens.weak_error).all() and np.isfinite(ens.weak_energy_error).all()
    rk4 = ens[ens.solver == "rk4"].set_index("h_s")
    # RK4 is fourth order: halving h divides the error by about 16 (the worst instance, omega h <= 1.2)
    assert 10 < rk4.error_max[0.02] / rk4.error_max[0.01] < 22
    sv = ens[ens.solver == "stormer-verlet"].set_index("h_s")
    assert (sv.error_max > rk4.error_max).all()  # second order: larger at the same step
    m = pd.read_csv(tmp_path / "stability_map.csv")
    assert len(m) == 8 and (m.parameter == "masses[1]").all()
    # the boundary within one grid spacing of 2 sqrt(2) at every mass
    assert (np.abs(m.z_max - 2.0 * np.sqrt(2.0)) < m.z_next - m.z_max).all()
    assert (tmp_path / "ens-small-stability-map.png").stat().st_size > 0
    index = (tmp_path / "index.md").read_text()
    assert "ens-small-stability-map.png" in index and "2.8284" in index


def test_the_boundary_check_can_fail(tmp_path, monkeypatch):
    # a wrong limit (Heun3's sqrt(3) for an RK4 map) must fail the check at every value
    monkeypatch.setattr(smap_output, "_limit", lambda method: np.sqrt(3.0))
    doc = copy.deepcopy(DOC)
    doc["run"]["outputs"] = ["stability_map"]
    results, failures = run_all.run([scene_from_dict(doc)], tmp_path, workers=1)
    assert any("of 1.7321 at 8 of 8 values" in f for f in failures)


def test_a_heun3_map_meets_its_own_boundary(tmp_path):
    # the limit is the tableau's imaginary-axis boundary, not RK4's: Heun3's is sqrt(3)
    doc = copy.deepcopy(DOC)
    doc["name"] = "ens-heun3"
    doc["methods"] = {"heun3": {"A": [[0, 0, 0], ["1/3", 0, 0], [0, "2/3", 0]], "b": ["1/4", 0, "3/4"],
                                "c": [0, "1/3", "2/3"]}}  # a scene tableau: Heun's third-order method
    doc["run"].update(solvers=["heun3"], outputs=["stability_map"])
    doc["ensemble"].update(map_h={"low": 0.015, "high": 0.15, "n": 30})
    results, failures = run_all.run([scene_from_dict(doc)], tmp_path, workers=1)
    assert failures == []
    m = pd.read_csv(tmp_path / "stability_map.csv")
    assert len(m) == 8 and (m.solver == "heun3").all()
    assert (np.abs(m.z_max - np.sqrt(3.0)) < m.z_next - m.z_max).all()
    assert not (np.abs(m.z_max - 2.0 * np.sqrt(2.0)) < m.z_next - m.z_max).any()
    assert "1.7321" in (tmp_path / "index.md").read_text()


def test_limit_is_the_tableau_boundary():
    scene = scene_from_dict(copy.deepcopy(DOC))
    assert smap_output._limit(scene.method("rk4")) == pytest.approx(2.0 * np.sqrt(2.0), rel=1e-12)
    assert smap_output._limit(scene.method("stormer-verlet")) == pytest.approx(2.0, rel=1e-12)
    assert smap_output._limit(scene.method("euler")) is None  # no stable interval on the imaginary axis
    assert smap_output._limit(scene.method("dop853")) is None  # adaptive: no tableau


@pytest.mark.parametrize("edit, field", [
    (lambda d: d["ensemble"].update(size=0), "ensemble.size"),
    (lambda d: d["ensemble"]["initial.x[0]"].update(high=float("nan")), 'ensemble."initial.x[0]".high'),
    (lambda d: d["ensemble"].update({"params.walls": {"dist": "uniform", "low": 0, "high": 1}}), "ensemble"),
    (lambda d: d["ensemble"].update(size=41), "ensemble.size"),
    (lambda d: d["ensemble"].pop("map_h"), "ensemble.map_h"),
    (lambda d: d["ensemble"].update(map_steps=0), "ensemble.map_steps"),
    (lambda d: d.pop("ensemble"), "run.outputs"),
    (lambda d: d["params"].update(alpha=1.0), "run.outputs"),
])
def test_bad_ensembles_name_the_field(edit, field):
    doc = copy.deepcopy(DOC)
    edit(doc)
    with pytest.raises(SceneError) as info:
        scene_from_dict(doc)
    assert info.value.field == field and "\n" not in str(info.value)


def test_cli_exit_2_one_line(tmp_path):
    text = (tmp_path / "s.toml")
    text.write_text('name = "bad"\nmodel = "chain"\n[params]\nmasses = [1.0, 1.0]\nsprings = [1.0, 1.0, 1.0]\n'
                    '[initial]\nx = [0.01, 0.0]\n[run]\nt_end = 1.0\nh = [0.1]\nsolvers = ["rk4"]\n'
                    'outputs = ["ensemble"]\n[ensemble]\nsize = 10\n'
                    '"params.masses[1]" = { dist = "normal", mean = 1.0, std = -1.0 }\n')
    out = subprocess.run([sys.executable, str(Path(__file__).resolve().parent.parent / "validation" / "run_all.py"), "--scene", str(text), "--out",
                          str(tmp_path / "o"), "--allow-code"], capture_output=True, text=True)
    assert out.returncode == 2
    lines = out.stderr.strip().splitlines()
    assert len(lines) == 1 and 'ensemble."params.masses[1]".std' in lines[0] and "Traceback" not in out.stderr


def test_chunks_of_instances_give_the_same_statistics(monkeypatch):
    from rk4h.validation.outputs import ensemble as ens_output
    from rk4h.validation.plan import plan

    scene = scene_from_dict(copy.deepcopy(DOC))
    spec = next(s for s in plan(scene) if s.purpose == "ensemble")
    whole = ens_output.execute(scene, spec, False).values
    monkeypatch.setattr(ens_output, "CHUNK_BYTES", 8 * 51 * 4 * 7)  # 7 instances per chunk
    chunked = ens_output.execute(scene, spec, False).values
    assert chunked == whole and whole["instances"] == 40


def test_loading_a_huge_ensemble_scene_draws_no_instances():
    # Validation checks every field on one instance; the 10^8 instances (3.2 GB of y0 here) are
    # drawn only by a run, which the budget refuses first.
    import tracemalloc

    doc = copy.deepcopy(DOC)
    doc["ensemble"]["size"] = 10 ** 8
    tracemalloc.start()
    try:
        scene_from_dict(doc)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 50e6, peak


def test_the_budget_counts_every_instance():
    from rk4h.validation import budget

    doc = copy.deepcopy(DOC)
    doc["ensemble"]["size"] = 10 ** 8
    scene = scene_from_dict(doc)
    with pytest.raises(SceneError, match="integration steps"):
        budget.check(scene)
    assert budget.estimate(scene_from_dict(copy.deepcopy(DOC))).steps == 40 * (50 + 100) * 2 + 8 * 30 * 1000
