"""CVODE for untimed work: the SUNDIALS library scikit-sundae ships, driven
through ``ctypes`` with compiled callbacks.

:func:`run_cvode_compiled` integrates as :func:`rk4h.references.solvers.cvode.run_cvode`
does -- the same CVODE (the shared libraries inside the installed
scikit-sundae wheel), the same configuration, the same output loop -- but
CVODE calls the right-hand side (and the dense Jacobian) as numba ``cfunc``
callbacks built from the model's compiled force, so no Python frame runs per
evaluation: scikit-sundae 1.2 takes only a Python callback, about 7-9 us per
call of its Cython wrapper. For untimed work (the trust table's confirmation
runs, the advisor): the timed work-precision rows keep running scikit-sundae
(:func:`rk4h.references.solvers.integrate`), as a user would.

Configuration (scikit-sundae 1.2's ``_cy_cvode.pyx``, as ``cvode.py`` sets it)
------------------------------------------------------------------------------
``SUNContext_Create``; ``N_VNew_Serial`` holding ``z0``; ``CVodeCreate``
(``CV_ADAMS`` or ``CV_BDF``); ``CVodeInit`` at ``t0``; ``CVodeSVtolerances``
(``rtol``, the per-component ``atol`` in the interleaved order); the dense
matrix and ``SUNLinSol_Dense`` (linear models whose Jacobian is not narrow
and nonlinear ones, with an analytic Jacobian: ``CVodeSetJacFn``) or the band
matrix ``SUNBandMatrix(n, uband, lband)`` and ``SUNLinSol_Band`` (CVODE's own
banded difference quotient, no Jacobian function); ``CVodeSetMaxNonlinIters``
3, ``CVodeSetMaxConvFails`` 10, ``CVodeSetInitStep`` 0 (CVODE's estimate),
``CVodeSetMinStep`` 0, ``CVodeSetMaxStep`` 0 (unbounded), ``CVodeSetMaxOrd``
12 (Adams) or 5 (BDF), ``CVodeSetMaxNumSteps``; ``CVodeSetStopTime(t_end)``
and one ``CVode(tout, CV_NORMAL)`` call per output time. With two output
times scikit-sundae's ``solve`` steps one by one, so ``run_cvode`` asks for an
extra midpoint (dropped); so does this runner (the first-step estimate
depends on the first output time). SUNDIALS' error handlers are cleared:
scikit-sundae's prints CVODE's errors, this one is silent (the message is in
the run).

The callbacks compute what scikit-sundae's calls of the compiled right-hand
side compute (the same generated force and permutation loop as
:meth:`rk4h.fast.CompiledRHS.permuted_parts`), and the Jacobians what
``cvode.py``'s ``jacfn`` writes: the constant interleaved matrix of a linear
model, or ``model.jacobian``'s central differences (relative step ``1e-6``
of the state scale, the same sums in the same order) for a nonlinear one. So
the states, ``n_steps`` and ``nfev`` equal scikit-sundae's
(``tests/test_cvode_compiled.py``: bit for bit on the shared cases and scene
models; a nonlinear force differs only where numba's and numpy's elementary
functions differ, e.g. the last bits of the time CVODE reports when a
run blows up).

CVODE's warnings ("t + h = t ...") are switched off with its logger
(scikit-sundae's run prints them on the C stdout, where they would mix with
a report's progress or the advisor's ``--json``).

Step cap
--------
``max_steps`` caps the run's total internal steps as in ``run_cvode``: before
each output interval CVODE's per-call limit ``max_num_steps`` is set to the
steps left, so CVODE returns ``CV_TOO_MUCH_WORK`` at step ``max_steps``; the
run ends FAILED ("step cap ...") with ``n_steps == max_steps``, the outputs
reached and ``t_fail`` CVODE's time of that step, as scikit-sundae's run. (Its
``nfev`` may differ from that run's, which spends a few calls returning NaN.)

The libraries and the fallback
------------------------------
The libraries are found next to the installed scikit-sundae (its wheel's
``scikit_sundae.libs`` or ``.dylibs``; nothing is loaded from anywhere else),
without importing it, and used only when SUNDIALS reports the version this
binding was written for (:data:`SUNDIALS_ABI`) and the layouts the callbacks
read (an ``N_Vector``'s and a dense ``SUNMatrix``'s data pointer, 32-bit
``sunindextype``) check out against the library's own accessors. Otherwise,
for a model without a compiled right-hand side, or when the callbacks fail to
compile, the run is :func:`run_cvode`'s, with ``extra["implementation"] =
"scikit-sundae"`` and ``extra["compiled_error"]`` saying why. Every SUNDIALS
object (context, vectors, matrix, linear solver, CVODE memory) is freed on
every path.
"""
from __future__ import annotations

