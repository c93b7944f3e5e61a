"""The tableau methods of the system under test (``rk4``, ``euler``,
``symplectic-euler``, any scene's own tableau). Built-in models run through the compiled fast path
(``rk4h.fast.solve_model``: the same numbers as ``rk4h.solve`` on
``model.rhs``, tested to 1e-14); any other model through ``rk4h.solve`` on
``model.rhs``. Compile/cache-load time of the fast path is ``compile_s``, kept
out of ``wall_s``; ``extra["path"]`` says which path ran.

``setting`` is the largest step ``h`` (s); the step used is
``(t_eval[-1] - t_eval[0]) / ceil(...)`` (``extra["h_used"]``). Output times on
the step grid are returned exactly, others by cubic Hermite interpolation
(``extra["dense"]`` says which). ``nfev`` is the method's own count
(``Tableau.nfev_per_step`` per step, first-same-as-last reuse counted: see
``rk4h.solve``), plus one end-slope evaluation per step that holds
off-grid outputs.

A run is UNSTABLE (with ``t_fail``; ``y`` NaN from the first output time not
reached) at the first step where a component is non-finite or exceeds
:data:`MAX_GROWTH` times its group scale (``s_q`` for positions, ``s_v`` for
velocities: :func:`rk4h.references.solvers.tolerances.state_scale`, the amplitude of
a state with the initial energy). Why that bound: on a linear conservative
model a step inside the method's stability region (``|R(i omega_j h)| <= 1`` on
every mode) never increases the energy, so every component stays below
``sqrt(n_dof m_max / m_min)`` times its scale (energy bound); on the shipped
models that is at most a few thousand. Exceeding 1e6 therefore means the
amplification ``|R|^n`` of some mode passed 1e6: the method left its
stability region (explicit Euler, whose ``|R| = sqrt(1 + theta^2) > 1`` at
every step, included). A run at 1e145 is never labelled ``ok``.

A repeated call on the same model object takes :func:`run_fixed_short`
(what a model keeps, and when it is dropped: the comment above it): the
same result bit for bit, without checking again what was checked before;
``compile_s`` is then 0 (nothing compiled or loaded).
"""
from __future__ import annotations

import math
import time

import numpy as np

import rk4h
import rk4h.fast as fast

from rk4h.fast import solve as _fast_solve
from rk4h.fast.solve import solve_checked
from rk4h.fast.statecheck import state_checker
from rk4h.validate import check_output_times
from rk4h.models.base import model_current, register_object_cache
from rk4h.solver import _DBL_MAX

from .base import SolverRun, Status
from .tolerances import group_scales, omega_bound, scales_from, state_scale

__all__ = ["run_fixed", "run_fixed_short", "MAX_GROWTH"]

#: A fixed-step run stops as UNSTABLE when a component exceeds this many times
#: its group scale (see the module docstring).
MAX_GROWTH = 1e6


def run_fixed(method, model, y0: np.ndarray, t_eval: np.ndarray, h: float) -> SolverRun:
    """Integrate ``model`` with the tableau ``method`` (an
    ``rk4h.methods.Tableau`` or a built-in name); never raises.

    The arguments are those :func:`rk4h.references.solvers.integrate` has checked:
    ``y0`` a finite float64 array of length ``2 n_dof`` (a state where the
    model's force is finite), ``t_eval`` a finite, strictly increasing
    float64 array of at least 2 times (s), ``h > 0`` finite (s)."""
    tab = rk4h.get_method(method)
    name = tab.name
    m = t_eval.shape[0]
    use_fast = fast.supports(model)
    compile_s = fast.warm_up(model, tab) if use_fast else 0.0
    s_q, s_v = group_scales(model, y0)
    trusted = use_fast and math.isfinite(s_q) and math.isfinite(s_v)
    if trusted:  # growth_bound(y0, MAX_GROWTH, state_scale(model, y0)), without the array round trip
        n_dof = model.n_dof
        growth = np.empty(2 * n_dof)
        growth[:n_dof] = min(MAX_GROWTH * s_q, _DBL_MAX)
        growth[n_dof:] = min(MAX_GROWTH * s_v, _DBL_MAX)
    else:
        bound = {"max_growth": MAX_GROWTH, "y_scale": state_scale(model, y0)}
    start = time.perf_counter()
    try:
        if trusted:
            # integrate() has checked y0, t_eval and h: the loop without solve_model's second round of checks
            res = solve_checked(model, t_eval, y0, h, tab, growth)
        elif use_fast:
            res = fast.solve_model(model, (t_eval[0], t_eval[-1]), y0, h=h, t_eval=t_eval, method=tab, **bound)
        else:
            res = rk4h.solve(model.rhs, (t_eval[0], t_eval[-1]), y0, h=h, t_eval=t_eval, method=tab,
                                **bound)
    except Exception as exc:  # noqa: BLE001 - a failure inside is a status, not an exception
        return SolverRun(name, h, t_eval, np.full((y0.shape[0], m), np.nan), 0, 0, time.perf_counter() - start, compile_s, status=Status.FAILED,
                         message=f"{name}: {type(exc).__name__}: {exc}", t_fail=float(t_eval[0]))
    wall = time.perf_counter() - start
    if trusted:
        _remember(model, tab, y0, growth)
    reached = res.y.shape[1]
    if reached == m:
        y = np.ascontiguousarray(res.y)
    else:
        y = np.full((y0.shape[0], m), np.nan)
        y[:, :reached] = res.y
    status = Status.OK if res.success else Status.UNSTABLE
    return SolverRun(name, h, t_eval, y, int(res.nfev), int(res.n_steps), wall, compile_s, status=status,
                     message=res.message, t_fail=res.t_fail,
                     extra={"h_used": res.h, "dense": res.dense, "path": "numba" if use_fast else "python",
                            "reason": res.reason})


