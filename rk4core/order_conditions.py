"""Order conditions of explicit (partitioned) Runge-Kutta methods, exactly.

A Runge-Kutta method (``A``, ``b``) has order ``p`` when, for every rooted
tree ``t`` with at most ``p`` vertices, its elementary weight satisfies

    b^T Phi(t) = 1 / gamma(t)

(Butcher's condition; Hairer-Norsett-Wanner I, sec. II.2, Theorem 2.13).
Here ``Phi(leaf) = 1`` (the vector of ones) and, for a tree whose root has
the subtrees ``t_1 ... t_m``, ``Phi(t)_i = prod_k (A Phi(t_k))_i``; the
density is ``gamma(t) = |t| prod_k gamma(t_k)``.

A partitioned method -- ``A, b`` for the first part ``y' = f(y, z)`` of the
state, ``A_v, b_v`` for the second part ``z' = g(y, z)`` -- has order ``p``
when the same holds over every *bi-coloured* tree with at most ``p`` vertices
(Hairer-Lubich-Wanner, Geometric Numerical Integration, 2nd ed., sec. III.2.1,
Theorem 2.4): a vertex of colour 0 stands for ``f``, of colour 1 for ``g``;
the colour of a child picks the matrix on the edge to it (``A`` for colour 0,
``A_v`` for colour 1) and the colour of the root picks the weights (``b`` or
``b_v``). In :mod:`rk4h.methods` colour 0 is the position half ``q`` and
colour 1 the velocity half ``v``.

All arithmetic is in :class:`fractions.Fraction`: a condition holds or it
does not. A tableau whose entries are not the intended values (decimals
printed to 8 places, ``1/3`` typed as ``0.333...``) passes with its
``uncertainty``: bounds ``dA, db`` (``dA_v, db_v``) on how far each entry may
be off. A condition then holds when

    |b^T Phi(t) - 1/gamma(t)| <= (|b| + db)^T Phi_{|A| + dA}(t) - |b|^T Phi_{|A|}(t),

the right side being the most that entries within those bounds can change
the weight (each term of the weight is a product of entries; with absolute
values and every entry at its bound, the sum can only grow). An exact entry
has bound 0, so an exact tableau is judged exactly. The older ``tol``
(relative, ``|residual| <= tol * |b|^T Phi_|A|(t)``) is kept for callers.

Trees are nested tuples: a tree is the sorted tuple of its subtrees, the
single vertex is ``()``; a bi-coloured tree is ``(colour, children)`` with
sorted children. They are generated once per order and kept.

References
----------
J. C. Butcher, *Numerical Methods for Ordinary Differential Equations*,
2nd ed., Wiley 2008, sec. 30-31 (trees, elementary weights, order).
E. Hairer, S. P. Norsett, G. Wanner, *Solving Ordinary Differential
Equations I*, 2nd ed., Springer 1993, sec. II.2.
E. Hairer, C. Lubich, G. Wanner, *Geometric Numerical Integration*, 2nd ed.,
Springer 2006, sec. III.2 (partitioned methods, bi-coloured trees).
"""
from __future__ import annotations

from fractions import Fraction
from functools import lru_cache
from typing import Sequence

__all__ = ["MAX_ORDER", "MAX_ORDER_PARTITIONED", "rooted_trees", "bicoloured_trees", "tree_order", "density",
           "tree_conditions", "bicoloured_tree_conditions", "elementary_weight", "order", "residuals",
           "separable_trees", "symmetry", "error_coefficients", "principal_error_norm"]

#: Highest order :func:`order` checks for a classical method (1205 trees).
MAX_ORDER = 10
#: Highest order :func:`order` checks for a partitioned method (24 250 trees).
MAX_ORDER_PARTITIONED = 8


# -- trees --------------------------------------------------------------------------------------------
def tree_order(tree) -> int:
    """Number of vertices of a tree (plain or bi-coloured)."""
    children = tree[1] if _coloured(tree) else tree
    return 1 + sum(tree_order(c) for c in children)


