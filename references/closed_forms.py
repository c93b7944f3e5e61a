"""Closed-form frequencies and trajectories the thesis derives by hand.

* Two masses between two walls, three springs (thesis sec. 2.1, eq. 2.28 and,
  for equal springs, eq. 2.31); the rows of the thesis' Table 4.3.
* The 2-D harmonic oscillator ``m x'' = -kx x, m y'' = -ky y`` (sec. 2.3.2,
  eqs. 2.83-2.87): isotropic ellipses and anisotropic Lissajous figures, and the
  small-oscillation frequency ``sqrt(2k/m)`` of the four-spring mass (eqs.
  2.81-2.82, Table 4.6).

Units: masses in kg, stiffnesses in N/m, angular frequencies in rad/s,
frequencies in Hz, times in s, lengths in m.

Numerical note
--------------
The frequencies are the roots ``lam = omega^2`` of ``lam^2 - S lam + P = 0``
(eq. 2.24). Written as in eq. 2.28, the smaller root ``(S - sqrt(D)) / 2``
cancels catastrophically when the mass ratio is extreme (``D ~ S^2``). Here the
larger root is computed with the sign that adds, ``(S + sqrt(D)) / 2``, and the
smaller one from Vieta's product, ``P / lam_high``, with ``P`` and ``D``
themselves written as sums of non-negative terms ([1], sec. 5.6):

    P = (k1 k2 + k1 k3 + k2 k3) / (m1 m2)
    D = ((k1 + k2)/m1 - (k2 + k3)/m2)^2 + 4 k2^2 / (m1 m2)          (eq. 2.27)

so both roots carry a relative error of a few ulp for any positive masses.

References
----------
[1] W. H. Press et al., *Numerical Recipes*, 3rd ed., Cambridge 2007, sec. 5.6
    (quadratic equations without cancellation).
[2] J. R. Taylor, *Classical Mechanics*, University Science Books 2005,
    sec. 5.3 (2-D oscillator) and sec. 11.2 (two carts, three springs).
"""
from __future__ import annotations

import math

import numpy as np

from rk4h.validate import positive

__all__ = [
    "two_dof_frequencies", "two_dof_equal_k", "thesis_table_4_3",
    "planar4_small_oscillation", "oscillator2d_frequencies",
    "oscillator2d_initial_state", "oscillator2d_trajectory", "thesis_table_4_6",
    "TABLE_4_3_CASES", "TABLE_4_6",
]


def _positive_array(name, value):
    """``value`` as a float array whose entries are finite and > 0."""
    if np.ndim(value) == 0:
        return np.asarray(positive(name, value))
    a = np.asarray(value, dtype=float)
    bad = ~(np.isfinite(a) & (a > 0))
    if bad.any():
        raise ValueError(f"`{name}` must be finite and > 0, got {a[bad].flat[0]!r}")
    return a


def _scalar_or_array(x):
    return float(x) if np.ndim(x) == 0 else x


def _quadratic_roots(S, P, D):
    """Roots of ``lam^2 - S lam + P`` with ``S, P > 0``, ``D = S^2 - 4P >= 0``
    given in a cancellation-free form: (lam_low, lam_high)."""
    lam_high = 0.5 * (S + np.sqrt(D))
    return P / lam_high, lam_high


def two_dof_frequencies(m1, m2, k1, k2, k3):
    """Natural angular frequencies of two masses on three springs, wall to wall.

    Thesis eq. 2.28 (the roots in ``omega^2`` of eq. 2.24), evaluated without
    cancellation (see the module notes). Vectorised: arguments broadcast.

    Parameters
    ----------
    m1, m2 : float or array_like
        Masses (kg), left and right; > 0.
    k1, k2, k3 : float or array_like
        Stiffness (N/m) of the springs wall-m1, m1-m2, m2-wall; > 0.

    Returns
    -------
    omega_low, omega_high : float or ndarray
        Angular frequencies (rad/s), ``omega_low <= omega_high``.
    """
    m1, m2 = _positive_array("m1", m1), _positive_array("m2", m2)
    k1, k2, k3 = (_positive_array(n, v) for n, v in (("k1", k1), ("k2", k2), ("k3", k3)))
    a = (k1 + k2) / m1
    b = (k2 + k3) / m2
    P = (k1 * k2 + k1 * k3 + k2 * k3) / (m1 * m2)
    D = (a - b) ** 2 + 4.0 * k2 * k2 / (m1 * m2)  # eq. 2.27
    lo, hi = _quadratic_roots(a + b, P, D)
    return _scalar_or_array(np.sqrt(lo)), _scalar_or_array(np.sqrt(hi))