import ctypes
import functools
import glob
import importlib.util
import os
import time

import numpy as np

from .base import SolverRun, Status, compiled_rhs
from .cvode import DEFAULT_MAX_STEPS, _linear_jacobian_once, interleave, run_cvode, solve_outputs

__all__ = ["run_cvode_compiled", "sundials_library", "SUNDIALS_ABI"]

#: The SUNDIALS version (major, minor) this binding's signatures and
#: layouts were written for: scikit-sundae 1.2's wheels ship 7.9.
SUNDIALS_ABI = (7, 9)
#: The shared libraries used, in load order (each links the ones before).
_LIBS = ("core", "nvecserial", "sunmatrixdense", "sunmatrixband", "sunlinsoldense", "sunlinsolband", "cvode")
CV_ADAMS, CV_BDF, CV_NORMAL = 1, 2, 1
CV_TOO_MUCH_WORK = -1

_P = ctypes.c_void_p
_I = ctypes.c_int        # int, and sunindextype (32-bit in scikit-sundae's build; checked)
_D = ctypes.c_double
_L = ctypes.c_long
#: name: (restype, argtypes)
_SIGNATURES = {
    "SUNDIALSGetVersionNumber": (_I, (ctypes.POINTER(_I),) * 3 + (ctypes.c_char_p, _I)),
    "SUNContext_Create": (_I, (_I, ctypes.POINTER(_P))),
    "SUNContext_Free": (_I, (ctypes.POINTER(_P),)),
    "SUNContext_ClearErrHandlers": (_I, (_P,)),
    "SUNContext_GetLogger": (_I, (_P, ctypes.POINTER(_P))),
    "SUNLogger_SetWarningFilename": (_I, (_P, ctypes.c_char_p)),
    "SUNMatDestroy": (None, (_P,)),
    "SUNLinSolFree": (_I, (_P,)),
    "N_VNew_Serial": (_P, (_I, _P)),
    "N_VDestroy": (None, (_P,)),
    "N_VGetArrayPointer": (_P, (_P,)),
    "N_VGetLength": (_I, (_P,)),
    "SUNDenseMatrix": (_P, (_I, _I, _P)),
    "SUNDenseMatrix_Data": (_P, (_P,)),
    "SUNBandMatrix": (_P, (_I, _I, _I, _P)),
    "SUNLinSol_Dense": (_P, (_P, _P, _P)),
    "SUNLinSol_Band": (_P, (_P, _P, _P)),
    "CVodeCreate": (_P, (_I, _P)),
    "CVodeFree": (None, (ctypes.POINTER(_P),)),
    "CVodeSetUserData": (_I, (_P, _P)),
    "CVodeInit": (_I, (_P, _P, _D, _P)),
    "CVodeSVtolerances": (_I, (_P, _D, _P)),
    "CVodeSetLinearSolver": (_I, (_P, _P, _P)),
    "CVodeSetJacFn": (_I, (_P, _P)),
    "CVodeSetMaxNonlinIters": (_I, (_P, _I)),
    "CVodeSetMaxConvFails": (_I, (_P, _I)),
    "CVodeSetInitStep": (_I, (_P, _D)),
    "CVodeSetMinStep": (_I, (_P, _D)),
    "CVodeSetMaxStep": (_I, (_P, _D)),
    "CVodeSetMaxOrd": (_I, (_P, _I)),
    "CVodeSetMaxNumSteps": (_I, (_P, _L)),
    "CVodeSetStopTime": (_I, (_P, _D)),
    "CVode": (_I, (_P, _D, _P, ctypes.POINTER(_D), _I)),
    "CVodeGetNumSteps": (_I, (_P, ctypes.POINTER(_L))),
    "CVodeGetNumRhsEvals": (_I, (_P, ctypes.POINTER(_L))),
    "CVodeGetNumLinRhsEvals": (_I, (_P, ctypes.POINTER(_L))),
    "CVodeGetNumJacEvals": (_I, (_P, ctypes.POINTER(_L))),
    "CVodeGetCurrentTime": (_I, (_P, ctypes.POINTER(_D))),
}


