"""The eight studies, each ``study(ctx) -> StudyResult``; ``ctx`` carries the
scene name, model, initial state, validated parameters, mode and output dir."""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from . import boundary as B
from . import geometry as G
from . import large_n as LN
from . import long_horizon as LH
from . import mass_ratio as MR
from . import plots
from . import stiffness as ST
from ._common import StudyResult, integrate_fixed, row
from .params import pick

__all__ = ["Context", "STUDY_FUNCTIONS"]

REL_BOUNDARY = 0.005  # issue 6: boundaries within 0.5 % of theory
REL_DRIFT = 0.02      # issue 6: drift and phase rates within 2 % where theta <= 0.5


@dataclass
class Context:
    scene: str
    model: object
    y0: np.ndarray
    params: dict
    quick: bool
    out_dir: object
    progress: object = None

    def say(self, text):
        if self.progress is not None:
            self.progress(f"stability {self.scene}: {text}")


def _needs_linear(ctx, study):
    if ctx.model.linear:
        return None
    r = StudyResult()
    r.rows.append(row(ctx.scene, "-", f"{study}", math.nan, status="skipped",
                      note=f"{study} needs a linear model; {ctx.model.name} is nonlinear"))
    return r


def boundary(ctx: Context) -> StudyResult:
    if (skip := _needs_linear(ctx, "boundary")) is not None:
        return skip
    res, s, m = StudyResult(), ctx.scene, ctx.model
    modes = m.modes()
    w = float(modes[0][-1])
    for meth in ("rk4", "symplectic-euler", "euler"):
        h_star, probes = B.largest_stable_step(m, meth, ctx.params["bisection_rtol"], w)
        h_th = B.theory_boundary(meth, w)
        if h_th > 0:
            ok = abs(h_star / h_th - 1) <= REL_BOUNDARY
        else:
            ok = h_star == 0.0
        res.rows.append(row(s, meth, "largest_stable_h_s", h_star, h_th, ok, note=(
            f"omega_max = {w:.6g} rad/s; bisection on rho(S(h)) <= 1 + {B.STABLE_TOL:g}, rtol "
            f"{ctx.params['bisection_rtol']:g}, {probes} probes"
            + ("; no stable h down to omega h = 1e-5" if meth == "euler" else ""))))
        if h_th > 0:
            res.findings.append(f"{s}: {meth} largest stable step {h_star:.6g} s = {h_star * w:.5f}/omega_max "
                                f"(theory {h_th * w:.5f}/omega_max)")
    for th in (1e-3, 0.1, 0.5, 1.0):
        g, _ = B.measured_growth(m, "euler", th, modes=modes)
        g_th = math.sqrt(1 + th * th)
        res.rows.append(row(s, "euler", f"growth_per_step(theta={th:g})", g, g_th,
                            abs((g - 1) / (g_th - 1) - 1) <= 1e-6,
                            note="fastest mode, integrated run; passed: (g-1) within 1e-6 relative"))
    # growth figure data
    thetas = ctx.params["growth_theta"]
    measured = {}
    for meth in ("rk4", "euler", "symplectic-euler"):
        pts = [B.measured_growth(m, meth, th, modes=modes)[0] for th in thetas]
        measured[meth] = (thetas, pts)
    line = np.linspace(1e-3, max(thetas) * 1.05, 400)
    theory = {meth: B.theory_growth(meth, line) for meth in measured}
    res.figures.append(plots.growth_figure(ctx.out_dir, s, line, theory, measured))
    # deliberate blow-ups: rows with status unstable and the time
    for meth, h, n in (("rk4", 1.2 * B.theory_boundary("rk4", w), 3000), ("euler", 1.0 / w, 6000)):
        r = B.blowup_run(m, meth, h, n)
        blew = r.status == -1 and r.t_fail is not None and math.isfinite(r.t_fail)
        g = float(B.theory_growth(meth, h * w))
        res.rows.append(row(s, meth, f"blowup_time_s(theta={h * w:.3g})",
                            r.t_fail if blew else math.nan, math.nan, blew,
                            status="unstable" if blew else "ok",
                            note=f"{r.message}; theory growth {g:.4g} per step"))
    return res


