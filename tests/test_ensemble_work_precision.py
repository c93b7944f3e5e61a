"""The ``ensemble`` output's work-precision figure: RHS calls per instance in
its table, and error statistics against them drawn per solver."""
import copy

import numpy as np
import pandas as pd
import pytest

from rk4h.validation import run_all
from rk4h.validation.scenes import scene_from_dict

pytest.importorskip("numba", reason="numba is not installed (the fast extra)")

DOC = {
    "name": "ens-wp", "model": "chain",
    "params": {"masses": [0.815, 3.099], "springs": [41.5, 138.0, 157.8], "walls": "both"},
    "initial": {"x": [0.005, 0.005], "v": [0.0, 0.0]},
    "run": {"t_end": 1.0, "h": [0.04, 0.02, 0.01], "solvers": ["rk4", "stormer-verlet"], "outputs": ["ensemble"]},
    "ensemble": {"size": 30, "seed": 3, "initial.x[0]": {"dist": "uniform", "low": -0.01, "high": 0.01}},
}


def test_rhs_calls_and_the_work_precision_figure(tmp_path):
    results, failures = run_all.run([scene_from_dict(copy.deepcopy(DOC))], tmp_path, workers=1)
    assert failures == []
    t = pd.read_csv(tmp_path / "ensemble.csv")
    steps = np.round(1.0 / t.h_s).astype(int)
    rk4, sv = t.solver == "rk4", t.solver == "stormer-verlet"
    # RK4: 4 calls a step; Stormer-Verlet reuses the last acceleration (first same as last): N + 1
    assert (t.rhs_calls[rk4] == 4 * steps[rk4]).all() and (t.rhs_calls[sv] == steps[sv] + 1).all()
    # more calls, smaller errors along each solver's line (fourth and second order)
    for solver in ("rk4", "stormer-verlet"):
        s = t[t.solver == solver].sort_values("rhs_calls")
        assert (np.diff(s.error_median) < 0).all() and (np.diff(s.error_p95) < 0).all()
    png = tmp_path / "ens-wp-ensemble-work-precision.png"
    assert png.stat().st_size > 0
    index = (tmp_path / "index.md").read_text()
    assert "ens-wp-ensemble-work-precision.png" in index and "over 30 instances" in index