class _Unavailable(Exception):
    """The compiled path cannot run here (the reason is the message)."""


class _Sundials:
    """The SUNDIALS functions of :data:`_SIGNATURES`, as attributes."""

    def __init__(self, libs: dict):
        self.paths = {k: lib._name for k, lib in libs.items()}
        self._libs = libs
        for name, (res, args) in _SIGNATURES.items():
            fn = None
            for lib in libs.values():
                try:
                    fn = getattr(lib, name)
                    break
                except AttributeError:
                    continue
            if fn is None:
                raise _Unavailable(f"SUNDIALS function {name} not found in scikit-sundae's libraries")
            fn.restype, fn.argtypes = res, args
            setattr(self, name, fn)


def _library_dirs():
    """The folders of the installed scikit-sundae wheel that may hold its
    SUNDIALS libraries (found without importing the package)."""
    spec = importlib.util.find_spec("sksundae")
    if spec is None or not spec.origin:
        raise _Unavailable("scikit-sundae is not installed")
    pkg = os.path.dirname(os.path.realpath(spec.origin))
    return pkg, [os.path.join(os.path.dirname(pkg), "scikit_sundae.libs"), os.path.join(pkg, ".dylibs")]


@functools.lru_cache(maxsize=1)
def _load_sundials():
    """``(_Sundials, None)`` or ``(None, reason)``: scikit-sundae's SUNDIALS,
    its version and layouts checked (module docstring)."""
    try:
        pkg, dirs = _library_dirs()
        site = os.path.dirname(pkg)
        libs = {}
        for key in _LIBS:
            found = []
            for d in dirs:
                found += sorted(glob.glob(os.path.join(d, f"libsundials_{key}[-.]*")))
            found = [p for p in found if os.path.realpath(p).startswith(site + os.sep)]
            if len(found) != 1:
                raise _Unavailable(f"libsundials_{key}: {len(found)} candidates beside scikit-sundae "
                                   f"({', '.join(dirs)}), expected 1")
            try:
                libs[key] = ctypes.CDLL(found[0])
            except OSError as exc:
                raise _Unavailable(f"cannot load {found[0]}: {exc}") from None
        lib = _Sundials(libs)
        major, minor, patch = _I(), _I(), _I()
        label = ctypes.create_string_buffer(32)
        if lib.SUNDIALSGetVersionNumber(ctypes.byref(major), ctypes.byref(minor), ctypes.byref(patch), label, 32):
            raise _Unavailable("SUNDIALSGetVersionNumber failed")
        version = (major.value, minor.value, patch.value)
        if version[:2] != SUNDIALS_ABI:
            raise _Unavailable(f"scikit-sundae's SUNDIALS is {'.'.join(map(str, version))}; this binding is "
                               f"written for {'.'.join(map(str, SUNDIALS_ABI))}.x")
        lib.version = version
        _check_layout(lib)
        return lib, None
    except _Unavailable as exc:
        return None, str(exc)


def _check_layout(lib):
    """The callbacks read an ``N_Vector``'s data as ``content`` (its first
    word) then the pointer 8 bytes into the content (``{int length; int
    own_data; double *data}``), and a dense ``SUNMatrix``'s the same way
    (``{int M; int N; double *data; ...}``): checked here against
    ``N_VGetArrayPointer``/``N_VGetLength`` and ``SUNDenseMatrix_Data``."""
    ctx = _P()
    if lib.SUNContext_Create(0, ctypes.byref(ctx)) or not ctx.value:
        raise _Unavailable("SUNContext_Create failed")
    v = A = None
    try:
        n = 7
        v = lib.N_VNew_Serial(n, ctx)
        A = lib.SUNDenseMatrix(n, n, ctx)
        if not v or not A:
            raise _Unavailable("N_VNew_Serial or SUNDenseMatrix returned NULL")
        content = _P.from_address(v).value
        if (lib.N_VGetLength(v) != n or ctypes.c_int32.from_address(content).value != n
                or _P.from_address(content + 8).value != lib.N_VGetArrayPointer(v)):
            raise _Unavailable("N_Vector serial layout differs from the one the callbacks read")
        mcontent = _P.from_address(A).value
        if (ctypes.c_int32.from_address(mcontent).value != n or ctypes.c_int32.from_address(mcontent + 4).value != n
                or _P.from_address(mcontent + 8).value != lib.SUNDenseMatrix_Data(A)):
            raise _Unavailable("dense SUNMatrix layout differs from the one the callbacks read")
    finally:
        if A:
            lib.SUNMatDestroy(A)
        if v:
            lib.N_VDestroy(v)
        lib.SUNContext_Free(ctypes.byref(ctx))


