"""Fixed-step integration as a superset of ``scipy.integrate.solve_ivp``.

``solve(fun, t_span, y0, method="rk4", t_eval=None, dense_output=False,
events=None, vectorized=False, args=None, *, h=None, n_steps=None)``
integrates ``dy/dt = fun(t, y)`` from ``t0`` to ``t1`` with a fixed step and
returns a :class:`FixedStepResult`, which behaves as scipy's ``OdeResult``
(attributes and ``res["t"]``) and adds what a fixed step has to report.

Conventions
-----------
* Shapes: ``y0`` is (n,); ``result.t`` is (m,), ``result.y`` is (n, m), as
  ``solve_ivp``. Times are in the units of ``t_span`` (seconds for every
  shipped model), states in those of ``y0``.
* The grid: ``N = ceil(|t1 - t0| / |h|)`` equal steps of ``(t1 - t0) / N``
  (relative slack 1e-12: 10 / 0.1 is 100 steps), or ``N = n_steps``. Grid
  time ``i`` is ``t0 + i (t1 - t0) / N``, the last one ``t1`` exactly.
  ``h`` is a magnitude; a negative ``h`` is accepted when ``t1 < t0``
  (backward) and refused when it contradicts the span.
* ``fun`` is never evaluated outside ``t_span`` (scipy gh-17341): stage
  times are clamped to ``t1``.
* Failure is a status, never an exception: a state that stops being finite,
  or grows past ``max_growth`` times its scale, ends the run with
  ``status = -1`` and a one-line message. A bad argument, or a ``fun`` that
  returns something other than an array of the state's shape, is a
  ``ValueError`` naming it, in one line.
* Options of ``solve_ivp`` that only an adaptive or implicit method uses
  (``rtol``, ``atol``, ``first_step``, ``max_step``, ``min_step``, ``jac``,
  ``jac_sparsity``, ``lband``, ``uband``) are refused, each with the reason;
  other unknown keywords are refused too (``solve_ivp`` warns and ignores
  them).

The dense output (``dense_output=True``: ``result.sol``) and the event
location are the method's cubic Hermite interpolant between steps
(:mod:`rk4h.dense`, :mod:`rk4h.events`); off-grid ``t_eval`` points use
the same polynomial.
"""
from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, fields

import numpy as np

from .methods import METHODS, Tableau, end_slope, get_method, rk_step, start_slope
from .validate import (MAX_STEPS, boolean, check_max_growth, check_output_size, check_step_args, check_step_sign,
                       check_t_eval, check_t_span, check_y0, check_y_scale, positive)

__all__ = ["solve", "FixedStepResult", "EmptyOutput", "MAX_STEPS_INFINITE", "step_count", "grid_time",
           "grid_times", "growth_bound", "unstable_message", "check_fun_value", "nfev_count", "ArgsError",
           "REFUSED_OPTIONS", "refuse_options"]

#: Default ``max_steps`` of :func:`solve`: the step cap of a run towards an infinite ``t_span`` end.
MAX_STEPS_INFINITE = 10**6
_SLACK = 1e-12  # relative slack when rounding (t1 - t0) / h up to a whole count
_DBL_MAX = float(np.finfo(np.float64).max)  # bound of the instability test when growth is not tested

MESSAGES = {0: "The solver successfully reached the end of the integration interval.",
            1: "A termination event occurred."}

_NO_JACOBIAN = "rk4core's methods are explicit and never use a Jacobian"
#: ``solve_ivp`` options refused by :func:`solve`, with the reason given.
REFUSED_OPTIONS = {
    "rtol": "an error tolerance steers an adaptive step size; rk4h.solve estimates no error",
    "atol": "an error tolerance steers an adaptive step size; rk4h.solve estimates no error",
    "first_step": "every step, the first included, has the one size set by h or n_steps",
    "max_step": "every step has the one size set by h or n_steps",
    "min_step": "every step has the one size set by h or n_steps",
    "jac": _NO_JACOBIAN,
    "jac_sparsity": _NO_JACOBIAN,
    "lband": _NO_JACOBIAN,
    "uband": _NO_JACOBIAN,
}
_ADAPTIVE = ("RK23", "RK45", "DOP853", "Radau", "BDF", "LSODA")
# OdeResult's keys first, in solve_ivp's order, then the fixed-step ones.
_SCIPY_KEYS = ("t", "y", "sol", "t_events", "y_events", "nfev", "njev", "nlu", "status", "message", "success")


class EmptyOutput(np.ndarray):
    """An empty ``result.t`` or ``result.y``: an ndarray (shape ``(0,)`` or
    ``(n, 0)``) that is false as a truth value, as ``solve_ivp``'s ``[]``
    there, so ``if not res.t`` works as with scipy."""

    def __bool__(self) -> bool:
        return bool(self.size)


class ArgsError(TypeError, ValueError):
    """``args`` that cannot be unpacked: a ``TypeError`` as in ``solve_ivp``
    and a ``ValueError`` as every other bad argument of :func:`solve`."""


