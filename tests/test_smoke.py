"""Smoke test: the package imports and RK4 -- the generic loop and the compiled
fast path, each on its own -- integrates the thesis' 2-DOF case 1."""
import numpy as np
import pytest

import rk4h
import rk4h.fast as fast
from rk4h.references.exact import modal_solution

SOLVE = {
    "generic": lambda model, y0: rk4h.solve(model.rhs, (0.0, 10.0), y0, h=0.01),
    "fast": lambda model, y0: fast.solve_model(model, (0.0, 10.0), y0, h=0.01),
}


@pytest.mark.parametrize("path", sorted(SOLVE))
def test_two_dof_case1_rk4_matches_modal_solution(path):
    model = rk4h.make_model("chain", {"masses": [0.815, 3.099], "springs": [41.5, 138.0, 157.8]})
    y0 = model.state([0.005, 0.005])
    res = SOLVE[path](model, y0)
    assert res.success
    exact = modal_solution(model, y0)
    err = np.max(np.abs(res.y[:2] - exact(res.t)[:2]))
    # RK4 multiplies each mode by R(i theta) = 1 - theta^2/2 + theta^4/24 - i(theta - theta^3/6),
    # whose phase lags exp(-i theta) by theta^5/120 + O(theta^7) per step (theta = omega h), so
    # after n steps a mode of amplitude a is off by at most a n theta^5/120 (|R| < 1 adds a
    # smaller amplitude error). Displacements are summed over the two modes.
    theta = exact.omega * res.h
    amp = np.max(np.abs(exact.phi), axis=0) * np.hypot(exact.eta0, exact.deta0 / exact.omega)
    bound = np.sum(amp * res.n_steps * theta**5 / 120)
    assert 0.2 * bound < err < 1.05 * bound