def sundials_library():
    """``(paths, version)`` of the SUNDIALS libraries the compiled runner
    uses, or ``(None, reason)`` when it falls back to scikit-sundae."""
    lib, why = _load_sundials()
    if lib is None:
        return None, why
    return dict(lib.paths), lib.version


# -- the callbacks ----------------------------------------------------------------------------------------------
#
# User data: an int64 array of addresses, read in the callbacks as void
# pointers: [0] sizes (int64: n2, len(fp), len(ip), len(w), calls, bad, jac
# calls), [1] fp, [2] ip (int64), [3] mass, [4] perm (int64), [5] buf (3, n2),
# [6] w, [7] info (float64: time of the first non-finite slope at a finite
# state), [8] the constant Jacobian (n2 x n2, column-major) or scratch (4, n).

_CALLBACKS = '''

from numba import carray


def cv_rhs(t, y, ydot, ud):
    # CVRhsFn: ydot = dy/dt in the order z = y[perm]; the permutation loop of rhs_permuted
    sz = carray(ud[0], 7, np.int64)
    n2 = sz[0]
    fp = carray(ud[1], sz[1], np.float64)
    ip = carray(ud[2], sz[2], np.int64)
    mass = carray(ud[3], n2 // 2, np.float64)
    perm = carray(ud[4], n2, np.int64)
    buf = carray(ud[5], (3, n2), np.float64)
    w = carray(ud[6], sz[3], np.float64)
    z = carray(y[0][1], n2)
    zp = carray(ydot[0][1], n2)
    sz[4] += 1
    finite_in = True
    for i in range(n2):
        buf[0, perm[i]] = z[i]
        finite_in = finite_in and math.isfinite(z[i])
    rhs(fp, ip, mass, buf[0], buf, 1, n2 // 2, w)
    finite_out = True
    for i in range(n2):
        zp[i] = buf[1, perm[i]]
        finite_out = finite_out and math.isfinite(zp[i])
    if finite_in and not finite_out and sz[5] == 0:
        sz[5] = 1
        info = carray(ud[7], 1, np.float64)
        info[0] = t
    return 0


def cv_jac(t, y, fy, J, ud, tmp1, tmp2, tmp3):
    # CVLsJacFn: Model.jacobian's central differences of the force, permuted,
    # into the dense matrix (column-major)
    sz = carray(ud[0], 7, np.int64)
    n2 = sz[0]
    n = n2 // 2
    fp = carray(ud[1], sz[1], np.float64)
    ip = carray(ud[2], sz[2], np.int64)
    mass = carray(ud[3], n, np.float64)
    perm = carray(ud[4], n2, np.int64)
    buf = carray(ud[5], (3, n2), np.float64)
    w = carray(ud[6], sz[3], np.float64)
    s = carray(ud[8], (4, n), np.float64)
    z = carray(y[0][1], n2)
    jj = carray(J[0][1], n2 * n2)
    sz[6] += 1
    for i in range(n2):
        buf[0, perm[i]] = z[i]
    qmax = 0.0
    for i in range(n):
        a = abs(buf[0, i])
        if a > qmax or a != a:
            qmax = a
    eps = 1e-6 * max(1.0, qmax)
    two_eps = 2 * eps
    jy = buf[2]
    for b in range(n2):
        c = perm[b]
        for a in range(n2):
            jy[a] = 0.0
        if c >= n:  # d(q')/dv = I
            jy[c - n] = 1.0
        else:
            for i in range(n):
                d = eps if i == c else 0.0
                s[0, i] = buf[0, i] + d
                s[1, i] = buf[0, i] - d
            force(fp, ip, s[0], s[2], w)
            force(fp, ip, s[1], s[3], w)
            for i in range(n):
                jy[n + i] = (s[2, i] - s[3, i]) / two_eps / mass[i]
        for a in range(n2):
            jj[b * n2 + a] = jy[perm[a]]
    return 0

'''

