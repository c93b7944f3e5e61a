"""Symbolic expressions: one definition of a model, everything else derived.

A small, immutable expression tree with its own parser, symbolic
differentiation, and three evaluators generated *from the tree* -- never by
``eval`` of user text:

* :func:`lambdify` -- a Python function of numpy arrays (or of floats, for the
  ``math`` backend), compiled from source printed from the validated tree;
* :func:`to_source` -- the scalar source text of one expression (for numba);
* :func:`to_heyoka` -- a ``heyoka.expression`` for heyoka's Taylor integrator.

Node types
----------
:class:`Num` (a finite double), :class:`Sym` (a name), :class:`Add` (a sum),
:class:`Mul` (a product), :class:`Pow` (a power) and :class:`Call` (one of
:data:`FUNCTIONS` applied to one argument). Subtraction is ``a + (-1) b``,
division ``a b^-1``, unary minus a factor ``-1``. Nodes are frozen, hashable
and compare structurally; they carry their hash, free symbols and depth, so
no operation on a tree recurses through it (every walk below is iterative).

Python operators build simplified trees: ``k * r**2 / 2`` works on
:class:`Expr` and numbers (int or float). The builders :func:`add`,
:func:`mul`, :func:`power`, :func:`call` apply the light simplification rules:

* numbers fold exactly: a product or sum of numbers becomes one number when
  its exact value is a double; otherwise the exact rational ``p/q`` is kept as
  ``p * q**-1``, printed ``p/q`` and so evaluated correctly rounded (numpy
  evaluates ``x/3`` as ``x/3.0``, not as ``x * 0.333...``; heyoka folds a
  division by a number into a product with its rounded reciprocal itself);
* ``x + 0 = x``, ``x * 1 = x``, ``x * 0 = 0``, ``x**1 = x``, ``x**0 = 1``,
  ``1**x = 1``, ``(x**a)**n = x**(a n)`` for an integer ``n``;
* equal terms of a sum are collected (``x + x = 2*x``, ``x - x = 0``) and
  powers of one base with integer exponents in a product are merged
  (``x * x = x**2``, ``x * x**-1 = 1``);
* the exact values ``sin(0) = tan(0) = sinh(0) = tanh(0) = sqrt(0) = 0``,
  ``cos(0) = cosh(0) = exp(0) = sqrt(1) = 1``, ``log(1) = 0``.

Terms and factors otherwise keep the order in which they were written.

Grammar (:func:`parse`)
-----------------------
::

    expr    := term (("+" | "-") term)*
    term    := unary (("*" | "/") unary)*
    unary   := ("+" | "-") unary | power
    power   := atom (("**" | "^") unary)?          right-associative
    atom    := NUMBER | NAME | FUNC "(" expr ")" | "(" expr ")"
    NUMBER  := digits ["." digits] [("e"|"E") ["+"|"-"] digits]  (or ".5")
    NAME    := [A-Za-z_][A-Za-z0-9_]*   (no "__", no Python keyword)
    FUNC    := sin | cos | tan | sinh | cosh | tanh | exp | log | sqrt

Precedence is Python's: ``**`` (and its synonym ``^``) binds tightest and is
right-associative (``2^3^2 = 2^9 = 512``), and it binds tighter than a unary
sign on its left (``-x**2 = -(x**2)``) but accepts one on its right
(``2**-1 = 0.5``); then ``*`` and ``/`` (left-associative: ``a/b/c =
(a/b)/c``), then ``+`` and ``-`` (``a-b-c = (a-b)-c``). Spaces, tabs and
newlines separate tokens. Anything else -- attribute access, subscripts,
strings, commas, keywords, ``;``, ``lambda``, double underscores, calls of
other functions -- is not in the grammar and is refused with
:class:`ExprError`: one line naming the problem and its 1-based column
(the character offset in the text, a newline counting as one character).
Text longer than :data:`MAX_LENGTH` characters or nested deeper than
:data:`MAX_DEPTH` levels (each parenthesis, function argument, unary sign or
right operand of an operator is a level) is refused before it can exhaust the
stack. Numbers are read as IEEE doubles (``float(text)``); non-finite ones
(``1e999``) are refused.

Cost limits, checked while the tree is built, so that no text of
:data:`MAX_LENGTH` characters takes minutes:

* a product with more than :data:`MAX_FACTORS` factors that are not numbers
  is refused, naming its column (its second derivatives grow as the cube of
  that count: 160 factors took 338 s and 1.5 GB);
* exact folding stops at :data:`MAX_FOLD_BITS` bits of numerator plus
  denominator: a larger number is kept as written and evaluated in floating
  point (``(5e-324^-64 * 2)^64`` no longer builds a 4-million-bit integer);
* derivatives taken with a :class:`Budget` (the ``potential`` model's are)
  are refused past :data:`MAX_DERIVATIVE_WORK` units of work.

Constants (``parse(..., constants={"k": 2.5})``) are substituted as numbers
when the text is parsed: the tree holds their double values, not their names,
so the same double reaches every evaluator, heyoka's real128 integration
included. There are no built-in constants (pass ``pi`` yourself).

Units: the tree is unit-agnostic. A model's potential is in joules when its
coordinates are in metres (or radians) and its constants in SI units.

References
----------
Python language reference, sec. 6.17 "Operator precedence" and sec. 6.5 "The
power operator" (https://docs.python.org/3/reference/expressions.html).
V. R. Pratt, "Top down operator precedence", POPL 1973 (the parser).
"""
from __future__ import annotations

import hashlib
import keyword
import math
import re
from dataclasses import dataclass, field
from fractions import Fraction
from numbers import Real
from typing import Callable, Iterable, Mapping, Sequence

__all__ = [
    "Expr", "Num", "Sym", "Add", "Mul", "Pow", "Call", "ExprError",
    "FUNCTIONS", "MAX_LENGTH", "MAX_DEPTH", "MAX_TREE_DEPTH", "MAX_FACTORS", "MAX_FOLD_BITS",
    "MAX_DERIVATIVE_WORK", "Budget",
    "parse", "check_name", "symbols", "as_expr", "add", "mul", "power", "call", "neg",
    "diff", "gradient", "hessian", "free_symbols", "substitute", "to_text", "digest",
    "lambdify", "to_source", "to_heyoka", "count_nodes", "MAX_SOURCE_DEPTH",
]

#: The functions the grammar knows (numpy/math/heyoka functions of the same name).
FUNCTIONS = ("sin", "cos", "tan", "sinh", "cosh", "tanh", "exp", "log", "sqrt")
#: Longest text :func:`parse` reads (characters).
MAX_LENGTH = 10_000
#: Deepest nesting :func:`parse` accepts (parser recursion levels).
MAX_DEPTH = 200
#: Deepest tree any builder accepts (parsed trees stay far below it).
MAX_TREE_DEPTH = 1_000
#: Longest name (characters).
MAX_NAME_LENGTH = 100
#: Most factors that are not numbers in one product :func:`parse` builds (after
#: flattening and merging powers of one base). A product of ``k`` such factors
#: has a second derivative of ``O(k^2)`` terms of ``k`` factors each; 32 keeps
#: a model's Hessian of one product within about a second.
MAX_FACTORS = 32
#: Most work units (factors and terms handed to the builders) the derivatives
#: of one expression may take when a :class:`Budget` is given (the ``potential``
#: model gives one for its gradient and Hessian together). A unit took 20 to
#: 80 us on a loaded 2-core machine (Hessian of a 32-factor product of sines:
#: 36 000 units, 0.8 s; of a 1499-term polynomial: 27 000 units, 2.1 s).
MAX_DERIVATIVE_WORK = 50_000

