"""The numba backend of :func:`rk4h.ensemble`: the loop of
:func:`rk4h.fast.solve_model` (straight-line for the small states, the
array loop beyond; :mod:`rk4h.fast.codegen`) called once per instance
inside a ``prange`` over instances. The per-instance call is the very
compiled loop the scalar path runs, so each instance's numbers are the
scalar path's bit for bit."""
from __future__ import annotations

import numpy as np
from numba import njit, prange

from ..fast.codegen import MAX_UNROLLED_DIM, array_kernel, kernel

__all__ = ["run", "batch_loop"]

_BATCH: dict = {}


def _make(loop, array: bool):
    """A ``parallel=True`` function running ``loop`` on every row of its
    batched arguments (compiled in memory on first call, once per loop and
    process)."""
    if array:
        @njit(parallel=True, error_model="numpy")
        def batch(fp, ip, mass, w, y0, t0, step, n, idx, theta, ys, bound, pending, y_fail, out):
            for b in prange(y0.shape[0]):
                r = loop(fp[b], ip, mass[b], w[b], y0[b], t0, step, n, idx, theta, ys[b], bound[b], pending[b],
                         y_fail[b])
                out[b, 0] = r[0]
                out[b, 1] = r[2]
    else:
        @njit(parallel=True, error_model="numpy")
        def batch(fp, ip, mass, w, y0, t0, step, n, idx, theta, ys, bound, pending, y_fail, out):
            for b in prange(y0.shape[0]):
                r = loop(fp[b], ip, mass[b], y0[b], t0, step, n, idx, theta, ys[b], bound[b], pending[b],
                         y_fail[b])
                out[b, 0] = r[0]
                out[b, 1] = r[2]
    return batch


def batch_loop(tab, kern, dim: int):
    """``(batch function, uses the array loop)`` for method ``tab``, force kernel ``kern``, state size ``dim``."""
    array = not (dim <= MAX_UNROLLED_DIM and kern.has_scalar())
    loop = array_kernel(tab, kern) if array else kernel(tab, kern)
    fn = _BATCH.get(id(loop))
    if fn is None:
        fn = _BATCH[id(loop)] = (_make(loop, array), loop)  # the loop is kept, so its id is never reused
    return fn[0], array


def run(tab, kern, fp, mass, y0, t0, step, n, idx, theta, ys, bound, pending, *, dtype="float64"):
    """Integrate the rows of ``y0`` (one chunk), writing ``ys`` (B, rows, dim)
    in place; returns ``(steps completed, status)`` per instance."""
    B, dim = y0.shape
    fn, array = batch_loop(tab, kern, dim)
    w = np.zeros((B, kern.work_size) if array else (B, 1))
    ip = np.ascontiguousarray(kern.ip, dtype=np.int64)
    y_fail = np.empty((B, dim))
    out = np.zeros((B, 2), dtype=np.int64)
    fn(np.ascontiguousarray(fp), ip, np.ascontiguousarray(mass), w, np.ascontiguousarray(y0), float(t0),
       float(step), int(n), idx, theta, ys, bound, pending, y_fail, out)
    return out[:, 0], out[:, 1]
