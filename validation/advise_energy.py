"""The advisor over a horizon: the cheapest method that keeps the energy within a target.

    rk4h advise SCENE --periods N --energy-target E       (or --horizon T, in s)

``E`` bounds ``max_t |E(t) - E0| / E_motion`` over the whole horizon
(:mod:`rk4h.energy`); ``N`` counts periods of the slowest (linearized)
mode. How (all plain data, every number measured on this machine):

1. *Candidates*: every fixed-step tableau of the registry
   (:data:`rk4h.methods.METHODS`: RK4, the shipped tableaux, the geometric
   methods) and of the scene, on the compiled loops (:mod:`rk4h.fast`),
   and the adaptive references the scene lists.
2. *Calibration* on a short horizon ``T_c = min(T, CALIBRATION_PERIODS
   periods)``: a fixed-step method runs at ``h0 = T_fast / 8`` (capped at 0.9
   of its stability limit) and ``h0 / 2``; the energy error's growth exponent
   ``k`` (:func:`rk4h.validation.energy_time.growth_exponent`, clipped to
   ``[0, 1]``) extrapolates each to the horizon, ``e_T = e_c (T / T_c)^k``,
   and their ratio gives the energy error's order in ``h``, hence the step for
   ``SAFETY * E``. A reference climbs the ladder :data:`REFERENCE_RTOLS`
   (1e-8, 1e-10, 1e-12: cheapest first): at each rtol it runs over ``T_c``,
   its error and wall time extrapolate the same way (time linearly), and the
   first rtol whose extrapolation meets the target is confirmed over the full
   horizon; a rung that misses (extrapolated or confirmed) is listed with its
   numbers and the next, tighter one is tried.
3. *Confirmation* over the full horizon (no verdict without a run): a
   fixed-step candidate runs at its predicted step (states sampled 16 times
   per fastest period; it confirms at :data:`CONFIRM_MARGIN` of the target, the
   margin for a peak between samples); a miss shrinks the step by
   the error ratio (at least 10 %) for at most :data:`CONFIRM_ROUNDS` rounds.
   Candidates run cheapest prediction first; one predicted at over
   :data:`SKIP_FACTOR` times the calls of the best confirmed one, over
   :data:`MAX_CALLS` calls, or (a reference) over :data:`MAX_REFERENCE_S`
   seconds, is not run and is listed with that reason.
4. *Choice*: the confirmed candidate with the fewest RHS calls, with one
   sentence saying why in numbers.
"""
from __future__ import annotations

import math
import time
from dataclasses import asdict, dataclass, field
from types import SimpleNamespace

import numpy as np

from . import energy_time

__all__ = ["EnergyAdvice", "advise_energy", "horizon_seconds", "CALIBRATION_PERIODS", "SAFETY", "CONFIRM_ROUNDS",
           "SKIP_FACTOR", "MAX_CALLS", "MAX_REFERENCE_S", "CONFIRM_MARGIN", "REFERENCE_RTOLS"]

#: Periods of the slowest mode in the calibration runs.
CALIBRATION_PERIODS = 100.0
#: The step is chosen for this fraction of the energy target.
SAFETY = 0.5
#: A full-horizon run confirms when its sampled maximum is at most this
#: fraction of the target: the samples (:func:`rk4h.validation.energy_time.dense_samples`,
#: 16 per fastest period) may miss up to 8 % of an oscillating error's peak.
CONFIRM_MARGIN = 0.9
#: Full-horizon runs per fixed-step candidate at most.
CONFIRM_ROUNDS = 4
#: A candidate predicted to need this many times the calls of the best confirmed one is not run.
SKIP_FACTOR = 10.0
#: A fixed-step candidate predicted to need more RHS calls than this is not run.
MAX_CALLS = 2e9
#: A reference predicted to take longer than this (s) over the horizon is not run.
MAX_REFERENCE_S = 60.0
#: A reference's rtols, cheapest first; the first that meets the target over the full horizon is taken.
REFERENCE_RTOLS = (1e-8, 1e-10, 1e-12)


