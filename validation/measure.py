"""Tables, checks and figure data from records: pure functions, no integration.

:func:`measure` turns one scene's plan and records into table rows (the CSV
files of the report), :class:`Check` records (a failed check is a failure
line in ``index.md``; nothing else fails a run), one-line findings, and
:class:`FigureJob` data that :mod:`rk4h.validation.draw` turns into PNGs.

Rows of a swept scene (``scene.sweep``) carry the swept parameters as columns.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np



from . import energy_time, metrics, trust
from .plan import ORDER_TOL, TARGETS, RunSpec, under_test

__all__ = ["Check", "FigureJob", "SceneTables", "measure", "ENERGY_RTOL", "ENERGY_ROUNDOFF_PER_STEP",
           "TOLERANCE_SLACK", "PACKET_RTOL"]

#: RK4 energy drift: measured vs theory, relative slack and round-off per step.
ENERGY_RTOL = 1e-6
ENERGY_ROUNDOFF_PER_STEP = 10 * np.finfo(float).eps
#: Adaptive solvers: tightening the tolerance may not raise the error more than this.
TOLERANCE_SLACK = 10.0
#: Wave packets: accepted |centroid speed / spectral-mean group velocity - 1|
#: (RK4's share at h = 0.02 s is <= 1.2e-4; the explained offset of the
#: spectral mean from v_g(kp0), 4.9e-3, would fail it).
PACKET_RTOL = 1e-3
#: Finite chain against the dispersion relation: accepted relative error.
DISPERSION_RTOL = 1e-10


@dataclass(frozen=True)
class Check:
    """One expectation: ``passed`` is whether ``measured`` met ``expected``
    within ``tolerance``; ``message`` is the failure line (scene first)."""

    scene: str
    name: str
    measured: float = math.nan
    expected: float = math.nan
    tolerance: float = math.nan
    passed: bool = True
    message: str = ""


@dataclass
class FigureJob:
    """A figure to draw: ``kind`` names a function of :mod:`rk4h.validation.draw`,
    ``data`` its arguments (arrays, rows)."""

    scene: str
    kind: str
    data: dict


@dataclass
class SceneTables:
    scene: str
    tables: dict = field(default_factory=dict)
    checks: list = field(default_factory=list)
    findings: list = field(default_factory=list)
    figures: list = field(default_factory=list)
    truth_kind: str = ""
    #: the model's fastest mode (rad/s; NaN: none), from the scene's truth record
    omega_max: float = math.nan
    seconds: float = 0.0
    drawn: list = field(default_factory=list)
    #: files other than tables and figures (rk4h.validation.outputs.FileJob)
    files: list = field(default_factory=list)

    def add(self, table, row):
        self.tables.setdefault(table, []).append(row)

    def check(self, name, passed, message="", measured=math.nan, expected=math.nan, tolerance=math.nan):
        self.checks.append(Check(self.scene, name, float(measured), float(expected), float(tolerance),
                                 bool(passed), message if not passed else ""))

    @property
    def failures(self) -> list:
        return [c.message for c in self.checks if not c.passed]


def measure(scene, specs: list[RunSpec], records: dict, *, quick=False, figures=True) -> SceneTables:
    """Everything ``scene`` reports, from its ``specs`` and their ``records``
    (key -> :class:`~rk4h.validation.records.RunRecord`)."""
    res = SceneTables(scene.name)
    by = {}
    for s in specs:
        by.setdefault(s.purpose, []).append(s)
    res.seconds = float(sum(records[s.key].seconds for s in specs if s.key in records))
    draw = figures and "figures" in scene.outputs
    for s in by.get("truth", []):
        rec = records[s.key]
        if s.grid == "scene":
            res.truth_kind = rec.values.get("truth_kind", "")
            res.omega_max = float(rec.values.get("omega_max", math.nan))
            if rec.values.get("truth_note"):  # the truth is two references that agree: say how well
                res.findings.append(f"{scene.name}: the reference is {rec.values['truth_note']}; errors below "
                                    f"that agreement are measured against dop853 alone")
        if rec.status == "failed" and s.grid != "figure":  # (_state_figure says it for the figure grid)
            _failed(res, s, rec)  # no reference: a failed check, never blank errors beside a green line
    from . import outputs

    m = outputs.Measuring(scene, by, records, res, quick, draw)
    for hook in outputs.measure_hooks(scene.outputs):  # each output's measurement (rk4h.validation.outputs)
        hook(m)
    _methods_table(scene, res)
    if scene_sweep(scene):
        cols = scene_sweep(scene)
        for rows in res.tables.values():
            for i, r in enumerate(rows):
                rows[i] = {"scene": r["scene"], **cols, **{k: v for k, v in r.items() if k != "scene"}}
    return res


def scene_sweep(scene) -> dict:
    return dict(getattr(scene, "sweep", None) or {})


def _failed(res, spec, rec):
    """A failed run: ``raised`` when its execution raised (no values), else ``failed``."""
    what = f"{spec.scene}: {spec.solver} at {spec.setting:g}" if spec.solver else f"{spec.scene}: {spec.purpose}"
    verb = "failed:" if rec.values else "raised"
    res.check(f"{spec.purpose} completes", False, f"{what} {verb} {rec.message or 'no message'}")


def _with_values(specs, records, res):
    """``(spec, record)`` of every spec whose record holds values; the others
    are failed checks (:func:`_failed`)."""
    for s in specs:
        rec = records[s.key]
        if rec.values:
            yield s, rec
        else:
            _failed(res, s, rec)


# -- accuracy, energy, work-precision --------------------------------------------------
def _tables_wanted(scene) -> frozenset:
    """Names of the tables the scene's outputs declare
    (:attr:`rk4h.validation.outputs.Output.tables`): which rows the shared
    runs add beside ``accuracy``."""
    from . import outputs

    return frozenset(t.name for o in scene.outputs if o in outputs.OUTPUTS for t in outputs.OUTPUTS[o].tables)


def _runs(scene, specs, records, res, draw, confirm_specs=()):
    series = {}
    wanted = _tables_wanted(scene)
    no_truth_runs = []
    for spec in specs:
        rec = records[spec.key]
        v, tm = rec.values, rec.timing
        row = {"scene": scene.name, "solver": spec.solver, "setting": float(spec.setting)}
        unit = {"cost_unit": scene.method(spec.solver).cost_unit.value}  # what its nfev counts
        if not v:  # the execution itself failed
            _failed(res, spec, rec)
            res.add("accuracy", {**row, "error_max": math.nan, "error_rel": math.nan, "error_final": math.nan,
                                 "energy_drift_max": math.nan, "nfev": 0, **unit, "n_steps": 0, "wall_s": math.nan,
                                 "compile_s": math.nan, "status": "failed", "message": rec.message,
                                 "note": ""})
            continue
        status = rec.status
        if status == "failed":
            _failed(res, spec, rec)
        elif status == "unavailable":  # a command method's program is not installed: said, not failed
            res.findings.append(f"{scene.name}: {spec.solver} at {spec.setting:g} did not run: {rec.message}")
        elif status == "unstable":
            res.findings.append(f"{scene.name}: {spec.solver} at {spec.setting:g} became unstable: "
                                f"{rec.message or 'non-finite state'}")
        no_truth = v.get("no_truth", "")
        if no_truth:
            no_truth_runs.append((spec, no_truth))
        # a program that is not installed evaluated nothing: no count, not a declared cost times steps
        nfev = math.nan if status == "unavailable" else v["nfev"]
        res.add("accuracy", {**row, "error_max": v["error_max"], "error_rel": v["error_rel"],
                             "error_final": v["error_final"], "energy_drift_max": v["energy_drift_max"],
                             "nfev": nfev, **unit, "n_steps": v["n_steps"], "wall_s": tm["wall_s"],
                             "compile_s": tm["compile_s"], "status": status, "message": rec.message,
                             "note": no_truth})
        if "work_precision" in wanted:
            res.add("work_precision", {**row, "error_max": v["error_max"], "error_rel": v["error_rel"],
                                       "wall_s": tm["wall_s"], "nfev": nfev, **unit, "n_steps": v["n_steps"],
                                       "taylor_order": v["taylor_order"], "status": status,
                                       "wall_min": tm.get("wall_min", tm["wall_s"]),
                                       "wall_max": tm.get("wall_max", tm["wall_s"]),
                                       "compile_s": tm["compile_s"]})
        if "energy" in wanted:
            res.add("energy", _energy_row(scene, spec, rec, row, res))
            if "energy_rel" in rec.arrays and math.isfinite(v["energy_drift_max"]) and v["error_rel"] <= 10.0:
                label = f"{spec.solver} {scene.method(spec.solver).setting_name}={spec.setting:g}"
                series[spec.solver] = (label, rec.arrays["energy_t"], rec.arrays["energy_rel"])
    for reason in dict.fromkeys(r for _, r in no_truth_runs):
        runs = [f"{sp.solver} {sp.setting:g}" for sp, r in no_truth_runs if r == reason]
        res.check("errors against the truth", False,
                  f"{scene.name}: {len(runs)} run(s) have no errors ({', '.join(runs)}): {reason}")
    if "work_precision" in wanted and specs:
        _cheapest(scene, res, confirm_specs, records)
        if draw:
            wp = [r for r in res.tables.get("work_precision", []) if r["error_rel"] <= 10.0]
            res.figures.append(FigureJob(scene.name, "work_precision", {"rows": wp}))
    if "convergence" in wanted:
        _tolerance_checks(scene, res)
    if draw and series:
        res.figures.append(FigureJob(scene.name, "energy_error",
                                     {"series": {lab: (t, e) for lab, t, e in series.values()}}))


def _energy_row(scene, spec, rec, row, res):
    v = rec.values
    ok = rec.status == "ok"
    out = {**row, "drift_per_time": v["drift_per_time"] if ok else math.nan,
           "theory_drift_per_time": v["theory_drift_per_time"],
           "energy_drift_max": v["energy_drift_max"] if ok else math.nan, "passed": "", "status": rec.status,
           **{k: v.get(k, math.nan) if ok else math.nan for k in energy_time.COLUMNS}}
    theory = v["theory_drift_per_time"]
    if ok and math.isfinite(theory):  # a tableau method on a linear model (rk4h.validation.execute)
        measured, duration = v["drift_per_time"], v["duration"]
        slack = ENERGY_RTOL * abs(theory) + ENERGY_ROUNDOFF_PER_STEP * v["n_steps"] / duration
        passed = bool(abs(measured - theory) <= slack)
        out["passed"] = passed
        res.check(f"{spec.solver} energy drift theory", passed,
                  f"{scene.name}: {spec.solver} energy drift per time at h={spec.setting:g} is {measured:.6e} 1/s, "
                  f"theory {theory:.6e} 1/s", measured, theory, slack)
    return out


def _cheapest(scene, res, confirm_specs=(), records=None):
    """``cheapest.csv``: the trust table of the method under test
    (:mod:`rk4h.validation.trust`), with the confirmation runs of ``confirm_specs``
    (:mod:`rk4h.validation.confirm`)."""
    from . import confirm

    under = under_test(scene)
    if under is None:
        return
    method = scene.method(under)
    rows = res.tables.get("work_precision", [])
    confirmations = confirm.rows_of(confirm_specs, records or {})
    for c in confirmations:  # said, not failed: the verdict then rests on the other runs
        if c["status"] != "ok":
            res.findings.append(f"{scene.name}: the confirmation run of {c['solver']} at {c['setting']:g} "
                                f"ended {c['status']}; no verdict rests on it.")
    res.tables.setdefault("cheapest", [])
    res.tables["cheapest"] += trust.trust_rows(
        scene.name, rows, method, scene.t_end, trust.stable_step(method, res.omega_max),
        TARGETS,
        setting_name=lambda sv: scene.method(sv).setting_name,
        confirmations=confirmations, output_dt=scene.output_dt,
        cost_unit=lambda sv: scene.method(sv).cost_unit.value)


def _tolerance_checks(scene, res):
    """Adaptive solvers: the error must fall as the tolerance tightens."""
    rows = res.tables.get("accuracy", [])
    for solver in scene.adaptive_solvers:
        mine = sorted((r for r in rows if r["solver"] == solver), key=lambda r: -r["setting"])
        if len(mine) < 2:
            continue
        tol = np.array([r["setting"] for r in mine])
        err = np.array([r["error_rel"] for r in mine], float)
        ok = np.isfinite(err)
        monotone = bool(ok.all() and np.all(err[1:] <= TOLERANCE_SLACK * err[:-1]) and err[-1] < err[0])
        above = ok & (err > metrics.ROUNDOFF_REL)
        slope = float(np.polyfit(np.log(tol[above]), np.log(err[above]), 1)[0]) if above.sum() >= 2 else math.nan
        res.add("convergence", {"scene": scene.name, "solver": solver, "quantity": "error vs tolerance",
                                "observed_order": slope, "expected_order": math.nan, "passed": monotone,
                                "h_min": float(tol.min()), "h_max": float(tol.max()),
                                "n_points": int(above.sum()), "t_end": scene.t_end})
        res.check(f"{solver} error falls with tolerance", monotone,
                  f"{scene.name}: {solver}'s error does not decrease with the tolerance "
                  f"(relative errors {', '.join(f'{e:.2g}' for e in err)})")


# -- the scene's own tableaux --------------------------------------------------------------
def _methods_table(scene, res):
    """``methods.csv``: for each tableau method the scene runs (its
    ``run.solvers`` that are tableaux: its own ``[methods]`` tables and the
    built-in fixed-step methods such as RK4), per order ``p`` up to its order
    plus one, the largest residual of the order conditions of order ``p``,
    the residual the coefficients' precision allows for that condition, and
    whether every condition of order ``p`` holds
    (:attr:`rk4h.methods.Tableau.order_residuals`); and per method its
    cost (``nfev_per_step``, first-same-as-last reuse counted), the end of
    its stable interval of the imaginary axis (``imaginary_axis_bound``,
    dimensionless ``h omega``;
    :func:`rk4h.stability_function.imaginary_axis_boundary`: RK4 2 sqrt 2,
    Heun3 sqrt 3) and its principal error coefficient
    (:attr:`rk4h.methods.Tableau.error_coefficient`: RK4 0.01450).
    Computed from the coefficients, not from runs; the thesis' built-in
    tableaux are exact rationals (every residual 0), the geometric ones are
    judged at their coefficients' precision (60-digit irrationals, Yoshida-6's
    40 digits, Blanes-Moan's 15)."""
    from rk4h.references.registry import BUILTIN
    from rk4h.stability_function import imaginary_axis_boundary

    own = getattr(scene, "registry", None) or {}
    for name in dict.fromkeys(scene.solvers):
        method = own.get(name) if name in own else BUILTIN.get(name)
        tab = getattr(method, "tableau", None)
        if tab is None:
            continue
        bound = float(imaginary_axis_boundary(tab))
        for r in tab.order_residuals:
            res.add("methods", {"scene": scene.name, "method": name, "order_p": r["order"],
                                "conditions": r["conditions"], "max_residual": r["max_residual"],
                                "tolerance": r["tolerance"], "holds": bool(r["holds"]), "order": tab.order,
                                "precision": tab.precision, "coefficient_tol": float(tab.coefficient_tol),
                                "stages": tab.n_stages, "partitioned": tab.partitioned,
                                "error_coefficient": float(tab.error_coefficient),
                                "nfev_per_step": int(tab.nfev_per_step), "imaginary_axis_bound": bound,
                                "builtin": name not in own})


