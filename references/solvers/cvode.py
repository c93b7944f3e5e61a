"""SUNDIALS CVODE (``sksundae.cvode.CVODE``): variable-order Adams (``cvode-adams``,
orders 1-12) and BDF (``cvode-bdf``, orders 1-5), both with Newton iteration.

Every option that matters is set explicitly (scikit-sundae's defaults are BDF,
rtol 1e-5, atol 1e-6 and 500 steps per output): ``method``, ``rtol``, ``atol``
(the vector of :mod:`references.solvers.tolerances`), ``max_num_steps`` and the
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

Counters
--------
``nfev`` counts every call of the right-hand side, including those CVODE spends
on banded difference-quotient Jacobians (counted by the wrapper that CVODE
calls; CVODE's own ``CVodeGetNumRhsEvals``, which leaves those out, is
``extra["nfev_cvode"]``). ``extra["njev"]`` counts Jacobian evaluations.
A non-finite right-hand side at the initial state ends the run before CVODE
starts (UNSTABLE); a run that met a non-finite right-hand side at a finite
state and then failed is UNSTABLE too (a singular state reached mid-run). ``n_steps`` counts
internal steps: the run advances with ``CV_ONE_STEP`` up to ``tstop = t_end``
and reads the output times that fall in each step from CVODE's interpolant
(``CV_NORMAL`` towards a time already passed), which is what ``CV_NORMAL``
mode does internally. (After such an interpolation CVODE's next ``CV_ONE_STEP``
call returns the current internal time without stepping; it is not counted.) ``max_steps`` caps the total number of internal steps
(not steps per output interval).

References
----------
A. C. Hindmarsh et al., "SUNDIALS: Suite of nonlinear and differential/algebraic
equation solvers", ACM TOMS 31 (2005) 363-396.
"""
from __future__ import annotations

import time

import numpy as np
import scipy.sparse as sp

from .base import SolverRun, Status, compiled_rhs

__all__ = ["run_cvode", "interleave", "linear_jacobian", "DEFAULT_MAX_STEPS"]

#: Default cap on the total number of CVODE steps in one run.
DEFAULT_MAX_STEPS = 5_000_000


class _NonFiniteStart(Exception):
    """The right-hand side is not finite at the initial state."""


def interleave(n_dof: int) -> np.ndarray:
    """Permutation ``p`` with ``z = y[p] = [q1, v1, q2, v2, ...]`` for ``y = [q, v]``."""
    p = np.empty(2 * n_dof, dtype=np.intp)
    p[0::2] = np.arange(n_dof)
    p[1::2] = np.arange(n_dof) + n_dof
    return p


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
    try:
        K = model.stiffness_matrix(sparse=True)
    except TypeError:
        K = model.stiffness_matrix()
    K = sp.csr_matrix(K, dtype=float)
    A = sp.diags(1.0 / model.mass) @ K
    J = sp.bmat([[None, sp.identity(n)], [-A, None]], format="csr")
    inv = np.empty_like(perm)
    inv[perm] = np.arange(perm.size)
    Jc = J.tocoo()
    rows, cols = inv[Jc.row], inv[Jc.col]
    keep = Jc.data != 0.0
    rows, cols, vals = rows[keep], cols[keep], Jc.data[keep]
    lband = int(max(0, np.max(rows - cols))) if rows.size else 0
    uband = int(max(0, np.max(cols - rows))) if rows.size else 0
    return rows, cols, vals, lband, uband


def _options(model, perm, method, rtol, atol, max_steps):
    n2 = 2 * model.n_dof
    opts = dict(method=method, rtol=rtol, atol=atol[perm], max_num_steps=max_steps)
    y = np.empty(n2)
    if model.linear:
        rows, cols, vals, lband, uband = linear_jacobian(model, perm)

        def jacfn(t, z, zp, JJ):
            JJ[rows, cols] = vals

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


