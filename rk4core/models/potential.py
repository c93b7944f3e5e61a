"""A model given by its potential: coordinates, masses and V(q) as text.

Scene key ``potential`` (``[params]``):

* ``coordinates`` -- list of distinct names (at most :data:`MAX_COORDINATES`),
  the generalized coordinates ``q`` in this order (the state is ``[q, v]``);
* ``masses`` -- one positive number per coordinate, or one number for all
  (kg for lengths, kg m^2 for angles);
* ``potential`` -- the text of ``V(q)`` (J) in the grammar of
  :mod:`rk4h.expr` (numbers, names, ``+ - * / ** ^``, parentheses, ``sin
  cos tan sinh cosh tanh exp log sqrt``), parsed by the harness's own parser,
  never by ``eval``;
* ``constants`` -- optional table of named numbers used in the text
  (substituted as their double values).

The text's cost is bounded before it is paid: besides the parser's length and
nesting limits, a product of more than :data:`rk4h.expr.MAX_FACTORS`
factors is refused while parsing, and the gradient and Hessian together may
take at most :data:`rk4h.expr.MAX_DERIVATIVE_WORK` units of work (a
:class:`rk4h.expr.Budget`); either refusal is a ``ValueError`` naming
``potential`` and the limit, in seconds.

Everything else is derived from the one parsed expression, never written by
hand: the force ``F = -grad V`` by symbolic differentiation
(:func:`rk4h.expr.diff`); the numpy right-hand side from the
:func:`rk4h.expr.lambdify`-compiled force (vectorised over states); heyoka's
equations from :func:`rk4h.expr.to_heyoka` of the same force expressions;
the stiffness matrix from the symbolic Hessian.

Reference state: ``q = 0``. :meth:`PotentialModel.stiffness_matrix` is the
Hessian of V there (so V must be twice differentiable and finite at q = 0;
write coordinates as displacements from the configuration you linearise
about). ``linear`` is true when V is a quadratic form -- every second
derivative is a constant, the force vanishes at q = 0 and the Hessian is
positive semidefinite -- so ``F = -K q`` exactly and the exact modal
reference applies. A quadratic V with linear terms or an indefinite Hessian
(an inverted oscillator) is integrated as nonlinear: the modal reference
assumes oscillating or uniformly moving modes.

Example (Henon-Heiles)::

    PotentialModel(coordinates=["x", "y"], masses=1.0,
                   potential="(x^2 + y^2)/2 + lam*(x^2*y - y^3/3)",
                   constants={"lam": 1.0})
"""
from __future__ import annotations

import math
from collections.abc import Mapping
from functools import partial

import numpy as np

from .. import expr as ex
from ..validate import float_list, positive, short
from .base import Model, check_masses
from .compiled import ExprKernel
from .params import Param

__all__ = ["PotentialModel", "MAX_COORDINATES"]

#: Most coordinates a potential model may have (its Hessian is n^2 symbolic
#: second derivatives; larger systems belong to per-element models).
MAX_COORDINATES = 100


_short = partial(short, limit=60)


def check_names(field: str, names, limit: int, *, reserved=None) -> list:
    """``names`` as a list of 1 to ``limit`` distinct expression names
    (:func:`rk4core.expr.check_name`); ``reserved`` maps a name the list may
    not hold to the message refusing it. Raises ValueError naming ``field``."""
    if isinstance(names, (str, bytes)) or not isinstance(names, (list, tuple)):
        raise ValueError(f"`{field}` must be a list of names, got {_short(names)}")
    if not 1 <= len(names) <= limit:
        raise ValueError(f"`{field}` must have 1 to {limit} names, got {len(names)}")
    seen = set()
    for i, c in enumerate(names):
        problem = ex.check_name(c)
        if problem:
            raise ValueError(f"`{field}[{i}]` must be a name: {problem}")
        if reserved and c in reserved:
            raise ValueError(reserved[c])
        if c in seen:
            raise ValueError(f"`{field}` must be distinct names, got {c!r} twice")
        seen.add(c)
    return list(names)


def check_constants(constants, taken: set, clash: str) -> dict:
    """``constants`` (None or a mapping of names to finite numbers) as a dict
    of floats; a key in ``taken`` is refused with ``clash.format(k=key)``."""
    if constants is None:
        return {}
    if not isinstance(constants, Mapping):
        raise ValueError(f"`constants` must be a table of names to numbers, got {_short(constants)}")
    out = {}
    for k, v in constants.items():
        problem = ex.check_name(k)
        if problem:
            raise ValueError(f"`constants` must have names as keys: {problem}")
        if k in taken:
            raise ValueError(clash.format(k=k))
        if isinstance(v, bool) or not isinstance(v, (int, float, np.floating, np.integer)) \
                or not math.isfinite(float(v)):
            raise ValueError(f"`constants.{k}` must be a finite number, got {_short(v)}")
        out[k] = float(v)
    return out


