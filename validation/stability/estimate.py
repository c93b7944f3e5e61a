"""How many integration steps the stability study of a scene will take, estimated
before running it (for the runner's budget).

:func:`estimate_steps` adds up, study by study, the steps of every run the
study makes (fixed-step RK4/Euler steps, adaptive solvers' accepted steps,
one per one-step-map probe of the boundary bisection). It never runs an
integration, and no model is named here:

* frequencies (rad/s) of the scene's model come from its own
  ``model.frequency_range()``: for chains LAPACK's bisection on the
  symmetric tridiagonal ``M^-1/2 K M^-1/2`` (O(N) per eigenvalue), for
  other models a dense eigensolve of the linearization, which they refuse
  beyond 400 DOF (a ``ValueError``);
* the amplitude and singular studies run only for a model drawn as the
  four-spring mass (:func:`validation.stability.geometry.four_spring_params`);
* the stiffness and mass-ratio sweeps integrate the study's own 8- and 2-DOF
  chains, whatever the scene: their modes (an 8 x 8 problem, microseconds)
  give RK4's error at each step of the halving loop from the exact per-step
  factor ``R(i theta)`` of every mode, so the loop is replayed without
  integrating.

Fixed-step counts are therefore the studies' own step rules evaluated on the
exact frequencies (equal to the steps taken up to rounding of ``ceil``).
Adaptive solvers' counts are models, calibrated on the shipped scenes: per
run, heyoka takes ``max(1.2 P_fast, 3.5 P_exc) + 15`` steps, DOP853 ``max(1.0
P_fast, 7 P_exc) + 5`` and CVODE-BDF ``100 (1e-10 / rtol)^(1/5) P_exc + 100``,
with ``P_fast`` the periods of the fastest mode and ``P_exc`` those of the
fastest mode excited above 1e-3 of the amplitude; a tolerance ladder is
assumed to be walked down to ``target / 10`` (heyoka, DOP853) or ``target /
1000`` (CVODE-BDF, whose global error is larger than its rtol). Measured on
the shipped stability scenes (``--quick``): the totals are within 0.7x-1.0x
of the steps counted in a real run, which ``tests/test_hostile_references.py``
checks to a factor of 2 (the fixed-step part, which dominates, to 5 %); one
adaptive solver's count alone can be off by up to 4x (CVODE-BDF on the
mass-ratio sweep, heyoka on the stiff chain at half).
"""
from __future__ import annotations

import math

import numpy as np

from .boundary import MAX_BISECTIONS, growth_steps, theory_growth
from .geometry import four_spring_params
from .long_horizon import rk4_phase_lag_per_step
from .params import pick, validate_params

__all__ = ["estimate_steps", "frequency_range"]

_FMAX_LOG = math.log(np.finfo(float).max)
_ADAPTIVE_CAP = 5_000_000  # references.solvers' default max_steps
_EXCITED = 1e-3


def frequency_range(model) -> tuple[float, float]:
    """``(omega_min, omega_max)`` (rad/s): the slowest non-zero and the fastest
    natural angular frequency of ``model``'s linearization, from
    ``model.frequency_range()`` (see the module docstring)."""
    lo, hi = model.frequency_range()
    return float(lo), float(hi)


# -- adaptive solvers -------------------------------------------------------------------------
def _heyoka(p_fast, p_exc):
    return max(1.2 * p_fast, 3.5 * p_exc) + 15


def _dop853(p_fast, p_exc):
    return max(1.0 * p_fast, 7.0 * p_exc) + 5


def _bdf(p_exc, rtol):
    return 100.0 * (1e-10 / rtol) ** 0.2 * p_exc + 100


def _rungs(ladder, target, depth):
    out = []
    for rtol in ladder:
        out.append(rtol)
        if rtol <= target * depth:
            break
    return out


# -- the cost sweeps (study-own small chains) ---------------------------------------------------
def _modal_amplitudes(model, y0):
    """Displacement amplitude (m) of each mode, the mode shapes, frequencies."""
    omega, phi = model.modes()
    n = model.n_dof
    M = model.mass
    eta, deta = phi.T @ (M * y0[:n]), phi.T @ (M * y0[n:])
    with np.errstate(divide="ignore", invalid="ignore"):
        amp = np.where(omega > 0, np.hypot(omega * eta, deta) / np.where(omega > 0, omega, 1.0), np.abs(eta))
    return omega, phi, amp


