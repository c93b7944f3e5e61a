"""``energy_work_precision``: energy error against cost over long horizons.

For every solver of the scene and every horizon of ``[energy_work_precision]
periods`` (periods of the slowest linearized mode; default 1e2 and 1e4, at
most 1e6), the largest relative energy error ``max_t |E(t) - E0| / E_motion``
over the run against its right-hand-side calls and wall time, as
SciMLBenchmarks draws it for its dynamical-ODE benchmarks:

* a fixed-step method (a tableau, partitioned or not) runs on the compiled
  loops at ``h = T_fast / n`` for each ``n`` of ``[energy_work_precision]
  steps`` (steps per period of the fastest mode);
* an adaptive reference runs at each of ``run.tolerances``.

Each run's energy is sampled 16 times per fastest period
(:func:`rk4h.validation.energy_time.dense_samples`) and its growth exponent fitted
(:func:`rk4h.validation.energy_time.growth_exponent`). The numbers come from
:func:`rk4h.validation.energy_time.work_precision_rows`, the code the opt-in CLI
``python -m rk4h.validation.energy_study`` runs. Never a default: its runs are long.

Check: every symplectic method's energy error stays bounded over every
horizon of at least :data:`CHECK_MIN_PERIODS` periods (growth exponent below
:data:`BOUNDED_EXPONENT` in each of its runs that stayed stable).
"""
from __future__ import annotations

import math

from rk4h.validation.outputs import Output, Table, solver_loop

#: A symplectic method's energy error counts as bounded while the fitted
#: growth exponent of its running maximum stays below this (secular growth: 1).
BOUNDED_EXPONENT = 0.1
#: The shortest horizon (periods of the slowest mode) the bounded-energy check
#: reads: 10**FIT_DECADES, so the fit starts after at least one slowest period.
CHECK_MIN_PERIODS = 100.0
#: The run purpose of this output.
PURPOSE = "energy_wp"
#: The figure kind (rk4h.validation.figures.GENERIC_CAPTIONS).
FIGURE = "energy_work_precision"


def settings(scene) -> tuple[list[float], list[int]]:
    """``(periods, steps)`` of ``scene``: its ``[energy_work_precision]`` keys,
    the defaults where it sets none (a repeated value once, in order)."""
    from rk4h.validation.scene_schema import EWP_PERIODS, EWP_STEPS

    cfg = getattr(scene, "energy_work_precision", None) or {}
    periods = list(dict.fromkeys(float(x) for x in cfg.get("periods", EWP_PERIODS)))
    steps = list(dict.fromkeys(int(x) for x in cfg.get("steps", EWP_STEPS)))
    return periods, steps


def plan(p) -> list:
    """One spec per (solver, horizon); ``setting`` is the horizon in periods."""
    periods, steps = settings(p.scene)
    return [p.spec(PURPOSE, solver=solver, setting=per, grid="periods", params=(("steps", tuple(steps)),))
            for solver in p.scene.solvers for per in periods]


def execute(scene, spec, quick):
    """The rows of one solver over one horizon (:func:`rk4h.validation.energy_time.work_precision_rows`)."""
    import rk4h.fast as fast
    from rk4h.validation.energy_time import is_symplectic, work_precision_rows
    from rk4h.validation.execute import problem
    from rk4h.validation.records import RunRecord

    model, y0 = problem(scene)
    method = scene.method(spec.solver)
    steps = tuple(int(n) for n in spec.param("steps", ()))
    if method.fixed_step:
        tab = getattr(method, "tableau", None)
        if tab is None:
            return RunRecord(spec.key, status="skipped",
                             message=f"{spec.solver} is not a tableau: the long runs use the compiled loops")
        if not fast.supports(model):
            return RunRecord(spec.key, status="skipped",
                             message="the model has no compiled force: the long runs use the compiled loops")
        rows = work_precision_rows(scene.name, model, y0, [tab], steps, [spec.setting])
        symplectic = is_symplectic(tab)
    else:
        rows = work_precision_rows(scene.name, model, y0, [], steps, [spec.setting], references=[spec.solver],
                                   rtols=tuple(scene.tolerances))
        symplectic = False
    for r in rows:
        r["solver"] = spec.solver  # the scene's name for it (a scene's own method keeps its table name)
        r["symplectic"] = bool(symplectic)
    return RunRecord(spec.key, values={"rows": rows}, timing={"wall_s": float(sum(r["wall_s"] for r in rows))})


