"""Explicit one-step methods as data: (partitioned) Butcher tableaux.

A method is a :class:`Tableau`, built by :func:`make_tableau` from its
coefficients (numbers or rational strings such as ``"1/3"``, kept exactly as
:class:`fractions.Fraction`). Everything else about it is computed from the
coefficients: its order (:mod:`rk4h.order_conditions`), its stability
function (:mod:`rk4h.stability_function`), which stages are evaluated and
which evaluation is reused by the next step (first same as last, FSAL), hence
its cost per step. Stepping is one pure function, :func:`rk_step`, shared by
every method; the compiled loops of :mod:`rk4h.fast` are generated from the
same data.

Classical methods use one tableau (``A``, ``b``, ``c``) for the whole state.
A *partitioned* method (``A_v``, ``b_v`` given) integrates ``y = [q, v]``
(positions, then velocities, equal halves) of a separable second-order system

    dq/dt = v,        dv/dt = a(q, t)

with ``A, b`` for the ``q`` half and ``A_v, b_v`` for the ``v`` half: stage
``i`` has ``Q_i = q + h sum_j A[i][j] V_j`` and ``V_i = v + h sum_j
A_v[i][j] a(Q_j, t + c_j h)``, the step ``q + h sum_i b_i V_i`` and ``v + h
sum_i b_v[i] a(Q_i, ...)``. The position slope of a stage is its own
velocity ``V_i`` (never a call of the right-hand side); only accelerations
are evaluated, and only those some weight or coefficient uses. Because a
stage's velocity needs accelerations and its position needs velocities, a
*diagonal* entry is explicit too as long as one row does not have both:
``A[i][i] != 0`` (then ``V_i`` is formed first) or ``A_v[i][i] != 0`` (then
``Q_i`` and its acceleration come first). Entries above the diagonal are
refused. This is what makes the Stormer-Verlet method -- the Lobatto
IIIA-IIIB pair, implicit as a general partitioned method -- an explicit
two-stage tableau here (HLW sec. II.2.2).

References
----------
J. C. Butcher, *Numerical Methods for Ordinary Differential Equations*, 2nd ed.,
Wiley 2008, sec. 23 and 32 (tableaux, explicit methods, order).
E. Hairer, S. P. Norsett, G. Wanner, *Solving Ordinary Differential Equations I*,
2nd ed., Springer 1993, sec. II.1 (Table 1.1: Heun's third-order method;
Table 1.2: classical RK4 and the 3/8 rule), sec. II.2 (order conditions).
E. Hairer, C. Lubich, G. Wanner, *Geometric Numerical Integration*, 2nd ed.,
Springer 2006 (HLW): sec. I.1.4 (symplectic Euler, Stormer-Verlet), sec. II.2
(partitioned RK methods, Lobatto IIIA-IIIB), sec. III.2 (their order).
A. Ralston, Runge-Kutta methods with minimum error bounds, *Math. Comp.* 16
(1962) 431-437.
"""
from __future__ import annotations

import math
import numbers
from dataclasses import dataclass, field
from fractions import Fraction
from functools import cached_property

import numpy as np

from . import order_conditions

__all__ = ["Tableau", "make_tableau", "RK4", "RK38", "HEUN3", "RALSTON", "EULER", "SYMPLECTIC_EULER",
           "STORMER_VERLET", "METHODS", "get_method", "rk_step", "stage_time", "start_slope", "end_slope",
           "ORDER_TOL", "EXACT_DECIMALS", "FLOAT_ULPS"]

#: Former relative tolerance of the order conditions for float tableaux,
#: kept for callers of :func:`rk4h.order_conditions.order` (``tol=``);
#: a :class:`Tableau` uses its coefficient uncertainty instead
#: (:attr:`Tableau.coefficient_tol`).
ORDER_TOL = Fraction(1, 2**40)
#: A decimal entry with at most this many decimal places (``0.5``, ``0.4``,
#: ``0.375``) is read as exact; one with more (``0.29697761``, a float
#: printed as ``0.16666666666666666``) as rounded to its last place.
EXACT_DECIMALS = 3
#: Uncertainty of a float entry from its binary rounding: this many units of
#: 2**-52 relative (a correctly rounded value is within half of one).
FLOAT_ULPS = 4


# -- parsing ------------------------------------------------------------------------------------------
def _fmt(x: Fraction) -> str:
    return str(x)


