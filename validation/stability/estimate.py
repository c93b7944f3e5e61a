"""How many integration steps the stability study of a scene will take, estimated
before running it (for the runner's budget).

:func:`unit_steps` estimates one work unit (:func:`rk4h.validation.stability.units`);
:func:`estimate_steps` is the sum over the scene's units, so a budget can be
summed over a plan. Each adds up the steps of every run the unit makes
(fixed-step RK4/Euler steps, adaptive solvers' accepted steps,
one per one-step-map probe of the boundary bisection). It never runs an
integration, and no model is named here:

* frequencies (rad/s) of the scene's model come from its own
  ``model.frequency_range()``: for chains LAPACK's bisection on the
  symmetric tridiagonal ``M^-1/2 K M^-1/2`` (O(N) per eigenvalue), for
  other models a dense eigensolve of the linearization, which they refuse
  beyond 400 DOF (a ``ValueError``);
* the amplitude and singular studies run only for a model drawn as the
  four-spring mass (:func:`rk4h.validation.stability.geometry.four_spring_params`);
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
assumed to need ``target / 10`` (heyoka, DOP853) or ``target / 1000``
(CVODE-BDF, whose global error is larger than its rtol), and the guided
search (:func:`rk4h.validation.stability.stiffness.ladder_search`) to run the
two loosest rungs, that rung and its looser neighbour; a skipped solver
(:func:`rk4h.validation.stability.stiffness.skip_reason`) counts 0. Measured on
the shipped stability scenes (``--quick``): the totals are within 0.7x-1.0x
of the steps counted in a real run, which ``tests/test_hostile_references.py``
checks to a factor of 2 (the fixed-step part, which dominates, to 5 %); one
adaptive solver's count alone can be off by up to 4x (CVODE-BDF on the
mass-ratio sweep, heyoka on the stiff chain at half).
"""
from __future__ import annotations

import math

import numpy as np

from rk4h.references.registry import BUILTIN

from .boundary import MAX_BISECTIONS, growth_steps, theory_growth
from .geometry import four_spring_params
from ..metrics import energy_log_factor, phase_lag
from .boundary import theory_boundary
from ._common import frequency_range, heyoka_steps
from .params import pick, validate_params
from .studies import COST_REFERENCES, GROWTH_ALWAYS, LONG_REFERENCES, context_method, parse_unit, units

__all__ = ["estimate_steps", "unit_steps", "frequency_range", "heyoka_steps"]

_FMAX_LOG = math.log(np.finfo(float).max)
_ADAPTIVE_CAP = 5_000_000  # rk4h.references.solvers' default max_steps
_EXCITED = 1e-3


def _dop853(p_fast, p_exc):
    return max(1.0 * p_fast, 7.0 * p_exc) + 5


def _bdf(p_exc, rtol):
    return 100.0 * (1e-10 / rtol) ** 0.2 * p_exc + 100


def _reference_steps(name, p_fast, p_exc, rtol):
    """Calibrated steps of reference ``name`` at ``rtol``, by its registry
    capabilities: a Taylor method (heyoka's fit), a stiff solver (BDF's), else
    an explicit adaptive Runge-Kutta method (DOP853's)."""
    m = BUILTIN[name]
    if m.taylor:
        return heyoka_steps(p_fast, p_exc)
    if m.stiff:
        return _bdf(p_exc, rtol)
    return _dop853(p_fast, p_exc)


def _search_depth(name):
    """How far below the target the guided rtol search of ``name`` reaches
    (a stiff solver's error lags its rtol most)."""
    return 1e-3 if BUILTIN[name].stiff else 0.1


def _rungs(ladder, target, depth):
    """The rungs the guided search runs: the two loosest, the one meeting
    ``target * depth`` and its looser neighbour."""
    m = next((i for i, rtol in enumerate(ladder) if rtol <= target * depth), len(ladder) - 1)
    return [ladder[i] for i in sorted({0, min(1, m), max(m - 1, 0), m})]


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