@dataclass
class EnergyAdvice:
    """What :func:`advise_energy` found (SI units; energy errors relative to E_motion)."""

    scene: str
    energy_target: float
    horizon_s: float
    periods: float
    method: str = ""
    setting: float = math.nan
    setting_name: str = ""
    confirmed_energy_error: float = math.nan
    growth_exponent: float = math.nan
    cost_rhs: float = math.nan
    cost_s: float = math.nan
    why: str = ""
    status: str = "ok"
    candidates: list = field(default_factory=list)
    not_listed: list = field(default_factory=list)

    def to_json(self) -> str:
        import json

        return json.dumps(asdict(self), allow_nan=True, default=float)

    def text(self) -> str:
        lines = [f"{self.scene}: energy within {self.energy_target:g} of E_motion over {self.periods:g} periods "
                 f"of the slowest mode ({self.horizon_s:.6g} s)"]
        if self.method:
            lines.append(f"  use {self.method} at {self.setting_name} = {self.setting:.6g}: confirmed max |E - E0| / "
                         f"E_motion = {self.confirmed_energy_error:.3g} over the full horizon, "
                         f"{self.cost_rhs:.4g} RHS calls, {self.cost_s:.3g} s")
        else:
            lines.append("  no candidate was confirmed to meet the target")
        lines.append(f"  why: {self.why}")
        for c in self.candidates:
            lines.append(f"  - {c['method']:<18} {c['setting_name']} = {c['setting']:<11.4g} energy error "
                         f"{c['energy_error']:.3g} (growth exponent {c['growth_exponent']:.2f}), "
                         f"{c['rhs']:.4g} calls, {c['wall_s']:.3g} s")
            for t in c.get("tried", ()):
                lines.append(f"      tried first {c['setting_name']} = {t['setting']:.3g}: {t['reason']}")
        for c in self.not_listed:
            lines.append(f"  - {c['method']:<18} not listed: {c['reason']}")
        return "\n".join(lines)


def horizon_seconds(model, periods=None, horizon=None) -> tuple[float, float]:
    """``(T, N)``: the horizon in s and in periods of the slowest mode, from either."""
    P = energy_time.slowest_period(model)
    if horizon is not None:
        return float(horizon), float(horizon) / P
    return float(periods) * P, float(periods)


def _energy_error(model, y) -> float:
    from rk4h.energy import relative_energy_error

    with np.errstate(all="ignore"):
        e = np.abs(relative_energy_error(model, y))
    return float("nan") if not np.all(np.isfinite(e)) else float(e.max())


def _fixed_run(model, y0, tab, h, T):
    res, wall = energy_time.long_run(model, y0, tab, h, T, energy_time.dense_samples(model, T))
    if not res.success:
        return math.nan, math.nan, int(res.nfev), wall, res.h
    from rk4h.energy import relative_energy_error

    with np.errstate(all="ignore"):
        e = relative_energy_error(model, res.y)
    k = energy_time.growth_exponent(res.t, e)[0]
    return float(np.max(np.abs(e))), k, int(res.nfev), wall, float(res.h)


def _extrapolate(e, k, T, Tc):
    kk = min(max(k, 0.0), 1.0) if math.isfinite(k) else 1.0
    return e * (T / Tc) ** kk


def _fixed_candidate(model, y0, tab, T, Tc, target, omega_max):
    """Calibrate and confirm one tableau: a listed row, or a not-listed row (key ``reason``)."""
    from rk4h.validation import trust

    h_stab = trust.stable_step(SimpleNamespace(tableau=tab), omega_max)  # wants a registry Method
    h0 = 2 * math.pi / omega_max / 8
    if math.isfinite(h_stab) and h_stab > 0:
        h0 = min(h0, 0.9 * h_stab)
    e1, k1, _, _, h1 = _fixed_run(model, y0, tab, h0, Tc)
    e2, k2, _, _, h2 = _fixed_run(model, y0, tab, h0 / 2, Tc)
    if not (math.isfinite(e1) and math.isfinite(e2) and e2 > 0 and e1 > e2):
        return None, {"method": tab.name, "reason": f"calibration over {Tc:.4g} s at h = {h0:.3g} and {h0 / 2:.3g} s "
                                                    f"gave energy errors {e1:.3g} and {e2:.3g}: no order in h"}
    p = math.log2(e1 / e2)
    eT = _extrapolate(e2, k2, T, Tc)
    h = h2 * (SAFETY * target / eT) ** (1.0 / p)
    if math.isfinite(h_stab) and h_stab > 0:
        h = min(h, 0.9 * h_stab)
    return {"method": tab.name, "h": h, "p": p, "k": k2,
            "predicted_rhs": tab.nfev_per_step * T / h}, None


