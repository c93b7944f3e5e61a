"""The stability study as independent work units, and their merge.

A scene's ``[stability]`` table names studies; each study is one or more
*units* (:func:`units`), string keys such as ``"boundary"``,
``"stiffness:ratio=1e+03"`` or ``"mass_ratio:mu=1e-06"``. :func:`run_unit`
computes one unit -- rows, findings and plot descriptions, all plain data, no
file written, no plotting library imported -- in any process or on any
machine; :func:`assemble` merges the units' results of a scene (one cost plot
per sweep, the sweep's finding) without integrating anything.

Units, and why a study is split where it is (CPU seconds measured on the
shipped scenes, 2-core machine):

``boundary``, ``roundoff``, ``large_n``, ``amplitude``, ``singular``
    one unit each (each under ~7 s in full mode);
``long_horizon:drift``, ``long_horizon:method``, ``long_horizon:heyoka``, ``long_horizon:cvode-bdf``
    the 2000-step drift and phase fits, the long run of ``stability.method``, and each
    reference's energy drift: separate runs of a few seconds each, so a pool
    runs them side by side (a nonlinear model: one unit ``long_horizon``, skipped);
``stiffness:ratio=X``, ``mass_ratio:closed_form``, ``mass_ratio:mu=X``
    one unit per point of the cost sweeps (the dearest point was ~60 s).

Reference choice on the long horizon (``long_horizon:*``): heyoka's Taylor
integrator covers the whole horizon (``long_periods``: 1e6 slow periods of the
2-DOF case, 7.9e6 Taylor steps at tol 1e-12, about 2.6-3.6 s), while
CVODE-BDF runs only ``reference_periods`` (default 200, quick 20): at about
8 ms of CPU per period (rtol 1e-10) the former 1e4-period run cost 78 s CPU
(69-117 s wall), a third of the whole study, for one informative number;
200 periods cost under 2 s and still show BDF's drift per period beside
RK4's and heyoka's.

Timings: a row's ``wall_s`` (and ``measured_timed``, for the large-N time
exponents) is the only non-reproducible content; every other column is the
same bit for bit on a rerun (:data:`rk4h.validation.stability.COLUMNS`).
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np

from rk4h.references.registry import BOUNDARY_ALWAYS, BUILTIN, GROWTH_ALWAYS, UNDER_TEST, long_references, with_role

from . import boundary as B
from . import geometry as G
from . import large_n as LN
from . import long_horizon as LH
from . import mass_ratio as MR
from . import stiffness as ST
from ..metrics import energy_loss, leading_terms, phase_lag
from ._common import (FREQUENCY_RATIO, PARAM_COLUMNS, SWEEP_NAMES, StudyResult, cost_at_point, frequency_range,
                      heyoka_steps, integrate_fixed, row, stiffest_index)
from .params import STUDIES, pick, validate_params

__all__ = ["context_method", "units", "run_unit", "run_unit_in", "assemble", "failed_unit", "parse_unit", "unit_key", "Context",
           "context", "REL_BOUNDARY", "REL_DRIFT", "COST_SOLVERS"]

REL_BOUNDARY = 0.005  # issue 6: boundaries within 0.5 % of theory
REL_DRIFT = 0.02      # issue 6: drift and phase rates within 2 % where theta <= 0.5
#: The references of the cost sweeps (the registry's methods with role
#: ``"cost"``); the scene's ``stability.method`` runs first.
COST_REFERENCES = with_role("cost")
COST_SOLVERS = (UNDER_TEST,) + COST_REFERENCES  # with the default method
#: Long-horizon references: (solver, rtol), from the registry's ``long_rtol``.
LONG_REFERENCES = long_references()
#: heyoka's step cap on the long horizon: this many times the calibrated
#: estimate (:mod:`.estimate`), at least LONG_MIN_STEPS (the references'
#: default cap, which stopped the former 1e6-period run at 63 %), at most
#: LONG_MAX_STEPS.
LONG_STEP_MARGIN = 3.0
LONG_MIN_STEPS = 5_000_000
LONG_MAX_STEPS = 100_000_000
#: ``method``: the long run of the scene's ``stability.method``.
_LONG_PARTS = ("drift", "method") + tuple(name for name, _ in LONG_REFERENCES)


@dataclass
class Context:
    scene: str
    model: object
    y0: np.ndarray
    params: dict
    quick: bool
    #: the scene's own tableau methods (name -> rk4core Tableau), studied beside the built-ins
    tableaux: dict = field(default_factory=dict)
    #: ``stability.method``: the classical tableau the studies other than boundary integrate
    method: str = UNDER_TEST
    tab: object = None

    def __post_init__(self):
        if self.tab is None:
            from rk4h.methods import get_method

            self.tab = self.tableaux.get(self.method) or get_method(self.method)


def context(scene, quick: bool) -> Context:
    """The validated parameters, model and initial state of ``scene``'s study."""
    params = validate_params(dict(scene.stability or {}))
    own = getattr(scene, "registry", {})
    tableaux = {n: m.tableau for n, m in own.items() if m.tableau is not None and n in scene.solvers}
    method, tab = context_method(scene, params)
    return Context(scene.name, scene.build_model(), np.asarray(scene.y0(), float), params, bool(quick), tableaux,
                   method, tab)