class _Parse:
    """Converts one method's entries, collecting those that came from inexact floats."""

    def __init__(self, name: str):
        self.name = name
        self.inexact: list[str] = []
        #: where -> (decimal places, significant digits, is a float) of every decimal entry
        self.decimals: dict[str, tuple[int, int, bool]] = {}

    def fail(self, field_: str, text: str):
        raise ValueError(f"method {self.name!r}: `{field_}` {text}")

    def entry(self, field_: str, where: str, x) -> Fraction:
        bad = (f"entry {where} = {x!r:.40} is not a number or a rational string "
               f"(such as '1/3', '-2', '0.5')")
        if isinstance(x, (bool, np.bool_)) or x is None:
            self.fail(field_, bad)
        if isinstance(x, Fraction):
            f = x
        elif isinstance(x, numbers.Integral):
            f = Fraction(int(x))
        elif isinstance(x, numbers.Real):
            xf = float(x)
            if not math.isfinite(xf):
                self.fail(field_, f"entry {where} = {xf!r} is not finite")
            f = Fraction(xf)
            if Fraction(repr(xf)) != f:  # 0.1, 1/3 as floats: the binary value is kept, and noted
                self.inexact.append(where)
            self._decimal(where, repr(xf), True)
        elif isinstance(x, str):
            try:
                f = Fraction(x.strip())
            except (ValueError, ZeroDivisionError):
                self.fail(field_, bad)
            self._decimal(where, x, False)
        else:
            try:
                f = Fraction(x)  # decimal.Decimal
            except (TypeError, ValueError, ZeroDivisionError, OverflowError):
                self.fail(field_, bad)
            self._decimal(where, str(x), False)
        try:
            finite = math.isfinite(float(f))
        except OverflowError:
            finite = False
        if not finite:
            self.fail(field_, f"entry {where} = {x!r:.40} is not finite in double precision")
        return f

    def _decimal(self, where: str, text: str, is_float: bool):
        digits = decimal_digits(text)
        if digits is not None:
            self.decimals[where] = (*digits, is_float)

    @staticmethod
    def _seq(x):
        if isinstance(x, np.ndarray):
            return x.tolist()
        if isinstance(x, (list, tuple)):
            return list(x)
        return None

    def matrix(self, field_: str, M):
        rows = self._seq(M)
        if not rows:
            self.fail(field_, f"must be a non-empty square matrix (a list of s rows of s entries), got {M!r:.60}")
        s = len(rows)
        out = []
        for i, row in enumerate(rows):
            r = self._seq(row)
            if r is None:
                self.fail(field_, f"must be a square matrix (a list of s rows of s entries): "
                                  f"row {i} is {row!r:.40}, not a list")
            if len(r) != s:
                self.fail(field_, f"must be square (s x s): row {i} has {len(r)} entries, `{field_}` has {s} rows")
            out.append(tuple(self.entry(field_, f"{field_}[{i}][{j}]", x) for j, x in enumerate(r)))
        return tuple(out)

    def vector(self, field_: str, v, s: int, what: str):
        entries = self._seq(v)
        if entries is None:
            self.fail(field_, f"must be a list of {s} entries ({what}), got {v!r:.60}")
        if len(entries) != s:
            self.fail(field_, f"must have {s} entries ({what} of the {s} x {s} `A`), got {len(entries)}")
        return tuple(self.entry(field_, f"{field_}[{i}]", x) for i, x in enumerate(entries))


def decimal_digits(text: str):
    """``(decimal places, significant digits)`` of a decimal numeral
    (``"0.29697761"`` -> (8, 8), ``"-3.05096516"`` -> (8, 9), ``"1e-05"`` ->
    (5, 1), ``"2.5E+3"`` -> (0, 2)); None for an integer or a rational
    (``"2"``, ``"1/3"``), which are exact. Trailing zeros count: they were typed."""
    t = str(text).strip().lower().lstrip("+-")
    if "/" in t or not ("." in t or "e" in t):
        return None
    mant, _, exp = t.partition("e")
    try:
        e = int(exp) if exp else 0
    except ValueError:
        return None
    whole, _, frac = mant.partition(".")
    if not (whole + frac).isdigit():
        return None
    sig = len((whole + frac).lstrip("0")) or 1
    return max(len(frac) - e, 0), sig


