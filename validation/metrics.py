"""Numbers from trajectories: errors, energy drift, observed order, the RK4
energy theory, the cheapest solver per target error.

Metrics see arrays only (states ``y`` of shape (2n, m) on output times ``t``),
never solvers. Conventions (docs/reading-the-report.md):

* ``error_max`` -- the largest absolute difference from the reference over
  output times and state components (m, m/s, rad, rad/s as the model's
  coordinates are); ``error_final`` -- the same at the last output time only.
  ``error_rel`` divides by ``scale = max |y_ref|`` over the whole reference
  trajectory, so targets like 1e-6 mean "six correct digits of the largest
  state component" (Hairer & Wanner's scd idea, Bari IVP test set).
* ``energy_drift_max`` -- ``max_t |E(t) - E0| / E_motion`` with
  ``E_motion = E0 - V(q*)``, the energy of the motion above the equilibrium
  ``q*`` the model is linearized about (:mod:`rk4h.energy`): invariant when
  a constant is added to ``V``, and a pre-tensioned network's static spring
  energy is not counted as motion.
* A run that did not reach every output time has NaN errors (its status says why).
"""
from __future__ import annotations

import functools
import math

import numpy as np

__all__ = ["error_max", "error_final", "relative_energy_error", "energy_drift_max",
           "drift_per_time", "rk4_energy_factor", "rk4_energy_loss", "rk4_energy_log_factor", "rk4_drift_theory",
           "energy_loss", "energy_factor", "energy_log_factor", "phase_lag", "leading_terms", "drift_theory",
           "modal_energy_fractions", "fit_order", "OrderFit", "cheapest", "ROUNDOFF_REL", "PREASYMPTOTIC_REL"]

#: Errors below this fraction of the state scale are round-off, not truncation.
ROUNDOFF_REL = 1e-11
#: Errors above this fraction of the state scale are not in the asymptotic range.
PREASYMPTOTIC_REL = 1e-1


def error_max(y, y_ref) -> float:
    """``max |y - y_ref|`` over times and components; NaN if ``y`` has NaN."""
    d = np.abs(np.asarray(y, float) - np.asarray(y_ref, float))
    return float("nan") if not np.all(np.isfinite(d)) else float(d.max())


def error_final(y, y_ref) -> float:
    """``max |y - y_ref|`` over components at the last output time."""
    return error_max(np.asarray(y)[:, -1:], np.asarray(y_ref)[:, -1:])


def relative_energy_error(model, y) -> np.ndarray:
    """``(E(t) - E0) / E_motion`` along the trajectory (signed, dimensionless;
    :func:`rk4h.energy.relative_energy_error`)."""
    from rk4h.energy import relative_energy_error as rel

    return rel(model, y)


def energy_drift_max(model, y) -> float:
    """``max_t |E(t) - E0| / E_motion``; NaN if the run has NaN."""
    with np.errstate(over="ignore", invalid="ignore"):
        r = np.abs(relative_energy_error(model, y))
    # NaN (a state that did not get there) wins over inf (an overflowed energy).
    return float("nan") if np.isnan(r).any() else float(np.max(r))


def drift_per_time(model, t, y) -> float:
    """Energy drift per unit time (1/s): ``(E(T) - E0) / (E_motion (T - t0))``."""
    with np.errstate(over="ignore", invalid="ignore"):
        r = relative_energy_error(model, y)
    return float(r[-1] / (t[-1] - t[0])) if not np.isnan(r[-1]) else float("nan")