def density(tree) -> int:
    """``gamma(t) = |t| prod gamma(children)`` (colours play no part)."""
    children = tree[1] if _coloured(tree) else tree
    g = tree_order(tree)
    for c in children:
        g *= density(c)
    return g


def _coloured(tree) -> bool:
    return len(tree) == 2 and isinstance(tree[0], int)


def _grow(tree):
    """Every tree with one more leaf than ``tree`` (plain trees)."""
    yield tuple(sorted(tree + ((),)))
    for k, child in enumerate(tree):
        for g in _grow(child):
            yield tuple(sorted(tree[:k] + (g,) + tree[k + 1:]))


def _grow_coloured(tree):
    """Every bi-coloured tree with one more leaf (of either colour) than ``tree``."""
    colour, children = tree
    for leaf_colour in (0, 1):
        yield (colour, tuple(sorted(children + ((leaf_colour, ()),))))
    for k, child in enumerate(children):
        for g in _grow_coloured(child):
            yield (colour, tuple(sorted(children[:k] + (g,) + children[k + 1:])))


@lru_cache(maxsize=None)
def rooted_trees(p: int) -> tuple:
    """The rooted trees with exactly ``p`` vertices (1, 1, 2, 4, 9, 20, 48,
    115, 286, 719 for p = 1..10), in a fixed order."""
    if p < 1:
        raise ValueError(f"`p` must be >= 1, got {p!r}")
    if p == 1:
        return ((),)
    return tuple(sorted({g for t in rooted_trees(p - 1) for g in _grow(t)}))


@lru_cache(maxsize=None)
def bicoloured_trees(p: int) -> tuple:
    """The bi-coloured rooted trees with exactly ``p`` vertices (2, 4, 14,
    52, 214, 916, 4116, 18996 for p = 1..8), in a fixed order."""
    if p < 1:
        raise ValueError(f"`p` must be >= 1, got {p!r}")
    if p == 1:
        return ((0, ()), (1, ()))
    return tuple(sorted({g for t in bicoloured_trees(p - 1) for g in _grow_coloured(t)}))


@lru_cache(maxsize=None)
def separable_trees(p: int) -> tuple:
    """The bi-coloured trees with ``p`` vertices that a method applied to
    ``q' = v``, ``v' = a(q, t)`` must integrate (Nystrom trees; HNW I, sec.
    II.14; HLW sec. III.2.3): a colour-0 vertex (``q' = v``, linear in
    ``v`` alone) has at most one child, of colour 1; a colour-1 vertex
    (``v' = a(q)``) has only colour-0 children. Every other elementary
    differential of such a system vanishes (2, 2, 3, 5, 9, 16, 30, 56 trees
    for p = 1..8)."""

    def ok(t):
        colour, kids = t
        if colour == 0 and (len(kids) > 1 or any(k[0] != 1 for k in kids)):
            return False
        if colour == 1 and any(k[0] != 0 for k in kids):
            return False
        return all(ok(k) for k in kids)

    return tuple(t for t in bicoloured_trees(p) if ok(t))


def tree_conditions(p: int) -> list[tuple[tuple, int]]:
    """The order conditions of order exactly ``p``: ``(tree, gamma)`` for every
    rooted tree with ``p`` vertices; the condition is ``b^T Phi(tree) = 1/gamma``."""
    return [(t, density(t)) for t in rooted_trees(p)]


def bicoloured_tree_conditions(p: int) -> list[tuple[tuple, int]]:
    """As :func:`tree_conditions` over the bi-coloured trees (partitioned methods)."""
    return [(t, density(t)) for t in bicoloured_trees(p)]


# -- elementary weights -------------------------------------------------------------------------------
def _matvec(M, x):
    return tuple(sum((m * xj for m, xj in zip(row, x) if m), Fraction(0)) for row in M)


