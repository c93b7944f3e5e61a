"""The fixed-step methods of the system under test: ``rk4``, ``euler`` and
``symplectic-euler``. Built-in models run through the compiled fast path
(``rk4core.fast.solve_model``: the same numbers as ``rk4core.solve`` on
``model.rhs``, tested to 1e-14); any other model through ``rk4core.solve`` on
``model.rhs``. Compile/cache-load time of the fast path is ``compile_s``, kept
out of ``wall_s``; ``extra["path"]`` says which path ran.

``setting`` is the largest step ``h`` (s); the step used is
``(t_eval[-1] - t_eval[0]) / ceil(...)`` (``extra["h_used"]``). Output times on
the step grid are returned exactly, others by cubic Hermite interpolation
(``extra["dense"]`` says which). ``nfev`` is stages x steps (4, 1 and 2 per
step), plus one end-slope evaluation per step that holds off-grid outputs. A non-finite state is status UNSTABLE with ``t_fail``; ``y`` is NaN
from the first output time not reached.
"""
from __future__ import annotations

import time

import numpy as np

import rk4core
import rk4core.fast as fast

from .base import SolverRun, Status

__all__ = ["run_fixed"]


def run_fixed(name: str, model, y0: np.ndarray, t_eval: np.ndarray, h: float) -> SolverRun:
    """Integrate ``model`` with fixed-step method ``name``; never raises."""
    m = t_eval.shape[0]
    y = np.full((y0.shape[0], m), np.nan)
    use_fast = fast.supports(model)
    compile_s = fast.warm_up(model, name) if use_fast else 0.0
    start = time.perf_counter()
    try:
        if use_fast:
            res = fast.solve_model(model, (t_eval[0], t_eval[-1]), y0, h=h, t_eval=t_eval, method=name)
        else:
            res = rk4core.solve(model.rhs, (t_eval[0], t_eval[-1]), y0, h=h, t_eval=t_eval, method=name)
    except Exception as exc:  # noqa: BLE001 - a failure inside is a status, not an exception
        return SolverRun(name, h, t_eval, y, 0, 0, time.perf_counter() - start, compile_s, status=Status.FAILED,
                         message=f"{name}: {type(exc).__name__}: {exc}", t_fail=float(t_eval[0]))
    wall = time.perf_counter() - start
    reached = res.y.shape[1]
    y[:, :reached] = res.y
    status = Status.OK if res.success else Status.UNSTABLE
    return SolverRun(name, h, t_eval, y, int(res.nfev), int(res.n_steps), wall, compile_s, status=status,
                     message=res.message, t_fail=res.t_fail,
                     extra={"h_used": res.h, "dense": res.dense, "path": "numba" if use_fast else "python"})