@dataclass
class FixedStepResult(Mapping):
    """Outcome of :func:`solve` (and of :func:`rk4h.fast.solve_model`).

    Behaves as scipy's ``OdeResult``: every field is an attribute and a key
    (``res.t``, ``res["t"]``, ``res.keys()``, ``dict(res)``); the keys start
    with ``solve_ivp``'s, in its order.

    Attributes
    ----------
    t : ndarray, shape (m,)
        Output times. Grid time ``i`` is ``t0 + i h`` and the last one is
        ``t1`` exactly (or the time of the terminal event that stopped the
        run). Decreasing for a backward run.
    y : ndarray, shape (n, m)
        States at ``t`` (float64, or complex128 for a complex ``y0``); on
        failure, only the times reached before the run stopped.
    sol : HermiteSolution or None
        With ``dense_output=True``, the continuous solution
        (:class:`rk4h.dense.HermiteSolution`, an ``OdeSolution``), else
        None.
    t_events, y_events : list of ndarray, or None
        With ``events``: per event, the times (shape (k,)) and the states
        (shape (k, n); shape (0,) when none) where it occurred, in the order
        found. None without ``events``, as ``solve_ivp``.
    nfev : int
        Calls of ``fun``. Without events or dense output, :func:`nfev_count`:
        ``nfev_first_step + (N - 1) nfev_per_step`` of the method
        (:class:`~rk4h.methods.Tableau`) for ``N`` steps attempted (the
        step that failed included), plus the dense-output slopes no stage
        provided (one per step holding off-grid ``t_eval`` points for a
        method that is not FSAL). With events or dense output, the calls
        counted as made (see :func:`solve`, Notes).
    njev, nlu : int
        0: no Jacobian, no LU decomposition (kept for ``solve_ivp`` code).
    h : float
        Step actually used, ``(t1 - t0) / n_steps`` (negative for a backward
        run; 0.0 when ``t1 == t0`` and no step is taken).
    n_steps : int
        Steps taken: fewer than the grid's when the run failed (the failed
        step not included) or a terminal event stopped it (the step holding
        the event included).
    success : bool
        ``status >= 0``.
    status : int
        0: reached ``t1``. 1: a terminal event stopped the run. -1: stopped as
        unstable -- the state became non-finite, or grew past ``max_growth``
        times its scale (see ``reason`` and :func:`solve`, "Instability").
    message : str
        One line: ``solve_ivp``'s messages for statuses 0 and 1. On failure it
        names the cause ("state became non-finite at t = ..." or "state grew
        past max_growth x its ... scale (|y[i]| = ... > ...) at t = ..."),
        the step, the step count and ``h``.
    t_fail : float or None
        Grid time at the end of the step that failed (the time of the first
        rejected state); None otherwise.
    dense : str
        How ``t_eval`` points were produced: ``"grid"`` (every one is a grid
        point) or ``"hermite"`` (cubic Hermite interpolation between steps).
    method : str
    reason : str
        ``"ok"``, ``"event"`` (a terminal event), ``"non-finite"`` (a component
        became inf or NaN), ``"growth"`` (a finite component exceeded its
        bound) or ``"max_steps"`` (an infinite ``t_span`` end and no
        terminal event within ``max_steps`` steps; ``status = -1``).
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
    sol: object = None
    t_events: list | None = None
    y_events: list | None = None
    njev: int = 0
    nlu: int = 0

    def __post_init__(self):
        # solve_ivp returns `[]` for t and y when no output time was reached
        # (a t_eval past an early terminal event), so `if not res.t` is scipy
        # users' test for it; an empty ndarray refuses to be a truth value.
        for name in ("t", "y"):
            value = getattr(self, name)
            if isinstance(value, np.ndarray) and value.size == 0 and type(value) is np.ndarray:
                setattr(self, name, value.view(EmptyOutput))

    # -- the OdeResult (dict-like) face -----------------------------------------------------------
    def _keys(self):
        names = [f.name for f in fields(self)]
        return [k for k in _SCIPY_KEYS if k in names] + [k for k in names if k not in _SCIPY_KEYS]

    def __getitem__(self, key):
        if isinstance(key, str) and key in self._keys():
            return getattr(self, key)
        raise KeyError(key)

    def __iter__(self):
        return iter(self._keys())

    def __len__(self) -> int:
        return len(self._keys())

    __hash__ = None


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
    ``t1`` (in the direction of ``step``), and exactly ``t1`` for ``i = n``."""
    if i >= n:
        return t1
    t = t0 + i * step
    return (t if t <= t1 else t1) if step > 0 else (t if t >= t1 else t1)


def grid_times(t0: float, t1: float, step: float, i, n: int) -> np.ndarray:
    """:func:`grid_time` of every index in the integer array ``i``."""
    t = t0 + step * np.asarray(i, dtype=np.int64)
    t = np.minimum(t, t1) if step > 0 else np.maximum(t, t1)
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


def past_bound(y_new, bound, pending: float):
    """``(past, pending)``: whether ``y_new`` is past its growth bound (inf
    and NaN included), and the pending growth factor after this state.

    While ``pending`` is non-zero (``y0`` was all zero and no ``y_scale``
    was given) the first non-zero state sets every bound in place to
    ``min(pending * max_i |y_new_i|, DBL_MAX)``; see :func:`growth_bound`.
    """
    a = np.abs(y_new)
    if not (a <= bound).all():  # NOT(|y_i| <= bound_i): also inf and NaN
        return True, pending
    if pending:
        norm = float(np.max(a))
        if norm > 0.0:
            bound[:] = min(pending * norm, _DBL_MAX)
            return False, 0.0
    return False, pending


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
        # astype would turn None into NaN and "1.5" into 1.5: neither is a number fun computed
        bad = next((x for x in arr.flat if x is None or isinstance(x, (str, bytes))), False)
        if bad is not False:
            raise ValueError(f"`fun` returned an array holding {bad!r:.40} at t = {float(t)!r}; {expected}")
        try:
            arr = arr.astype(dtype)
        except (TypeError, ValueError, OverflowError):
            pass
    if arr.shape != shape or arr.dtype.kind not in ok_kinds:
        what = "complex values" if arr.dtype.kind == "c" else f"dtype {arr.dtype}"
        raise ValueError(f"`fun` returned shape {arr.shape} with {what} at t = {float(t)!r}; {expected}")
    return arr