def context_method(scene, params) -> tuple:
    """``(name, tableau)`` of the scene's ``stability.method`` (validated by
    :mod:`rk4h.validation.scenes`; :data:`UNDER_TEST` when absent)."""
    from rk4h.methods import get_method

    method = params.get("method") or UNDER_TEST
    own = getattr(scene, "registry", {})
    return method, (own[method].tableau if method in own else get_method(method))


# -- unit keys --------------------------------------------------------------------------------
def _num(x: float) -> str:
    """Shortest ``%.{d}e`` form of ``x`` that reads back as ``x`` (``1e+03``, ``2.5e-06``)."""
    x = float(x)
    for d in range(17):
        s = f"{x:.{d}e}"
        if float(s) == x:
            return s
    return repr(x)


def unit_key(study: str, part: str | None = None, **param) -> str:
    """``study``, ``study:part`` or ``study:name=value``."""
    if param:
        ((k, v),) = param.items()
        return f"{study}:{k}={_num(v)}"
    return study if part is None else f"{study}:{part}"


def parse_unit(unit: str):
    """``(study, part, params)`` of a unit key: ``"stiffness:ratio=1e+03"`` ->
    ``("stiffness", "ratio=1e+03", {"ratio": 1000.0})``; ValueError naming the
    unit if it is malformed."""
    if not isinstance(unit, str):
        raise ValueError(f"`unit` must be a string, got {unit!r}")
    study, _, part = unit.partition(":")
    if study not in STUDIES:
        raise ValueError(f"`unit` {unit!r}: unknown study {study!r} (known: {', '.join(STUDIES)})")
    params = {}
    if "=" in part:
        k, _, v = part.partition("=")
        if k not in PARAM_COLUMNS:
            raise ValueError(f"`unit` {unit!r}: unknown parameter {k!r}")
        try:
            params[k] = float(v)
        except ValueError:
            raise ValueError(f"`unit` {unit!r}: {v!r} is not a number") from None
    return study, (part or None), params


def _dedup(xs):
    out = []
    for x in xs:
        if float(x) not in out:
            out.append(float(x))
    return out


def _study_units(study, model, p, quick):
    if study == "long_horizon":
        return [unit_key(study, part) for part in _LONG_PARTS] if model.linear else [study]
    if study == "stiffness":
        return [unit_key(study, ratio=x) for x in _dedup(pick(p, "stiffness_ratios", quick))]
    if study == "mass_ratio":
        return [unit_key(study, "closed_form")] + [unit_key(study, mu=x) for x in _dedup(pick(p, "mu", quick))]
    return [study]


def units(scene, quick: bool) -> list[str]:
    """The independent work units of ``scene``'s stability studies, in the
    order of its ``studies`` list (and of each sweep's values). Needs the
    model's linearity only: no eigensolve, no integration."""
    p = validate_params(dict(scene.stability or {}))
    model = scene.build_model() if any(s in p["studies"] for s in ("long_horizon",)) else None
    out = []
    for study in p["studies"]:
        out += _study_units(study, model, p, bool(quick))
    return out


# -- skips and failures -----------------------------------------------------------------------
def _needs_linear(ctx, study):
    if ctx.model.linear:
        return None
    r = StudyResult()
    r.rows.append(row(ctx.scene, study, "-", study, math.nan, status="skipped",
                      note=f"{study} needs a linear model; {ctx.model.name} is nonlinear"))
    return r


def failed_unit(scene, unit: str, exc: BaseException | str) -> StudyResult:
    """The result of a unit that raised (``exc``: the exception or its text):
    one row with status ``failed`` (passed False), the unit's parameter in its
    column and the error in the note. ``scene``: a scene or its name."""
    scene_name = getattr(scene, "name", scene)
    try:
        study, part, params = parse_unit(unit)
    except ValueError:
        study, part, params = str(unit).partition(":")[0], None, {}
    solver = part if part in dict(LONG_REFERENCES) else "-"
    text = exc if isinstance(exc, str) else f"{type(exc).__name__}: {exc}"
    return StudyResult(rows=[row(scene_name, study, solver, study, math.nan, passed=False, status="failed",
                                 note=f"unit {unit}: {text}", **params)])


