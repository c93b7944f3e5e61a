"""Linear stability of an explicit (partitioned) Runge-Kutta method, exactly.

Classical methods. On ``y' = lambda y`` one step multiplies ``y`` by the
stability function

    R(z) = 1 + z b^T (I - z A)^{-1} 1 = 1 + sum_{k >= 1} (b^T A^{k-1} 1) z^k,
    z = h lambda,

a polynomial of degree at most ``s`` for an explicit method (``A`` is
nilpotent); :func:`stability_polynomial` gives its coefficients as
:class:`~fractions.Fraction` (Butcher 2008, sec. 23; HNW I, sec. IV.2 of
vol. II). On an undamped oscillator ``q'' = -w^2 q`` the eigenvalues are
``+-i w`` and the step is stable while ``|R(i h w)| <= 1``.

Partitioned methods (``y = [q, v]``, ``q' = v``, ``v' = a(q)``; see
:mod:`rk4h.methods`) have no scalar test equation. On ``q'' = -w^2 q`` one
step is a 2 x 2 matrix ``M(h w)`` acting on ``(q, h v)``
(:func:`partitioned_step_matrix`), with entries polynomial in ``(h w)^2``;
it is stable while both its eigenvalues lie in the closed unit disk, i.e.
(Schur-Cohn for ``lambda^2 - T lambda + D``) ``|D| <= 1`` and ``|T| <= 1 +
D``. For the symplectic methods ``D = 1`` and the condition is ``|T| <= 2``
(HLW sec. I.5).

A tableau given to a finite precision (decimals printed to 8 places, floats:
:attr:`rk4h.methods.Tableau.uncertainty`) is judged with the same
tolerance as its order conditions: each coefficient of the polynomial whose
sign decides stability is set to zero when it is no larger than what
coefficients that far off can produce (the same polynomial formed from the
entries' absolute values plus their bounds, minus that formed from the
absolute values alone). Ralston's fourth-order method printed to 8 decimals
has ``|R(i y)|^2 - 1 = 5.5e-9 y^4 - y^6/72 + ...`` as given: read exactly, it
is unstable for every ``y > 0``; at its precision the ``y^4`` term is noise
and the boundary is RK4's ``2 sqrt 2``. An exact tableau is unchanged.

Boundaries are computed from exact polynomials: the odd-multiplicity part of
the polynomial whose sign says "unstable" (square-free decomposition, Yun's
algorithm), its smallest positive root isolated with a Sturm sequence and
bisected in exact rational arithmetic to 2^-64 relative, then rounded to
float -- far below the 1e-12 asked for.

References
----------
J. C. Butcher, *Numerical Methods for Ordinary Differential Equations*, 2nd ed.,
Wiley 2008, sec. 23 (stability function of explicit methods).
E. Hairer, G. Wanner, *Solving Ordinary Differential Equations II*, 2nd ed.,
Springer 1996, sec. IV.2 (stability function, stability domains).
E. Hairer, C. Lubich, G. Wanner, *Geometric Numerical Integration*, 2nd ed.,
Springer 2006, sec. I.5 (linear stability of Stormer-Verlet: ``h w < 2``).
"""
from __future__ import annotations

import math
from fractions import Fraction
from functools import lru_cache

import numpy as np

__all__ = ["stability_polynomial", "R", "imaginary_axis_boundary", "real_axis_boundary",
           "partitioned_step_matrix"]

_REL = Fraction(1, 2**64)  # relative width at which a root's bracket is rounded to float
_MAX_BISECTIONS = 4000


# -- exact polynomials: lists of Fraction, lowest degree first ------------------------------------------
def _trim(p):
    p = list(p)
    while p and p[-1] == 0:
        p.pop()
    return p


def _add(p, q):
    n = max(len(p), len(q))
    return _trim([(p[i] if i < len(p) else 0) + (q[i] if i < len(q) else 0) for i in range(n)])


def _scale(p, a):
    return _trim([a * x for x in p])


def _mul(p, q):
    if not p or not q:
        return []
    out = [Fraction(0)] * (len(p) + len(q) - 1)
    for i, x in enumerate(p):
        if x:
            for j, y in enumerate(q):
                out[i + j] += x * y
    return _trim(out)


def _deriv(p):
    return _trim([i * p[i] for i in range(1, len(p))])


def _divmod(p, q):
    p, q = _trim(p), _trim(q)
    if len(p) < len(q):
        return [], p
    quot = [Fraction(0)] * (len(p) - len(q) + 1)
    r = list(p)
    for d in range(len(p) - len(q), -1, -1):
        f = r[d + len(q) - 1] / q[-1]
        quot[d] = f
        if f:
            for i, y in enumerate(q):
                r[d + i] -= f * y
    return _trim(quot), _trim(r[:len(q) - 1])


