"""What the generated loops share: status codes and the cubic Hermite output.

The force kernels and the loops themselves are generated per model
definition and per method by :mod:`rk4h.fast.codegen` (from
:mod:`rk4h.models.compiled`); nothing here depends on a model.

Everything numba compiles from a fixed file lives in this one module on
purpose: numba's on-disk cache (``cache=True``) is invalidated by the
modification time of the file that holds the cached function only, so the
generated files embed a hash of this file (a change here yields new files and
a fresh compile, never a stale cached loop).

Every kernel is compiled with ``error_model="numpy"``: a division by zero
gives inf or NaN as in numpy (and so a non-finite state, status -1, as on the
generic path) instead of raising ``ZeroDivisionError``.
"""
from __future__ import annotations

import numpy as np
from numba import njit

STATUS_OK = 0
STATUS_UNSTABLE = -1  # a component with NOT(|y_i| <= bound_i): non-finite, or grown past its bound
STATUS_NONFINITE = STATUS_UNSTABLE  # former name

#: Largest finite float64: the bound of the instability test when growth is not tested.
DBL_MAX = np.finfo(np.float64).max


@njit(cache=True, inline="always", error_model="numpy")
def hermite_weights(th, step):
    """Weights ``(h00, h10 h, h01, h11 h)`` of the cubic Hermite interpolant
    ``h00 y0 + h10 h f0 + h01 y1 + h11 h f1`` at fraction ``th`` of a step
    ``h`` (as ``rk4h.solver._emit``)."""
    h00 = (1 + 2 * th) * (1 - th) ** 2
    h10 = th * (1 - th) ** 2
    h01 = th * th * (3 - 2 * th)
    h11 = th * th * (th - 1)
    return h00, h10 * step, h01, h11 * step


@njit(cache=True, error_model="numpy")
def _hermite(ys, row, th, y_old, y_new, k, step, f1):
    """``ys[row]`` = cubic Hermite interpolant at fraction ``th`` of the step
    ``[y_old, y_new]`` with end slopes ``k[0] = f(y_old)`` and ``f1[0] =
    f(y_new)``."""
    h00, a10, h01, a11 = hermite_weights(th, step)
    for p in range(y_new.shape[0]):
        ys[row, p] = h00 * y_old[p] + a10 * k[0, p] + h01 * y_new[p] + a11 * f1[0, p]
