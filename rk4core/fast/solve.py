"""Fixed-step integration of a symbolically defined model with compiled kernels.

:func:`solve_model` has the semantics of :func:`rk4h.solve` applied to
``model.rhs`` -- same step-count rule, same output grid or ``t_eval`` handling
(grid points exact, cubic Hermite in between), same blow-up status and message
-- and returns the same :class:`~rk4h.solver.FixedStepResult`, with the
numbers equal to round-off (bit for bit where the elementary functions agree).
The instability rule (``max_growth``, ``y_scale``) is applied at the same
step with the same bounds, so ``t_fail``, ``reason`` and the message are the
same too.
"""
from __future__ import annotations

import math
import time

import numpy as np

from ..methods import get_method
from ..solver import (FixedStepResult, grid_time, grid_times, growth_bound, nfev_count, step_count,
                      unstable_message)
from ..validate import (check_max_growth, check_model_y0, check_output_size, check_step_args, check_t_eval,
                        check_t_span, check_y_scale)
from . import _kernels as K
from .codegen import MAX_UNROLLED_DIM, array_kernel, array_loop, kernel, model_module

__all__ = ["solve_model", "warm_up", "compile_time", "supports", "force_kernel", "compiled_rhs", "CompiledRHS",
           "compiled_entry", "plain_vector"]

_COMPILE_S: float | None = None
#: The loops :func:`warm_up` has run once in this process, by ``id`` (the
#: loop object is kept beside it, so the id is never reused).
_WARMED: dict = {}

#: Methods whose override in a subclass would make the compiled kernels (printed
#: from the definition) disagree with the numpy right-hand side.
_PHYSICS = ("_force", "force", "acceleration", "rhs", "force_kernel")


def _owner(cls, attr):
    return next((c for c in cls.__mro__ if attr in vars(c)), None)


def force_kernel(model):
    """The model's compiled force kernel (:meth:`Model.force_kernel`) when the
    compiled path computes what ``model.rhs`` computes, else None: a subclass
    that redefines the force (or the right-hand side) below the class that
    derives the kernel runs on the generic path."""
    cached = model.__dict__.get("_fast_force_kernel", False) if hasattr(model, "__dict__") else None
    if cached is not False and cached is not None:
        from rk4h.models.base import model_current

        if model_current(model):  # else changed: it dropped this kernel with the other per-object caches
            return cached
    try:
        kern = model.force_kernel()
    except AttributeError:
        return None
    if kern is None:
        return None
    mro = type(model).__mro__
    owner = _owner(type(model), "force_kernel")
    for attr in _PHYSICS:
        c = _owner(type(model), attr)
        if c is not None and mro.index(c) < mro.index(owner):
            return None
        # a function assigned onto the class later (a monkeypatch) is not the class's own
        fn = vars(c)[attr] if c is not None else None
        if fn is not None and not getattr(fn, "__qualname__", "").startswith(c.__qualname__ + "."):
            return None
    model.__dict__["_fast_force_kernel"] = kern  # once per model object while it is unchanged (model_current)
    return kern


def supports(model) -> bool:
    """True when ``model``'s right-hand side has a compiled form: its force
    is derived from a symbolic definition (every shipped model, ``network``,
    ``potential``, FPUT chains) and no subclass redefines it."""
    return force_kernel(model) is not None