# -- convergence -----------------------------------------------------------------------------
def _convergence(scene, specs, records, res, draw):
    points = []
    methods = list(dict.fromkeys(s.solver for s in specs))
    conv_rows = []
    for method in methods:
        mine = [s for s in specs if s.solver == method]
        hs, errs, scale, T = [], [], math.nan, math.nan
        for s in mine:
            v = records[s.key].values
            if not v:
                _failed(res, s, records[s.key])
                hs.append(math.nan)
                errs.append(math.nan)
                continue
            hs.append(v["h"])
            errs.append(v["error_max"])
            scale, T = v["scale"], v["t_end"]
        fit = metrics.fit_order(hs, errs, scale)
        points += [{"solver": method, "h": h, "error_max": e, "error_rel": e / scale} for h, e in zip(hs, errs)]
        expected = float(scene.method(method).order)
        passed = fit.passed(expected, ORDER_TOL)
        row = {"scene": scene.name, "solver": method, "quantity": "order in h", "observed_order": fit.order,
               "expected_order": expected, "passed": passed, "h_min": fit.h_min, "h_max": fit.h_max,
               "n_points": fit.n_points, "t_end": T}
        conv_rows.append(row)
        res.check(f"{method} order", passed,
                  f"{scene.name}: {method} observed order {fit.order:.3f}, expected {expected:g} +- "
                  f"{ORDER_TOL:g} (h in [{fit.h_min:.3g}, {fit.h_max:.3g}], {fit.n_points} points)",
                  fit.order, expected, ORDER_TOL)
    # order rows first, then the tolerance rows already added from the accuracy table
    res.tables["convergence"] = conv_rows + res.tables.get("convergence", [])
    if draw:
        res.figures.append(FigureJob(scene.name, "convergence", {"points": points, "fits": conv_rows}))