class PotentialModel(Model):
    """A model defined by the text of its potential (see the module docstring).

    Parameters
    ----------
    coordinates : list of str
        Distinct names of the generalized coordinates.
    masses : float or list of float
        Generalized masses, each >= ``MASS_MIN`` (1e-300) with a finite
        largest/smallest ratio; one number is used for every coordinate.
    potential : str
        ``V(q)`` in the coordinates and ``constants`` (J).
    constants : mapping of str to float, optional
        Named finite numbers (not coordinate names).

    Attributes
    ----------
    V : rk4h.expr.Expr
        The parsed potential.
    force_exprs : list of rk4h.expr.Expr
        ``-dV/dq_i``, derived symbolically.
    hessian_exprs : list of list of rk4h.expr.Expr
        ``d2V/dq_i dq_j``.
    digest : str
        SHA-256 of the canonical text of V (a cache key for derived code).
    """

    name = "potential"
    summary = "Any potential typed as text: V(q) over named coordinates (parsed by rk4h.expr, never eval'd)."
    parameters = (
        Param("coordinates", "list[str]", "-", "names of the generalized coordinates, as used in `potential`",
              ["x", "y"], min_length=1, max_length=MAX_COORDINATES),
        Param("masses", "normal|list", "kg", "mass of each coordinate (kg m^2 for an angle); one number for all",
              1.0),
        Param("potential", "str", "J", "the potential energy V of the coordinates and `constants`: numbers, names, "
              "+ - * / ^, sin cos tan sinh cosh tanh exp log sqrt", "(x^2 + y^2)/2 + x^2*y - y^3/3"),
        Param("constants", "dict[str,finite]", "-", "named numbers used in `potential`", {"lam": 1.0},
              default=None),
    )

    def __init__(self, coordinates, masses, potential, constants=None):
        self.coordinates = check_names("coordinates", coordinates, MAX_COORDINATES)
        n = len(self.coordinates)
        if isinstance(masses, (str, bytes)) or not hasattr(masses, "__len__"):
            self.mass = check_masses("masses", np.full(n, positive("masses", masses)))
        else:
            self.mass = check_masses("masses", float_list("masses", masses, length=n, positive_items=True))
        self.constants = check_constants(constants, set(self.coordinates),
                                         "`constants.{k}`: `{k}` is both a coordinate and a constant")
        if not isinstance(potential, str):
            raise ValueError(f"`potential` must be a string (the expression of V), got {_short(potential)}")
        self.potential_text = potential
        try:
            self.V = ex.parse(potential, self.coordinates, self.constants)
        except ex.ExprError as e:
            raise ValueError(f"`potential`: {e}") from None
        self.n_dof = n
        self.coord_names = list(self.coordinates)
        self.digest = ex.digest(self.V)

        names = self.coordinates
        try:
            # one budget for every derivative, so a V whose derivatives would take
            # minutes is refused in about a second (rk4h.expr.MAX_DERIVATIVE_WORK)
            budget = ex.Budget()
            self.force_exprs = [ex.neg(g) for g in ex.gradient(self.V, names, budget=budget)]
            self.hessian_exprs = ex.hessian(self.V, names, budget=budget)
            # Broadcasting versions (any shapes) and unchecked ones for one
            # state (q of shape (n,), whose entries are numpy scalars).
            self._V_fn = ex.lambdify(self.V, names)
            self._F_fn = ex.lambdify(self.force_exprs, names)
            self._V_one = ex.lambdify(self.V, names, broadcast=False)
            self._F_one = ex.lambdify(self.force_exprs, names, broadcast=False)
            self._H_fn = ex.lambdify([h for row in self.hessian_exprs for h in row], names)
        except ex.ExprError as e:  # e.g. a derivative nested past the tree cap
            raise ValueError(f"`potential`: {e}") from None

        zero = [0.0] * n
        with np.errstate(all="ignore"):
            K = np.array(self._H_fn(*zero), dtype=float).reshape(n, n)
            F0 = np.array(self._F_fn(*zero), dtype=float).reshape(n)
        if not np.all(np.isfinite(K)):
            i, j = np.argwhere(~np.isfinite(K))[0]
            raise ValueError(f"`potential`: its Hessian at the reference state q = 0 is not finite "
                             f"(d2V/d{names[i]} d{names[j]} = {K[i, j]}); write the coordinates as "
                             f"displacements from a regular point")
        self._K = K
        with np.errstate(all="ignore"):  # the tolerance rule's frequency bound must stay finite
            w2 = float(np.max(np.abs(K).sum(axis=1) / self.mass))
        if not (math.isfinite(w2) and math.isfinite(math.sqrt(w2))):
            raise ValueError(f"`potential` must give, with the masses, a finite fastest frequency at q = 0 "
                             f"(Gershgorin bound sqrt(max_i sum_j |K_ij| / m_i)), got omega^2 = {w2!r}")
        constant_hessian = all(not ex.free_symbols(h) for row in self.hessian_exprs for h in row)
        self.linear = bool(constant_hessian and np.all(F0 == 0.0) and self._semidefinite(K))

    # -- validation -----------------------------------------------------------
    @staticmethod
    def _semidefinite(K) -> bool:
        if K.size == 0 or not np.any(K):
            return True
        lam = np.linalg.eigvalsh(0.5 * (K + K.T))
        return bool(lam.min() >= -1e-12 * np.abs(lam).max())

    # -- the Model interface ----------------------------------------------------
    def params(self):
        return {"coordinates": list(self.coordinates), "masses": self.mass.tolist(),
                "potential": self.potential_text, "constants": dict(self.constants)}

    def _symbols(self, q):
        return {c: q[i] for i, c in enumerate(self.coordinates)}

    def _potential(self, q, ops):
        if q.dtype == object:  # heyoka expressions
            return ex.to_heyoka(self.V, self._symbols(q))
        if q.ndim == 1:
            return np.float64(self._V_one(*q))
        return self._V_fn(*q)

    def _force(self, q, ops):
        if q.dtype == object:
            return np.array(ex.to_heyoka(self.force_exprs, self._symbols(q)), dtype=object)
        if q.ndim == 1:
            return np.array(self._F_one(*q), dtype=float)
        return np.stack(self._F_fn(*q))

    def force_kernel(self):
        return ExprKernel(self.force_exprs, self.coordinates)

    def potential_above_rest(self, q) -> np.ndarray | float:
        """``V(q) - V(0)`` (J), ``q`` of shape (n_dof,) or (n_dof, m): ``V(0)`` is
        subtracted from the expression before evaluation, so a constant in ``V``
        cancels exactly (the energy of the motion, :mod:`rk4h.energy`)."""
        fn = self.__dict__.get("_V_above_fn")
        if fn is None:
            V0 = ex.substitute(self.V, {c: ex.Num(0.0) for c in self.coordinates})
            fn = self._V_above_fn = ex.lambdify(ex.add(self.V, ex.neg(V0)), self.coordinates)
        q = np.asarray(q, dtype=float)
        out = fn(*q)
        return np.float64(out) if q.ndim == 1 else np.asarray(out, dtype=float)

    def stiffness_matrix(self) -> np.ndarray:
        """Hessian of V at the reference state ``q = 0`` (N/m, or N m/rad),
        from the symbolic second derivatives (checked finite when built)."""
        return self._K.copy()

    def state_problem(self, y) -> str | None:
        """Why ``y`` -- a state ``[q, v]`` or coordinates ``q`` alone -- cannot
        be integrated from (V, the force or the energy not finite there), or
        None."""
        y = np.asarray(y, dtype=float)
        n = self.n_dof
        if y.ndim != 1 or y.shape[0] not in (n, 2 * n):
            return f"it has shape {y.shape}, not ({2 * n},) (y = [q, v]) or ({n},) (q)"
        if not np.all(np.isfinite(y)):
            return "it is not finite"
        q = y[:n]
        at = ", ".join(f"{c} = {v:.6g}" for c, v in zip(self.coordinates[:6], q))
        at += ", ..." if n > 6 else ""
        with np.errstate(all="ignore"):
            V = float(self._V_fn(*q))
            F = np.asarray(self._F_fn(*q), dtype=float)
            T = 0.5 * float(np.sum(self.mass * y[n:] ** 2)) if y.shape[0] == 2 * n else 0.0
        if not math.isfinite(V):
            return f"the potential is not finite there (V = {V!r} at {at})"
        bad = np.flatnonzero(~np.isfinite(F))
        if bad.size:
            i = int(bad[0])
            return f"the force is not finite there (-dV/d{self.coordinates[i]} = {float(F[i])!r} at {at})"
        if not math.isfinite(T + V):
            return f"its energy is not finite ({T + V!r} J; an overflow)"
        return None

    def check_state(self, y, name: str = "y0") -> np.ndarray:
        """``y`` as a float array when V, the force and the energy are finite
        there (:meth:`state_problem`); else ``ValueError`` naming ``name`` (one
        line). ``y`` is a state ``[q, v]`` or the coordinates ``q`` alone."""
        problem = self.state_problem(y)
        if problem is not None:
            shown = np.array2string(np.asarray(y, dtype=float).ravel(), precision=6, max_line_width=10**6,
                                    threshold=12, separator=", ")
            raise ValueError(f"`{name}` must be a state of {self.name} with finite force and energy: "
                             f"{problem}, got {shown}")
        return np.asarray(y, dtype=float)
