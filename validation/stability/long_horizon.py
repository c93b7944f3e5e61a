"""Long horizons: a tableau method's energy drift and phase error per step
(RK4 below; any classical tableau through its stability function,
:func:`rk4h.validation.metrics.energy_loss` and :func:`rk4h.validation.metrics.phase_lag`),
the references' drift on the same run, and the round-off floor.

In each normal mode (``theta = omega h``) one RK4 step multiplies the complex
mode amplitude ``z = omega eta - i eta'`` by ``R(i theta)`` (see
:mod:`.boundary`). Hence, per step and exactly,

* relative energy loss ``1 - |R(i theta)|^2 = theta^6/72 - theta^8/576``
  (leading order ``theta^6/72``; RK4 is dissipative on oscillators);
* phase lag ``theta - arg R(i theta) = theta^5/120 - O(theta^7)``, with the
  continuous argument (no ``2 pi`` jump at ``theta = sqrt 6``) and, at small
  ``theta``, a series free of cancellation (:func:`rk4_phase_lag_per_step`).

The leading-order terms alone are 3.1 % (energy) and 8.8 % (phase) off the
exact per-step values at ``theta = 0.5``; the comparison is therefore made
against the exact expressions, with the leading-order value kept in the note.

Round-off: with ``n = T/h`` steps the truncation error falls like ``h^4`` while
the accumulated rounding grows like ``n eps`` (systematic) to ``sqrt(n) eps``
(random); the total error vs ``h`` has a minimum, the best step.
"""
from __future__ import annotations

import math

import numpy as np

from rk4h.references.exact import modal_solution

from rk4h.energy import energy_scale
from rk4h.methods import RK4

from ..metrics import phase_lag, rk4_energy_loss

from ._common import error_rel, integrate_fixed, mode_amplitudes

__all__ = ["rk4_energy_loss_per_step", "rk4_phase_lag_per_step", "rk4_phase_arg", "measure_drift_and_phase",
           "roundoff_sweep", "reference_drift"]


_FIT_FLOOR = 1e-6
_MIN_FIT_POINTS = 10


def _R(theta):
    z = 1j * np.asarray(theta, dtype=float)
    return 1 + z + z**2 / 2 + z**3 / 6 + z**4 / 24


def rk4_energy_loss_per_step(theta, leading=False):
    """Relative energy lost per RK4 step by a mode, ``1 - |R(i theta)|^2 =
    theta^6/72 - theta^8/576`` (dimensionless), evaluated as
    ``theta^6 (8 - theta^2) / 576`` (no cancellation; negative, a gain, beyond
    the stability boundary ``theta = 2 sqrt 2``).

    Parameters
    ----------
    theta : float or array_like
        ``omega h`` (rad) of the mode.
    leading : bool
        Return the leading term ``theta^6/72`` instead.
    """
    th = np.asarray(theta, dtype=float)
    return th**6 / 72 if leading else rk4_energy_loss(th)


def rk4_phase_arg(theta):
    """The continuous argument (rad) of ``R(i theta)``, ``R`` the RK4 stability
    polynomial, starting from 0 at ``theta = 0``.

    ``Im R(i theta) = theta (1 - theta^2/6)`` vanishes only at ``theta = 0``
    and ``sqrt 6``; so for ``theta > 0`` the argument lies in ``(0, 2 pi)``:
    ``atan2(Im, Re)`` taken modulo ``2 pi``. ``np.angle`` alone jumps by
    ``-2 pi`` at ``theta = sqrt 6 = 2.449``. Odd in ``theta``.
    """
    th = np.asarray(theta, dtype=float)
    a = np.abs(th)
    R = _R(a)
    arg = np.mod(np.arctan2(R.imag, R.real), 2 * np.pi)
    return np.sign(th) * arg


def rk4_phase_lag_per_step(theta, leading=False):
    """Phase lag (rad) per RK4 step of a mode, ``theta - arg R(i theta)``:
    :func:`rk4h.validation.metrics.phase_lag` of classical RK4 (continuous
    argument, no ``2 pi`` jump at ``theta = sqrt 6``; negative, a phase lead,
    beyond about 2.3; a few ulp relative for every ``theta``).

    Parameters
    ----------
    theta : float or array_like
        ``omega h`` (rad) of the mode.
    leading : bool
        Return the leading term ``theta^5/120`` instead.
    """
    th = np.asarray(theta, dtype=float)
    return th**5 / 120 if leading else phase_lag(RK4, th)