def run_cvode(solver_name: str, model, y0: np.ndarray, t_eval: np.ndarray, rtol: float,
              atol: np.ndarray, max_steps: int = DEFAULT_MAX_STEPS) -> SolverRun:
    """Integrate ``model`` with CVODE (``solver_name`` ``"cvode-adams"`` or
    ``"cvode-bdf"``); never raises."""
    from sksundae.cvode import CVODE

    method = {"cvode-adams": "Adams", "cvode-bdf": "BDF"}[solver_name]
    n2, m = y0.shape[0], t_eval.shape[0]
    perm = interleave(n2 // 2)
    y = np.full((n2, m), np.nan)
    y[:, 0] = y0
    ybuf = np.empty(n2)

    calls = [0]
    bad = []  # time of the first non-finite right-hand side at a finite state
    fast_rhs = compiled_rhs(model)
    permuted = fast_rhs.permuted(perm) if fast_rhs is not None else None

    def rhsfn(t, z, zp):
        calls[0] += 1
        if permuted is not None:
            if permuted(z, zp) and not bad:
                bad.append(float(t))
            return
        ybuf[perm] = z
        f = model.rhs(t, ybuf)
        if not bad and not np.all(np.isfinite(f)) and np.all(np.isfinite(z)):
            bad.append(float(t))
        zp[:] = f[perm]

    t1, tn = float(t_eval[-1]), float(t_eval[0])
    n_steps, k, nfev, njev = 0, 1, 0, 0
    status, message, t_fail = Status.OK, f"{solver_name}: reached the end of the interval", None
    extra = {"atol_state": atol, "max_steps": max_steps, "rhs": "compiled" if fast_rhs is not None else "numpy"}
    start = time.perf_counter()
    try:
        with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
            f0 = np.asarray(model.rhs(float(t_eval[0]), y0), dtype=float)
        if not np.all(np.isfinite(f0)):
            raise _NonFiniteStart(f"{solver_name}: the right-hand side is not finite at the initial state "
                                  f"(t = {float(t_eval[0]):.6g}); no step taken")
        opts = _options(model, perm, method, rtol, atol, max_steps)
        extra.update({key: opts[key] for key in ("linsolver", "lband", "uband") if key in opts})
        solver = CVODE(rhsfn, **opts)
        solver.init_step(float(t_eval[0]), y0[perm])
        with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
            while k < m:
                if n_steps >= max_steps:
                    status, t_fail = Status.FAILED, tn
                    message = f"{solver_name}: step cap max_steps = {max_steps} reached at t = {tn:.6g}"
                    break
                res = solver.step(t1, method="onestep", tstop=t1)
                nfev, njev = res.nfev, res.njev
                if not res.success:
                    status, t_fail = Status.FAILED, float(res.t)
                    message = f"{solver_name}: CVODE flag {res.status} at t = {t_fail:.6g}: {res.message}"
                    if bad:
                        status = Status.UNSTABLE
                        message = (f"{solver_name}: the right-hand side became non-finite at t = {bad[0]:.6g} "
                                   f"(a state where the force is undefined?); CVODE flag {res.status} at "
                                   f"t = {t_fail:.6g}: {res.message}")
                    break
                if float(res.t) == tn:
                    # After an interpolated output CV_ONE_STEP first returns the
                    # current internal time without stepping (tretlast < tn).
                    continue
                n_steps += 1
                tn = float(res.t)
                if not np.all(np.isfinite(res.y)):
                    status, t_fail = Status.UNSTABLE, tn
                    message = f"{solver_name}: state became non-finite at t = {tn:.6g}"
                    break
                while k < m and t_eval[k] <= tn:
                    if t_eval[k] == tn:
                        y[perm, k] = res.y
                    else:  # inside the last step: CVODE interpolates, no new step
                        out = solver.step(float(t_eval[k]), method="normal")
                        if not out.success:
                            raise RuntimeError(f"interpolation at t = {t_eval[k]}: {out.message}")
                        y[perm, k] = out.y
                    k += 1
    except _NonFiniteStart as exc:
        status, message, t_fail = Status.UNSTABLE, str(exc), float(t_eval[0])
    except Exception as exc:  # noqa: BLE001 - a failure inside is a status, not an exception
        status = Status.FAILED
        message = f"{solver_name}: {type(exc).__name__}: {exc}"
        t_fail = float(t_eval[k - 1]) if k > 0 else float(t_eval[0])
    wall = time.perf_counter() - start
    if status is not Status.OK:
        y[:, k:] = np.nan
    extra["njev"] = int(njev)
    extra["nfev_cvode"] = int(nfev)
    return SolverRun(solver_name, rtol, t_eval, y, int(calls[0]), n_steps, wall, status=status,
                     message=message, atol=float(atol[0]), t_fail=t_fail, extra=extra)
