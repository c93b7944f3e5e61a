"""Splitting and composition methods as data, converted to partitioned tableaux.

Two ways to write a geometric integrator of ``q' = v``, ``v' = a(q, t)``
(positions ``q``, velocities ``v``; units of the model), both turned into the
equivalent explicit (partitioned) Runge-Kutta tableau of
:mod:`rk4h.methods`, so that the order conditions
(:mod:`rk4h.order_conditions`), the stability function
(:mod:`rk4h.stability_function`), the cost (evaluated stages, first same
as last) and the compiled loops (:mod:`rk4h.fast`) apply unchanged.

Splitting (:func:`splitting_tableau`)
    Drift and kick coefficients ``a_1..a_s``, ``b_1..b_s`` (dimensionless
    fractions of the step ``h``): for ``i = 1..s``, drift
    ``q <- q + a_i h v``, then kick ``v <- v + b_i h a(q, t + c_i h)`` with
    ``c_i = a_1 + ... + a_i``. A method that starts with a kick has
    ``a_1 = 0``; one that ends with a drift has ``b_s = 0``. Stage ``i`` of
    the tableau is the ``i``-th kick: its position ``Q_i`` is ``q`` after
    ``i`` drifts and its velocity ``V_i`` is ``v`` after ``i - 1`` kicks, so
    ``A[i][j] = a_j`` (``j <= i``), ``A_v[i][j] = b_j`` (``j < i``),
    ``b = a``, ``b_v = b`` (HLW sec. III.2.2, eq. 2.9, and sec. II.5).
Composition (:func:`composition_tableau`)
    A base method ``Phi_h`` and step fractions ``gamma_1..gamma_m``: one step
    is ``Phi_{gamma_m h} o ... o Phi_{gamma_1 h}`` (HLW sec. II.4). Its
    tableau is the block one (Butcher 2008, sec. 383): block ``(k, k)`` is
    ``gamma_k A``, block ``(k, l < k)`` is ``gamma_l 1 b^T``, weights
    ``(gamma_1 b, ..., gamma_m b)`` -- for both halves of a partitioned base.
    The end of one sub-step and the start of the next evaluate the force at
    the same position: such repeated evaluations are merged
    (:func:`_merge_repeated`), so Yoshida's three Stormer-Verlet sub-steps
    cost three evaluations per step, as written by hand.

Coefficients
    Each coefficient is a number or a string: a plain decimal numeral (any
    number of digits, read exactly as the decimal it shows), or an
    expression of the harness's parser (:func:`rk4h.expr.parse`) over
    integers and short decimals (``"1/(2 - 2^(1/3))"``, ``"sqrt(7)/3"``),
    evaluated with mpmath at :data:`DIGITS` significant digits. A value
    carries a bound on how far it may be from the intended one: 0 for
    rationals, ``2**-BITS`` relative for an irrational expression, one unit
    in the last place for a decimal with more than
    :data:`rk4h.methods.EXACT_DECIMALS` places (plus 4 ulps for a binary
    float). These bounds become the tableau's ``uncertainty``, with which
    its order conditions and stability boundaries are judged
    (``Tableau.coefficient_tol``). The drift, kick or step fractions must
    sum to 1 within those bounds; they are then scaled to sum to 1 exactly
    (so that the last node is 1 and first-same-as-last reuse is found).

References
----------
E. Hairer, C. Lubich, G. Wanner, *Geometric Numerical Integration*, 2nd ed.,
Springer 2006 (HLW): sec. II.4 (composition), II.5 (splitting), III.2
(partitioned RK form of splitting methods), V.3 (symmetric compositions).
J. C. Butcher, *Numerical Methods for Ordinary Differential Equations*, 2nd
ed., Wiley 2008, sec. 38 (composition of methods).
"""
from __future__ import annotations

import math
import numbers
import re
from fractions import Fraction
from functools import cached_property

from . import order_conditions
from .methods import EXACT_DECIMALS, FLOAT_ULPS, STORMER_VERLET, Tableau, decimal_digits

__all__ = ["DIGITS", "BITS", "coefficient", "splitting_tableau", "composition_tableau", "YOSHIDA4",
           "YOSHIDA6", "SUZUKI4", "FOREST_RUTH", "BLANES_MOAN4", "BLANES_MOAN6", "GEOMETRIC", "agreement"]