def _uncertainty(P: "_Parse", mats: dict) -> tuple[dict, int | None, int | None]:
    """Per-entry uncertainty (Fraction, absolute) of each coefficient, from the
    precision it was given with: ``(name -> matrix/vector of bounds, D, S)``.

    A tableau is *rounded* when some decimal entry has more than
    :data:`EXACT_DECIMALS` decimal places; ``D`` and ``S`` are then the most
    decimal places and significant digits of those entries, and every nonzero
    decimal entry ``x`` may be off by ``max(10**-D, 10**(1-S) |x|, FLOAT_ULPS
    2**-52 |x|)`` (one unit in the last place, absolute for tables printed to
    fixed decimals, relative for tables printed to fixed significant digits;
    never finer than double precision: 17 printed digits of a value computed
    in floats carry its few ulps of round-off). A float entry may in addition
    be :data:`FLOAT_ULPS` units of ``2**-52 |x|`` off (binary rounding).
    Integers, rational strings and zeros are exact.
    """
    rounded = [v for v in P.decimals.values() if v[0] > EXACT_DECIMALS]
    D = max((v[0] for v in rounded), default=None)
    S = max((v[1] for v in rounded), default=None)
    ulp = FLOAT_ULPS * Fraction(1, 2**52)

    def one(where, x):
        if x == 0 or where not in P.decimals:
            return Fraction(0)
        u = Fraction(0)
        if D is not None:  # never finer than double precision, in which the integrators use it
            u = max(Fraction(1, 10**D), abs(x) * max(Fraction(1, 10**(S - 1)), ulp))
        if where in P.inexact:  # a float whose binary value is not its decimal
            u += ulp * abs(x)
        return u

    out = {}
    for key, M in mats.items():
        if M is None:
            out[key] = None
        elif isinstance(M[0], tuple):
            out[key] = tuple(tuple(one(f"{key}[{i}][{j}]", x) for j, x in enumerate(row)) for i, row in enumerate(M))
        else:
            out[key] = tuple(one(f"{key}[{i}]", x) for i, x in enumerate(M))
    return out, D, S


def _floats(M):
    if M is None:
        return None
    a = np.array([[float(x) for x in row] for row in M] if isinstance(M[0], tuple) else [float(x) for x in M],
                 dtype=float)
    a.flags.writeable = False
    return a


