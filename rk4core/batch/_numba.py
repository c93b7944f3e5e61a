"""The numba backend of :func:`rk4h.ensemble`: the loop of
:func:`rk4h.fast.solve_model` (straight-line for the small states, the
array loop beyond; :mod:`rk4h.fast.codegen`) called once per instance
inside a ``prange`` over instances. The per-instance call is the very
compiled loop the scalar path runs, so each instance's numbers are the
scalar path's bit for bit."""
from __future__ import annotations

import numpy as np

from ..fast import codegen

__all__ = ["run", "batch_loop", "batch_key"]

_BATCH: dict = {}


def batch_source(loop_text: str, array: bool) -> str:
    """``loop_text`` (:func:`rk4h.fast.codegen.source` or
    :func:`~rk4h.fast.codegen.array_source`: the very text the scalar path
    loads) followed by ``batch``, a ``parallel=True`` function running that
    module's ``integrate`` on every row of its batched arguments;
    ``out[b] = (steps completed, status)``. Loaded through codegen's loader,
    the module and numba's compiled code of both functions live in rk4h's
    private on-disk cache: the wrapper is compiled once per machine, not once
    per process."""
    work = "w[b], " if array else ""
    return loop_text + f"""

from numba import prange  # noqa: E402


@njit(parallel=True, error_model="numpy")  # on-disk caching is switched on by codegen's loader
def batch(fp, ip, mass, w, y0, t0, step, n, idx, theta, ys, bound, pending, y_fail, out):
    for b in prange(y0.shape[0]):
        r = integrate(fp[b], ip, mass[b], {work}y0[b], t0, step, n, idx, theta, ys[b], bound[b], pending[b],
                      y_fail[b])
        out[b, 0] = r[0]
        out[b, 1] = r[2]
"""


def batch_key(tab, kern, dim: int) -> tuple:
    """``(key, uses the array loop)`` of the batch loop for method ``tab``,
    force kernel ``kern``, state size ``dim``: equal keys, one generated module."""
    array = codegen.array_loop(kern, dim)
    return codegen.loop_key(tab, kern, array), array


def batch_loop(tab, kern, dim: int):
    """``(batch function, uses the array loop)`` for method ``tab``, force kernel ``kern``, state size ``dim``."""
    key, array = batch_key(tab, kern, dim)
    fn = _BATCH.get(key)
    if fn is None:
        text = codegen.array_source(tab, kern) if array else codegen.source(tab, kern)
        fn = _BATCH[key] = codegen.load_generated(batch_source(text, array)).batch
    return fn, array


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