#: Significant decimal digits of mpmath's evaluation of an irrational coefficient.
DIGITS = 60
#: An irrational coefficient is kept as a binary fraction with this many bits
#: after the point, and may be ``2**-(BITS - 8)`` relative off (far below
#: double precision: the tableau's floats are its correctly rounded values).
BITS = 180

#: Largest power of two an intermediate value of an expression may reach.
_MAX_LOG2 = 4096
_DECIMAL = re.compile(r"[+-]?(\d+\.?\d*|\.\d+)([eE][+-]?\d+)?")


#: The irrational coefficients of the shipped methods below, as this module
#: evaluates them (text -> the integer ``round(value * 2**BITS)`` of mpmath's
#: value at :data:`DIGITS` digits): data, so that importing rk4h neither
#: imports mpmath nor parses and evaluates them (about 0.03 s CPU in every
#: process). ``tests/test_startup_lazy.py`` evaluates each again and holds it equal.
_EVALUATED = {
    "1/(2 - 2^(1/3))": 2070718996464094436956569525680530486015564304294558673,
    "-2^(1/3)/(2 - 2^(1/3))": -2608942452062300015554792024210751788412389486405515171,
    "1/(4 - 4^(1/3))": 635205259504941555443972100145849546355998462218780983,
    "1 - 4/(4 - 4^(1/3))": -1008325497153877363417541373433089001805254726691521756,
    "1/(2*(2 - 2^(1/3)))": 1035359498232047218478284762840265243007782152147279337,
    "(1 - 2^(1/3))/(2*(2 - 2^(1/3)))": -269111727799102789299111249265110651198412591055478249,
}


class _Bad(ValueError):
    pass


class _Valued:
    """A coefficient already evaluated: ``value`` and ``bound`` (Fractions)."""

    __slots__ = ("value", "bound")

    def __init__(self, value: Fraction, bound: Fraction):
        self.value, self.bound = value, bound


def _mp_eval(node, mp):
    from . import expr as E

    if isinstance(node, E.Num):
        v = node.value
        text = repr(v)
        d = decimal_digits(text)
        if d is not None and d[0] > EXACT_DECIMALS:
            raise _Bad(f"holds the number {text}, not exact; in an expression use integers and decimals of at "
                       f"most {EXACT_DECIMALS} places (give a long decimal as a plain number)")
        f = Fraction(text)
        return mp.mpf(f.numerator) / f.denominator
    if isinstance(node, E.Add):
        return mp.fsum(_mp_eval(t, mp) for t in node.terms)
    if isinstance(node, E.Mul):
        out = mp.mpf(1)
        for f in node.factors:
            out *= _mp_eval(f, mp)
        return out
    if isinstance(node, E.Pow):
        base, exp = _mp_eval(node.base, mp), _mp_eval(node.exp, mp)
        if base < 0 and exp != int(exp):
            raise _Bad("takes a non-integer power of a negative number")
        if base == 0 and exp <= 0:
            raise _Bad("divides by zero")
        if base != 0 and abs(exp * mp.log(abs(base), 2)) > _MAX_LOG2:
            raise _Bad(f"is too large (a power beyond 2^{_MAX_LOG2})")
        return mp.power(base, exp)
    if isinstance(node, E.Call):
        arg = _mp_eval(node.arg, mp)
        if node.func in ("sqrt", "log") and arg < 0 or node.func == "log" and arg == 0:
            raise _Bad(f"takes {node.func} of a number outside its domain")
        if node.func in ("exp", "sinh", "cosh") and abs(arg) > _MAX_LOG2 / 2:
            raise _Bad(f"is too large ({node.func} of {float(arg):.3g})")
        return getattr(mp, node.func)(arg)
    raise _Bad("has a symbol; a coefficient is a constant")


def _rational(node):
    """The exact value of an expression of integers and short decimals built
    with + - * / and integer powers, else None."""
    from . import expr as E

    if isinstance(node, E.Num):
        return Fraction(repr(node.value))
    if isinstance(node, E.Add):
        parts = [_rational(t) for t in node.terms]
        return None if None in parts else sum(parts, Fraction(0))
    if isinstance(node, E.Mul):
        out = Fraction(1)
        for f in node.factors:
            x = _rational(f)
            if x is None:
                return None
            out *= x
        return out
    if isinstance(node, E.Pow):
        base, exp = _rational(node.base), _rational(node.exp)
        if base is None or exp is None or exp.denominator != 1 or abs(exp) > 64 or (base == 0 and exp < 0):
            return None
        if abs(exp) * max(base.numerator.bit_length(), base.denominator.bit_length()) > _MAX_LOG2:
            return None  # left to the evaluation below, which refuses it as too large
        return base ** int(exp)
    return None


