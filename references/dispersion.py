"""Dispersion relation of the monatomic lattice (thesis sec. 2.2.2, Fig. 4.8).

Equal masses ``m`` (kg) joined by equal springs ``k`` (N/m) at spacing ``d``
(m): ``m x_n'' = k (x_{n-1} - 2 x_n + x_{n+1})`` (eq. 2.42 with erratum 6).
A travelling wave ``x_n = A exp(i (kp n d - omega t))`` solves it when

    omega(kp) = sqrt(4k/m) |sin(kp d / 2)|                            (eq. 2.49)

with ``kp`` the wavenumber (rad/m; the thesis' "propagation constant"). The
relation is periodic with period ``2 pi / d``: wavenumbers differing by a
multiple of it describe the same lattice motion, so every wave is represented
in the first Brillouin zone ``-pi/d <= kp <= pi/d``. Derived quantities:

* ``omega_0 = sqrt(4k/m)`` the largest frequency (eq. 2.50),
* phase velocity ``v_p = omega / kp`` (eq. 2.51), ``-> d sqrt(k/m)`` as ``kp -> 0``,
* group velocity ``v_g = d omega / d kp = d sqrt(k/m) cos(kp d / 2) sign(kp)``
  on the first zone (eq. 2.54; erratum 7: eq. 2.53 prints ``d omega / d t``).
  It vanishes at the zone edge (standing waves carry no energy) and its
  largest magnitude is ``v_0 = d sqrt(k/m)`` (eq. 2.52).
* the speed of a Gaussian wave packet's energy centroid,
  ``gaussian_packet_group_velocity``: the energy-weighted mean of ``v_g``
  over the packet's spectrum, ``v_g(kp0) (1 - 5 d^2 / (16 sigma^2) + ...)``.

A finite chain of ``N`` equal masses between two walls has the standing-wave
modes ``x_j ~ sin(j kp_n d)`` with ``kp_n = n pi / ((N + 1) d)``,
``n = 1..N``, and frequencies ``omega(kp_n) = 2 sqrt(k/m) sin(n pi / (2 (N+1)))``.

References
----------
C. Kittel, *Introduction to Solid State Physics*, 8th ed., Wiley 2005, ch. 4
(monatomic lattice, first Brillouin zone, group velocity).
"""
from __future__ import annotations

import math

import numpy as np

from rk4h.validate import positive

__all__ = [
    "omega", "omega_0", "v_0", "phase_velocity", "group_velocity",
    "fold_to_first_zone", "in_first_zone", "finite_chain_wavenumbers",
    "finite_chain_frequencies", "gaussian_packet_group_velocity", "THESIS_LATTICE",
]

#: The thesis' lattice (sec. 4.2, Code 02): m = 0.815 kg, k = 41.5 N/m, d = 0.01 m.
THESIS_LATTICE = {"m": 0.815, "k": 41.5, "d": 0.01}


def _check(m, k, d=None):
    m, k = positive("m", m), positive("k", k)
    return (m, k) if d is None else (m, k, positive("d", d))


def omega_0(m, k) -> float:
    """Largest angular frequency of the lattice, ``sqrt(4k/m)`` (rad/s, eq. 2.50)."""
    m, k = _check(m, k)
    return math.sqrt(4.0 * k / m)


def v_0(m, k, d) -> float:
    """Long-wave speed of sound ``d sqrt(k/m)`` (m/s, eq. 2.52): the phase and
    group velocity as ``kp -> 0`` and the largest group speed."""
    m, k, d = _check(m, k, d)
    return d * math.sqrt(k / m)


def omega(kp, m, k, d):
    """Angular frequency (rad/s) of the wave with wavenumber ``kp`` (rad/m), eq. 2.49.

    ``omega = sqrt(4k/m) |sin(kp d / 2)|``; even and ``2 pi / d``-periodic in ``kp``.
    """
    m, k, d = _check(m, k, d)
    return math.sqrt(4.0 * k / m) * np.abs(np.sin(0.5 * d * np.asarray(kp, dtype=float)))


def phase_velocity(kp, m, k, d):
    """Phase velocity ``omega / kp`` (m/s), eq. 2.51; signed like ``kp``, and
    ``d sqrt(k/m)`` at ``kp = 0`` (the limit from either side in magnitude,
    taken as the right-moving one)."""
    m, k, d = _check(m, k, d)
    kp = np.asarray(kp, dtype=float)
    half = 0.5 * d * kp
    safe = np.where(half == 0.0, 1.0, half)
    # omega / kp = v0 |sin(x)| / x with x = kp d / 2, v0 = d sqrt(k/m)
    ratio = np.where(half == 0.0, 1.0, np.abs(np.sin(safe)) / safe)
    return d * math.sqrt(k / m) * ratio


