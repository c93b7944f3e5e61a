"""Any arrangement of point masses, fixed anchors and springs, in 1D or the plane.

A network has ``n`` masses at reference positions ``X`` (m), fixed anchors
``A`` and springs between nodes (indices ``0..n-1`` are the masses, ``n..``
the anchors). Its coordinates are the displacements ``u`` of the masses from
their reference positions, flat: ``x1, y1, x2, y2, ...`` (``dim = 2``) or
``x1, x2, ...`` (``dim = 1``); the generalized mass of each coordinate is the
mass of its node.

Exact geometry: spring ``s`` between nodes ``a`` and ``b`` has length
``L_s = |P_b - P_a|`` (``P = X + u`` for a mass, ``A`` for an anchor) and
extension ``r_s = L_s - rest_s``; ``rest`` defaults to the distance at the
reference positions. Its energy is one template in the extension,

    E(r) = k r^2 / 2 + alpha r^3 / 3 + beta r^4 / 4      (J; alpha = beta = 0 here)

written once as an expression (:mod:`rk4h.expr`); its derivatives, the
tension ``E'(r)`` (N) and the stiffness ``E''(r)`` (N/m), are derived from it
symbolically, never written by hand. The force on ``a`` is ``E'(r) (P_b -
P_a) / L`` and on ``b`` its opposite; the Hessian at the reference state is
``E''(r0) e e^T + E'(r0) / L0 (I - e e^T)`` per spring (``e`` the unit vector
from ``a`` to ``b``; the second term vanishes unless the spring is
pre-stressed). Memory and cost per evaluation are O(number of springs).

``planar4``, ``triangle`` and a chain with walls are special cases; the tests
check that they agree to round-off.
"""
from __future__ import annotations

import math

import numpy as np

from .. import expr as ex
from .base import NUMPY, Drawing, Model, check_masses
from .compiled import SpringKernel
from .params import Param
from .spring_template import NAMES, SPRING_ENERGY, TENSION

__all__ = ["Network", "SPRING_ENERGY", "spring_energy", "spring_tension", "spring_energy_heyoka",
           "spring_tension_heyoka"]

_NAMES = NAMES
_TENSION = TENSION
_STIFFNESS = ex.diff(_TENSION, "r")
_np_energy, _np_tension, _np_stiffness = (ex.lambdify(e, _NAMES) for e in (SPRING_ENERGY, _TENSION, _STIFFNESS))
#: The tension with ``alpha = beta = 0`` substituted (it is ``k r``): the
#: harmonic springs' numpy path, printed from the same template as the
#: compiled kernels' (:mod:`rk4h.models.compiled`).
_TENSION_HARMONIC = ex.substitute(_TENSION, {"alpha": 0.0, "beta": 0.0})
_np_tension_harmonic = ex.lambdify(_TENSION_HARMONIC, ("r", "k"), broadcast=False)


def spring_energy(r, k, alpha=0.0, beta=0.0):
    """``E(r)`` (J) of springs with extension ``r`` (m), stiffness ``k`` (N/m)
    and the anharmonic coefficients ``alpha`` (N/m^2), ``beta`` (N/m^3)."""
    return _np_energy(r, k, alpha, beta)


def spring_tension(r, k, alpha=0.0, beta=0.0):
    """``E'(r)`` (N): the tension of springs with extension ``r`` (m)."""
    return _np_tension(r, k, alpha, beta)


def _substituted(e, k, alpha, beta):
    return ex.substitute(e, {"k": ex.Num(float(k)), "alpha": ex.Num(float(alpha)), "beta": ex.Num(float(beta))})


def spring_energy_heyoka(r, k, alpha=0.0, beta=0.0):
    """``E(r)`` as a heyoka expression of the heyoka expression ``r``."""
    return ex.to_heyoka(_substituted(SPRING_ENERGY, k, alpha, beta), {"r": r})


def spring_tension_heyoka(r, k, alpha=0.0, beta=0.0):
    """``E'(r)`` as a heyoka expression of the heyoka expression ``r``."""
    return ex.to_heyoka(_substituted(_TENSION, k, alpha, beta), {"r": r})