def _monic(p):
    return _scale(p, 1 / p[-1]) if p else p


def _gcd(p, q):
    p, q = _trim(p), _trim(q)
    while q:
        p, q = q, _divmod(p, q)[1]
    return _monic(p)


def _odd_part(p):
    """The product of the square-free factors of odd multiplicity of ``p``
    (Yun's algorithm): its roots are exactly where ``p`` changes sign."""
    p = _monic(_trim(p))
    if len(p) <= 1:
        return p
    dp = _deriv(p)
    a = _gcd(p, dp)
    b = _divmod(p, a)[0]
    c = _divmod(dp, a)[0]
    d = _add(c, _scale(_deriv(b), -1))
    odd, i = [Fraction(1)], 1
    while len(b) > 1:
        a = _gcd(b, d)
        if i % 2 == 1:
            odd = _mul(odd, a)
        b = _divmod(b, a)[0]
        c = _divmod(d, a)[0]
        d = _add(c, _scale(_deriv(b), -1))
        i += 1
    return odd


def _sturm(p):
    seq = [p, _deriv(p)]
    while len(seq[-1]) > 1:
        r = _divmod(seq[-2], seq[-1])[1]
        if not r:
            break
        seq.append(_scale(r, -1))
    return seq


def _integer(p):
    """``p`` times the least common multiple of its denominators: integer
    coefficients, and the sign of ``p`` everywhere."""
    m = math.lcm(*(a.denominator for a in p)) if p else 1
    return [int(a * m) for a in p]


def _value_sign_times(c, num, den):
    """``sum c_i num^i den^(n-i)`` for integer ``c`` of degree ``n`` and
    ``den > 0``: ``den^n p(num / den)``, which has the sign of ``p(num /
    den)``; integer Horner, no fraction reduced on the way."""
    if not c:
        return 0
    it = reversed(c)
    acc, scale = next(it), 1
    for a in it:
        scale *= den
        acc = acc * num + a * scale
    return acc


def _variations(seq, x):
    """Sign changes of the Sturm sequence ``seq`` (integer polynomials,
    :func:`_integer`) at the rational ``x``, zeros skipped."""
    x = Fraction(x)
    num, den = x.numerator, x.denominator
    signs = [v for v in (_value_sign_times(c, num, den) for c in seq) if v != 0]
    return sum(1 for u, v in zip(signs, signs[1:]) if (u < 0) != (v < 0))


def _first_violation(p) -> float:
    """Smallest ``x >= 0`` past which the polynomial ``p`` becomes positive:
    ``p <= 0`` on ``[0, x]`` and ``p > 0`` just beyond. 0.0 when ``p > 0``
    right of 0 (or at 0), ``inf`` when ``p <= 0`` on the whole half-line."""
    p = _trim(p)
    if not p:
        return math.inf
    m = next(i for i, a in enumerate(p) if a != 0)
    q = p[m:]  # p = x^m q, q(0) != 0
    if q[0] > 0:
        return 0.0
    odd = _odd_part(q)  # q changes sign exactly at the roots of odd
    if len(odd) <= 1:
        return math.inf
    seq = [_integer(c) for c in _sturm(odd)]  # the same signs, in integer arithmetic
    bound = 1 + max(abs(a / odd[-1]) for a in odd[:-1])  # Cauchy: every root is below it
    lo, hi = Fraction(0), Fraction(bound)
    v_lo = _variations(seq, lo)
    if v_lo - _variations(seq, hi) == 0:
        return math.inf
    for _ in range(_MAX_BISECTIONS):  # keep the smallest positive root in (lo, hi]
        if hi - lo <= _REL * hi:
            break
        mid = (lo + hi) / 2
        if v_lo - _variations(seq, mid) >= 1:
            hi = mid
        else:
            lo, v_lo = mid, _variations(seq, mid)
    return float(hi)


# -- classical methods --------------------------------------------------------------------------------
def _classical(tab, what):
    if tab.partitioned:
        raise ValueError(f"method {tab.name!r}: `tab` is partitioned; {what} is defined for classical "
                         f"methods (use partitioned_step_matrix / imaginary_axis_boundary)")


