"""Hand-written numba RK4 loops: the yardsticks of ``bench_rk4.py``.

Both do the arithmetic of the loops ``rk4h.fast`` generates, in the same
order, so their final states must equal the generated loops' bit for bit
(the benchmark checks it):

* stage state ``s = y + (h a_s,s-1) k_{s-1}`` (classical RK4: one non-zero
  ``a`` per stage, ``h a`` formed once as ``h * a``);
* tensions ``T_j = k_j (x_{j+1} - x_j)`` with the walls at 0 (``x_1 - 0.0``
  on the left, ``0.0 - x_N`` on the right), force ``F_i = T_{i+1} - T_i``,
  acceleration ``F_i / m_i`` (a division);
* new state ``y + (h b_0) k_0 + (h b_1) k_1 + (h b_2) k_2 + (h b_3) k_3``,
  summed left to right.

``rk4_network`` does the arithmetic of the generated loop of a planar
``network`` of harmonic springs (its fused slope: positions, one pass over
the edge list, the ``b`` ends after) in the same order.

Nothing else: no output rows, no instability test, only the final state.
Compiled with ``error_model="numpy"`` as the generated loops are.
"""
from __future__ import annotations

import numpy as np
from numba import njit

# The classical RK4 tableau as rk4h.methods stores it (floats).
A10 = A21 = 0.5
A32 = 1.0
B0 = B3 = 1.0 / 6.0
B1 = B2 = 1.0 / 3.0

__all__ = ["rk4_two_mass", "rk4_chain", "rk4_network", "compile_all", "compile_network"]


@njit(cache=True, error_model="numpy")
def rk4_two_mass(m0, m1, k0, k1, k2, y_start, step, n):
    """``n`` RK4 steps of the two-mass chain with both walls (springs ``k0``
    wall-m0, ``k1`` m0-m1, ``k2`` m1-wall), fully unrolled, state in scalars;
    returns the final state ``[x0, x1, v0, v1]``."""
    y0, y1, y2, y3 = y_start[0], y_start[1], y_start[2], y_start[3]
    h10 = step * A10
    h21 = step * A21
    h32 = step * A32
    hb0 = step * B0
    hb1 = step * B1
    hb2 = step * B2
    hb3 = step * B3
    for _ in range(n):
        # stage 0
        s0, s1, s2, s3 = y0, y1, y2, y3
        T0 = k0 * (s0 - 0.0)
        T1 = k1 * (s1 - s0)
        T2 = k2 * (0.0 - s1)
        a0_0, a0_1, a0_2, a0_3 = s2, s3, (T1 - T0) / m0, (T2 - T1) / m1
        # stage 1
        s0 = y0 + h10 * a0_0
        s1 = y1 + h10 * a0_1
        s2 = y2 + h10 * a0_2
        s3 = y3 + h10 * a0_3
        T0 = k0 * (s0 - 0.0)
        T1 = k1 * (s1 - s0)
        T2 = k2 * (0.0 - s1)
        a1_0, a1_1, a1_2, a1_3 = s2, s3, (T1 - T0) / m0, (T2 - T1) / m1
        # stage 2
        s0 = y0 + h21 * a1_0
        s1 = y1 + h21 * a1_1
        s2 = y2 + h21 * a1_2
        s3 = y3 + h21 * a1_3
        T0 = k0 * (s0 - 0.0)
        T1 = k1 * (s1 - s0)
        T2 = k2 * (0.0 - s1)
        a2_0, a2_1, a2_2, a2_3 = s2, s3, (T1 - T0) / m0, (T2 - T1) / m1
        # stage 3
        s0 = y0 + h32 * a2_0
        s1 = y1 + h32 * a2_1
        s2 = y2 + h32 * a2_2
        s3 = y3 + h32 * a2_3
        T0 = k0 * (s0 - 0.0)
        T1 = k1 * (s1 - s0)
        T2 = k2 * (0.0 - s1)
        a3_0, a3_1, a3_2, a3_3 = s2, s3, (T1 - T0) / m0, (T2 - T1) / m1
        # new state
        y0 = y0 + hb0 * a0_0 + hb1 * a1_0 + hb2 * a2_0 + hb3 * a3_0
        y1 = y1 + hb0 * a0_1 + hb1 * a1_1 + hb2 * a2_1 + hb3 * a3_1
        y2 = y2 + hb0 * a0_2 + hb1 * a1_2 + hb2 * a2_2 + hb3 * a3_2
        y3 = y3 + hb0 * a0_3 + hb1 * a1_3 + hb2 * a2_3 + hb3 * a3_3
    out = np.empty(4)
    out[0], out[1], out[2], out[3] = y0, y1, y2, y3
    return out


@njit(inline="always", error_model="numpy")
def _chain_slope(k, mass, s, out, N):
    """``out = dy/dt`` at ``s`` for the fixed-end chain: ``out[:N] = v``,
    ``out[N:] = (T_{i+1} - T_i) / m_i``, each tension formed once and carried
    to the next mass."""
    T_prev = k[0] * (s[0] - 0.0)
    for i in range(N - 1):
        T = k[i + 1] * (s[i + 1] - s[i])
        out[i] = s[N + i]
        out[N + i] = (T - T_prev) / mass[i]
        T_prev = T
    T = k[N] * (0.0 - s[N - 1])
    out[N - 1] = s[2 * N - 1]
    out[2 * N - 1] = (T - T_prev) / mass[N - 1]