def _flat(name, value, multiple) -> np.ndarray:
    if isinstance(value, (str, bytes)) or not hasattr(value, "__len__"):
        raise ValueError(f"`{name}` must be a flat list of numbers, got {value!r}")
    items = list(value)
    for i, v in enumerate(items):
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(float(v)):
            raise ValueError(f"`{name}[{i}]` must be a finite number, got {v!r}")
    if len(items) % multiple:
        raise ValueError(f"`{name}` must hold {multiple} numbers per point, got {len(items)}")
    return np.asarray(items, dtype=float).reshape(-1, multiple)


class Network(Model):
    """Masses, anchors and springs with exact geometry (see the module docstring).

    Parameters
    ----------
    dim : {1, 2}
    masses : list of float
        One mass (kg) per node; ``n`` entries.
    positions : list of float
        Reference positions of the masses, flat (``dim * n`` numbers, m).
    springs : list of [a, b, k] or [a, b, k, rest]
        Node indices (``0..n-1`` masses, ``n..`` anchors), stiffness (N/m) and
        natural length (m; default: the distance at the reference positions).
    anchors : list of float, optional
        Fixed points, flat (m).
    """

    name = "network"
    linear = False
    summary = "Masses, anchors and springs with exact geometry, on a line or in the plane."
    parameters = (
        Param("dim", "int", "-", "dimension of the positions: 1 (a line) or 2 (the plane)", 2, ge=1, le=2),
        Param("masses", "list[normal]", "kg", "one mass per node; the masses are nodes 0 .. n-1", [0.5, 0.8],
              min_length=1),
        Param("positions", "list[finite]", "m", "reference positions of the masses, flat: dim numbers per mass",
              [-0.2, 0.0, 0.2, 0.0]),
        Param("springs", "list[list[float]]", "N/m, m", "springs as [a, b, k] or [a, b, k, rest]: nodes a and b "
              "(masses, then anchors), stiffness k (N/m), natural length rest (m; default: the reference "
              "distance)", [[0, 1, 50.0]], min_length=1, item_length=(3, 4)),
        Param("anchors", "list[finite]", "m", "fixed points, flat (dim numbers each): nodes n, n+1, ...",
              [-0.6, 0.0], default=[]),
    )

    def __init__(self, dim, masses, positions, springs, anchors=()):
        if isinstance(dim, bool) or dim not in (1, 2):
            raise ValueError(f"`dim` must be 1 or 2, got {dim!r}")
        self.dim = int(dim)
        if isinstance(masses, (str, bytes)) or not hasattr(masses, "__len__") or not len(masses):
            raise ValueError(f"`masses` must be a non-empty list of numbers, got {masses!r}")
        self.node_mass = check_masses("masses", list(masses))
        n = self.node_mass.shape[0]
        self.X = _flat("positions", positions, self.dim)
        if self.X.shape[0] != n:
            raise ValueError(f"`positions` must hold {self.dim * n} numbers ({n} masses x dim {self.dim}), "
                             f"got {self.X.size}")
        self.A = _flat("anchors", anchors, self.dim) if len(anchors) else np.zeros((0, self.dim))
        nodes = n + self.A.shape[0]
        ref = np.concatenate([self.X, self.A])
        if isinstance(springs, (str, bytes)) or not hasattr(springs, "__len__") or not len(springs):
            raise ValueError(f"`springs` must be a non-empty list of [a, b, k] or [a, b, k, rest], got {springs!r}")
        a, b, k, rest = [], [], [], []
        seen = set()
        for i, s in enumerate(springs):
            if isinstance(s, (str, bytes)) or not hasattr(s, "__len__") or len(s) not in (3, 4):
                raise ValueError(f"`springs[{i}]` must be [a, b, k] or [a, b, k, rest], got {s!r}")
            for j, node in enumerate(s[:2]):
                if isinstance(node, bool) or not isinstance(node, int) or not 0 <= node < nodes:
                    raise ValueError(f"`springs[{i}][{j}]` must be a node index in 0..{nodes - 1} "
                                     f"({n} masses, then {nodes - n} anchors), got {node!r}")
            if s[0] == s[1]:
                raise ValueError(f"`springs[{i}]` joins node {s[0]} to itself")
            if s[0] >= n and s[1] >= n:
                raise ValueError(f"`springs[{i}]` joins two anchors ({s[0]}, {s[1]}): it would do nothing")
            key = (min(s[0], s[1]), max(s[0], s[1]))
            if key in seen:
                raise ValueError(f"`springs[{i}]` joins nodes {key} a second time")
            seen.add(key)
            kk = s[2]
            if isinstance(kk, bool) or not isinstance(kk, (int, float)) or not (math.isfinite(kk) and kk > 0):
                raise ValueError(f"`springs[{i}][2]` (k) must be a finite number > 0, got {kk!r}")
            length = float(np.linalg.norm(ref[s[1]] - ref[s[0]]))
            if length == 0.0:
                raise ValueError(f"`springs[{i}]` joins nodes {s[0]} and {s[1]}, which coincide at the reference "
                                 f"positions: its direction is undefined")
            r0 = length
            if len(s) == 4:
                rr = s[3]
                if isinstance(rr, bool) or not isinstance(rr, (int, float)) or not (math.isfinite(rr) and rr >= 0):
                    raise ValueError(f"`springs[{i}][3]` (rest) must be a finite number >= 0, got {rr!r}")
                r0 = float(rr)
            a.append(s[0])
            b.append(s[1])
            k.append(float(kk))
            rest.append(r0)
        self.a, self.b = np.asarray(a, dtype=np.int64), np.asarray(b, dtype=np.int64)
        self.k, self.rest = np.asarray(k), np.asarray(rest)
        self.alpha = np.zeros_like(self.k)
        self.beta = np.zeros_like(self.k)
        self.n_nodes, self.n_masses = nodes, n
        self.n_dof = n * self.dim
        self.mass = np.repeat(self.node_mass, self.dim)
        axes = "xy"[: self.dim]
        self.coord_names = [f"{c}{i + 1}" for i in range(n) for c in axes]
        self._springs_input = [list(s) for s in springs]
        self._harmonic = not (np.any(self.alpha) or np.any(self.beta))
        self._check_scales("springs")

    def params(self):
        return {"dim": self.dim, "masses": self.node_mass.tolist(), "positions": self.X.ravel().tolist(),
                "springs": [list(s) for s in self._springs_input], "anchors": self.A.ravel().tolist()}

    # -- geometry --------------------------------------------------------------------------
    def _points(self, q):
        """Node positions, shape (nodes, dim) or (nodes, dim, m); object arrays for heyoka."""
        extra = q.shape[1:]
        u = q.reshape((self.n_masses, self.dim) + extra)
        X = self.X.reshape(self.X.shape + (1,) * len(extra))
        A = np.broadcast_to(self.A.reshape(self.A.shape + (1,) * len(extra)), self.A.shape + extra)
        if q.dtype == object:
            A = A.astype(object)
        return np.concatenate([X + u, A], axis=0)

    def _bonds(self, q, ops):
        P = self._points(q)
        d = P[self.b] - P[self.a]                       # (springs, dim, ...)
        L2 = d[:, 0] * d[:, 0]
        for c in range(1, self.dim):
            L2 = L2 + d[:, c] * d[:, c]
        L = ops.sqrt(L2)
        return d, L

    def _coefficients(self, extra_dims):
        shape = (-1,) + (1,) * extra_dims
        return (self.k.reshape(shape), self.alpha.reshape(shape), self.beta.reshape(shape),
                self.rest.reshape(shape))

    def _potential(self, q, ops):
        d, L = self._bonds(q, ops)
        if q.dtype == object:
            return sum(self._heyoka(SPRING_ENERGY, i, L[i] - self.rest[i]) for i in range(self.k.size))
        k, alpha, beta, rest = self._coefficients(q.ndim - 1)
        return np.sum(_np_energy(L - rest, k, alpha, beta), axis=0)

    def _heyoka(self, e, i, r):
        return ex.to_heyoka(_substituted(e, self.k[i], self.alpha[i], self.beta[i]), {"r": r})

    def _force(self, q, ops):
        d, L = self._bonds(q, ops)
        if q.dtype == object:
            t_over_L = np.array([self._heyoka(_TENSION, i, L[i] - self.rest[i]) / L[i]
                                 for i in range(self.k.size)], dtype=object)
        else:
            k, alpha, beta, rest = self._coefficients(q.ndim - 1)
            if self._harmonic:
                t_over_L = _np_tension_harmonic(L - rest, k) / L
            else:
                t_over_L = _np_tension(L - rest, k, alpha, beta) / L
        F = t_over_L[:, None] * d                       # force on a (pulls a towards b when stretched)
        f = np.zeros((self.n_nodes,) + F.shape[1:], dtype=F.dtype)
        if q.dtype == object:
            f[...] = 0.0
            for i in range(self.k.size):
                f[self.a[i]] = f[self.a[i]] + F[i]
                f[self.b[i]] = f[self.b[i]] - F[i]
        else:
            np.add.at(f, self.a, F)
            np.add.at(f, self.b, -F)
        return f[: self.n_masses].reshape(q.shape)

    def force_kernel(self):
        return SpringKernel(self.dim, self.X, self.A, self.a, self.b, self.k, self.alpha, self.beta, self.rest)

    def drawing(self):
        if self.dim == 1:
            return Drawing(layout="line", point_labels=tuple(self.coord_names))
        return Drawing(layout="plane", points=tuple((2 * i, 2 * i + 1) for i in range(self.n_masses)),
                       reference=tuple(map(tuple, self.X.tolist())), anchors=tuple(map(tuple, self.A.tolist())),
                       springs=tuple((int(a), int(b), f"{a}-{b}") for a, b in zip(self.a, self.b)),
                       rest=tuple(self.rest.tolist()), point_labels=tuple(f"mass {i + 1}" for i in range(self.n_masses)))

    def stiffness_matrix(self, sparse: bool = False):
        """Hessian of ``V`` at the reference state ``u = 0`` (N/m); ``sparse=True``
        gives a scipy.sparse matrix (O(springs) memory)."""
        import scipy.sparse as sp

        d, L = self._bonds(np.zeros(self.n_dof), NUMPY)
        e = d / L[:, None]
        r0 = L - self.rest
        kk = _np_stiffness(r0, self.k, self.alpha, self.beta) * np.ones_like(L)
        t = _np_tension(r0, self.k, self.alpha, self.beta) * np.ones_like(L)
        eye = np.eye(self.dim)
        blocks = kk[:, None, None] * e[:, :, None] * e[:, None, :] + \
            (t / L)[:, None, None] * (eye - e[:, :, None] * e[:, None, :])
        D, n = self.dim, self.n_masses
        rows, cols, vals = [], [], []
        c1, c2 = np.meshgrid(np.arange(D), np.arange(D), indexing="ij")
        for p, q_, sgn in ((self.a, self.a, 1.0), (self.b, self.b, 1.0), (self.a, self.b, -1.0), (self.b, self.a, -1.0)):
            keep = (p < n) & (q_ < n)  # anchors have no coordinates
            rows.append((p[keep, None, None] * D + c1).ravel())
            cols.append((q_[keep, None, None] * D + c2).ravel())
            vals.append((sgn * blocks[keep]).ravel())
        rows, cols, vals = np.concatenate(rows), np.concatenate(cols), np.concatenate(vals)
        K = sp.coo_matrix((vals, (rows, cols)), shape=(self.n_dof, self.n_dof)).tocsr()
        K = ((K + K.T) * 0.5).tocsr()  # the sums of duplicates round alike: exactly symmetric
        return K if sparse else K.toarray()


