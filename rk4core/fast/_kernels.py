"""Compiled (numba) right-hand sides of the built-in models and the fixed-step loop.

Everything numba compiles lives in this one module on purpose: numba's on-disk
cache (``cache=True``) is invalidated by the modification time of the file that
holds the cached function only, so a kernel in another file could change
without the cached loop noticing.

One compiled signature serves every model and every method: the model is an
integer ``kind`` plus integer and float parameter arrays ``ip``, ``fp`` (packed
from the model's own attributes by :mod:`rk4core.fast.pack`), and the method is
its (partitioned) Butcher tableau ``A, b, c, A_v, b_v`` passed as arrays.

Each force kernel repeats the floating-point operations of the model's
``_force`` in the same order, so the compiled and the numpy right-hand sides
agree to the last bit wherever the elementary functions (sqrt, sin, cos) do.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

# Model kinds (see pack.py for the parameter layout of each).
CHAIN = 0
PLANAR4 = 1
PLANAR4_LINEAR = 2
OSCILLATOR2D = 3
PENDULUMS = 4
PENDULUMS_LINEAR = 5
TRIANGLE = 6

STATUS_OK = 0
STATUS_NONFINITE = -1


# The force kernels read q = y[:n] and write F(q) into out[r, n:n + n]; they
# index instead of slicing because a slice costs more than a 2-mass force.

@njit(cache=True, inline="always")
def _chain_force(ip, fp, y, n, out, r):
    # ip = [left wall, right wall]; fp = spring constants left to right.
    # Chain._force: tensions T_j = k_j (u_{j+1} - u_j) of the wall-padded
    # displacements u, zero tension beyond a free end, and F_i = T_{i+1} - T_i.
    # O(N): each tension is formed once and carried to the next mass.
    left = ip[0] != 0
    right = ip[1] != 0
    off = 1 if left else 0  # index of the spring to the right of mass 0
    prev = fp[0] * (y[0] - 0.0) if left else 0.0
    for i in range(n):
        if i < n - 1:
            nxt = fp[i + off] * (y[i + 1] - y[i])
        elif right:
            nxt = fp[i + off] * (0.0 - y[i])
        else:
            nxt = 0.0
        out[r, n + i] = nxt - prev
        prev = nxt


@njit(cache=True, inline="always")
def _planar4_force(fp, y, out, r):
    # fp = [k, l, ax0, ay0, ..., ax3, ay3]; Planar4._force (exact geometry).
    k, l = fp[0], fp[1]
    fx = 0.0
    fy = 0.0
    for j in range(4):
        dx = y[0] - fp[2 + 2 * j]
        dy = y[1] - fp[3 + 2 * j]
        L = math.sqrt(dx * dx + dy * dy)
        s = k * (L - l) / L  # tension / length
        fx = fx - s * dx
        fy = fy - s * dy
    out[r, 2] = fx
    out[r, 3] = fy


@njit(cache=True, inline="always")
def _pendulums_force(fp, y, out, r):
    # fp = [m g L, k L^2, L, d, k]; Pendulums._force (exact geometry).
    mgl, L, d, k = fp[0], fp[2], fp[3], fp[4]
    s1, c1, s2, c2 = math.sin(y[0]), math.cos(y[0]), math.sin(y[1]), math.cos(y[1])
    dx = d + L * (s2 - s1)
    dy = -L * (c2 - c1)
    D = math.sqrt(dx * dx + dy * dy)
    t = k * (D - d) / D  # tension / length
    out[r, 2] = -mgl * s1 + t * L * (dx * c1 + dy * s1)
    out[r, 3] = -mgl * s2 - t * L * (dx * c2 + dy * s2)


@njit(cache=True, inline="always")
def _triangle_force(fp, y, out, r):
    # fp = [k, side, then (dx, dy) of rest positions r_j - r_i for the pairs
    # (0,1), (1,2), (0,2)]; Triangle._force.
    k, a = fp[0], fp[1]
    for p in range(6, 12):
        out[r, p] = 0.0
    for b in range(3):
        if b == 0:
            i, j = 0, 1
        elif b == 1:
            i, j = 1, 2
        else:
            i, j = 0, 2
        dx = fp[2 + 2 * b] + y[2 * j] - y[2 * i]
        dy = fp[3 + 2 * b] + y[2 * j + 1] - y[2 * i + 1]
        L = math.sqrt(dx * dx + dy * dy)
        s = k * (L - a) / L  # tension / length, pulls i towards j
        out[r, 6 + 2 * i] = out[r, 6 + 2 * i] + s * dx
        out[r, 7 + 2 * i] = out[r, 7 + 2 * i] + s * dy
        out[r, 6 + 2 * j] = out[r, 6 + 2 * j] - s * dx
        out[r, 7 + 2 * j] = out[r, 7 + 2 * j] - s * dy


@njit(cache=True, inline="always")
def rhs(kind, ip, fp, mass, y, out, r):
    """``out[r] = dy/dt`` for ``y = [q, v]``: ``q' = v``, ``v' = F(q) / mass``
    (as ``Model.rhs``)."""
    n = mass.shape[0]
    if kind == CHAIN:
        _chain_force(ip, fp, y, n, out, r)
    elif kind == PLANAR4:
        _planar4_force(fp, y, out, r)
    elif kind == PLANAR4_LINEAR:
        out[r, 2] = -2.0 * fp[0] * y[0]
        out[r, 3] = -2.0 * fp[0] * y[1]
    elif kind == OSCILLATOR2D:
        out[r, 2] = -fp[0] * y[0]
        out[r, 3] = -fp[1] * y[1]
    elif kind == PENDULUMS:
        _pendulums_force(fp, y, out, r)
    elif kind == PENDULUMS_LINEAR:
        mgl, kl2 = fp[0], fp[1]
        dth = y[1] - y[0]
        out[r, 2] = -mgl * y[0] + kl2 * dth
        out[r, 3] = -mgl * y[1] - kl2 * dth
    else:
        _triangle_force(fp, y, out, r)
    for i in range(n):
        out[r, i] = y[n + i]
        out[r, n + i] = out[r, n + i] / mass[i]


@njit(cache=True)
def _hermite(ys, row, th, y_old, y_new, k, step, f1):
    """``ys[row]`` = cubic Hermite interpolant at fraction ``th`` of the step
    ``[y_old, y_new]`` with end slopes ``k[0] = f(y_old)`` and ``f1[0] =
    f(y_new)`` (as ``rk4core.solver._emit``)."""
    h00 = (1 + 2 * th) * (1 - th) ** 2
    h10 = th * (1 - th) ** 2
    h01 = th * th * (3 - 2 * th)
    h11 = th * th * (th - 1)
    a10 = h10 * step
    a11 = h11 * step
    for p in range(y_new.shape[0]):
        ys[row, p] = h00 * y_old[p] + a10 * k[0, p] + h01 * y_new[p] + a11 * f1[0, p]


@njit(cache=True)
def integrate(kind, ip, fp, mass, y0, t0, step, n, A, b, c, A_v, b_v, idx, theta, ys):
    """Take ``n`` fixed steps of the (partitioned) Runge-Kutta method from ``y0``.

    Stage ``s`` sees ``y + h sum_j A[s, j] k_j`` on the position half and
    ``y + h sum_j A_v[s, j] k_j`` on the velocity half (``A_v = A``, ``b_v =
    b`` for a classical method), summed in the order of ``rk4core.rk_step``.
    Output points ``(idx, theta)`` -- step index and fraction inside the step
    -- are written to ``ys`` as they are passed.

    Returns
    -------
    n_done : int
        Steps completed with a finite state.
    n_out : int
        Rows of ``ys`` written.
    status : int
        0, or -1 when step ``n_done + 1`` produced a non-finite state.
    n_extra : int
        Right-hand-side calls for Hermite end slopes (one per step that holds
        off-grid output points).
    """
    ns = b.shape[0]
    dim = y0.shape[0]
    nq = dim // 2
    k = np.empty((ns, dim))
    yi = np.empty(dim)
    f1 = np.empty((1, dim))
    y = y0.copy()
    y_new = np.empty(dim)
    m_out = idx.shape[0]
    ptr = 0
    n_extra = 0
    while ptr < m_out and idx[ptr] == 0 and theta[ptr] == 0.0:
        for p in range(dim):
            ys[ptr, p] = y[p]
        ptr += 1
    for i in range(n):
        # The models are autonomous: the stage times t_i + c[s] h are not needed.
        for s in range(ns):
            for p in range(dim):
                yi[p] = y[p]
            for j in range(s):
                if A[s, j] != 0.0:
                    hq = step * A[s, j]
                    for p in range(nq):
                        yi[p] = yi[p] + hq * k[j, p]
                if A_v[s, j] != 0.0:
                    hv = step * A_v[s, j]
                    for p in range(nq, dim):
                        yi[p] = yi[p] + hv * k[j, p]
            rhs(kind, ip, fp, mass, yi, k, s)
        finite = True
        for p in range(dim):
            y_new[p] = y[p]
        for s in range(ns):
            if b[s] != 0.0:
                hq = step * b[s]
                for p in range(nq):
                    y_new[p] = y_new[p] + hq * k[s, p]
            if b_v[s] != 0.0:
                hv = step * b_v[s]
                for p in range(nq, dim):
                    y_new[p] = y_new[p] + hv * k[s, p]
        for p in range(dim):
            finite = finite and math.isfinite(y_new[p])
        if not finite:
            return i, ptr, STATUS_NONFINITE, n_extra
        # Outputs due now (in order): inside this step, then at its end.
        have_f1 = False
        while ptr < m_out:
            if idx[ptr] == i and theta[ptr] > 0.0:
                if not have_f1:  # the end slope, once per step
                    rhs(kind, ip, fp, mass, y_new, f1, 0)
                    have_f1 = True
                    n_extra += 1
                _hermite(ys, ptr, theta[ptr], y, y_new, k, step, f1)
            elif idx[ptr] == i + 1 and theta[ptr] == 0.0:
                for p in range(dim):
                    ys[ptr, p] = y_new[p]
            else:
                break
            ptr += 1
        for p in range(dim):
            y[p] = y_new[p]
    return n, ptr, STATUS_OK, n_extra