class CompiledRHS:
    """The right-hand side of a model compiled from its definition, for the
    references (DOP853, CVODE): equal to ``model.rhs`` (bit for bit where
    the elementary functions agree), without numpy's per-call overhead.

    Built by :func:`compiled_rhs`. ``rhs(t, y)`` returns ``dy/dt`` as a new
    array; :meth:`checked` also says whether it is non-finite at a finite
    state (a spring of zero length reached); :meth:`permuted` gives CVODE's
    in-place form for a reordered state.
    """

    def __init__(self, model, kern):
        module = model_module(kern)
        # one compiled entry point (identity order for DOP853), for one signature
        self._perm = _one_signature(module.rhs_permuted)
        # own writable copies: the one compiled signature takes writable
        # constants (a caller's read-only or memory-mapped array would not match)
        self.fp = np.array(kern.fp, dtype=float, order="C")
        self.ip = np.array(kern.ip, dtype=np.int64, order="C")
        self.mass = np.array(model.mass, dtype=float, order="C")
        self.w = np.zeros(kern.work_size)
        self.n_state = 2 * model.n_dof
        self._identity = np.arange(self.n_state, dtype=np.int64)
        self._buf = np.zeros((3, self.n_state))
        # The entry point is compiled (or loaded from the disk cache) here,
        # once per force structure and process (:func:`_one_signature`).

    def __call__(self, t, y):
        out = np.empty(self.n_state)
        try:
            self._perm(self.fp, self.ip, self.mass, y, out, self._identity, self._buf, self.w)
        except TypeError:
            self._any(y, out, self._identity, self._buf)
        return out

    def checked(self, y):
        """``(dy/dt, bad)``: ``bad`` is True when ``y`` is finite and ``dy/dt`` is not."""
        out = np.empty(self.n_state)
        try:
            bad = self._perm(self.fp, self.ip, self.mass, y, out, self._identity, self._buf, self.w)
        except TypeError:
            bad = self._any(y, out, self._identity, self._buf)
        return out, bad

    def _any(self, z, zp, perm, buf):
        """The entry point for a state ``z`` or an output ``zp`` that is not
        a C-contiguous float64 vector (the one compiled signature's): through
        copies of that type, the same numbers."""
        zc = np.ascontiguousarray(z, dtype=np.float64)
        out = np.empty(self.n_state)
        bad = self._perm(self.fp, self.ip, self.mass, zc, out, perm, buf, self.w)
        zp[...] = out
        return bad

    def permuted(self, perm):
        """``fun(z, zp) -> bad``: writes ``zp = (dy/dt)[perm]`` for the state
        ``y[perm] = z`` (CVODE's interleaved order) and says whether ``dy/dt``
        is non-finite at a finite state."""
        perm = np.array(perm, dtype=np.int64, order="C")  # an own writable copy (the signature's)
        buf = np.zeros((3, self.n_state))
        fn, fp, ip, mass, w = self._perm, self.fp, self.ip, self.mass, self.w
        any_type = self._any

        def fun(z, zp):
            try:
                return fn(fp, ip, mass, z, zp, perm, buf, w)
            except TypeError:
                return any_type(z, zp, perm, buf)

        return fun

    def permuted_parts(self, perm, readonly=True):
        """``(fn, fp, ip, mass, perm, buf, w)``: :meth:`permuted`'s compiled
        function (a numba dispatcher) and its constant arguments, for a caller
        that calls ``fn(fp, ip, mass, z, zp, perm, buf, w) -> bad`` itself
        (one Python frame less per call: CVODE's glue). ``fn`` is called once
        here with a writable ``z`` and, with ``readonly``, a read-only one
        (scikit-sundae passes the state read-only), so that no later call
        compiles or loads anything: with one compiled signature
        (:func:`_one_signature`) both run its machine code."""
        perm = np.array(perm, dtype=np.int64, order="C")  # an own writable copy (the signature's)
        buf = np.zeros((3, self.n_state))
        fn = self._perm
        z = np.zeros(self.n_state)
        fn(self.fp, self.ip, self.mass, z, np.zeros(self.n_state), perm, buf, self.w)
        if readonly:
            z.setflags(write=False)
            fn(self.fp, self.ip, self.mass, z, np.zeros(self.n_state), perm, buf, self.w)
        return fn, self.fp, self.ip, self.mass, perm, buf, self.w