def coefficient(x, where: str = "coefficient") -> tuple[Fraction, Fraction]:
    """``(value, bound)`` of one coefficient (module docstring, "Coefficients").

    Parameters
    ----------
    x : int, float, Fraction or str
        A number, a decimal numeral or an expression such as ``"1/(2 - 2^(1/3))"``.
    where : str
        How error messages name it (``"a[2]"``).

    Returns
    -------
    value : Fraction
        Exact for rationals and decimals; a binary fraction with :data:`BITS`
        bits after the point for an irrational expression.
    bound : Fraction
        How far ``value`` may be from the intended coefficient (absolute, >= 0).

    Raises
    ------
    ValueError
        ``"{where} ..."``: not a number or a constant expression, not finite,
        a symbol, a domain error.
    """
    if isinstance(x, (bool,)) or x is None:
        raise ValueError(f"{where} = {x!r:.40} is not a number or an expression such as '1/(2 - 2^(1/3))'")
    ulp = FLOAT_ULPS * Fraction(1, 2**52)
    if isinstance(x, Fraction) or isinstance(x, numbers.Integral):
        return Fraction(x), Fraction(0)
    if isinstance(x, numbers.Real):
        xf = float(x)
        if not math.isfinite(xf):
            raise ValueError(f"{where} = {xf!r} is not finite")
        f = Fraction(xf)
        # a float carries its binary rounding and is never finer than double precision
        return f, max(_decimal_bound(repr(xf), f), ulp * abs(f)) + (ulp * abs(f) if Fraction(repr(xf)) != f else 0)
    if not isinstance(x, str):
        raise ValueError(f"{where} = {x!r:.40} is not a number or an expression such as '1/(2 - 2^(1/3))'")
    text = x.strip()
    if _DECIMAL.fullmatch(text):
        f = Fraction(text)
        return f, _decimal_bound(text, f)
    if text in _EVALUATED:
        return _irrational(_EVALUATED[text])
    from . import expr as E

    try:
        node = E.parse(text, [])
    except (E.ExprError, ValueError) as e:
        raise ValueError(f"{where} = {text!r:.60} is not a constant expression: {str(e).splitlines()[0]}") from None
    exact = _rational(node)
    if exact is not None:
        return exact, Fraction(0)
    import mpmath

    mp = mpmath.mp
    try:
        with mpmath.workdps(DIGITS):
            v = _mp_eval(node, mp)
            if not isinstance(v, mpmath.mpf) or not mp.isfinite(v):
                raise _Bad("is not a finite real number")
            scaled = int(mp.nint(v * mp.mpf(2) ** BITS))
    except _Bad as e:
        raise ValueError(f"{where} = {text!r:.60} {e}") from None
    except (ZeroDivisionError, ValueError, OverflowError) as e:
        raise ValueError(f"{where} = {text!r:.60} cannot be evaluated ({type(e).__name__})") from None
    return _irrational(scaled)


def _irrational(scaled: int) -> tuple[Fraction, Fraction]:
    """``(value, bound)`` of an irrational coefficient evaluated to ``scaled / 2**BITS``."""
    f = Fraction(scaled, 2**BITS)
    return f, Fraction(1, 2**(BITS - 8)) * max(1, abs(f))


def _decimal_bound(text: str, f: Fraction) -> Fraction:
    d = decimal_digits(text)
    if d is None or d[0] <= EXACT_DECIMALS or f == 0:
        return Fraction(0)
    places, sig = d
    return max(Fraction(1, 10**places), abs(f) * Fraction(1, 10**(sig - 1)))