def _checked(fun, n: int, dtype, *, args=(), vectorized=False, t_floor=None):
    """``fun`` with every return value checked (shape, dtype) by
    :func:`check_fun_value`; an ndarray of the right shape and kind passes
    at the cost of three attribute tests.

    ``args`` are passed after ``(t, y)``; with ``vectorized`` ``fun`` is
    called with ``y[:, None]`` (shape (n, 1)) and a value of shape (n, 1) is
    taken as its column, as ``solve_ivp`` does; ``t_floor`` (a backward run's
    ``t1``) clamps the stage times from below."""
    shape = (n,)
    ok_kinds = "iufc" if np.dtype(dtype).kind == "c" else "iuf"

    if not args and not vectorized and t_floor is None:  # the common case, one layer
        def checked(t, y):
            out = fun(t, y)
            if type(out) is np.ndarray and out.shape == shape and out.dtype.kind in ok_kinds:
                return out
            return check_fun_value(out, t, shape, dtype)

        return checked

    def checked_general(t, y):
        if t_floor is not None and t < t_floor:
            t = t_floor
        if vectorized:
            out = fun(t, y[:, None], *args)
            if out is not None and not (type(out) is np.ndarray and out.shape == shape):
                try:
                    arr = np.asarray(out)
                except (TypeError, ValueError):
                    arr = None
                if arr is not None and arr.shape == (n, 1):
                    out = arr[:, 0]
        else:
            out = fun(t, y, *args)
        if type(out) is np.ndarray and out.shape == shape and out.dtype.kind in ok_kinds:
            return out
        return check_fun_value(out, t, shape, dtype)

    return checked_general


class _Once:
    """``fun`` for one step of a run with events or dense output whose first
    stage was already evaluated (an interpolant needed ``f(t_i, y_i)`` before
    step ``i`` ran): returns that value for the call at ``(t_i, y_i)`` and
    counts the calls it passes on."""

    __slots__ = ("fun", "calls", "_t", "_y", "_f")

    def __init__(self, fun, t, y, f):
        self.fun = fun
        self.calls = 0
        self._t, self._y, self._f = t, y, f

    def __call__(self, t, y):
        if self._y is not None:
            hit = t == self._t and (y is self._y or np.array_equal(y, self._y))
            f, self._y, self._f = self._f, None, None
            if hit:
                return f
        self.calls += 1
        return self.fun(t, y)


def refuse_options(options, owner="rk4h.solve", give="h or n_steps",
                   unknown="solve_ivp warns about unknown options and ignores them; rk4h.solve refuses them"):
    """Raise ``ValueError`` for any keyword in ``options``: an adaptive
    solver's option (:data:`REFUSED_OPTIONS`) names why it does not apply to
    ``owner`` and that the step is ``give``; any other is unknown (``unknown``
    says what ``owner`` takes instead)."""
    for name in options:
        if name in REFUSED_OPTIONS:
            raise ValueError(f"`{name}` does not apply to {owner}: {REFUSED_OPTIONS[name]} "
                             f"(fixed step: give {give})")
    if options:
        names = ", ".join(f"`{k}`" for k in options)
        raise ValueError(f"unknown option(s) {names} for {owner} ({unknown})")


def _check_args(args) -> tuple:
    if args is None:
        return ()
    try:
        return tuple(args)  # as solve_ivp: any iterable is unpacked
    except TypeError:
        shown = str(args).replace("\n", " ")[:40]
        raise ArgsError(f"Supplied 'args' cannot be unpacked. Please supply `args` as a tuple "
                        f"(e.g. `args=({shown},)`)") from None


def _get_method(method) -> Tableau:
    if isinstance(method, str) and method in _ADAPTIVE:
        raise ValueError(f"`method` = {method!r} is an adaptive method of scipy's solve_ivp; rk4h.solve takes "
                         f"a fixed step with one of {sorted(METHODS)} or a Tableau")
    if isinstance(method, type):
        raise ValueError(f"`method` must be one of {sorted(METHODS)} or a Tableau, got the class "
                         f"{method.__name__} (solve_ivp's OdeSolver classes are adaptive)")
    return get_method(method)


def _infinite_end(t_span):
    """``t_span``'s end if it is +inf or -inf (with a finite start), else None."""
    try:
        t0, t1 = t_span
        t0, t1 = float(t0), float(t1)
    except (TypeError, ValueError):
        return None
    if math.isinf(t1) and math.isfinite(t0):
        return t1
    return None


def _infinite_grid(t0, t1, h, n_steps, max_steps, ev):
    """``(n, step)`` of a run towards an infinite ``t1``: steps of ``h`` (signed
    by the direction), at most ``max_steps`` of them; a terminal event must be
    able to end it."""
    span = f"t_span = ({t0!r}, {t1!r})"
    if ev is None or not np.isfinite(ev.max_events).any():
        raise ValueError(f"{span} has an infinite end: give a terminal event (`events` with `terminal` set) "
                         f"to end the run")
    if n_steps is not None or h is None:
        raise ValueError(f"{span} has an infinite end: give `h` (the step), not `n_steps`, got h={h!r}, "
                         f"n_steps={n_steps!r}")
    h = positive("h", check_step_sign(h, t0, t1))
    if isinstance(max_steps, bool) or not isinstance(max_steps, (int, np.integer)) or not 1 <= max_steps <= MAX_STEPS:
        raise ValueError(f"`max_steps` must be an integer from 1 to MAX_STEPS = {MAX_STEPS:.0e}, got {max_steps!r}")
    step = h if t1 > t0 else -h
    if not math.isfinite(t0 + int(max_steps) * step):
        raise ValueError(f"`max_steps` = {max_steps!r} steps of h = {h!r} from t0 = {t0!r} overflow float64")
    return int(max_steps), step