_NAME_RE = re.compile(r"[A-Za-z_][A-Za-z0-9_]*\Z")
_NUMBER_RE = re.compile(r"(?:[0-9]+(?:\.[0-9]*)?|\.[0-9]+)(?:[eE][+-]?[0-9]+)?")
_NAME_TOKEN_RE = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")
_WORD_RE = re.compile(r"[A-Za-z0-9_.]*")
_WHITESPACE = " \t\r\n"
# Exact folding of number powers only up to this integer exponent.
_MAX_FOLD_EXPONENT = 64
#: Largest exact rational folded (bits of numerator plus denominator). Doubles
#: need at most 2100; above this, numbers are kept as written (evaluated in
#: floating point), so ``(5e-324^-64 * 2)^64`` never builds a 4-million-bit integer.
MAX_FOLD_BITS = 8192
_EXACT_INT = 2 ** 53
#: Integer powers ``b**n`` with ``2 <= n <=`` this exponent are evaluated as
#: products by binary powering (``b**3 = b * (b*b)``, ``b**4 = (b*b) * (b*b)``)
#: in :func:`lambdify`'s source and in :func:`to_heyoka`; numba evaluates
#: ``b**n`` with an integer literal ``n`` by the same multiplications, so the
#: numpy, ``math``, numba and heyoka forms of a polynomial agree to the bit.
POWER_PRODUCTS_MAX = 64


class ExprError(ValueError):
    """A malformed expression or a misuse of the expression API (one line)."""


# ---------------------------------------------------------------------------
# Nodes
# ---------------------------------------------------------------------------

class Expr:
    """Base class of the expression nodes (immutable, hashable).

    Supports ``+ - * / **`` and unary ``-`` with other expressions and with
    real numbers; ``str()`` gives the canonical text (:func:`to_text`).
    """

    __slots__ = ()

    # Filled by subclasses' __post_init__ (via object.__setattr__).
    _hash: int
    _free: frozenset
    _depth: int

    def children(self) -> tuple:
        return ()

    def _key(self) -> tuple:  # pragma: no cover - abstract
        raise NotImplementedError

    def _finish(self, children=()):
        depth = 1 + max((c._depth for c in children), default=0)
        if depth > MAX_TREE_DEPTH:
            raise ExprError(f"expression nested deeper than {MAX_TREE_DEPTH} levels")
        free = frozenset().union(*(c._free for c in children)) if children else frozenset()
        object.__setattr__(self, "_depth", depth)
        object.__setattr__(self, "_free", free)
        object.__setattr__(self, "_hash", hash((type(self).__name__,) + self._key()))

    def __hash__(self):
        return self._hash

    def __eq__(self, other):
        # Iterative, so comparing two deep trees never recurses.
        stack = [(self, other)]
        while stack:
            a, b = stack.pop()
            if a is b:
                continue
            if type(a) is not type(b) or a._hash != b._hash:
                return False
            ka, kb = a._key(), b._key()
            if len(ka) != len(kb):
                return False
            for x, y in zip(ka, kb):
                if isinstance(x, Expr):
                    stack.append((x, y))
                elif x != y:
                    return False
        return True

    def __ne__(self, other):
        return not self.__eq__(other)

    # -- arithmetic -------------------------------------------------------
    def __add__(self, other):
        o = _coerce(other)
        return NotImplemented if o is None else add(self, o)

    def __radd__(self, other):
        o = _coerce(other)
        return NotImplemented if o is None else add(o, self)

    def __sub__(self, other):
        o = _coerce(other)
        return NotImplemented if o is None else add(self, neg(o))

    def __rsub__(self, other):
        o = _coerce(other)
        return NotImplemented if o is None else add(o, neg(self))

    def __mul__(self, other):
        o = _coerce(other)
        return NotImplemented if o is None else mul(self, o)

    def __rmul__(self, other):
        o = _coerce(other)
        return NotImplemented if o is None else mul(o, self)

    def __truediv__(self, other):
        o = _coerce(other)
        return NotImplemented if o is None else mul(self, power(o, _MINUS_ONE))

    def __rtruediv__(self, other):
        o = _coerce(other)
        return NotImplemented if o is None else mul(o, power(self, _MINUS_ONE))

    def __pow__(self, other):
        o = _coerce(other)
        return NotImplemented if o is None else power(self, o)

    def __rpow__(self, other):
        o = _coerce(other)
        return NotImplemented if o is None else power(o, self)

    def __neg__(self):
        return neg(self)

    def __pos__(self):
        return self

    def __str__(self):
        return to_text(self)

    def __repr__(self):
        text = to_text(self)
        if len(text) > 200:
            text = text[:197] + "..."
        return f"{type(self).__name__}<{text}>"


@dataclass(frozen=True, eq=False, repr=False)
class Num(Expr):
    """A finite double-precision number."""

    value: float
    __slots__ = ("value", "_hash", "_free", "_depth")

    def __post_init__(self):
        v = self.value
        if isinstance(v, bool) or not isinstance(v, Real):
            raise ExprError(f"a number node needs a real number, got {v!r}")
        v = float(v)
        if not math.isfinite(v):
            raise ExprError(f"numbers must be finite, got {v!r}")
        object.__setattr__(self, "value", v)
        self._finish()

    def _key(self):
        return (self.value,)


@dataclass(frozen=True, eq=False, repr=False)
class Sym(Expr):
    """A named symbol (a coordinate). Names follow :func:`check_name`."""

    name: str
    __slots__ = ("name", "_hash", "_free", "_depth")

    def __post_init__(self):
        problem = check_name(self.name)
        if problem:
            raise ExprError(problem)
        self._finish()
        object.__setattr__(self, "_free", frozenset((self.name,)))

    def _key(self):
        return (self.name,)


def _check_children(kind, items):
    if not isinstance(items, tuple) or not items or not all(isinstance(t, Expr) for t in items):
        raise ExprError(f"{kind} needs a non-empty tuple of expressions, got {items!r}")


@dataclass(frozen=True, eq=False, repr=False)
class Add(Expr):
    """A sum of ``terms`` (left to right)."""

    terms: tuple
    __slots__ = ("terms", "_hash", "_free", "_depth")

    def __post_init__(self):
        _check_children("a sum", self.terms)
        self._finish(self.terms)

    def children(self):
        return self.terms

    def _key(self):
        return self.terms


@dataclass(frozen=True, eq=False, repr=False)
class Mul(Expr):
    """A product of ``factors`` (left to right)."""

    factors: tuple
    __slots__ = ("factors", "_hash", "_free", "_depth")

    def __post_init__(self):
        _check_children("a product", self.factors)
        self._finish(self.factors)

    def children(self):
        return self.factors

    def _key(self):
        return self.factors


@dataclass(frozen=True, eq=False, repr=False)
class Pow(Expr):
    """``base ** exp``."""

    base: Expr
    exp: Expr
    __slots__ = ("base", "exp", "_hash", "_free", "_depth")

    def __post_init__(self):
        if not isinstance(self.base, Expr) or not isinstance(self.exp, Expr):
            raise ExprError(f"a power needs two expressions, got {self.base!r}, {self.exp!r}")
        self._finish((self.base, self.exp))

    def children(self):
        return (self.base, self.exp)

    def _key(self):
        return (self.base, self.exp)


@dataclass(frozen=True, eq=False, repr=False)
class Call(Expr):
    """``func(arg)`` with ``func`` one of :data:`FUNCTIONS`."""

    func: str
    arg: Expr
    __slots__ = ("func", "arg", "_hash", "_free", "_depth")

    def __post_init__(self):
        if self.func not in FUNCTIONS:
            raise ExprError(f"unknown function {self.func!r} (known: {', '.join(FUNCTIONS)})")
        if not isinstance(self.arg, Expr):
            raise ExprError(f"a function call needs an expression argument, got {self.arg!r}")
        self._finish((self.arg,))

    def children(self):
        return (self.arg,)

    def _key(self):
        return (self.func, self.arg)


ZERO = Num(0.0)
ONE = Num(1.0)
_MINUS_ONE = Num(-1.0)


def check_name(name) -> str | None:
    """``None`` if ``name`` may name a symbol, else a one-line reason.

    A name is 1 to :data:`MAX_NAME_LENGTH` ASCII letters, digits and
    underscores, not starting with a digit, without a double underscore, and
    neither a Python keyword nor one of :data:`FUNCTIONS`.
    """
    if not isinstance(name, str):
        return f"a name must be a string, got {name!r}"
    shown = _clip(name)
    if not _NAME_RE.match(name):
        return (f"`{shown}` is not a name (letters, digits and underscores, not starting "
                f"with a digit)")
    if len(name) > MAX_NAME_LENGTH:
        return f"name `{shown}` is longer than {MAX_NAME_LENGTH} characters"
    if "__" in name:
        return f"name `{shown}` is not allowed (double underscore)"
    if keyword.iskeyword(name):
        return f"`{name}` is a Python keyword, not a name"
    if name in FUNCTIONS:
        return f"`{name}` is a function, not a name"
    return None