def plain_vector(a, n: int) -> bool:
    """Whether ``a`` is a C-contiguous float64 ndarray of shape ``(n,)``: a
    state :func:`compiled_entry`'s entry point may be given (scikit-sundae's
    views of CVODE's vectors and scipy's DOP853 stages are)."""
    return type(a) is np.ndarray and a.dtype == np.float64 and a.shape == (n,) and a.flags.c_contiguous


#: numpy's array flags that numba's type of an array depends on: C_CONTIGUOUS,
#: F_CONTIGUOUS, ALIGNED, WRITEABLE.
_TYPE_FLAGS = 0x1 | 0x2 | 0x100 | 0x400
#: :func:`compiled_entry`'s answers, by ``(id(dispatcher), the arrays' type key)``;
#: each value keeps its dispatcher, so that the id is not reused.
_ENTRIES: dict = {}


def compiled_entry(dispatcher, args):
    """The compiled entry point of the numba ``dispatcher`` for exactly the
    types of ``args`` (numba's per-call type resolution skipped: about 0.6 us
    of a call with 8 array arguments), or ``dispatcher`` itself when it has
    no such compiled version. The entry point converts its arguments without
    checking their types (only the item size of arrays): a caller passes
    arrays of the types of ``args`` on every later call. ``args`` are
    ndarrays; the answer is kept per dispatcher and argument types (numba's
    ``typeof`` of 8 arrays takes about 0.1-0.2 ms, the key 2-3 us)."""
    # numba's type of an array: its dtype (byte order included), ndim, layout
    # (C/F contiguous), alignment and whether it is writable
    key = (id(dispatcher),) + tuple((a.dtype, a.ndim, a.flags.num & _TYPE_FLAGS) for a in args)
    hit = _ENTRIES.get(key)
    if hit is not None:
        return hit[1]
    try:
        from numba import typeof

        cres = dispatcher.overloads.get(tuple(typeof(a) for a in args))
        entry = getattr(cres, "entry_point", None)
    except Exception:  # noqa: BLE001 - another numba: its dispatcher
        return dispatcher
    entry = dispatcher if entry is None else entry
    if entry is not dispatcher:
        if len(_ENTRIES) > 256:
            _ENTRIES.clear()
        _ENTRIES[key] = (dispatcher, entry)
    return entry


def _one_signature(dispatcher):
    """``dispatcher`` (a model module's ``rhs_permuted``) compiled, or loaded
    from numba's on-disk cache, for one signature only: the state ``z``
    read-only, the other arrays writable, all C-contiguous float64 (``ip``
    and ``perm`` int64; ``buf`` 2-D).

    scikit-sundae hands CVODE's state over read-only, DOP853's is writable:
    numba converts a writable array to the read-only type at call time (a
    safe conversion, no copy), but compiles a second specialization instead
    while compiling is allowed. Compiling is switched off once this one is
    there, so both references run the same machine code and the module is
    compiled once (issue 29, cold start). A call with other types then raises
    ``TypeError``; :class:`CompiledRHS` catches it (``_any``). Should numba's
    dispatcher lack these hooks, it is left as it was (compiled per call
    signature)."""
    try:
        if not dispatcher._can_compile:
            return dispatcher
        from numba import types

        f = types.Array(types.float64, 1, "C")
        i = types.Array(types.int64, 1, "C")
        sig = (f, i, f, types.Array(types.float64, 1, "C", readonly=True), f, i,
               types.Array(types.float64, 2, "C"), f)
    except (AttributeError, ImportError, TypeError):
        return dispatcher
    dispatcher.compile(sig)
    dispatcher.disable_compile()
    return dispatcher


def compiled_rhs(model) -> CompiledRHS | None:
    """The model's :class:`CompiledRHS`, or None when it has no compiled form
    (:func:`supports`)."""
    kern = force_kernel(model)
    return None if kern is None else CompiledRHS(model, kern)


