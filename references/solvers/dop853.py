"""scipy's DOP853 (explicit Runge-Kutta 8(5,3), Hairer-Norsett-Wanner) on ``model.rhs``.

The stepping loop is the one ``scipy.integrate.solve_ivp(method="DOP853",
t_eval=...)`` runs, written out so that accepted steps can be counted: one
``DOP853.step()`` per accepted step, output times inside a step from the
method's 7th-order dense output, and the exact step end when it is an output
time. ``nfev`` is scipy's count (rejected steps included).

scipy raises ``rtol`` below ``100 * eps`` (2.2e-14) to that value with a
warning; here the clip is recorded in ``message`` and ``extra["rtol_used"]``.

References
----------
E. Hairer, S. P. Norsett, G. Wanner, *Solving Ordinary Differential Equations I*,
2nd ed., Springer 1993, sec. II.10.
"""
from __future__ import annotations

import time
import warnings

import numpy as np
from scipy.integrate import DOP853

from .base import SolverRun, Status

__all__ = ["run_dop853", "RTOL_MIN"]

#: scipy's floor on rtol (``scipy.integrate._ivp.rk``: ``100 * EPS``).
RTOL_MIN = 100 * np.finfo(float).eps


def run_dop853(model, y0: np.ndarray, t_eval: np.ndarray, rtol: float, atol: np.ndarray) -> SolverRun:
    """Integrate ``model`` with DOP853 at ``rtol``/``atol``; never raises."""
    m = t_eval.shape[0]
    y = np.full((y0.shape[0], m), np.nan)
    y[:, 0] = y0
    rtol_used = max(rtol, RTOL_MIN)
    extra = {"rtol_used": rtol_used}
    note = f" (rtol {rtol:.3g} clipped to scipy's floor {RTOL_MIN:.3g})" if rtol < RTOL_MIN else ""
    n_steps, k = 0, 1
    status, message, t_fail = Status.OK, "", None
    solver = None
    start = time.perf_counter()
    try:
        with warnings.catch_warnings(), np.errstate(over="ignore", invalid="ignore", divide="ignore"):
            warnings.simplefilter("ignore")
            solver = DOP853(model.rhs, t_eval[0], y0, t_eval[-1], rtol=rtol, atol=atol)
            while solver.status == "running":
                msg = solver.step()
                if solver.status == "failed":
                    status, message, t_fail = Status.FAILED, f"dop853: {msg}", float(solver.t)
                    break
                n_steps += 1
                if not np.all(np.isfinite(solver.y)):
                    status, t_fail = Status.UNSTABLE, float(solver.t)
                    message = f"dop853: state became non-finite at t = {t_fail:.6g}"
                    break
                j = int(np.searchsorted(t_eval, solver.t, side="right"))
                if j > k:
                    sol = solver.dense_output()
                    y[:, k:j] = sol(t_eval[k:j])
                    if t_eval[j - 1] == solver.t:
                        y[:, j - 1] = solver.y
                    k = j
    except Exception as exc:  # noqa: BLE001 - a failure inside is a status, not an exception
        status, message = Status.FAILED, f"dop853: {type(exc).__name__}: {exc}"
        t_fail = float(solver.t) if solver is not None else float(t_eval[0])
    wall = time.perf_counter() - start
    if status is Status.OK:
        message = "dop853: reached the end of the interval" + note
    else:
        message += note
        y[:, k:] = np.nan
    nfev = int(solver.nfev) if solver is not None else 0
    return SolverRun("dop853", rtol, t_eval, y, nfev, n_steps, wall, status=status, message=message,
                     atol=float(atol[0]), t_fail=t_fail, extra={**extra, "atol_state": atol})