def symbols(*names: str) -> tuple:
    """``Sym`` nodes for ``names`` (convenience for models written in Python)."""
    return tuple(Sym(n) for n in names)


def _clip(text: str, limit: int = 40) -> str:
    text = text if text.isprintable() else text.encode("unicode_escape").decode("ascii")
    return text if len(text) <= limit else text[: limit - 3] + "..."


def _coerce(x):
    if isinstance(x, Expr):
        return x
    if isinstance(x, Real) and not isinstance(x, bool):
        return Num(float(x))
    return None


def as_expr(x) -> Expr:
    """``x`` as an expression: an :class:`Expr` itself, a real number as :class:`Num`."""
    e = _coerce(x)
    if e is None:
        raise ExprError(f"expected an expression or a real number, got {x!r}")
    return e


# ---------------------------------------------------------------------------
# Exact number folding
# ---------------------------------------------------------------------------

def _exact_float(f: Fraction) -> float | None:
    """The double equal to ``f``, or None when ``f`` is not a double."""
    try:
        x = float(f)
    except OverflowError:
        return None
    if not math.isfinite(x) or Fraction(x) != f:
        return None
    return x


def _bits(f: Fraction) -> int:
    return f.numerator.bit_length() + f.denominator.bit_length()


def _too_big(f: Fraction | None) -> bool:
    return f is not None and _bits(f) > MAX_FOLD_BITS


def _int_exponent(e: Expr) -> int | None:
    if isinstance(e, Num) and e.value.is_integer() and abs(e.value) <= _MAX_FOLD_EXPONENT:
        return int(e.value)
    return None


def _numeric(e: Expr) -> Fraction | None:
    """The exact rational value of a number-only node (Num, p*q**-1, ...), else None."""
    if isinstance(e, Num):
        return Fraction(e.value)
    if isinstance(e, Pow) and isinstance(e.base, Num):
        k = _int_exponent(e.exp)
        if k is not None and e.base.value != 0.0:
            base = Fraction(e.base.value)
            if _bits(base) * abs(k) > MAX_FOLD_BITS:
                return None
            return base ** k
        return None
    if isinstance(e, Mul):
        out = Fraction(1)
        for f in e.factors:
            v = _numeric(f) if not isinstance(f, Mul) else None
            if v is None:
                return None
            out *= v
            if _too_big(out):
                return None
        return out
    return None


def _coeff_factors(c: Fraction) -> list | None:
    """Factors that evaluate to ``c`` correctly rounded (``[]`` for 1), or None."""
    if c == 1:
        return []
    x = _exact_float(c)
    if x is not None:
        return [Num(x)]
    p, q = c.numerator, c.denominator
    if abs(p) <= _EXACT_INT and q <= _EXACT_INT:
        return ([] if p == 1 else [Num(float(p))]) + [Pow(Num(float(q)), _MINUS_ONE)]
    try:
        x = float(c)
    except OverflowError:
        return None
    return [Num(x)] if math.isfinite(x) and x != 0.0 else None


def _from_factors(factors: list) -> Expr:
    if not factors:
        return ONE
    return factors[0] if len(factors) == 1 else Mul(tuple(factors))


# ---------------------------------------------------------------------------
# Builders (with the light simplification rules of the module docstring)
# ---------------------------------------------------------------------------

def add(*terms) -> Expr:
    """The simplified sum of ``terms`` (expressions or numbers)."""
    flat = []
    for t in terms:
        t = as_expr(t)
        flat.extend(t.terms if isinstance(t, Add) else (t,))
    total, raw_numbers = Fraction(0), []
    order, coeff, originals = [], {}, {}
    for t in flat:
        v = _numeric(t)
        if v is not None and not _too_big(total + v):
            total += v
            raw_numbers.append(t)
            continue
        c, rest = _split_coeff(t)
        if rest not in coeff:
            order.append(rest)
            coeff[rest] = Fraction(0)
            originals[rest] = []
        if _too_big(coeff[rest] + c):  # kept as written: no exact sum
            rest = t
            if rest not in coeff:
                order.append(rest)
                coeff[rest], originals[rest] = Fraction(0), []
            c = Fraction(1)
        coeff[rest] += c
        originals[rest].append(t)
    out = []
    for rest in order:
        c = coeff[rest]
        if c == 0:
            continue
        cf = _coeff_factors(c)
        if cf is None:
            out.extend(originals[rest])
        else:
            out.append(_from_factors(cf + list(_factors_of(rest))))
    if total != 0:
        cf = _coeff_factors(total)
        if cf is None:
            out.extend(raw_numbers)
        else:
            out.append(_from_factors(cf))
    if not out:
        return ZERO
    return out[0] if len(out) == 1 else Add(tuple(out))


def _factors_of(e: Expr) -> tuple:
    return e.factors if isinstance(e, Mul) else (e,)


def _split_coeff(t: Expr):
    """``(c, rest)``: ``t = c * rest`` with ``c`` the exact numeric coefficient."""
    if not isinstance(t, Mul):
        return Fraction(1), t
    c, rest = Fraction(1), []
    for f in t.factors:
        v = _numeric(f)
        if v is None or _too_big(c * v):
            rest.append(f)
        else:
            c *= v
    return c, _from_factors(rest)


def mul(*factors) -> Expr:
    """The simplified product of ``factors`` (expressions or numbers)."""
    flat = []
    for f in factors:
        f = as_expr(f)
        flat.extend(f.factors if isinstance(f, Mul) else (f,))
    c, raw_numbers, others = Fraction(1), [], []
    for f in flat:
        v = _numeric(f)
        if v is None or _too_big(c * v):
            others.append(f)
        else:
            c *= v
            raw_numbers.append(f)
    if c == 0:
        return ZERO
    # Merge powers of one base when every exponent is an integer number.
    order, group = [], {}
    for f in others:
        b = f.base if isinstance(f, Pow) else f
        if b not in group:
            order.append(b)
            group[b] = []
        group[b].append(f)
    rest = []
    for b in order:
        fs = group[b]
        es = [f.exp if isinstance(f, Pow) else ONE for f in fs]
        if len(fs) > 1 and all(isinstance(e, Num) and e.value.is_integer() for e in es):
            p = power(b, Num(math.fsum(e.value for e in es)))
            if p != ONE:
                rest.extend(_factors_of(p))
        else:
            rest.extend(fs)
    cf = _coeff_factors(c)
    if cf is None:
        cf = raw_numbers
    return _from_factors(cf + rest)


def neg(x) -> Expr:
    """``-x``."""
    return mul(_MINUS_ONE, x)


def power(base, exp) -> Expr:
    """The simplified ``base ** exp``."""
    b, e = as_expr(base), as_expr(exp)
    if isinstance(e, Num):
        k = e.value
        if k == 0.0:
            return ONE
        if k == 1.0:
            return b
        bv = _numeric(b)
        n = _int_exponent(e)
        if bv is not None and n is not None and (bv == 0 or _bits(bv) * abs(n) <= MAX_FOLD_BITS):
            if bv == 0:
                return ZERO if n > 0 else Pow(b, e)
            cf = _coeff_factors(bv ** n)
            if cf is not None:
                return _from_factors(cf)
            return Pow(b, e)
        if isinstance(b, Pow) and isinstance(b.exp, Num) and k.is_integer() \
                and math.isfinite(b.exp.value * k):
            return power(b.base, Num(b.exp.value * k))
    if isinstance(b, Num) and b.value == 1.0:
        return ONE
    return Pow(b, e)