class _Prepared:
    """What :func:`solve_model` needs of a (model, method) pair besides the
    run's own arguments: the compiled loop it chooses and the kernel's
    constant arrays (contiguous, never written by the loops)."""

    __slots__ = ("tab", "loop", "unrolled", "fp", "ip", "mass", "work_size")

    def __init__(self, model, kern, tab):
        self.tab = tab  # kept: the cache key is id(tab)
        self.unrolled = not array_loop(kern, 2 * model.n_dof)
        self.loop = kernel(tab, kern) if self.unrolled else array_kernel(tab, kern)
        # own writable copies: the one compiled signature takes writable
        # constants (a caller's read-only or memory-mapped array would not match)
        self.fp = np.array(kern.fp, dtype=float, order="C")
        self.ip = np.array(kern.ip, dtype=np.int64, order="C")
        self.mass = np.array(model.mass, dtype=float, order="C")
        self.work_size = kern.work_size


#: At most this many methods' loops are kept on one model object.
_PREPARED_PER_MODEL = 16


def _prepared(model, kern, tab) -> _Prepared:
    """``model``'s :class:`_Prepared` for ``tab``, built once per model object
    and method object (models are not changed after construction)."""
    store = model.__dict__.get("_fast_prepared") if hasattr(model, "__dict__") else None
    if store is not None:
        prep = store.get(id(tab))
        if prep is not None and prep.tab is tab:
            return prep
    prep = _Prepared(model, kern, tab)
    if hasattr(model, "__dict__"):
        store = model.__dict__.setdefault("_fast_prepared", {})
        if len(store) >= _PREPARED_PER_MODEL:
            store.clear()
        store[id(tab)] = prep
    return prep


def solve_checked(model, t_eval, y0, h, method, bound) -> FixedStepResult | None:
    """:func:`solve_model` with ``t_eval``, ``h`` and a ``y_scale``, for
    arguments a caller has already checked; None when ``model`` has no
    compiled force.

    The caller guarantees (``rk4h.references.solvers.run_fixed`` does): ``y0`` a
    finite float64 array of length ``2 n_dof`` (copied: the loop works on
    the copy); ``t_eval`` a finite, strictly increasing float64 array of at
    least 2 times (s; ``t_span = (t_eval[0], t_eval[-1])``); ``h > 0``
    finite (s); ``method`` a :class:`~rk4h.methods.Tableau`; ``bound``
    the growth bounds ``min(max_growth * y_scale, DBL_MAX)`` of
    :func:`rk4h.solver.growth_bound` for finite scales ``y_scale > 0``
    (a float64 array the loop may not keep). The step count and the output
    size are checked as :func:`solve_model` checks them (same errors). The
    numbers are those of ``solve_model(..., max_growth=max_growth,
    y_scale=y_scale)``, bit for bit.
    """
    kern = force_kernel(model)
    if kern is None:
        return None
    y = y0.copy()
    t0, t1, step, n, idx, theta, dense = output_plan(t_eval, h, y.shape[0])
    return _finish(_prepared(model, kern, method), method, y, t0, t1, step, n, idx, theta, dense, t_eval,
                   bound, 0.0, "given")


def output_plan(t_eval, h, n_state):
    """``(t0, t1, step, n, idx, theta, dense)`` of a run of :func:`solve_checked`
    over checked ``t_eval`` (s) with the largest step ``h`` (s) and a state of
    ``n_state`` components: the span, the step used, the step count and the
    output points (:func:`_output_points`). Raises as :func:`solve_model`
    for too many steps or too large an output."""
    t0, t1 = float(t_eval[0]), float(t_eval[-1])
    n = check_step_args(t0, t1, h, None, step_count)
    step = (t1 - t0) / n
    check_output_size("t_eval", f"<{t_eval.shape[0]} times>", t_eval.shape[0], n_state)
    idx, theta, dense = _output_points(t0, step, n, t_eval, 1)
    return t0, t1, step, n, idx, theta, dense