@functools.lru_cache(maxsize=None)
def _energy_loss_coefficients(tab) -> tuple[int, tuple[int, ...], int]:
    """``(m, (n_m, n_m+1, ...), D)`` with ``1 - |R(i theta)|^2 =
    theta^(2m) (n_m + n_m+1 theta^2 + ...) / D`` exactly (integers), from the
    method's stability polynomial ``R(z) = sum a_k z^k``
    (:func:`rk4h.stability_function.stability_polynomial`).

    ``|R(iy)|^2 = sum_n y^n sum_{j+k=n} a_j a_k i^(j-k)``: odd powers cancel,
    and the low even powers cancel exactly for a method of order ``p``
    (``m >= p/2 + 1`` when ``p`` is even)."""
    from fractions import Fraction

    from rk4h.stability_function import stability_polynomial

    a = [Fraction(x) for x in stability_polynomial(tab)]
    deg = len(a) - 1
    coef = []
    for n in range(0, 2 * deg + 1, 2):
        c = Fraction(0)
        for j in range(max(0, n - deg), min(n, deg) + 1):
            c += a[j] * a[n - j] * (1 if (j - (n - j)) % 4 == 0 else -1)
        coef.append(-c)
    coef[0] += 1  # 1 - |R|^2
    m = next((i for i, c in enumerate(coef) if c != 0), len(coef))
    coef = coef[m:] or [Fraction(0)]
    den = math.lcm(*(c.denominator for c in coef))
    return m, tuple(int(c * den) for c in coef), den


def energy_loss(tab, theta):
    """``1 - |R(i theta)|^2`` (dimensionless, per step) of the tableau ``tab``
    on a harmonic mode, ``theta = omega h``: the energy lost per step.

    For ``x'' = -omega^2 x`` in the complex variable ``z = omega x + i x'``,
    ``z' = -i omega z`` and one step of an explicit Runge-Kutta method
    multiplies ``z`` by ``R(-i theta)``, so the mode energy ``|z|^2 / 2`` is
    multiplied by exactly ``|R(i theta)|^2`` every step. Evaluated from the
    exact integer form of :func:`_energy_loss_coefficients` (for RK4
    ``theta^6 (8 - theta^2) / 576``): no cancellation, exact in sign at the
    imaginary-axis stability boundary (negative, a gain, beyond it)."""
    m, ints, den = _energy_loss_coefficients(tab)
    t2 = np.asarray(theta, float) ** 2
    acc = np.zeros_like(t2) + float(ints[-1])
    for c in ints[-2::-1]:
        acc = acc * t2 + float(c)
    return t2 ** m * acc / den


def energy_factor(tab, theta):
    """``|R(i theta)|^2``: the per-step energy factor of a harmonic mode."""
    return 1.0 - energy_loss(tab, theta)


def energy_log_factor(tab, theta):
    """``log |R(i theta)|^2`` (per step) without cancellation: the small part
    :func:`energy_loss` is formed on its own and passed to ``log1p`` (forming
    ``1 - loss`` first would lose, for RK4 at ``theta = 0.05``, 2.5e-7
    relative). Negative inside the stability interval (energy lost)."""
    return np.log1p(-energy_loss(tab, theta))


#: Below this |theta| :func:`phase_lag` sums the series of ``e^{i theta} -
#: R(i theta)`` (no cancellation); above it, the continuous argument of R.
_SERIES_BELOW = 2.0
_SERIES_TERMS = 24  # terms past R's degree: the last is < 1e-19 of the first for |theta| < 2
_UNWRAP_STEP = 0.01  # rad: grid of the continuous argument above _SERIES_BELOW


@functools.lru_cache(maxsize=None)
def _exp_minus_R(tab) -> tuple[tuple[float, ...], int]:
    """``(c_0 ... c_d, d)``: ``e^z - R(z) = sum_k c_k z^k`` for ``k <= d``
    (exact rationals ``1/k! - r_k``, zero up to the method's order) plus the
    tail ``sum_{k > d} z^k / k!``; ``d`` the degree of ``R``."""
    from fractions import Fraction

    from rk4h.stability_function import stability_polynomial

    r = [Fraction(x) for x in stability_polynomial(tab)]
    return tuple(float(Fraction(1, math.factorial(k)) - rk) for k, rk in enumerate(r)), len(r) - 1