_CALL_FOLDS = {("sin", 0.0): 0.0, ("tan", 0.0): 0.0, ("sinh", 0.0): 0.0, ("tanh", 0.0): 0.0,
               ("sqrt", 0.0): 0.0, ("cos", 0.0): 1.0, ("cosh", 0.0): 1.0, ("exp", 0.0): 1.0,
               ("sqrt", 1.0): 1.0, ("log", 1.0): 0.0}


def call(func: str, arg) -> Expr:
    """``func(arg)`` for ``func`` in :data:`FUNCTIONS` (exact values folded)."""
    a = as_expr(arg)
    if func not in FUNCTIONS:
        raise ExprError(f"unknown function `{_clip(str(func))}` (known: {', '.join(FUNCTIONS)})")
    if isinstance(a, Num) and (func, a.value) in _CALL_FOLDS:
        return Num(_CALL_FOLDS[(func, a.value)])
    return Call(func, a)


# ---------------------------------------------------------------------------
# Iterative walks
# ---------------------------------------------------------------------------

def _postorder(roots: Iterable[Expr], prune: Callable[[Expr], bool] | None = None):
    """Every distinct node under ``roots``, children before parents (no recursion).
    Nodes for which ``prune`` is true are yielded without their children."""
    seen = set()
    for root in roots:
        if root in seen:
            continue
        stack = [(root, False)]
        while stack:
            node, expanded = stack.pop()
            if expanded:
                yield node
                continue
            if node in seen:
                continue
            seen.add(node)
            stack.append((node, True))
            if prune is None or not prune(node):
                for c in reversed(node.children()):
                    if c not in seen:
                        stack.append((c, False))


def _as_list(exprs) -> tuple[list, bool]:
    if isinstance(exprs, Expr):
        return [exprs], True
    if isinstance(exprs, (str, bytes)) or not isinstance(exprs, Iterable):
        raise ExprError(f"expected an expression or a list of expressions, got {exprs!r}")
    items = [as_expr(e) for e in exprs]
    return items, False


def free_symbols(expr: Expr) -> frozenset:
    """The names of the symbols in ``expr``."""
    return as_expr(expr)._free


def count_nodes(expr) -> int:
    """Number of distinct nodes (the size of the shared graph) under ``expr``."""
    items, _ = _as_list(expr)
    return sum(1 for _ in _postorder(items))


def substitute(expr: Expr, mapping: Mapping) -> Expr:
    """``expr`` with symbols replaced: ``mapping`` is name -> expression or number.
    The result is rebuilt (and so simplified) by the builders."""
    sub = {}
    for k, v in mapping.items():
        if not isinstance(k, str):
            raise ExprError(f"substitute: keys must be names, got {k!r}")
        sub[k] = as_expr(v)
    expr = as_expr(expr)
    keys = frozenset(sub)
    memo = {}
    for node in _postorder([expr], prune=lambda n: not (n._free & keys)):
        if not (node._free & keys):
            memo[node] = node
        elif isinstance(node, Sym):
            memo[node] = sub[node.name]
        else:
            memo[node] = _rebuild(node, [memo[c] for c in node.children()])
    return memo[expr]


def _rebuild(node: Expr, kids: list) -> Expr:
    if isinstance(node, Add):
        return add(*kids)
    if isinstance(node, Mul):
        return mul(*kids)
    if isinstance(node, Pow):
        return power(kids[0], kids[1])
    if isinstance(node, Call):
        return call(node.func, kids[0])
    return node


class Budget:
    """A running count of the work derivatives take, shared by several
    :func:`diff` calls (``diff(..., budget=b)``): each node differentiated
    spends the number of factors and terms it hands to the builders. Past
    ``limit`` units :func:`diff` raises :class:`ExprError` naming the limit,
    so an expression whose derivatives would take minutes is refused after
    ``limit`` units (:data:`MAX_DERIVATIVE_WORK`: a second or two) instead."""

    def __init__(self, limit: int = MAX_DERIVATIVE_WORK):
        self.limit, self.spent = int(limit), 0

    def spend(self, units: int) -> None:
        self.spent += units
        if self.spent > self.limit:
            raise ExprError(f"its derivatives take more than {self.limit} units of work (the limit "
                            f"MAX_DERIVATIVE_WORK); write the expression with fewer factors per product "
                            f"or less nesting")


def _width(e: Expr) -> int:
    return len(e.factors) if isinstance(e, Mul) else len(e.terms) if isinstance(e, Add) else 1


def diff(expr: Expr, name: str, *, budget: Budget | None = None) -> Expr:
    """The symbolic derivative ``d expr / d name``, simplified by the builders.

    Rules: sums and products term by term; ``d(b**e) = e b**(e-1) db`` when
    ``e`` is free of ``name``, else ``b**e (de log b + e db / b)``; the chain
    rule with ``sin' = cos``, ``cos' = -sin``, ``tan' = 1 + tan**2``,
    ``sinh' = cosh``, ``cosh' = sinh``, ``tanh' = 1 - tanh**2``,
    ``exp' = exp``, ``log'(u) = u**-1``, ``sqrt'(u) = 0.5 sqrt(u)**-1``.
    Shared subtrees are differentiated once. With a :class:`Budget`, the
    work is counted against it (:class:`ExprError` past its limit).
    """
    expr = as_expr(expr)
    if not isinstance(name, str):
        raise ExprError(f"diff: the variable must be a name, got {name!r}")
    d = {}
    for node in _postorder([expr], prune=lambda n: name not in n._free):
        if budget is not None and name in node._free:
            kids = node.children()
            # what the rule below hands to the builders: each child's derivative,
            # and for a product every factor once per term
            budget.spend(1 + sum(_width(d[c]) for c in kids if c in d)
                         + (len(kids) * len(kids) if isinstance(node, Mul) else 0))
        if name not in node._free:
            d[node] = ZERO
        elif isinstance(node, Sym):
            d[node] = ONE
        elif isinstance(node, Add):
            d[node] = add(*(d[t] for t in node.terms))
        elif isinstance(node, Mul):
            fs = node.factors
            terms = [mul(*fs[:i], d[f], *fs[i + 1:]) for i, f in enumerate(fs) if d[f] != ZERO]
            d[node] = add(*terms)
        elif isinstance(node, Pow):
            b, e = node.base, node.exp
            if name not in e._free:
                d[node] = mul(e, power(b, add(e, _MINUS_ONE)), d[b])
            else:
                d[node] = mul(node, add(mul(d[e], call("log", b)), mul(e, d[b], power(b, _MINUS_ONE))))
        elif isinstance(node, Call):
            u = node.arg
            f = node.func
            if f == "sin":
                outer = call("cos", u)
            elif f == "cos":
                outer = neg(call("sin", u))
            elif f == "tan":
                outer = add(ONE, power(node, Num(2.0)))
            elif f == "sinh":
                outer = call("cosh", u)
            elif f == "cosh":
                outer = call("sinh", u)
            elif f == "tanh":
                outer = add(ONE, neg(power(node, Num(2.0))))
            elif f == "exp":
                outer = node
            elif f == "log":
                outer = power(u, _MINUS_ONE)
            else:  # sqrt
                outer = mul(Num(0.5), power(node, _MINUS_ONE))
            d[node] = mul(outer, d[u])
        else:  # pragma: no cover - Num has no free symbols
            d[node] = ZERO
    return d[expr]


def gradient(expr: Expr, names: Sequence[str], *, budget: Budget | None = None) -> list:
    """``[d expr / d n for n in names]`` (``budget`` as for :func:`diff`)."""
    return [diff(expr, n, budget=budget) for n in names]


def hessian(expr: Expr, names: Sequence[str], *, budget: Budget | None = None) -> list:
    """The symmetric matrix (list of lists) of second derivatives; the upper
    triangle is differentiated and mirrored (``budget`` as for :func:`diff`,
    counting the gradient too)."""
    g = gradient(expr, names, budget=budget)
    n = len(names)
    H = [[None] * n for _ in range(n)]
    for i in range(n):
        for j in range(i, n):
            H[i][j] = H[j][i] = diff(g[i], names[j], budget=budget)
    return H


# ---------------------------------------------------------------------------
# Printing: canonical text and Python source
# ---------------------------------------------------------------------------