class _Weights:
    """Memoised stage vectors ``Phi(t)`` of one method (plain or bi-coloured)."""

    def __init__(self, mats):
        self.mats = mats  # (A,) or (A, A_v): the matrix picked by a child's colour
        self.s = len(mats[0])
        self.memo = {}

    def phi(self, tree):
        v = self.memo.get(tree)
        if v is not None:
            return v
        if len(self.mats) == 1:
            kids = [(0, c) for c in tree]
        else:
            kids = [(c[0], c) for c in tree[1]]
        v = tuple(Fraction(1) for _ in range(self.s))
        for colour, c in kids:
            w = _matvec(self.mats[colour], self.phi(c))
            v = tuple(a * b for a, b in zip(v, w))
        self.memo[tree] = v
        return v


def _exact(M):
    if M is None:
        return None
    if len(M) and isinstance(M[0], (list, tuple)) or hasattr(M, "ndim") and M.ndim == 2:
        return tuple(tuple(Fraction(x) for x in row) for row in M)
    return tuple(Fraction(x) for x in M)


def elementary_weight(tree, A, b, A_v=None, b_v=None) -> Fraction:
    """``b^T Phi(tree)`` for a plain tree, or ``w_root^T Phi(tree)`` for a
    bi-coloured one (``w`` = ``b`` for root colour 0, ``b_v`` for colour 1)."""
    A, b, A_v, b_v = _exact(A), _exact(b), _exact(A_v), _exact(b_v)
    if _coloured(tree):
        W = _Weights((A, A_v if A_v is not None else A))
        w = b if tree[0] == 0 else (b_v if b_v is not None else b)
    else:
        W, w = _Weights((A,)), b
    return sum((x * y for x, y in zip(w, W.phi(tree))), Fraction(0))


class _Judge:
    """The residual and the tolerance of each condition of one method."""

    def __init__(self, A, b, A_v, b_v, uncertainty, tol, trees=None):
        partitioned = A_v is not None or b_v is not None
        if partitioned and (A_v is None or b_v is None):
            raise ValueError("`A_v` and `b_v` must be given together")
        A, b = _exact(A), _exact(b)
        self.partitioned = partitioned
        self.tol = Fraction(tol)
        if partitioned:
            A_v, b_v = _exact(A_v), _exact(b_v)
            mats, weights = (A, A_v), (b, b_v)
            self.trees, self.root = trees or bicoloured_trees, (lambda t: t[0])
        else:
            mats, weights = (A,), (b,)
            self.trees, self.root = rooted_trees, (lambda t: 0)
        self.W, self.weights = _Weights(mats), weights
        self.abs_weights = tuple(_absv(w) for w in weights)
        self.Wabs = _Weights(tuple(_absm(M) for M in mats)) if (self.tol or uncertainty) else None
        self.Wup = None
        if uncertainty is not None:
            u = list(uncertainty) + [None] * (4 - len(uncertainty))
            dmats = (u[0], u[2]) if partitioned else (u[0],)
            dweights = (u[1], u[3]) if partitioned else (u[1],)
            dmats = tuple(_exact(d) if d is not None else _zeros_like(M) for d, M in zip(dmats, mats))
            dweights = tuple(_exact(d) if d is not None else _zeros_like(w) for d, w in zip(dweights, weights))
            self.Wup = _Weights(tuple(tuple(tuple(abs(x) + y for x, y in zip(r, dr)) for r, dr in zip(M, dM))
                                      for M, dM in zip(mats, dmats)))
            self.up_weights = tuple(tuple(abs(x) + y for x, y in zip(w, dw)) for w, dw in zip(weights, dweights))

    def residual(self, t) -> Fraction:
        w = self.weights[self.root(t)]
        return sum((x * y for x, y in zip(w, self.W.phi(t))), Fraction(0)) - Fraction(1, density(t))

    def allowed(self, t) -> Fraction:
        """The largest residual condition ``t`` may have and still hold."""
        r = self.root(t)
        out = Fraction(0)
        if self.Wabs is not None:
            size = sum((x * y for x, y in zip(self.abs_weights[r], self.Wabs.phi(t))), Fraction(0))
            out = self.tol * size
            if self.Wup is not None:
                up = sum((x * y for x, y in zip(self.up_weights[r], self.Wup.phi(t))), Fraction(0))
                out = max(out, up - size)
        return out


