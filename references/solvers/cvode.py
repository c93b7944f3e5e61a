"""SUNDIALS CVODE (``sksundae.cvode.CVODE``): variable-order Adams (``cvode-adams``,
orders 1-12) and BDF (``cvode-bdf``, orders 1-5), both with Newton iteration.

Every option that matters is set explicitly (scikit-sundae's defaults are BDF,
rtol 1e-5, atol 1e-6 and 500 steps per output): ``method``, ``rtol``, ``atol``
(the vector of :mod:`rk4h.references.solvers.tolerances`), ``max_num_steps`` and the
linear solver (dense with an analytic Jacobian, or banded with CVODE's own
banded difference-quotient Jacobian).

State ordering and linear algebra
---------------------------------
CVODE integrates the interleaved state ``z = [q1, v1, q2, v2, ...]``. For a
linear model the Jacobian ``[[0, I], [-M^-1 K, 0]]`` is constant and is built
once from ``model.stiffness_matrix(sparse=True)`` (dense ``K`` for models
without a sparse form); when ``K`` has half-bandwidth ``b`` the interleaved
Jacobian has lower bandwidth ``2b + 1`` and upper bandwidth ``max(1, 2b - 1)``
-- 3 and 1 for a chain -- and the banded direct solver is used, so that the cost
per step grows linearly with N. The banded path deliberately passes no
``jacfn``: scikit-sundae 1.2 hands a user Jacobian a dense (2N)^2 array even
for the band solver (588 MB at N = 4000, ~320 GB at N = 1e5), while CVODE's
banded difference quotient costs ``lband + uband + 1`` = 5 RHS calls per
Jacobian and O(N) memory. Nonlinear models (at most 6 DOF here) use the
dense solver and ``model.jacobian(t, y)`` (central differences of the force:
two vectorised force evaluations per Jacobian, not included in ``nfev``).

How the run is driven
---------------------
One ``CVODE.solve(t_eval, z0)`` call: scikit-sundae loops over the output
times in C with ``CV_NORMAL`` (CVODE steps past each output time and
interpolates there) and ``tstop = t_eval[-1]``. Only the right-hand side (and
the dense Jacobian) is called from C into Python. A Python loop of
``CV_ONE_STEP`` calls (this module until issue 12, still here as the fallback
below) takes the same internal steps at 2-5x the wall time:
``python benchmarks/bench_cvode.py`` measured 3.5x in total (median of 5,
per row 1.9-4.9x) over the CVODE runs of three shipped scenes.

The right-hand side's glue
--------------------------
scikit-sundae 1.2 takes no compiled callback: its Cython wrapper makes two
ndarrays from CVODE's vectors and calls ``rhsfn(t, z, zp)`` (and ``jacfn``)
as Python objects, for every evaluation. So the CVODE rows time scikit-sundae
with a compiled right-hand side called from Python, as a user would run it.
What is ours per call is kept small: one Python frame (``rhsfn_compiled``:
the count, the step-cap test, the call) that calls the model's compiled
right-hand side (:meth:`rk4h.fast.CompiledRHS.permuted_parts`) through the
numba entry point of the argument types scikit-sundae passes, picked at the
run's first call (:func:`rk4h.fast.solve.compiled_entry`: numba's per-call type resolution
of 8 arguments skipped). The constant dense Jacobian of a linear model is
written once into the array scikit-sundae passes (it is the same array at
every call and is only copied into CVODE's matrix). The numbers are those of
the earlier glue bit for bit (``tests/test_cvode_glue.py``);
``python benchmarks/bench_cvode.py --per-call`` prints where a call's time
goes (most of it is scikit-sundae's wrapper and CVODE itself).

Counters
--------
CVODE's own statistics are read with the SUNDIALS C API (``CVodeGetNumSteps``,
``CVodeGetNumRhsEvals``, ``CVodeGetNumLinRhsEvals``, ``CVodeGetNumJacEvals``)
through ``ctypes`` on the ``libsundials_cvode`` that scikit-sundae loaded:
scikit-sundae 1.2's ``CVODEResult`` holds only ``nfev`` and ``njev``, and no
step count, and keeps CVODE's memory pointer private. The pointer is read from
the solver object at the offset its declared layout gives, and used only when
that layout is confirmed (object size, the options dict and the ``AuxData``
object found at their offsets, the system size, the ``SUNContext`` at the head
of the CVODE memory); otherwise, or when the library is not found, the run
falls back to the one-step loop below. After the solve, CVODE's ``nfe`` and
``nje`` read this way must equal the result's ``nfev`` and ``njev``.

- ``n_steps``: ``CVodeGetNumSteps``, CVODE's successful internal steps (failed
  attempts and output interpolations are not steps).
- ``nfev``: every call of the right-hand side, counted by the wrapper CVODE
  calls. It equals ``extra["nfev_cvode"]`` (``CVodeGetNumRhsEvals``: the
  integrator's calls, including the initial call and the first-step
  estimate, which scikit-sundae reports as ``nfev``) plus
  ``extra["nfev_jac_dq"]`` (``CVodeGetNumLinRhsEvals``: the calls spent on
  banded difference-quotient Jacobians, ``lband + uband + 1`` each, which
  scikit-sundae's ``nfev`` leaves out); 0 with an analytic Jacobian.
- ``extra["njev"]``: Jacobian evaluations (``CVodeGetNumJacEvals``, analytic
  or difference quotient).
- ``extra["counters"]``: ``"cvode-stats"``, or ``"one-step-loop"`` for the
  fallback, where ``n_steps`` is counted by the loop and ``nfev_jac_dq`` is
  ``nfev - nfev_cvode``.

Step cap
--------
``max_steps`` caps the total number of internal steps of the run, as before
issue 12: a run that needs more ends FAILED ("step cap max_steps = ... reached
at t = ...") with ``n_steps == max_steps`` and the outputs reached so far.
CVODE's own ``max_num_steps`` counts steps per output interval (per
``CV_NORMAL`` call); it is set to ``max_steps`` too, so it never binds first.
The total cap is enforced from the right-hand-side wrapper: every step makes
at least one RHS call, so steps can reach ``max_steps`` only after
``max_steps - nst`` more calls than at the last reading ``nst`` of
``CVodeGetNumSteps``; the wrapper reads it again only then (a handful of
readings per run). At the first RHS call of step ``max_steps + 1`` it returns
NaN, from then on: CVODE rejects every further attempt (its error and
convergence tests are false on NaN) and stops within a bounded number of
calls (10 convergence failures), at the time of step ``max_steps``.
The fallback loop counts its steps itself and stops before step
``max_steps + 1``.

Failures
--------
A non-finite right-hand side at the initial state ends the run before CVODE
starts (UNSTABLE); a run that met a non-finite right-hand side at a finite
state and then failed is UNSTABLE too (a singular state reached mid-run), as
is a run whose output state is not finite. Any other CVODE error flag is
FAILED with CVODE's message; ``y`` keeps every output reached before the
failure (``solve`` returns them), ``t_fail`` is CVODE's last internal time.
An exception inside (a Python error in a model's ``rhs``) is FAILED too; then
``solve`` returns no partial trajectory and ``y`` is NaN after ``t_eval[0]``.

Fallback: the one-step loop
---------------------------
``CV_ONE_STEP`` calls up to ``tstop = t_end`` (towards the next output time,
so that CVODE's first-step estimate sees the same ``tout`` as in ``solve``)
and the output times that fall in each step read from CVODE's interpolant
(``CV_NORMAL`` towards a time already passed), which is what ``CV_NORMAL``
does internally: the same internal steps and outputs as ``solve``. (After
such an interpolation CVODE's next ``CV_ONE_STEP`` call returns the current
internal time without stepping; it is not counted.) ``tests/test_cvode_solve.py``
checks that both paths give the same counters and trajectories.

References
----------
A. C. Hindmarsh et al., "SUNDIALS: Suite of nonlinear and differential/algebraic
equation solvers", ACM TOMS 31 (2005) 363-396. SUNDIALS CVODE user guide,
"Optional output functions" (``CVodeGetNumSteps``, ``CVodeGetNumLinRhsEvals``).
"""
from __future__ import annotations