COLUMNS = (
    ("scene", "", "str", "scene name"),
    ("solver", "", "category", "method name (rk4h.references.registry or the scene's [methods.NAME])"),
    ("symplectic", "", "bool", "whether the method is symplectic (a partitioned tableau: splittings, compositions)"),
    ("periods", "1", "float", "horizon in periods of the slowest linearized mode"),
    ("t_end", "s", "float", "horizon: periods times the slowest period"),
    ("h", "s", "float", "step of a fixed-step run (T_fast / steps); NaN for an adaptive reference"),
    ("rtol", "1", "float", "relative tolerance of an adaptive reference's run; NaN for a fixed-step method"),
    ("energy_drift_max", "1", "float", "max over the run of |E(t) - E0| / E_motion, sampled 16 times per "
                                       "fastest period; NaN for a run that did not end ok"),
    ("energy_growth_exponent", "1", "float", "slope of log max_{s<=t}|E(s) - E0| against log t over the last two "
                                             "decades of the run: ~0 bounded, ~1 secular; NaN (not fitted) when "
                                             "those decades start before half an FPUT-alpha chain's 2:1 exchange "
                                             "period (energy_time.exchange_period)"),
    ("nfev", "calls", "int", "right-hand-side calls of the run (heyoka: Taylor steps times order)"),
    ("cost_unit", "", "category", "what `nfev` counts (rk4h.references.registry.CostUnit): rhs, "
                                  "rhs+jacobian-dq, rhs-without-jacobian or taylor-steps"),
    ("wall_s", "s", "float", "wall time of the run, compile time apart"),
    ("status", "", "category", "outcome of the run: ok, unstable, step_cap (a reference reached its step cap, "
                               "or would need more than the ceiling: a failure, no numbers), or the solver's "
                               "failure"),
    ("max_steps", "steps", "float", "a reference's step cap, sized from the horizon (energy_time.reference_step_cap: "
                                    "2 x the steps estimated from 100 slowest periods, at least 5e6, at most 5e8; "
                                    "0: not run); NaN for a fixed-step run"),
)


def measure(m) -> None:
    """Rows, the bounded-energy check of every symplectic method and the figure job."""
    from rk4h.validation.measure import FigureJob

    rows = []
    for spec in m.specs(PURPOSE):
        rec = m.records[spec.key]
        what = f"{m.scene.name}: {spec.solver} over {spec.setting:g} periods"
        if rec.status == "skipped":
            m.res.findings.append(f"{what}: no energy work-precision run ({rec.message})")
            continue
        if "rows" not in rec.values:
            m.res.check("energy work-precision completes", False, f"{what} raised {rec.message or 'no message'}")
            continue
        for r in rec.values["rows"]:
            row = {c[0]: r.get(c[0], math.nan) for c in COLUMNS}
            m.res.add("energy_work_precision", row)
            rows.append({**row, "message": r.get("message", "")})
    _bounded_checks(m, rows)
    _step_cap_checks(m, rows)
    if m.draw and any(r["status"] == "ok" for r in rows):
        m.res.figures.append(FigureJob(m.scene.name, FIGURE, {"rows": rows}))


def _bounded_checks(m, rows) -> None:
    """Per symplectic method and horizon: every stable run's growth exponent < BOUNDED_EXPONENT.

    Only over horizons of at least :data:`CHECK_MIN_PERIODS`: the exponent is
    fitted over the run's last two decades, which over a shorter horizon start
    within the first slowest period, while the running maximum of even a
    bounded error is still rising (a finding says which horizons were not checked)."""
    keys = dict.fromkeys((r["solver"], r["periods"]) for r in rows if r["symplectic"])
    short = sorted({per for _, per in keys if per < CHECK_MIN_PERIODS})
    if short:
        m.res.findings.append(f"{m.scene.name}: the bounded-energy check skips the horizons under "
                              f"{CHECK_MIN_PERIODS:g} periods ({', '.join(f'{p:g}' for p in short)}): their "
                              f"growth exponents are fitted from the first slowest period on")
    for solver, per in keys:
        if per < CHECK_MIN_PERIODS:
            continue
        mine = [r for r in rows if r["solver"] == solver and r["periods"] == per]
        ok = [r for r in mine if r["status"] == "ok" and math.isfinite(r["energy_growth_exponent"])]
        unfitted = [r for r in mine if r["status"] == "ok" and str(r.get("message", "")).startswith("not fitted")]
        if not ok and unfitted:
            m.res.findings.append(f"{m.scene.name}: {solver} over {per:g} periods: bounded-energy check not made, "
                                  f"{unfitted[0]['message']}")
            continue
        if not ok:
            m.res.check("symplectic energy bounded", False,
                        f"{m.scene.name}: {solver} over {per:g} periods: no stable run to fit "
                        f"({', '.join(sorted({r['status'] for r in mine}))})")
            continue
        worst = max(ok, key=lambda r: r["energy_growth_exponent"])
        k = worst["energy_growth_exponent"]
        m.res.check("symplectic energy bounded", k < BOUNDED_EXPONENT,
                    f"{m.scene.name}: {solver} over {per:g} periods at h = {worst['h']:.4g} s: energy growth "
                    f"exponent {k:.3f} >= {BOUNDED_EXPONENT} (secular, not bounded)",
                    measured=k, expected=0.0, tolerance=BOUNDED_EXPONENT)


def _step_cap_checks(m, rows) -> None:
    """Every reference run ended within its step cap: a run cut at the cap
    (or refused over the ceiling) is a failed check naming where it stopped,
    never a shorter run read as the horizon's."""
    from rk4h.validation.energy_time import STEP_CAP_STATUS

    for r in rows:
        if not math.isfinite(r["rtol"]):
            continue
        m.res.check("reference within its step cap", r["status"] != STEP_CAP_STATUS,
                    f"{m.scene.name}: {r['solver']} at rtol {r['rtol']:g} over {r['periods']:g} periods: "
                    f"{r.get('message') or 'step cap reached'}")