# -- the tableau --------------------------------------------------------------------------------------
@dataclass(frozen=True, init=False, repr=False)
class Tableau:
    """An explicit (partitioned) Runge-Kutta method: exact coefficients and
    what follows from them.

    Build one with :func:`make_tableau` (the positional form
    ``Tableau(name, A, b, c=None, order=None, A_v=None, b_v=None,
    description="")`` is the same, ``order`` being an optional *declared*
    order that must equal the computed one). Equality and hashing are by name
    and exact coefficients.

    Attributes
    ----------
    name : str
        Registry name (``"rk4"``, ``"stormer-verlet"``, a scene's own name).
    A_exact, b_exact, c_exact : tuple of Fraction
        The coefficients as given (strings and ints exactly; floats as their
        exact binary value). ``A_exact`` is a tuple of rows.
    A_v_exact, b_v_exact : tuple of Fraction or None
        Velocity-half coefficients of a partitioned method; None for a
        classical one.
    A, b, c, A_v, b_v : ndarray (read-only) or None
        The same rounded to float64 (each entry correctly rounded), what the
        integrators use. ``c`` is dimensionless: stage ``i`` is at ``t + c_i h``.
    description : str
        One line for reports (with the method's reference).
    inexact : tuple of str
        Entries given as floats that are not the decimal they print as
        (``1/3`` typed as ``0.3333333333333333``), e.g. ``("b[1]",)``: the
        exact binary value is kept and judged at its binary precision (see
        ``coefficient_tol``). Give such entries as strings (``"1/3"``) to have
        them exact.
    rounded : tuple of str
        Decimal entries with more than :data:`EXACT_DECIMALS` decimal places
        (``"0.29697761"``, or a float printed so): the tableau is then read as
        given to that precision.
    precision : str
        ``"exact"``, ``"binary float rounding"`` or ``"D decimals, S
        significant digits"`` (the finest of the rounded entries).
    coefficient_tol : Fraction
        The one tolerance every property computed from the tableau uses:
        ``10**-D`` for a rounded tableau (each nonzero decimal entry ``x`` may
        be ``max(10**-D, 10**(1-S) |x|, FLOAT_ULPS 2**-52 |x|)`` off, plus
        :data:`FLOAT_ULPS` ulps for floats), ``FLOAT_ULPS * 2**-52`` (relative) for floats that are
        otherwise exact decimals, 0 for exact entries. The order conditions
        (:attr:`order`, :attr:`order_residuals`), the row-sum check and the
        stability boundaries (:mod:`rk4h.stability_function`) each accept
        a residual no larger than what entries that far off can produce
        (:attr:`uncertainty` propagated through the same formula with
        absolute values). Ralston's fourth-order method printed to 8 decimals
        has residuals up to 6.6e-9 in its order-2..4 conditions: order 4.
    order : int
        Computed from the order conditions (:func:`rk4h.order_conditions.order`;
        bi-coloured trees for a partitioned method), up to 10 (8 partitioned).
        Conditions for autonomous problems: with ``row_sum=False`` a method
        whose ``c`` is not ``A``'s row sums may have a lower order on ``t``-
        dependent ones.
    n_stages : int
    partitioned : bool
    stage_evaluated : tuple of bool
        Whether stage ``i``'s right-hand side is evaluated: every stage of a
        classical method; for a partitioned one the stages whose acceleration
        is used (``b_v[i] != 0`` or some ``A_v[j][i] != 0``).
    start_stage : int or None
        A stage whose evaluation is ``f(t_n, y_n)`` (classical: stage 0 when
        ``c_0 = 0``; partitioned: an evaluated stage with ``Q_i = q_n``, i.e.
        row ``i`` of ``A`` zero, and ``c_i = 0``, giving ``a(q_n, t_n)``).
        Dense output uses it as the slope at the step's start.
    fsal_stages : (int, int) or None
        ``(i0, i_last)`` when the evaluation of stage ``i_last`` of a step is
        that of stage ``i0`` of the next (first same as last), else None.
        Classical: ``(0, s - 1)`` when the last row of ``A`` equals ``b``,
        ``c_s = 1`` and ``c_0 = 0``. Partitioned (FSAL on ``q``):
        ``i0 = start_stage`` and ``i_last`` the last other evaluated stage
        whose row of ``A`` equals ``b`` (so ``Q_{i_last} = q_{n+1}``, bit for
        bit) with ``c = 1``.
    fsal : bool
        ``fsal_stages is not None``.
    nfev_first_step : int
        Right-hand-side evaluations of the first step: ``sum(stage_evaluated)``.
    nfev_per_step : int
        Evaluations per step after the first: ``nfev_first_step - fsal``
        (RK4 4, RK38 4, Heun3 3, Ralston 2, Euler 1, symplectic Euler 1,
        Stormer-Verlet 1). A run of ``N`` steps costs
        ``nfev_first_step + (N - 1) nfev_per_step`` (see :func:`rk4h.solve`).
    """

    name: str
    A_exact: tuple
    b_exact: tuple
    c_exact: tuple
    A_v_exact: tuple | None = None
    b_v_exact: tuple | None = None
    description: str = field(default="", compare=False)
    inexact: tuple = field(default=(), compare=False)
    coefficient_tol: Fraction = field(default=Fraction(0), compare=False)
    precision: str = field(default="exact", compare=False)
    rounded: tuple = field(default=(), compare=False)
    _uncertainty: dict = field(default=None, compare=False)

    def __init__(self, name, A, b, c=None, order=None, A_v=None, b_v=None, description="", *, row_sum=True):
        if not isinstance(name, str) or not name:
            raise ValueError(f"method {name!r}: `name` must be a non-empty string")
        if not isinstance(description, str):
            raise ValueError(f"method {name!r}: `description` must be a string, got {description!r:.60}")
        P = _Parse(name)
        A_e = P.matrix("A", A)
        s = len(A_e)
        b_e = P.vector("b", b, s, "one weight per stage")
        partitioned = A_v is not None or b_v is not None
        if partitioned and (A_v is None or b_v is None):
            given, missing = ("A_v", "b_v") if A_v is not None else ("b_v", "A_v")
            P.fail(missing, f"must be given with `{given}` (a partitioned method needs both)")
        A_v_e = b_v_e = None
        if partitioned:
            A_v_e = P.matrix("A_v", A_v)
            if len(A_v_e) != s:
                P.fail("A_v", f"must be {s} x {s} like `A`, got {len(A_v_e)} x {len(A_v_e)}")
            b_v_e = P.vector("b_v", b_v, s, "one velocity weight per stage")
        _check_explicit(P, A_e, A_v_e)
        row_sums = tuple(sum(row, Fraction(0)) for row in A_e)
        c_e = None if c is None else P.vector("c", c, s, "one node per stage")
        unc, D, S = _uncertainty(P, {"A": A_e, "b": b_e, "c": c_e, "A_v": A_v_e, "b_v": b_v_e})
        if c is None:
            c_e = row_sums
            unc["c"] = tuple(sum(row, Fraction(0)) for row in unc["A"])
        elif row_sum:
            _check_row_sums(P, A_e, c_e, row_sums, unc)
        tol = Fraction(1, 10**D) if D is not None else Fraction(0)
        if D is None and any(any(u) if not isinstance(u[0], tuple) else any(map(any, u))
                             for u in unc.values() if u is not None):
            tol = FLOAT_ULPS * Fraction(1, 2**52)  # floats only: binary rounding, relative
        precision = (f"{D} decimals, {S} significant digits" if D is not None else
                     "binary float rounding" if tol else "exact")
        for key, value in (("name", name), ("A_exact", A_e), ("b_exact", b_e), ("c_exact", c_e),
                           ("A_v_exact", A_v_e), ("b_v_exact", b_v_e), ("description", description),
                           ("inexact", tuple(P.inexact)), ("coefficient_tol", tol), ("precision", precision),
                           ("rounded", tuple(w for w, v in P.decimals.items() if v[0] > EXACT_DECIMALS)),
                           ("_uncertainty", unc),
                           ("A", _floats(A_e)), ("b", _floats(b_e)), ("c", _floats(c_e)),
                           ("A_v", _floats(A_v_e)), ("b_v", _floats(b_v_e))):
            object.__setattr__(self, key, value)
        self._plan()
        if order is not None:
            if isinstance(order, bool) or not isinstance(order, numbers.Integral):
                P.fail("order", f"must be an integer (the declared order), got {order!r:.40}")
            if int(order) != self.order:
                P.fail("order", f"is declared {int(order)} but the order conditions give {self.order}")

    def _plan(self):
        """Which stages are evaluated, the start stage, FSAL and the cost (all from the data)."""
        A, b, c, s = self.A_exact, self.b_exact, self.c_exact, self.n_stages
        zero_row = [all(x == 0 for x in row) for row in A]
        if not self.partitioned:
            evaluated = (True,) * s
            start = 0 if c[0] == 0 else None
            fsal = (0, s - 1) if s > 1 and start == 0 and A[s - 1] == b and c[s - 1] == 1 else None
        else:
            A_v, b_v = self.A_v_exact, self.b_v_exact
            evaluated = tuple(b_v[i] != 0 or any(A_v[j][i] != 0 for j in range(s)) for i in range(s))
            start = next((i for i in range(s) if evaluated[i] and zero_row[i] and c[i] == 0), None)
            last = [i for i in range(s) if i != start and evaluated[i] and A[i] == b and c[i] == 1]
            fsal = (start, last[-1]) if start is not None and last else None
        first = sum(evaluated)
        for key, value in (("stage_evaluated", evaluated), ("start_stage", start), ("fsal_stages", fsal),
                           ("fsal", fsal is not None), ("nfev_first_step", first),
                           ("nfev_per_step", first - (fsal is not None))):
            object.__setattr__(self, key, value)

    @property
    def uncertainty(self):
        """``(dA, db, dA_v, db_v)``: how far each coefficient may be from the
        intended one at the precision it was given with (Fractions, absolute;
        zeros for exact entries; see :attr:`coefficient_tol`); None when every
        entry is exact."""
        u = self._uncertainty
        vals = (u["A"], u["b"], u["A_v"], u["b_v"])
        flat = [x for m in vals if m is not None for row in m for x in (row if isinstance(row, tuple) else (row,))]
        return vals if any(flat) else None

    @cached_property
    def order(self) -> int:
        """Order from the order conditions (see the class docstring), each
        held to the tableau's coefficient precision (:attr:`uncertainty`)."""
        return order_conditions.order(self.A_exact, self.b_exact, self.A_v_exact, self.b_v_exact,
                                      uncertainty=self.uncertainty)

    @cached_property
    def order_residuals(self) -> list[dict]:
        """Per order ``p`` up to ``order + 1`` (at most the highest order
        checked): the largest residual ``|b^T Phi(t) - 1/gamma(t)|`` over the
        conditions of order ``p``, the tolerance of that condition (what the
        coefficients' precision allows, 0 for an exact tableau) and whether
        every condition of order ``p`` holds
        (:func:`rk4h.order_conditions.residuals`)."""
        return order_conditions.residuals(self.A_exact, self.b_exact, self.A_v_exact, self.b_v_exact,
                                          uncertainty=self.uncertainty, max_order=self.order + 1)

    #: Trees of the order conditions of a partitioned tableau (None: every
    #: bi-coloured tree; rk4h.geometric's splittings use the Nystrom subset).
    _order_trees = None

    @cached_property
    def error_coefficient(self) -> float:
        """Principal error coefficient: the 2-norm of the truncation-error
        coefficients of order ``order + 1`` over the trees its order is
        judged on (:func:`rk4h.order_conditions.principal_error_norm`, as
        nodepy computes it; RK4 0.01450). From the
        coefficients as given; dimensionless."""
        return order_conditions.principal_error_norm(self.A_exact, self.b_exact, self.A_v_exact, self.b_v_exact,
                                                     self.order, trees=self._order_trees)

    @property
    def n_stages(self) -> int:
        return len(self.b_exact)

    @property
    def partitioned(self) -> bool:
        return self.A_v_exact is not None

    def __repr__(self) -> str:
        kind = "partitioned, " if self.partitioned else ""
        return f"Tableau({self.name!r}, {kind}{self.n_stages} stages, order {self.order})"