import ctypes
import functools
import gc
import glob
import os
import time

import numpy as np

from rk4h.fast.solve import compiled_entry, plain_vector

from .base import SolverRun, Status, compiled_rhs

__all__ = ["run_cvode", "interleave", "linear_jacobian", "DEFAULT_MAX_STEPS"]

#: Default cap on the total number of CVODE steps in one run.
DEFAULT_MAX_STEPS = 5_000_000

#: CVODE statistics read through its C API (``int f(void *cvode_mem, long *out)``).
_STATS = ("CVodeGetNumSteps", "CVodeGetNumRhsEvals", "CVodeGetNumLinRhsEvals", "CVodeGetNumJacEvals")
#: The C attributes of ``sksundae._cy_cvode.CVODE`` (scikit-sundae 1.1-1.2), in
#: declaration order, one pointer-sized slot each after the object header and
#: the Cython vtable pointer.
_LAYOUT = ("mem", "ctx", "atol", "constraints", "yy", "A", "LS", "NEQ", "aux", "_size", "_malloc",
           "_options", "_initialized")


class _NonFiniteStart(Exception):
    """The right-hand side is not finite at the initial state."""


def interleave(n_dof: int) -> np.ndarray:
    """Permutation ``p`` with ``z = y[p] = [q1, v1, q2, v2, ...]`` for ``y = [q, v]``."""
    p = np.empty(2 * n_dof, dtype=np.intp)
    p[0::2] = np.arange(n_dof)
    p[1::2] = np.arange(n_dof) + n_dof
    return p