# Precedence of a printed piece (higher binds tighter).
_P_ADD, _P_MUL, _P_NEG, _P_POW, _P_ATOM = 1, 2, 3, 4, 5


def _is_negative(e: Expr) -> bool:
    if isinstance(e, Num):
        return e.value < 0.0 or (e.value == 0.0 and math.copysign(1.0, e.value) < 0)
    if isinstance(e, Mul):
        f = e.factors[0]
        return isinstance(f, Num) and f.value < 0.0
    return False


def _mul_parts(factors: tuple):
    """``(negative, numerators, denominators)`` of a product: a leading negative
    number gives the sign (its absolute value stays a numerator unless it is 1);
    ``b**-k`` (numeric ``k > 0``) is the denominator ``b**k``."""
    negative = False
    nums, dens = [], []
    for i, f in enumerate(factors):
        if i == 0 and isinstance(f, Num) and f.value < 0.0:
            negative = True
            if f.value != -1.0:
                nums.append(Num(-f.value))
        elif isinstance(f, Pow) and isinstance(f.exp, Num) and f.exp.value < 0.0:
            k = -f.exp.value
            dens.append(f.base if k == 1.0 else Pow(f.base, Num(k)))
        else:
            nums.append(f)
    return negative, nums, dens


def _num_text(v: float, *, source: bool) -> str:
    if not source and v.is_integer() and abs(v) < _EXACT_INT:
        return str(int(v))
    return repr(v)


class _Printer:
    """Prints expressions bottom-up (iteratively).

    ``names``: symbol name -> text; ``func``: function name -> text;
    ``source``: numbers as Python float literals; ``literal``: number ->
    text (overrides ``source``; the numpy backend names its float64
    constants); ``temps``: when true, shared nodes, deeply nested pieces and
    long chunks of sums become assignments ``_tN = ...`` (``temp_prefix``
    then ``N``) appended to ``lines`` (keeps every line far inside Python's
    parser and compiler limits); ``products`` (with ``temps``): integer
    powers ``2 <= n <=`` :data:`POWER_PRODUCTS_MAX` printed as binary
    powering, each square a temporary (:meth:`_integer_power`).
    """

    #: A piece whose syntax tree is deeper than this becomes a temporary.
    DEEP = 40
    #: Sums and products are written in chunks of this many operands.
    CHUNK = 40

    def __init__(self, names: Mapping[str, str] | None, func: Callable[[str], str], *, source: bool,
                 temps: bool = False, literal: Callable[[float], str] | None = None, temp_prefix: str = "_t",
                 products: bool = False):
        if products and not temps:
            raise ValueError("_Printer: `products` needs `temps` (each square is a temporary)")
        self.names, self.func, self.source = names, func, source
        self.products = products
        self.squares: dict[str, str] = {}
        self.temp_prefix = temp_prefix
        self.literal = literal
        self.use_temps = temps
        self.lines: list[str] = []
        self.memo: dict = {}
        self.shared: set = set()
        self.n_temps = 0

    # A printed piece: (text, precedence, syntax depth)
    def _temp(self, text: str):
        name = f"{self.temp_prefix}{self.n_temps}"
        self.n_temps += 1
        self.lines.append(f"{name} = {text}")
        return name

    def mark_shared(self, roots):
        """Count parents in the shared graph; nodes with two or more (that are
        not leaves) will be printed once, into a temporary."""
        if not self.use_temps:
            return
        parents = {}
        for node in _postorder(roots):
            for c in node.children():
                parents[c] = parents.get(c, 0) + 1
        self.shared = {n for n, k in parents.items() if k > 1 and n.children()}

    def print(self, root: Expr) -> str:
        for node in _postorder([root], prune=lambda n: n in self.memo):
            if node in self.memo:
                continue
            text, prec, depth = self._node(node)
            if self.use_temps and node.children() and (node in self.shared or depth > self.DEEP):
                text, prec, depth = self._temp(text), _P_ATOM, 1
            self.memo[node] = (text, prec, depth)
        return self.memo[root][0]

    def _get(self, e: Expr):
        piece = self.memo.get(e)
        if piece is None:  # a node made while printing (e.g. a positive denominator)
            self.print(e)
            piece = self.memo[e]
        return piece

    @staticmethod
    def _wrap(piece, min_prec):
        """``piece`` in parentheses when it binds looser than ``min_prec``."""
        text, prec, depth = piece
        return (f"({text})", _P_ATOM, depth + 1) if prec < min_prec else piece

    def _chain(self, pieces: list, ops: list, prec: int):
        """Join ``pieces`` with the binary ``ops`` (``ops[0]`` is unused), left
        to right, in chunks that become temporaries when too long."""
        if len(pieces) == 1:
            return pieces[0]
        text, depth = pieces[0][0], pieces[0][2]
        count = 1
        for (t, _, d), op in zip(pieces[1:], ops[1:]):
            if self.use_temps and count >= self.CHUNK:
                text, depth, count = self._temp(text), 1, 1
            text = f"{text} {op} {t}" if op in "+-" else f"{text}{op}{t}"
            depth = max(depth, d) + 1
            count += 1
        return text, prec, depth

    def _integer_power(self, piece, n: int):
        """``piece ** n`` as numba evaluates a float to an integer literal
        power (binary powering): the squares ``b*b``, ``(b*b)*(b*b)``, ...
        each a temporary, and the product of those the bits of ``n`` select,
        from the lowest bit up. Every step is one correctly rounded multiply,
        the same for a numpy array, a float and numba; ``pow`` is not (libm's
        and numpy's SIMD ``pow`` differ in the last bit, and numpy's takes a
        scalar path for a negative base, some 40 times slower than for a
        positive one)."""
        text, prec, depth = piece
        # a name or a number is repeated; anything else (a call, a sum) is computed once
        square = text if (prec == _P_ATOM and depth == 1) else self._temp(text)
        out, factors = None, 0
        while n:
            if n & 1:
                out = square if out is None else f"{out}*{square}"
                factors += 1
            n >>= 1
            if n:
                product = f"{square}*{square}"
                if product not in self.squares:  # x**2 and x**3 share x*x
                    self.squares[product] = self._temp(product)
                square = self.squares[product]
        return out, (_P_ATOM if factors == 1 else _P_MUL), factors

    def _node(self, node: Expr):
        if isinstance(node, Num):
            v = node.value
            if v < 0.0 or (v == 0.0 and math.copysign(1.0, v) < 0):
                return "-" + self._number(-v), _P_NEG, 2
            return self._number(v), _P_ATOM, 1
        if isinstance(node, Sym):
            if self.names is None:
                return node.name, _P_ATOM, 1
            if node.name not in self.names:
                raise ExprError(f"no variable given for the symbol `{node.name}`")
            return self.names[node.name], _P_ATOM, 1
        if isinstance(node, Call):
            text, depth = self._get(node.arg)[0], self._get(node.arg)[2]
            return f"{self.func(node.func)}({text})", _P_ATOM, depth + 2
        if isinstance(node, Pow):
            if isinstance(node.exp, Num) and node.exp.value < 0.0:
                return self._product((node,))
            n = _int_exponent(node.exp) if self.products else None
            if n is not None and 2 <= n <= POWER_PRODUCTS_MAX:
                return self._integer_power(self._get(node.base), n)
            base = self._wrap(self._get(node.base), _P_ATOM)
            if isinstance(node.exp, Num) and node.exp.value.is_integer() and abs(node.exp.value) < 2**31:
                exp = (str(int(node.exp.value)), _P_ATOM, 1)
            else:
                exp = self._wrap(self._get(node.exp), _P_POW)
            return f"{base[0]}**{exp[0]}", _P_POW, max(base[2], exp[2]) + 1
        if isinstance(node, Mul):
            return self._product(node.factors)
        if isinstance(node, Add):
            pieces, ops = [], []
            for i, t in enumerate(node.terms):
                if i > 0 and _is_negative(t) and not (self.use_temps and t in self.shared):
                    p = self._get(neg(t))
                    ops.append("-")
                    pieces.append(self._wrap(p, _P_MUL))
                else:
                    ops.append("+")
                    pieces.append(self._wrap(self._get(t), _P_ADD if i == 0 else _P_MUL))
            return self._chain(pieces, ops, _P_ADD)
        raise ExprError(f"cannot print {type(node).__name__}")  # pragma: no cover

    def _number(self, v: float) -> str:
        return self.literal(v) if self.literal is not None else _num_text(v, source=self.source)

    def _product(self, factors: tuple):
        negative, nums, dens = _mul_parts(factors)
        pieces, ops = [], []
        for f in nums:
            pieces.append(self._wrap(self._get(f), _P_POW))
            ops.append("*")
        if not pieces:
            pieces.append((self._number(1.0), _P_ATOM, 1))
            ops.append("*")
        for f in dens:
            pieces.append(self._wrap(self._get(f), _P_POW))
            ops.append("/")
        text, prec, depth = self._chain(pieces, ops, _P_MUL)
        if negative:
            # "-a*b" reads (-a)*b in Python: the same value, so it stays flat.
            return f"-{text}", (_P_NEG if len(pieces) == 1 else _P_MUL), depth + 1
        return text, prec, depth