# -- modes, dispersion, modal energy, linearization, state figures ------------------------------
def _modes(scene, specs, records, res):
    for s, rec in _with_values(specs, records, res):
        for j, w in enumerate(rec.values["omega"], start=1):
            res.add("modes", {"scene": scene.name, "mode": j, "omega_rad_s": w, "freq_hz": w / (2 * math.pi),
                              "linearized": not rec.values["linear"]})


def _thesis_code(scene, specs, records, res):
    """The thesis' programs against rk4core and the truth: one check per
    comparison that ran; programs that could not run (no ``octave-cli``)
    are rows with status ``unavailable`` and one finding, not failures."""
    for s, rec in _with_values(specs, records, res):
        rows = rec.values["rows"]
        for r in rows:
            res.add("thesis_code", {"scene": scene.name, **r})
            if r["status"] == "ok" and r["passed"] in (True, False):
                what = f"{r['program']} ({r['variant']}, {r['case']}) {r['quantity']}"
                value, expected, tol = (math.nan if r[k] is None else float(r[k])
                                        for k in ("value", "expected", "tolerance"))
                res.check(f"thesis code {what}", bool(r["passed"]),
                          f"{scene.name}: {what} = {value:.6g}, expected {expected:.6g} +- {tol:.3g}"
                          + (f" ({r['message']})" if r.get("message") else ""), value, expected, tol)
        missing = sorted({r["message"] for r in rows if r["status"] == "unavailable"})
        if missing:
            res.findings.append(f"{scene.name}: the thesis' programs did not run: {missing[0]} "
                                f"({sum(r['status'] == 'unavailable' for r in rows)} rows unavailable).")
        for e in rec.values["errata"]:
            res.add("thesis_errata", {"scene": scene.name, **e})