def _check_explicit(P: _Parse, A, A_v):
    s = len(A)
    if A_v is None:
        for i in range(s):
            for j in range(i, s):
                if A[i][j] != 0:
                    P.fail("A", f"must be strictly lower triangular (explicit methods only); "
                                f"A[{i}][{j}] = {_fmt(A[i][j])}")
        return
    for key, M in (("A", A), ("A_v", A_v)):
        for i in range(s):
            for j in range(i + 1, s):
                if M[i][j] != 0:
                    P.fail(key, f"must be lower triangular for a partitioned method (explicit on y = [q, v] "
                                f"with q' = v, v' = a(q, t)); {key}[{i}][{j}] = {_fmt(M[i][j])}")
    for i in range(s):
        if A[i][i] != 0 and A_v[i][i] != 0:
            P.fail("A", f"and `A_v` must not both have a diagonal entry in one row (the stage would be "
                        f"implicit); A[{i}][{i}] = {_fmt(A[i][i])}, A_v[{i}][{i}] = {_fmt(A_v[i][i])}")


def _check_row_sums(P: _Parse, A, c, row_sums, unc):
    for i, (ci, si) in enumerate(zip(c, row_sums)):
        if ci == si:
            continue
        if abs(ci - si) <= unc["c"][i] + sum(unc["A"][i], Fraction(0)):  # within the coefficients' precision
            continue
        P.fail("c", f"must equal the row sums of `A` (c_i = sum_j a_ij; pass row_sum=False to allow it); "
                    f"row {i}: c[{i}] = {_fmt(ci)} but sum_j A[{i}][j] = {_fmt(si)}")