def _output_points(t_eval, t0, step, n):
    """Step index and fraction of every ``t_eval`` point (the arithmetic of
    the compiled path's ``_output_points``): ``idx``, ``theta``, ``on_grid``."""
    s = (t_eval - t0) / step
    idx = np.clip(np.floor(s + 1e-9).astype(np.int64), 0, n)
    theta = s - idx
    on_grid = np.abs(theta) <= 1e-9 * np.maximum(1.0, np.abs(s))
    theta[on_grid] = 0.0
    return idx, theta, on_grid


class _StepHook:
    """What a run keeps of each step, beyond the state (:func:`_drive`).

    The driver calls, for step ``i`` from ``(t_i, y_i)``:
    ``first_stage(i)`` before it (a :class:`_Once` when ``f(t_i, y_i)`` was
    already evaluated, else None); ``taken(i, y_i, k)`` once the stages ``k``
    are computed, before the growth test; ``accepted(i, t_i, y_i, y_new, k)``
    once ``y_new`` passed it, returning ``(extra, stop)``: the calls of
    ``fun`` it made itself and whether a terminal event ends the run."""

    def first_stage(self, i):
        return None

    def taken(self, i, y_i, k):
        pass

    def accepted(self, i, t, y_i, y_new, k):
        return 0, False


class _GridOutput(_StepHook):
    """Every grid state into ``ys`` (row ``i + 1`` after step ``i``)."""

    __slots__ = ("ys",)

    def __init__(self, ys):
        self.ys = ys

    def accepted(self, i, t, y_i, y_new, k):
        self.ys[i + 1] = y_new
        return 0, False


class _PointOutput(_StepHook):
    """The ``t_eval`` points of each step into ``ys`` (:func:`_emit`)."""

    def __init__(self, ys, ptr, idx, theta, step, fun, t0, t1, n, tab):
        self.ys, self.ptr, self.idx, self.theta = ys, ptr, idx, theta
        self.step, self.fun, self.t0, self.t1, self.n, self.tab = step, fun, t0, t1, n, tab

    def accepted(self, i, t, y_i, y_new, k):
        self.ptr, extra = _emit(self.ys, self.ptr, self.idx, self.theta, i + 1, y_new, y_i, self.step, self.fun,
                                self.t0, self.t1, self.n, k, self.tab)
        return extra, False


def _drive(fun, tab, t0, t1, n, step, y, bound, pending, scale_from, t_max, hook):
    """The stepping loop of :func:`solve`: ``n`` fixed steps of ``tab`` from
    ``(t0, y)``, each tested against the growth ``bound``; ``hook``
    (:class:`_StepHook`) keeps the output, dense-output slopes and events.

    Returns ``(nfev, n_done, status, reason, message, t_fail)``: the calls of
    ``fun`` (the hook's own included), the steps accepted, and ``status`` 0
    (all done), 1 (a terminal event, the hook's ``stop``) or -1 (the state
    left the bound at ``t_fail``; ``reason`` and ``message`` say how)."""
    k = np.empty((tab.n_stages, y.shape[0]), dtype=y.dtype)
    nfev = 0
    reuse = False  # from the second step on, a FSAL method reuses its last stage
    status, reason, t_fail = 0, "ok", None
    message = MESSAGES[0]
    n_done = n
    # A blow-up is reported through status/message, so the floating-point
    # warnings on the way to it (overflow, inf - inf, division by a zero length)
    # are not raised, even under -W error.
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        for i in range(n):
            t = grid_time(t0, t1, step, i, n)
            once = hook.first_stage(i)
            if once is None:
                y_new = rk_step(fun, t, y, step, tab, k, t_max=t_max, reuse=reuse)
                nfev += tab.nfev_per_step if reuse else tab.nfev_first_step
            else:
                y_new = rk_step(once, t, y, step, tab, k, t_max=t_max, reuse=reuse)
                nfev += once.calls
            reuse = tab.fsal
            hook.taken(i, y, k)
            past, pending = past_bound(y_new, bound, pending)
            if past:
                status, t_fail = -1, grid_time(t0, t1, step, i + 1, n)
                reason, message = unstable_message(y_new, bound, t_fail, i, n, step, scale_from)
                n_done = i
                break
            extra, stop = hook.accepted(i, t, y, y_new, k)
            nfev += extra
            y = y_new
            if stop:
                status, reason, message = 1, "event", MESSAGES[1]
                n_done = i + 1
                break
    return nfev, n_done, status, reason, message, t_fail


