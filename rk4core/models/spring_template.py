"""The one spring-energy template every spring model applies.

``E(r) = k r^2/2 + alpha r^3/3 + beta r^4/4`` (J) in the extension ``r``
(m), stiffness ``k`` (N/m) and the Fermi-Pasta-Ulam-Tsingou coefficients
``alpha`` (N/m^2) and ``beta`` (N/m^3). Its tension ``E'(r)`` (N) is
derived, never written by hand; :mod:`rk4h.models.network` evaluates
both and :mod:`rk4h.models.compiled` prints the tension into the
compiled kernels.
"""
from __future__ import annotations

from .. import expr as ex

__all__ = ["SPRING_ENERGY", "TENSION", "NAMES"]

_R, _K, _ALPHA, _BETA = ex.symbols("r", "k", "alpha", "beta")
#: The energy of one spring (J) in its extension ``r`` (m): the one definition.
SPRING_ENERGY = _K * _R**2 / 2 + _ALPHA * _R**3 / 3 + _BETA * _R**4 / 4
#: The template's variables, in the order the numpy evaluators take them.
NAMES = ("r", "k", "alpha", "beta")
#: The tension ``dE/dr`` (N).
TENSION = ex.diff(SPRING_ENERGY, "r")