#: Up to this many degrees of freedom :func:`linear_jacobian` builds the
#: Jacobian dense (no scipy.sparse import); above it, sparse.
_DENSE_JACOBIAN_MAX = 64


def linear_jacobian(model, perm: np.ndarray):
    """Constant Jacobian of a linear model in the order ``perm``.

    Returns
    -------
    rows, cols, vals : ndarray
        Its non-zero entries (COO).
    lband, uband : int
        Lower and upper bandwidths.
    """
    n = model.n_dof
    if n <= _DENSE_JACOBIAN_MAX:
        # dense: the same products (1/m_i) K_ij, without scipy.sparse
        K = model.stiffness_matrix()
        K = np.asarray(K.toarray() if hasattr(K, "toarray") else K, dtype=float)  # a user's model may give sparse
        J = np.zeros((2 * n, 2 * n))
        J[:n, n:] = np.eye(n)
        J[n:, :n] = -((1.0 / model.mass)[:, None] * K)
        r, c = np.nonzero(J)
        vals = J[r, c]
    else:
        import scipy.sparse as sp

        try:
            K = model.stiffness_matrix(sparse=True)
        except TypeError:
            K = model.stiffness_matrix()
        K = sp.csr_matrix(K, dtype=float)
        A = sp.diags(1.0 / model.mass) @ K
        Jc = sp.bmat([[None, sp.identity(n)], [-A, None]], format="csr").tocoo()
        keep = Jc.data != 0.0
        r, c, vals = Jc.row[keep], Jc.col[keep], Jc.data[keep]
    inv = np.empty_like(perm)  # entry (r, c) of J is entry (inv[r], inv[c]) in the order perm
    inv[perm] = np.arange(perm.size)
    rows, cols = inv[r], inv[c]
    lband = int(max(0, np.max(rows - cols))) if rows.size else 0
    uband = int(max(0, np.max(cols - rows))) if rows.size else 0
    return rows, cols, vals, lband, uband