def solve(fun, t_span, y0, method="rk4", t_eval=None, dense_output=False, events=None, vectorized=False,
          args=None, *, h=None, n_steps=None, max_growth=1e8, y_scale=None, max_steps=MAX_STEPS_INFINITE,
          **options) -> FixedStepResult:
    """Integrate ``dy/dt = fun(t, y)`` over ``t_span`` with a fixed step.

    A superset of ``scipy.integrate.solve_ivp`` for fixed-step methods: the
    same positional arguments and result, plus ``h`` or ``n_steps`` (one of
    them required) and the instability bound.

    Parameters
    ----------
    fun : callable
        ``fun(t, y, *args) -> ndarray`` of shape (n,), as in ``solve_ivp``.
        Every return value is checked: ``None`` (or an array holding
        ``None``), a scalar, a wrong shape, strings, or complex values for a
        real ``y0`` raise ``ValueError``
        naming ``fun``, what it returned and what was expected. ``fun`` is
        never called outside ``t_span``: stage times are ``t_i + c_j h``
        clamped to ``t1``.
    t_span : (float, float)
        ``(t0, t1)``, finite, ``t1 - t0`` finite. ``t1 < t0`` integrates
        backward; ``t1 == t0`` takes no step (``result.t = [t0]``).
        ``t1`` may be ``inf`` (or ``-inf``) when a terminal event can end
        the run: ``h`` is then required (not ``n_steps``), the grid is
        ``t0 + i h`` and at most ``max_steps`` steps are taken.
    y0 : array_like, shape (n,)
        Real or complex numbers (a complex ``y0`` integrates a complex state,
        imaginary part kept, as in ``solve_ivp``); strings, booleans and an
        empty ``y0`` are refused.
    method : str or Tableau, optional
        A name of ``rk4h.METHODS`` (``"rk4"``, the default, ``"euler"``,
        ``"rk38"``, ``"heun3"``, ``"ralston"``, ``"symplectic-euler"``,
        ``"stormer-verlet"``) or a :class:`~rk4h.methods.Tableau`
        (:func:`~rk4h.methods.make_tableau`). ``solve_ivp``'s adaptive
        names (``"RK45"``, ...) are refused naming ``method``. A partitioned
        method (``"symplectic-euler"``, ``"stormer-verlet"``) needs ``y = [q,
        v]`` (equal halves) of a separable second-order system ``dq/dt = v``,
        ``dv/dt = a(q, t)``: it uses only the velocity half of ``fun``'s
        value, at the stages whose acceleration it needs, and takes a stage's
        position slope to be its velocity.
    t_eval : array_like, optional
        Output times inside ``t_span``, in its direction (non-decreasing, or
        non-increasing for a backward run). Grid points are returned exactly;
        other points by the cubic Hermite interpolant of their step
        (:mod:`rk4h.dense`; ``result.dense`` says which). Default: every
        grid point.
    dense_output : bool, optional
        Also return ``result.sol``, the continuous solution
        (:class:`rk4h.dense.HermiteSolution`, an ``OdeSolution``): one
        cubic Hermite polynomial per step from the step's end states and
        slopes. Order 3 as a continuous extension (local error O(h^4)),
        hence globally fourth order with RK4, like the grid values; see
        :mod:`rk4h.dense`. Default False.
    events : callable or list of callables, optional
        Event functions ``event(t, y, *args) -> float`` with the optional
        attributes ``terminal`` (bool, or a positive int: stop at that
        occurrence) and ``direction`` (> 0, < 0, 0), as ``solve_ivp``
        (:mod:`rk4h.events`). A sign change over a step is located by
        ``brentq`` on the step's dense-output polynomial; ``result.t_events``
        and ``result.y_events`` hold the findings, and a terminal event ends
        the run there with ``status = 1``, its time and state being the last
        of ``result.t``, ``result.y``.
    vectorized : bool, optional
        As ``solve_ivp``: ``fun`` accepts ``y`` of shape (n, k). A fixed-step
        explicit method never needs several states at once (in ``solve_ivp``
        the flag only speeds up finite-difference Jacobians), so ``fun`` is
        then called, as ``solve_ivp``'s explicit methods do, with one column
        ``y[:, None]`` (shape (n, 1)) and its value of shape (n, 1) (or (n,))
        taken as the slope. Default False: ``y`` has shape (n,).
    args : tuple, optional
        Extra arguments passed to ``fun`` and to every event function after
        ``(t, y)``. As ``solve_ivp``, any iterable is unpacked (a list works);
        one that cannot be (``args=5``) raises :class:`ArgsError`, a
        ``TypeError`` and ``ValueError`` whose message starts as scipy's
        ("Supplied 'args' cannot be unpacked.").
    h : float, keyword-only
        Largest step magnitude (> 0; a negative ``h`` is accepted for a
        backward span and refused, naming ``h``, for a forward one). The
        count is ``N = ceil(|t1 - t0| / |h|)`` and the step used,
        ``(t1 - t0) / N``, is ``result.h``.
    n_steps : int, keyword-only
        Number of steps. Exactly one of ``h`` and ``n_steps`` is given; the
        count is at most ``rk4h.validate.MAX_STEPS`` (``10**10``), and the
        output array (``n_steps + 1`` rows, or ``len(t_eval)``, x n
        components x 8 bytes, 16 if complex; with events or dense output the
        ``2 (n_steps + 1)`` rows of states and slopes kept for the
        interpolants) at most ``rk4h.validate.MAX_OUTPUT_BYTES``
        (``2**33`` bytes, 8 GiB), else ``ValueError`` naming ``h``,
        ``n_steps`` or ``t_eval``.
    max_growth : float or None, keyword-only
        Growth factor (>= 1, dimensionless) past which the run is stopped as
        unstable; default 1e8. None keeps only the non-finite test.
    y_scale : array_like, shape (n,), optional, keyword-only
        Positive finite scale of each component (units of that component),
        replacing the default scale ``max_i |y0_i|``.
    max_steps : int, optional, keyword-only
        Step cap of a run towards an infinite ``t1`` (default
        :data:`MAX_STEPS_INFINITE` = 10**6; unused for a finite span). A run
        that reaches it without a terminal event ends with ``status = -1``,
        ``reason = "max_steps"`` and a message naming it.
    **options
        Refused, each with a one-line ``ValueError`` naming it: ``rtol``,
        ``atol``, ``first_step``, ``max_step``, ``min_step`` (a fixed step has
        no error control and one step size: give ``h`` or ``n_steps``),
        ``jac``, ``jac_sparsity``, ``lband``, ``uband`` (explicit methods use
        no Jacobian), and any other keyword (``solve_ivp`` warns about
        unknown options and ignores them; here a misspelt option is an
        error, not a silent default).

    Returns
    -------
    FixedStepResult
        ``t``, ``y``, ``sol``, ``t_events``, ``y_events``, ``nfev``,
        ``njev`` (0), ``nlu`` (0), ``status``, ``message``, ``success`` as
        ``solve_ivp``'s ``OdeResult`` (also as keys: ``res["t"]``), plus
        ``h``, ``n_steps``, ``t_fail``, ``dense``, ``method``, ``reason``.

    Notes
    -----
    Cost. ``result.nfev`` is the number of calls of ``fun``. Without events
    and dense output it is ``nfev_count(tab, N) = tab.nfev_first_step + (N -
    1) tab.nfev_per_step`` for ``N`` steps attempted (``N = n_steps``, plus
    one when a step failed), plus, with off-grid ``t_eval`` points, the
    dense-output slopes no stage gave: the end slope ``f(t_{n+1}, y_{n+1})``
    once per step holding such points unless the method is first-same-as-last
    (FSAL: its last stage is that slope), and the start slope only for a
    method without ``tab.start_stage``. A FSAL method reuses its last stage's
    evaluation as the next step's first (so RK4: ``4 N``, Stormer-Verlet:
    ``N + 1``); the reused value was evaluated at ``t_n + h``, which for a
    ``t``-dependent ``fun`` may differ from the grid time ``t_{n+1}`` by an
    ulp.

    With events or dense output every step's state and start slope are kept,
    and a slope an interpolant needs before the next step has computed it
    (a step where an event changed sign) is computed once and reused as that
    next step's first stage. The extra calls are then only the slopes no
    stage gives: for RK4 one, ``f(t_N, y_N)`` at the end, with
    ``dense_output`` (or an event or off-grid ``t_eval`` point in the last
    step); for a method without a start stage one per slope needed.
    ``nfev`` counts the calls as made. Event functions are not counted in
    ``nfev`` (nor are they in ``solve_ivp``).

    Backward integration. ``t1 < t0`` steps with ``(t1 - t0) / N < 0``; the
    arithmetic is that of the forward run of the time-reversed problem
    ``dz/ds = -fun(-s, z)`` from ``-t0`` to ``-t1``, so a backward run equals
    that forward run, reversed, to round-off (bit for bit in practice).

    Instability. The run stops, with ``success=False``, ``status=-1``,
    ``t_fail`` and a one-line message, at the first step whose new state has
    a component with ``NOT(|y_i| <= bound_i)`` -- one comparison that also
    catches inf and NaN. ``bound_i = min(max_growth * scale_i, DBL_MAX)``
    (``DBL_MAX`` when ``max_growth`` is None); ``scale_i = y_scale[i]`` if
    given, else the infinity norm of ``y0`` (if ``y0`` is all zero, the
    infinity norm of the first non-zero state reached). ``result.reason`` is
    ``"non-finite"`` when a component is inf or NaN, else ``"growth"``. The
    failure is a status, never an exception, and the output holds only the
    states accepted before it (``result.sol`` only their steps).

    Differences from ``solve_ivp``: the step is fixed (``h`` or ``n_steps``
    required; no ``rtol``/``atol``); unknown options are refused, not
    warned about; an empty ``y0`` is refused; ``t1 == t0`` returns the one
    point ``t0`` (``solve_ivp`` returns it twice); a zero of an event
    function exactly on a grid point is recorded once (:mod:`rk4h.events`);
    a run that becomes non-finite or grows past ``max_growth`` ends with
    ``status = -1`` where ``solve_ivp`` would shrink its step; an infinite
    ``t1`` needs a terminal event and stops after ``max_steps``; an empty
    output (``t_eval`` wholly past an early terminal event) is an
    :class:`EmptyOutput`, an empty ndarray that is false as ``solve_ivp``'s
    ``[]`` is.

    Examples
    --------
    >>> import numpy as np, rk4h

    A ball thrown up at 10 m/s; ``args`` reach the event function too:

    >>> def hit_ground(t, y, g): return y[0]
    >>> hit_ground.terminal, hit_ground.direction = True, -1
    >>> res = rk4h.solve(lambda t, y, g: [y[1], -g], (0.0, 10.0), [0.0, 10.0], args=(9.81,),
    ...                     events=hit_ground, dense_output=True, h=0.01)
    >>> res.status, round(float(res.t_events[0][0]), 9), bool(res["t"][-1] == res.t_events[0][0])
    (1, 2.038735984, True)
    >>> round(float(res.sol(1.0)[0]), 9)  # y(1) = 10 - 9.81 / 2
    5.095
    """
    refuse_options(options)
    tab: Tableau = _get_method(method)
    t_inf = _infinite_end(t_span)
    t0, t1 = check_t_span(t_span if t_inf is None else (t_span[0], 0.0), allow_backward=True)
    if t_inf is not None:
        t1 = t_inf
    y = check_y0(y0, allow_complex=True)
    n_comp = y.shape[0]
    if tab.partitioned and n_comp % 2:
        raise ValueError(f"`y0` must have even length for {tab.name!r} (y = [q, v]), got {n_comp}")
    max_growth = check_max_growth(max_growth)
    y_scale = check_y_scale(y_scale, n_comp)
    dense_output = boolean("dense_output", dense_output)
    vectorized = boolean("vectorized", vectorized)
    args = _check_args(args)
    ev = None
    if events is not None:
        from .events import Events
        ev = Events(events, args)
    t_eval = check_t_eval(t_eval, t0, t1)
    if t_inf is not None:
        n, step = _infinite_grid(t0, t1, h, n_steps, max_steps, ev)
        t1 = t0 + n * step  # the grid's end, reached only when no terminal event fired
    else:
        n = check_step_args(t0, t1, check_step_sign(h, t0, t1), n_steps, step_count)
        if t1 == t0:
            n = 0
        step = (t1 - t0) / n if n else 0.0
    dtype = y.dtype
    rich = dense_output or (ev is not None and len(ev) > 0)
    step_name, step_value = ("h", h) if h is not None else ("n_steps", n_steps)
    if t_inf is not None:
        step_name, step_value = "max_steps", max_steps
    if t_eval is None:
        check_output_size(step_name, step_value, n + 1, n_comp, dtype.itemsize)
    else:
        check_output_size("t_eval", f"<{t_eval.shape[0]} times>", t_eval.shape[0], n_comp, dtype.itemsize)
    if rich:
        check_output_size(step_name, step_value, 2 * (n + 1), n_comp, dtype.itemsize)
    fun = _checked(fun, n_comp, dtype, args=args, vectorized=vectorized, t_floor=t1 if t1 < t0 else None)
    if n == 0:
        return _no_step(t0, y, t_eval, dense_output, ev, tab)
    bound, pending = growth_bound(y, max_growth, y_scale)
    scale_from = "given" if y_scale is not None else "initial"
    t_max = t1 if t1 > t0 else None  # backward: the clamp is in `fun` (t_floor)
    if rich:
        res = _solve_rich(fun, tab, t0, t1, n, step, y, bound, pending, scale_from, t_max, t_eval,
                          dense_output, ev)
        if t_inf is not None and res.status == 0:
            res.status, res.success, res.reason = -1, False, "max_steps"
            res.message = (f"no terminal event ended the run within max_steps = {n} steps (t = {t1:.6g}, "
                           f"h = {step:.6g}); t_span's end is infinite")
        return res

    grid_out = t_eval is None
    if grid_out:
        ys = np.empty((n + 1, n_comp), dtype=dtype)
        ys[0] = y
        hook = _GridOutput(ys)
    else:
        # Index of the step each output time falls in, and its position in it.
        idx, theta, on_grid = _output_points(t_eval, t0, step, n)
        dense = "grid" if on_grid.all() else "hermite"
        ys = np.empty((t_eval.shape[0], n_comp), dtype=dtype)
        out_ptr, _ = _emit(ys, 0, idx, theta, 0, y, None, step, fun, t0, t1, n, None, tab)
        hook = _PointOutput(ys, out_ptr, idx, theta, step, fun, t0, t1, n, tab)
    nfev, n_done, status, reason, message, t_fail = _drive(fun, tab, t0, t1, n, step, y, bound, pending,
                                                          scale_from, t_max, hook)
    if not grid_out:
        out_ptr = hook.ptr
    if grid_out:
        t_out = grid_times(t0, t1, step, np.arange(n_done + 1), n)
        y_out = ys[: n_done + 1].T.copy()
        dense = "grid"
    else:
        t_out = t_eval[:out_ptr]
        y_out = ys[:out_ptr].T.copy()
    return FixedStepResult(
        t=t_out, y=y_out, nfev=nfev, h=step, n_steps=n_done, success=status >= 0,
        status=status, message=message, t_fail=t_fail, dense=dense, method=tab.name, reason=reason,
        t_events=None if ev is None else [], y_events=None if ev is None else [],
    )


