"""The 2-D harmonic oscillator (thesis sec. 2.3.2, Table 4.6, Figs 4.15-4.20).

``m x'' = -kx x``, ``m y'' = -ky y``: isotropic when ``kx == ky`` (closed
ellipses), anisotropic otherwise (Lissajous figures, closed only when
``omega_x / omega_y`` is rational).
"""
from __future__ import annotations

import numpy as np

from ..validate import positive
from .base import Model, check_normal_positive


class Oscillator2D(Model):
    """Parameters: ``m`` (kg), ``kx``, ``ky`` (N/m)."""

    name = "oscillator2d"
    linear = True

    def __init__(self, m, kx, ky):
        self.m = check_normal_positive("m", positive("m", m))
        self.kx = check_normal_positive("kx", positive("kx", kx))
        self.ky = check_normal_positive("ky", positive("ky", ky))
        self.n_dof = 2
        self.mass = np.array([self.m, self.m])
        self.coord_names = ["x", "y"]
        self._check_scales("kx")

    def params(self):
        return {"m": self.m, "kx": self.kx, "ky": self.ky}

    def _potential(self, q, ops):
        return 0.5 * (self.kx * q[0] * q[0] + self.ky * q[1] * q[1])

    def _force(self, q, ops):
        comps = [-self.kx * q[0], -self.ky * q[1]]
        return np.array(comps, dtype=object) if q.dtype == object else np.stack(comps)

    def stiffness_matrix(self):
        return np.diag([self.kx, self.ky])