def two_dof_equal_k(k, m1=None, m2=None, mu=None):
    """Natural angular frequencies of the 2-DOF chain with three equal springs.

    Thesis eq. 2.31: ``omega^2 = (k/m2) [mu + 1 -+ sqrt((mu - 1)^2 + mu)]`` with
    the mass ratio ``mu = m2 / m1``. Evaluated without cancellation:
    ``(mu - 1)^2 + mu = (mu - 1/2)^2 + 3/4`` (a ``hypot``, no overflow), the
    larger root directly, the smaller from the product of the roots,
    ``3 mu (k/m2)^2``. Vectorised over ``mu`` (and the masses).

    Give exactly two of ``m1``, ``m2``, ``mu``.

    Parameters
    ----------
    k : float
        Stiffness (N/m) of each of the three springs.
    m1, m2 : float or array_like, optional
        Masses (kg).
    mu : float or array_like, optional
        Mass ratio ``m2 / m1``; must be finite and > 0 (thesis eqs. 2.34-2.40:
        ``omega_low^2 > 0`` exactly when ``mu > 0``).

    Returns
    -------
    omega_low, omega_high : float or ndarray
        Angular frequencies (rad/s). Limits (``m1`` fixed):
        ``mu -> 0``: ``omega_low^2 -> 3k / (2 m1)``, ``omega_high^2 ~ 2k / m2``;
        ``mu -> inf``: ``omega_low^2 ~ 3k / (2 m2)``, ``omega_high^2 -> 2k / m1``.
    """
    k = _positive_array("k", k)
    given = [name for name, v in (("m1", m1), ("m2", m2), ("mu", mu)) if v is not None]
    if len(given) != 2:
        raise ValueError(f"give exactly two of `m1`, `m2`, `mu`, got {given or 'none'}")
    if mu is not None:
        mu = _positive_array("mu", mu)
        if m2 is not None:
            m2 = _positive_array("m2", m2)
        else:
            m2 = _positive_array("m1", m1) * mu
    else:
        m1, m2 = _positive_array("m1", m1), _positive_array("m2", m2)
        mu = m2 / m1
    w2 = k / m2  # (k / m2), the unit of eq. 2.31
    s = np.hypot(mu - 0.5, math.sqrt(3.0) / 2.0)  # sqrt((mu - 1)^2 + mu)
    hi = w2 * (mu + 1.0 + s)
    lo = w2 * (3.0 * mu / (mu + 1.0 + s))  # Vieta: lo * hi = 3 mu w2^2
    return _scalar_or_array(np.sqrt(lo)), _scalar_or_array(np.sqrt(hi))


#: Table 4.3 (with Tables 4.1-4.2): parameters and initial displacements (m).
#: Case 2 is case 1 with x2(0) = 0 (thesis sec. 4.1.2).
TABLE_4_3_CASES = (
    {"case": 1, "m1": 0.815, "m2": 3.099, "k1": 41.5, "k2": 138.0, "k3": 157.8, "x0": (0.005, 0.005)},
    {"case": 2, "m1": 0.815, "m2": 3.099, "k1": 41.5, "k2": 138.0, "k3": 157.8, "x0": (0.005, 0.0)},
    {"case": 3, "m1": 0.815, "m2": 0.815, "k1": 41.5, "k2": 41.5, "k3": 41.5, "x0": (0.005, 0.0)},
)