def _fixed_error(tab, omega, phi, amp, t_end, h, scale):
    """Bound on ``max_i |q_i(t_end) - q_i^exact| / scale`` after ``ceil(t_end/h)``
    steps of the tableau ``tab``: each mode's amplitude times ``|R(i theta)^n -
    e^{i n theta}|``."""
    n = math.ceil(t_end / h * (1 - 1e-12))
    hu = t_end / n
    th = omega * hu
    log_abs = 0.5 * energy_log_factor(tab, th)
    r = np.exp(np.minimum(n * log_abs, 700.0))
    ph = n * phase_lag(tab, th)
    dev = np.sqrt((r * np.cos(ph) - 1.0) ** 2 + (r * np.sin(ph)) ** 2)
    err = np.max(np.abs(phi) @ (amp * dev)) / scale
    return n, float(err)


def _sweep(model, y0, target, ladder, skipped, meth, tab, max_rk4_steps=5e7):
    """Steps per solver of :func:`rk4h.validation.stability.stiffness.cost_at_target`."""
    omega, phi, amp = _modal_amplitudes(model, y0)
    pos = omega > 0
    w_lo, w_hi = float(omega[pos][0]), float(omega[-1])
    t_end = 2 * math.pi / w_lo
    scale = float(np.max(np.abs(y0[: model.n_dof])))
    excited = pos & (amp * np.max(np.abs(phi), axis=0) >= _EXCITED * scale)
    w_exc = float(omega[excited][-1]) if excited.any() else w_lo
    p_fast, p_exc = t_end * w_hi / (2 * math.pi), t_end * w_exc / (2 * math.pi)
    out = {meth: 0.0}
    h_stab = theory_boundary(tab, w_hi)
    h = 0.99 * h_stab if h_stab > 0 else 0.5 / w_hi
    while t_end / h <= max_rk4_steps:
        n, err = _fixed_error(tab, omega, phi, amp, t_end, h, scale)
        out[meth] += n
        if err <= target:
            break
        h /= 2
    for ref in COST_REFERENCES:
        out[ref] = 0.0 if ref in skipped else sum(min(_reference_steps(ref, p_fast, p_exc, r), _ADAPTIVE_CAP)
                                                  for r in _rungs(ladder, target, _search_depth(ref)))
    return out


def _cost_point(p, quick, study, x):
    from .stiffness import RTOL_LADDER, RTOL_LADDER_QUICK, excited_ratio, mass_ratio_chain, skip_reason, stiff_chain

    what, build = {"stiffness": ("ratio", stiff_chain), "mass_ratio": ("mu", mass_ratio_chain)}[study]
    model, y0 = build(x)
    ratio, exc = excited_ratio(model, y0)
    skipped = {sv for sv in COST_REFERENCES if skip_reason(sv, what, ratio, exc, quick)}
    return _sweep(model, y0, p["target_error"], RTOL_LADDER_QUICK if quick else RTOL_LADDER, skipped,
                  p["method"], p["_tab"])


# -- the units --------------------------------------------------------------------------------
def _boundary(model, p, quick, part):
    if not model.linear:
        return {}
    probes = 3 * min(2 + math.ceil(math.log2(1.0 / p["bisection_rtol"])) + 1, MAX_BISECTIONS + 12)
    runs = {("euler", float(th)) for th in (1e-3, 0.1, 0.5, 1.0)}  # one run per (method, theta)
    meths = tuple(dict.fromkeys((p["method"],) + GROWTH_ALWAYS))
    tabs = {m: (p["_tab"] if m == p["method"] else m) for m in meths}
    runs |= {(meth, float(th)) for meth in meths for th in p["growth_theta"]}
    steps = {meth: float(sum(growth_steps(tabs[m], th) for m, th in runs if m == meth)) for meth in meths}
    b = theory_boundary(p["_tab"], 1.0)
    if b > 0:  # the blow-up run 20 % past the boundary
        g = float(theory_growth(p["_tab"], 1.2 * b))
        steps[p["method"]] += min(3000, math.ceil(_FMAX_LOG / math.log(g)))
    steps["euler"] += min(6000, math.ceil(_FMAX_LOG / math.log(math.sqrt(2.0))))
    return {"probe": float(probes), **steps}


def _long_horizon(model, p, quick, part):
    if not model.linear or part not in ("drift", "method") + tuple(dict(LONG_REFERENCES)):
        return {}
    w_lo, w_hi = frequency_range(model)
    periods = pick(p, "long_periods", quick)
    if part == "drift":
        return {p["method"]: 2000.0 * len(p["drift_theta"])}
    if part == "method":
        return {p["method"]: float(math.ceil(periods * 2 * math.pi / w_lo / (p["long_theta"] / w_hi)))}
    if BUILTIN[part].taylor:  # the whole horizon, under its own step cap (studies._long_reference)
        from .studies import long_reference_max_steps

        return {part: float(min(heyoka_steps(periods * w_hi / w_lo, periods * w_hi / w_lo),
                                long_reference_max_steps(model, periods)))}
    p_ref = min(periods, pick(p, "reference_periods", quick)) * w_hi / w_lo
    return {part: min(_reference_steps(part, p_ref, p_ref, dict(LONG_REFERENCES)[part]), _ADAPTIVE_CAP)}