def _confirm_fixed(model, y0, tab, cand, T, target):
    h = cand["h"]
    runs = []
    for _ in range(CONFIRM_ROUNDS):
        e, k, nfev, wall, h_run = _fixed_run(model, y0, tab, h, T)
        runs.append([h_run, e])
        if math.isfinite(e) and e <= CONFIRM_MARGIN * target:
            return {"method": tab.name, "setting": h_run, "setting_name": "h", "energy_error": e,
                    "growth_exponent": k, "rhs": float(nfev), "wall_s": wall, "runs": runs}, None
        ratio = (target * SAFETY / e) ** (1.0 / cand["p"]) if math.isfinite(e) and e > 0 else 0.5
        h = h_run * min(ratio, 0.9)
    return None, {"method": tab.name, "reason": f"{len(runs)} full-horizon runs missed the target: "
                                                + ", ".join(f"h = {a:.3g} s -> {b:.3g}" for a, b in runs)}


def _reference(model, y0, name, T, Tc, target, rtols=REFERENCE_RTOLS):
    """Climb ``rtols`` (cheapest first) for reference ``name``: the first rtol
    whose full-horizon run meets the target is a listed row (``tried``: the
    looser rtols and why each lost); if none does, a not-listed row whose
    reason names every rtol tried and why it lost."""
    from rk4h.references.registry import BUILTIN
    from rk4h.references.solvers import integrate

    def run(t_end, rtol):
        t = np.linspace(0.0, t_end, energy_time.dense_samples(model, t_end))
        r = integrate(name, model, y0, t, rtol)
        ok = getattr(r.status, "value", str(r.status)) == "ok"
        e = _energy_error(model, r.y) if ok else math.nan
        from rk4h.energy import relative_energy_error

        with np.errstate(all="ignore"):
            k = energy_time.growth_exponent(t, relative_energy_error(model, r.y))[0] if ok else math.nan
        from rk4h.validation import trust

        rhs = trust.rhs_calls({"nfev": r.nfev, "n_steps": r.n_steps, "taylor_order": r.taylor_order or 0})
        why = "" if ok else (getattr(r, "message", "") or getattr(r.status, "value", str(r.status)))
        return e, k, rhs, r.wall_s, why

    floor = getattr(BUILTIN.get(name), "rtol_floor", None) or 0.0
    tried = []
    for rtol in rtols:
        if rtol < floor:
            tried.append({"setting": rtol, "reason": f"below its rtol floor {floor:.3g}: not run"})
            continue
        e, k, rhs, wall, why = run(Tc, rtol)
        if not math.isfinite(e):
            tried.append({"setting": rtol, "reason": f"its calibration run over {Tc:.4g} s failed"
                                                     + (f" ({str(why).splitlines()[0][:120]})" if why else "")})
            continue
        eT, wT = _extrapolate(e, k, T, Tc), wall * T / Tc
        if eT > target:
            tried.append({"setting": rtol, "reason": f"energy error {e:.3g} over {Tc:.4g} s (growth exponent "
                                                     f"{k:.2f}) extrapolates to {eT:.3g} over the horizon, "
                                                     f"above the target"})
            continue
        if wT > MAX_REFERENCE_S:
            # a tighter rtol costs more: the ladder stops here
            tried.append({"setting": rtol, "reason": f"predicted {wT:.3g} s over the horizon (measured "
                                                     f"{wall:.3g} s over {Tc:.4g} s), over {MAX_REFERENCE_S:g} s: "
                                                     f"not run"})
            break
        e, k, rhs, wall, why = run(T, rtol)
        if not (math.isfinite(e) and e <= CONFIRM_MARGIN * target):
            tried.append({"setting": rtol, "reason": f"its full-horizon run gave {e:.3g}, above "
                                                     f"{CONFIRM_MARGIN:g} x the target"
                                                     + (f" ({str(why).splitlines()[0][:120]})" if why else "")})
            continue
        return {"method": name, "setting": rtol, "setting_name": "rtol", "energy_error": e,
                "growth_exponent": k, "rhs": float(rhs), "wall_s": wall,
                "runs": [[rtol, e]], "tried": tried}, None
    return None, {"method": name, "reason": "; ".join(f"rtol {t['setting']:g}: {t['reason']}" for t in tried),
                  "tried": tried}


def _tableaux(scene):
    from rk4h.references.registry import Kind
    from rk4h.methods import METHODS

    out = dict(METHODS)
    for name in scene.solvers:
        m = scene.method(name)
        if m.kind in (Kind.TABLEAU, Kind.PARTITIONED) and m.tableau is not None:
            out.setdefault(m.tableau.name, m.tableau)
    return list(out.values())