# -- the short path of a repeated call (issue 29) -------------------------------------------------
#
# ``run_fixed`` checks and computes everything on every call. A model object that ran through it
# keeps a _Short record (in its ``__dict__``): the loop of each method run (warmed), the frequency
# bound, the growth bounds of the last initial states accepted (by their bytes) and the output plan
# of the last ``(t_eval, h)`` pairs (by the bytes of ``t_eval``). A later call whose inputs match
# runs the loop on those; anything else (a new state is checked here, and refused by the general
# path) goes the general way, with its checks and messages.
#
# Models are not changed after construction (their compiled kernel and constants are kept per
# object). A user who does change one anyway, in place or by rebinding an attribute, is noticed by
# the model's one change detection (rk4h.models.base.model_current, shared with its fingerprint and
# constants): it drops every per-object cache, this record included, and the call runs the general
# path on the model as it now is.

_RECORD = "_fixed_short"
register_object_cache(_RECORD)  # dropped with the model's other per-object caches when it changes
#: Most initial states and output plans one record keeps (then it starts again).
_KEEP = 16
#: Largest initial state (components) and output plan (times) a record keeps: larger ones are worked
#: out on each call (their run costs far more than that), so a record holds at most about 1 MiB.
_KEEP_SIZE = 4096


_UNSET = object()


class _Short:
    """What a repeated ``run_fixed`` of one model object needs (see above)."""

    __slots__ = ("n_state", "n_dof", "w", "preps", "states", "plans", "accepts")

    def __init__(self, model, w):
        self.accepts = _UNSET  # the compiled state test (rk4h.fast.statecheck), made on the first new state
        self.n_dof = model.n_dof
        self.n_state = 2 * model.n_dof
        self.w = w
        self.preps = {}   # id(tab) -> (tab, prepared loop)
        self.states = {}  # bytes of y0 -> growth bounds (read only)
        self.plans = {}   # (bytes of t_eval, h) -> output_plan(...)

    def growth(self, s_q, s_v):
        g = np.empty(self.n_state)
        g[:self.n_dof] = min(MAX_GROWTH * s_q, _DBL_MAX)
        g[self.n_dof:] = min(MAX_GROWTH * s_v, _DBL_MAX)
        g.flags.writeable = False
        return g


def _remember(model, tab, y0, growth) -> None:
    """Record, after a trusted general run of ``tab`` on ``model`` from ``y0``
    (checked) with the growth bounds ``growth``, what a repeated call needs."""
    d = getattr(model, "__dict__", None)
    if d is None or getattr(model, "first_order", False) or not _fast_solve.warmed(model, tab):
        return
    rec = d.get(_RECORD)
    if rec is None:
        try:
            w = omega_bound(model)
        except Exception:  # noqa: BLE001 - no bound: no record, the general path runs
            return
        rec = d[_RECORD] = _Short(model, w)
    if id(tab) not in rec.preps:
        if len(rec.preps) >= _KEEP:
            rec.preps.clear()
        rec.preps[id(tab)] = (tab, _fast_solve.prepared(model, tab))
    if y0.shape[0] > _KEEP_SIZE:
        return
    if len(rec.states) >= _KEEP:
        rec.states.clear()
    g = growth.copy()
    g.flags.writeable = False
    rec.states[y0.tobytes()] = g