def _zeros_like(M):
    if len(M) and isinstance(M[0], tuple):
        return tuple(tuple(Fraction(0) for _ in row) for row in M)
    return tuple(Fraction(0) for _ in M)


def order(A: Sequence, b: Sequence, A_v: Sequence | None = None, b_v: Sequence | None = None, *,
          max_order: int | None = None, tol=0, uncertainty=None, trees=None) -> int:
    """Order of the (partitioned) Runge-Kutta method from its order conditions.

    Parameters
    ----------
    A : (s, s) sequence of numbers
        Runge-Kutta matrix (of the first part, for a partitioned method).
        Entries are converted with ``Fraction(x)`` (exact for ints, floats,
        Fractions and rational strings).
    b : (s,) sequence
        Weights.
    A_v, b_v : optional
        Coefficients of the second part; given together, they make the
        conditions those over bi-coloured trees.
    max_order : int, optional
        Highest order checked: :data:`MAX_ORDER` (10) for a classical method,
        :data:`MAX_ORDER_PARTITIONED` (8) for a partitioned one.
    tol : number, optional
        Relative tolerance for tableaux carrying float round-off (module
        docstring); 0 (the default) demands exact equality.
    uncertainty : tuple, optional
        ``(dA, db)`` or ``(dA, db, dA_v, db_v)``: nonnegative bounds, entry by
        entry, on how far the coefficients may be from the intended ones
        (:attr:`rk4h.methods.Tableau.uncertainty`); a condition holds when
        its residual is within what such errors can produce (module
        docstring). None: exact.
    trees : callable, optional
        ``p -> trees of order p`` for a partitioned method, in place of
        :func:`bicoloured_trees`: :func:`separable_trees` gives the order on
        ``q' = v``, ``v' = a(q, t)`` alone (splitting methods written as
        tableaux are equivalent to their splitting only there).

    Returns
    -------
    int
        The largest ``p <= max_order`` such that every condition of order
        ``<= p`` holds; ``max_order`` means "at least ``max_order``". 0 when
        the weights do not sum to 1.
    """
    key = _order_key(A, b, A_v, b_v, max_order, tol, uncertainty, trees)
    found = _ORDERS.get(key) if key is not None else None
    if found is not None:
        return found
    J = _Judge(A, b, A_v, b_v, uncertainty, tol, trees)
    if max_order is None:
        max_order = MAX_ORDER_PARTITIONED if J.partitioned else MAX_ORDER
    p_found = _order(J, max_order)
    if key is not None:
        if len(_ORDERS) >= _ORDERS_MAX:
            _ORDERS.clear()
        _ORDERS[key] = p_found
    return p_found


#: :func:`order` by its exact arguments, so that one tableau's order is worked
#: out once per process (a scene loaded again, each point of a sweep, a
#: written tableau equal to a shipped one), however many objects carry it.
_ORDERS: dict = {}
_ORDERS_MAX = 512


def _order(J, max_order: int) -> int:
    for p in range(1, max_order + 1):
        for t in J.trees(p):
            residual = J.residual(t)
            if residual == 0:
                continue
            if abs(residual) <= J.allowed(t):
                continue
            return p - 1
    return max_order


def _order_key(A, b, A_v, b_v, max_order, tol, uncertainty, trees):
    """The exact arguments of :func:`order` as a hashable key; None when they
    do not convert (the call then computes and raises as it would)."""
    try:
        unc = None if uncertainty is None else tuple(_exact(u) if u is not None else None for u in uncertainty)
        key = (_exact(A), _exact(b), _exact(A_v), _exact(b_v), max_order, Fraction(tol), unc, trees)
        hash(key)
        return key
    except (TypeError, ValueError, ZeroDivisionError, OverflowError):
        return None


