"""Two equal pendulums coupled by a spring between the bobs (thesis sec. 1.1.1, Fig 1.4).

Pivots at (0, 0) and (d, 0) with ``d = separation`` (default: ``length``);
bobs of mass ``m`` on massless rods of length ``length``; the spring (stiffness
``k``) has natural length ``d``, so it is unstretched when both hang straight.
Coordinates: angles ``theta1, theta2`` (rad) from the downward vertical;
generalized mass ``m length^2``.

Exact model: ``V = m g L (2 - cos th1 - cos th2) + k/2 (|b2 - b1| - d)^2``.
Small-angle model (``linear=True``): ``V = m g L (th1^2 + th2^2)/2 +
k L^2 (th2 - th1)^2 / 2``; normal modes ``sqrt(g/L)`` (in phase) and
``sqrt(g/L + 2k/m)`` (anti-phase); a weak spring gives beats.
"""
from __future__ import annotations

import numpy as np

from ..validate import boolean, positive
from .base import MASS_MIN, Model, check_normal_positive


class Pendulums(Model):
    """Parameters: ``m`` (kg), ``length`` (m), ``g`` (m/s^2), ``k`` (N/m),
    ``linear`` (bool), ``separation`` (m, optional, default ``length``)."""

    name = "pendulums"

    def __init__(self, m, length, g, k, linear=False, separation=None):
        self.m = check_normal_positive("m", positive("m", m))
        self.length = check_normal_positive("length", positive("length", length))
        self.g = check_normal_positive("g", positive("g", g))
        self.k = check_normal_positive("k", positive("k", k))
        self.linear = boolean("linear", linear)
        self.separation = (self.length if separation is None
                           else check_normal_positive("separation", positive("separation", separation)))
        self.n_dof = 2
        ml2 = self.m * self.length ** 2
        if not ml2 >= MASS_MIN:
            raise ValueError(f"`length` must make the generalized mass m length^2 >= {MASS_MIN:g} kg m^2, "
                             f"got m = {self.m!r}, length = {self.length!r}")
        self.mass = np.array([ml2, ml2])
        self.coord_names = ["theta1", "theta2"]
        self._check_scales("k")

    def params(self):
        return {"m": self.m, "length": self.length, "g": self.g, "k": self.k,
                "linear": self.linear, "separation": self.separation}

    def _spring(self, q, ops):
        """Bob-to-bob vector (dx, dy) and its length."""
        L, d = self.length, self.separation
        s1, c1, s2, c2 = ops.sin(q[0]), ops.cos(q[0]), ops.sin(q[1]), ops.cos(q[1])
        dx = d + L * (s2 - s1)
        dy = -L * (c2 - c1)
        return dx, dy, ops.sqrt(dx * dx + dy * dy), (s1, c1, s2, c2)

    def _potential(self, q, ops):
        mgl, kl2 = self.m * self.g * self.length, self.k * self.length ** 2
        if self.linear:
            dth = q[1] - q[0]
            return 0.5 * mgl * (q[0] * q[0] + q[1] * q[1]) + 0.5 * kl2 * dth * dth
        _, _, D, (s1, c1, s2, c2) = self._spring(q, ops)
        ext = D - self.separation
        return mgl * (2.0 - c1 - c2) + 0.5 * self.k * ext * ext

    def _force(self, q, ops):
        mgl, kl2 = self.m * self.g * self.length, self.k * self.length ** 2
        if self.linear:
            dth = q[1] - q[0]
            comps = [-mgl * q[0] + kl2 * dth, -mgl * q[1] - kl2 * dth]
        else:
            L = self.length
            dx, dy, D, (s1, c1, s2, c2) = self._spring(q, ops)
            t = self.k * (D - self.separation) / D  # tension / length
            # dD/dth1 = (dx * (-L c1) + dy * (-L s1)) / D ; dD/dth2 = (dx * L c2 + dy * L s2) / D
            comps = [-mgl * s1 + t * L * (dx * c1 + dy * s1),
                     -mgl * s2 - t * L * (dx * c2 + dy * s2)]
        return np.array(comps, dtype=object) if q.dtype == object else np.stack(comps)

    def stiffness_matrix(self):
        mgl, kl2 = self.m * self.g * self.length, self.k * self.length ** 2
        return np.array([[mgl + kl2, -kl2], [-kl2, mgl + kl2]])
