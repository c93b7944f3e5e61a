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

from ..validate import boolean, positive
from .base import MASS_MIN, Defined, Drawing, check_normal_positive
from .params import Param
from .potential import PotentialModel

#: The potential (J) of the exact model in the angles and the constants
#: ``mgl = m g L``, ``k``, ``L``, ``d``; the spring's length is the distance
#: between the bobs ``(L sin th1, -L cos th1)`` and ``(d + L sin th2, -L cos th2)``.
EXACT = ("mgl*(2 - cos(theta1) - cos(theta2))"
         " + k/2*(sqrt((d + L*(sin(theta2) - sin(theta1)))^2 + (L*(cos(theta2) - cos(theta1)))^2) - d)^2")
#: The small-angle potential, ``kl2 = k L^2``.
LINEAR = "mgl*(theta1^2 + theta2^2)/2 + kl2*(theta2 - theta1)^2/2"


class Pendulums(Defined):
    """Parameters: ``m`` (kg), ``length`` (m), ``g`` (m/s^2), ``k`` (N/m),
    ``linear`` (bool), ``separation`` (m, optional, default ``length``).

    Defined by the potential :data:`EXACT` (or :data:`LINEAR`)."""

    name = "pendulums"
    summary = "Two equal pendulums coupled by a spring between the bobs (thesis sec. 1.1.1)."
    parameters = (
        Param("m", "normal", "kg", "mass of each bob", 1.0),
        Param("length", "normal", "m", "length of each rod", 1.0),
        Param("g", "normal", "m/s^2", "gravitational acceleration", 9.81),
        Param("k", "normal", "N/m", "stiffness of the coupling spring", 0.5),
        Param("linear", "bool", "-", "true: the small-angle equations; false: the exact ones", True, default=False),
        Param("separation", "normal", "m", "distance between the pivots, the spring's natural length", 1.0,
              default=None, default_text="length"),
    )

    def __init__(self, m, length, g, k, linear=False, separation=None):
        self.m = check_normal_positive("m", positive("m", m))
        self.length = check_normal_positive("length", positive("length", length))
        self.g = check_normal_positive("g", positive("g", g))
        self.k = check_normal_positive("k", positive("k", k))
        linear = boolean("linear", linear)
        self.separation = (self.length if separation is None
                           else check_normal_positive("separation", positive("separation", separation)))
        ml2 = self.m * self.length ** 2
        if not ml2 >= MASS_MIN:
            raise ValueError(f"`length` must make the generalized mass m length^2 >= {MASS_MIN:g} kg m^2, "
                             f"got m = {self.m!r}, length = {self.length!r}")
        mgl, kl2 = self.m * self.g * self.length, self.k * self.length ** 2
        if linear:
            self._adopt(lambda: PotentialModel(["theta1", "theta2"], [ml2, ml2], LINEAR, {"mgl": mgl, "kl2": kl2}),
                        "k")
        else:
            self._adopt(lambda: PotentialModel(["theta1", "theta2"], [ml2, ml2], EXACT,
                                               {"mgl": mgl, "k": self.k, "L": self.length, "d": self.separation}),
                        "k")
        self.linear = linear
        self.coord_names = ["theta1", "theta2"]
        self._check_scales("k")

    def params(self):
        return {"m": self.m, "length": self.length, "g": self.g, "k": self.k,
                "linear": self.linear, "separation": self.separation}

    def drawing(self):
        return Drawing(layout="angles", unit="rad", point_labels=("theta1 (pendulum 1)", "theta2 (pendulum 2)"),
                       caption=("with a weak spring the swing passes back and forth between them (beats at the "
                                "difference of the two mode frequencies)"))
