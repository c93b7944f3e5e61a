"""scipy's DOP853 stepping compiled with numba on a model's compiled right-hand side.

:func:`dop853_loop` returns, for one force kernel (one model *structure*,
:mod:`rk4core.models.compiled`), a numba function that runs the whole
``scipy.integrate.DOP853`` loop -- steps, rejections, output times inside a
step -- without returning to Python. It is the loop of
``scipy.integrate._ivp.rk.RungeKutta._step_impl`` and ``DOP853`` (scipy
1.17) written out:

* the tableau ``A``, ``B``, ``C``, ``E3``, ``E5``, ``D`` are scipy's own
  arrays (``scipy.integrate._ivp.dop853_coefficients``), passed in at run
  time, never copied;
* stage ``s`` is ``y + (sum_j K_j a_sj) h`` and the new state
  ``y + h sum_j K_j b_j``; scipy forms these sums with BLAS (``np.dot``),
  whose summation order is the library's: here they are summed left to
  right, so the states differ from scipy's by round-off of the sums
  (a few ulps per step), not by method;
* error norm ``|h| |e5|^2 / sqrt((|e5|^2 + 0.01 |e3|^2) n)`` with ``e5``,
  ``e3`` divided by ``atol + max(|y|, |y_new|) rtol``; accepted when below
  1; step factor ``min(10, 0.9 err^(-1/8))`` (at most 1 after a rejection),
  ``max(0.2, 0.9 err^(-1/8))`` on a rejection (0.2 when ``err`` is NaN, as
  Python's ``max`` gives); the step is refused below ``10`` ulps of ``t``
  (scipy's "Required step size is less than spacing between numbers.");
* dense output (3 more evaluations per step holding output times) with
  scipy's 7th-order interpolant and its Horner order; an output time equal to
  a step end takes the step's state.

The loop text is fixed; it is appended to the model's generated right-hand
side (:func:`rk4core.fast.codegen.model_source`'s ``rhs``) and loaded as every
generated loop is (:func:`rk4core.fast.codegen._module`: a private on-disk
cache keyed by a hash of the text), so one compilation per model structure
and machine.
"""
from __future__ import annotations

import numpy as np

from . import codegen

__all__ = ["dop853_loop", "coefficients", "STATUS_TEXT", "OK", "TOO_SMALL_STEP", "STEP_CAP", "EVAL_CAP",
           "NONFINITE_STEP", "NONFINITE_STATE"]

#: Return codes of the compiled loop.
OK, TOO_SMALL_STEP, STEP_CAP, EVAL_CAP, NONFINITE_STEP, NONFINITE_STATE = 0, 1, 2, 3, 4, 5
#: scipy's message for :data:`TOO_SMALL_STEP` (``OdeSolver.TOO_SMALL_STEP``).
STATUS_TEXT = {TOO_SMALL_STEP: "Required step size is less than spacing between numbers."}