def stability_polynomial(tab) -> list[Fraction]:
    """Coefficients ``[r_0, r_1, ..., r_d]`` (lowest degree first) of
    ``R(z) = 1 + z b^T (I - zA)^{-1} 1``: ``r_0 = 1``, ``r_k = b^T A^{k-1} 1``;
    exact, trailing zeros dropped (``d <= s``). Classical tableaux only."""
    _classical(tab, "the stability polynomial")
    A, b = tab.A_exact, tab.b_exact
    s = len(b)
    coeffs = [Fraction(1)]
    v = [Fraction(1)] * s
    for _ in range(s):
        coeffs.append(sum((x * y for x, y in zip(b, v)), Fraction(0)))
        v = [sum((a * y for a, y in zip(row, v)), Fraction(0)) for row in A]
    return _trim(coeffs) or [Fraction(0)]


def _stability_polynomial_bound(tab) -> list[Fraction]:
    """Bounds on how far each coefficient of :func:`stability_polynomial` may
    be from the intended method's at the tableau's precision
    (``tab.uncertainty``): ``(|b| + db)^T (|A| + dA)^{k-1} 1 - |b|^T
    |A|^{k-1} 1``; zeros for an exact tableau."""
    s = tab.n_stages
    unc = getattr(tab, "uncertainty", None)
    if unc is None:
        return [Fraction(0)] * (s + 1)
    dA, db = unc[0], unc[1]
    A0 = [[abs(x) for x in row] for row in tab.A_exact]
    A1 = [[abs(x) + d for x, d in zip(row, drow)] for row, drow in zip(tab.A_exact, dA)]
    b0 = [abs(x) for x in tab.b_exact]
    b1 = [abs(x) + d for x, d in zip(tab.b_exact, db)]
    out = [Fraction(0)]
    v0 = v1 = [Fraction(1)] * s
    for _ in range(s):
        out.append(sum((x * y for x, y in zip(b1, v1)), Fraction(0)) - sum((x * y for x, y in zip(b0, v0)),
                                                                          Fraction(0)))
        v0 = [sum((a * y for a, y in zip(row, v0)), Fraction(0)) for row in A0]
        v1 = [sum((a * y for a, y in zip(row, v1)), Fraction(0)) for row in A1]
    return out


def _snap(p, bound):
    """``p`` with every coefficient no larger than its ``bound`` set to 0."""
    return _trim([Fraction(0) if i < len(bound) and a != 0 and abs(a) <= bound[i] else a
                  for i, a in enumerate(p)])


def _pad(p, n):
    return list(p) + [Fraction(0)] * (n - len(p))


def R(tab, z):
    """Stability function ``R(z)`` at ``z`` (scalar or array, real or complex;
    numpy, Horner in float64). Classical tableaux only."""
    coeffs = [float(a) for a in stability_polynomial(tab)]
    z = np.asarray(z)
    acc = np.zeros_like(z, dtype=np.result_type(z.dtype, float))
    for a in reversed(coeffs):
        acc = acc * z + a
    return acc if acc.ndim else acc[()]