def make_tableau(name: str, A, b, c=None, *, A_v=None, b_v=None, description: str = "",
                 row_sum: bool = True) -> Tableau:
    """A validated :class:`Tableau` from its coefficients.

    Parameters
    ----------
    name : str
        The method's name.
    A : (s, s) nested sequence
        Runge-Kutta matrix (the position half of a partitioned method).
        Entries: ints, floats, :class:`~fractions.Fraction`, or strings
        holding a rational (``"1/3"``, ``"-2"``, ``"0.5"``, ``"1e-3"``), kept
        exactly (floats as their exact binary value; see ``Tableau.inexact``).
    b : (s,) sequence
        Weights.
    c : (s,) sequence, optional
        Nodes (dimensionless fractions of the step). Default: the row sums of
        ``A``. When given they must equal the row sums exactly (floats to 8
        ulps), unless ``row_sum=False``.
    A_v, b_v : optional, keyword-only
        Velocity-half coefficients: given together, they make the method
        partitioned (``y = [q, v]``, ``q' = v``, ``v' = a(q, t)``; see the
        module docstring for the explicitness rule).
    description : str, keyword-only
    row_sum : bool, keyword-only
        Check ``c_i = sum_j A[i][j]`` (default True).

    Returns
    -------
    Tableau

    Raises
    ------
    ValueError
        One line naming the method and the field: an empty or non-square
        ``A``; ``b``/``c``/``b_v`` of the wrong length; an entry that is not a
        number or a rational string, or not finite; ``A`` not strictly lower
        triangular (classical), an entry above the diagonal or a row with both
        diagonal entries (partitioned); ``A_v`` without ``b_v``; ``c`` not the
        row sums (naming the row).
    """
    return Tableau(name, A, b, c, None, A_v, b_v, description, row_sum=row_sum)


# -- built-in methods ---------------------------------------------------------------------------------
#: Classical RK4 as in the thesis, sec. 1.1.4 (eqs. 1.7-1.12): stages at t, t+h/2,
#: t+h/2, t+h; weights 1/6, 1/3, 1/3, 1/6 (HNW I, Table II.1.2, left).
RK4 = make_tableau(
    "rk4",
    A=[[0, 0, 0, 0], ["1/2", 0, 0, 0], [0, "1/2", 0, 0], [0, 0, 1, 0]],
    b=["1/6", "1/3", "1/3", "1/6"],
    c=[0, "1/2", "1/2", 1],
    description="classical Runge-Kutta, 4 stages (thesis sec. 1.1.4)",
)

#: Kutta's 3/8 rule (Kutta 1901; HNW I, Table II.1.2, right): order 4, 4 stages.
RK38 = make_tableau(
    "rk38",
    A=[[0, 0, 0, 0], ["1/3", 0, 0, 0], ["-1/3", 1, 0, 0], [1, -1, 1, 0]],
    b=["1/8", "3/8", "3/8", "1/8"],
    c=[0, "1/3", "2/3", 1],
    description="Kutta's 3/8 rule, 4 stages, order 4 (HNW I, Table II.1.2)",
)