def phase_lag(tab, theta):
    """Phase lag (rad) per step of a harmonic mode, ``theta - arg R(i theta)``,
    for the classical tableau ``tab`` (``theta = omega h``; odd in theta;
    ``theta^5/120`` to leading order for RK4; negative is a phase lead).

    ``arg`` is continuous from 0 at ``theta = 0`` (no ``2 pi`` jump where
    ``R(i theta)`` crosses the negative real axis, at ``sqrt 6`` for RK4).
    Below ``|theta| = 2`` the lag is formed from ``w = R(i theta) e^{-i
    theta} - 1`` with ``e^z - R(z)`` summed as exact low coefficients plus
    the exponential's tail (``theta - arg R`` would cancel: the lag is
    2.6e-9 at ``theta = 0.05`` for RK4); a few ulp relative there. Above, the
    argument is unwrapped along a grid of :data:`_UNWRAP_STEP`."""
    th = np.asarray(theta, dtype=float)
    a = np.abs(th)
    c, d = _exp_minus_R(tab)
    small = a < _SERIES_BELOW
    x = np.where(small, a, 0.0)
    z = 1j * x
    diff = np.zeros_like(z)
    for ck in reversed(c):
        diff = diff * z + ck
    term = z ** (d + 1) / math.factorial(d + 1)
    for k in range(d + 1, d + 1 + _SERIES_TERMS):
        diff = diff + term
        term = term * z / (k + 1)
    w = -diff * np.exp(-z)
    out = -np.arctan2(w.imag, 1.0 + w.real)
    if not small.all():
        from rk4h.stability_function import R

        big = np.flatnonzero(~small.ravel())
        flat = out.ravel().copy() if out.ndim else np.array([float(out)])
        for i in big:
            ai = float(a.ravel()[i]) if a.ndim else float(a)
            grid = np.linspace(0.0, ai, max(2, int(math.ceil(ai / _UNWRAP_STEP)) + 1))
            flat[i] = ai - float(np.unwrap(np.angle(R(tab, 1j * grid)))[-1])
        out = flat.reshape(out.shape) if out.ndim else flat[0]
    return np.sign(th) * out


def leading_terms(tab) -> tuple[tuple[float, int], tuple[float, int]]:
    """Leading orders of :func:`energy_loss` and :func:`phase_lag`:
    ``((a, p), (b, q))`` with loss ``~ a theta^p`` and lag ``~ b theta^q``
    (RK4: ``(1/72, 6)`` and ``(1/120, 5)``; Heun's third order ``(1/12, 4)``
    and ``(-1/30, 5)``), from exact coefficients. The lag is ``theta - Im log
    R(i theta) = -Im sum l_k (i theta)^k`` with ``log R(z) - z = sum l_k z^k``
    (a formal power series in exact rationals): its leading term is the first
    odd ``k`` with ``l_k != 0``."""
    from fractions import Fraction

    from rk4h.stability_function import stability_polynomial

    m, ints, den = _energy_loss_coefficients(tab)
    r = [Fraction(x) for x in stability_polynomial(tab)]
    n = len(r) + 8
    r += [Fraction(0)] * (n + 1 - len(r))
    # L = log R: L' R = R', so k l_k = k r_k - sum_{j=1}^{k-1} j l_j r_{k-j}
    L = [Fraction(0)] * (n + 1)
    for k in range(1, n + 1):
        L[k] = (k * r[k] - sum((j * L[j] * r[k - j] for j in range(1, k)), Fraction(0))) / k
    L[1] -= 1
    k = next(k for k in range(1, n + 1, 2) if L[k] != 0)
    return (ints[0] / den, 2 * m), (-float(L[k]) * (1 if k % 4 == 1 else -1), k)


def _rk4():
    from rk4h.methods import RK4

    return RK4


def rk4_energy_factor(theta):
    """:func:`energy_factor` of classical RK4: ``1 - theta^6/72 + theta^8/576``."""
    return energy_factor(_rk4(), theta)


def rk4_energy_loss(theta):
    """:func:`energy_loss` of classical RK4: ``theta^6 (8 - theta^2) / 576``."""
    return energy_loss(_rk4(), theta)


def rk4_energy_log_factor(theta):
    """:func:`energy_log_factor` of classical RK4."""
    return energy_log_factor(_rk4(), theta)


def modal_energy_fractions(omega, eta0, deta0) -> np.ndarray:
    """Share of the total energy in each mode: ``E_j = (deta_j^2 + omega_j^2 eta_j^2)/2``
    for mass-normalised modes (the energy of a linear model separates by mode)."""
    e = 0.5 * (np.asarray(deta0) ** 2 + (np.asarray(omega) * np.asarray(eta0)) ** 2)
    return e / e.sum()


