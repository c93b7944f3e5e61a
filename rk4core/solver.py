"""Fixed-step integration with a ``scipy.integrate.solve_ivp``-like interface.

``solve(fun, t_span, y0, h=..., method="rk4")`` integrates ``dy/dt = fun(t, y)``
with a fixed step. The returned :class:`FixedStepResult` mirrors scipy's
``OdeResult``: ``t`` has shape (m,), ``y`` has shape (n, m). A numerical failure
(a non-finite state, or one grown past ``max_growth`` times its scale) is a
status and a message, never an exception; a bad argument, or a ``fun`` that
returns something other than an array of the state's shape, is a
``ValueError`` naming it.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .methods import Tableau, end_slope, get_method, rk_step, start_slope
from .validate import (check_max_growth, check_output_size, check_step_args, check_t_eval, check_t_span,
                       check_y0, check_y_scale)

__all__ = ["solve", "FixedStepResult", "step_count", "grid_time", "grid_times", "growth_bound",
           "unstable_message", "check_fun_value", "nfev_count"]

_SLACK = 1e-12  # relative slack when rounding (t1 - t0) / h up to a whole count
_DBL_MAX = float(np.finfo(np.float64).max)  # bound of the instability test when growth is not tested


@dataclass
class FixedStepResult:
    """Outcome of :func:`solve` (and of :func:`rk4core.fast.solve_model`).

    Attributes
    ----------
    t : ndarray, shape (m,)
        Output times. Grid time ``i`` is ``t0 + i h`` and the last one is
        ``t1`` exactly.
    y : ndarray, shape (n, m)
        States at ``t`` (float64, or complex128 for a complex ``y0``); on
        failure, only the times reached before the run stopped.
    nfev : int
        Right-hand-side evaluations, :func:`nfev_count`: ``nfev_first_step +
        (N - 1) nfev_per_step`` of the method (:class:`~rk4core.methods.Tableau`)
        for ``N`` steps attempted (the step that failed included), plus the
        dense-output slopes no stage provided (one per step holding off-grid
        ``t_eval`` points for a method that is not FSAL).
    h : float
        Step actually used, ``(t1 - t0) / n_steps``.
    n_steps : int
        Steps completed (fewer than requested when the run stopped).
    success : bool
        ``status == 0``.
    status : int
        0: reached ``t1``. -1: stopped as unstable -- the state became
        non-finite, or grew past ``max_growth`` times its scale (see
        ``reason`` and :func:`solve`, "Instability").
    message : str
        One line. On failure it names the cause ("state became non-finite at
        t = ..." or "state grew past max_growth x its ... scale (|y[i]| = ...
        > ...) at t = ..."), the step, the step count and ``h``.
    t_fail : float or None
        Grid time at the end of the step that failed (the time of the first
        rejected state); None on success.
    dense : str
        How ``t_eval`` points were produced: ``"grid"`` (every one is a grid
        point) or ``"hermite"`` (cubic Hermite interpolation between steps).
    method : str
    reason : str
        ``"ok"``, ``"non-finite"`` (a component became inf or NaN) or
        ``"growth"`` (a finite component exceeded its bound).
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
    reason: str = "ok"


def nfev_count(tab: Tableau, n_attempted: int) -> int:
    """Right-hand-side evaluations of ``n_attempted`` steps of ``tab``
    (dense output apart): ``tab.nfev_first_step + (n_attempted - 1) *
    tab.nfev_per_step``, 0 for no step.

    The first step evaluates every stage the method uses
    (``tab.stage_evaluated``); each later step of a first-same-as-last
    method reuses the previous step's last evaluation for its first stage
    (``tab.fsal_stages``). RK4 ``4 N``, Euler ``N``, symplectic Euler ``N``
    (its second stage's acceleration is unused), Stormer-Verlet ``N + 1``."""
    if n_attempted <= 0:
        return 0
    return tab.nfev_first_step + (n_attempted - 1) * tab.nfev_per_step


def step_count(t_span, h: float) -> int:
    """Steps of size at most ``h`` that cover ``t_span``: ``ceil((t1 - t0) / h)``
    with a relative slack of 1e-12, so 10 / 0.1 is 100 steps, not 101.

    Raises ``ValueError`` naming ``h`` when the count is not finite (a
    subnormal ``h``); :func:`solve` also caps it at ``MAX_STEPS``."""
    t0, t1 = t_span
    ratio = (t1 - t0) / h
    if not math.isfinite(ratio):
        raise ValueError(f"`h` = {h!r} implies {ratio} steps over t_span = ({t0!r}, {t1!r})")
    n = math.ceil(ratio * (1.0 - _SLACK))
    return max(n, 1)


def grid_time(t0: float, t1: float, step: float, i: int, n: int) -> float:
    """Time of grid point ``i`` of ``n`` steps: ``t0 + i step``, never past
    ``t1``, and exactly ``t1`` for ``i = n``."""
    return t1 if i >= n else min(t0 + i * step, t1)


def grid_times(t0: float, t1: float, step: float, i, n: int) -> np.ndarray:
    """:func:`grid_time` of every index in the integer array ``i``."""
    t = np.minimum(t0 + step * np.asarray(i, dtype=np.int64), t1)
    t[np.asarray(i) >= n] = t1
    return t


def growth_bound(y0: np.ndarray, max_growth: float | None, y_scale: np.ndarray | None):
    """Per-component bounds of the instability test and whether the scale is
    still to be set from the first non-zero state.

    ``bound_i = min(max_growth * scale_i, DBL_MAX)``; ``scale_i`` is
    ``y_scale[i]`` or else ``max_j |y0_j|``. Capped at the largest finite
    float64, so ``NOT(|y_i| <= bound_i)`` also holds for inf and NaN. With
    ``max_growth`` None every bound is ``DBL_MAX`` (non-finite test only).

    Parameters
    ----------
    y0 : ndarray, shape (n,)
        Initial state (units of each component).
    max_growth : float or None
        Growth factor (dimensionless, >= 1), or None for no growth test.
    y_scale : ndarray, shape (n,), or None
        Per-component scales (units of each component), or None.

    Returns
    -------
    bound : ndarray, shape (n,), float64
        Largest accepted ``|y_i|`` (units of component i).
    pending : float
        ``max_growth`` when ``y0`` is all zero and no ``y_scale`` is given --
        the integrator then sets every bound to ``min(max_growth * max_j
        |y_j|, DBL_MAX)`` at the first accepted non-zero state -- else 0.
    """
    n = y0.shape[0]
    bound = np.full(n, _DBL_MAX)
    if max_growth is None:
        return bound, 0.0
    if y_scale is not None:
        return np.minimum(max_growth * np.asarray(y_scale, dtype=np.float64), _DBL_MAX), 0.0
    scale = float(np.max(np.abs(y0)))
    if scale > 0.0:
        bound[:] = min(max_growth * scale, _DBL_MAX)
        return bound, 0.0
    return bound, float(max_growth)


def unstable_message(y_new, bound, t_fail, i, n, step, scale_from):
    """``(reason, message)`` for a state rejected at step ``i + 1`` of ``n``.

    Parameters
    ----------
    y_new : ndarray, shape (n_components,)
        The rejected state.
    bound : ndarray, shape (n_components,)
        The bounds it was tested against (:func:`growth_bound`).
    t_fail : float
        Grid time of the rejected state (s, or the units of ``t``).
    i, n : int
        Zero-based index of the step and the number of steps.
    step : float
        The step ``h``.
    scale_from : {"initial", "given"}
        Where the scale came from (``y0``/first non-zero state, or ``y_scale``).

    Returns
    -------
    reason : {"non-finite", "growth"}
        ``"non-finite"`` if any component is inf or NaN, else ``"growth"``.
    message : str
        One line naming the cause (for growth: the first component past its
        bound, its value and the bound), ``t_fail``, the step and ``h``.
    """
    where = f"at t = {t_fail:.6g} (step {i + 1} of {n}, h = {step:.6g}); integration stopped"
    if not np.all(np.isfinite(y_new)):
        return "non-finite", f"state became non-finite {where}"
    a = np.abs(y_new)
    j = int(np.argmax(~(a <= bound)))
    return "growth", (f"state grew past max_growth x its {scale_from} scale "
                      f"(|y[{j}]| = {a[j]:.6g} > {bound[j]:.6g}) {where}")


def check_fun_value(value, t, shape, dtype):
    """``value`` returned by ``fun`` at time ``t`` as an array of ``shape`` that
    can be stored in ``dtype``; else ``ValueError`` naming ``fun``, what it
    returned and what was expected."""
    expected = f"expected an array of shape {shape} and dtype {np.dtype(dtype)}"
    if value is None:
        raise ValueError(f"`fun` returned None at t = {float(t)!r}; {expected}")
    try:
        arr = np.asarray(value)
    except (TypeError, ValueError):
        raise ValueError(f"`fun` returned {type(value).__name__} {value!r:.60} at t = {float(t)!r}; "
                         f"{expected}") from None
    ok_kinds = "iufc" if np.dtype(dtype).kind == "c" else "iuf"
    if arr.dtype.kind == "O":
        try:
            arr = arr.astype(dtype)
        except (TypeError, ValueError, OverflowError):
            pass
    if arr.shape != shape or arr.dtype.kind not in ok_kinds:
        what = "complex values" if arr.dtype.kind == "c" else f"dtype {arr.dtype}"
        raise ValueError(f"`fun` returned shape {arr.shape} with {what} at t = {float(t)!r}; {expected}")
    return arr


def _checked(fun, n: int, dtype):
    """``fun`` with every return value checked (shape, dtype) by
    :func:`check_fun_value`; an ndarray of the right shape and kind passes
    at the cost of three attribute tests."""
    shape = (n,)
    ok_kinds = "iufc" if np.dtype(dtype).kind == "c" else "iuf"

    def checked(t, y):
        out = fun(t, y)
        if type(out) is np.ndarray and out.shape == shape and out.dtype.kind in ok_kinds:
            return out
        return check_fun_value(out, t, shape, dtype)

    return checked


def solve(fun, t_span, y0, *, h=None, n_steps=None, t_eval=None, method="rk4",
          max_growth=1e8, y_scale=None) -> FixedStepResult:
    """Integrate ``dy/dt = fun(t, y)`` over ``t_span`` with a fixed step.

    Parameters
    ----------
    fun : callable
        ``fun(t, y) -> ndarray`` of shape (n,), as in ``scipy.integrate.solve_ivp``.
        Every return value is checked: ``None``, a scalar, a wrong shape,
        strings, or complex values for a real ``y0`` raise ``ValueError``
        naming ``fun``, what it returned and what was expected. ``fun`` is
        never called outside ``[t0, t1]``: stage times are
        ``min(t_i + c_j h, t1)``.
    t_span : (float, float)
        ``(t0, t1)`` with ``t1 > t0`` and ``t1 - t0`` finite.
    y0 : array_like, shape (n,)
        Real or complex numbers (a complex ``y0`` integrates a complex state,
        imaginary part kept, as in ``solve_ivp``); strings and booleans are
        refused.
    h : float, optional
        Largest step; the count is ``ceil((t1 - t0) / h)`` and the step used,
        ``(t1 - t0) / n_steps``, is reported as ``result.h``.
    n_steps : int, optional
        Number of steps. Exactly one of ``h`` and ``n_steps`` is given; the
        count is at most ``rk4core.validate.MAX_STEPS`` (``10**10``), and the
        output array (``n_steps + 1`` rows, or ``len(t_eval)``, x n
        components x 8 bytes, 16 if complex) at most
        ``rk4core.validate.MAX_OUTPUT_BYTES`` (``2**33`` bytes, 8 GiB), else
        ``ValueError`` naming ``h``, ``n_steps`` or ``t_eval``.
    t_eval : array_like, optional
        Output times inside ``t_span``, increasing. Grid points are returned
        exactly; other points by cubic Hermite interpolation of the step
        endpoints (third order, uses the method's own slopes; ``result.dense``
        says which). Default: every step.
    method : str or Tableau
        A name of ``rk4core.METHODS`` (``"rk4"``, ``"euler"``, ``"rk38"``,
        ``"heun3"``, ``"ralston"``, ``"symplectic-euler"``,
        ``"stormer-verlet"``) or a :class:`~rk4core.methods.Tableau`
        (:func:`~rk4core.methods.make_tableau`). A partitioned method
        (``"symplectic-euler"``, ``"stormer-verlet"``) needs ``y = [q, v]``
        (equal halves) of a separable second-order system ``dq/dt = v``,
        ``dv/dt = a(q, t)``: it uses only the velocity half of ``fun``'s
        value, at the stages whose acceleration it needs, and takes a stage's
        position slope to be its velocity.
    max_growth : float or None, keyword-only
        Growth factor (>= 1, dimensionless) past which the run is stopped as
        unstable; default 1e8. None keeps only the non-finite test.
    y_scale : array_like, shape (n,), optional, keyword-only
        Positive finite scale of each component (units of that component),
        replacing the default scale ``max_i |y0_i|``.

    Returns
    -------
    FixedStepResult

    Notes
    -----
    Cost. ``result.nfev`` is the number of calls of ``fun``:
    ``nfev_count(tab, N) = tab.nfev_first_step + (N - 1) tab.nfev_per_step``
    for ``N`` steps attempted (``N = n_steps``, plus one when a step failed),
    plus, with off-grid ``t_eval`` points, the dense-output slopes no stage
    gave: the end slope ``f(t_{n+1}, y_{n+1})`` once per step holding such
    points unless the method is first-same-as-last (FSAL: its last stage is
    that slope), and the start slope only for a method without
    ``tab.start_stage``. A FSAL method reuses its last stage's evaluation as
    the next step's first (so RK4: ``4 N``, Stormer-Verlet: ``N + 1``); the
    reused value was evaluated at ``t_n + h``, which for a ``t``-dependent
    ``fun`` may differ from the grid time ``t_{n+1}`` by an ulp.


    Instability. The run stops, with ``success=False``, ``status=-1``,
    ``t_fail`` and a one-line message, at the first step whose new state has
    a component with ``NOT(|y_i| <= bound_i)`` -- one comparison that also
    catches inf and NaN. ``bound_i = min(max_growth * scale_i, DBL_MAX)``
    (``DBL_MAX`` when ``max_growth`` is None); ``scale_i = y_scale[i]`` if
    given, else the infinity norm of ``y0`` (if ``y0`` is all zero, the
    infinity norm of the first non-zero state reached). ``result.reason`` is
    ``"non-finite"`` when a component is inf or NaN, else ``"growth"``. The
    failure is a status, never an exception, and the output holds only the
    states accepted before it.
    """
    tab: Tableau = get_method(method)
    t0, t1 = check_t_span(t_span)
    y = check_y0(y0, allow_complex=True)
    n_comp = y.shape[0]
    if tab.partitioned and n_comp % 2:
        raise ValueError(f"`y0` must have even length for {tab.name!r} (y = [q, v]), got {n_comp}")
    max_growth = check_max_growth(max_growth)
    y_scale = check_y_scale(y_scale, n_comp)
    n = check_step_args(t0, t1, h, n_steps, step_count)
    step = (t1 - t0) / n
    t_eval = check_t_eval(t_eval, t0, t1)
    dtype = y.dtype
    grid_out = t_eval is None
    if grid_out:
        check_output_size("h" if h is not None else "n_steps", h if h is not None else n_steps,
                          n + 1, n_comp, dtype.itemsize)
    else:
        check_output_size("t_eval", f"<{t_eval.shape[0]} times>", t_eval.shape[0], n_comp, dtype.itemsize)
    fun = _checked(fun, n_comp, dtype)
    bound, pending = growth_bound(y, max_growth, y_scale)
    scale_from = "given" if y_scale is not None else "initial"

    k = np.empty((tab.n_stages, n_comp), dtype=dtype)
    if grid_out:
        ys = np.empty((n + 1, n_comp), dtype=dtype)
        ys[0] = y
    else:
        # Index of the step each output time falls in, and its position in it.
        s = (t_eval - t0) / step
        idx = np.clip(np.floor(s + 1e-9).astype(np.int64), 0, n)
        theta = s - idx
        on_grid = np.abs(theta) <= 1e-9 * np.maximum(1.0, np.abs(s))
        theta[on_grid] = 0.0
        dense = "grid" if on_grid.all() else "hermite"
        ys = np.empty((t_eval.shape[0], n_comp), dtype=dtype)
        out_ptr, _ = _emit(ys, 0, idx, theta, 0, y, None, step, fun, t0, t1, n, None, tab)
    nfev = 0
    reuse = False  # from the second step on, a FSAL method reuses its last stage
    status, reason, t_fail = 0, "ok", None
    message = "The solver successfully reached the end of the integration interval."
    # A blow-up is reported through status/message, so the floating-point
    # warnings on the way to it (overflow, inf - inf, division by a zero length)
    # are not raised, even under -W error.
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        for i in range(n):
            t = grid_time(t0, t1, step, i, n)
            y_new = rk_step(fun, t, y, step, tab, k, t_max=t1, reuse=reuse)
            nfev += tab.nfev_per_step if reuse else tab.nfev_first_step
            reuse = tab.fsal
            a = np.abs(y_new)
            if not (a <= bound).all():  # NOT(|y_i| <= bound_i): also inf and NaN
                status, t_fail = -1, grid_time(t0, t1, step, i + 1, n)
                reason, message = unstable_message(y_new, bound, t_fail, i, n, step, scale_from)
                n_done = i
                break
            if pending:
                norm = float(np.max(a))
                if norm > 0.0:  # the first non-zero state sets the scale
                    bound[:] = min(pending * norm, _DBL_MAX)
                    pending = 0.0
            if grid_out:
                ys[i + 1] = y_new
            else:
                out_ptr, extra = _emit(ys, out_ptr, idx, theta, i + 1, y_new, y, step, fun, t0, t1, n, k, tab)
                nfev += extra
            y = y_new
        else:
            n_done = n
    if grid_out:
        t_out = grid_times(t0, t1, step, np.arange(n_done + 1), n)
        y_out = ys[: n_done + 1].T.copy()
        dense = "grid"
    else:
        t_out = t_eval[:out_ptr]
        y_out = ys[:out_ptr].T.copy()
    return FixedStepResult(
        t=t_out, y=y_out, nfev=nfev, h=step, n_steps=n_done, success=status == 0,
        status=status, message=message, t_fail=t_fail, dense=dense, method=tab.name, reason=reason,
    )


def _emit(ys, ptr, idx, theta, i_step, y_new, y_old, step, fun, t0, t1, n, k, tab):
    """Write every output point that falls at grid point ``i_step`` or inside
    step ``i_step - 1`` (cubic Hermite on [y_old, y_new]) into ``ys``.

    The slopes at the step's ends come from its stages when the method has
    them (:func:`~rk4core.methods.start_slope`: the first stage of every
    built-in method; :func:`~rk4core.methods.end_slope`: the last stage of a
    FSAL method), else from one call of ``fun`` each, made at most once per
    step and only for off-grid points.

    Returns the next output index and the number of extra ``fun`` calls.
    """
    m = idx.shape[0]
    f0 = f1 = None
    extra = 0
    while ptr < m:
        j = idx[ptr]
        if j == i_step and theta[ptr] == 0.0:
            ys[ptr] = y_new
        elif j == i_step - 1 and theta[ptr] > 0.0:
            th = theta[ptr]
            if f1 is None:
                f0 = start_slope(tab, y_old, k)
                if f0 is None:
                    f0 = fun(grid_time(t0, t1, step, i_step - 1, n), y_old)
                    extra += 1
                f1 = end_slope(tab, y_new, k)
                if f1 is None:
                    f1 = fun(grid_time(t0, t1, step, i_step, n), y_new)
                    extra += 1
            h00 = (1 + 2 * th) * (1 - th) ** 2
            h10 = th * (1 - th) ** 2
            h01 = th * th * (3 - 2 * th)
            h11 = th * th * (th - 1)
            ys[ptr] = h00 * y_old + h10 * step * f0 + h01 * y_new + h11 * step * f1
        else:
            break
        ptr += 1
    return ptr, extra