#: The callbacks of each force kernel structure built in this process, by ``kern.key()``.
_CALLBACK_CACHE: dict = {}


def _signatures():
    from numba import types

    f = types.float64
    nv = types.CPointer(types.CPointer(types.CPointer(f)))  # N_Vector / SUNMatrix: -> content -> words
    ud = types.CPointer(types.voidptr)
    rhs = types.int32(f, nv, nv, ud)
    jac = types.int32(f, nv, nv, nv, ud, nv, nv, nv)
    return rhs, jac


def _callback(module, name: str, sig):
    """``module.name`` compiled as a C callback (numba ``cfunc``), with
    numba's on-disk cache pinned beside the generated module as every
    generated loop's (:mod:`rk4h.fast.codegen`), or without a cache when the
    module was compiled in memory."""
    from numba.core.ccallback import CFunc

    from rk4h.fast import codegen

    fn = getattr(module, name)
    cf = CFunc(fn, (sig.args, sig.return_type), {}, {"error_model": "numpy"})
    if not str(getattr(module, "__file__", "<")).startswith("<"):
        try:
            cf._cache = codegen._private_cache_class(str(codegen._cache_dirs()[1]))(fn)
        except Exception:  # noqa: BLE001 - numba's caching internals changed: compiled without a cache
            pass
    cf.compile()
    return cf


def _callbacks(kern, kind: str):
    """The C callback ``kind`` (``"rhs"``, ``"jac"``, ``"jac_constant"``) for
    force kernel ``kern``: the model's generated force and right-hand side
    (:func:`rk4h.fast.codegen.model_source`'s text) with :data:`_CALLBACKS`;
    the constant Jacobian's is :mod:`rk4h.references.solvers._cvode_jac`'s,
    one for every model."""
    key = (kern.key(), kind) if kind != "jac_constant" else kind
    cf = _CALLBACK_CACHE.get(key)
    if cf is None and kind == "jac_constant":  # the same for every model: compiled once per machine
        from . import _cvode_jac

        cf = _CALLBACK_CACHE[key] = _callback(_cvode_jac, "cv_jac_constant", _signatures()[1])
    if cf is None:
        from rk4h.fast import codegen

        text = "\n".join(["# Generated by rk4h.references.solvers.cvode_compiled from a model's definition; "
                          "do not edit.", f"# depends on: {codegen._dependencies_digest()}"]
                         + codegen._HEADER + codegen._rhs_lines(kern)) + _CALLBACKS
        module = codegen.load_generated(text)
        rhs_sig, jac_sig = _signatures()
        cf = _callback(module, {"rhs": "cv_rhs", "jac": "cv_jac"}[kind], rhs_sig if kind == "rhs" else jac_sig)
        _CALLBACK_CACHE[key] = cf
    return cf


# -- the run ----------------------------------------------------------------------------------------------------

def _fallback(solver_name, model, y0, t_eval, rtol, atol, max_steps, why):
    run = run_cvode(solver_name, model, y0, t_eval, rtol, atol, max_steps)
    run.extra["implementation"] = "scikit-sundae"
    run.extra["compiled_error"] = why
    return run


