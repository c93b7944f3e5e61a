"""The constant-Jacobian callback of :mod:`rk4h.references.solvers.cvode_compiled`,
the same for every model, so compiled once per machine (numba's on-disk cache,
as :mod:`rk4h.fast._dop853_loop`). Imported only where it runs (it imports numba)."""
from __future__ import annotations

import numpy as np
from numba import carray


def cv_jac_constant(t, y, fy, J, ud, tmp1, tmp2, tmp3):
    # CVLsJacFn: the constant Jacobian of a linear model, already permuted and
    # column-major in ud[8], copied into the dense matrix; ud[0][6] counts calls
    sz = carray(ud[0], 7, np.int64)
    n2 = sz[0]
    src = carray(ud[8], n2 * n2, np.float64)
    jj = carray(J[0][1], n2 * n2)
    sz[6] += 1
    for a in range(n2 * n2):
        jj[a] = src[a]
    return 0
