"""The compiled DOP853 loop, shared by every model (:mod:`rk4h.fast.dop853`).

The model's right-hand side is an argument, a first-class function of
signature :data:`RHS_SIG`, so this loop is compiled once per machine (numba's
on-disk cache beside this file, as :mod:`rk4h.fast._kernels`) and only the
small wrapper of each model structure's right-hand side is compiled per
structure. Compiled when this module is imported (explicit signature):
import it only where the loop runs.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit, types

_F1 = types.float64[::1]
_F2 = types.float64[:, ::1]
_I1 = types.int64[::1]
#: ``f(fp, ip, mass, y, out, r, n_dof, w) -> bad``: ``out[r] = dy/dt`` at ``y``,
#: and whether it is non-finite at a finite ``y``.
RHS_SIG = types.boolean(_F1, _I1, _F1, _F1, _F2, types.int64, types.int64, _F1)
#: The loop's: the right-hand side, fp, ip, mass, w, info, y0, t_eval, h_abs,
#: rtol, atol, A, B, C, E3, E5, D, max_steps, max_evals, ys, counts.
LOOP_SIG = types.int64(types.FunctionType(RHS_SIG), _F1, _I1, _F1, _F1, _F1, _F1, _F1, types.float64,
                       types.float64, _F1, _F2, _F1, _F1, _F1, _F1, _F2, types.int64, types.int64, _F2, _I1)

@njit(LOOP_SIG, cache=True, error_model="numpy")
def dop853(_f, fp, ip, mass, w, info, y0, t_eval, h_abs, rtol, atol, A, B, C, E3, E5, D, max_steps, max_evals, ys,
           counts):
    # _f(fp, ip, mass, y, out, r, n_dof, w): out[r] = dy/dt at y, and whether
    # it is non-finite at a finite y (the model's, a first-class function).
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