def _values(seq, field_: str, name: str):
    if isinstance(seq, (str, bytes)) or not hasattr(seq, "__len__") or len(seq) == 0:
        raise ValueError(f"method {name!r}: `{field_}` must be a non-empty list of coefficients, got {seq!r:.60}")
    out = []
    for i, x in enumerate(seq):
        if isinstance(x, _Valued):
            out.append((x.value, x.bound))
            continue
        try:
            out.append(coefficient(x, f"entry {field_}[{i}]"))
        except ValueError as e:
            raise ValueError(f"method {name!r}: `{field_}` {e}") from None
    return [v for v, _ in out], [d for _, d in out]


def _normalise(vals, bounds, field_: str, name: str, what: str):
    """Scale ``vals`` to sum to 1 exactly, when they do within their bounds."""
    total = sum(vals, Fraction(0))
    slack = sum(bounds, Fraction(0))
    if abs(total - 1) > slack:
        raise ValueError(f"method {name!r}: `{field_}` must sum to 1 ({what}), got {float(total)!r}")
    if total == 1:
        return list(vals), list(bounds)
    return [v / total for v in vals], [d + 2 * abs(v) * slack for v, d in zip(vals, bounds)]


class SeparableTableau(Tableau):
    """A partitioned :class:`~rk4h.methods.Tableau` that is a splitting or
    composition method: equivalent to it on ``q' = v``, ``v' = a(q, t)``
    (the only systems the harness gives a partitioned method), not on a
    general partitioned system. Its :attr:`order` and
    :attr:`order_residuals` are therefore over
    :func:`rk4h.order_conditions.separable_trees` (a classical
    composition keeps the plain trees)."""

    @cached_property
    def order(self) -> int:
        return order_conditions.order(self.A_exact, self.b_exact, self.A_v_exact, self.b_v_exact,
                                      uncertainty=self.uncertainty, trees=self._trees)

    @cached_property
    def order_residuals(self) -> list[dict]:
        return order_conditions.residuals(self.A_exact, self.b_exact, self.A_v_exact, self.b_v_exact,
                                          uncertainty=self.uncertainty, max_order=self.order + 1,
                                          trees=self._trees)

    @property
    def _trees(self):
        return order_conditions.separable_trees if self.partitioned else None

    _order_trees = _trees


def _build(name, A, b, A_v, b_v, dA, db, dA_v, db_v, description) -> Tableau:
    """A tableau of exact entries with the given per-entry bounds as its precision."""
    tab = SeparableTableau(name, A, b, None, None, A_v, b_v, description)
    if any(x for m in (dA, dA_v) if m is not None for row in m for x in row) or any(
            x for v in (db, db_v) if v is not None for x in v):
        t = lambda M: tuple(tuple(Fraction(x) for x in row) for row in M)  # noqa: E731
        unc = {"A": t(dA), "b": tuple(db), "c": tuple(sum(row, Fraction(0)) for row in dA),
               "A_v": t(dA_v) if dA_v is not None else None, "b_v": tuple(db_v) if db_v is not None else None}
        worst = max(x for m in (dA, dA_v) if m is not None for row in m for x in row)
        worst = max(worst, max(db), max(db_v) if db_v is not None else 0)
        object.__setattr__(tab, "_uncertainty", unc)
        object.__setattr__(tab, "coefficient_tol", worst)
        object.__setattr__(tab, "precision", f"computed to within {float(worst):.1e} per entry")
    return tab


def splitting_tableau(name: str, a, b, *, description: str = "") -> Tableau:
    """The partitioned tableau of the drift-kick splitting ``a``, ``b``.

    Parameters
    ----------
    name : str
    a, b : sequence of s coefficients
        Drift and kick fractions of the step (module docstring, "Splitting"):
        drift ``a_1``, kick ``b_1``, drift ``a_2``, ... kick ``b_s``. Each
        list must sum to 1 (within the coefficients' precision).
    description : str

    Returns
    -------
    Tableau
        ``s`` stages, partitioned, ``A[i][j] = a_j (j <= i)``, ``A_v[i][j] =
        b_j (j < i)``, ``b = a``, ``b_v = b``; repeated evaluations merged.

    Raises
    ------
    ValueError
        One line naming the method and ``a`` or ``b``.
    """
    av, ad = _values(a, "a", name)
    bv, bd = _values(b, "b", name)
    if len(av) != len(bv):
        raise ValueError(f"method {name!r}: `b` must have as many entries as `a` ({len(av)}: drift a_i, then kick "
                         f"b_i; end with b = 0 after a last drift), got {len(bv)}")
    av, ad = _normalise(av, ad, "a", name, "the drifts make one step")
    bv, bd = _normalise(bv, bd, "b", name, "the kicks make one step")
    s = len(av)
    z = Fraction(0)
    A = [[av[j] if j <= i else z for j in range(s)] for i in range(s)]
    dA = [[ad[j] if j <= i else z for j in range(s)] for i in range(s)]
    A_v = [[bv[j] if j < i else z for j in range(s)] for i in range(s)]
    dA_v = [[bd[j] if j < i else z for j in range(s)] for i in range(s)]
    A, av, A_v, bv, dA, ad, dA_v, bd = _merge_repeated(A, av, A_v, bv, dA, ad, dA_v, bd)
    return _build(name, A, av, A_v, bv, dA, ad, dA_v, bd, description)