def _dispersion(scene, specs, packets, records, res, draw):
    if not specs:
        return
    rec = records[specs[0].key]
    if rec.status != "ok":
        res.check("dispersion", False, f"{scene.name}: {rec.message}")
        return
    finite, theory, kp = rec.arrays["finite"], rec.arrays["theory"], rec.arrays["kp"]
    rel = np.abs(finite - theory) / theory
    worst = float(rel.max())
    for n in range(finite.size):
        res.add("dispersion", {"scene": scene.name, "quantity": "finite-chain omega", "index": n + 1,
                               "kp_rad_m": float(kp[n]), "measured": float(finite[n]), "theory": float(theory[n]),
                               "rel_error": float(rel[n]), "passed": bool(rel[n] <= DISPERSION_RTOL)})
    res.check("finite chain vs dispersion relation", worst <= DISPERSION_RTOL,
              f"{scene.name}: finite-chain frequencies differ from the dispersion relation by {worst:.2e} "
              f"(relative)", worst, 0.0, DISPERSION_RTOL)
    drawn = []
    for s in packets:
        p = records[s.key]
        if not p.values:
            _failed(res, s, p)
            continue
        v = p.values
        ok = bool(v["success"] and abs(v["rel_error_spectral"]) <= PACKET_RTOL)
        res.add("dispersion", {"scene": scene.name, "quantity": "wave-packet group velocity", "index": s.setting,
                               "kp_rad_m": v["kp0"], "measured": v["v_measured"], "theory": v["v_spectral"],
                               "rel_error": v["rel_error_spectral"], "passed": ok})
        drawn.append((v["kp0"], v["v_measured"]))
        res.check("wave-packet group velocity", ok,
                  f"{scene.name}: wave packet at kp0 = {s.setting:g} pi/d moves at {v['v_measured']:.5g} m/s, "
                  f"its spectrum's mean v_g = {v['v_spectral']:.5g} m/s", v["rel_error_spectral"], 0.0, PACKET_RTOL)
        if ok:
            res.findings.append(
                f"{scene.name}: a wave packet at kp0 = {s.setting:g} pi/d integrated by RK4 moves at "
                f"{v['v_measured']:.6g} m/s vs {v['v_spectral']:.6g} m/s, the energy-weighted mean group velocity "
                f"of its spectrum ({v['rel_error_spectral']:+.1e}; RK4's predicted -(omega h)^4/24 is "
                f"{v['rk4_offset']:+.1e}). That mean is {100 * v['spectral_offset']:+.3f}% off v_g(kp0) = "
                f"{v['v_theory']:.5g} m/s: -5 d^2/(16 sigma^2) for a Gaussian packet of width "
                f"sigma = {v['sigma'] / rec.values['d']:g} d, whose energy ~ omega^2 favours the larger, slower "
                f"wavenumbers.")
    if draw:
        v = rec.values
        res.figures.append(FigureJob(scene.name, "dispersion", {"m": v["m"], "k": v["k"], "d": v["d"],
                                                                "n": v["n"], "finite": finite,
                                                                "packets": drawn}))


