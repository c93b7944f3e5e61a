"""Numbers from trajectories: errors, energy drift, observed order, the RK4
energy theory, the cheapest solver per target error.

Metrics see arrays only (states ``y`` of shape (2n, m) on output times ``t``),
never solvers. Conventions (DESIGN.md):

* ``error_max`` -- the largest absolute difference from the reference over
  output times and state components (m, m/s, rad, rad/s as the model's
  coordinates are); ``error_final`` -- the same at the last output time only.
  ``error_rel`` divides by ``scale = max |y_ref|`` over the whole reference
  trajectory, so targets like 1e-6 mean "six correct digits of the largest
  state component" (Hairer & Wanner's scd idea, Bari IVP test set).
* ``energy_drift_max`` -- ``max_t |E(t) - E0| / |E0|``.
* A run that did not reach every output time has NaN errors (its status says why).
"""
from __future__ import annotations

import math

import numpy as np

__all__ = ["error_max", "error_final", "relative_energy_error", "energy_drift_max",
           "drift_per_time", "rk4_energy_factor", "rk4_energy_loss", "rk4_energy_log_factor", "rk4_drift_theory",
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
    """``(E(t) - E0) / |E0|`` along the trajectory (signed, dimensionless)."""
    with np.errstate(over="ignore", invalid="ignore"):  # a blown-up run's energy is inf
        E = np.asarray(model.energy(np.asarray(y, float)), float)
        return (E - E[0]) / abs(E[0])


def energy_drift_max(model, y) -> float:
    """``max_t |E(t) - E0| / |E0|``; NaN if the run has NaN."""
    with np.errstate(over="ignore", invalid="ignore"):
        r = np.abs(relative_energy_error(model, y))
    # NaN (a state that did not get there) wins over inf (an overflowed energy).
    return float("nan") if np.isnan(r).any() else float(np.max(r))


def drift_per_time(model, t, y) -> float:
    """Energy drift per unit time (1/s): ``(E(T) - E0) / (|E0| (T - t0))``."""
    with np.errstate(over="ignore", invalid="ignore"):
        r = relative_energy_error(model, y)
    return float(r[-1] / (t[-1] - t[0])) if not np.isnan(r[-1]) else float("nan")


def rk4_energy_factor(theta):
    """Per-step energy factor of classical RK4 on a harmonic mode,
    ``|R(i theta)|^2 = 1 - theta^6/72 + theta^8/576`` with ``theta = omega h``.

    For ``x'' = -omega^2 x`` in the complex variable ``z = omega x + i x'``,
    ``z' = -i omega z`` and one RK4 step multiplies ``z`` by ``R(-i theta)``,
    ``R(w) = 1 + w + w^2/2 + w^3/6 + w^4/24``; so the mode energy
    ``|z|^2 / 2`` is multiplied by exactly this factor every step.
    """
    theta = np.asarray(theta, float)
    return 1.0 - theta**6 / 72.0 + theta**8 / 576.0


def rk4_energy_loss(theta):
    """``1 - |R(i theta)|^2 = theta^6/72 - theta^8/576`` (dimensionless, per
    step), evaluated as ``theta^6 (8 - theta^2) / 576``: no cancellation,
    exact in sign at the RK4 boundary ``theta^2 = 8`` (negative, a gain,
    beyond it)."""
    theta = np.asarray(theta, float)
    t2 = theta * theta
    return t2 * t2 * t2 * (8.0 - t2) / 576.0


def rk4_energy_log_factor(theta):
    """``log |R(i theta)|^2 = log(1 - theta^6/72 + theta^8/576)`` (dimensionless,
    per step), without cancellation.

    Forming ``1 - theta^6/72 + theta^8/576`` first rounds away the small part:
    at ``theta = 0.05`` (``theta^6/72 = 2.2e-10``) ``log`` of the rounded
    factor is wrong by 2.5e-7 relative. Here the small part is formed on its
    own, as ``-theta^6 (8 - theta^2) / 576`` (exact in sign at the RK4
    boundary ``theta^2 = 8``), and passed to ``log1p``: a few ulp relative
    for every ``theta``.

    Parameters
    ----------
    theta : float or array_like
        ``omega h`` (rad) of the mode.

    Returns
    -------
    ndarray or float
        Negative for ``0 < |theta| < 2 sqrt 2`` (RK4 loses energy), positive beyond.
    """
    return np.log1p(-rk4_energy_loss(theta))


def modal_energy_fractions(omega, eta0, deta0) -> np.ndarray:
    """Share of the total energy in each mode: ``E_j = (deta_j^2 + omega_j^2 eta_j^2)/2``
    for mass-normalised modes (the energy of a linear model separates by mode)."""
    e = 0.5 * (np.asarray(deta0) ** 2 + (np.asarray(omega) * np.asarray(eta0)) ** 2)
    return e / e.sum()


def rk4_drift_theory(omega, eta0, deta0, h, n_steps, duration) -> float:
    """RK4's relative energy change per unit time after ``n_steps`` steps of ``h``:
    ``sum_j f_j (g(omega_j h)^n - 1) / duration`` with ``f_j`` the modal energy
    fractions and ``g`` :func:`rk4_energy_factor` (its log from
    :func:`rk4_energy_log_factor`, without cancellation). Exact for linear
    models (RK4 commutes with the modal decomposition), up to round-off."""
    f = modal_energy_fractions(omega, eta0, deta0)
    # g^n - 1 without cancellation: expm1(n log g), log g by log1p (rk4_energy_log_factor)
    change = np.sum(f * np.expm1(n_steps * rk4_energy_log_factor(np.asarray(omega) * h)))
    return float(change / duration)


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


def cheapest(rows, targets, *, cost="wall_s"):
    """Cheapest solver per target relative error.

    Parameters
    ----------
    rows : list of dict
        One scene's runs with keys solver, setting, error_rel, status, and ``cost``.
    targets : sequence of float
        Target relative errors (e.g. 1e-3 ... 1e-12).

    Returns
    -------
    list of dict
        Per target: ``target_error``, ``solver``, ``setting``, ``cost`` of the
        cheapest run reaching it (None if none does), and ``rk4_setting``,
        ``rk4_cost`` (RK4's cheapest run reaching it, None if none).
    """
    out = []
    ok = [r for r in rows if r["status"] == "ok" and np.isfinite(r["error_rel"])]
    for target in targets:
        good = [r for r in ok if r["error_rel"] <= target]
        best = min(good, key=lambda r: r[cost], default=None)
        rk4 = min((r for r in good if r["solver"] == "rk4"), key=lambda r: r[cost], default=None)
        out.append({
            "target_error": target,
            "solver": best["solver"] if best else None,
            "setting": best["setting"] if best else None,
            "cost": best[cost] if best else None,
            "rk4_setting": rk4["setting"] if rk4 else None,
            "rk4_cost": rk4[cost] if rk4 else None,
        })
    return out