def to_text(expr: Expr) -> str:
    """The canonical text of ``expr``: parseable by :func:`parse`, with
    ``**`` for powers, integers without a decimal point and other numbers in
    Python's shortest round-tripping form (``repr``)."""
    expr = as_expr(expr)
    return _Printer(None, lambda f: f, source=False).print(expr)


def digest(expr: Expr) -> str:
    """SHA-256 (hex) of the canonical text (:func:`to_text`), versioned; a
    stable key for caches of anything derived from ``expr``."""
    return hashlib.sha256(("rk4h.expr/1\n" + to_text(expr)).encode("utf-8")).hexdigest()


_SOURCE_VAR_RE = re.compile(r"[A-Za-z_][A-Za-z0-9_]*(?:\[[0-9]+\])?\Z")
_MODULE_RE = re.compile(r"[A-Za-z_][A-Za-z0-9_]*\Z")
#: to_source refuses expressions whose one-line source would nest deeper.
MAX_SOURCE_DEPTH = 150


def to_source(expr: Expr, var_names_map: Mapping[str, str], module: str = "math") -> str:
    """Python source text of one expression, for scalar code (e.g. numba's ``njit``).

    Parameters
    ----------
    expr : Expr
    var_names_map : mapping
        Symbol name -> the source text that holds its value: an identifier or
        an identifier with one integer subscript (``"q[0]"``). Every free
        symbol of ``expr`` must be mapped.
    module : str
        Prefix of the functions: ``"math"`` gives ``math.sin(q[0])`` (so the
        caller's code must ``import math``); ``"np"`` gives ``np.sin(...)``.

    Returns
    -------
    str
        One expression: only the mapped variables, float literals, ``+ - * /
        **``, parentheses and ``module.f(...)`` for ``f`` in :data:`FUNCTIONS`.
        Python semantics apply: ``math.log`` of a negative number raises, a
        negative number to a fractional power is complex in plain Python (nan
        under numba). Expressions nested deeper than ``MAX_SOURCE_DEPTH``
        raise :class:`ExprError` (use ``lambdify(..., backend="math").source``,
        which writes temporaries).
    """
    expr = as_expr(expr)
    if not isinstance(module, str) or not _MODULE_RE.match(module) or "__" in module:
        raise ExprError(f"to_source: `module` must be an identifier such as 'math', got {module!r}")
    names = _check_var_map(var_names_map, expr._free)
    printer = _Printer(names, lambda f: f"{module}.{f}", source=True)
    text = printer.print(expr)
    if printer.memo[expr][2] > MAX_SOURCE_DEPTH:
        raise ExprError(f"to_source: the expression nests deeper than {MAX_SOURCE_DEPTH} levels "
                        f"for one line of source; use lambdify(..., backend='math').source")
    return text


def _check_var_map(var_names_map, needed) -> dict:
    if not isinstance(var_names_map, Mapping):
        raise ExprError(f"`var_names_map` must map symbol names to source variables, got {var_names_map!r}")
    out = {}
    for k, v in var_names_map.items():
        if not isinstance(v, str) or not _SOURCE_VAR_RE.match(v) or "__" in v or keyword.iskeyword(v.split("[")[0]):
            raise ExprError(f"`var_names_map[{k!r}]` must be an identifier or `name[i]`, got {v!r}")
        out[k] = v
    missing = sorted(set(needed) - set(out))
    if missing:
        raise ExprError(f"no variable given for the symbol `{missing[0]}`")
    return out


def _numpy_namespace():
    import numpy as np

    def _bc(value, shape):
        out = np.empty(shape, dtype=np.result_type(value, np.float64))
        out[...] = value
        return out if out.ndim else out[()]

    def _num(value):
        # float64, or complex128 for complex input (complex-step derivatives)
        a = np.asarray(value)
        return a.astype(np.complex128 if np.iscomplexobj(a) else np.float64, copy=False)

    ns = {f"_f_{f}": getattr(np, f) for f in FUNCTIONS}
    ns.update({"_num": _num, "_bshape": np.broadcast_shapes,
               "_shape": np.shape, "_bc": _bc})
    return ns


def _math_namespace():
    return {f"_f_{f}": getattr(math, f) for f in FUNCTIONS}


def lambdify(exprs, names: Sequence[str], backend: str = "numpy", *, broadcast: bool = True):
    """Compile expressions into a Python function of the symbols ``names``.

    Parameters
    ----------
    exprs : Expr or sequence of Expr
    names : sequence of str
        The function's positional arguments, in order; every free symbol of
        ``exprs`` must be among them (others are allowed and ignored).
    backend : {"numpy", "math"}
        ``"numpy"``: the arguments may be floats or arrays (broadcast
        together, e.g. each of shape (m,)); each result is a float64 array of
        the broadcast shape (a numpy scalar for scalar inputs), with numpy's
        semantics (nan/inf with a warning, never an exception; every number
        of the expression is a ``numpy.float64``, so even a constant
        ``1/0`` gives inf).
        ``"math"``: floats in, floats out, with the ``math`` module and
        Python's semantics (``math.log(-1)`` and ``1/0`` raise, an overflow
        in ``**`` raises; an integer power is products, see Notes, and
        overflows to inf).
    broadcast : bool
        numpy backend only. False skips converting and broadcasting: the
        arguments must already be numpy scalars (``numpy.float64``, e.g. the
        entries of a 1-D array) or arrays of one shape, and a constant
        expression returns a scalar. About 8x faster for one state of a
        small system (the fixed-step solvers' case).

    Returns
    -------
    callable
        ``f(*values)`` returning one result for a single expression, a list
        (numpy) or tuple (math) for a sequence. ``f.source`` is the generated
        Python source (``def _rk4core_expr(...)``, functions named
        ``_f_sin``, ...); ``f.names`` the argument names.

    Notes
    -----
    No user text is ever evaluated: the source is printed from the validated
    tree, whose only leaves are numbers and argument names generated here
    (``_x0, _x1, ...``), and it runs in a namespace that holds only the numpy
    (or math) functions of :data:`FUNCTIONS` (and, for numpy, the numbers as
    ``_k0, _k1, ...``) and no builtins. Shared subexpressions are computed
    once (temporaries ``_t0, _t1, ...``); long sums and deep nesting are split
    into temporaries so the source stays inside Python's parser limits.

    A power ``b**n`` with an integer ``2 <= n <=`` :data:`POWER_PRODUCTS_MAX`
    is printed as products by binary powering (``b**3 = b * (b*b)``), the
    multiplications numba performs for ``b**n`` with an integer literal: so
    a model's numpy path equals its compiled loop bit for bit, on every
    processor (numpy's SIMD ``pow`` and libm's differ in the last bit), and
    a negative base costs what a positive one does (numpy's ``pow`` takes a
    scalar path for it, about 40 times slower than for a positive base).
    Other powers call ``**``.
    """
    items, single = _as_list(exprs)
    if backend not in ("numpy", "math"):
        raise ExprError(f"`backend` must be 'numpy' or 'math', got {backend!r}")
    if isinstance(names, (str, bytes)) or not isinstance(names, Iterable):
        raise ExprError(f"`names` must be a list of names, got {names!r}")
    names = list(names)
    for n in names:
        problem = check_name(n)
        if problem:
            raise ExprError(f"`names`: {problem}")
    if len(set(names)) != len(names):
        raise ExprError(f"`names` must be distinct, got {names!r}")
    needed = frozenset().union(*(e._free for e in items)) if items else frozenset()
    missing = sorted(needed - set(names))
    if missing:
        raise ExprError(f"the symbol `{missing[0]}` is not among the arguments ({', '.join(names)})")
    args = [f"_x{i}" for i in range(len(names))]
    if backend == "numpy":
        import numpy as np

        ns = _numpy_namespace()
        consts: dict = {}

        def literal(v: float) -> str:
            key = (v, math.copysign(1.0, v))
            if key not in consts:
                consts[key] = f"_k{len(consts)}"
                ns[consts[key]] = np.float64(v)
            return consts[key]
    else:
        ns = _math_namespace()
        literal = None
    printer = _Printer(dict(zip(names, args)), lambda f: f"_f_{f}", source=True, temps=True, literal=literal,
                       products=True)
    printer.mark_shared(items)
    results = [printer.print(e) for e in items]
    body = []
    if backend == "numpy" and broadcast:
        body += [f"{a} = _num({a})" for a in args]
        shapes = ", ".join(f"_shape({a})" for a in args)
        body.append(f"_s = _bshape({shapes})")
        body += printer.lines
        outs = [f"_bc({r}, _s)" for r in results]
        body.append(f"return {outs[0]}" if single else f"return [{', '.join(outs)}]")
    elif backend == "numpy":
        body += printer.lines
        body.append(f"return {results[0]}" if single else f"return [{', '.join(results)}]")
    else:
        body += printer.lines
        body.append(f"return {results[0]}" if single else
                    f"return ({', '.join(results)}{',' if len(results) == 1 else ''})")
    src = f"def _rk4core_expr({', '.join(args)}):\n" + "".join(f"    {line}\n" for line in body)
    ns["__builtins__"] = {}
    code = compile(src, "<rk4h.expr.lambdify>", "exec")
    exec(code, ns)  # noqa: S102 - source printed from a validated tree, see Notes
    fn = ns["_rk4core_expr"]
    fn.source = src
    fn.names = tuple(names)
    return fn


