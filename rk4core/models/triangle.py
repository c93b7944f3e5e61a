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

from ..validate import positive
from .base import Defined, Drawing, check_normal_positive
from .network import Network
from .params import Param

_PAIRS = ((0, 1), (1, 2), (0, 2))


class Triangle(Defined):
    """Parameters: ``m`` (kg, each mass), ``k`` (N/m, each spring), ``side`` (m).

    Defined as a :class:`~rk4h.models.Network` of three masses at the rest
    positions and three springs of natural length ``side``."""

    name = "triangle"
    summary = ("Three equal masses on the corners of an equilateral triangle of springs, free in the plane "
               "(thesis sec. 1.1.1).")
    parameters = (
        Param("m", "normal", "kg", "mass at each corner", 0.815),
        Param("k", "normal", "N/m", "stiffness of each side's spring", 41.5),
        Param("side", "normal", "m", "side of the triangle, the springs' natural length", 0.1),
    )

    def __init__(self, m, k, side):
        self.m = check_normal_positive("m", positive("m", m))
        self.k = check_normal_positive("k", positive("k", k))
        self.side = check_normal_positive("side", positive("side", side))
        a = self.side
        self.rest = ((0.0, 0.0), (a, 0.0), (0.5 * a, 0.5 * math.sqrt(3.0) * a))
        self._adopt(lambda: Network(2, [self.m] * 3, [c for xy in self.rest for c in xy],
                                    [[i, j, self.k, self.side] for i, j in _PAIRS]), "k")
        self.coord_names = ["x1", "y1", "x2", "y2", "x3", "y3"]
        self._check_scales("k")

    def params(self):
        return {"m": self.m, "k": self.k, "side": self.side}

    def drawing(self):
        return Drawing(layout="plane", points=((0, 1), (2, 3), (4, 5)), reference=self.rest,
                       springs=tuple((i, j, f"{i + 1}-{j + 1}") for i, j in _PAIRS), rest=(self.side,) * 3,
                       point_labels=("mass 1", "mass 2", "mass 3"),
                       caption="the mix of vibration modes and any rigid drift or rotation")