def prepared(model, method):
    """The compiled loop and constant arrays :func:`solve_model` uses for
    ``model`` and the :class:`~rk4h.methods.Tableau` ``method`` (kept on the
    model object), or None without a compiled force."""
    kern = force_kernel(model)
    return None if kern is None else _prepared(model, kern, method)


def warmed(model, method) -> bool:
    """Whether :func:`warm_up` has already run the loop ``solve_model`` runs
    for ``model`` and ``method`` in this process."""
    loop = _loop_of(model, method)
    return loop is not None and id(loop) in _WARMED


def _output_points(t0, step, n, t_eval, record_every):
    """Step index and fraction inside the step of every output point (as
    ``rk4h.solve``), and how they are produced (``"grid"``/``"hermite"``)."""
    if t_eval is None:
        idx = np.arange(0, n + 1, record_every, dtype=np.int64)
        if idx[-1] != n:
            idx = np.append(idx, np.int64(n))
        return idx, np.zeros(idx.shape[0]), "grid"
    if t_eval.shape[0] <= 32:
        return _output_points_few(t0, step, n, t_eval)
    s = (t_eval - t0) / step
    # np.minimum/np.maximum: np.clip's numbers, without its Python wrapper
    idx = np.minimum(np.maximum(np.floor(s + 1e-9).astype(np.int64), 0), n)
    theta = s - idx
    on_grid = np.abs(theta) <= 1e-9 * np.maximum(1.0, np.abs(s))
    theta[on_grid] = 0.0
    return idx, np.ascontiguousarray(theta), "grid" if on_grid.all() else "hermite"


def _output_points_few(t0, step, n, t_eval):
    """:func:`_output_points` for a few ``t_eval`` points, as Python floats:
    the same IEEE operations one by one (bit for bit), without a dozen
    ufunc calls."""
    idx, theta, grid = [], [], True
    for t in t_eval.tolist():
        s = (t - t0) / step
        i = min(max(math.floor(s + 1e-9), 0), n)
        th = s - i
        if abs(th) <= 1e-9 * max(1.0, abs(s)):
            th = 0.0
        else:
            grid = False
        idx.append(i)
        theta.append(th)
    return np.array(idx, dtype=np.int64), np.array(theta, dtype=np.float64), "grid" if grid else "hermite"


def _record_every(value, t_eval) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
        raise ValueError(f"`record_every` must be an integer >= 1, got {value!r}")
    if t_eval is not None and value != 1:
        raise ValueError(f"`record_every` must be 1 when `t_eval` is given, got {value!r}")
    return int(value)


def _output_rows(n, t_eval, record_every) -> int:
    """Rows of the output array (as :func:`_output_points` will make them)."""
    if t_eval is not None:
        return t_eval.shape[0]
    return n // record_every + 1 + (n % record_every != 0)


