"""The fixed-step methods of the system under test: ``rk4``, ``euler`` and
``symplectic-euler`` (``rk4core.solve`` on ``model.rhs``).

``setting`` is the largest step ``h`` (s); the step used is
``(t_eval[-1] - t_eval[0]) / ceil(...)`` (``extra["h_used"]``). Output times on
the step grid are returned exactly, others by cubic Hermite interpolation
(``extra["dense"]`` says which). ``nfev`` is stages x steps (4, 1 and 2 per
step). A non-finite state is status UNSTABLE with ``t_fail``; ``y`` is NaN
from the first output time not reached.
"""
from __future__ import annotations

import time

import numpy as np

import rk4core

from .base import SolverRun, Status

__all__ = ["run_fixed"]


def run_fixed(name: str, model, y0: np.ndarray, t_eval: np.ndarray, h: float) -> SolverRun:
    """Integrate ``model`` with fixed-step method ``name``; never raises."""
    m = t_eval.shape[0]
    y = np.full((y0.shape[0], m), np.nan)
    start = time.perf_counter()
    try:
        res = rk4core.solve(model.rhs, (t_eval[0], t_eval[-1]), y0, h=h, t_eval=t_eval, method=name)
    except Exception as exc:  # noqa: BLE001 - a failure inside is a status, not an exception
        return SolverRun(name, h, t_eval, y, 0, 0, time.perf_counter() - start, status=Status.FAILED,
                         message=f"{name}: {type(exc).__name__}: {exc}", t_fail=float(t_eval[0]))
    wall = time.perf_counter() - start
    reached = res.y.shape[1]
    y[:, :reached] = res.y
    status = Status.OK if res.success else Status.UNSTABLE
    return SolverRun(name, h, t_eval, y, int(res.nfev), int(res.n_steps), wall, status=status,
                     message=res.message, t_fail=res.t_fail,
                     extra={"h_used": res.h, "dense": res.dense})