def run_cvode_compiled(solver_name: str, model, y0: np.ndarray, t_eval: np.ndarray, rtol: float,
                       atol: np.ndarray, max_steps: int = DEFAULT_MAX_STEPS) -> SolverRun:
    """:func:`rk4h.references.solvers.cvode.run_cvode` with CVODE driven
    through ``ctypes`` and compiled callbacks (module docstring): the same
    states, ``n_steps``, ``nfev``, counters, statuses and messages. For
    untimed work. ``extra["implementation"]`` is ``"compiled"``, or
    ``"scikit-sundae"`` with ``extra["compiled_error"]`` when it fell back;
    ``compile_s`` is the callbacks' build (compile or cache load) time, kept
    out of ``wall_s``. Never raises."""
    lib, why = _load_sundials()
    if lib is None:
        return _fallback(solver_name, model, y0, t_eval, rtol, atol, max_steps, why)
    try:
        fast_rhs = compiled_rhs(model)
    except Exception as exc:  # noqa: BLE001 - scikit-sundae's run reports it as its status
        return _fallback(solver_name, model, y0, t_eval, rtol, atol, max_steps,
                         f"compiled right-hand side failed: {type(exc).__name__}: {exc}")
    if fast_rhs is None or getattr(model, "first_order", False):
        return _fallback(solver_name, model, y0, t_eval, rtol, atol, max_steps,
                         "the model has no compiled right-hand side")
    from rk4h.fast import force_kernel

    n2 = y0.shape[0]
    perm = interleave(n2 // 2)
    lband = uband = None
    jac_kind = "jac"
    if model.linear:
        try:
            rows, cols, vals, lband, uband = _linear_jacobian_once(model, perm)
        except Exception as exc:  # noqa: BLE001 - scikit-sundae's run reports it as its status
            return _fallback(solver_name, model, y0, t_eval, rtol, atol, max_steps,
                             f"constant Jacobian failed: {type(exc).__name__}: {exc}")
        if lband + uband + 1 < n2:
            jac_kind = None  # band solver, CVODE's difference-quotient Jacobian
        else:
            jac_kind, lband, uband = "jac_constant", None, None
    start = time.perf_counter()
    try:
        kern = force_kernel(model)
        rhs_cb = _callbacks(kern, "rhs")
        jac_cb = _callbacks(kern, jac_kind) if jac_kind else None
    except Exception as exc:  # noqa: BLE001 - no compiled callbacks: scikit-sundae's run, said in extra
        return _fallback(solver_name, model, y0, t_eval, rtol, atol, max_steps,
                         f"callbacks failed to compile: {type(exc).__name__}: {exc}")
    compile_s = time.perf_counter() - start

    m = t_eval.shape[0]
    n = n2 // 2
    y = np.full((n2, m), np.nan)
    y[:, 0] = y0
    # the callbacks' data (kept alive by these names until the run ends)
    sizes = np.array([n2, fast_rhs.fp.size, fast_rhs.ip.size, fast_rhs.w.size, 0, 0, 0], dtype=np.int64)
    perm64 = np.ascontiguousarray(perm, dtype=np.int64)
    buf = np.zeros((3, n2))
    info = np.full(1, np.nan)
    if jac_kind == "jac_constant":
        jdata = np.zeros(n2 * n2)
        jdata[cols * n2 + rows] = vals  # column-major, as SUNDIALS' dense matrix
    else:
        jdata = np.zeros((4, max(n, 1)))
    work = np.zeros_like(fast_rhs.w)  # per run: CVODE runs without the GIL, so two threads may share a model
    keep = (sizes, fast_rhs.fp, fast_rhs.ip, fast_rhs.mass, perm64, buf, work, info, jdata)
    ud = np.array([a.ctypes.data for a in keep], dtype=np.int64)
    atol_z = np.ascontiguousarray(np.asarray(atol, dtype=float)[perm])
    extra = {"atol_state": atol, "max_steps": max_steps, "rhs": "compiled", "implementation": "compiled",
             "linsolver": "dense" if jac_kind else "band", "counters": "cvode-stats"}
    if jac_kind is None:
        extra.update(lband=lband, uband=uband)

    t0 = float(t_eval[0])
    status, message, t_fail = Status.OK, f"{solver_name}: reached the end of the interval", None
    n_steps = nfev_cvode = njev = nfev_dq = 0
    k = 1
    start = time.perf_counter()
    try:
        with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
            f0 = np.asarray(model.rhs(t0, y0), dtype=float)
    except Exception as exc:  # noqa: BLE001 - scikit-sundae's run reports it as its status
        return _fallback(solver_name, model, y0, t_eval, rtol, atol, max_steps,
                         f"the right-hand side raised at the initial state: {type(exc).__name__}: {exc}")
    if not np.all(np.isfinite(f0)):
        status, t_fail = Status.UNSTABLE, t0
        message = (f"{solver_name}: the right-hand side is not finite at the initial state "
                   f"(t = {t0:.6g}); no step taken")
    else:
        try:
            (status, message, t_fail, k, n_steps, nfev_cvode, njev,
             nfev_dq) = _solve(lib, solver_name, n2, y, perm, t_eval, rtol, atol_z, max_steps, rhs_cb, jac_cb,
                               jac_kind is None, lband, uband, ud, y0, info, sizes)
        except Exception as exc:  # noqa: BLE001 - a failure inside is a status, not an exception
            status, message = Status.FAILED, f"{solver_name}: {type(exc).__name__}: {exc}"
            t_fail = float(t_eval[k - 1])
    wall = time.perf_counter() - start
    del keep
    if status is not Status.OK:
        y[:, k:] = np.nan
    calls = int(sizes[4])
    extra["njev"] = int(njev)
    extra["nfev_cvode"] = int(nfev_cvode)
    extra["nfev_jac_dq"] = int(nfev_dq)
    run = SolverRun(solver_name, rtol, t_eval, y, calls, int(n_steps), wall, status=status, message=message,
                    atol=float(atol[0]), t_fail=t_fail, extra=extra)
    run.compile_s = compile_s
    return run


def _solve(lib, solver_name, n2, y, perm, t_eval, rtol, atol_z, max_steps, rhs_cb, jac_cb, band, lband, uband,
           ud, y0, info, sizes):
    """CVODE set up as scikit-sundae sets it, one ``CV_NORMAL`` call per
    output time, every object freed on return. Returns ``(status, message,
    t_fail, k, n_steps, nfev_cvode, njev, nfev_dq)``, ``y`` filled up to
    column ``k``."""
    m = t_eval.shape[0]
    t0, t1 = float(t_eval[0]), float(t_eval[-1])
    # with two output times run_cvode asks for a midpoint more (scikit-sundae's solve steps one by one otherwise)
    t_call = t_eval if m > 2 else np.array([t0, t0 + 0.5 * (t1 - t0), t1])
    ctx, mem = _P(), _P()
    yy = atol_v = A = LS = None

    def check(flag, what):
        if flag < 0:
            raise RuntimeError(f"{what} returned flag {flag}")

    try:
        check(lib.SUNContext_Create(0, ctypes.byref(ctx)), "SUNContext_Create")
        yy = lib.N_VNew_Serial(n2, ctx)
        atol_v = lib.N_VNew_Serial(n2, ctx)
        if not yy or not atol_v:
            raise MemoryError("N_VNew_Serial returned NULL")
        zv = np.ctypeslib.as_array((_D * n2).from_address(lib.N_VGetArrayPointer(yy)))
        zv[:] = y0[perm]
        np.ctypeslib.as_array((_D * n2).from_address(lib.N_VGetArrayPointer(atol_v)))[:] = atol_z
        mem.value = lib.CVodeCreate(CV_ADAMS if solver_name == "cvode-adams" else CV_BDF, ctx)
        if not mem.value:
            raise MemoryError("CVodeCreate returned NULL")
        check(lib.CVodeSetUserData(mem, ud.ctypes.data), "CVodeSetUserData")
        check(lib.CVodeInit(mem, rhs_cb.address, t0, yy), "CVodeInit")
        check(lib.CVodeSVtolerances(mem, rtol, atol_v), "CVodeSVtolerances")
        if band:
            A = lib.SUNBandMatrix(n2, uband, lband, ctx)
            LS = lib.SUNLinSol_Band(yy, A, ctx) if A else None
        else:
            A = lib.SUNDenseMatrix(n2, n2, ctx)
            LS = lib.SUNLinSol_Dense(yy, A, ctx) if A else None
        if not A or not LS:
            raise MemoryError("SUNMatrix or SUNLinearSolver constructor returned NULL")
        check(lib.CVodeSetLinearSolver(mem, LS, A), "CVodeSetLinearSolver")
        if jac_cb is not None:
            check(lib.CVodeSetJacFn(mem, jac_cb.address), "CVodeSetJacFn")
        check(lib.CVodeSetMaxNonlinIters(mem, 3), "CVodeSetMaxNonlinIters")
        check(lib.CVodeSetMaxConvFails(mem, 10), "CVodeSetMaxConvFails")
        lib.SUNContext_ClearErrHandlers(ctx)
        logger = _P()  # CVODE's warnings ("t + h = t ...") go to the C stdout unless switched off
        if lib.SUNContext_GetLogger(ctx, ctypes.byref(logger)) == 0 and logger.value:
            lib.SUNLogger_SetWarningFilename(logger, b"")
        check(lib.CVodeSetInitStep(mem, 0.0), "CVodeSetInitStep")
        check(lib.CVodeSetMinStep(mem, 0.0), "CVodeSetMinStep")
        check(lib.CVodeSetMaxStep(mem, 0.0), "CVodeSetMaxStep")
        check(lib.CVodeSetMaxOrd(mem, 12 if solver_name == "cvode-adams" else 5), "CVodeSetMaxOrd")
        check(lib.CVodeSetMaxNumSteps(mem, max_steps), "CVodeSetMaxNumSteps")
        check(lib.CVodeSetStopTime(mem, float(t_call[-1])), "CVodeSetStopTime")

        out = _L()
        tret = _D()

        def stat(name):
            check(getattr(lib, name)(mem, ctypes.byref(out)), name)
            return int(out.value)

        # scikit-sundae's _normal_solve: outputs until the last time, tstop or a failure
        mc = t_call.shape[0]
        tt, zz = [t0], [zv.copy()]
        capped = False
        flag = 0
        for ind in range(1, mc):
            left = max_steps - stat("CVodeGetNumSteps")
            if left <= 0:
                check(lib.CVodeGetCurrentTime(mem, ctypes.byref(tret)), "CVodeGetCurrentTime")
                if t_call[ind] > tret.value:  # needs a step more than the cap allows
                    capped, flag = True, CV_TOO_MUCH_WORK
                    tt.append(tret.value)
                    zz.append(zv.copy())
                    break
                left = 1  # an interpolation inside the last step takes none
            check(lib.CVodeSetMaxNumSteps(mem, left), "CVodeSetMaxNumSteps")
            flag = lib.CVode(mem, float(t_call[ind]), yy, ctypes.byref(tret), CV_NORMAL)
            tt.append(tret.value)
            zz.append(zv.copy())
            if flag < 0 or flag == 1 or ind == mc - 1:  # error, CV_TSTOP_RETURN or the last output
                break
        tt, zz = np.array(tt), np.array(zz)
        success = flag >= 0
        zz, k, status, t_fail, message = solve_outputs(
            solver_name, tt, zz, t_eval, t_call, success, flag, lambda: _cv_message(flag),
            f"{solver_name}: reached the end of the interval")
        capped = capped or (status is Status.FAILED and not success and flag == CV_TOO_MUCH_WORK)
        y[perm, 1:k] = zz[1:k].T
        n_steps = stat("CVodeGetNumSteps")
        nfev_cvode, njev = stat("CVodeGetNumRhsEvals"), stat("CVodeGetNumJacEvals")
        nfev_dq = stat("CVodeGetNumLinRhsEvals")
        if nfev_cvode + nfev_dq != int(sizes[4]) or (jac_cb is not None and njev != int(sizes[6])):
            raise RuntimeError(f"CVODE's counters (nfe {nfev_cvode} + {nfev_dq}, nje {njev}) differ from the "
                               f"callbacks' (rhs {int(sizes[4])}, jac {int(sizes[6])})")
        if status is Status.FAILED:  # run_cvode's messages
            if int(sizes[5]) != 0:
                status = Status.UNSTABLE
                message = (f"{solver_name}: the right-hand side became non-finite at t = {info[0]:.6g} "
                           f"(a state where the force is undefined?)")
                if not success:
                    message += f"; CVODE flag {flag} at t = {t_fail:.6g}: {_cv_message(flag)}"
            elif capped:
                message = f"{solver_name}: step cap max_steps = {max_steps} reached at t = {t_fail:.6g}"
            elif not success:
                message = f"{solver_name}: CVODE flag {flag} at t = {t_fail:.6g}: {_cv_message(flag)}"
        return status, message, t_fail, k, n_steps, nfev_cvode, njev, nfev_dq
    finally:
        if mem.value:
            lib.CVodeFree(ctypes.byref(mem))
        if LS:
            lib.SUNLinSolFree(LS)
        if A:
            lib.SUNMatDestroy(A)
        if atol_v:
            lib.N_VDestroy(atol_v)
        if yy:
            lib.N_VDestroy(yy)
        if ctx.value:
            lib.SUNContext_Free(ctypes.byref(ctx))


def _cv_message(flag: int) -> str:
    """scikit-sundae's text for CVODE's return flag (its ``CVMESSAGES``)."""
    try:
        from sksundae._cy_cvode import CVMESSAGES

        return CVMESSAGES.get(flag, f"CVODE flag {flag}")
    except Exception:  # noqa: BLE001 - another scikit-sundae: the number alone
        return f"CVODE flag {flag}"