def solve_model(model, t_span, y0, *, h=None, n_steps=None, t_eval=None, method="rk4",
                record_every=1, max_growth=1e8, y_scale=None) -> FixedStepResult:
    """Integrate a model's equations of motion with loops compiled from its definition.

    Parameters
    ----------
    model : rk4h.models.Model
        A model with a compiled force (see :func:`rk4h.fast.supports`); its right-hand
        side is ``model.rhs`` (``y = [q, v]``, SI units of the model).
    t_span, y0, h, n_steps, t_eval, method, max_growth, y_scale
        As :func:`rk4h.solve` (same caps on the step count and the output
        size, same instability rule). ``y0`` is real (a complex ``y0`` is
        refused), of length ``2 * model.n_dof``; ``y_scale`` has the same
        length (m for positions, m/s for velocities, or the model's units).
    record_every : int, optional
        Without ``t_eval``: keep every ``record_every``-th step (and always
        the last one reached), to integrate long runs or large chains without
        storing each step. Default 1 (every step, as ``rk4h.solve``).

    Returns
    -------
    FixedStepResult
        ``nfev`` counts force evaluations as ``rk4h.solve`` counts
        right-hand-side calls: ``nfev_count(tab, N) = tab.nfev_first_step +
        (N - 1) tab.nfev_per_step`` for ``N`` steps attempted (a
        first-same-as-last method evaluates its reused stage once before the
        first step and carries its last stage into the next), plus the
        dense-output slopes no stage gave (one end slope per step holding
        off-grid ``t_eval`` points unless the method is FSAL).

    Notes
    -----
    A state of up to ``codegen.MAX_UNROLLED_DIM`` components (up to 8
    degrees of freedom, where the force has a straight-line form) runs a loop
    generated from the method's tableau with the state in registers
    (:mod:`rk4h.fast.codegen`); larger states run an array loop generated
    from the same tableau. Both give the numbers of
    ``rk4h.solve(model.rhs, ...)`` bit for bit wherever the elementary
    functions agree. The first call in a process for a method and a force
    structure compiles the loop,
    or loads it from numba's on-disk cache; call :func:`warm_up` (with the
    model and method) first to keep that time out of a timed run. The
    kernels divide as numpy does (``error_model="numpy"``): a zero spring
    length gives a non-finite state (status -1), not an exception.
    """
    tab = get_method(method)
    kern = force_kernel(model)
    if kern is None:
        raise ValueError(f"`model` must have a compiled force (a model defined by a potential, a network or "
                         f"a chain; see rk4h.fast.supports) for the fast path, got {type(model).__name__}")
    t0, t1 = check_t_span(t_span)
    y = check_model_y0(model, y0)
    max_growth = check_max_growth(max_growth)
    y_scale = check_y_scale(y_scale, y.shape[0])
    n = check_step_args(t0, t1, h, n_steps, step_count)
    step = (t1 - t0) / n
    t_eval = check_t_eval(t_eval, t0, t1)
    every = _record_every(record_every, t_eval)
    rows = _output_rows(n, t_eval, every)
    if t_eval is not None:
        check_output_size("t_eval", f"<{t_eval.shape[0]} times>", rows, y.shape[0])
    elif every > 1:
        check_output_size("record_every", every, rows, y.shape[0])
    else:
        check_output_size("h" if h is not None else "n_steps", h if h is not None else n_steps, rows, y.shape[0])
    idx, theta, dense = _output_points(t0, step, n, t_eval, every)
    bound, pending = growth_bound(y, max_growth, y_scale)
    prep = _prepared(model, kern, tab)
    return _finish(prep, tab, y, t0, t1, step, n, idx, theta, dense, t_eval, bound, pending,
                   "given" if y_scale is not None else "initial")


def _finish(prep, tab, y, t0, t1, step, n, idx, theta, dense, t_eval, bound, pending, scale_from):
    """Run ``prep``'s loop on checked arguments; the result of :func:`solve_model`."""
    ys, n_done, n_out, status, n_extra, y_fail = run_loop(prep, y, t0, step, n, idx, theta, bound, pending)
    nfev, message, t_fail, reason = outcome(tab, t0, t1, step, n, n_done, status, n_extra, y_fail, bound,
                                            scale_from)
    if t_eval is None:
        t_out = grid_times(t0, t1, step, idx[:n_out], n)
    else:
        t_out = t_eval[:n_out]
    return FixedStepResult(
        t=t_out, y=ys[:n_out].T, nfev=nfev, h=step, n_steps=n_done,
        success=status == K.STATUS_OK, status=status, message=message, t_fail=t_fail,
        dense=dense, method=tab.name, reason=reason,
    )


#: The message of a run that reached the end (``rk4h.solve``'s).
OK_MESSAGE = "The solver successfully reached the end of the integration interval."


