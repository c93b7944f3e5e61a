"""Group velocity of a Gaussian wave packet on the monatomic chain, by RK4.

The experiment behind the report's dispersion check: a packet of carrier
wavenumber ``kp0`` (rad/m) and Gaussian envelope of width ``sigma`` (m) is
launched rightwards on a long chain of equal masses (walls at both ends),
integrated with RK4's compiled loop (:func:`rk4h.fast.solve_model`, equal
to ``rk4h.solve(chain.rhs, ...)`` bit for bit, which runs instead where
numba is not installed), and its energy centroid is tracked while it is far
from both walls. The fitted centroid speed is compared with the
energy-weighted mean group velocity of the packet's spectrum
(``v_spectral``; ``rel_error_spectral``), and, with the explained offset
``spectral_offset`` beside it, with the group velocity ``d omega / d kp``
at the carrier
(``rk4h.references.dispersion.group_velocity``; thesis eq. 2.54 with erratum 7).

Initial state (a right-moving packet)
-------------------------------------
Sites ``j = 1..N`` sit at ``x_j = j d``; the walls are at ``0`` and
``(N + 1) d``. With the complex field
``psi_j = A exp(-(x_j - x0)^2 / (2 sigma^2)) exp(i kp0 (x_j - x0))`` and its
discrete Fourier components ``psi_hat(K)``, each component of a right-moving
wave evolves as ``exp(i (K x - omega(K) t))``; hence

    u_j(0) = Re psi_j,     v_j(0) = Re IDFT[ -i omega(K) psi_hat(K) ]_j ,

the exact travelling-wave form of the infinite lattice (to leading order,
``v_j = omega(kp0) env_j sin(kp0 (x_j - x0)) - v_g env'_j cos(...)``). The
field is negligible near the walls, so the periodic DFT does not matter.

The energy of site ``j`` is its kinetic energy plus half of each adjoining
spring's energy; the centroid is ``sum x_j e_j / sum e_j``.

What the centroid speed is (measured; ``tests/test_wavepacket_bias.py``)
-----------------------------------------------------------------------
The chain is linear and the packet never reaches a wall, so the centroid
moves at a constant speed: the energy-weighted mean of ``v_g(K)`` over the
packet's spectrum, ``v_spectral``, not ``v_g(kp0)``. The energy of the wave
``K`` is ``omega(K)^2 |psi_hat(K)|^2``: the Gaussian displacement spectrum
tilted towards larger ``K``, where ``v_g = v_0 cos(K d / 2)`` is smaller.
Hence ``v_spectral = v_g(kp0) (1 - 5 d^2 / (16 sigma^2) + ...)``
(``rk4h.references.dispersion.gaussian_packet_group_velocity``), independent of
``kp0`` to that order: ``-0.485%`` (kp0 = 0.3 pi/d) and ``-0.487%``
(0.6 pi/d) for the default ``sigma = 8 d``, the ``-0.49%`` offset of both
packets from ``v_g(kp0)``. What is left, ``rel_error_spectral``, is RK4's: its
phase error ``-z^5/120`` per step (``z = omega h``) slows every wave's group
velocity by ``(omega h)^4 / 24`` (``rk4_offset``: ``-1.2e-5`` and ``-1.2e-4``
at ``h = 0.02 s``; measured ``-1.2e-5`` and ``-6.9e-5``, the latter partly
offset by RK4's amplitude loss ``(omega h)^6 / 72`` per step, which damps the
slower high-``K`` side), shrinking 12-16x per halving of ``h``. The sample
count (20-200), fit window (either half of the samples), chain length
(N = 800) and start position change the measured speed by < 2e-6 of it at
0.3 pi/d and < 5e-5 at 0.6 pi/d (there RK4's amplitude loss, 0.4% of the
energy, makes the speed drift slowly with time); never near the 0.49%.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

import rk4h
from rk4h.references.dispersion import THESIS_LATTICE, group_velocity, omega
from rk4h.models import Chain
from rk4h.validate import positive

__all__ = ["WavePacketResult", "packet_state", "site_energy", "energy_centroid",
           "spectral_group_velocity", "rk4_group_velocity_offset", "measure_group_velocity"]


@dataclass
class WavePacketResult:
    """Outcome of :func:`measure_group_velocity` (SI units: m, s, m/s, rad/m).

    Attributes
    ----------
    kp0, sigma, x0 : float
        Carrier wavenumber, envelope width, initial centre.
    N, h, t_end : int, float, float
        Masses, RK4 step actually used, integration time.
    t, centroid : ndarray, shape (n,)
        Sample times and energy centroids.
    v_measured : float
        Least-squares slope of ``centroid(t)``.
    v_theory : float
        ``group_velocity(kp0)``.
    v_spectral : float
        Energy-weighted mean of ``group_velocity`` over the packet's spectrum:
        the speed the energy centroid should have (the apples-to-apples theory).
    rel_error : float
        ``(v_measured - v_theory) / v_theory``: includes ``spectral_offset``.
    rel_error_spectral : float
        ``(v_measured - v_spectral) / v_spectral``: the measurement's error
        (RK4's, about ``rk4_offset``).
    spectral_offset : float
        ``v_spectral / v_theory - 1``, about ``-5 d^2 / (16 sigma^2)``: the
        explained part of ``rel_error`` (``1 + rel_error = (1 + spectral_offset)
        (1 + rel_error_spectral)``).
    rk4_offset : float
        ``rk4_group_velocity_offset(kp0, h)``: RK4's predicted relative
        group-velocity error at the carrier, ``-(omega(kp0) h)^4 / 24``.
    energy_drift : float
        ``max |E(t) - E(0)| / E(0)`` over the samples (``E(0)`` is ``E_motion``
        of :mod:`rk4h.energy`: the lattice's potential is 0 at rest).
    success : bool
    message : str
    """

    kp0: float
    sigma: float
    x0: float
    N: int
    h: float
    t_end: float
    t: np.ndarray = field(repr=False)
    centroid: np.ndarray = field(repr=False)
    v_measured: float
    v_theory: float
    v_spectral: float
    rel_error: float
    rel_error_spectral: float
    spectral_offset: float
    rk4_offset: float
    energy_drift: float
    success: bool
    message: str


def _sites(N, d):
    return d * np.arange(1, N + 1)


def packet_state(N, kp0, sigma, x0, *, amplitude=1e-3, m=THESIS_LATTICE["m"],
                 k=THESIS_LATTICE["k"], d=THESIS_LATTICE["d"]):
    """State ``[u, v]`` (m, m/s), shape (2N,), of a right-moving Gaussian packet.

    See the module notes for the construction. ``amplitude`` (m) is the
    envelope's peak; the model is linear, so it only scales the state.
    """
    x = _sites(N, d)
    env = amplitude * np.exp(-0.5 * ((x - x0) / sigma) ** 2)
    psi = env * np.exp(1j * kp0 * (x - x0))
    K = 2.0 * math.pi * np.fft.fftfreq(N, d)
    v = np.fft.ifft(-1j * omega(K, m, k, d) * np.fft.fft(psi))
    return np.concatenate([psi.real, v.real])


def site_energy(y, m, k):
    """Energy (J) per site, shape (N,) or (N, n) for ``y`` (2N,) or (2N, n):
    ``m v_j^2 / 2`` plus half the energy of each adjoining spring (walls fixed)."""
    y = np.asarray(y, dtype=float)
    N = y.shape[0] // 2
    u, v = y[:N], y[N:]
    zero = np.zeros_like(u[:1])
    springs = 0.5 * k * np.diff(np.concatenate([zero, u, zero], axis=0), axis=0) ** 2
    return 0.5 * m * v * v + 0.5 * (springs[:-1] + springs[1:])


def energy_centroid(y, m, k, d):
    """Energy-weighted mean position (m) of the chain state(s) ``y``."""
    e = site_energy(y, m, k)
    x = _sites(e.shape[0], d)
    x = x if e.ndim == 1 else x[:, None]
    return np.sum(x * e, axis=0) / np.sum(e, axis=0)


def spectral_group_velocity(y0, m, k, d):
    """Energy-weighted mean group velocity (m/s) of the right-moving packet
    ``y0``: each DFT component carries energy ``~ omega(K)^2 |u_hat(K)|^2``
    and moves at ``group_velocity(K)``."""
    N = y0.shape[0] // 2
    K = 2.0 * math.pi * np.fft.fftfreq(N, d)
    w = omega(K, m, k, d)
    # u = Re psi, v = Re(-i omega psi) per component, omega even in K, give
    # psi_hat(K) = u_hat(K) + i v_hat(K) / omega(K): the amplitude of the wave
    # exp(i (K x - omega t)), moving right for K > 0 and left for K < 0.
    u_hat, v_hat = np.fft.fft(y0[:N]), np.fft.fft(y0[N:])
    with np.errstate(invalid="ignore", divide="ignore"):
        psi_hat = np.where(w > 0, u_hat + 1j * v_hat / np.where(w > 0, w, 1.0), 0.0)
    weight = w * w * np.abs(psi_hat) ** 2
    return float(np.sum(weight * group_velocity(K, m, k, d)) / np.sum(weight))


def rk4_group_velocity_offset(kp, h, m=THESIS_LATTICE["m"], k=THESIS_LATTICE["k"],
                              d=THESIS_LATTICE["d"]):
    """RK4's relative group-velocity error ``-(omega(kp) h)^4 / 24`` (leading order).

    RK4 advances the wave ``exp(-i omega t)`` by ``R(-i z)``, ``z = omega h``,
    whose phase is ``-(z - z^5 / 120 + O(z^7))``: the numerical frequency is
    ``omega - omega^5 h^4 / 120`` and its ``kp``-derivative
    ``v_g (1 - (omega h)^4 / 24)``.
    """
    z = omega(kp, m, k, d) * positive("h", h)
    return -z ** 4 / 24.0


def _rk4(chain, t_end, y0, n_steps, t_eval):
    """RK4 on ``chain`` over ``[0, t_end]``: its compiled loop
    (:func:`rk4h.fast.solve_model`) where numba is installed, else (the base
    install) :func:`rk4h.solve` on ``chain.rhs``; the same numbers either way."""
    try:
        from rk4h.fast import solve_model
    except ModuleNotFoundError as e:
        if e.name != "numba":
            raise
        return rk4h.solve(chain.rhs, (0.0, t_end), y0, n_steps=n_steps, t_eval=t_eval)
    return solve_model(chain, (0.0, t_end), y0, n_steps=n_steps, t_eval=t_eval)


def measure_group_velocity(kp0, *, N=400, sigma=None, h=0.02, n_samples=80,
                           m=THESIS_LATTICE["m"], k=THESIS_LATTICE["k"], d=THESIS_LATTICE["d"],
                           start=0.3, travel=0.4) -> WavePacketResult:
    """Launch a packet with RK4 and fit the speed of its energy centroid.

    Parameters
    ----------
    kp0 : float
        Carrier wavenumber (rad/m), ``0 < kp0 < pi/d``.
    N : int
        Number of masses (the chain is ``(N + 1) d`` long, walls at both ends).
    sigma : float, optional
        Envelope width (m); default ``8 d``.
    h : float
        RK4 step (s); ``omega_max h = sqrt(4k/m) h`` must stay well inside
        RK4's stability interval (``2.83``).
    n_samples : int
        Centroid samples (on the step grid) used in the fit.
    m, k, d : float
        Lattice mass (kg), stiffness (N/m), spacing (m).
    start, travel : float
        Initial centre and distance travelled, as fractions of the chain
        length; the packet stays ``min(start, 1 - start - travel)`` lengths
        from the walls.

    Returns
    -------
    WavePacketResult
    """
    m, k, d, h = positive("m", m), positive("k", k), positive("d", d), positive("h", h)
    kp0 = positive("kp0", kp0)
    if kp0 >= math.pi / d:
        raise ValueError(f"`kp0` must be < pi/d = {math.pi / d:.6g}, got {kp0!r}")
    sigma = 8.0 * d if sigma is None else positive("sigma", sigma)
    if isinstance(N, bool) or not isinstance(N, (int, np.integer)) or N < 2:
        raise ValueError(f"`N` must be an integer >= 2, got {N!r}")
    if not (0.0 < start and 0.0 < travel and start + travel < 1.0):
        raise ValueError(f"`start` and `travel` must be > 0 with start + travel < 1, got {start!r}, {travel!r}")
    length = (N + 1) * d
    x0 = start * length
    v_theory = float(group_velocity(kp0, m, k, d))
    t_end = travel * length / v_theory
    chain = Chain([m] * N, [k] * (N + 1), walls="both")
    y0 = packet_state(N, kp0, sigma, x0, m=m, k=k, d=d)
    n_steps = rk4h.step_count((0.0, t_end), h)
    step = t_end / n_steps
    idx = np.unique(np.linspace(0, n_steps, n_samples).round().astype(int))
    res = _rk4(chain, t_end, y0, n_steps, idx * step)
    v_spectral = spectral_group_velocity(y0, m, k, d)
    common = dict(kp0=kp0, sigma=sigma, x0=x0, N=N, h=res.h, t_end=t_end, v_theory=v_theory,
                  v_spectral=v_spectral, spectral_offset=v_spectral / v_theory - 1.0,
                  rk4_offset=float(rk4_group_velocity_offset(kp0, step, m, k, d)))
    if not res.success:
        nan = float("nan")
        return WavePacketResult(t=res.t, centroid=np.full(res.t.shape, nan), v_measured=nan,
                                rel_error=nan, rel_error_spectral=nan, energy_drift=nan, success=False,
                                message=res.message, **common)
    # row-major, as rk4h.solve returns it: numpy sums over sites in an order set by the layout
    y = np.ascontiguousarray(res.y)
    X = energy_centroid(y, m, k, d)
    v_measured = float(np.polyfit(res.t, X, 1)[0])
    E = np.sum(site_energy(y, m, k), axis=0)
    return WavePacketResult(
        t=res.t, centroid=X, v_measured=v_measured,
        rel_error=(v_measured - v_theory) / v_theory,
        rel_error_spectral=(v_measured - v_spectral) / v_spectral,
        energy_drift=float(np.max(np.abs(E - E[0])) / E[0]),
        success=True, message=res.message, **common,
    )