def _roundoff(model, p, quick, part):
    if not model.linear:
        return {}
    w_lo, w_hi = frequency_range(model)
    t_end = 2 * math.pi / w_lo
    return {p["method"]: float(sum(math.ceil(t_end / (th / w_hi)) for th in pick(p, "roundoff_theta", quick)))}


def _large_n(model, p, quick, part):
    from .studies import LARGE_N_TIMING, banded_reference

    n_steps, repeats = LARGE_N_TIMING[bool(quick)]
    Ns = [int(v) for v in pick(p, "n_values", quick)]
    # step_cost: one warm-up step and the timed repeats; peak_bytes: 3 steps; CVODE-BDF
    # (band) over one period of the lowest mode at rtol 1e-6, only that mode excited
    return {p["method"]: float(sum(1 + repeats * n_steps + 3 for _ in Ns)),
            banded_reference(): float(len(Ns) * _bdf(1.0, 1e-6))}


def _amplitude(model, p, quick, part):
    if four_spring_params(model) is None:  # the study is skipped
        return {}
    return {p["method"]: float(len(p["amplitudes"]) * 2 * round(5.0 * 400))}


def _singular(model, p, quick, part):
    if four_spring_params(model) is None:  # the study is skipped
        return {}
    return {p["method"]: 400.0 + 1.0}


_UNITS = {"boundary": _boundary, "long_horizon": _long_horizon, "roundoff": _roundoff, "large_n": _large_n,
          "amplitude": _amplitude, "singular": _singular}


def _unit_detail(model, p, quick, unit) -> dict:
    study, part, params = parse_unit(unit)
    if study in ("stiffness", "mass_ratio"):
        if part == "closed_form":
            return {}
        if not params:
            raise ValueError(f"`unit` {unit!r}: expected {study}:<name>=<number>")
        return _cost_point(p, quick, study, next(iter(params.values())))
    return _UNITS[study](model, p, quick, part)


def _params(scene) -> dict:
    """The scene's validated ``[stability]`` table, with ``_tab``: the tableau
    of ``stability.method``."""
    p = validate_params(dict(scene.stability or {}))
    p["method"], p["_tab"] = context_method(scene, p)
    return p


def unit_steps(scene, unit: str, quick: bool = False, *, detail: bool = False):
    """Estimated integration steps of one unit of ``scene``'s stability study
    (fixed-step steps, adaptive solvers' steps, one-step-map probes added up;
    ``detail=True``: ``{solver: steps}``). No integration; see the module
    docstring for the model and its accuracy."""
    p = _params(scene)
    study = parse_unit(unit)[0]
    if study not in p["studies"]:
        raise ValueError(f"`unit` {unit!r}: scene {scene.name!r} has no {study} study")
    d = _unit_detail(scene.build_model(), p, bool(quick), unit)
    return d if detail else float(sum(d.values()))


def estimate_steps(scene, quick: bool = False, *, detail: bool = False):
    """Estimated total integration steps of the stability study of ``scene``:
    the sum of :func:`unit_steps` over :func:`rk4h.validation.stability.units`.

    Parameters
    ----------
    scene : rk4h.validation.scenes.Scene
        A scene with a ``[stability]`` table (none: 0).
    quick : bool
        Estimate the ``--quick`` settings (the ``*_quick`` parameters, the
        short tolerance ladder).
    detail : bool
        Return ``{study: {solver: steps}}`` (summed over the study's units)
        instead of the total.

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
    p = _params(scene)
    model = scene.build_model()
    parts: dict = {study: {} for study in p["studies"]}
    for unit in units(scene, quick):
        study = parse_unit(unit)[0]
        for k, v in _unit_detail(model, p, bool(quick), unit).items():
            parts[study][k] = parts[study].get(k, 0.0) + v
    if detail:
        return parts
    return float(sum(v for d in parts.values() for v in d.values()))