def run_fixed_short(tab, model, y0, t_eval, h: float) -> SolverRun | None:
    """:func:`run_fixed` for a repeated call, or None where the general path
    must run (:func:`rk4h.references.solvers.integrate` then runs it).

    ``tab`` is a :class:`~rk4h.methods.Tableau`, ``h`` a finite float > 0
    (s); ``model``, ``y0`` and ``t_eval`` are the caller's, unchecked: the
    short path runs only on a model object that has run ``tab`` through
    :func:`run_fixed` and is unchanged since, a float64 ``y0`` of the
    model's length (finite, and a state :meth:`Model.check_state` accepts)
    and a float64 ``t_eval``; its result is :func:`run_fixed`'s, bit for
    bit, with ``compile_s = 0`` (nothing was compiled or loaded)."""
    d = getattr(model, "__dict__", None)
    rec = d.get(_RECORD) if d is not None else None
    if rec is None:
        return None
    if not model_current(model):  # changed: every per-object cache, this record included, was dropped
        return None
    entry = rec.preps.get(id(tab))
    if entry is None or entry[0] is not tab:
        return None
    if type(y0) is not np.ndarray or y0.dtype != np.float64 or y0.shape != (rec.n_state,):
        return None
    if type(t_eval) is not np.ndarray or t_eval.dtype != np.float64 or t_eval.ndim != 1:
        return None
    y = y0.copy()
    growth = rec.states.get(y.tobytes())
    if growth is None:
        growth = _new_state(rec, model, y)
        if growth is None:
            return None
    key = (t_eval.tobytes(), h)
    plan = rec.plans.get(key)
    t = t_eval.copy()
    if plan is None:
        try:
            plan = _fast_solve.output_plan(check_output_times(t), h, rec.n_state)
        except Exception:  # noqa: BLE001 - the general path refuses or reports it
            return None
        if t.shape[0] <= _KEEP_SIZE:
            if len(rec.plans) >= _KEEP:
                rec.plans.clear()
            rec.plans[key] = plan
    t0, t1, step, n, idx, theta, dense = plan
    bound = growth.copy()
    start = time.perf_counter()
    try:
        ys, n_done, n_out, status, n_extra, y_fail = _fast_solve.run_loop(entry[1], y, t0, step, n, idx, theta,
                                                                           bound, 0.0)
        nfev, message, t_fail, reason = _fast_solve.outcome(tab, t0, t1, step, n, n_done, status, n_extra,
                                                            y_fail, bound, "given")
    except Exception:  # noqa: BLE001 - the general path runs it again and reports the failure as a status
        return None
    m = t.shape[0]
    if n_out == m:
        y_out = np.ascontiguousarray(ys.T)
    else:
        y_out = np.full((rec.n_state, m), np.nan)
        y_out[:, :n_out] = ys[:n_out].T
    wall = time.perf_counter() - start
    return SolverRun(tab.name, h, t, y_out, nfev, n_done, wall, 0.0,
                     status=Status.OK if status == _fast_solve.K.STATUS_OK else Status.UNSTABLE,
                     message=message, t_fail=t_fail,
                     extra={"h_used": step, "dense": dense, "path": "numba", "reason": reason})


def _new_state(rec, model, y):
    """The growth bounds of a new initial state ``y`` (a copy) of ``rec``'s
    model, as :func:`run_fixed` computes them, or None when ``y`` is not
    finite or not a state of the model (the general path refuses it).

    Whether ``y`` is a state of the model: the compiled test of
    :func:`rk4h.fast.statecheck.state_checker` (a few us) where the model has
    one and it accepts; else :meth:`Model.check_state`'s numpy test."""
    n = rec.n_dof
    a = np.abs(y)
    aq, av = float(a[:n].max()), float(a[n:].max())
    if not (math.isfinite(aq) and math.isfinite(av)):
        return None
    accepts = rec.accepts
    if accepts is _UNSET:
        try:
            accepts = state_checker(model)
        except Exception:  # noqa: BLE001 - no compiled test: the numpy check decides
            accepts = None
        rec.accepts = accepts
    # the compiled test only ever accepts a state the numpy check accepts; else the numpy check decides
    if accepts is None or not accepts(y):
        try:
            if model._state_problem_once(y) is not None:
                return None
        except Exception:  # noqa: BLE001 - the general path says what is wrong
            return None
    s_q, s_v = scales_from(aq, av, rec.w)
    if not (math.isfinite(s_q) and math.isfinite(s_v)):
        return None
    g = rec.growth(s_q, s_v)
    if y.shape[0] <= _KEEP_SIZE:
        if len(rec.states) >= _KEEP:
            rec.states.clear()
        rec.states[y.tobytes()] = g
    return g
