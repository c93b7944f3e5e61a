"""The 2-D harmonic oscillator (thesis sec. 2.3.2, Table 4.6, Figs 4.15-4.20).

``m x'' = -kx x``, ``m y'' = -ky y``: isotropic when ``kx == ky`` (closed
ellipses), anisotropic otherwise (Lissajous figures, closed only when
``omega_x / omega_y`` is rational).
"""
from __future__ import annotations

import math

from ..validate import positive
from .base import Defined, Drawing, check_normal_positive
from .params import Param
from .potential import PotentialModel


class Oscillator2D(Defined):
    """Parameters: ``m`` (kg), ``kx``, ``ky`` (N/m). Defined by the potential
    ``kx x^2/2 + ky y^2/2``."""

    name = "oscillator2d"
    summary = "The 2-D harmonic oscillator, isotropic or not (thesis sec. 2.3.2, Table 4.6)."
    parameters = (
        Param("m", "normal", "kg", "the mass", 0.815),
        Param("kx", "normal", "N/m", "stiffness along x", 41.5),
        Param("ky", "normal", "N/m", "stiffness along y", 83.0),
    )

    def __init__(self, m, kx, ky):
        self.m = check_normal_positive("m", positive("m", m))
        self.kx = check_normal_positive("kx", positive("kx", kx))
        self.ky = check_normal_positive("ky", positive("ky", ky))
        self._adopt(lambda: PotentialModel(["x", "y"], [self.m, self.m], "kx*x^2/2 + ky*y^2/2",
                                           {"kx": self.kx, "ky": self.ky}), "kx")
        self.coord_names = ["x", "y"]
        self._check_scales("kx")

    def params(self):
        return {"m": self.m, "kx": self.kx, "ky": self.ky}

    def drawing(self):
        ratio = math.sqrt(self.kx / self.ky)
        return Drawing(layout="plane", points=((0, 1),), reference=((0.0, 0.0),), point_labels=("mass",),
                       caption=(f"omega_x/omega_y = {ratio:.4g}: an ellipse or line when isotropic, a closed "
                                f"Lissajous figure for a rational ratio, space-filling for sqrt(2)"),
                       extra={"path_title": "x-y trajectory (Lissajous figure)"})
