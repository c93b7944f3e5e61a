"""A 1-D chain of masses joined by springs, with or without walls at the ends.

Covers the thesis' 2-DOF case studies (sec. 2.1, Tables 4.1-4.3), the N-mass
chain (sec. 2.2, Code 02), three blocks on four springs and CO2 (sec. 1.1.1).

Coordinates ``x_i`` (m) are displacements from equilibrium, positive to the
right. Springs are listed left to right: with ``walls="both"`` there are N+1
(wall-m1, m1-m2, ..., mN-wall); ``"left"`` and ``"right"`` have N; ``"none"``
has N-1. Equation of motion (thesis eq. 2.42, sign corrected, erratum 6):
``m_n x_n'' = k_n (x_{n-1} - x_n) + k_{n+1} (x_{n+1} - x_n)``.
"""
from __future__ import annotations

import numpy as np

from ..validate import choice, float_list
from .base import Model, check_masses, check_normal_positive

WALLS = ("both", "left", "right", "none")


class Chain(Model):
    """Masses ``masses`` (kg) and springs ``springs`` (N/m) in a line.

    Parameters
    ----------
    masses : list of float, length N >= 1
        Each a finite float >= ``MASS_MIN`` (1e-300 kg), largest/smallest finite.
    springs : list of float
        N+1, N, N or N-1 entries for walls "both", "left", "right", "none";
        each >= 1e-300 N/m, and ``sqrt(k/m)`` must stay finite.
    walls : {"both", "left", "right", "none"}
    """

    name = "chain"
    linear = True

    def __init__(self, masses, springs, walls="both"):
        self.walls = choice("walls", walls, WALLS)
        self.mass = check_masses("masses", float_list("masses", masses, positive_items=True))
        N = self.mass.shape[0]
        n_springs = N + {"both": 1, "left": 0, "right": 0, "none": -1}[walls]
        if n_springs < 1:
            raise ValueError(f"`masses` must have at least 2 entries when walls = 'none', got {N}")
        self.k = float_list("springs", springs, length=n_springs, positive_items=True)
        for i, k in enumerate(self.k):
            check_normal_positive(f"springs[{i}]", k)
        self.n_dof = N
        self.coord_names = [f"x{i + 1}" for i in range(N)]
        self._left = walls in ("both", "left")
        self._right = walls in ("both", "right")
        self._check_scales("springs")

    def params(self):
        return {"masses": self.mass.tolist(), "springs": self.k.tolist(), "walls": self.walls}

    def _padded(self, x):
        """Displacements with the walls (fixed at 0) attached at the ends."""
        parts = [x]
        zero = np.zeros_like(x[:1]) if x.dtype != object else np.array([0.0], dtype=object)
        if self._left:
            parts.insert(0, zero)
        if self._right:
            parts.append(zero)
        return np.concatenate(parts, axis=0)

    def _tension(self, x):
        """Spring tensions k_j * extension_j (N), left to right."""
        u = self._padded(x)
        k = self.k if x.ndim == 1 else self.k[:, None]
        return k * np.diff(u, axis=0)

    def _force(self, x, ops):
        T = self._tension(x)
        zero = np.zeros_like(T[:1]) if T.dtype != object else np.array([0.0], dtype=object)
        if not self._left:
            T = np.concatenate([zero, T], axis=0)
        if not self._right:
            T = np.concatenate([T, zero], axis=0)
        return T[1:] - T[:-1]

    def _potential(self, x, ops):
        u = self._padded(x)
        k = self.k if x.ndim == 1 else self.k[:, None]
        d = np.diff(u, axis=0)
        return 0.5 * np.sum(k * d * d, axis=0)

    def stiffness_matrix(self, sparse: bool = False):
        """Tridiagonal K (N/m); ``sparse=True`` gives a scipy.sparse matrix (O(N) memory)."""
        import scipy.sparse as sp

        N = self.n_dof
        kpad = np.concatenate([[] if self._left else [0.0], self.k, [] if self._right else [0.0]])
        diag = kpad[:N] + kpad[1:]  # left spring + right spring of each mass
        off = -kpad[1:N]
        K = sp.diags([off, diag, off], [-1, 0, 1], format="csr")
        return K if sparse else K.toarray()