def composition_tableau(name: str, base: Tableau | str, gamma, *, description: str = "") -> Tableau:
    """The tableau of the composition ``Phi_{gamma_m h} o ... o Phi_{gamma_1 h}``.

    Parameters
    ----------
    name : str
    base : Tableau or str
        The base method (a name of :data:`rk4h.methods.METHODS` or a tableau).
    gamma : sequence of m coefficients
        Step fractions, in the order the sub-steps are taken; they must sum
        to 1 (within their precision).
    description : str

    Returns
    -------
    Tableau
        The block tableau (module docstring, "Composition"), classical or
        partitioned as ``base``, with repeated evaluations merged.

    Raises
    ------
    ValueError
        One line naming the method and ``base`` or ``gamma``.
    """
    from .methods import METHODS

    if isinstance(base, str):
        if base not in METHODS:
            raise ValueError(f"method {name!r}: `base` must be one of {sorted(METHODS)}, got {base!r}")
        base = METHODS[base]
    if not isinstance(base, Tableau):
        raise ValueError(f"method {name!r}: `base` must be a method name, got {base!r:.60}")
    gv, gd = _values(gamma, "gamma", name)
    gv, gd = _normalise(gv, gd, "gamma", name, "the sub-steps make one step")
    u = base.uncertainty
    zero_m = tuple(tuple(Fraction(0) for _ in row) for row in base.A_exact)
    zero_v = tuple(Fraction(0) for _ in base.b_exact)
    halves = [(base.A_exact, base.b_exact, u[0] if u else zero_m, u[1] if u else zero_v)]
    if base.partitioned:
        halves.append((base.A_v_exact, base.b_v_exact, u[2] if u else zero_m, u[3] if u else zero_v))
    s, m = base.n_stages, len(gv)
    out = []
    for Ab, bb, dAb, dbb in halves:
        n = s * m
        A = [[Fraction(0)] * n for _ in range(n)]
        dA = [[Fraction(0)] * n for _ in range(n)]
        for k in range(m):
            for i in range(s):
                r = k * s + i
                for l in range(k):
                    for j in range(s):
                        A[r][l * s + j] = gv[l] * bb[j]
                        dA[r][l * s + j] = abs(gv[l]) * dbb[j] + gd[l] * abs(bb[j])
                for j in range(s):
                    A[r][k * s + j] = gv[k] * Ab[i][j]
                    dA[r][k * s + j] = abs(gv[k]) * dAb[i][j] + gd[k] * abs(Ab[i][j])
        w = [gv[k] * bb[j] for k in range(m) for j in range(s)]
        dw = [abs(gv[k]) * dbb[j] + gd[k] * abs(bb[j]) for k in range(m) for j in range(s)]
        out.append((A, w, dA, dw))
    if not base.partitioned:
        A, w, dA, dw = out[0]
        A, w, _, _, dA, dw, _, _ = _merge_repeated(A, w, None, None, dA, dw, None, None)
        return _build(name, A, w, None, None, dA, dw, None, None, description)
    (A, w, dA, dw), (A_v, w_v, dA_v, dw_v) = out
    A, w, A_v, w_v, dA, dw, dA_v, dw_v = _merge_repeated(A, w, A_v, w_v, dA, dw, dA_v, dw_v)
    return _build(name, A, w, A_v, w_v, dA, dw, dA_v, dw_v, description)