def long_horizon(ctx: Context) -> StudyResult:
    if (skip := _needs_linear(ctx, "long_horizon")) is not None:
        return skip
    res, s, m, p = StudyResult(), ctx.scene, ctx.model, ctx.params
    omega = m.modes()[0]
    w_hi, w_lo = float(omega[-1]), float(omega[omega > 0][0])
    pts = {"theta": [], "energy_loss": [], "phase_lag": []}
    for th in p["drift_theta"]:
        d = LH.measure_drift_and_phase(m, ctx.y0, th / w_hi, 2000)
        th_m = d["theta"][-1]
        e_th = float(LH.rk4_energy_loss_per_step(th_m))
        p_th = float(LH.rk4_phase_lag_per_step(th_m))
        e_lead, p_lead = th_m**6 / 72, th_m**5 / 120
        checked = th_m <= 0.5
        res.rows.append(row(s, "rk4", f"energy_loss_per_step(theta={th_m:.3g})", d["energy_loss"][-1], e_th,
                            abs(d["energy_loss"][-1] / e_th - 1) <= REL_DRIFT if checked else None,
                            note=f"theory 1-|R(i theta)|^2; leading order theta^6/72 = {e_lead:.6g}"))
        res.rows.append(row(s, "rk4", f"phase_lag_per_step(theta={th_m:.3g})", d["phase_lag"][-1], p_th,
                            abs(d["phase_lag"][-1] / p_th - 1) <= REL_DRIFT if checked else None,
                            note=f"theory theta - arg R(i theta); leading order theta^5/120 = {p_lead:.6g}"))
        for key in pts:
            pts[key].append(d[key][-1] if key != "theta" else th_m)
    # the long run
    periods = pick(p, "long_periods", ctx.quick)
    h = p["long_theta"] / w_hi
    t_end = periods * 2 * math.pi / w_lo
    n = int(math.ceil(t_end / h))
    ctx.say(f"long RK4 run: {periods:g} periods, {n} steps")
    d = LH.measure_drift_and_phase(m, ctx.y0, h, n, record_every=max(1, n // 20000))
    if d["path"] != "fast" and n > 2_000_000:
        res.rows.append(row(s, "rk4", "long_run", math.nan, status="skipped", note="no compiled path"))
    series = {"rk4": (d["t"], d["rel_energy_error"])}
    for j, th in enumerate(d["theta"]):
        e_th, p_th = float(LH.rk4_energy_loss_per_step(th)), float(LH.rk4_phase_lag_per_step(th))
        res.rows.append(row(s, "rk4", f"long_energy_loss_per_step(mode={j + 1},theta={th:.3g})",
                            d["energy_loss"][j], e_th, abs(d["energy_loss"][j] / e_th - 1) <= REL_DRIFT,
                            note=f"{periods:g} periods of the slowest mode, {n} steps; fitted over steps "
                                 f"0..{d['steps_fitted'][j]:.0f} (while the mode is above 1e-6 of its start)"))
        res.rows.append(row(s, "rk4", f"long_phase_lag_per_step(mode={j + 1},theta={th:.3g})",
                            d["phase_lag"][j], p_th, abs(d["phase_lag"][j] / p_th - 1) <= REL_DRIFT,
                            note=f"{periods:g} periods, {n} steps; fitted over steps 0..{d['steps_fitted'][j]:.0f}"))
    final = float(d["rel_energy_error"][-1])
    res.findings.append(f"{s}: RK4 at omega_max h = {p['long_theta']:g} over {periods:g} periods: "
                        f"relative energy change {final:.3g} (RK4 dissipates: theta^6/72 per step per mode)")
    ref_periods = min(periods, pick(p, "reference_periods", ctx.quick))
    for solver, rtol in (("heyoka", 1e-12), ("cvode-bdf", 1e-10)):
        per = periods if solver == "heyoka" else ref_periods
        ctx.say(f"{solver} drift over {per:g} periods")
        run, t, err = LH.reference_drift(solver, m, ctx.y0, per * 2 * math.pi / w_lo, rtol)
        if run is None:
            res.rows.append(row(s, solver, "energy_drift_per_period", math.nan, status="skipped",
                                note="references.solvers not installed"))
            continue
        ok = run.ok
        res.rows.append(row(s, solver, "energy_drift_per_period", err[-1] / per if ok else math.nan,
                            status="ok" if ok else run.status.value, passed=None, note=(
                                f"rtol {rtol:g}, {per:g} periods (RK4: {periods:g}), |E_end-E0|/E0 = "
                                f"{err[-1]:.3g}, wall {run.wall_s:.3g} s; {run.message}")))
        if ok:
            series[f"{solver} (rtol {rtol:g}, {per:g} periods)"] = (t, err)
    line = np.logspace(np.log10(min(pts["theta"]) / 2), np.log10(0.6), 100)
    res.figures.append(plots.drift_figure(ctx.out_dir, s, line, LH.rk4_energy_loss_per_step(line),
                                          LH.rk4_phase_lag_per_step(line),
                                          {k: np.array(v) for k, v in pts.items()}, series))
    return res


def roundoff(ctx: Context) -> StudyResult:
    if (skip := _needs_linear(ctx, "roundoff")) is not None:
        return skip
    res, s, m = StudyResult(), ctx.scene, ctx.model
    omega = m.modes()[0]
    w_hi, w_lo = float(omega[-1]), float(omega[omega > 0][0])
    thetas = pick(ctx.params, "roundoff_theta", ctx.quick)
    t_end = 2 * math.pi / w_lo
    h, err, paths = LH.roundoff_sweep(m, ctx.y0, t_end, [th / w_hi for th in thetas])
    i = int(np.nanargmin(err))
    turned = i < len(err) - 1 and err[-1] > err[i]
    res.rows.append(row(s, "rk4", "best_h_s", h[i], math.nan, None, note=(
        f"error {err[i]:.3g} at omega_max h = {h[i] * w_hi:.3g}; one slow period; paths {sorted(set(paths))}")))
    res.rows.append(row(s, "rk4", "roundoff_floor_error", err[i], math.nan, None))
    res.rows.append(row(s, "rk4", "error_turns_up_below_best_h", float(turned), 1.0, turned,
                        note=f"error at smallest h ({h[-1]:.3g} s): {err[-1]:.3g}"))
    res.figures.append(plots.roundoff_figure(ctx.out_dir, s, h, err, h[i]))
    res.findings.append(f"{s}: RK4 best step {h[i]:.3g} s (omega_max h = {h[i] * w_hi:.3g}) gives error "
                        f"{err[i]:.3g}; smaller steps lose to round-off" if turned else
                        f"{s}: RK4 error still falling at the smallest h probed ({h[-1]:.3g} s)")
    return res


def _cost_sweep(ctx, xs, build, xlabel, what):
    res, s = StudyResult(), ctx.scene
    solvers = ["rk4", "dop853", "cvode-bdf", "heyoka"]
    curves = {sv: ([], [], []) for sv in solvers}
    target = ctx.params["target_error"]
    for x in xs:
        model, y0 = build(x)
        w = model.modes()[0]
        big = w[-1] / w[w > 0][0] > (1e3 if ctx.quick else 1e4)
        ctx.say(f"{what} {x:g}")
        recs = ST.cost_at_target(model, y0, target, solvers,
                                 skip=lambda sv, big=big: sv == "dop853" and big and what == "ratio",
                                 rtol_ladder=ST.RTOL_LADDER_QUICK if ctx.quick else ST.RTOL_LADDER)
        for r in recs:
            res.rows.append(row(s, r["solver"], f"nfev_at_error_{target:g}({what}={x:g})", r["nfev"],
                                math.nan, r["status"] == "ok" if r["status"] != "skipped" else None,
                                status=r["status"], note=(
                                    f"stiffness ratio {r['stiffness_ratio']:.3g}; setting {r['setting']:.3g}; "
                                    f"error {r['error']:.3g}; steps {r['n_steps']}; wall {r['wall_s']:.3g} s; "
                                    f"{r['note']}")))
            c = curves[r["solver"]]
            c[0].append(r["stiffness_ratio"])
            c[1].append(r["nfev"] if r["status"] == "ok" else math.nan)
            c[2].append(r["wall_s"] if r["status"] == "ok" else math.nan)
        rk = recs[0]
        if rk["status"] == "ok" and what == "ratio":
            h_stab = 2 * math.sqrt(2) / rk["omega_max"]
            res.rows.append(row(s, "rk4", f"h_at_target_over_h_stab({what}={x:g})", rk["setting"] / h_stab,
                                math.nan, None, note="1 (x0.99) = step forced by stability, not accuracy"))
    curves = {k: tuple(np.array(v, float) for v in c) for k, c in curves.items()}
    res.figures.append(plots.cost_figure(ctx.out_dir, f"{s}_{what}", curves, "stiffness ratio omega_max/omega_min"))
    rk, bdf = curves["rk4"], curves["cvode-bdf"]
    res.findings.append(f"{s}: at stiffness ratio {rk[0][-1]:.3g} RK4 needs {rk[1][-1]:.3g} RHS evaluations "
                        f"({rk[2][-1]:.3g} s) to reach {target:g}, CVODE-BDF {bdf[1][-1]:.3g} ({bdf[2][-1]:.3g} s)")
    return res


def stiffness(ctx: Context) -> StudyResult:
    return _cost_sweep(ctx, pick(ctx.params, "stiffness_ratios", ctx.quick), ST.stiff_chain,
                       "spring ratio", "ratio")


def mass_ratio(ctx: Context) -> StudyResult:
    res, s = StudyResult(), ctx.scene
    eps = np.finfo(float).eps
    for mu in (1e-6, 1e-3, 1.0, 1e3, 1e6):
        cf, dec, eig = MR.closed_form_sq(1.0, 1.0, mu), MR.omega_sq_decimal(1.0, 1.0, mu), MR.omega_sq_eig(1.0, 1.0, mu)
        for i, name in enumerate(("low", "high")):
            res.rows.append(row(s, "closed-form", f"omega_{name}^2_vs_50_digits(mu={mu:g})", cf[i], dec[i],
                                abs(cf[i] / dec[i] - 1) <= 4 * eps, note="eq. 2.31, relative error <= 4 eps"))
            tol = 8 * eps * eig[1] / eig[0]  # eigenvalue error bound eps ||M^-1/2 K M^-1/2|| / lam
            res.rows.append(row(s, "closed-form", f"omega_{name}^2_vs_eig(mu={mu:g})", cf[i], eig[i],
                                abs(cf[i] / eig[i] - 1) <= tol, note=f"tolerance {tol:.2g} (eigh's bound)"))
            if mu != 1.0:
                lim = MR.omega_sq_limits(1.0, 1.0, mu)
                x = min(mu, 1 / mu)
                res.rows.append(row(s, "closed-form", f"omega_{name}^2_vs_limit(mu={mu:g})", cf[i], lim[i],
                                    abs(cf[i] / lim[i] - 1) <= x * x,
                                    note="two-term expansion, remainder O(mu^2) (or O(mu^-2))"))
    try:
        from references.closed_forms import two_dof_equal_k
        two_dof_equal_k(1.0, m1=1.0, mu=0.0)
        refused, msg = False, "mu = 0 accepted"
    except ValueError as e:
        refused, msg = True, str(e)
    res.rows.append(row(s, "closed-form", "mu_le_0_refused", float(refused), 1.0, refused, note=msg))
    res.extend(_cost_sweep(ctx, pick(ctx.params, "mu", ctx.quick), ST.mass_ratio_chain, "mass ratio", "mu"))
    return res


def large_n(ctx: Context) -> StudyResult:
    res, s = StudyResult(), ctx.scene
    Ns = [int(v) for v in pick(ctx.params, "n_values", ctx.quick)]
    t_rk, b_rk, t_cv, calls = [], [], [], []
    for N in Ns:
        ctx.say(f"large N = {N}")
        t, per_step, _ = LN.rk4_cost(N, n_steps=500, repeats=3)
        t_rk.append(t)
        calls.append(per_step)
        b_rk.append(LN.rk4_peak_bytes(N))
        t_cv.append(LN.cvode_band_cost(N)["wall_per_step"])
    fits = {"rk4_time": LN.fit_exponent(Ns, t_rk), "rk4_bytes": LN.fit_exponent(Ns, b_rk),
            "cvode_time": LN.fit_exponent(Ns, t_cv)}
    timing = "timing on a shared machine: reported, not asserted (tests/test_stability.py checks it, slow)"
    res.rows.append(row(s, "rk4", "rhs_calls_per_step", max(calls), 4.0, all(c == 4 for c in calls),
                        note=f"each call O(N); N = {Ns}"))
    res.rows.append(row(s, "rk4", "peak_memory_exponent", fits["rk4_bytes"], 1.0,
                        abs(fits["rk4_bytes"] - 1) <= 0.1, note=f"tracemalloc peak, N = {Ns}"))
    res.rows.append(row(s, "rk4", "cost_per_step_exponent", fits["rk4_time"], 1.0, None,
                        note=f"wall per step, min of 3 repeats of 500 steps, N = {Ns}; {timing}"))
    res.rows.append(row(s, "cvode-bdf", "cost_per_step_exponent", fits["cvode_time"], 1.0, None,
                        note=f"banded solver, difference-quotient band Jacobian; {timing}"))
    res.figures.append(plots.large_n_figure(ctx.out_dir, s, np.array(Ns), np.array(t_rk), np.array(b_rk),
                                            np.array(t_cv), fits))
    res.findings.append(f"{s}: up to N = {Ns[-1]}, RK4 time per step ~ N^{fits['rk4_time']:.2f}, memory ~ "
                        f"N^{fits['rk4_bytes']:.2f}; CVODE-BDF (band) ~ N^{fits['cvode_time']:.2f}")
    return res


def _planar_params(ctx):
    """``{"m", "k", "l"}`` when the scene's model is drawn as the four-spring
    mass (:func:`geometry.four_spring_params`), else None."""
    return G.four_spring_params(ctx.model)


def amplitude(ctx: Context) -> StudyResult:
    res, s = StudyResult(), ctx.scene
    p = _planar_params(ctx)
    if p is None:
        res.rows.append(row(s, "-", "amplitude", math.nan, status="skipped", note=f"amplitude {G.FOUR_SPRING_NEEDS}"))
        return res
    a = np.array(ctx.params["amplitudes"])
    err = G.linearization_error(p, a)
    slope = G.amplitude_exponent(a[a >= 1e-5], err[a >= 1e-5])
    for ai, ei in zip(a, err):
        res.rows.append(row(s, "rk4", f"linearization_error(a/l={ai:g})", ei, math.nan, None,
                            note="max over 5 periods of |q_nl - q_lin| / r0"))
    res.rows.append(row(s, "rk4", "linearization_error_exponent", slope, 2.0, abs(slope - 2) <= 0.1,
                        note="fit over 1e-5 <= a/l <= 1e-2; cubic terms of V cancel by symmetry"))
    res.figures.append(plots.amplitude_figure(ctx.out_dir, s, a, err, slope))
    for tol in (1e-3, 1e-2):
        ok = a[err <= tol]
        res.findings.append(f"{s}: the linear model stays within {tol:g} of the exact geometry up to "
                            f"r0 = {ok.max() if ok.size else 0:.3g} l (Table 4.5's 3 l: error {err[-1]:.3g})")
    return res


def singular(ctx: Context) -> StudyResult:
    res, s = StudyResult(), ctx.scene
    p = _planar_params(ctx)
    if p is None:
        res.rows.append(row(s, "-", "singular", math.nan, status="skipped", note=f"singular {G.FOUR_SPRING_NEEDS}"))
        return res
    T = 2 * math.pi / math.sqrt(2 * p["k"] / p["m"])
    h, t_end = T / 200, 2 * T
    off = ctx.params["singular_offset"]
    out = G.singular_pass(p, off, h, t_end)
    res.rows.append(row(s, "rk4", f"closest_approach_m(offset={off:g})", out["d_min"], off,
                        out["status"] in ("singular", "ok", "unstable"), status=out["status"],
                        note=out["message"]))
    res.findings.append(f"{s}: aimed at an anchor with offset {off:g} m: {out['message']}")
    out = G.singular_pass(p, 0.0, h, t_end, start_on_anchor=True)
    t_fail = out["result"].t_fail
    res.rows.append(row(s, "rk4", "blowup_time_s(start_on_anchor)", t_fail if t_fail is not None else math.nan,
                        math.nan, out["status"] == "unstable", status=out["status"], note=out["message"]))
    return res


STUDY_FUNCTIONS = {"boundary": boundary, "stiffness": stiffness, "mass_ratio": mass_ratio,
                   "long_horizon": long_horizon, "roundoff": roundoff, "large_n": large_n,
                   "amplitude": amplitude, "singular": singular}

_ = integrate_fixed  # re-exported helper used by callers of this module