# -- boundary ---------------------------------------------------------------------------------
def _boundary(ctx: Context, part) -> StudyResult:
    if (skip := _needs_linear(ctx, "boundary")) is not None:
        return skip
    res, s, m = StudyResult(), ctx.scene, ctx.model
    modes = m.modes()
    w = float(modes[0][-1])
    methods = {name: name for name in BOUNDARY_ALWAYS}
    methods.update(ctx.tableaux)  # the scene's own tableaux: boundary from the tableau, against runs
    methods.setdefault(ctx.method, ctx.tab)  # and the method the other studies integrate
    for meth, tab in methods.items():
        h_star, probes = B.largest_stable_step(m, tab, ctx.params["bisection_rtol"], w)
        h_th = B.theory_boundary(tab, w)
        # no stable step in theory: the bisection's tolerance 1 + STABLE_TOL sets what it finds
        expect = h_th if h_th > 0 else B.tolerance_boundary(tab, w)
        ok = abs(h_star / expect - 1) <= REL_BOUNDARY if expect > 0 else h_star == 0.0
        res.rows.append(row(s, "boundary", meth, "largest_stable_h_s", h_star, expect, ok, theta=h_star * w, note=(
            f"omega_max = {w:.6g} rad/s; bisection on rho(S(h)) <= 1 + {B.STABLE_TOL:g}, rtol "
            f"{ctx.params['bisection_rtol']:g}, {probes} probes"
            + ("" if h_th > 0 else "; |R(i theta)| > 1 for every theta > 0: expected is where the growth "
               f"passes 1 + {B.STABLE_TOL:g}" + (" (below omega h = 1e-5: no stable h)" if expect == 0 else "")))))
        if h_th > 0:
            res.findings.append(f"{s}: {meth} largest stable step {h_star:.6g} s = {h_star * w:.5f}/omega_max "
                                f"(theory {h_th * w:.5f}/omega_max)")
    growth: dict = {}  # one run per (method, theta), shared by the rows and the figure

    def g(meth, th):
        if (meth, th) not in growth:
            growth[meth, th] = B.measured_growth(m, methods.get(meth, meth), th, modes=modes)[0]
        return growth[meth, th]

    for th in (1e-3, 0.1, 0.5, 1.0):
        gm, g_th = g("euler", th), math.sqrt(1 + th * th)
        res.rows.append(row(s, "boundary", "euler", "growth_per_step", gm, g_th,
                            abs((gm - 1) / (g_th - 1) - 1) <= 1e-6, theta=th,
                            note="fastest mode, integrated run; passed: (g-1) within 1e-6 relative"))
    thetas = [float(t) for t in ctx.params["growth_theta"]]
    meths = tuple(dict.fromkeys((ctx.method,) + GROWTH_ALWAYS))
    tabs = {meth: (ctx.tab if meth == ctx.method else meth) for meth in meths}
    line = np.linspace(1e-3, max(thetas) * 1.05, 400)
    res.plots.append({"kind": "growth", "scene": s, "study": "boundary", "name": "growth", "data": {
        "theta_line": line, "theory": {meth: np.asarray(B.theory_growth(tabs[meth], line), float) for meth in meths},
        "theta": np.array(thetas), "measured": {meth: np.array([g(meth, th) for th in thetas]) for meth in meths},
        "boundary": {meth: b for meth in meths if (b := B.theory_boundary(tabs[meth], 1.0)) > 0}}})
    # deliberate blow-ups: rows with status unstable and the time (the studied
    # method 20 % past its boundary, when it has one; explicit Euler at omega h = 1)
    blow = [(ctx.method, 1.2 * B.theory_boundary(ctx.tab, w), 3000)] if B.theory_boundary(ctx.tab, w) > 0 else []
    for meth, h, n in blow + [("euler", 1.0 / w, 6000)]:
        r = B.blowup_run(m, tabs.get(meth, meth), h, n)
        blew = r.status == -1 and r.t_fail is not None and math.isfinite(r.t_fail)
        gth = float(B.theory_growth(tabs.get(meth, meth), h * w))
        res.rows.append(row(s, "boundary", meth, "blowup_time_s", r.t_fail if blew else math.nan, math.nan, blew,
                            status="unstable" if blew else "ok", theta=h * w,
                            note=f"{r.message}; theory growth {gth:.4g} per step"))
    return res


# -- long horizon -----------------------------------------------------------------------------
def _omegas(model):
    omega = model.modes()[0]
    return float(omega[-1]), float(omega[omega > 0][0])


def _long(ctx: Context, part) -> StudyResult:
    if (skip := _needs_linear(ctx, "long_horizon")) is not None:
        return skip
    if part not in _LONG_PARTS:
        raise ValueError(f"`unit` long_horizon:{part}: the parts are {', '.join(_LONG_PARTS)}")
    return {"drift": _long_drift, "method": _long_method}.get(part, _long_reference)(ctx, part)


def _long_drift(ctx, part):
    res, s, m, p = StudyResult(), ctx.scene, ctx.model, ctx.params
    w_hi, _ = _omegas(m)
    pts = {"theta": [], "energy_loss": [], "phase_lag": []}
    meth, tab = ctx.method, ctx.tab
    (a_e, p_e), (a_p, p_p) = leading_terms(tab)
    for th in p["drift_theta"]:
        d = LH.measure_drift_and_phase(m, ctx.y0, th / w_hi, 2000, method=tab)
        th_m = float(d["theta"][-1])
        e_th = float(energy_loss(tab, th_m))
        p_th = float(phase_lag(tab, th_m))
        checked = th_m <= 0.5 and e_th > 0 and p_th != 0
        e, ph = float(d["energy_loss"][-1]), float(d["phase_lag"][-1])
        res.rows.append(row(s, "long_horizon", meth, "energy_loss_per_step", e, e_th,
                            abs(e / e_th - 1) <= REL_DRIFT if checked else None, theta=th_m,
                            note=f"2000 steps; theory 1-|R(i theta)|^2 from the tableau; leading order "
                                 f"{a_e:.6g} theta^{p_e} = {a_e * th_m**p_e:.6g}"))
        res.rows.append(row(s, "long_horizon", meth, "phase_lag_per_step", ph, p_th,
                            abs(ph / p_th - 1) <= REL_DRIFT if checked else None, theta=th_m,
                            note=f"2000 steps; theory theta - arg R(i theta) from the tableau; leading order "
                                 f"{a_p:.6g} theta^{p_p} = {a_p * th_m**p_p:.6g}"))
        pts["theta"].append(th_m)
        pts["energy_loss"].append(e)
        pts["phase_lag"].append(ph)
    data = {k: np.array(v, float) for k, v in pts.items()}
    th = data["theta"][np.isfinite(data["theta"]) & (data["theta"] > 0)]
    line = np.logspace(np.log10(float(th.min()) / 2 if th.size else 1e-2), np.log10(0.6), 100)
    data.update(method=meth, theta_line=line, loss_theory=np.asarray(energy_loss(tab, line), float),
                lag_theory=np.asarray(phase_lag(tab, line), float), loss_leading=(a_e, p_e), lag_leading=(a_p, p_p))
    res.plots.append({"kind": "drift_points", "scene": s, "study": "long_horizon", "name": "drift", "part": True,
                      "data": data})
    return res


