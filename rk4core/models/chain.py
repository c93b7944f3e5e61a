"""A 1-D chain of masses joined by springs, with or without walls at the ends.

Covers the thesis' 2-DOF case studies (sec. 2.1, Tables 4.1-4.3), the N-mass
chain (sec. 2.2, Code 02), three blocks on four springs and CO2 (sec. 1.1.1).

Coordinates ``x_i`` (m) are displacements from equilibrium, positive to the
right. Springs are listed left to right: with ``walls="both"`` there are N+1
(wall-m1, m1-m2, ..., mN-wall); ``"left"`` and ``"right"`` have N; ``"none"``
has N-1. Equation of motion (thesis eq. 2.42, sign corrected, erratum 6):
``m_n x_n'' = k_n (x_{n-1} - x_n) + k_{n+1} (x_{n+1} - x_n)``.

Fermi-Pasta-Ulam-Tsingou chains: with ``alpha`` (N/m^2) or ``beta`` (N/m^3)
non-zero every spring's energy is ``k r^2/2 + alpha r^3/3 + beta r^4/4`` in its
extension ``r`` -- the one spring-energy expression of
:mod:`rk4h.models.network`, whose derivative gives the tension -- and the
chain is nonlinear. With ``alpha = beta = 0`` it is the linear chain, bit for
bit. Long uniform chains need no spelled-out lists: ``masses = 0.815``,
``springs = 41.5``, ``n = 100``.

References
----------
E. Fermi, J. Pasta, S. Ulam, M. Tsingou, "Studies of nonlinear problems",
Los Alamos report LA-1940 (1955).
"""
from __future__ import annotations

import numpy as np

from ..validate import choice, finite, float_list
from .base import Drawing, Model, check_all_normal_positive, check_masses
from .compiled import ChainKernel
from .network import (_np_stiffness, _np_tension_harmonic, spring_energy, spring_energy_heyoka, spring_tension,
                      spring_tension_heyoka)
from .params import Param, ParamRule

WALLS = ("both", "left", "right", "none")