def solve_outputs(solver_name: str, tt, zz, t_eval, t_call, success: bool, flag: int, flag_message, message: str):
    """What CVODE's ``CV_NORMAL`` outputs ``tt``, ``zz`` (one row per time,
    the times ``t_call``; on a failure the last row is CVODE's last internal
    time and state, as scikit-sundae's ``solve`` returns them) say at the
    output times ``t_eval``: the shared post-processing of :func:`run_cvode`
    and the compiled runner's.

    With two output times the interpolated midpoint asked for in ``t_call``
    is dropped. Returns ``(zz, k, status, t_fail, message)``: ``k`` outputs
    reached with finite states; ``UNSTABLE`` at the first non-finite one;
    ``FAILED`` at CVODE's last time when it returned ``flag < 0``
    (``message`` left for the caller to word), or at the last output
    reached when CVODE stopped early (``flag_message()``, called only then,
    gives CVODE's text for ``flag``)."""
    m = t_eval.shape[0]
    if m == 2 and tt.shape[0] >= 2 and tt[1] == t_call[1]:
        tt, zz = np.delete(tt, 1), np.delete(zz, 1, axis=0)
    status, t_fail = Status.OK, None
    n_out = min(m, tt.shape[0] - (0 if success else 1))
    at = tt[:n_out] == t_eval[:n_out]
    k = n_out if at.all() else int(np.argmin(at))
    finite = np.all(np.isfinite(zz[:k]), axis=1)
    if not finite.all():
        k = int(np.argmin(finite))
        status, t_fail = Status.UNSTABLE, float(t_eval[k])
        message = f"{solver_name}: state became non-finite at t = {t_fail:.6g}"
    elif not success:
        status, t_fail = Status.FAILED, float(tt[-1])
    elif k < m:
        status, t_fail = Status.FAILED, float(tt[k - 1])
        message = (f"{solver_name}: CVODE stopped at t = {t_fail:.6g} before the last output "
                   f"(flag {flag}: {flag_message()})")
    return zz, k, status, t_fail, message


def _linear_jacobian_once(model, perm: np.ndarray):
    """:func:`linear_jacobian` for the interleaved order (``perm`` =
    :func:`interleave`), built once per model (``Model.constant``); the
    arrays are read-only."""
    if not np.array_equal(perm, interleave(model.n_dof)):
        return linear_jacobian(model, perm)

    def build():
        rows, cols, vals, lband, uband = linear_jacobian(model, perm)
        for a in (rows, cols, vals):
            a.setflags(write=False)
        return rows, cols, vals, lband, uband

    return model.constant("cvode_linear_jacobian", build)


def _options(model, perm, method, rtol, atol, max_steps):
    n2 = perm.size
    opts = dict(method=method, rtol=rtol, atol=atol[perm], max_num_steps=max_steps)
    y = np.empty(n2)
    if model.linear:
        rows, cols, vals, lband, uband = _linear_jacobian_once(model, perm)
        filled = [None]

        def jacfn(t, z, zp, JJ):
            # constant: scikit-sundae passes the same array every call and only
            # copies it into CVODE's matrix, so it is written once
            if JJ is not filled[0]:
                JJ[rows, cols] = vals
                filled[0] = JJ

        jacfn.constant = True  # no cap check needed (_run_cvode)
        if lband + uband + 1 < n2:
            opts.update(linsolver="band", lband=lband, uband=uband)
            return opts  # CVODE's banded difference quotient: see the module docstring
        opts.update(linsolver="dense")
    else:
        ix = np.ix_(perm, perm)

        def jacfn(t, z, zp, JJ):
            y[perm] = z
            JJ[:, :] = model.jacobian(t, y)[ix]

        opts.update(linsolver="dense")
    opts["jacfn"] = jacfn
    return opts


@functools.lru_cache(maxsize=1)
def _cvode_library():
    """A ``ctypes`` handle on the ``libsundials_cvode`` scikit-sundae loaded
    (found in the process's memory map, else beside the package), or None."""
    import sksundae
    import sksundae._cy_cvode  # noqa: F401 - loads the library

    paths = []
    try:
        with open("/proc/self/maps") as fh:
            for line in fh:
                parts = line.split(maxsplit=5)
                if len(parts) == 6 and "sundials_cvode" in os.path.basename(parts[5].strip()):
                    path = parts[5].strip()
                    if path not in paths:
                        paths.append(path)
    except OSError:
        pass
    if not paths:
        root = os.path.dirname(sksundae.__file__)
        for pattern in ("../scikit_sundae.libs/*sundials_cvode*", ".dylibs/*sundials_cvode*"):
            paths += sorted(glob.glob(os.path.join(root, pattern)))
    for path in paths:
        try:
            lib = ctypes.CDLL(path)
            for name in _STATS:
                fn = getattr(lib, name)
                fn.argtypes = (ctypes.c_void_p, ctypes.POINTER(ctypes.c_long))
                fn.restype = ctypes.c_int
        except (OSError, AttributeError):
            continue
        return lib
    return None


