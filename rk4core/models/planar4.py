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

from ..validate import boolean, positive
from .base import Defined, Drawing, check_normal_positive
from .network import Network
from .params import Param
from .potential import PotentialModel


class Planar4(Defined):
    """Parameters: ``m`` (kg), ``k`` (N/m, each spring), ``l`` (m), ``linear`` (bool).

    Defined as a :class:`~rk4h.models.Network` (one mass at the origin,
    four anchors, springs of natural length ``l``), or, when ``linear``, as
    the potential ``k (x^2 + y^2)``."""

    name = "planar4"
    summary = "One mass on four springs to anchors at (+-l, 0), (0, +-l) (thesis sec. 2.3, Tables 4.4-4.5)."
    parameters = (
        Param("m", "normal", "kg", "the mass", 0.815),
        Param("k", "normal", "N/m", "stiffness of each spring", 41.5),
        Param("l", "normal", "m", "distance of each anchor from the centre, the springs' natural length", 0.01),
        Param("linear", "bool", "-", "true: the linearized (small-amplitude) model; false: the exact spring "
              "geometry", True, default=False),
    )

    def __init__(self, m, k, l, linear=False):  # noqa: E741 - the thesis' symbol
        self.m = check_normal_positive("m", positive("m", m))
        self.k = check_normal_positive("k", positive("k", k))
        self.l = check_normal_positive("l", positive("l", l))
        linear = boolean("linear", linear)
        l_ = self.l
        self.anchors = ((-l_, 0.0), (l_, 0.0), (0.0, -l_), (0.0, l_))
        if linear:
            self._adopt(lambda: PotentialModel(["x", "y"], [self.m, self.m], "k*(x^2 + y^2)", {"k": self.k}), "k")
        else:
            self._adopt(lambda: Network(2, [self.m], [0.0, 0.0], [[0, j + 1, self.k, self.l] for j in range(4)],
                                        anchors=[a for xy in self.anchors for a in xy]), "k")
        self.linear = linear
        self.coord_names = ["x", "y"]
        self._check_scales("k")

    def params(self):
        return {"m": self.m, "k": self.k, "l": self.l, "linear": self.linear}

    def drawing(self):
        return Drawing(layout="plane", points=((0, 1),), reference=((0.0, 0.0),), anchors=self.anchors,
                       springs=tuple((0, j + 1, name) for j, name in enumerate(("left", "right", "bottom", "top"))),
                       rest=(self.l,) * 4, point_labels=("mass",),
                       caption=("the linear model gives an ellipse, the exact geometry a precessing or "
                                "rosette-like curve"),
                       extra={"rest_note": f"l = {self.l:g} m; erratum 3: not length - l^2"})