#: Heun's third-order method (Heun 1900; HNW I, Table II.1.1).
HEUN3 = make_tableau(
    "heun3",
    A=[[0, 0, 0], ["1/3", 0, 0], [0, "2/3", 0]],
    b=["1/4", 0, "3/4"],
    c=[0, "1/3", "2/3"],
    description="Heun's third-order method, 3 stages (HNW I, Table II.1.1)",
)

#: Ralston's second-order method, the two-stage one with the least error bound
#: (A. Ralston, Math. Comp. 16 (1962) 431-437).
RALSTON = make_tableau(
    "ralston",
    A=[[0, 0], ["2/3", 0]],
    b=["1/4", "3/4"],
    c=[0, "2/3"],
    description="Ralston's second-order method, 2 stages (Ralston 1962)",
)

#: Explicit (forward) Euler, used by the thesis' animation code (Code 01).
EULER = make_tableau("euler", A=[[0]], b=[1], c=[0], description="explicit Euler")

#: Semi-implicit (symplectic) Euler of the thesis' N-mass code (Code 02):
#: v_{n+1} = v_n + h a(q_n);  q_{n+1} = q_n + h v_{n+1}  (HLW eq. I.1.9).
#: Stage 2 has V_2 = v_n + h a(q_n) = v_{n+1}, and q is advanced with it; the
#: acceleration of stage 2 is used by nothing, so one evaluation per step.
SYMPLECTIC_EULER = make_tableau(
    "symplectic-euler",
    A=[[0, 0], [0, 0]],
    b=[0, 1],
    c=[0, 0],
    A_v=[[0, 0], [1, 0]],
    b_v=[1, 0],
    description="semi-implicit (symplectic) Euler, velocity first (thesis Code 02; HLW eq. I.1.9)",
)

#: Stormer-Verlet, velocity form (Verlet 1967; HLW sec. I.1.4, eq. I.1.17, and
#: sec. II.2.2: the Lobatto IIIA-IIIB pair):
#: v_{n+1/2} = v_n + h/2 a(q_n);  q_{n+1} = q_n + h v_{n+1/2};
#: v_{n+1} = v_{n+1/2} + h/2 a(q_{n+1}).
#: Stage 1: Q_1 = q_n, V_1 = v_n + h/2 a(Q_1); stage 2: V_2 = V_1,
#: Q_2 = q_n + h/2 (V_1 + V_2) = q_{n+1}. Q_2's acceleration is the next step's
#: first (FSAL on q): one evaluation per step.
STORMER_VERLET = make_tableau(
    "stormer-verlet",
    A=[[0, 0], ["1/2", "1/2"]],
    b=["1/2", "1/2"],
    c=[0, 1],
    A_v=[["1/2", 0], ["1/2", 0]],
    b_v=["1/2", "1/2"],
    description="Stormer-Verlet (velocity Verlet), symplectic, order 2 (HLW sec. I.1.4, II.2)",
)

METHODS: dict[str, Tableau] = {m.name: m for m in (RK4, EULER, SYMPLECTIC_EULER, STORMER_VERLET, RK38,
                                                   HEUN3, RALSTON)}
# (rk4core's package import adds the splitting and composition methods of
# rk4h.geometric, built from Stormer-Verlet above: yoshida4, yoshida6,
# suzuki4, forest-ruth, blanes-moan4, blanes-moan6.)


def get_method(method: str | Tableau) -> Tableau:
    """Return the tableau named ``method`` (or ``method`` itself)."""
    if isinstance(method, Tableau):
        return method
    try:
        return METHODS[method]
    except (KeyError, TypeError):
        raise ValueError(
            f"`method` must be one of {sorted(METHODS)}, got {method!r}"
        ) from None


# -- stepping -----------------------------------------------------------------------------------------
def stage_time(t: float, c: float, h: float, t_max: float | None) -> float:
    """Time ``t + c h`` of a stage, never past ``t_max`` (None: no limit).

    ``t + c h`` can round one ulp past the end of the interval on its last
    step; the right-hand side is never evaluated outside ``t_span`` (as scipy's
    ``solve_ivp`` after gh-17341)."""
    ti = t + c * h
    return ti if t_max is None or ti <= t_max else t_max