def caption(scene_name, rows) -> str:
    """The figure's sentence: horizons, and per method at the longest horizon
    its smallest energy error, the calls it took and its growth exponent."""
    ok = [r for r in rows if r["status"] == "ok" and r["energy_drift_max"] > 0]
    horizons = sorted({r["periods"] for r in rows})
    longest = horizons[-1]
    parts = []
    for name in dict.fromkeys(r["solver"] for r in rows):
        mine = [r for r in ok if r["solver"] == name and r["periods"] == longest]
        if not mine:
            parts.append(f"{name}: no stable run")
            continue
        best = min(mine, key=lambda r: r["energy_drift_max"])
        ks = [r["energy_growth_exponent"] for r in mine if math.isfinite(r["energy_growth_exponent"])]
        k = f", growth exponent {min(ks):.2f} to {max(ks):.2f}" if ks else ""
        parts.append(f"{name} {best['energy_drift_max']:.2g} at {best['nfev']:.3g} calls{k}")
    t_slow = rows[0]["t_end"] / rows[0]["periods"] if rows else math.nan
    return (f"{scene_name}: energy work-precision over {', '.join(f'{p:g}' for p in horizons)} periods of the "
            f"slowest mode ({t_slow:.4g} s); over {longest:g} periods the smallest max |E - E0| / E_motion: "
            + "; ".join(parts) + ".")


#: Line styles of the horizons, shortest first.
HORIZON_STYLES = ("-", "--", ":", "-.")


def figure(out_dir, scene_name, rows):
    """``<scene>_energy_work_precision.png``: max |E(t) - E0| / E_motion against
    RHS calls (left) and wall time (right), log-log, one line per (method,
    horizon) in the report's house style (:mod:`rk4h.validation.figures.style`),
    markers at the method's steps or tolerances; rows that did not end ok are
    left out. Returns ``(Path, Caption)``."""
    import numpy as np

    from rk4h.validation.figures import Caption
    from rk4h.validation.figures import style as kit

    fig = kit.new_figure()
    kit.suptitle(fig, f"{scene_name}: energy work-precision over horizons in periods of the slowest mode")
    ax_n, ax_t = fig.subplots(1, 2, sharey=True)
    ok = [r for r in rows if r["status"] == "ok" and r["energy_drift_max"] > 0]
    horizons = sorted({r["periods"] for r in rows})
    for name in kit.in_palette_order(list(dict.fromkeys(r["solver"] for r in rows))):
        color, marker = kit.solver_style(name)
        for hi, per in enumerate(horizons):
            mine = sorted((r for r in ok if r["solver"] == name and r["periods"] == per), key=lambda r: r["nfev"])
            if not mine:
                continue
            e = np.array([r["energy_drift_max"] for r in mine])
            for ax, key, lab in ((ax_n, "nfev", f"{name}, {per:g} periods"), (ax_t, "wall_s", None)):
                ax.plot([r[key] for r in mine], e, marker=marker, ms=4, lw=1.2, color=color,
                        ls=HORIZON_STYLES[hi % len(HORIZON_STYLES)], label=lab)
    for ax, xl in ((ax_n, "right-hand-side calls"), (ax_t, "wall time (s, one run)")):
        if ax.lines:
            kit.log_axes(ax)
        ax.set_xlabel(xl)
    ax_n.set_ylabel("max |E(t) - E0| / E_motion")
    if ok:
        kit.legend_below(fig)
    path = kit.save(fig, out_dir, f"{kit.slug(scene_name)}_energy_work_precision")
    return path, Caption(caption(scene_name, rows), FIGURE)


def draw(out_dir, job, scene) -> list:
    """The output's figure (:func:`figure`)."""
    return [figure(out_dir, job.scene, job.data["rows"])]


OUTPUT = Output(
    name="energy_work_precision", rank=125, plan_rank=80, measure_rank=80,
    when="never by default (long runs)",
    what="the largest relative energy error over each run against RHS calls and wall time over horizons of "
         "`[energy_work_precision] periods` of the slowest mode, every solver: `energy_work_precision.csv`, its "
         "figure and the check that every symplectic method's energy stays bounded (growth exponent < 0.1)",
    plan=plan, measure=measure, execute={PURPOSE: execute}, draw={FIGURE: draw}, loops={PURPOSE: solver_loop},
    purposes={PURPOSE: "one solver over one horizon: a fixed-step method at each steps-per-fastest-period, an "
                       "adaptive reference at each run.tolerances; energy error, growth exponent, calls, wall time"},
    tables=(Table("energy_work_precision", columns=COLUMNS, timing=frozenset({"wall_s"}),
                  description="energy work-precision: per solver, horizon and step or tolerance, the largest "
                              "relative energy error over the run, its growth exponent and its cost"),),
)