def recurrence_applies(model, n_modes: int) -> bool:
    """Whether an FPUT recurrence finding means anything: a nonlinear model
    (modes of its linearization exchange energy) with at least two modes
    followed. A linear model's modes keep their energy; one mode has no one
    to share it with."""
    return _recurrence(bool(model.linear), n_modes)


def _recurrence(linear: bool, n_modes: int) -> bool:
    """:func:`recurrence_applies` from the model's recorded linearity."""
    return (not linear) and n_modes >= 2


def _modal(scene, specs, records, res, draw):
    series, t_all, omega_all = {}, None, None
    linear = True  # no run recorded: no recurrence is claimed
    for s in specs:
        rec = records[s.key]
        if "fraction" not in rec.arrays:
            _failed(res, s, rec)
            continue
        t, frac, omega = rec.arrays["t"], rec.arrays["fraction"], rec.arrays["omega"]
        t_all, omega_all = t, omega
        linear = bool(rec.values.get("linear", True))
        label = f"{s.solver} {scene.method(s.solver).setting_name}={s.setting:g}"
        series[label] = frac
        for j in range(frac.shape[0]):
            f = frac[j]
            i_min = int(np.nanargmin(f)) if np.isfinite(f).any() else 0
            row = {"scene": scene.name, "solver": s.solver, "setting": float(s.setting), "mode": j + 1,
                   "omega_rad_s": float(omega[j]), "fraction_start": float(f[0]), "fraction_min": float(f[i_min]),
                   "t_min": float(t[i_min]), "status": rec.status}
            if j > 0 and np.isfinite(f).any():  # a mode that starts empty: its largest share
                i_pk = int(np.nanargmax(f))
                row.update(fraction_peak=float(f[i_pk]), t_peak=float(t[i_pk]))
            elif i_min < f.size - 1 and np.isfinite(f[i_min:]).any():
                i_ret = i_min + int(np.nanargmax(f[i_min:]))
                row.update(fraction_peak=float(f[i_ret]), t_peak=float(t[i_ret]))
                if _recurrence(linear, frac.shape[0]):
                    res.findings.append(
                        f"{scene.name}: {label}: mode 1 holds {f[0]:.1%} of the energy at t = 0, falls to "
                        f"{f[i_min]:.1%} at t = {t[i_min]:.4g} s and returns to {f[i_ret]:.1%} at "
                        f"t = {t[i_ret]:.4g} s (FPUT recurrence).")
            else:
                row.update(fraction_peak=math.nan, t_peak=math.nan)
            res.add("modal_energy", row)
    if draw and series:
        res.figures.append(FigureJob(scene.name, "modal_energy", {
            "t": t_all, "series": series, "omega": omega_all,
            "recurrence": _recurrence(linear, len(omega_all))}))