def run_loop(prep, y, t0, step, n, idx, theta, bound, pending):
    """Run ``prep``'s compiled loop (:class:`_Prepared`) from the state ``y``
    (overwritten) over ``n`` steps of ``step`` (s) from ``t0`` (s), keeping
    the output points ``idx``/``theta`` (:func:`_output_points`; read only).

    Returns ``(ys, n_done, n_out, status, n_extra, y_fail)``: ``ys`` of shape
    (len(idx), len(y)) (rows past ``n_out`` unset), the steps completed, the
    rows filled, the loop's status (``_kernels.STATUS_OK`` or not), the
    dense-output slope evaluations and the rejected state."""
    ys = np.empty((idx.shape[0], y.shape[0]))
    y_fail = np.empty(y.shape[0])
    if prep.unrolled:
        n_done, n_out, status, n_extra = prep.loop(prep.fp, prep.ip, prep.mass, y, t0, step, n, idx, theta, ys,
                                                   bound, pending, y_fail)
    else:
        w = np.zeros(prep.work_size)
        n_done, n_out, status, n_extra = prep.loop(prep.fp, prep.ip, prep.mass, w, y, t0, step, n, idx, theta, ys,
                                                   bound, pending, y_fail)
    return ys, int(n_done), int(n_out), int(status), n_extra, y_fail


def outcome(tab, t0, t1, step, n, n_done, status, n_extra, y_fail, bound, scale_from):
    """``(nfev, message, t_fail, reason)`` of a :func:`run_loop` run, as
    :func:`rk4h.solve` reports them."""
    message = OK_MESSAGE
    t_fail, reason = None, "ok"
    if status != K.STATUS_OK:
        t_fail = grid_time(t0, t1, step, n_done + 1, n)  # as rk4h.solve
        reason, message = unstable_message(y_fail, bound, t_fail, n_done, n, step, scale_from)
    # As rk4h.solve, the stages of the step that failed are counted.
    nfev = nfev_count(tab, n_done + (status != K.STATUS_OK)) + int(n_extra)
    return nfev, message, t_fail, reason


def warm_up(model=None, method="rk4") -> float:
    """Compile the loop(s) ``solve_model(model, ..., method=method)`` will run,
    or load them from numba's on-disk cache.

    Each (method, force structure) has its own generated loop
    (:mod:`rk4h.fast.codegen`): straight-line up to ``MAX_UNROLLED_DIM``
    state components (one per size), an array loop beyond. Without ``model``
    the loops of a two-mass chain and of a chain too long for the
    straight-line loop are prepared.

    A model's loop that an earlier ``warm_up`` of this process already ran
    is not run again (the first call costs one step, later ones a look-up).

    Returns
    -------
    float
        Seconds spent now (compilation or cache load); about 0 when the
        loops were already loaded in this process. :func:`compile_time` keeps
        the first figure.
    """
    global _COMPILE_S
    from ..models import Chain

    start = time.perf_counter()
    if model is not None:
        loop = _loop_of(model, method)
        if loop is not None and id(loop) in _WARMED:
            return time.perf_counter() - start
    if model is None:  # a two-mass chain and a chain too long to unroll
        models = [Chain([1.0] * N, [1.0] * (N + 1)) for N in (2, MAX_UNROLLED_DIM // 2 + 1)]
    else:
        models = [model]
    for m in models:
        # One step with an on-grid and an off-grid output point loads every helper.
        solve_model(m, (0.0, 1.0), np.zeros(2 * m.n_dof), n_steps=1, t_eval=[0.0, 0.5, 1.0], method=method)
        loop = _loop_of(m, method)
        if loop is not None:
            _WARMED[id(loop)] = loop
    elapsed = time.perf_counter() - start
    if _COMPILE_S is None:
        _COMPILE_S = elapsed
    return elapsed


def _loop_of(model, method):
    """The compiled loop :func:`solve_model` runs for ``model`` and
    ``method`` (the choice it makes), or None without a compiled force."""
    kern = force_kernel(model)
    if kern is None:
        return None
    return _prepared(model, kern, get_method(method)).loop


def compile_time() -> float | None:
    """Seconds the first :func:`warm_up` of this process took (None before)."""
    return _COMPILE_S