def residuals(A: Sequence, b: Sequence, A_v: Sequence | None = None, b_v: Sequence | None = None, *,
              max_order: int | None = None, tol=0, uncertainty=None, trees=None) -> list[dict]:
    """The order conditions' residuals, order by order.

    Parameters are those of :func:`order`. Returns one dict per order ``p =
    1 .. max_order`` (default: the method's order plus one, at most the
    highest order checked): ``order`` (p), ``conditions`` (how many trees),
    ``max_residual`` (the largest ``|w^T Phi(t) - 1/gamma(t)|`` over them,
    float), ``tolerance`` (the residual the coefficients' precision allows for
    that same condition, float; 0 for exact coefficients), ``worst_ratio``
    (the largest residual / allowed over the conditions; inf where an exact
    condition fails, 0 when all residuals are 0) and ``holds`` (every
    condition of order ``p`` holds).
    """
    J = _Judge(A, b, A_v, b_v, uncertainty, tol, trees)
    top = MAX_ORDER_PARTITIONED if J.partitioned else MAX_ORDER
    if max_order is None:
        max_order = min(order(A, b, A_v, b_v, tol=tol, uncertainty=uncertainty, trees=trees) + 1, top)
    out = []
    for p in range(1, min(max_order, top) + 1):
        worst, worst_allowed, ratio, holds, n = Fraction(0), Fraction(0), 0.0, True, 0
        for t in J.trees(p):
            n += 1
            r = abs(J.residual(t))
            if r == 0:
                continue
            allowed = J.allowed(t)
            holds = holds and r <= allowed
            ratio = max(ratio, float(r / allowed) if allowed else float("inf"))
            if r > worst:
                worst, worst_allowed = r, allowed
        out.append({"order": p, "conditions": n, "max_residual": float(worst), "tolerance": float(worst_allowed),
                    "worst_ratio": ratio, "holds": holds})
    return out


def _absm(M):
    return tuple(tuple(abs(x) for x in row) for row in M)


def _absv(v):
    return tuple(abs(x) for x in v)


# -- error coefficients -------------------------------------------------------------------------------
def symmetry(tree) -> int:
    """``sigma(t)``, the order of the tree's automorphism group: the product,
    over the distinct subtrees ``u`` of the root occurring ``m`` times, of
    ``sigma(u)^m m!`` (Butcher 2008, sec. 301; colours must match for a
    bi-coloured tree)."""
    children = tree[1] if _coloured(tree) else tree
    out = 1
    for u in set(children):
        m = children.count(u)
        out *= symmetry(u) ** m * _factorial(m)
    return out


def _factorial(m: int) -> int:
    out = 1
    for k in range(2, m + 1):
        out *= k
    return out


def error_coefficients(A, b, A_v=None, b_v=None, p: int = 1, *, trees=None) -> list[Fraction]:
    """The truncation-error coefficients of order ``p``: ``(w^T Phi(t) -
    1/gamma(t)) / sigma(t)`` for every tree ``t`` with ``p`` vertices (plain,
    bi-coloured, or ``trees(p)``), as nodepy's ``error_coeffs`` (Butcher
    2008, sec. 318: the local error is ``h^p sum_t (coefficient) F(t)(y) +
    O(h^{p+1})`` with the elementary differentials ``F(t)``)."""
    J = _Judge(A, b, A_v, b_v, None, 0, trees)
    return [J.residual(t) / symmetry(t) for t in J.trees(p)]


def principal_error_norm(A, b, A_v=None, b_v=None, p: int | None = None, *, trees=None) -> float:
    """The principal error coefficient of a method of order ``p``: the 2-norm
    of its error coefficients of order ``p + 1`` (:func:`error_coefficients`),
    as nodepy's ``principal_error_norm`` (classical RK4: 0.014504). ``p``
    defaults to :func:`order`. Dimensionless; nan above the orders checked
    (``p + 1`` > :data:`MAX_ORDER` + 1, or > :data:`MAX_ORDER_PARTITIONED`
    for a partitioned method over all bi-coloured trees)."""
    if p is None:
        p = order(A, b, A_v, b_v, trees=trees)
    partitioned = A_v is not None
    top = MAX_ORDER + 1 if not partitioned or trees is not None else MAX_ORDER_PARTITIONED
    if p + 1 > top:
        return float("nan")
    return float(sum(float(c) ** 2 for c in error_coefficients(A, b, A_v, b_v, p + 1, trees=trees))) ** 0.5
