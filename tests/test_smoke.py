"""Smoke test: the package imports and RK4 integrates the thesis' 2-DOF case 1."""
import numpy as np

import rk4core
from references.exact import modal_solution


def test_two_dof_case1_rk4_matches_modal_solution():
    model = rk4core.make_model("chain", {"masses": [0.815, 3.099], "springs": [41.5, 138.0, 157.8]})
    y0 = model.state([0.005, 0.005])
    res = rk4core.solve(model.rhs, (0.0, 10.0), y0, h=0.01)
    assert res.success
    exact = modal_solution(model, y0)
    err = np.max(np.abs(res.y[:2] - exact(res.t)[:2]))
    # Per step RK4 makes a phase error theta^5/120 in each mode (theta = omega h),
    # so after n steps the displacement error is at most sum_j |mode amplitude_j| n theta_j^5/120.
    theta = exact.omega * res.h
    amp = np.max(np.abs(exact.phi), axis=0) * np.hypot(exact.eta0, exact.deta0 / exact.omega)
    bound = np.sum(amp * res.n_steps * theta**5 / 120)
    assert 0.2 * bound < err < 1.05 * bound