def _merge_repeated(A, b, A_v, b_v, dA, db, dA_v, db_v):
    """Evaluate each right-hand side once: a later stage ``j`` whose argument
    equals an earlier stage ``i``'s (same row of ``A``, hence same node;
    exact equality) uses stage ``i``'s evaluation. Classical: column ``j`` of
    ``A`` and ``b_j`` move to ``i`` and stage ``j`` is dropped. Partitioned
    (the argument is the position ``Q``): column ``j`` of ``A_v`` and
    ``b_v[j]`` move to ``i``; stage ``j`` stays (its velocity ``V_j`` may be
    used) but is no longer evaluated. Stages neither evaluated nor used are
    dropped. Lower-triangularity is kept (``i < j``)."""
    A = [list(r) for r in A]
    dA = [list(r) for r in dA]
    b, db = list(b), list(db)
    part = A_v is not None
    if part:
        A_v, dA_v = [list(r) for r in A_v], [list(r) for r in dA_v]
        b_v, db_v = list(b_v), list(db_v)
    M, dM, w, dw = (A_v, dA_v, b_v, db_v) if part else (A, dA, b, db)
    n = len(b)
    for j in range(n):
        for i in range(j):
            if A[i] == A[j]:
                if not (any(M[r][j] for r in range(n)) or w[j]):
                    break
                for r in range(n):
                    M[r][i] += M[r][j]
                    dM[r][i] += dM[r][j]
                    M[r][j] = Fraction(0)
                    dM[r][j] = Fraction(0)
                w[i] += w[j]
                dw[i] += dw[j]
                w[j] = Fraction(0)
                dw[j] = Fraction(0)
                break
    keep = []
    for j in range(n):
        evaluated = w[j] != 0 or any(M[r][j] for r in range(n))
        used = part and (b[j] != 0 or any(A[r][j] for r in range(n)))
        keep.append(evaluated or used)
    if not any(keep):
        keep[0] = True
    idx = [j for j in range(n) if keep[j]]

    def sub(X):
        return None if X is None else [[X[r][c] for c in idx] for r in idx]

    def subv(x):
        return None if x is None else [x[c] for c in idx]

    return sub(A), subv(b), sub(A_v), subv(b_v), sub(dA), subv(db), sub(dA_v), subv(db_v)


# -- shipped methods ----------------------------------------------------------------------------------
def _palindrome(half, middle):
    return list(half) + [middle] + list(reversed(half))


#: Yoshida's fourth-order composition of Stormer-Verlet, three sub-steps
#: ``gamma_1 = gamma_3 = 1/(2 - 2^(1/3))``, ``gamma_2 = -2^(1/3)/(2 - 2^(1/3))``
#: (H. Yoshida, Construction of higher order symplectic integrators, *Phys.
#: Lett. A* 150 (1990) 262-268, eq. 4.11; HLW sec. II.4, eq. 4.4; also
#: Forest & Ruth 1990). Exact; 3 force evaluations per step.
YOSHIDA4 = composition_tableau(
    "yoshida4", STORMER_VERLET,
    ["1/(2 - 2^(1/3))", "-2^(1/3)/(2 - 2^(1/3))", "1/(2 - 2^(1/3))"],
    description="Yoshida's 4th-order composition of Stormer-Verlet, 3 sub-steps (Yoshida 1990)",
)

#: Yoshida's sixth-order composition of Stormer-Verlet, seven sub-steps
#: ``w3 w2 w1 w0 w1 w2 w3``, solution A of Yoshida 1990, Table 1 (printed
#: there to 15 digits: w1 = -1.17767998417887, w2 = 0.235573213359357,
#: w3 = 0.784513610477560; the 40-digit values are the roots of his
#: sixth-order equations, e.g. in the C++ and Julia codes that ship
#: "Yoshida6"; w0 = 1 - 2 (w1 + w2 + w3)). 7 force evaluations per step.
_Y6 = ("0.7845136104775572638194976338663498757768", "0.2355732133593581336847931829785346016865",
       "-1.177679984178871006946415680964315734639")
YOSHIDA6 = composition_tableau(
    "yoshida6", STORMER_VERLET,
    _palindrome(_Y6, "1.315186320683911218884249728238862514352"),
    description="Yoshida's 6th-order composition of Stormer-Verlet, 7 sub-steps, solution A (Yoshida 1990)",
)

