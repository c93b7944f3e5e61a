"""A single mass held by four springs in the plane (thesis sec. 2.3, Tables 4.4-4.5).

Anchors at (-l, 0), (l, 0), (0, -l), (0, l) (m); each spring has natural length
``l`` (= the anchor distance), so the springs are unstretched when the mass is
at the origin. Coordinates ``(x, y)`` (m) are the mass' position. Exact geometry:
``V = k/2 * sum_j (|r - a_j| - l)^2`` (thesis eqs. 2.68-2.71 with erratum 3: the
extension is length - l, not length - l^2). The small-oscillation model
(``linear=True``) is ``m x'' = -2 k x, m y'' = -2 k y`` (eqs. 2.81-2.82).

When the mass reaches an anchor (|r - a_j| = 0) the spring's direction is
undefined; the force is then not finite and the integrators report it as a
blow-up at that time rather than raising.
"""
from __future__ import annotations

import numpy as np

from ..validate import boolean, positive
from .base import Model, check_normal_positive


class Planar4(Model):
    """Parameters: ``m`` (kg), ``k`` (N/m, each spring), ``l`` (m), ``linear`` (bool)."""

    name = "planar4"

    def __init__(self, m, k, l, linear=False):  # noqa: E741 - the thesis' symbol
        self.m = check_normal_positive("m", positive("m", m))
        self.k = check_normal_positive("k", positive("k", k))
        self.l = check_normal_positive("l", positive("l", l))
        self.linear = boolean("linear", linear)
        self.n_dof = 2
        self.mass = np.array([self.m, self.m])
        self.coord_names = ["x", "y"]
        l_ = self.l
        self.anchors = ((-l_, 0.0), (l_, 0.0), (0.0, -l_), (0.0, l_))
        self._check_scales("k")

    def params(self):
        return {"m": self.m, "k": self.k, "l": self.l, "linear": self.linear}

    def _spring_vectors(self, q):
        x, y = q[0], q[1]
        return [(x - ax, y - ay) for ax, ay in self.anchors]

    def spring_lengths(self, q, ops=None):
        """Lengths (m) of the four springs, anchor order as ``anchors``."""
        ops = ops or np
        return [ops.sqrt(dx * dx + dy * dy) for dx, dy in self._spring_vectors(q)]

    def _potential(self, q, ops):
        if self.linear:
            return self.k * (q[0] * q[0] + q[1] * q[1])
        total = 0.0
        for L in self.spring_lengths(q, ops):
            total = total + 0.5 * self.k * (L - self.l) * (L - self.l)
        return total

    def _force(self, q, ops):
        if self.linear:
            return np.array([-2.0 * self.k * q[0], -2.0 * self.k * q[1]], dtype=q.dtype)
        fx, fy = 0.0, 0.0
        for dx, dy in self._spring_vectors(q):
            L = ops.sqrt(dx * dx + dy * dy)
            s = self.k * (L - self.l) / L  # tension / length
            fx = fx - s * dx
            fy = fy - s * dy
        return np.array([fx, fy], dtype=q.dtype) if q.dtype == object else np.stack([fx, fy])

    def stiffness_matrix(self):
        return np.diag([2.0 * self.k, 2.0 * self.k])