def thesis_table_4_3() -> list[dict]:
    """The thesis' Table 4.3 recomputed, with correct units (erratum 1).

    For each case: the parameters, ``omega_1``, ``omega_2`` (rad/s, ascending)
    from the closed form eq. 2.28, the same from the generalized eigenproblem
    ``K phi = omega^2 M phi`` of ``rk4core``'s chain model (``*_eig``), and
    ``f_max = omega_2 / (2 pi)`` (Hz).

    Returns
    -------
    list of dict
        Keys ``case, m1, m2, k1, k2, k3, x0, omega_1, omega_2, f_max,
        omega_1_eig, omega_2_eig, f_max_eig``.
    """
    from rk4h.models import Chain

    rows = []
    for p in TABLE_4_3_CASES:
        w1, w2 = two_dof_frequencies(p["m1"], p["m2"], p["k1"], p["k2"], p["k3"])
        chain = Chain([p["m1"], p["m2"]], [p["k1"], p["k2"], p["k3"]], walls="both")
        omega_eig, _ = chain.modes()
        rows.append({
            **p,
            "omega_1": w1, "omega_2": w2, "f_max": w2 / (2 * math.pi),
            "omega_1_eig": float(omega_eig[0]), "omega_2_eig": float(omega_eig[1]),
            "f_max_eig": float(omega_eig[1]) / (2 * math.pi),
        })
    return rows


# -- the 2-D oscillator ---------------------------------------------------------

#: Table 4.6: the four-spring mass used for the isotropic oscillator figures.
TABLE_4_6 = {"m": 0.815, "k": 41.5, "l": 0.01, "A": 1.0, "B": 1.0,
             "Delta": (0.0, math.pi / 4, math.pi / 2, 3 * math.pi / 4)}


def planar4_small_oscillation(m, k):
    """Angular frequency (rad/s) and period (s) of the four-spring mass in the
    small-oscillation limit, ``m x'' = -2k x`` (thesis eqs. 2.79-2.82):
    ``omega = sqrt(2k/m)``, ``T = 2 pi / omega``. Independent of ``l``."""
    omega = math.sqrt(2.0 * positive("k", k) / positive("m", m))
    return omega, 2.0 * math.pi / omega


def thesis_table_4_6() -> dict:
    """Table 4.6 recomputed (erratum 5): ``omega`` (rad/s) and ``T`` (s) of
    the isotropic oscillator ``m = 0.815 kg``, ``k = 41.5 N/m``."""
    omega, period = planar4_small_oscillation(TABLE_4_6["m"], TABLE_4_6["k"])
    return {**TABLE_4_6, "omega": omega, "T": period}


def oscillator2d_frequencies(m, kx, ky):
    """``(omega_x, omega_y) = (sqrt(kx/m), sqrt(ky/m))`` (rad/s) of
    ``m x'' = -kx x, m y'' = -ky y``. Isotropic when ``kx == ky``."""
    m = positive("m", m)
    return math.sqrt(positive("kx", kx) / m), math.sqrt(positive("ky", ky) / m)


def oscillator2d_initial_state(A, B, omega_y, Delta):
    """State ``[x, y, vx, vy]`` at ``t = 0`` of the trajectory
    ``x = A cos(omega_x t)``, ``y = B cos(omega_y t - Delta)`` (eqs. 2.86-2.87):
    ``[A, B cos(Delta), 0, B omega_y sin(Delta)]`` (m, m/s)."""
    return np.array([float(A), B * math.cos(Delta), 0.0, B * omega_y * math.sin(Delta)])


def oscillator2d_trajectory(t, A, B, omega_x, omega_y, Delta):
    """Closed-form trajectory of the 2-D oscillator (thesis eqs. 2.86-2.87).

    ``x = A cos(omega_x t)``, ``y = B cos(omega_y t - Delta)`` and their time
    derivatives. Isotropic (``omega_x = omega_y``): a line for ``Delta = 0``
    or ``pi``, otherwise an ellipse; anisotropic: a Lissajous figure, closed
    only when ``omega_x / omega_y`` is rational.

    Parameters
    ----------
    t : array_like, shape (m,)
        Times (s), origin chosen so that ``x`` has zero phase (eq. 2.85).
    A, B : float
        Amplitudes (m).
    omega_x, omega_y : float
        Angular frequencies (rad/s).
    Delta : float
        Phase lag (rad) of ``y`` behind ``x``.

    Returns
    -------
    ndarray, shape (4, m)
        ``[x, y, vx, vy]`` in the layout of ``rk4core``'s states ``[q, v]``.
    """
    t = np.atleast_1d(np.asarray(t, dtype=float))
    px, py = omega_x * t, omega_y * t - Delta
    return np.vstack([A * np.cos(px), B * np.cos(py),
                      -A * omega_x * np.sin(px), -B * omega_y * np.sin(py)])