def group_velocity(kp, m, k, d):
    """Group velocity ``d omega / d kp`` (m/s), eq. 2.54 with erratum 7.

    ``v_g = d sqrt(k/m) cos(kp d / 2) sign(sin(kp d / 2))``: on the first
    Brillouin zone this is ``v_0 cos(kp d / 2) sign(kp)``, so a packet with
    ``kp > 0`` moves right. At ``kp = 0`` (where ``|sin|`` has a kink) the
    right-moving value ``+v_0`` is returned; at the zone edge ``v_g = 0``.
    """
    m, k, d = _check(m, k, d)
    half = 0.5 * d * np.asarray(kp, dtype=float)
    sgn = np.where(np.sin(half) < 0.0, -1.0, 1.0)
    return d * math.sqrt(k / m) * np.cos(half) * sgn


def fold_to_first_zone(kp, d):
    """The wavenumber equivalent to ``kp`` in the first Brillouin zone,
    ``[-pi/d, pi/d)`` (rad/m): ``kp - 2 pi n / d`` for the integer ``n`` that
    lands there. Same ``omega``, same lattice displacements ``exp(i kp n d)``."""
    d = positive("d", d)
    g = 2.0 * math.pi / d
    kp = np.asarray(kp, dtype=float)
    return kp - g * np.floor((kp + 0.5 * g) / g)


def in_first_zone(kp, d):
    """True where ``|kp| <= pi / d``."""
    d = positive("d", d)
    return np.abs(np.asarray(kp, dtype=float)) <= math.pi / d


def finite_chain_wavenumbers(N: int, d) -> np.ndarray:
    """``kp_n = n pi / ((N + 1) d)``, ``n = 1..N`` (rad/m): the standing waves
    of ``N`` equal masses between two fixed walls (mode ``n``: ``x_j ~
    sin(j kp_n d)``, vanishing at the walls ``j = 0`` and ``j = N + 1``)."""
    if isinstance(N, bool) or not isinstance(N, (int, np.integer)) or N < 1:
        raise ValueError(f"`N` must be an integer >= 1, got {N!r}")
    d = positive("d", d)
    return np.arange(1, N + 1) * math.pi / ((N + 1) * d)


def finite_chain_frequencies(N: int, m, k) -> np.ndarray:
    """Angular frequencies (rad/s, ascending) of ``N`` equal masses between
    walls: ``omega(kp_n) = 2 sqrt(k/m) sin(n pi / (2 (N + 1)))``."""
    d = 1.0  # omega(kp_n) does not depend on the spacing
    return omega(finite_chain_wavenumbers(N, d), m, k, d)


def gaussian_packet_group_velocity(kp0, sigma, m, k, d) -> float:
    """Speed (m/s) of the energy centroid of a right-moving Gaussian packet.

    The packet is ``u_j = Re[A exp(-(x_j - x0)^2 / (2 sigma^2)) exp(i kp0 (x_j - x0))]``
    travelling right (``rk4h.references.wavepacket.packet_state``). Its wave of
    wavenumber ``K`` has amplitude ``psi_hat(K) ~ exp(-(K - kp0)^2 sigma^2 / 2)``
    and energy ``~ omega(K)^2 |psi_hat(K)|^2``, and travels at ``v_g(K)``; the
    energy centroid of a linear, non-reflecting chain moves at the
    energy-weighted mean of ``v_g`` over that spectrum. With ``a = K d / 2``,
    Gaussian of mean ``a0 = kp0 d / 2`` and variance ``s = d^2 / (8 sigma^2)``,
    ``omega^2 v_g ~ sin^2 a cos a = (cos a - cos 3a) / 4`` and
    ``omega^2 ~ sin^2 a = (1 - cos 2a) / 2``, and ``<cos(n a)> = cos(n a0)
    exp(-n^2 s / 2)``, so

        v = v_0 (cos a0 e^{-s/2} - cos 3a0 e^{-9s/2}) / (2 (1 - cos 2a0 e^{-2s}))
          = v_g(kp0) (1 - 5 s / 2 + (25 / 8 + 1 / sin^2 a0) s^2 + O(s^3))
          = v_g(kp0) (1 - 5 d^2 / (16 sigma^2) + ...).

    The first-order offset ``-5 s / 2`` does not depend on ``kp0``: ``-s / 2``
    from the curvature of ``v_g`` (the mean of ``cos a``), ``-2 s`` from the
    energy weight ``omega^2`` favouring the larger ``K`` where ``v_g`` is
    smaller. Exact (for the continuous spectrum) when the spectrum lies inside
    ``0 < K < 2 pi / d``: ``kp0 sigma >> 1`` and ``(2 pi / d - kp0) sigma >> 1``
    (no left-moving part, no aliasing); sampling the Gaussian on the lattice
    changes it by ``exp(-(pi sigma / d)^2)``-small terms when ``sigma >> d``.
    """
    m, k, d = _check(m, k, d)
    sigma = positive("sigma", sigma)
    kp0 = float(kp0)
    a0, s = 0.5 * d * kp0, d * d / (8.0 * sigma * sigma)
    num = math.cos(a0) * math.exp(-0.5 * s) - math.cos(3.0 * a0) * math.exp(-4.5 * s)
    den = 2.0 * (1.0 - math.cos(2.0 * a0) * math.exp(-2.0 * s))
    return d * math.sqrt(k / m) * num / den