def _rk4_error(omega, phi, amp, t_end, h, scale):
    """Bound on ``max_i |q_i(t_end) - q_i^exact| / scale`` after ``ceil(t_end/h)``
    RK4 steps: each mode's amplitude times ``|R(i theta)^n - e^{i n theta}|``."""
    n = math.ceil(t_end / h * (1 - 1e-12))
    hu = t_end / n
    th = omega * hu
    t2 = th * th
    log_abs = 0.5 * np.log1p(-(t2 * t2 * t2) * (8.0 - t2) / 576.0)
    r = np.exp(np.minimum(n * log_abs, 700.0))
    ph = n * rk4_phase_lag_per_step(th)
    dev = np.sqrt((r * np.cos(ph) - 1.0) ** 2 + (r * np.sin(ph)) ** 2)
    err = np.max(np.abs(phi) @ (amp * dev)) / scale
    return n, float(err)


def _sweep(model, y0, target, ladder, skip_dop853, max_rk4_steps=5e7):
    """Steps per solver of :func:`validation.stability.stiffness.cost_at_target`."""
    omega, phi, amp = _modal_amplitudes(model, y0)
    pos = omega > 0
    w_lo, w_hi = float(omega[pos][0]), float(omega[-1])
    t_end = 2 * math.pi / w_lo
    scale = float(np.max(np.abs(y0[: model.n_dof])))
    excited = pos & (amp * np.max(np.abs(phi), axis=0) >= _EXCITED * scale)
    w_exc = float(omega[excited][-1]) if excited.any() else w_lo
    p_fast, p_exc = t_end * w_hi / (2 * math.pi), t_end * w_exc / (2 * math.pi)
    out = {"rk4": 0.0}
    h = 0.99 * 2 * math.sqrt(2) / w_hi
    while t_end / h <= max_rk4_steps:
        n, err = _rk4_error(omega, phi, amp, t_end, h, scale)
        out["rk4"] += n
        if err <= target:
            break
        h /= 2
    out["dop853"] = 0.0 if skip_dop853 else sum(
        min(_dop853(p_fast, p_exc), _ADAPTIVE_CAP) for _ in _rungs(ladder, target, 0.1))
    out["cvode-bdf"] = sum(min(_bdf(p_exc, r), _ADAPTIVE_CAP) for r in _rungs(ladder, target, 1e-3))
    out["heyoka"] = sum(min(_heyoka(p_fast, p_exc), _ADAPTIVE_CAP) for _ in _rungs(ladder, target, 0.1))
    return out


# -- the studies ------------------------------------------------------------------------------
def _boundary(model, p, quick):
    if not model.linear:
        return {}
    probes = 3 * min(2 + math.ceil(math.log2(1.0 / p["bisection_rtol"])) + 1, MAX_BISECTIONS + 12)
    euler = sum(growth_steps("euler", th) for th in (1e-3, 0.1, 0.5, 1.0))
    fig = {meth: sum(growth_steps(meth, th) for th in p["growth_theta"])
           for meth in ("rk4", "euler", "symplectic-euler")}
    g_rk4 = float(theory_growth("rk4", 1.2 * 2 * math.sqrt(2)))
    blow_rk4 = min(3000, math.ceil(_FMAX_LOG / math.log(g_rk4)))
    blow_euler = min(6000, math.ceil(_FMAX_LOG / math.log(math.sqrt(2.0))))
    return {"probe": float(probes), "rk4": float(fig["rk4"] + blow_rk4),
            "euler": float(euler + fig["euler"] + blow_euler), "symplectic-euler": float(fig["symplectic-euler"])}


def _long_horizon(model, p, quick, w_lo, w_hi):
    if not model.linear:
        return {}
    periods = pick(p, "long_periods", quick)
    drift = 2000.0 * len(p["drift_theta"])
    n_long = math.ceil(periods * 2 * math.pi / w_lo / (p["long_theta"] / w_hi))
    ref = min(periods, pick(p, "reference_periods", quick))
    return {"rk4": drift + n_long,
            "heyoka": min(_heyoka(periods * w_hi / w_lo, periods * w_hi / w_lo), _ADAPTIVE_CAP),
            "cvode-bdf": min(_bdf(ref * w_hi / w_lo, 1e-10), _ADAPTIVE_CAP)}