def _linearization(scene, specs, records, res):
    for s, rec in _with_values(specs, records, res):
        v = rec.values
        res.add("linearization", {"scene": scene.name, "amplitude_q": v["amplitude_q"],
                                  "error_max_q": v["error_max_q"], "error_rel_q": v["error_rel_q"]})


def _state_figure(scene, specs, records, res):
    draw = "figures" in scene.outputs
    for s in specs:
        rec = records[s.key]
        if "y" not in rec.arrays:
            if s.purpose == "figure":
                continue  # an unstable RK4 run: no figure, its status is in the accuracy table
            _failed(res, s, rec)
            continue
        title = (f"{scene.name}: {s.solver}, h = {s.setting:g} s" if s.purpose == "figure"
                 else f"{scene.name}: reference ({rec.values.get('truth_kind', '')})")
        if draw:
            from .execute import recorded_modal
            from .look import recorded_look

            res.figures.append(FigureJob(scene.name, "state", {"t": rec.arrays["t"], "y": rec.arrays["y"],
                                                               "title": title, "look": recorded_look(rec),
                                                               "thesis": getattr(scene, "thesis_figures", ""),
                                                               "modal": recorded_modal(rec)}))
        return


# -- stability ------------------------------------------------------------------------------
def _stability(scene, specs, records, res, quick):
    from . import stability

    results = {}
    for s in specs:
        rec = records[s.key]
        if rec.result is None:
            results[s.unit] = stability.failed_unit(scene, s.unit, rec.message)
        else:
            results[s.unit] = stability.StudyResult(rows=list(rec.result["rows"]),
                                                    findings=list(rec.result["findings"]),
                                                    plots=list(rec.result["plots"]))
    study = stability.assemble(scene, quick, results)
    for row in study.rows:
        res.add("stability", row)
        passed = row.get("passed")
        if isinstance(passed, (bool, np.bool_)):
            res.check(f"stability {row.get('quantity')}", bool(passed),
                      f"{scene.name}: stability {row.get('solver')} {row.get('quantity')}"
                      f"{_params_text(row)}: measured {row.get('measured')}, theory {row.get('theory')}",
                      row.get("measured", math.nan), row.get("theory", math.nan))
    res.findings.extend(study.findings)
    for p in study.plots:
        res.figures.append(FigureJob(scene.name, "stability", {"plot": p}))


#: The measurements the output modules delegate to (rk4h.validation.outputs).
measure_runs = _runs
measure_state_figure = _state_figure
measure_linearization = _linearization
measure_convergence = _convergence
measure_modes = _modes
measure_dispersion = _dispersion
measure_modal = _modal
measure_stability = _stability
measure_thesis_code = _thesis_code


def _params_text(row) -> str:
    from . import stability

    bits = [f"{c}={row[c]:g}" for c in stability.PARAM_COLUMNS
            if isinstance(row.get(c), (int, float)) and math.isfinite(row[c])]
    return f" ({', '.join(bits)})" if bits else ""
