"""A user's Python step function, run on the generic fixed-step loop.

A ``python`` method (:mod:`rk4h.references.registry`) is a function
``step(fun, t, y, h) -> y_next`` that advances the state ``y`` (shape (n,),
``[q, v]``) from ``t`` to ``t + h`` (s) using only ``fun(t, y) -> dy/dt``.
The loop here owns the grid (``n = ceil((t_end - t0) / h)`` equal steps, as
``rk4h.solve``), counts every call of ``fun`` (``nfev``), and stops a run
as UNSTABLE at the same bound as the built-in fixed-step methods
(:data:`rk4h.references.solvers.fixed.MAX_GROWTH` times the state scale). An
exception inside the step, or a step that returns an array of another
shape, ends the run FAILED with the
message; nothing raises.
"""
from __future__ import annotations

import time

import numpy as np

from rk4h.solver import grid_time, step_count

from .base import SolverRun, Status
from .fixed import MAX_GROWTH
from .tolerances import state_scale

__all__ = ["run_python"]


def run_python(method, model, y0: np.ndarray, t_eval: np.ndarray, h: float) -> SolverRun:
    """Integrate ``model`` with the python method ``method``; never raises.

    ``t_eval`` must lie on the step grid ``t0 + i (t_end - t0) / n`` (the
    scenes' output grids do); other times end the run FAILED."""
    name = method.name
    m = t_eval.shape[0]
    y_out = np.full((y0.shape[0], m), np.nan)
    t0, t1 = float(t_eval[0]), float(t_eval[-1])
    n = step_count((t0, t1), h)
    step = (t1 - t0) / n
    idx = np.rint((t_eval - t0) / step).astype(np.int64)
    if np.any(np.abs(t0 + idx * step - t_eval) > 1e-9 * step):
        return SolverRun(name, h, t_eval, y_out, 0, 0, 0.0, status=Status.FAILED, t_fail=t0,
                         message=f"{name}: output times are not on the step grid of h = {step!r}")
    calls = [0]
    rhs = model.rhs

    def fun(t, y):
        calls[0] += 1
        return rhs(t, y)

    stepper = method.step_function()
    bound = MAX_GROWTH * state_scale(model, y0)
    y = np.array(y0, dtype=float)
    ptr = 0
    if idx[0] == 0:
        y_out[:, 0] = y
        ptr = 1
    status, message, t_fail, done = Status.OK, "reached t_end", None, n
    start = time.perf_counter()
    with np.errstate(all="ignore"):
        for i in range(n):
            t = grid_time(t0, t1, step, i, n)
            try:
                y_new = np.asarray(stepper(fun, t, y.copy(), step), dtype=float)
            except Exception as e:  # noqa: BLE001 - the user's step failing is a status
                status, t_fail, done = Status.FAILED, t, i
                message = f"{name}: step raised {type(e).__name__}: {e}"
                break
            if y_new.shape != y.shape:
                status, t_fail, done = Status.FAILED, t, i
                message = f"{name}: step returned shape {y_new.shape}, expected {y.shape}"
                break
            if not (np.abs(y_new) <= bound).all():
                status, t_fail, done = Status.UNSTABLE, grid_time(t0, t1, step, i + 1, n), i
                message = f"{name}: state left {MAX_GROWTH:g} x its scale at t = {t_fail:g} s"
                break
            y = y_new
            while ptr < m and idx[ptr] == i + 1:
                y_out[:, ptr] = y
                ptr += 1
    wall = time.perf_counter() - start
    return SolverRun(name, h, t_eval, y_out, calls[0], done, wall, status=status, message=message,
                     t_fail=t_fail, extra={"h_used": step, "dense": "grid", "path": "python"})