def advise_energy(scene, energy_target: float, *, periods=None, horizon=None) -> EnergyAdvice:
    """The cheapest method (RHS calls) whose full-horizon run keeps the energy within ``energy_target``.

    Parameters
    ----------
    scene : rk4h.validation.scenes.Scene
    energy_target : float
        Bound on ``max_t |E(t) - E0| / E_motion`` over the horizon, in (0, 1).
    periods, horizon : float
        The horizon in periods of the slowest mode, or in s (one of them).

    Returns
    -------
    EnergyAdvice
    """
    import rk4h.fast as fast
    from rk4h.references.registry import Kind
    from rk4h.validation.execute import problem

    model, y0 = problem(scene)
    T, N = horizon_seconds(model, periods, horizon)
    Tc = min(T, CALIBRATION_PERIODS * energy_time.slowest_period(model))
    omega_max = float(np.max(model.modes()[0]))
    adv = EnergyAdvice(scene.name, float(energy_target), T, N)
    preds, listed = [], []
    if fast.supports(model):
        for tab in _tableaux(scene):
            cand, miss = _fixed_candidate(model, y0, tab, T, Tc, energy_target, omega_max)
            (preds.append((cand["predicted_rhs"], tab, cand)) if cand else adv.not_listed.append(miss))
    else:
        adv.not_listed.append({"method": "fixed-step tableaux", "reason": "the model has no compiled force"})
    for pred, tab, cand in sorted(preds, key=lambda x: x[0]):
        best = min((c["rhs"] for c in listed), default=math.inf)
        if pred > MAX_CALLS or pred > SKIP_FACTOR * best:
            adv.not_listed.append({"method": tab.name, "reason": f"predicted {pred:.3g} RHS calls at h = "
                                                                 f"{cand['h']:.3g} s (energy order {cand['p']:.2f} "
                                                                 f"in h, growth exponent {cand['k']:.2f}): not run"})
            continue
        c, miss = _confirm_fixed(model, y0, tab, cand, T, energy_target)
        (listed.append(c) if c else adv.not_listed.append(miss))
    for name in scene.solvers:
        if scene.method(name).kind is Kind.REFERENCE:
            c, miss = _reference(model, y0, name, T, Tc, energy_target)
            (listed.append(c) if c else adv.not_listed.append(miss))
    listed.sort(key=lambda c: c["rhs"])
    adv.candidates = listed
    if not listed:
        adv.status = "no candidate"
        adv.why = "no candidate's full-horizon run met the target (see not_listed)"
        return adv
    b = listed[0]
    adv.method, adv.setting, adv.setting_name = b["method"], b["setting"], b["setting_name"]
    adv.confirmed_energy_error, adv.growth_exponent = b["energy_error"], b["growth_exponent"]
    adv.cost_rhs, adv.cost_s = b["rhs"], b["wall_s"]
    from rk4h.references.registry import UNDER_TEST

    rk4 = next((c for c in listed if c["method"] == UNDER_TEST), None)  # the thesis' method, for contrast
    base = (f"{b['method']} at {b['setting_name']} = {b['setting']:.3g} keeps the energy within "
            f"{b['energy_error']:.2g} over {N:g} periods (growth exponent {b['growth_exponent']:.2f}) with "
            f"{b['rhs']:.3g} RHS calls")
    if rk4 is not None and rk4 is not b:
        base += (f", where {UNDER_TEST.upper()} needs h = {rk4['setting']:.3g} s and {rk4['rhs']:.3g} calls "
                 f"({rk4['rhs'] / b['rhs']:.2g}x) to stay within {rk4['energy_error']:.2g} "
                 f"(growth exponent {rk4['growth_exponent']:.2f})")
    elif len(listed) > 1:
        o = listed[1]
        base += f", fewer than {o['method']} ({o['rhs']:.3g} calls)"
    adv.why = base + "."
    return adv


def run_cli(scene, args, t0) -> int:
    """``advise.py ... --energy-target E --periods N | --horizon T``: print the advice (exit 0)."""
    adv = advise_energy(scene, args.energy_target, periods=args.periods, horizon=args.horizon)
    print(adv.to_json() if args.json else adv.text() + f"\n  ({time.perf_counter() - t0:.1f} s)")
    return 0