def rk_step(fun, t: float, y: np.ndarray, h: float, tab: Tableau, k: np.ndarray, *,
            t_max: float | None = None, reuse: bool = False) -> np.ndarray:
    """Advance ``y`` by one step of size ``h``; pure apart from the scratch ``k``.

    Parameters
    ----------
    fun : callable
        ``fun(t, y) -> dy/dt``. For a partitioned method only the velocity
        half of its value (the acceleration) is used: the position slope of a
        stage is the stage's velocity (``dq/dt = v``).
    t, y, h : float, ndarray, float
        Current time, state (shape (n,) -- or (n, m) for m states at once --
        real or complex) and step.
    tab : Tableau
        The method.
    k : ndarray, shape (n_stages, n) (or (n_stages, n, m))
        Stage slopes of the state's dtype, overwritten. A partitioned method
        stores ``[V_i, a(Q_i)]`` in row ``i`` (the acceleration of a stage
        that is not evaluated is left as it was).
    t_max : float, optional, keyword-only
        End of the integration interval: stage times are
        ``min(t + c_i h, t_max)`` (:func:`stage_time`), so ``fun`` is never
        called past it. Default: no limit.
    reuse : bool, keyword-only
        ``k`` holds the previous step's slopes and ``y`` its result: for a
        FSAL method (``tab.fsal``) stage ``i0`` takes stage ``i_last``'s
        evaluation instead of calling ``fun`` (``tab.fsal_stages``). Ignored
        otherwise. The step then costs ``tab.nfev_per_step`` calls, else
        ``tab.nfev_first_step``.

    Returns
    -------
    ndarray
        The new state ``y(t + h)`` (a new array).
    """
    A, b, c = tab.A, tab.b, tab.c
    s = tab.n_stages
    reused = tab.fsal_stages[0] if reuse and tab.fsal else -1
    if not tab.partitioned:
        if reused == 0:
            k[0] = k[s - 1]
        for i in range(s):
            if i == reused:
                continue
            yi = y
            for j in range(i):
                if A[i, j] != 0.0:
                    yi = yi + (h * A[i, j]) * k[j]
            k[i] = fun(stage_time(t, c[i], h, t_max), yi)
        y_new = y.copy()
        for i in range(s):
            if b[i] != 0.0:
                y_new += (h * b[i]) * k[i]
        return y_new
    n = y.shape[0] // 2
    A_v, b_v, evaluated = tab.A_v, tab.b_v, tab.stage_evaluated
    if reused >= 0:
        k[reused, n:] = k[tab.fsal_stages[1], n:]
    for i in range(s):
        evaluate = evaluated[i] and i != reused
        yi = y.copy()
        for j in range(i):  # the velocity from earlier accelerations
            if A_v[i, j] != 0.0:
                yi[n:] += (h * A_v[i, j]) * k[j, n:]
        if A_v[i, i] == 0.0:  # velocity first: V_i is complete; Q_i may use it (A[i, i])
            k[i, :n] = yi[n:]
            if evaluate:
                for j in range(i + 1):
                    if A[i, j] != 0.0:
                        yi[:n] += (h * A[i, j]) * k[j, :n]
                k[i, n:] = fun(stage_time(t, c[i], h, t_max), yi)[n:]
        else:  # position first (A[i, i] == 0): V_i needs the acceleration at Q_i
            for j in range(i):
                if A[i, j] != 0.0:
                    yi[:n] += (h * A[i, j]) * k[j, :n]
            if evaluate:
                k[i, n:] = fun(stage_time(t, c[i], h, t_max), yi)[n:]
            yi[n:] += (h * A_v[i, i]) * k[i, n:]
            k[i, :n] = yi[n:]
    y_new = y.copy()
    for i in range(s):
        if b[i] != 0.0:
            y_new[:n] += (h * b[i]) * k[i, :n]
        if b_v[i] != 0.0:
            y_new[n:] += (h * b_v[i]) * k[i, n:]
    return y_new


def start_slope(tab: Tableau, y: np.ndarray, k: np.ndarray):
    """``f(t_n, y_n)`` from the stages of the step that started at ``y``
    (:func:`rk_step`'s ``k``), or None when no stage computed it
    (``tab.start_stage`` is None). Partitioned: ``[v_n, a(q_n)]``."""
    i = tab.start_stage
    if i is None:
        return None
    if not tab.partitioned:
        return k[i]
    n = y.shape[0] // 2
    return np.concatenate((y[n:], k[i, n:]))


def end_slope(tab: Tableau, y_new: np.ndarray, k: np.ndarray):
    """``f(t_n + h, y_{n+1})`` from the stages of the step that produced
    ``y_new`` when the method is FSAL (the last evaluated stage is at
    ``y_{n+1}``), else None."""
    if not tab.fsal:
        return None
    i = tab.fsal_stages[1]
    if not tab.partitioned:
        return k[i]
    n = y_new.shape[0] // 2
    return np.concatenate((y_new[n:], k[i, n:]))