#: Suzuki's fourth-order five-fold composition of Stormer-Verlet,
#: ``p p (1 - 4p) p p`` with ``p = 1/(4 - 4^(1/3))`` (M. Suzuki, Fractal
#: decomposition of exponential operators..., *Phys. Lett. A* 146 (1990)
#: 319-323; HLW sec. II.4, eq. 4.5). Exact; 5 force evaluations per step.
SUZUKI4 = composition_tableau(
    "suzuki4", STORMER_VERLET,
    ["1/(4 - 4^(1/3))"] * 2 + ["1 - 4/(4 - 4^(1/3))"] + ["1/(4 - 4^(1/3))"] * 2,
    description="Suzuki's 4th-order five-fold composition of Stormer-Verlet (Suzuki 1990)",
)

#: Forest and Ruth's fourth-order splitting, position (drift-first) form
#: (E. Forest, R. D. Ruth, Fourth-order symplectic integration, *Physica D* 43
#: (1990) 105-117; theta = 1/(2 - 2^(1/3))): drifts theta/2, (1 - theta)/2,
#: (1 - theta)/2, theta/2; kicks theta, 1 - 2 theta, theta, 0. Exact; 3 force
#: evaluations per step.
FOREST_RUTH = splitting_tableau(
    "forest-ruth",
    a=["1/(2*(2 - 2^(1/3)))", "(1 - 2^(1/3))/(2*(2 - 2^(1/3)))", "(1 - 2^(1/3))/(2*(2 - 2^(1/3)))",
       "1/(2*(2 - 2^(1/3)))"],
    b=["1/(2 - 2^(1/3))", "-2^(1/3)/(2 - 2^(1/3))", "1/(2 - 2^(1/3))", "0"],
    description="Forest-Ruth 4th-order splitting, drift first (Forest & Ruth 1990)",
)


def _bm(a_half, b_half, name, description):
    """A symmetric Blanes-Moan splitting ``a1 b1 a2 b2 ... a_k b_k a_{k+1} b_k ... b1 a1``
    whose last drift and kick fractions close the sums (``a_{k+1} = 1 - 2 sum
    a_i``, ``b_k = 1/2 - sum b_i``), computed exactly from the printed ones."""
    av = [coefficient(x) for x in a_half]
    bv = [coefficient(x) for x in b_half]
    a_mid = (1 - 2 * sum((v for v, _ in av), Fraction(0)), 2 * sum((d for _, d in av), Fraction(0)))
    b_last = (Fraction(1, 2) - sum((v for v, _ in bv), Fraction(0)), sum((d for _, d in bv), Fraction(0)))
    a_all = _palindrome(av, a_mid)
    b_all = bv + [b_last, b_last] + list(reversed(bv)) + [(Fraction(0), Fraction(0))]
    return splitting_tableau(name, [_Valued(*x) for x in a_all], [_Valued(*x) for x in b_all],
                             description=description)


#: Blanes and Moan's optimised fourth-order symmetric splitting S6 (six
#: kicks; S. Blanes, P. C. Moan, Practical symplectic partitioned
#: Runge-Kutta and Runge-Kutta-Nystrom methods, *J. Comput. Appl. Math.* 142
#: (2002) 313-330, Table 2, order 4): drifts a1 = 0.0792036964311957,
#: a2 = 0.353172906049774, a3 = -0.0420650803577195, a4 = 1 - 2(a1+a2+a3);
#: kicks b1 = 0.209515106613362, b2 = -0.143851773179818, b3 = 1/2 - (b1+b2);
#: a1 b1 a2 b2 a3 b3 a4 b3 a3 b2 a2 b1 a1 (drift first). Valid for any
#: separable splitting (bi-coloured order conditions), printed to 15 digits:
#: the tableau is judged at that precision. 6 force evaluations per step.
BLANES_MOAN4 = _bm(["0.0792036964311957", "0.353172906049774", "-0.0420650803577195"],
                   ["0.209515106613362", "-0.143851773179818"], "blanes-moan4",
                   "Blanes-Moan optimised 4th-order splitting S6, 6 kicks (Blanes & Moan 2002)")