class Chain(Model):
    """Masses ``masses`` (kg) and springs ``springs`` (N/m) in a line.

    Parameters
    ----------
    masses : list of float, length N >= 1, or one number with ``n``
        Each a finite float >= ``MASS_MIN`` (1e-300 kg), largest/smallest finite.
    springs : list of float, or one number
        N+1, N, N or N-1 entries for walls "both", "left", "right", "none";
        each >= 1e-300 N/m, and ``sqrt(k/m)`` must stay finite.
    walls : {"both", "left", "right", "none"}
    alpha, beta : float, optional
        Cubic (N/m^2) and quartic (N/m^3) spring coefficients (FPUT); default 0.
    n : int, optional
        Number of masses when ``masses`` is one number (then required).
    """

    name = "chain"
    linear = True
    summary = "Masses in a line joined by springs (thesis sec. 2.1-2.2; FPUT chains with alpha, beta)."
    parameters = (
        Param("masses", "normal|list", "kg", "mass of each block, left to right; one number with `n` for n equal "
              "masses", [0.815, 3.099]),
        Param("springs", "normal|list", "N/m", "stiffness of each spring, left to right: N+1 with walls = both, N "
              "with one wall, N-1 with none; one number for all", [41.5, 138.0, 157.8]),
        Param("walls", "choice", "-", "which ends are tied to a wall", "both", default="both", choices=WALLS),
        Param("alpha", "finite", "N/m^2", "cubic term of each spring's energy k r^2/2 + alpha r^3/3 + beta r^4/4 "
              "(FPUT alpha)", 0.25, default=0.0),
        Param("beta", "finite", "N/m^3", "quartic term of each spring's energy (FPUT beta)", 1.0, default=0.0),
        Param("n", "int", "masses", "number of masses when `masses` is one number", 2, default=None, ge=1, le=10**7),
    )

    @classmethod
    def check_parameters(cls, values):
        """``n`` goes with one number for ``masses``; ``springs`` has as many
        entries as the walls and masses need."""
        masses, springs, walls, n = values["masses"], values["springs"], values["walls"], values["n"]
        many = isinstance(masses, list)
        if not many and n is None:
            raise ParamRule("n", "must be given when `masses` is one number")
        if many and n is not None and n != len(masses):
            raise ParamRule("n", f"disagrees with the {len(masses)} entries of `masses`", n)
        count = len(masses) if many else n
        n_springs = count + {"both": 1, "left": 0, "right": 0, "none": -1}[walls]
        if n_springs < 1:
            raise ParamRule("masses", "must have at least 2 entries when walls = 'none'", masses)
        if isinstance(springs, list) and len(springs) != n_springs:
            raise ParamRule("springs", f"must have {n_springs} entries for {count} masses and walls = {walls!r}",
                            springs)

    def __init__(self, masses, springs, walls="both", alpha=0.0, beta=0.0, n=None):
        self.walls = choice("walls", walls, WALLS)
        if n is not None and (isinstance(n, bool) or not isinstance(n, int) or not 1 <= n <= 10**7):
            raise ValueError(f"`n` must be an integer from 1 to 10^7, got {n!r}")
        if not hasattr(masses, "__len__") and not isinstance(masses, bool):
            if n is None:
                raise ValueError(f"`n` must be given when `masses` is one number, got masses = {masses!r}")
            masses = [masses] * n
        elif n is not None and hasattr(masses, "__len__") and len(masses) != n:
            raise ValueError(f"`n` = {n} disagrees with the {len(masses)} entries of `masses`")
        self.mass = check_masses("masses", float_list("masses", masses, positive_items=True))
        N = self.mass.shape[0]
        n_springs = N + {"both": 1, "left": 0, "right": 0, "none": -1}[walls]
        if n_springs < 1:
            raise ValueError(f"`masses` must have at least 2 entries when walls = 'none', got {N}")
        if not hasattr(springs, "__len__") and not isinstance(springs, bool):
            springs = [springs] * n_springs
        self.k = float_list("springs", springs, length=n_springs, positive_items=True)
        self.alpha, self.beta = finite("alpha", alpha), finite("beta", beta)
        self.linear = self.alpha == 0.0 and self.beta == 0.0
        check_all_normal_positive(self.k, lambda i: f"springs[{i}]")
        self.n_dof = N
        self.coord_names = [f"x{i + 1}" for i in range(N)]
        self._left = walls in ("both", "left")
        self._right = walls in ("both", "right")
        self._check_scales("springs")

    def params(self):
        p = {"masses": self.mass.tolist(), "springs": self.k.tolist(), "walls": self.walls}
        if not self.linear:
            p.update(alpha=self.alpha, beta=self.beta)
        return p

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
        """Spring tensions ``E'(r_j)`` (N) of the extensions ``r_j``, left to
        right: ``k_j r_j`` for the linear chain."""
        u = self._padded(x)
        k = self.k if x.ndim == 1 else self.k[:, None]
        d = np.diff(u, axis=0)
        if self.linear:
            return _np_tension_harmonic(d, k)
        if x.dtype == object:
            return np.array([spring_tension_heyoka(d[j], self.k[j], self.alpha, self.beta)
                             for j in range(d.shape[0])], dtype=object)
        return spring_tension(d, k, self.alpha, self.beta)

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
        if self.linear:
            return 0.5 * np.sum(k * d * d, axis=0)
        if x.dtype == object:
            return sum(spring_energy_heyoka(d[j], self.k[j], self.alpha, self.beta) for j in range(d.shape[0]))
        return np.sum(spring_energy(d, k, self.alpha, self.beta), axis=0)

    def force_kernel(self):
        return ChainKernel(self.k, self.alpha, self.beta, self._left, self._right, self.linear)

    def drawing(self):
        return Drawing(layout="line", point_labels=tuple(self.coord_names))

    def frequency_range(self) -> tuple[float, float]:
        """``(omega_min, omega_max)`` (rad/s) of the linearization from the
        tridiagonal eigenproblem (O(N) memory; two eigenvalues)."""
        import math

        from scipy.linalg import eigvalsh_tridiagonal

        off, diag = self._bands()
        m = np.asarray(self.mass, float)
        d = diag / m
        n = d.shape[0]
        if n == 1:
            return math.sqrt(d[0]), math.sqrt(d[0])
        e = off / np.sqrt(m[:-1] * m[1:])
        hi = float(eigvalsh_tridiagonal(d, e, select="i", select_range=(n - 1, n - 1))[0])
        lo = eigvalsh_tridiagonal(d, e, select="i", select_range=(0, 1))
        lo = [v for v in lo if v > 1e-12 * hi]
        return math.sqrt(lo[0]), math.sqrt(hi)

    def _bands(self):
        """``(off, diag)``: K's off-diagonal (length N-1, the same below and
        above) and diagonal (N/m), from each spring's ``E''(0)``."""
        N = self.n_dof
        k0 = np.asarray(_np_stiffness(0.0, self.k, self.alpha, self.beta), dtype=float) * np.ones_like(self.k)
        kpad = np.concatenate([[] if self._left else [0.0], k0, [] if self._right else [0.0]])
        return -kpad[1:N], kpad[:N] + kpad[1:]  # diag: left spring + right spring of each mass

    def stiffness_matrix(self, sparse: bool = False):
        """Tridiagonal K (N/m): each spring's stiffness ``E''(0)`` from the
        spring-energy template (``k``); ``sparse=True`` gives a scipy.sparse
        matrix (O(N) memory), else a dense array (built without scipy)."""
        off, diag = self._bands()
        if not sparse:
            K = np.diag(diag)
            i = np.arange(off.shape[0])
            K[i + 1, i] = off
            K[i, i + 1] = off
            return K
        import scipy.sparse as sp

        return sp.diags([off, diag, off], [-1, 0, 1], format="csr")

    def _compute_gershgorin_w2(self) -> float:
        """:meth:`_gershgorin_w2` from the bands, without scipy: each row's
        ``|K_i,i-1| + (|K_ii| + |K_i,i+1|)``, the grouping of scipy's sparse
        row sum (so the bound is the one the sparse matrix gives, to the bit)."""
        off, diag = self._bands()
        a = np.abs(off)
        row = np.abs(diag)
        row[:-1] = row[:-1] + a
        row[1:] = a + row[1:]
        return float(np.max(row / self.mass))