def measure_drift_and_phase(model, y0, h, n_steps, *, method="rk4", record_every=1):
    """Integrate ``n_steps`` steps of ``method`` (a classical tableau or its
    name; RK4 by default) and measure, per mode, the energy loss and phase lag
    per step.

    Both are least-squares slopes over the recorded steps: of ``-2 log|z_k|``
    (energy, returned as ``-expm1(2 slope)``) and of the unwrapped
    ``arg(z_k exp(-i omega t_k))`` (phase lag, sign flipped), so a few rounding
    errors do not decide the result.

    A mode is fitted only over the steps where its amplitude is above
    ``_FIT_FLOOR`` (1e-6) of its initial value: RK4 damps a fast mode by
    ``theta^6/72`` per step, and once it reaches round-off its amplitude and
    phase carry no information (NaN when fewer than ``_MIN_FIT_POINTS`` remain).

    Returns
    -------
    dict
        ``theta``, ``energy_loss``, ``phase_lag`` (arrays over modes, ascending
        omega), ``steps_fitted`` (last step used per mode), ``t``, ``rel_energy_error`` (total energy, for a figure),
        ``result`` (the solver result), ``path`` ("fast"/"solve").
    """
    res, path = integrate_fixed(model, (0.0, n_steps * h), y0, n_steps=n_steps, method=method,
                                record_every=record_every)
    omega, z = mode_amplitudes(model, res.y)
    k = np.rint(res.t / res.h)
    logabs = np.log(np.abs(z))
    drift = np.unwrap(np.angle(z * np.exp(-1j * omega[:, None] * res.t[None, :]) / z[:, :1]), axis=1)
    # RK4 damps every mode (|R(i theta)| < 1): over a long run a fast mode can
    # decay to the round-off floor of the state, where its log-amplitude and
    # phase are noise. Fit each mode only while its amplitude is above
    # _FIT_FLOOR of its start (far above round-off).
    keep = logabs - logabs[:, :1] > np.log(_FIT_FLOOR)
    s_abs = np.full(omega.shape, np.nan)
    s_ph = np.full(omega.shape, np.nan)
    n_fit = keep.sum(axis=1)
    for j in range(omega.shape[0]):
        if n_fit[j] >= _MIN_FIT_POINTS:
            s_abs[j] = np.polyfit(k[keep[j]], logabs[j, keep[j]], 1)[0]
            s_ph[j] = np.polyfit(k[keep[j]], drift[j, keep[j]], 1)[0]
    k_fit = np.array([k[keep[j]].max() if n_fit[j] else 0.0 for j in range(omega.shape[0])])
    E = model.energy(res.y)
    E_motion = energy_scale(model, E[0])
    return {"theta": omega * res.h, "energy_loss": -np.expm1(2 * s_abs), "phase_lag": -s_ph,
            "steps_fitted": k_fit,
            "t": res.t, "rel_energy_error": np.abs(E - E[0]) / E_motion, "result": res, "path": path}


def roundoff_sweep(model, y0, t_end, hs, method="rk4"):
    """Error of ``method`` (RK4 by default) at ``t_end`` against the modal solution for each step in ``hs``.

    Error: :func:`._common.error_rel` (``max_i |q_i - q_i^exact| / max_i
    |q_i(0)|``) at ``t_end``. Returns (h_used, errors, paths).
    """
    exact = modal_solution(model, y0)
    ref = exact(np.array([t_end]))
    scale = float(np.max(np.abs(y0[: model.n_dof]))) or 1.0
    h_used, errs, paths = [], [], []
    for h in hs:
        res, path = integrate_fixed(model, (0.0, t_end), y0, h=h, t_eval=[t_end], method=method)
        h_used.append(res.h)
        errs.append(error_rel(model, res.y[:, -1:], ref, scale) if res.success else math.nan)
        paths.append(path)
    return np.array(h_used), np.array(errs), paths


def reference_drift(solver, model, y0, t_end, setting, n_out=200, max_steps=None):
    """Run a reference solver through ``rk4h.references.solvers.integrate`` and
    return ``(run, t, rel_energy_error)``; ``max_steps`` (default: the
    solver interface's) caps its steps."""
    from rk4h.references.solvers import integrate

    t_eval = np.linspace(0.0, t_end, n_out)
    kw = {} if max_steps is None else {"max_steps": int(max_steps)}
    with np.errstate(all="ignore"):
        run = integrate(solver, model, y0, t_eval, setting, **kw)
        E = model.energy(run.y)
    return run, run.t, np.abs(E - E[0]) / energy_scale(model, E[0])