class _CvodeStats:
    """CVODE's counters of one solver, read through the SUNDIALS C API."""

    def __init__(self, lib, mem: int):
        self._mem = ctypes.c_void_p(mem)
        self._out = ctypes.c_long()
        self._fns = {name: getattr(lib, name) for name in _STATS}

    def get(self, name: str) -> int:
        flag = self._fns[name](self._mem, ctypes.byref(self._out))
        if flag != 0:
            raise RuntimeError(f"{name} returned flag {flag}")
        return int(self._out.value)

    def steps(self) -> int:
        return self.get("CVodeGetNumSteps")

    @classmethod
    def attach(cls, solver, rhsfn, n_eq: int):
        """The statistics of ``solver`` (a ``CVODE`` after ``init_step``, built
        with ``rhsfn`` for ``n_eq`` equations), or None unless its memory
        layout is confirmed (see the module docstring)."""
        inner = getattr(solver, "_CVODE__CVODE", None)
        ptr = ctypes.sizeof(ctypes.c_void_p)
        base = object.__basicsize__ + ptr  # the object header, then Cython's vtable pointer
        if inner is None or type(inner).__basicsize__ != base + ptr * len(_LAYOUT):
            return None

        def field(name, ctype=ctypes.c_void_p):
            return ctype.from_address(id(inner) + base + ptr * _LAYOUT.index(name)).value

        refs = gc.get_referents(inner)
        opts = [r for r in refs if type(r) is dict and r.get("rhsfn") is rhsfn]
        aux = [r for r in refs if type(r).__name__ == "AuxData"]
        if len(opts) != 1 or field("_options") != id(opts[0]) or len(aux) != 1 or field("aux") != id(aux[0]):
            return None
        if ptr != 8 or field("NEQ", ctypes.c_int64) != n_eq:
            return None
        mem, ctx = field("mem"), field("ctx")
        if not mem or not ctx or ctypes.c_void_p.from_address(mem).value != ctx:
            return None  # CVODE's memory record starts with its SUNContext
        lib = _cvode_library()
        if lib is None:
            return None
        stats = cls(lib, mem)
        try:
            fresh = all(stats.get(name) == 0 for name in _STATS)
        except RuntimeError:
            return None
        return stats if fresh else None


def run_cvode(solver_name: str, model, y0: np.ndarray, t_eval: np.ndarray, rtol: float,
              atol: np.ndarray, max_steps: int = DEFAULT_MAX_STEPS) -> SolverRun:
    """Integrate ``model`` with CVODE (``solver_name`` ``"cvode-adams"`` or
    ``"cvode-bdf"``) in one ``solve`` call over ``t_eval``; never raises. See
    the module docstring for the counters and the step cap."""
    return _run_cvode(solver_name, model, y0, t_eval, rtol, atol, max_steps)