#: Blanes and Moan's optimised sixth-order symmetric splitting S10 (ten
#: kicks; Blanes & Moan 2002, Table 2, order 6): drifts
#: a1 = 0.0502627644003922, a2 = 0.413514300428344, a3 = 0.0450798897943977,
#: a4 = -0.188054853819569, a5 = 0.541960678450780, a6 = 1 - 2(a1+...+a5);
#: kicks b1 = 0.148816447901042, b2 = -0.132385865767784,
#: b3 = 0.067307604692185, b4 = 0.432666402578175, b5 = 1/2 - (b1+...+b4);
#: drift first. Printed to 15 digits. 10 force evaluations per step.
BLANES_MOAN6 = _bm(["0.0502627644003922", "0.413514300428344", "0.0450798897943977", "-0.188054853819569",
                    "0.541960678450780"],
                   ["0.148816447901042", "-0.132385865767784", "0.067307604692185", "0.432666402578175"],
                   "blanes-moan6", "Blanes-Moan optimised 6th-order splitting S10, 10 kicks (Blanes & Moan 2002)")

#: The shipped geometric methods by name (added to :data:`rk4h.methods.METHODS`).
GEOMETRIC: dict[str, Tableau] = {t.name: t for t in (YOSHIDA4, YOSHIDA6, SUZUKI4, FOREST_RUTH, BLANES_MOAN4,
                                                     BLANES_MOAN6)}
#: The end of each shipped method's stable interval of the imaginary axis
#: (:func:`rk4h.stability_function.imaginary_axis_boundary`, dimensionless
#: ``h w``), as data for these very objects: its exact root isolation takes
#: about 2 s CPU for yoshida6 and 4 s for blanes-moan6, in every process whose
#: methods table lists them. ``tests/test_startup.py`` recomputes each and
#: holds it equal to this.
_IMAGINARY_AXIS_BOUNDS = {"yoshida4": 1.57340194743454, "yoshida6": 2.2690579963976596,
                          "suzuki4": 2.72097453856015, "forest-ruth": 1.57340194743454,
                          "blanes-moan4": 3.1328233983908755, "blanes-moan6": 3.1342475220889923}


def agreement(written: Tableau, shipped: Tableau) -> dict:
    """How closely a tableau written elsewhere (a scene's ``[methods.NAME]``)
    reproduces a shipped one, entry by entry over ``A, b, c`` and, for a
    partitioned pair, ``A_v, b_v``.

    Returns
    -------
    dict
        ``shape`` (bool: same stages and partitioning), ``bit_identical``
        (bool: the float64 coefficients the integrators use are equal, so
        the runs are bit-identical), ``max_ulps`` (int: the largest float64
        difference in units in the last place of the shipped entry; 0 when
        bit-identical) and ``within_bound`` (bool: every exact difference is
        within the sum of the two tableaux' stated coefficient uncertainties,
        :attr:`rk4h.methods.Tableau.uncertainty`: the same method at the
        precision each was given with).
    """
    import numpy as np

    keys = ("A", "b", "c") + (("A_v", "b_v") if shipped.partitioned else ())
    if written.partitioned != shipped.partitioned or written.A.shape != shipped.A.shape:
        return {"shape": False, "bit_identical": False, "max_ulps": None, "within_bound": False}
    ulps, same = 0, True
    for k in keys:
        x, y = np.asarray(getattr(written, k)), np.asarray(getattr(shipped, k))
        same = same and bool(np.array_equal(x, y))
        spacing = np.spacing(np.maximum(np.abs(y), np.finfo(float).tiny))
        ulps = max(ulps, int(np.max(np.rint(np.abs(x - y) / spacing))))

    def flat(m):
        return [] if m is None else [v for row in m for v in (row if isinstance(row, (tuple, list)) else (row,))]

    zero = (None,) * 4
    du, ds = written.uncertainty or zero, shipped.uncertainty or zero
    ok = True
    for i, k in enumerate(("A_exact", "b_exact", "A_v_exact", "b_v_exact")):
        xs, ys = flat(getattr(written, k)), flat(getattr(shipped, k))
        bx = flat(du[i]) or [Fraction(0)] * len(xs)
        by = flat(ds[i]) or [Fraction(0)] * len(ys)
        ok = ok and all(abs(x - y) <= ex + ey for x, y, ex, ey in zip(xs, ys, bx, by))
    return {"shape": True, "bit_identical": same, "max_ulps": ulps, "within_bound": ok}