@njit(cache=True, error_model="numpy")
def rk4_chain(mass, k, y_start, step, n):
    """``n`` RK4 steps of the chain of ``N = mass.size`` masses with walls at
    both ends (``k``: N + 1 springs, wall to wall), in stage arrays; returns
    the final state ``[x, v]``."""
    N = mass.shape[0]
    dim = 2 * N
    y = y_start.copy()
    s = np.empty(dim)
    k0 = np.empty(dim)
    k1 = np.empty(dim)
    k2 = np.empty(dim)
    k3 = np.empty(dim)
    h10 = step * A10
    h21 = step * A21
    h32 = step * A32
    hb0 = step * B0
    hb1 = step * B1
    hb2 = step * B2
    hb3 = step * B3
    for _ in range(n):
        _chain_slope(k, mass, y, k0, N)
        for p in range(dim):
            s[p] = y[p] + h10 * k0[p]
        _chain_slope(k, mass, s, k1, N)
        for p in range(dim):
            s[p] = y[p] + h21 * k1[p]
        _chain_slope(k, mass, s, k2, N)
        for p in range(dim):
            s[p] = y[p] + h32 * k2[p]
        _chain_slope(k, mass, s, k3, N)
        for p in range(dim):
            y[p] = y[p] + hb0 * k0[p] + hb1 * k1[p] + hb2 * k2[p] + hb3 * k3[p]
    return y


@njit(inline="always", error_model="numpy")
def _network_slope(X, A, ea, eb, k, rest, mass, s, out, P, g, F, N, D):
    """``out = dy/dt`` at ``s`` for a network of harmonic springs (exact
    geometry, ``N`` coordinates, ``D`` per node): node positions ``P`` (mass
    ``X + u``, anchor ``A``), one pass over the edge list (``F = k r / L d``
    added to the ``a`` end), the ``b`` ends after, then ``v`` and ``g / m``."""
    for i in range(N):
        P[i] = X[i] + s[i]
        g[i] = 0.0
    for j in range(A.shape[0]):
        P[N + j] = A[j]
        g[N + j] = 0.0
    for e in range(ea.shape[0]):
        a = ea[e] * D
        b = eb[e] * D
        d0 = P[b] - P[a]
        d1 = P[b + 1] - P[a + 1]
        L = np.sqrt(d0 * d0 + d1 * d1)
        tL = k[e] * (L - rest[e]) / L
        f0 = tL * d0
        f1 = tL * d1
        F[2 * e] = f0
        F[2 * e + 1] = f1
        g[a] = g[a] + f0
        g[a + 1] = g[a + 1] + f1
    for e in range(ea.shape[0]):
        b = eb[e] * D
        g[b] = g[b] + -F[2 * e]
        g[b + 1] = g[b + 1] + -F[2 * e + 1]
    for i in range(N):
        out[i] = s[N + i]
        out[N + i] = g[i] / mass[i]


@njit(cache=True, error_model="numpy")
def rk4_network(X, A, ea, eb, k, rest, mass, y_start, step, n):
    """``n`` RK4 steps of a planar network of harmonic springs (``X``: the
    masses' reference positions flat, ``A`` the anchors' flat, ``ea``/``eb``
    the node indices of each spring's ends, masses first), in stage arrays;
    returns the final state ``[u, v]``."""
    N = X.shape[0]
    dim = 2 * N
    y = y_start.copy()
    s = np.empty(dim)
    k0 = np.empty(dim)
    k1 = np.empty(dim)
    k2 = np.empty(dim)
    k3 = np.empty(dim)
    P = np.empty(N + A.shape[0])
    g = np.empty(N + A.shape[0])
    F = np.empty(2 * ea.shape[0])
    h10 = step * A10
    h21 = step * A21
    h32 = step * A32
    hb0 = step * B0
    hb1 = step * B1
    hb2 = step * B2
    hb3 = step * B3
    for _ in range(n):
        _network_slope(X, A, ea, eb, k, rest, mass, y, k0, P, g, F, N, 2)
        for p in range(dim):
            s[p] = y[p] + h10 * k0[p]
        _network_slope(X, A, ea, eb, k, rest, mass, s, k1, P, g, F, N, 2)
        for p in range(dim):
            s[p] = y[p] + h21 * k1[p]
        _network_slope(X, A, ea, eb, k, rest, mass, s, k2, P, g, F, N, 2)
        for p in range(dim):
            s[p] = y[p] + h32 * k2[p]
        _network_slope(X, A, ea, eb, k, rest, mass, s, k3, P, g, F, N, 2)
        for p in range(dim):
            y[p] = y[p] + hb0 * k0[p] + hb1 * k1[p] + hb2 * k2[p] + hb3 * k3[p]
    return y


def compile_all() -> None:
    """Compile (or load from numba's cache) both loops: one call each."""
    rk4_two_mass(1.0, 1.0, 1.0, 1.0, 1.0, np.zeros(4), 0.01, 1)
    rk4_chain(np.ones(3), np.ones(4), np.zeros(6), 0.01, 1)


def compile_network() -> None:
    """Compile (or load from numba's cache) :func:`rk4_network`: one call."""
    rk4_network(np.array([0.0, 0.0]), np.array([1.0, 0.0]), np.array([0]), np.array([1]), np.ones(1), np.ones(1),
                np.ones(2), np.zeros(4), 0.01, 1)