def to_heyoka(exprs, symbols: Mapping):
    """heyoka expression(s) of ``exprs``.

    Parameters
    ----------
    exprs : Expr or sequence of Expr
    symbols : mapping
        Symbol name -> heyoka expression (a variable such as
        ``heyoka.make_vars("x")``, or any heyoka expression, e.g. ``par[0] * z0``).

    Returns
    -------
    heyoka.expression, or a list of them for a sequence. Numbers become
    heyoka numbers holding the same doubles (``heyoka.expression(float)``);
    in a real128 integration heyoka widens them exactly. The structure
    mirrors the numpy source (:func:`lambdify`): ``a - b`` for a negative
    term, ``n / d`` for negative powers. Shared subtrees are translated once.
    A power with an integer exponent 1..64 becomes products (binary powering:
    ``x**3 = x * x * x``, ``x**4 = (x*x) * (x*x)``), never heyoka's ``pow``:
    the Taylor recurrence of ``pow(x, a)`` divides by ``x`` and is NaN where
    ``x`` is exactly 0 (an FPUT spring at zero extension).
    """
    from rk4h._heyoka import heyoka as _heyoka
    hy = _heyoka()

    items, single = _as_list(exprs)
    if not isinstance(symbols, Mapping):
        raise ExprError(f"`symbols` must map names to heyoka expressions, got {symbols!r}")
    needed = frozenset().union(*(e._free for e in items)) if items else frozenset()
    missing = sorted(needed - set(symbols))
    if missing:
        raise ExprError(f"no heyoka expression given for the symbol `{missing[0]}`")
    funcs = {f: getattr(hy, f) for f in FUNCTIONS}
    memo = {}

    def get(e):
        if e not in memo:
            build_all([e])
        return memo[e]

    def product(factors):
        negative, nums, dens = _mul_parts(factors)
        out = None
        for f in nums:
            out = get(f) if out is None else out * get(f)
        if out is None:
            out = hy.expression(1.0)
        for f in dens:
            out = out / get(f)
        return -out if negative else out

    def integer_power(b, n):
        # Binary powering with products: heyoka's Taylor recurrence of pow(x, a)
        # divides by x, so pow(x, 3.0) is NaN wherever x passes through 0.
        out, square = None, b
        while n:
            if n & 1:
                out = square if out is None else out * square
            n >>= 1
            if n:
                square = square * square
        return out

    def build(node):
        if isinstance(node, Num):
            return hy.expression(node.value)
        if isinstance(node, Sym):
            return symbols[node.name]
        if isinstance(node, Call):
            return funcs[node.func](get(node.arg))
        if isinstance(node, Pow):
            if isinstance(node.exp, Num):
                if node.exp.value < 0.0:
                    return product((node,))
                n = _int_exponent(node.exp)
                if n is not None and 0 < n <= POWER_PRODUCTS_MAX:
                    return integer_power(get(node.base), n)
                return get(node.base) ** hy.expression(node.exp.value)
            return get(node.base) ** get(node.exp)
        if isinstance(node, Mul):
            return product(node.factors)
        out = None
        for i, t in enumerate(node.terms):
            if i > 0 and _is_negative(t):
                out = out - get(neg(t))
            else:
                out = get(t) if out is None else out + get(t)
        return out

    def build_all(roots):
        for node in _postorder(roots, prune=lambda n: n in memo):
            if node not in memo:
                memo[node] = build(node)

    build_all(items)
    out = [memo[e] for e in items]
    return out[0] if single else out


# ---------------------------------------------------------------------------
# Parser
# ---------------------------------------------------------------------------

@dataclass(frozen=True)
class _Token:
    kind: str   # "num", "name", "op", "(", ")", "end"
    text: str
    col: int    # 1-based
    value: float = field(default=0.0)


def _show_char(ch: str) -> str:
    return ch if ch.isprintable() else ch.encode("unicode_escape").decode("ascii")


def _tokenize(text: str) -> list:
    tokens = []
    i, n = 0, len(text)
    while i < n:
        ch = text[i]
        col = i + 1
        if ch in _WHITESPACE:
            i += 1
            continue
        if ch.isdigit() and ch.isascii() or (ch == "." and i + 1 < n and text[i + 1].isdigit()
                                             and text[i + 1].isascii()):
            m = _NUMBER_RE.match(text, i)
            end = m.end()
            if end < n and (text[end].isascii() and (text[end].isalnum() or text[end] in "_.")):
                word = _WORD_RE.match(text, i).group()
                raise ExprError(f"malformed number `{_clip(word)}` at column {col}")
            literal = m.group()
            value = float(literal)
            if not math.isfinite(value):
                raise ExprError(f"number `{_clip(literal)}` at column {col} is not finite")
            tokens.append(_Token("num", literal, col, value))
            i = end
            continue
        if ch.isascii() and (ch.isalpha() or ch == "_"):
            word = _NAME_TOKEN_RE.match(text, i).group()
            if "__" in word:
                raise ExprError(f"name `{_clip(word)}` at column {col} is not allowed (double underscore)")
            if keyword.iskeyword(word):
                raise ExprError(f"`{word}` at column {col} is a Python keyword, not part of an expression")
            tokens.append(_Token("name", word, col))
            i += len(word)
            continue
        if text.startswith("**", i):
            tokens.append(_Token("op", "**", col))
            i += 2
            continue
        if ch in "+-*/^":
            tokens.append(_Token("op", ch, col))
            i += 1
            continue
        if ch in "()":
            tokens.append(_Token(ch, ch, col))
            i += 1
            continue
        hint = ""
        if ch == ",":
            hint = " (functions take one argument)"
        elif ch == "." :
            hint = " (attribute access is not part of an expression)"
        elif ch in "'\"":
            hint = " (strings are not part of an expression)"
        elif ch in "[]{}":
            hint = " (only ( ) group)"
        raise ExprError(f"unexpected `{_show_char(ch)}` at column {col}{hint}")
    tokens.append(_Token("end", "", n + 1))
    return tokens


