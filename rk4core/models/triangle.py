"""Three equal masses at the corners of an equilateral triangle, joined by three
equal springs, free in the plane (thesis sec. 1.1.1, Fig 1.5).

Rest positions P1 = (0, 0), P2 = (a, 0), P3 = (a/2, a sqrt(3)/2) with ``a =
side``; springs have natural length ``a``. Coordinates are displacements from
rest, flat: ``x1, y1, x2, y2, x3, y3`` (m). Exact geometry:
``V = k/2 sum_{i<j} (|r_j - r_i| - a)^2``. The linearization has three zero
modes (two translations, one rotation), a degenerate pair at sqrt(3k/(2m)) and
the breathing mode at sqrt(3k/m).
"""
from __future__ import annotations

import math

import numpy as np

from ..validate import positive
from .base import Model, check_normal_positive

_PAIRS = ((0, 1), (1, 2), (0, 2))


class Triangle(Model):
    """Parameters: ``m`` (kg, each mass), ``k`` (N/m, each spring), ``side`` (m)."""

    name = "triangle"
    linear = False

    def __init__(self, m, k, side):
        self.m = check_normal_positive("m", positive("m", m))
        self.k = check_normal_positive("k", positive("k", k))
        self.side = check_normal_positive("side", positive("side", side))
        a = self.side
        self.rest = ((0.0, 0.0), (a, 0.0), (0.5 * a, 0.5 * math.sqrt(3.0) * a))
        self.n_dof = 6
        self.mass = np.full(6, self.m)
        self.coord_names = ["x1", "y1", "x2", "y2", "x3", "y3"]
        self._check_scales("k")

    def params(self):
        return {"m": self.m, "k": self.k, "side": self.side}

    def _bond(self, q, i, j, ops):
        (xi, yi), (xj, yj) = self.rest[i], self.rest[j]
        dx = (xj - xi) + q[2 * j] - q[2 * i]
        dy = (yj - yi) + q[2 * j + 1] - q[2 * i + 1]
        return dx, dy, ops.sqrt(dx * dx + dy * dy)

    def _potential(self, q, ops):
        total = 0.0
        for i, j in _PAIRS:
            _, _, L = self._bond(q, i, j, ops)
            total = total + 0.5 * self.k * (L - self.side) * (L - self.side)
        return total

    def _force(self, q, ops):
        f = [0.0] * 6
        for i, j in _PAIRS:
            dx, dy, L = self._bond(q, i, j, ops)
            s = self.k * (L - self.side) / L  # tension / length, pulls i towards j
            f[2 * i] = f[2 * i] + s * dx
            f[2 * i + 1] = f[2 * i + 1] + s * dy
            f[2 * j] = f[2 * j] - s * dx
            f[2 * j + 1] = f[2 * j + 1] - s * dy
        return np.array(f, dtype=object) if q.dtype == object else np.stack(np.broadcast_arrays(*f))

    def stiffness_matrix(self):
        K = np.zeros((6, 6))
        for i, j in _PAIRS:
            e = np.subtract(self.rest[j], self.rest[i]) / self.side
            B = self.k * np.outer(e, e)
            for a_, b_, sgn in ((i, i, 1), (j, j, 1), (i, j, -1), (j, i, -1)):
                K[2 * a_:2 * a_ + 2, 2 * b_:2 * b_ + 2] += sgn * B
        return K