def _long_method(ctx, part):
    from rk4h import fast

    res, s, m, p = StudyResult(), ctx.scene, ctx.model, ctx.params
    meth, tab = ctx.method, ctx.tab
    w_hi, w_lo = _omegas(m)
    periods = pick(p, "long_periods", ctx.quick)
    h = p["long_theta"] / w_hi
    n = int(math.ceil(periods * 2 * math.pi / w_lo / h))
    if n > 2_000_000 and not fast.supports(m):
        res.rows.append(row(s, "long_horizon", meth, "long_run", math.nan, status="skipped", periods=periods,
                            note=f"{n} steps and no compiled path for {m.name} (rk4h.fast.supports)"))
        return res
    t0 = time.perf_counter()
    d = LH.measure_drift_and_phase(m, ctx.y0, h, n, method=tab, record_every=max(1, n // 20000))
    wall = time.perf_counter() - t0
    for j, th in enumerate(d["theta"]):
        th = float(th)
        e_th, p_th = float(energy_loss(tab, th)), float(phase_lag(tab, th))
        e, ph = float(d["energy_loss"][j]), float(d["phase_lag"][j])
        res.rows.append(row(s, "long_horizon", meth, "long_energy_loss_per_step", e, e_th,
                            abs(e / e_th - 1) <= REL_DRIFT if e_th > 0 else None, mode=j + 1, theta=th,
                            periods=periods,
                            note=f"{n} steps; fitted over steps 0..{d['steps_fitted'][j]:.0f} (while the mode is "
                                 f"above 1e-6 of its start)"))
        res.rows.append(row(s, "long_horizon", meth, "long_phase_lag_per_step", ph, p_th,
                            abs(ph / p_th - 1) <= REL_DRIFT if p_th != 0 else None, mode=j + 1, theta=th,
                            periods=periods, note=f"{n} steps; fitted over steps 0..{d['steps_fitted'][j]:.0f}"))
    err = np.asarray(d["rel_energy_error"], float)
    res.rows.append(row(s, "long_horizon", meth, "energy_drift_per_period", err[-1] / periods, periods=periods,
                        theta=p["long_theta"], wall_s=wall,
                        note=f"|E_end-E0|/E_motion = {err[-1]:.3g} after {n} steps"))
    (a_e, p_e), _ = leading_terms(tab)
    lead = f" ({a_e:.4g} theta^{p_e} per step per mode" + (", lost" if a_e > 0 else ", gained") + ")"
    res.findings.append(f"{s}: {meth} at omega_max h = {p['long_theta']:g} over {periods:g} periods: "
                        f"relative energy change {err[-1]:.3g}{lead}")
    res.plots.append({"kind": "energy_series", "scene": s, "study": "long_horizon", "name": "long_energy", "part": True,
                      "data": {"label": f"{meth} (omega_max h = {p['long_theta']:g}, {periods:g} periods)",
                               "t": np.asarray(d["t"], float), "err": err}})
    return res


def long_reference_max_steps(model, periods: float) -> int:
    """heyoka's step cap on the long horizon: :data:`LONG_STEP_MARGIN` times the
    calibrated estimate, at least the references' default, at most
    :data:`LONG_MAX_STEPS`."""

    w_lo, w_hi = frequency_range(model)
    p_fast = periods * w_hi / w_lo
    return int(min(max(LONG_MIN_STEPS, math.ceil(LONG_STEP_MARGIN * heyoka_steps(p_fast, p_fast))),
                   LONG_MAX_STEPS))


def _long_reference(ctx, solver):
    res, s, m, p = StudyResult(), ctx.scene, ctx.model, ctx.params
    _, w_lo = _omegas(m)
    rtol = dict(LONG_REFERENCES)[solver]
    periods = pick(p, "long_periods", ctx.quick)
    taylor = BUILTIN[solver].taylor  # a Taylor method's long steps cover the whole horizon
    per = periods if taylor else min(periods, pick(p, "reference_periods", ctx.quick))
    cap = long_reference_max_steps(m, per) if taylor else None
    run, t, err = LH.reference_drift(solver, m, ctx.y0, per * 2 * math.pi / w_lo, rtol, max_steps=cap)
    ok = run.ok
    res.rows.append(row(s, "long_horizon", solver, "energy_drift_per_period", err[-1] / per if ok else math.nan,
                        status="ok" if ok else run.status.value, periods=per, wall_s=run.wall_s, note=(
                            f"rtol {rtol:g}, {per:g} periods ({ctx.method}: {periods:g}), {run.n_steps} steps, "
                            f"|E_end-E0|/E_motion "
                            f"= {err[-1]:.3g}; {run.message}")))
    if ok:
        res.plots.append({"kind": "energy_series", "scene": s, "study": "long_horizon", "name": "long_energy",
                          "part": True, "data": {"label": f"{solver} (rtol {rtol:g}, {per:g} periods)",
                                                 "t": np.asarray(t, float), "err": np.asarray(err, float)}})
    return res


def _assemble_long(scene, quick, res: StudyResult) -> None:
    parts = [pl for pl in res.plots if pl.get("part") and pl["kind"] in ("drift_points", "energy_series")]
    res.plots[:] = [pl for pl in res.plots if not any(pl is q for q in parts)]
    pts = [pl["data"] for pl in parts if pl["kind"] == "drift_points"]
    if pts:
        d = pts[0]
        res.plots.append({"kind": "drift", "scene": scene, "study": "long_horizon", "name": "drift", "data": d})
    series = [pl["data"] for pl in parts if pl["kind"] == "energy_series"]
    if series:
        res.plots.append({"kind": "long_energy", "scene": scene, "study": "long_horizon", "name": "long_energy",
                          "data": {"series": {sd["label"]: {"t": sd["t"], "err": sd["err"]} for sd in series}}})


# -- round-off --------------------------------------------------------------------------------
def _roundoff(ctx: Context, part) -> StudyResult:
    if (skip := _needs_linear(ctx, "roundoff")) is not None:
        return skip
    res, s, m, meth = StudyResult(), ctx.scene, ctx.model, ctx.method
    w_hi, w_lo = _omegas(m)
    thetas = pick(ctx.params, "roundoff_theta", ctx.quick)
    t_end = 2 * math.pi / w_lo
    h, err, paths = LH.roundoff_sweep(m, ctx.y0, t_end, [th / w_hi for th in thetas], method=ctx.tab)
    for hi, ei in zip(h, err):
        res.rows.append(row(s, "roundoff", meth, "error_at_t_end", ei, theta=hi * w_hi,
                            note=f"h = {hi:.6g} s; one slow period; max |q - q_exact| / max |q0|"))
    i = int(np.nanargmin(err))
    turned = bool(i < len(err) - 1 and err[-1] > err[i])
    # The turn-up is expected only where the sweep reaches the round-off level:
    # the truncation error, extrapolated from the largest step with omega_max h
    # <= 0.1 at the method's order, below sqrt(n) eps at the smallest step.
    th = h * w_hi
    j = int(np.argmax(np.where((th <= 0.1) & np.isfinite(err), h, -np.inf)))
    trunc = float(err[j] * (h[-1] / h[j]) ** ctx.tab.order)
    level = math.sqrt(t_end / h[-1]) * float(np.finfo(float).eps)
    expect = trunc < level
    res.rows.append(row(s, "roundoff", meth, "best_h_s", h[i], math.nan, None, theta=h[i] * w_hi, note=(
        f"error {err[i]:.3g} at omega_max h = {h[i] * w_hi:.3g}; one slow period; paths {sorted(set(paths))}")))
    res.rows.append(row(s, "roundoff", meth, "roundoff_floor_error", err[i], math.nan, None, theta=h[i] * w_hi))
    res.rows.append(row(s, "roundoff", meth, "error_turns_up_below_best_h", float(turned), 1.0 if expect else 0.0,
                        turned if expect else None, note=(
                            f"error at smallest h ({h[-1]:.3g} s): {err[-1]:.3g}; order-{ctx.tab.order} truncation "
                            f"extrapolated there {trunc:.3g} " + ("<" if expect else ">=") + f" round-off level "
                            f"sqrt(n) eps {level:.3g}" + ("" if expect else ": no turn-up expected in this sweep"))))
    res.plots.append({"kind": "roundoff", "scene": s, "study": "roundoff", "name": "roundoff",
                      "data": {"h": np.asarray(h, float), "error": np.asarray(err, float), "h_best": float(h[i]),
                               "omega_max": w_hi, "method": meth,
                               "order": ctx.tab.order}})
    res.findings.append(f"{s}: {meth} best step {h[i]:.3g} s (omega_max h = {h[i] * w_hi:.3g}) gives error "
                        f"{err[i]:.3g}; smaller steps lose to round-off" if turned else
                        f"{s}: {meth} error still falling at the smallest h probed ({h[-1]:.3g} s)")
    return res


# -- cost sweeps ------------------------------------------------------------------------------
_SWEEPS = {"stiffness": ("ratio", ST.stiff_chain, "spring ratio k_mid/k"),
           "mass_ratio": ("mu", ST.mass_ratio_chain, "mass ratio mu = m2/m1")}


def _cost_point(ctx: Context, study: str, x: float) -> StudyResult:
    what, build, _ = _SWEEPS[study]
    res, s = StudyResult(), ctx.scene
    target = ctx.params["target_error"]
    model, y0 = build(x)
    ratio, exc = ST.excited_ratio(model, y0)
    recs = ST.cost_at_target(model, y0, target, (ctx.method,) + COST_REFERENCES, fixed={ctx.method: ctx.tab},
                             skip=lambda sv: ST.skip_reason(sv, what, ratio, exc, ctx.quick),
                             rtol_ladder=ST.RTOL_LADDER_QUICK if ctx.quick else ST.RTOL_LADDER)
    for r in recs:
        res.rows.append(row(s, study, r["solver"], "nfev_at_error", r["nfev"], math.nan,
                            r["status"] == "ok" if r["status"] != "skipped" else None, status=r["status"],
                            target_error=target, wall_s=r["wall_s"], stiffness_ratio=r["stiffness_ratio"],
                            **{what: x}, note=(f"setting {r['setting']:.3g}; "
                                f"error {r['error']:.3g}; steps {r['n_steps']}; {r['note']}")))
    rk = recs[0]
    h_stab = B.theory_boundary(ctx.tab, rk["omega_max"])
    if rk["status"] == "ok" and what == "ratio" and h_stab > 0:
        res.rows.append(row(s, study, ctx.method, "h_at_target_over_h_stab", rk["setting"] / h_stab, math.nan, None,
                            target_error=target, **{what: x},
                            note="1 (x0.99) = step forced by stability, not accuracy"))
    ok = [r["status"] == "ok" for r in recs]
    res.plots.append({"kind": "cost_point", "scene": s, "study": study, "name": f"cost_{what}", "part": True, "data": {
        "what": what, "x": float(x), "stiffness_ratio": float(ratio), "target_error": float(target),
        "solvers": [r["solver"] for r in recs],
        "nfev": np.array([r["nfev"] if k else math.nan for r, k in zip(recs, ok)], float),
        "wall_s": np.array([r["wall_s"] if k else math.nan for r, k in zip(recs, ok)], float),
        "status": [r["status"] for r in recs]}})
    return res


def _assemble_cost(scene, study, res: StudyResult) -> None:
    what, _, xlabel = _SWEEPS[study]
    parts = [pl for pl in res.plots if pl.get("part") and pl["kind"] == "cost_point"
             and pl["data"]["what"] == what]
    res.plots[:] = [pl for pl in res.plots if not any(pl is q for q in parts)]
    if not parts:
        return
    solvers = list(dict.fromkeys(sv for pl in parts for sv in pl["data"]["solvers"]))

    def column(key, sv):
        return np.array([pl["data"][key][pl["data"]["solvers"].index(sv)] if sv in pl["data"]["solvers"]
                         else math.nan for pl in parts], float)

    def status(sv):
        return [pl["data"]["status"][pl["data"]["solvers"].index(sv)] if sv in pl["data"]["solvers"] else "not run"
                for pl in parts]

    data = {"what": what, "xlabel": xlabel, "x": np.array([pl["data"]["x"] for pl in parts], float),
            "stiffness_ratio": np.array([pl["data"]["stiffness_ratio"] for pl in parts], float),
            "target_error": float(parts[0]["data"]["target_error"]),
            "nfev": {sv: column("nfev", sv) for sv in solvers}, "wall_s": {sv: column("wall_s", sv) for sv in solvers},
            "status": {sv: status(sv) for sv in solvers}}
    res.plots.append({"kind": "cost", "scene": scene, "study": study, "name": f"cost_{what}", "data": data})
    k = stiffest_index(data["x"], data["stiffness_ratio"])  # the point the caption and limits line quote too
    pl = parts[k]["data"]
    res.findings.append(f"{scene}: RHS evaluations to reach {data['target_error']:g} at {FREQUENCY_RATIO} "
                        f"{pl['stiffness_ratio']:.3g} ({SWEEP_NAMES[what]} = {pl['x']:g}): "
                        + ", ".join(cost_at_point(sv, data["nfev"][sv][k], data["status"][sv][k]) for sv in solvers)
                        + "".join(f" ({sv}: {BUILTIN[sv].cost_unit.text})" for sv in solvers
                                  if sv in BUILTIN and BUILTIN[sv].taylor))


def _sweep_unit(ctx: Context, study, part, params) -> StudyResult:
    what = _SWEEPS[study][0]
    if study == "mass_ratio" and part == "closed_form":
        return _closed_form(ctx)
    if what not in params:
        raise ValueError(f"`unit` {study}:{part}: expected {study}:{what}=<number>"
                         + (" or mass_ratio:closed_form" if study == "mass_ratio" else ""))
    return _cost_point(ctx, study, params[what])


def _closed_form(ctx: Context) -> StudyResult:
    res, s = StudyResult(), ctx.scene
    eps = np.finfo(float).eps
    for mu in (1e-6, 1e-3, 1.0, 1e3, 1e6):
        cf, dec, eig = MR.closed_form_sq(1.0, 1.0, mu), MR.omega_sq_decimal(1.0, 1.0, mu), MR.omega_sq_eig(1.0, 1.0, mu)
        for i, name in enumerate(("low", "high")):
            res.rows.append(row(s, "mass_ratio", "closed-form", f"omega_{name}^2_vs_50_digits", cf[i], dec[i],
                                abs(cf[i] / dec[i] - 1) <= 4 * eps, mu=mu, note="eq. 2.31, relative error <= 4 eps"))
            tol = 8 * eps * eig[1] / eig[0]  # eigenvalue error bound eps ||M^-1/2 K M^-1/2|| / lam
            res.rows.append(row(s, "mass_ratio", "closed-form", f"omega_{name}^2_vs_eig", cf[i], eig[i],
                                abs(cf[i] / eig[i] - 1) <= tol, mu=mu, note=f"tolerance {tol:.2g} (eigh's bound)"))
            if mu != 1.0:
                lim = MR.omega_sq_limits(1.0, 1.0, mu)
                x = min(mu, 1 / mu)
                res.rows.append(row(s, "mass_ratio", "closed-form", f"omega_{name}^2_vs_limit", cf[i], lim[i],
                                    abs(cf[i] / lim[i] - 1) <= x * x, mu=mu,
                                    note="two-term expansion, remainder O(mu^2) (or O(mu^-2))"))
    try:
        from rk4h.references.closed_forms import two_dof_equal_k
        two_dof_equal_k(1.0, m1=1.0, mu=0.0)
        refused, msg = False, "mu = 0 accepted"
    except ValueError as e:
        refused, msg = True, str(e)
    res.rows.append(row(s, "mass_ratio", "closed-form", "mu_le_0_refused", float(refused), 1.0, refused, mu=0.0,
                        note=msg))
    return res


# -- large N ----------------------------------------------------------------------------------
#: Steps and repeats of the timed RK4 runs of the large-N study (full, quick).
LARGE_N_TIMING = {False: (500, 3), True: (200, 3)}


def banded_reference() -> str:
    """The large-N study's reference: the built-in method with role
    ``"banded"`` (CVODE-BDF with a banded linear solver)."""
    return with_role("banded")[0]


def _large_n(ctx: Context, part) -> StudyResult:
    res, s, meth, tab = StudyResult(), ctx.scene, ctx.method, ctx.tab
    ref = banded_reference()
    Ns = [int(v) for v in pick(ctx.params, "n_values", ctx.quick)]
    n_steps, repeats = LARGE_N_TIMING[ctx.quick]
    t_rk, b_rk, t_cv, calls, cv_steps = [], [], [], [], []
    for N in Ns:
        t, per_step, _ = LN.step_cost(N, n_steps=n_steps, repeats=repeats, method=tab)
        t_rk.append(t)
        calls.append(per_step)
        b_rk.append(LN.peak_bytes(N, method=tab))
        cv = LN.cvode_band_cost(N)
        t_cv.append(cv["wall_per_step"])
        cv_steps.append(cv["n_steps"])
    fits = {"time": LN.fit_exponent(Ns, t_rk), "bytes": LN.fit_exponent(Ns, b_rk),
            "cvode_time": LN.fit_exponent(Ns, t_cv)}
    for N, b, t, tc, k in zip(Ns, b_rk, t_rk, t_cv, cv_steps):
        res.rows.append(row(s, "large_n", meth, "peak_bytes", b, n=N, note="tracemalloc peak of 3 generic-path steps"))
        res.rows.append(row(s, "large_n", meth, "wall_per_step_s", math.nan, n=N, measured_timed=t,
                            note=f"timing: min of {repeats} repeats of {n_steps} compiled-path steps"))
        res.rows.append(row(s, "large_n", ref, "steps", k, n=N,
                            note="one period of the lowest mode, rtol 1e-6, banded"))
        res.rows.append(row(s, "large_n", ref, "wall_per_step_s", math.nan, n=N, measured_timed=tc,
                            note="timing: one run"))
    timing = "timing on a shared machine: reported, not asserted (tests/test_stability.py checks it, slow)"
    per = float(tab.nfev_per_step)
    res.rows.append(row(s, "large_n", meth, "rhs_calls_per_step", max(calls), per, all(c == per for c in calls),
                        note=f"each call O(N); N = {Ns}"))
    res.rows.append(row(s, "large_n", meth, "peak_memory_exponent", fits["bytes"], 1.0,
                        abs(fits["bytes"] - 1) <= 0.1, note=f"tracemalloc peak, N = {Ns}"))
    res.rows.append(row(s, "large_n", meth, "cost_per_step_exponent", math.nan, 1.0, None,
                        measured_timed=fits["time"],
                        note=f"wall per step, min of {repeats} repeats of {n_steps} steps, N = {Ns}; {timing}"))
    res.rows.append(row(s, "large_n", ref, "cost_per_step_exponent", math.nan, 1.0, None,
                        measured_timed=fits["cvode_time"],
                        note=f"banded solver, difference-quotient band Jacobian; {timing}"))
    res.plots.append({"kind": "large_n", "scene": s, "study": "large_n", "name": "large_n", "data": {
        "n": np.array(Ns, float), "method": meth, "reference": ref, "wall_per_step": np.array(t_rk, float),
        "peak_bytes": np.array(b_rk, float),
        "cvode_wall_per_step": np.array(t_cv, float), "fits": {k: float(v) for k, v in fits.items()}}})
    res.findings.append(f"{s}: up to N = {Ns[-1]}, {meth} time per step ~ N^{fits['time']:.2f}, memory ~ "
                        f"N^{fits['bytes']:.2f}; CVODE-BDF (band) ~ N^{fits['cvode_time']:.2f}")
    return res


# -- planar geometry --------------------------------------------------------------------------
def _amplitude(ctx: Context, part) -> StudyResult:
    res, s = StudyResult(), ctx.scene
    p = G.four_spring_params(ctx.model)
    if p is None:
        res.rows.append(row(s, "amplitude", "-", "amplitude", math.nan, status="skipped",
                            note=f"amplitude {G.FOUR_SPRING_NEEDS}"))
        return res
    a = np.array(ctx.params["amplitudes"], float)
    err = G.linearization_error(p, a, method=ctx.tab)
    slope = G.amplitude_exponent(a[a >= 1e-5], err[a >= 1e-5])
    for ai, ei in zip(a, err):
        res.rows.append(row(s, "amplitude", ctx.method, "linearization_error", ei, math.nan, None, a_over_l=ai,
                            note="max over 5 periods of |q_nl - q_lin| / r0"))
    res.rows.append(row(s, "amplitude", ctx.method, "linearization_error_exponent", slope, 2.0, abs(slope - 2) <= 0.1,
                        note="fit over 1e-5 <= a/l <= 1e-2; cubic terms of V cancel by symmetry"))
    res.plots.append({"kind": "amplitude", "scene": s, "study": "amplitude", "name": "amplitude",
                      "data": {"method": ctx.method, "a_over_l": a, "error": np.asarray(err, float), "slope": float(slope)}})
    for tol in (1e-3, 1e-2):
        ok = a[err <= tol]
        res.findings.append(f"{s}: the linear model stays within {tol:g} of the exact geometry up to "
                            f"r0 = {ok.max() if ok.size else 0:.3g} l (Table 4.5's 3 l: error {err[-1]:.3g})")
    return res


def _singular(ctx: Context, part) -> StudyResult:
    res, s = StudyResult(), ctx.scene
    p = G.four_spring_params(ctx.model)
    if p is None:
        res.rows.append(row(s, "singular", "-", "singular", math.nan, status="skipped",
                            note=f"singular {G.FOUR_SPRING_NEEDS}"))
        return res
    T = 2 * math.pi / math.sqrt(2 * p["k"] / p["m"])
    h, t_end = T / 200, 2 * T
    off = ctx.params["singular_offset"]
    out = G.singular_pass(p, off, h, t_end, method=ctx.tab)
    res.rows.append(row(s, "singular", ctx.method, "closest_approach_m", out["d_min"], off,
                        out["status"] in ("singular", "ok", "unstable"), status=out["status"], offset=off,
                        note=out["message"]))
    res.findings.append(f"{s}: aimed at an anchor with offset {off:g} m: {out['message']}")
    out = G.singular_pass(p, 0.0, h, t_end, start_on_anchor=True, method=ctx.tab)
    t_fail = out["result"].t_fail
    res.rows.append(row(s, "singular", ctx.method, "blowup_time_on_anchor_s", t_fail if t_fail is not None else math.nan,
                        math.nan, out["status"] == "unstable", status=out["status"],
                        note="started exactly on the anchor (l, 0); " + out["message"]))
    return res


# -- dispatch ---------------------------------------------------------------------------------
_UNIT_FUNCTIONS = {"boundary": _boundary, "long_horizon": _long, "roundoff": _roundoff, "large_n": _large_n,
                   "amplitude": _amplitude, "singular": _singular}


def run_unit(scene, unit: str, quick: bool) -> StudyResult:
    """Compute one unit of ``scene``'s stability study (see :func:`units`):
    rows, findings and plot descriptions; no file is written. Exceptions
    propagate (the caller records the unit as failed, e.g. :func:`failed_unit`)."""
    study, part, params = parse_unit(unit)
    listed = units(scene, quick)
    if unit not in listed:
        raise ValueError(f"`unit` {unit!r} is not a unit of scene {scene.name!r} "
                         f"({'quick' if quick else 'full'} mode: {', '.join(listed)})")
    return run_unit_in(context(scene, quick), unit)


def run_unit_in(ctx: Context, unit: str) -> StudyResult:
    """:func:`run_unit` on a ready :class:`Context` (a model not built from a
    scene file, in tests); the unit is not checked against the scene's list."""
    study, part, params = parse_unit(unit)
    with np.errstate(all="ignore"):  # blow-ups are reported by status, not warnings
        if study in _SWEEPS:
            return _sweep_unit(ctx, study, part, params)
        return _UNIT_FUNCTIONS[study](ctx, part)


def assemble(scene, quick: bool, results: dict) -> StudyResult:
    """Merge the units' results of ``scene`` (``{unit: StudyResult}``, or
    objects/dicts with ``rows``, ``findings``, ``plots``) into the scene's
    rows, findings and plots, in the order of :func:`units`: the sweep points
    become one cost plot and one finding per sweep, the long-horizon parts one
    drift plot and one energy plot. Pure: integrates nothing. A unit without
    a result becomes a ``failed`` row."""
    p = validate_params(dict(scene.stability or {}))
    all_units = units(scene, quick)
    out = StudyResult()
    for study in p["studies"]:
        res = StudyResult()
        for u in (u for u in all_units if parse_unit(u)[0] == study):
            r = results.get(u)
            if r is None:
                res.extend(failed_unit(scene.name, u, "no result for this unit"))
                continue
            get = (lambda k: r.get(k, [])) if isinstance(r, dict) else (lambda k: getattr(r, k, []))
            res.rows += list(get("rows"))
            res.findings += list(get("findings"))
            res.plots += list(get("plots"))
        if study == "long_horizon":
            _assemble_long(scene.name, quick, res)
        elif study in _SWEEPS:
            _assemble_cost(scene.name, study, res)
        out.extend(res)
    return out


_ = integrate_fixed  # the study's one fixed-step entry point (rk4h.validation.stability._common)