def _check_parens(tokens):
    stack = []
    for t in tokens:
        if t.kind == "(":
            stack.append(t.col)
            if len(stack) > MAX_DEPTH:
                raise ExprError(f"nesting deeper than {MAX_DEPTH} levels at column {t.col}")
        elif t.kind == ")":
            if not stack:
                raise ExprError(f"unbalanced parenthesis at column {t.col} (`)` without `(`)")
            stack.pop()
    if stack:
        raise ExprError(f"unbalanced parenthesis at column {stack[0]} (`(` is never closed)")


# Binding powers (Pratt): left binding power of the binary operators, and the
# right binding power with which their right operand is parsed.
_LBP = {"+": 10, "-": 10, "*": 20, "/": 20, "**": 40, "^": 40}
_RBP = {"+": 11, "-": 11, "*": 21, "/": 21, "**": 39, "^": 39}
_UNARY_BP = 30


class _Parser:
    def __init__(self, tokens, symbols: dict, known: list):
        self.tokens, self.pos = tokens, 0
        self.symbols, self.known = symbols, known

    def peek(self):
        return self.tokens[self.pos]

    def next(self):
        t = self.tokens[self.pos]
        self.pos += 1
        return t

    def known_text(self):
        if not self.known:
            return "none"
        shown = self.known[:20]
        return ", ".join(shown) + (", ..." if len(self.known) > 20 else "")

    def parse(self):
        e = self.expr(0, 1)
        t = self.peek()
        if t.kind != "end":  # pragma: no cover - expr() stops only at ")" or the end
            raise ExprError(f"unexpected `{t.text}` at column {t.col}")
        return e

    def expr(self, rbp: int, depth: int):
        if depth > MAX_DEPTH:
            raise ExprError(f"nesting deeper than {MAX_DEPTH} levels at column {self.peek().col}")
        col = self.peek().col
        left = self.prefix(depth)
        # Operators met in this loop never rise in precedence (a higher one
        # is consumed by the right operand's own call), so a run of + and -
        # (or of * and /) is collected and built once: a sum of n terms costs
        # O(n), not O(n^2).
        kind, group = None, []
        while True:
            t = self.peek()
            if t.kind == "op":
                if _LBP[t.text] <= rbp:
                    return self.finish(kind, group, left, col)
                self.next()
                self.operand_expected(t)
                right = self.expr(_RBP[t.text], depth + 1)
                if t.text in ("**", "^"):
                    left = power(left, right)
                    continue
                k = "add" if t.text in "+-" else "mul"
                if k != kind:
                    left = self.finish(kind, group, left, col)
                    kind, group = k, [left]
                group.append(self.operand(t.text, right))
            elif t.kind in ("num", "name", "("):
                what = "number" if t.kind == "num" else ("name" if t.kind == "name" else "`(`")
                shown = f"`{_clip(t.text)}`" if t.kind != "(" else "`(`"
                raise ExprError(f"unexpected {what + ' ' if t.kind != '(' else ''}{shown} at column {t.col} "
                                f"(missing operator?)")
            else:  # ")" or end
                return self.finish(kind, group, left, col)

    @staticmethod
    def finish(kind, group, left, col):
        if kind == "add":
            return add(*group)
        if kind == "mul":
            e = mul(*group)
            if isinstance(e, Mul) and len(e.factors) > MAX_FACTORS:
                k = sum(1 for f in e.factors if _numeric(f) is None)
                if k > MAX_FACTORS:
                    raise ExprError(f"the product at column {col} has {k} factors that are not numbers, above "
                                    f"the limit of {MAX_FACTORS} (MAX_FACTORS: its second derivatives grow as "
                                    f"the cube of the number of factors)")
            return e
        return left

    @staticmethod
    def operand(op, right):
        if op == "-":
            return neg(right)
        if op == "/":
            return power(right, _MINUS_ONE)
        return right

    def operand_expected(self, op):
        t = self.peek()
        if t.kind == "end":
            raise ExprError(f"missing operand after `{op.text}` at column {op.col}")

    def prefix(self, depth):
        t = self.next()
        if t.kind == "num":
            return Num(t.value)
        if t.kind == "name":
            if self.peek().kind == "(":
                if t.text not in FUNCTIONS:
                    raise ExprError(f"unknown function `{_clip(t.text)}` at column {t.col} "
                                    f"(known: {', '.join(FUNCTIONS)})")
                lp = self.next()
                if self.peek().kind == ")":
                    raise ExprError(f"missing argument of `{t.text}` at column {lp.col + 1}")
                arg = self.expr(0, depth + 1)
                self.closing(lp)
                return call(t.text, arg)
            if t.text in FUNCTIONS:
                raise ExprError(f"function `{t.text}` at column {t.col} needs its argument in "
                                f"parentheses, as {t.text}(...)")
            if t.text not in self.symbols:
                raise ExprError(f"unknown name `{_clip(t.text)}` at column {t.col} "
                                f"(known: {self.known_text()})")
            return self.symbols[t.text]
        if t.kind == "(":
            if self.peek().kind == ")":
                raise ExprError(f"empty parentheses at column {t.col}")
            e = self.expr(0, depth + 1)
            self.closing(t)
            return e
        if t.kind == "op" and t.text in "+-":
            self.operand_expected(t)
            e = self.expr(_UNARY_BP, depth + 1)
            return neg(e) if t.text == "-" else e
        if t.kind == "end":  # pragma: no cover - caught by operand_expected / empty check
            raise ExprError(f"missing operand at column {t.col}")
        raise ExprError(f"unexpected `{t.text}` at column {t.col} (expected a number, a name, "
                        f"a function call or `(`)")

    def closing(self, lp):
        t = self.next()
        if t.kind != ")":  # pragma: no cover - parentheses are balanced by _check_parens
            raise ExprError(f"unbalanced parenthesis at column {lp.col} (`(` is never closed)")


def parse(text: str, names: Sequence[str], constants: Mapping[str, float] | None = None) -> Expr:
    """Parse ``text`` into an expression tree (see the module docstring for the grammar).

    Parameters
    ----------
    text : str
        At most :data:`MAX_LENGTH` characters.
    names : sequence of str
        The symbols the text may use (a model's coordinates); each a valid
        name (:func:`check_name`), all distinct.
    constants : mapping of str to float, optional
        Named numbers: each finite and real, substituted as its double value.
        A name may not be both a symbol and a constant.

    Returns
    -------
    Expr

    Raises
    ------
    ExprError
        One line naming the problem and the 1-based column, e.g. ``unknown
        name `foo` at column 5 (known: x, y, k)``.
    """
    if not isinstance(text, str):
        raise ExprError(f"the expression must be a string, got {type(text).__name__}")
    if len(text) > MAX_LENGTH:
        raise ExprError(f"expression longer than {MAX_LENGTH} characters (got {len(text)})")
    if isinstance(names, (str, bytes)) or not isinstance(names, Iterable):
        raise ExprError(f"the names must be a list of strings, got {names!r}")
    names = list(names)
    syms: dict = {}
    for n in names:
        problem = check_name(n)
        if problem:
            raise ExprError(problem)
        if n in syms:
            raise ExprError(f"name `{n}` is given twice")
        syms[n] = Sym(n)
    known = list(names)
    if constants is not None:
        if not isinstance(constants, Mapping):
            raise ExprError(f"the constants must be a mapping of names to numbers, got {constants!r}")
        for k, v in constants.items():
            problem = check_name(k)
            if problem:
                raise ExprError(f"constant {problem}")
            if k in syms:
                raise ExprError(f"name `{k}` is both a coordinate and a constant")
            if isinstance(v, bool) or not isinstance(v, Real) or not math.isfinite(float(v)):
                raise ExprError(f"constant `{k}` must be a finite number, got {v!r}")
            syms[k] = Num(float(v))
            known.append(k)
    tokens = _tokenize(text)
    if len(tokens) == 1:
        raise ExprError("empty expression")
    _check_parens(tokens)
    return _Parser(tokens, syms, known).parse()