def _roundoff(model, p, quick, w_lo, w_hi):
    if not model.linear:
        return {}
    t_end = 2 * math.pi / w_lo
    return {"rk4": float(sum(math.ceil(t_end / (th / w_hi)) for th in pick(p, "roundoff_theta", quick)))}


def _sweeps(xs, build, p, quick, what):
    from .stiffness import RTOL_LADDER, RTOL_LADDER_QUICK

    ladder = RTOL_LADDER_QUICK if quick else RTOL_LADDER
    total: dict = {}
    for x in xs:
        model, y0 = build(x)
        w_lo, w_hi = frequency_range(model)
        big = w_hi / w_lo > (1e3 if quick else 1e4)
        for k, v in _sweep(model, y0, p["target_error"], ladder, big and what == "ratio").items():
            total[k] = total.get(k, 0.0) + v
    return total


def _stiffness(model, p, quick):
    from .stiffness import stiff_chain

    return _sweeps(pick(p, "stiffness_ratios", quick), stiff_chain, p, quick, "ratio")


def _mass_ratio(model, p, quick):
    from .stiffness import mass_ratio_chain

    return _sweeps(pick(p, "mu", quick), mass_ratio_chain, p, quick, "mu")


def _large_n(model, p, quick):
    Ns = [int(v) for v in pick(p, "n_values", quick)]
    # rk4_cost: one warm-up step and 3 repeats of 500; rk4_peak_bytes: 3 steps; CVODE-BDF
    # (band) over one period of the lowest mode at rtol 1e-6, only that mode excited
    return {"rk4": float(sum(1 + 3 * 500 + 3 for _ in Ns)), "cvode-bdf": float(len(Ns) * _bdf(1.0, 1e-6))}


def _amplitude(model, p, quick):
    if four_spring_params(model) is None:  # the study is skipped
        return {}
    return {"rk4": float(len(p["amplitudes"]) * 2 * round(5.0 * 400))}


def _singular(model, p, quick):
    if four_spring_params(model) is None:  # the study is skipped
        return {}
    return {"rk4": 400.0 + 1.0}


def estimate_steps(scene, quick: bool = False, *, detail: bool = False):
    """Estimated total integration steps of the stability study of ``scene``.

    Parameters
    ----------
    scene : validation.scenes.Scene
        A scene with a ``[stability]`` table (none: 0).
    quick : bool
        Estimate the ``--quick`` settings (the ``*_quick`` parameters, the
        short tolerance ladder).
    detail : bool
        Return ``{study: {solver: steps}}`` instead of the total.

    Returns
    -------
    float or dict
        Steps: fixed-step steps, adaptive solvers' steps and boundary probes
        (one-step maps) added up; see the module docstring for the model and
        its accuracy (totals within a factor of 2 on the shipped scenes). Cost per step
        differs by solver (an RK4 step on the compiled path is ~30 ns x DOF, a
        DOP853 step ~50 us): use ``detail=True`` to weigh them.
    """
    if not scene.stability:
        return {} if detail else 0.0
    p = validate_params(dict(scene.stability))
    model = scene.build_model()
    needs_w = any(s in p["studies"] for s in ("long_horizon", "roundoff")) and model.linear
    w_lo, w_hi = frequency_range(model) if needs_w else (math.nan, math.nan)
    parts = {}
    for study in p["studies"]:
        if study == "long_horizon":
            parts[study] = _long_horizon(model, p, quick, w_lo, w_hi)
        elif study == "roundoff":
            parts[study] = _roundoff(model, p, quick, w_lo, w_hi)
        else:
            parts[study] = {"boundary": _boundary, "stiffness": _stiffness, "mass_ratio": _mass_ratio,
                            "large_n": _large_n, "amplitude": _amplitude, "singular": _singular}[study](
                model, p, quick)
    if detail:
        return parts
    return float(sum(v for d in parts.values() for v in d.values()))
