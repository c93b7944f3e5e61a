"""Fixed-step integration with a ``scipy.integrate.solve_ivp``-like interface.

``solve(fun, t_span, y0, h=..., method="rk4")`` integrates ``dy/dt = fun(t, y)``
with a fixed step. The returned :class:`FixedStepResult` mirrors scipy's
``OdeResult``: ``t`` has shape (m,), ``y`` has shape (n, m). A numerical failure
(non-finite state) is a status and a message, never an exception.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .methods import Tableau, get_method, rk_step
from .validate import check_t_span, check_y0, check_step_args, check_t_eval

__all__ = ["solve", "FixedStepResult", "step_count"]

_SLACK = 1e-12  # relative slack when rounding (t1 - t0) / h up to a whole count


@dataclass
class FixedStepResult:
    """Outcome of :func:`solve`.

    Attributes
    ----------
    t : ndarray, shape (m,)
        Output times.
    y : ndarray, shape (n, m)
        States at ``t``; on failure, only the times reached before the blow-up.
    nfev : int
        Right-hand-side evaluations: ``n_stages`` per step, plus one per step
        that holds off-grid ``t_eval`` points (the Hermite end slope).
    h : float
        Step actually used, ``(t1 - t0) / n_steps``.
    n_steps : int
        Steps taken (fewer than requested when the run blew up).
    success : bool
    status : int
        0 finished; -1 the state became non-finite.
    message : str
    t_fail : float or None
        Time of the first non-finite state.
    dense : str
        How ``t_eval`` points were produced: ``"grid"`` (every one is a grid
        point) or ``"hermite"`` (cubic Hermite interpolation between steps).
    method : str
    """

    t: np.ndarray
    y: np.ndarray
    nfev: int
    h: float
    n_steps: int
    success: bool
    status: int
    message: str
    t_fail: float | None = None
    dense: str = "grid"
    method: str = "rk4"


def step_count(t_span, h: float) -> int:
    """Steps of size at most ``h`` that cover ``t_span``: ``ceil((t1 - t0) / h)``
    with a relative slack of 1e-12, so 10 / 0.1 is 100 steps, not 101."""
    t0, t1 = t_span
    ratio = (t1 - t0) / h
    n = math.ceil(ratio * (1.0 - _SLACK))
    return max(n, 1)


def solve(fun, t_span, y0, *, h=None, n_steps=None, t_eval=None, method="rk4") -> FixedStepResult:
    """Integrate ``dy/dt = fun(t, y)`` over ``t_span`` with a fixed step.

    Parameters
    ----------
    fun : callable
        ``fun(t, y) -> ndarray`` of shape (n,), as in ``scipy.integrate.solve_ivp``.
    t_span : (float, float)
        ``(t0, t1)`` with ``t1 > t0``.
    y0 : array_like, shape (n,)
    h : float, optional
        Largest step; the count is ``ceil((t1 - t0) / h)`` and the step used,
        ``(t1 - t0) / n_steps``, is reported as ``result.h``.
    n_steps : int, optional
        Number of steps. Exactly one of ``h`` and ``n_steps`` is given.
    t_eval : array_like, optional
        Output times inside ``t_span``, increasing. Grid points are returned
        exactly; other points by cubic Hermite interpolation of the step
        endpoints (third order, uses the method's own slopes; ``result.dense``
        says which). Default: every step.
    method : {"rk4", "euler", "symplectic-euler"} or Tableau
        ``"symplectic-euler"`` needs ``y = [q, v]`` with ``dq/dt = v``.

    Returns
    -------
    FixedStepResult
    """
    tab: Tableau = get_method(method)
    t0, t1 = check_t_span(t_span)
    y = check_y0(y0)
    if tab.partitioned and y.shape[0] % 2:
        raise ValueError(f"`y0` must have even length for {tab.name!r} (y = [q, v]), got {y.shape[0]}")
    n = check_step_args(t0, t1, h, n_steps, step_count)
    step = (t1 - t0) / n
    t_eval = check_t_eval(t_eval, t0, t1)

    k = np.empty((tab.n_stages, y.shape[0]))
    nfev_per_step = tab.n_stages
    grid_out = t_eval is None
    if grid_out:
        ys = np.empty((n + 1, y.shape[0]))
        ys[0] = y
    else:
        # Index of the step each output time falls in, and its position in it.
        s = (t_eval - t0) / step
        idx = np.clip(np.floor(s + 1e-9).astype(np.int64), 0, n)
        theta = s - idx
        on_grid = np.abs(theta) <= 1e-9 * np.maximum(1.0, np.abs(s))
        theta[on_grid] = 0.0
        dense = "grid" if on_grid.all() else "hermite"
        ys = np.empty((t_eval.shape[0], y.shape[0]))
        out_ptr, _ = _emit(ys, 0, idx, theta, 0, y, None, step, fun, t0, None)
    nfev = 0
    status, message, t_fail = 0, "The solver successfully reached the end of the integration interval.", None
    # A blow-up is reported through status/message, so the floating-point
    # warnings on the way to it (overflow, inf - inf, division by a zero length)
    # are not raised, even under -W error.
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        for i in range(n):
            t = t0 + i * step
            y_new = rk_step(fun, t, y, step, tab, k)
            nfev += nfev_per_step
            if not np.all(np.isfinite(y_new)):
                status, t_fail = -1, t + step
                message = (
                    f"state became non-finite at t = {t_fail:.6g} (step {i + 1} of {n}, h = {step:.6g}); "
                    f"integration stopped"
                )
                n_done = i
                break
            if grid_out:
                ys[i + 1] = y_new
            else:
                out_ptr, extra = _emit(ys, out_ptr, idx, theta, i + 1, y_new, y, step, fun, t0, k)
                nfev += extra
            y = y_new
        else:
            n_done = n
    if grid_out:
        t_out = t0 + step * np.arange(n_done + 1)
        t_out[-1] = t1 if status == 0 else t_out[-1]
        y_out = ys[: n_done + 1].T.copy()
        dense = "grid"
    else:
        t_out = t_eval[:out_ptr]
        y_out = ys[:out_ptr].T.copy()
    return FixedStepResult(
        t=t_out, y=y_out, nfev=nfev, h=step, n_steps=n_done, success=status == 0,
        status=status, message=message, t_fail=t_fail, dense=dense, method=tab.name,
    )


def _emit(ys, ptr, idx, theta, i_step, y_new, y_old, step, fun, t0, k):
    """Write every output point that falls at grid point ``i_step`` or inside
    step ``i_step - 1`` (cubic Hermite on [y_old, y_new]) into ``ys``.

    Returns the next output index and the number of extra ``fun`` calls (the
    end slope, evaluated at most once per step and only for off-grid points).
    """
    m = idx.shape[0]
    f1 = None
    extra = 0
    while ptr < m:
        j = idx[ptr]
        if j == i_step and theta[ptr] == 0.0:
            ys[ptr] = y_new
        elif j == i_step - 1 and theta[ptr] > 0.0:
            # Cubic Hermite on the step with the slopes at both ends. The start
            # slope is the method's first stage (k[0] = f(t_n, y_n)) for every
            # tableau here; the end slope costs one evaluation.
            th = theta[ptr]
            if f1 is None:
                f1 = fun(t0 + i_step * step, y_new)
                extra += 1
            h00 = (1 + 2 * th) * (1 - th) ** 2
            h10 = th * (1 - th) ** 2
            h01 = th * th * (3 - 2 * th)
            h11 = th * th * (th - 1)
            ys[ptr] = h00 * y_old + h10 * step * k[0] + h01 * y_new + h11 * step * f1
        else:
            break
        ptr += 1
    return ptr, extra