def drift_theory(tab, omega, eta0, deta0, h, n_steps, duration) -> float:
    """Relative energy change per unit time (1/s) of the explicit tableau
    ``tab`` after ``n_steps`` steps of ``h`` on a linear model:
    ``sum_j f_j (g(omega_j h)^n - 1) / duration`` with ``f_j`` the modal
    energy fractions and ``g = |R(i omega_j h)|^2`` (:func:`energy_factor`,
    its log from :func:`energy_log_factor`). Exact for linear models (a
    Runge-Kutta step commutes with the modal decomposition), up to round-off.
    Not for partitioned methods, whose step is no polynomial in ``h A``."""
    f = modal_energy_fractions(omega, eta0, deta0)
    # g^n - 1 without cancellation: expm1(n log g), log g by log1p
    change = np.sum(f * np.expm1(n_steps * energy_log_factor(tab, np.asarray(omega) * h)))
    return float(change / duration)


def rk4_drift_theory(omega, eta0, deta0, h, n_steps, duration) -> float:
    """:func:`drift_theory` of classical RK4."""
    return drift_theory(_rk4(), omega, eta0, deta0, h, n_steps, duration)


class OrderFit:
    """Least-squares slope of ``log error`` vs ``log h`` over the asymptotic range.

    Points whose relative error lies in ``(ROUNDOFF_REL, PREASYMPTOTIC_REL)``
    are used (above the round-off floor, below the pre-asymptotic regime);
    fewer than three such points give ``order = NaN``.

    Attributes: ``order``, ``h_min``, ``h_max`` (range used), ``n_points``, ``used`` (mask).
    """

    def __init__(self, h, err, scale):
        h = np.asarray(h, float)
        err = np.asarray(err, float)
        rel = err / scale
        self.used = np.isfinite(rel) & (rel > ROUNDOFF_REL) & (rel < PREASYMPTOTIC_REL)
        self.n_points = int(self.used.sum())
        if self.n_points >= 3:
            slope, _ = np.polyfit(np.log(h[self.used]), np.log(err[self.used]), 1)
            self.order = float(slope)
            self.h_min, self.h_max = float(h[self.used].min()), float(h[self.used].max())
        else:
            self.order, self.h_min, self.h_max = float("nan"), float("nan"), float("nan")

    def passed(self, expected: float, tol: float = 0.1) -> bool:
        return bool(math.isfinite(self.order) and abs(self.order - expected) <= tol)


def fit_order(h, err, scale) -> OrderFit:
    """See :class:`OrderFit`."""
    return OrderFit(h, err, scale)


def cheapest(rows, targets, *, cost="wall_s", under_test=None):
    """Cheapest solver per target relative error.

    Parameters
    ----------
    rows : list of dict
        One scene's runs with keys solver, setting, error_rel, status, and ``cost``.
    targets : sequence of float
        Target relative errors (e.g. 1e-3 ... 1e-12).
    cost : str
        The key of the cost column.
    under_test : str or None
        The method under test (None: the registry's
        :data:`rk4h.references.registry.UNDER_TEST`).

    Returns
    -------
    list of dict
        Per target: ``target_error``, ``solver``, ``setting``, ``cost`` of the
        cheapest run reaching it (None if none does), and ``rk4_setting``,
        ``rk4_cost`` (the method under test's cheapest run reaching it, None
        if none; named after the thesis' RK4, the default).
    """
    if under_test is None:
        from rk4h.references.registry import UNDER_TEST as under_test

    out = []
    ok = [r for r in rows if r["status"] == "ok" and np.isfinite(r["error_rel"])]
    for target in targets:
        good = [r for r in ok if r["error_rel"] <= target]
        best = min(good, key=lambda r: r[cost], default=None)
        rk4 = min((r for r in good if r["solver"] == under_test), key=lambda r: r[cost], default=None)
        out.append({
            "target_error": target,
            "solver": best["solver"] if best else None,
            "setting": best["setting"] if best else None,
            "cost": best[cost] if best else None,
            "rk4_setting": rk4["setting"] if rk4 else None,
            "rk4_cost": rk4[cost] if rk4 else None,
        })
    return out