def _run_cvode(solver_name, model, y0, t_eval, rtol, atol, max_steps, one_step_loop=False) -> SolverRun:
    """:func:`run_cvode`; ``one_step_loop=True`` forces the fallback (for
    tests and ``benchmarks/bench_cvode.py``)."""
    from sksundae.cvode import CVODE

    method = {"cvode-adams": "Adams", "cvode-bdf": "BDF"}[solver_name]
    n2, m = y0.shape[0], t_eval.shape[0]
    # a first-order model's state is not [q, v]: nothing to interleave
    perm = np.arange(n2) if getattr(model, "first_order", False) else interleave(n2 // 2)
    y = np.full((n2, m), np.nan)
    y[:, 0] = y0
    ybuf = np.empty(n2)
    nan = np.nan

    calls = 0           # every right-hand-side call
    next_check = max_steps  # the step count can reach max_steps only from this call on
    capped = False      # the step cap was reached: the wrapper returns NaN
    stats = None
    bad = []  # time of the first non-finite right-hand side at a finite state
    fast_rhs = compiled_rhs(model)
    permuted = call = None
    if fast_rhs is not None and hasattr(fast_rhs, "permuted_parts"):
        call, fp, ip, mass, perm64, buf, w = fast_rhs.permuted_parts(perm)
        next_check = 1  # the first call picks the compiled entry (over_cap)
    elif fast_rhs is not None:
        permuted = fast_rhs.permuted(perm)

    def over_cap(z=None, zp=None):
        """Reads CVODE's step count when it may have reached ``max_steps``
        (every step makes >= 1 call; module docstring, "Step cap"). At the
        first call of the compiled path, first picks the compiled entry for
        the arrays scikit-sundae passes (:func:`rk4h.fast.solve.compiled_entry`)."""
        nonlocal next_check, capped, call
        if calls == 1 and next_check == 1:
            next_check = max_steps
            if call is not None and plain_vector(z, n2) and plain_vector(zp, n2):
                call = compiled_entry(call, (fp, ip, mass, z, zp, perm64, buf, w))
            if calls < next_check:
                return False
        if capped:
            return True
        if stats is None:  # the one-step loop counts its own steps
            next_check = 1 << 62
            return False
        nst = stats.steps()
        if nst >= max_steps:
            capped = True
            return True
        next_check = calls + (max_steps - nst)
        return False

    def rhsfn_compiled(t, z, zp):
        # one Python frame per call: the compiled right-hand side is called
        # with its constant arguments bound here
        nonlocal calls
        calls += 1
        if calls >= next_check and over_cap(z, zp):
            zp.fill(nan)
            return
        if call(fp, ip, mass, z, zp, perm64, buf, w) and not bad:
            bad.append(float(t))

    def rhsfn(t, z, zp):
        nonlocal calls
        calls += 1
        if calls >= next_check and over_cap():
            zp.fill(nan)
            return
        if permuted is not None:
            if permuted(z, zp) and not bad:
                bad.append(float(t))
            return
        ybuf[perm] = z
        f = model.rhs(t, ybuf)
        if not bad and not np.all(np.isfinite(f)) and np.all(np.isfinite(z)):
            bad.append(float(t))
        zp[:] = f[perm]

    cvode_rhs = rhsfn_compiled if call is not None else rhsfn

    t0, t1, tn = float(t_eval[0]), float(t_eval[-1]), float(t_eval[0])
    n_steps, k, nfev_cvode, njev, nfev_dq = 0, 1, 0, 0, None
    status, message, t_fail = Status.OK, f"{solver_name}: reached the end of the interval", None
    extra = {"atol_state": atol, "max_steps": max_steps, "rhs": "compiled" if fast_rhs is not None else "numpy"}
    start = time.perf_counter()
    try:
        with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
            f0 = np.asarray(model.rhs(t0, y0), dtype=float)
        if not np.all(np.isfinite(f0)):
            raise _NonFiniteStart(f"{solver_name}: the right-hand side is not finite at the initial state "
                                  f"(t = {t0:.6g}); no step taken")
        opts = _options(model, perm, method, rtol, atol, max_steps)
        extra.update({key: opts[key] for key in ("linsolver", "lband", "uband") if key in opts})
        if "jacfn" in opts and not getattr(opts["jacfn"], "constant", False):
            jac = opts["jacfn"]

            def jacfn(t, z, zp, JJ):
                if not capped:  # past the cap the Jacobian no longer matters
                    jac(t, z, zp, JJ)

            opts["jacfn"] = jacfn
        solver = CVODE(cvode_rhs, **opts)
        solver.init_step(t0, y0[perm])
        if not one_step_loop:
            stats = _CvodeStats.attach(solver, cvode_rhs, n2)
        extra["counters"] = "cvode-stats" if stats is not None else "one-step-loop"
        with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
            if stats is not None:
                # With two output times scikit-sundae returns every internal step; one
                # interpolated midpoint more (dropped below) keeps the outputs and the steps.
                t_call = t_eval if m > 2 else np.array([t0, t0 + 0.5 * (t1 - t0), t1])
                res = solver.solve(t_call, y0[perm])
                tt, zz = np.asarray(res.t, dtype=float), np.asarray(res.y, dtype=float)
                zz, k, status, t_fail, message = solve_outputs(
                    solver_name, tt, zz, t_eval, t_call, res.success, res.status, lambda: res.message, message)
                # CV_TOO_MUCH_WORK: max_num_steps = max_steps steps in one output interval
                capped = capped or (status is Status.FAILED and not res.success and res.status == -1)
                y[perm, 1:k] = zz[1:k].T
                n_steps = stats.steps()
                nfev_cvode, njev = stats.get("CVodeGetNumRhsEvals"), stats.get("CVodeGetNumJacEvals")
                nfev_dq = stats.get("CVodeGetNumLinRhsEvals")
                if (nfev_cvode, njev) != (res.nfev, res.njev):
                    raise RuntimeError(f"CVODE's counters read through ctypes (nfe {nfev_cvode}, nje {njev}) "
                                       f"differ from scikit-sundae's (nfev {res.nfev}, njev {res.njev})")
                if status is Status.OK or res.success:
                    res = None  # no CVODE failure to report
            else:
                res = None
                while k < m:
                    if n_steps >= max_steps:
                        capped = True
                        status, t_fail = Status.FAILED, tn
                        break
                    # towards the next output (CVODE's first-step estimate uses it, as in solve)
                    out = solver.step(float(t_eval[k]), method="onestep", tstop=t1)
                    nfev_cvode, njev = out.nfev, out.njev
                    if not out.success:
                        res, status, t_fail = out, Status.FAILED, float(out.t)
                        break
                    if float(out.t) == tn:
                        # After an interpolated output CV_ONE_STEP first returns the
                        # current internal time without stepping (tretlast < tn).
                        continue
                    n_steps += 1
                    tn = float(out.t)
                    if not np.all(np.isfinite(out.y)):
                        status, t_fail = Status.UNSTABLE, tn
                        message = f"{solver_name}: state became non-finite at t = {tn:.6g}"
                        break
                    while k < m and t_eval[k] <= tn:
                        if t_eval[k] == tn:
                            y[perm, k] = out.y
                        else:  # inside the last step: CVODE interpolates, no new step
                            dense = solver.step(float(t_eval[k]), method="normal")
                            if not dense.success:
                                raise RuntimeError(f"interpolation at t = {t_eval[k]}: {dense.message}")
                            y[perm, k] = dense.y
                        k += 1
                nfev_dq = calls - nfev_cvode
        if status is Status.FAILED:
            if bad:
                status = Status.UNSTABLE
                message = (f"{solver_name}: the right-hand side became non-finite at t = {bad[0]:.6g} "
                           f"(a state where the force is undefined?)")
                if res is not None:
                    message += f"; CVODE flag {res.status} at t = {t_fail:.6g}: {res.message}"
            elif capped:
                message = f"{solver_name}: step cap max_steps = {max_steps} reached at t = {t_fail:.6g}"
            elif res is not None:
                message = f"{solver_name}: CVODE flag {res.status} at t = {t_fail:.6g}: {res.message}"
    except _NonFiniteStart as exc:
        status, message, t_fail = Status.UNSTABLE, str(exc), t0
    except Exception as exc:  # noqa: BLE001 - a failure inside is a status, not an exception
        status = Status.FAILED
        message = f"{solver_name}: {type(exc).__name__}: {exc}"
        if capped:
            message = f"{solver_name}: step cap max_steps = {max_steps} reached; then {type(exc).__name__}: {exc}"
        t_fail = float(t_eval[k - 1]) if k > 0 else t0
        if stats is not None:
            try:
                n_steps = stats.steps()
                nfev_cvode, njev = stats.get("CVodeGetNumRhsEvals"), stats.get("CVodeGetNumJacEvals")
                nfev_dq = stats.get("CVodeGetNumLinRhsEvals")
            except RuntimeError:
                pass
    wall = time.perf_counter() - start
    if status is not Status.OK:
        y[:, k:] = np.nan
    extra["njev"] = int(njev)
    extra["nfev_cvode"] = int(nfev_cvode)
    extra["nfev_jac_dq"] = int(calls - nfev_cvode if nfev_dq is None else nfev_dq)
    return SolverRun(solver_name, rtol, t_eval, y, int(calls), int(n_steps), wall, status=status,
                     message=message, atol=float(atol[0]), t_fail=t_fail, extra=extra)