def _no_step(t0, y, t_eval, dense_output, ev, tab) -> FixedStepResult:
    """``t1 == t0``: no step, no call of ``fun``; the state is ``y0``."""
    m = 1 if t_eval is None else t_eval.shape[0]
    t_out = np.array([t0]) if t_eval is None else t_eval.copy()
    sol = None
    if dense_output:
        from .dense import HermiteSolution
        sol = HermiteSolution([t0, t0], [t0], y[None, :].copy(), np.zeros((1, y.shape[0]), dtype=y.dtype))
    t_events = y_events = None
    if ev is not None:
        t_events, y_events = ev.results()
    return FixedStepResult(
        t=t_out, y=np.repeat(y[:, None], m, axis=1), nfev=0, h=0.0, n_steps=0, success=True, status=0,
        message=MESSAGES[0], method=tab.name, sol=sol, t_events=t_events, y_events=y_events,
    )


def _solve_rich(fun, tab, t0, t1, n, step, y, bound, pending, scale_from, t_max, t_eval, dense_output,
                ev) -> FixedStepResult:
    """The loop of :func:`solve` with events and/or dense output: every
    step's state and start slope are kept for the Hermite interpolants."""
    from .dense import HermiteSolution, hermite

    n_comp = y.shape[0]
    dtype = y.dtype
    half = n_comp // 2
    ys = np.empty((n + 1, n_comp), dtype=dtype)
    ys[0] = y
    fs = np.empty((n + 1, n_comp), dtype=dtype)  # f(t_i, y_i), where have[i]
    have = bytearray(n + 1)
    s0 = tab.start_stage if not tab.partitioned else None  # k[s0] is f(t_i, y_i) (classical)
    nfev = 0
    kept = None  # (t_i, y_i, f) for step i's first stage

    def slope(i, y_i, keep=False):
        """f(t_i, y_i) by one call (kept for step i's first stage if ``keep``)."""
        nonlocal nfev, kept
        t_i = grid_time(t0, t1, step, i, n)
        f = fun(t_i, y_i)
        nfev += 1
        if keep:
            kept = (t_i, y_i, f)
        if tab.partitioned:  # [v, a(q)], as start_slope
            fs[i, :half] = y_i[half:]
            fs[i, half:] = f[half:]
        else:
            fs[i] = f
        have[i] = 1

    def local(i):
        """The interpolant of step i (the same arithmetic as HermiteSolution)."""
        a = grid_time(t0, t1, step, i, n)
        d = grid_time(t0, t1, step, i + 1, n) - a
        y0_, y1_, f0_, f1_ = ys[i], ys[i + 1], fs[i], fs[i + 1]

        def interp(t):
            return hermite(np.array([(t - a) / d]), d, y0_, y1_, f0_, f1_)[0]

        return interp

    stop = {}

    class Rich(_StepHook):
        def first_stage(self, i):
            nonlocal kept
            if kept is None:
                return None
            once, kept = _Once(fun, *kept), None
            return once

        def taken(self, i, y_i, k):
            if not have[i]:
                if s0 is not None:
                    fs[i] = k[s0]
                    have[i] = 1
                else:
                    f0 = start_slope(tab, y_i, k)
                    if f0 is not None:
                        fs[i] = f0
                        have[i] = 1

        def accepted(self, i, t, y_i, y_new, k):
            nonlocal g
            ys[i + 1] = y_new
            if tab.fsal:
                fs[i + 1] = end_slope(tab, y_new, k)
                have[i + 1] = 1
            if ev is None:
                return 0, False
            t_new = grid_time(t0, t1, step, i + 1, n)
            g_new = ev.values(t_new, y_new)
            active = ev.active(g, g_new, t)
            if active.size:
                if not have[i]:
                    slope(i, ys[i])
                if not have[i + 1]:
                    slope(i + 1, y_new, keep=True)
                hit = ev.handle(active, local(i), t, t_new)
                if hit is not None:
                    stop["at"] = hit
                    return 0, True
            g = g_new
            return 0, False

    g = ev.values(t0, y) if ev is not None else None
    steps_nfev, n_done, status, reason, message, t_fail = _drive(fun, tab, t0, t1, n, step, y, bound, pending,
                                                                 scale_from, t_max, Rich())
    nfev += steps_nfev  # slope() counted its own calls
    t_stop, y_stop = stop.get("at", (None, None))
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        # Segments of the dense output: the steps done; a terminal event at the
        # start of its step ends the run on that grid point.
        n_seg = n_done
        if status == 1 and t_stop == grid_time(t0, t1, step, n_done - 1, n):
            n_seg = n_done - 1
        if dense_output:
            for i in range(n_seg + 1):
                if not have[i]:
                    slope(i, ys[i])
        dense = "grid"
        if t_eval is None:
            last = n_done - 1 if status == 1 else n_done
            t_out = grid_times(t0, t1, step, np.arange(last + 1), n)
            y_out = ys[: last + 1].T.copy()
            if status == 1 and t_stop != t_out[-1]:
                t_out = np.append(t_out, t_stop)
                y_out = np.concatenate((y_out, y_stop[:, None]), axis=1)
        else:
            idx, theta, on_grid = _output_points(t_eval, t0, step, n)
            if status == 1:
                keep = (t_eval <= t_stop) if t1 > t0 else (t_eval >= t_stop)
            else:
                keep = (idx < n_done) | ((idx == n_done) & (theta == 0.0))
            m = int(np.argmin(keep)) if not keep.all() else keep.shape[0]  # t_eval is monotone: a prefix
            idx, theta, on_grid = idx[:m], theta[:m], on_grid[:m]
            off = np.nonzero(theta > 0.0)[0]
            for j in np.unique(idx[off]):
                for i in (j, j + 1):
                    if not have[i]:
                        slope(i, ys[i])
            y_rows = ys[idx].copy()
            if off.size:
                dense = "hermite"
                io = idx[off]
                y_rows[off] = hermite(theta[off], step, ys[io], ys[io + 1], fs[io], fs[io + 1])
            t_out = t_eval[:m]
            y_out = np.ascontiguousarray(y_rows.T)

    sol = None
    if dense_output:
        nodes = grid_times(t0, t1, step, np.arange(n_seg + 1), n)
        ts = nodes.copy()
        if status == 1 and n_seg > 0:
            ts[-1] = t_stop
        if n_seg < n:  # a shorter run: keep only what the interpolants use
            ys, fs = ys[: n_seg + 1].copy(), fs[: n_seg + 1].copy()
        sol = HermiteSolution(ts, nodes, ys, fs)
    t_events = y_events = None
    if ev is not None:
        t_events, y_events = ev.results()
    return FixedStepResult(
        t=t_out, y=y_out, nfev=nfev, h=step, n_steps=n_done, success=status >= 0, status=status,
        message=message, t_fail=t_fail, dense=dense, method=tab.name, reason=reason, sol=sol,
        t_events=t_events, y_events=y_events,
    )


def _emit(ys, ptr, idx, theta, i_step, y_new, y_old, step, fun, t0, t1, n, k, tab):
    """Write every output point that falls at grid point ``i_step`` or inside
    step ``i_step - 1`` (cubic Hermite on [y_old, y_new]) into ``ys``.

    The slopes at the step's ends come from its stages when the method has
    them (:func:`~rk4h.methods.start_slope`: the first stage of every
    built-in method; :func:`~rk4h.methods.end_slope`: the last stage of a
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