_LOOP = '''
@njit(error_model="numpy")
def _f(fp, ip, mass, y, out, r, n, w):
    # out[r] = dy/dt at y; returns whether it is non-finite at a finite y
    rhs(fp, ip, mass, y, out, r, n, w)
    fin_in = True
    fin_out = True
    for i in range(y.shape[0]):
        fin_in = fin_in and math.isfinite(y[i])
        fin_out = fin_out and math.isfinite(out[r, i])
    return fin_in and not fin_out


@njit(error_model="numpy")
def dop853(fp, ip, mass, w, info, y0, t_eval, h_abs, rtol, atol, A, B, C, E3, E5, D, max_steps, max_evals, ys,
           counts):
    # ys: (m, n) outputs (row 0 and rows not reached left as given); counts:
    # [n_steps, nfev, k (first output row not written), bad (0/1)]; info[0]:
    # t reached, info[1]: time of the first non-finite slope at a finite
    # state, info[2]: the non-finite step end; w: the force's work array.
    # Returns a status code.
    n2 = y0.shape[0]
    nd = n2 // 2
    m = t_eval.shape[0]
    ns = 12
    K = np.empty((16, n2))
    y = y0.copy()
    yn = np.empty(n2)
    yt = np.empty(n2)
    F = np.empty((7, n2))
    acc = np.empty(n2)
    t = t_eval[0]
    t_bound = t_eval[m - 1]
    nfev = counts[1]
    n_steps = 0
    k = 1
    bad = counts[3] != 0
    # K[0] = f(t0, y0): scipy's DOP853 evaluates it when it starts
    nfev += 1
    if _f(fp, ip, mass, y, K, 0, nd, w) and not bad:
        bad = True
        info[1] = t
    code = 0
    err_exp = -1.0 / 8.0
    while True:
        if t == t_bound:
            break
        if n_steps >= max_steps:
            code = 2
            break
        min_step = 10.0 * abs(np.nextafter(t, np.inf) - t)
        if h_abs < min_step:
            h_abs = min_step
        accepted = False
        rejected = False
        h = 0.0
        t_new = t
        while not accepted:
            if h_abs < min_step:
                code = 1
                break
            t_new = t + h_abs
            if t_new - t_bound > 0:
                t_new = t_bound
            h = t_new - t
            h_abs = abs(h)
            if not math.isfinite(t_new):
                code = 4
                info[2] = t_new
                break
            if nfev + ns > max_evals:
                code = 3
                break
            for s in range(1, ns):
                for i in range(n2):
                    acc[i] = 0.0
                for j in range(s):
                    a = A[s, j]
                    for i in range(n2):
                        acc[i] += K[j, i] * a
                for i in range(n2):
                    yt[i] = y[i] + acc[i] * h
                nfev += 1
                if _f(fp, ip, mass, yt, K, s, nd, w) and not bad:
                    bad = True
                    info[1] = t + C[s] * h
            for i in range(n2):
                acc[i] = 0.0
            for j in range(ns):
                b = B[j]
                for i in range(n2):
                    acc[i] += K[j, i] * b
            for i in range(n2):
                yn[i] = y[i] + h * acc[i]
            nfev += 1
            if _f(fp, ip, mass, yn, K, ns, nd, w) and not bad:
                bad = True
                info[1] = t + h
            s5 = 0.0
            s3 = 0.0
            for i in range(n2):
                ay = abs(y[i])
                an = abs(yn[i])
                mx = ay if ay >= an else an
                if ay != ay or an != an:
                    mx = math.nan
                sc = atol[i] + mx * rtol
                e5 = 0.0
                e3 = 0.0
                for j in range(ns + 1):
                    e5 += K[j, i] * E5[j]
                    e3 += K[j, i] * E3[j]
                e5 = e5 / sc
                e3 = e3 / sc
                s5 += e5 * e5
                s3 += e3 * e3
            n5 = math.sqrt(s5) ** 2
            n3 = math.sqrt(s3) ** 2
            if n5 == 0.0 and n3 == 0.0:
                err = 0.0
            else:
                err = abs(h) * n5 / math.sqrt((n5 + 0.01 * n3) * n2)
            if err < 1.0:
                if err == 0.0:
                    factor = 10.0
                else:
                    factor = 0.9 * err ** err_exp
                    if not factor < 10.0:
                        factor = 10.0
                if rejected and factor > 1.0:
                    factor = 1.0
                h_abs *= factor
                accepted = True
            else:
                factor = 0.9 * err ** err_exp
                if not factor > 0.2:
                    factor = 0.2
                h_abs *= factor
                rejected = True
        if not accepted:
            break
        t_old = t
        n_steps += 1
        # outputs inside (t_old, t_new]
        j = k
        while j < m and t_eval[j] <= t_new:
            j += 1
        finite = True
        for i in range(n2):
            finite = finite and math.isfinite(yn[i])
        if j > k and finite:
            if nfev + 3 > max_evals:
                t = t_new
                for i in range(n2):
                    y[i] = yn[i]
                code = 3
                break
            for s in range(ns + 1, 16):
                for i in range(n2):
                    acc[i] = 0.0
                for jj in range(s):
                    a = A[s, jj]
                    for i in range(n2):
                        acc[i] += K[jj, i] * a
                for i in range(n2):
                    yt[i] = y[i] + acc[i] * h
                nfev += 1
                if _f(fp, ip, mass, yt, K, s, nd, w) and not bad:
                    bad = True
                    info[1] = t_old + C[s] * h
            for i in range(n2):
                dy = yn[i] - y[i]
                F[0, i] = dy
                F[1, i] = h * K[0, i] - dy
                F[2, i] = 2 * dy - h * (K[ns, i] + K[0, i])
                for r in range(4):
                    d = 0.0
                    for s in range(16):
                        d += D[r, s] * K[s, i]
                    F[3 + r, i] = h * d
            hh = t_new - t_old
            for p in range(k, j):
                x = (t_eval[p] - t_old) / hh
                for i in range(n2):
                    v = 0.0
                    for q in range(7):
                        v += F[6 - q, i]
                        if q % 2 == 0:
                            v *= x
                        else:
                            v *= 1 - x
                    ys[p, i] = v + y[i]
            if t_eval[j - 1] == t_new:
                for i in range(n2):
                    ys[j - 1, i] = yn[i]
            k = j
        t = t_new
        for i in range(n2):
            y[i] = yn[i]
            K[0, i] = K[ns, i]
        if not finite:
            code = 5
            break
    info[0] = t
    counts[0] = n_steps
    counts[1] = nfev
    counts[2] = k
    counts[3] = 1 if bad else 0
    return code
'''


def coefficients():
    """scipy's DOP853 arrays ``(A, B, C, E3, E5, D)`` (C-contiguous float64),
    read from ``scipy.integrate._ivp.dop853_coefficients``: ``A`` (16, 16)
    with the three dense-output stages in rows 13-15, ``B`` (12,), ``C`` (16,),
    ``E3``/``E5`` (13,), ``D`` (4, 16)."""
    from scipy.integrate._ivp import dop853_coefficients as dc

    return tuple(np.ascontiguousarray(x, dtype=float) for x in (dc.A, dc.B, dc.C, dc.E3, dc.E5, dc.D))


def loop_source(kern) -> str:
    """Python source of the compiled DOP853 loop of force kernel ``kern``:
    the model's ``rhs`` (as :func:`rk4core.fast.codegen.model_source` prints
    it) and the fixed loop text of this module."""
    L = ["# Generated by rk4core.fast.dop853 from a model's definition; do not edit.",
         f"# depends on: {codegen._dependencies_digest()}"] + codegen._HEADER + codegen._rhs_lines(kern)
    return "\n".join(L) + _LOOP


def dop853_loop(kern):
    """The compiled DOP853 loop of force kernel ``kern`` (a numba function,
    compiled on its first call or loaded from the private on-disk cache)."""
    key = ("dop853",) + (kern.key(),)
    fn = codegen._KERNELS.get(key)
    if fn is None:
        fn = codegen._KERNELS[key] = codegen._module(loop_source(kern)).dop853
    return fn