def _modulus_excess_on_imaginary_axis(r):
    """``|R(i y)|^2 - 1`` as a polynomial in ``u = y^2`` (exact)."""
    even = [a * (-1) ** (k // 2) for k, a in enumerate(r) if k % 2 == 0]
    odd = [a * (-1) ** (k // 2) for k, a in enumerate(r) if k % 2 == 1]
    return _add(_add(_mul(even, even), [Fraction(0)] + _mul(odd, odd)), [Fraction(-1)])


def _excess_majorant(r):
    """:func:`_modulus_excess_on_imaginary_axis` with every sign dropped and
    without the ``-1``: a coefficientwise bound for nonnegative ``r``."""
    even = [a for k, a in enumerate(r) if k % 2 == 0]
    odd = [a for k, a in enumerate(r) if k % 2 == 1]
    return _add(_mul(even, even), [Fraction(0)] + _mul(odd, odd))


def _excess_bound(r, beta):
    """How far each coefficient of ``|R(i y)|^2 - 1`` may move when each
    ``r_k`` moves by at most ``beta_k``."""
    n = max(len(r), len(beta))
    r0 = [abs(a) for a in _pad(r, n)]
    r1 = [a + b for a, b in zip(r0, _pad(beta, n))]
    hi, lo = _excess_majorant(r1), _excess_majorant(r0)
    m = max(len(hi), len(lo))
    return [a - b for a, b in zip(_pad(hi, m), _pad(lo, m))]


def real_axis_boundary(tab) -> float:
    """Largest ``x`` with ``|R(-x')| <= 1`` for every ``0 <= x' <= x``
    (dimensionless, ``x = h |lambda|`` for a decay ``y' = lambda y``, lambda < 0):
    RK4 2.785293563405282, Euler 2. 0.0 if ``|R(-x)| > 1`` just right of 0;
    ``inf`` if never. Classical tableaux only."""
    r = stability_polynomial(tab)
    beta = _stability_polynomial_bound(tab)
    minus = [a * (-1) ** k for k, a in enumerate(r)]  # R(-x)
    above = _snap(_add(minus, [Fraction(-1)]), beta)  # R(-x) - 1 <= 0
    below = _snap(_scale(_add(minus, [Fraction(1)]), -1), beta)  # -(R(-x) + 1) <= 0
    return min(_first_violation(above), _first_violation(below))


# -- partitioned methods ------------------------------------------------------------------------------
@lru_cache(maxsize=64)
def _step_matrix_poly(tab):
    """One step on ``q'' = -w^2 q`` with ``h = 1``, ``w^2 = x``, as a 2 x 2
    matrix of exact polynomials in ``x`` acting on ``(q, h v)``; the stage
    order of :func:`rk4h.methods.rk_step`."""
    A, b = tab.A_exact, tab.b_exact
    A_v, b_v = (tab.A_v_exact, tab.b_v_exact) if tab.partitioned else (A, b)
    return _step_matrix_of(tab, A, b, A_v, b_v, Fraction(-1))


def _step_matrix_bound(tab):
    """``(trace bound, determinant bound)``: how far each coefficient of the
    trace and the determinant of :func:`_step_matrix_poly` may move at the
    tableau's precision (``tab.uncertainty``), from the step matrix formed
    with absolute values (``+x`` for ``-x``) with and without the bounds;
    None for an exact tableau."""
    unc = getattr(tab, "uncertainty", None)
    if unc is None:
        return None
    dA, db, dA_v, db_v = unc
    if not tab.partitioned:
        dA_v, db_v = dA, db
    A, b = tab.A_exact, tab.b_exact
    A_v, b_v = (tab.A_v_exact, tab.b_v_exact) if tab.partitioned else (A, b)
    absm = lambda M, dM=None: tuple(tuple(abs(x) + (dM[i][j] if dM else 0) for j, x in enumerate(row))  # noqa: E731
                                    for i, row in enumerate(M))
    absv = lambda v, dv=None: tuple(abs(x) + (dv[i] if dv else 0) for i, x in enumerate(v))  # noqa: E731
    lo = _step_matrix_of(tab, absm(A), absv(b), absm(A_v), absv(b_v), Fraction(1))
    hi = _step_matrix_of(tab, absm(A, dA), absv(b, db), absm(A_v, dA_v), absv(b_v, db_v), Fraction(1))

    def trace(M):
        return _add(M[0][0], M[1][1])

    def det(M):  # majorant: both products added
        return _add(_mul(M[0][0], M[1][1]), _mul(M[0][1], M[1][0]))

    def diff(p, q):
        n = max(len(p), len(q))
        return [x - y for x, y in zip(_pad(p, n), _pad(q, n))]

    return diff(trace(hi), trace(lo)), diff(det(hi), det(lo))


def _step_matrix_of(tab, A, b, A_v, b_v, sign):
    """The step matrix of :func:`_step_matrix_poly` from the given
    coefficients; ``sign`` multiplies ``x`` in the acceleration (-1: the
    oscillator; +1 with absolute values: a coefficientwise majorant)."""
    s = tab.n_stages
    minus_x = [Fraction(0), sign]
    cols = []
    for q0, v0 in (([Fraction(1)], []), ([], [Fraction(1)])):
        Q, V, acc = [None] * s, [None] * s, [None] * s
        for i in range(s):
            if tab.partitioned and A_v[i][i] != 0:  # position first
                Q[i] = q0
                for j in range(i):
                    Q[i] = _add(Q[i], _scale(V[j], A[i][j]))
                acc[i] = _mul(minus_x, Q[i])
                V[i] = v0
                for j in range(i + 1):
                    V[i] = _add(V[i], _scale(acc[j], A_v[i][j]))
            else:  # velocity first
                V[i] = v0
                for j in range(i):
                    V[i] = _add(V[i], _scale(acc[j], A_v[i][j]))
                Q[i] = q0
                for j in range(i + 1 if tab.partitioned else i):
                    Q[i] = _add(Q[i], _scale(V[j], A[i][j]))
                acc[i] = _mul(minus_x, Q[i])
        q1, v1 = q0, v0
        for i in range(s):
            q1 = _add(q1, _scale(V[i], b[i]))
            v1 = _add(v1, _scale(acc[i], b_v[i]))
        cols.append((q1, v1))
    return ((cols[0][0], cols[1][0]), (cols[0][1], cols[1][1]))


def partitioned_step_matrix(tab, hw):
    """One-step matrix ``M(h w)`` of ``tab`` on the oscillator ``q'' = -w^2 q``.

    Parameters
    ----------
    tab : Tableau
        A partitioned method (a classical one gives its own step matrix, with
        eigenvalues ``R(+-i h w)``).
    hw : float or array_like
        ``h w`` (dimensionless: step times angular frequency).

    Returns
    -------
    ndarray, shape hw.shape + (2, 2)
        ``(q_{n+1}, h v_{n+1}) = M (q_n, h v_n)``; computed from exact
        polynomials in ``(h w)^2`` and evaluated in float64. Symplectic Euler:
        ``[[1 - (hw)^2, 1], [-(hw)^2, 1]]``; Stormer-Verlet ``[[1 - (hw)^2/2,
        1], [-(hw)^2 (1 - (hw)^2/4), 1 - (hw)^2/2]]``.
    """
    P = _step_matrix_poly(tab)
    x = np.asarray(hw, dtype=float) ** 2
    out = np.empty(x.shape + (2, 2))
    for r in range(2):
        for col in range(2):
            acc = np.zeros_like(x)
            for a in reversed(P[r][col]):
                acc = acc * x + float(a)
            out[..., r, col] = acc
    return out


def imaginary_axis_boundary(tab) -> float:
    """Largest ``y >= 0`` such that the method is stable on an undamped
    oscillator for every ``h w`` in ``[0, y]``.

    Classical: ``|R(i y')| <= 1`` for all ``0 <= y' <= y`` (RK4 and the 3/8
    rule ``2 sqrt 2``, Heun3 ``sqrt 3``; 0.0 when none, as Euler and
    Ralston's method). Partitioned: both eigenvalues of
    :func:`partitioned_step_matrix` in the closed unit disk (Stormer-Verlet
    and symplectic Euler: 2). Dimensionless (``h w``); ``inf`` if stable for
    every ``h w``.

    Worked out once per process for each tableau, by value (a tableau equal
    to one seen before, as the same scene loaded again, reuses the result):
    in exact arithmetic it takes seconds for the sixth-order geometric
    methods (yoshida6 about 2 s CPU, blanes-moan6 about 4 s). For the
    shipped geometric tableaux themselves (the objects of
    :data:`rk4h.geometric.GEOMETRIC`) it is read from data that a test
    recomputes.
    """
    shipped = _shipped_bound(tab)
    if shipped is not None:
        return shipped
    try:
        return _imaginary_axis_boundary_cached(tab)
    except TypeError:  # an unhashable stand-in for a tableau
        return _imaginary_axis_boundary(tab)


def _shipped_bound(tab):
    """The stored boundary of a shipped geometric tableau (this very object),
    else None. Reads :mod:`rk4h.geometric` only when it is loaded: a tableau
    of it cannot exist otherwise."""
    import sys

    geometric = sys.modules.get(f"{__package__}.geometric")
    name = getattr(tab, "name", None)
    if geometric is None or not isinstance(name, str) or geometric.GEOMETRIC.get(name) is not tab:
        return None
    return geometric._IMAGINARY_AXIS_BOUNDS.get(name)


@lru_cache(maxsize=256)
def _imaginary_axis_boundary_cached(tab) -> float:
    return _imaginary_axis_boundary(tab)


def _imaginary_axis_boundary(tab) -> float:
    if not tab.partitioned:
        r = stability_polynomial(tab)
        excess = _snap(_modulus_excess_on_imaginary_axis(r), _excess_bound(r, _stability_polynomial_bound(tab)))
        return math.sqrt(_first_violation(excess))
    (m11, m12), (m21, m22) = _step_matrix_poly(tab)
    trace = _add(m11, m22)
    det = _add(_mul(m11, m22), _scale(_mul(m12, m21), -1))
    one = [Fraction(1)]
    conditions = (_add(det, _scale(one, -1)),  # D <= 1
                  _scale(_add(det, one), -1),  # D >= -1
                  _add(trace, _scale(_add(one, det), -1)),  # T <= 1 + D
                  _scale(_add(trace, _add(one, det)), -1))  # -T <= 1 + D
    bound = _step_matrix_bound(tab)
    if bound is not None:
        bt, bd = bound
        n = max(len(bt), len(bd))
        both = [x + y for x, y in zip(_pad(bt, n), _pad(bd, n))]
        conditions = tuple(_snap(c, bd if k < 2 else both) for k, c in enumerate(conditions))
    return math.sqrt(min(_first_violation(c) for c in conditions))
