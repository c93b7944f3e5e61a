"""Drawing of the stability study's plot descriptions: the only module of the
study that imports matplotlib (through :mod:`rk4h.validation.figures`, whose style
it shares: size, dpi, fonts (nothing under 8 pt), solver colours and markers,
a title on every figure, legends below the axes, log axes, file names
``<scene>_stability_<name>.png``).

A plot description is plain data made by :func:`rk4h.validation.stability.run_unit`
or :func:`rk4h.validation.stability.assemble`: ``{"kind", "scene", "study",
"name", "data"}``. :func:`draw` computes nothing but display aids (axis
windows, guide lines) and the numbers its sentence quotes from the data.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from matplotlib.lines import Line2D

from rk4h.references.registry import BUILTIN, with_role

from .. import figures as F
from ._common import FREQUENCY_RATIO, SWEEP_NAMES, cost_at_point, stiffest_index

__all__ = ["draw", "KINDS"]


def _stem(plot) -> str:
    return f"{F.slug(plot['scene'])}_stability_{F.slug(plot.get('name') or plot['kind'])}"


def _log_axes(ax, x=True, y=True):
    """The figures' log axes (:func:`rk4h.validation.figures.style.log_axes`)."""
    F.log_axes(ax, x=x, y=y)


def _caption(text, kind):
    return F.Caption(text, f"stability_{kind}")


def _growth(plot, out_dir):
    d = plot["data"]
    fig = F.new_figure()
    F.suptitle(fig, f"{plot['scene']}: growth per step of the fastest mode against omega h")
    ax = fig.subplots()
    line = np.asarray(d["theta_line"], float)
    for meth, g in d["theory"].items():
        color, marker = F.solver_style(meth)
        ax.plot(line, g, color=color, lw=1.2, label=f"{meth} theory")
        ax.plot(d["theta"], d["measured"][meth], marker, mfc="none", color=color, ls="none", ms=6,
                label=f"{meth} measured")
    ax.axhline(1.0, color="0.35", lw=0.8, ls="-", label="growth 1")
    for meth, th in d["boundary"].items():
        color, _ = F.solver_style(meth)
        ax.axvline(th, color=color, ls=":", lw=1.0, label=f"{meth} boundary {th:.3g}")
    _log_axes(ax, x=False)
    ax.set_xlabel("omega_max h")
    ax.set_ylabel("growth factor per step")
    F.legend_below(fig)
    path = F.save(fig, out_dir, _stem(plot))
    facts = []
    for meth, g in d["theory"].items():
        g = np.asarray(g, float)
        if meth in d["boundary"]:
            bits = [f"{meth} stable up to omega h = {d['boundary'][meth]:.3g}"]
        elif np.all(g[line > 0] > 1.0):
            bits = [f"{meth} grows (> 1) at every step"]
        else:
            bits = [meth]
        meas = np.asarray(d["measured"][meth], float)
        th = np.interp(np.asarray(d["theta"], float), line, g)
        ok = np.isfinite(meas) & np.isfinite(th) & (th > 0)
        if ok.any():
            bits.append(f"measured within {100 * np.max(np.abs(meas[ok] / th[ok] - 1)):.2g}% of theory")
        facts.append(", ".join(bits))
    return path, _caption(F.sentence(f"{plot['scene']}", *facts), "growth")


def _drift(plot, out_dir):
    d = plot["data"]
    fig = F.new_figure()
    meth = d["method"]
    F.suptitle(fig, f"{plot['scene']}: {meth} energy loss and phase lag per step against theta = omega h")
    ax_e, ax_p = fig.subplots(1, 2)
    color, marker = F.solver_style(meth)
    line = d["theta_line"]
    (a_e, p_e), (a_p, p_p) = d["loss_leading"], d["lag_leading"]
    facts = []
    for ax, th_curve, lead, pts, ylabel, lab, lab_lead, what in (
            (ax_e, d["loss_theory"], a_e * line**p_e, d["energy_loss"], "relative energy loss per step",
             "loss: theory 1 - |R(i theta)|^2", f"loss: leading order {a_e:.4g} theta^{p_e}", "energy loss"),
            (ax_p, d["lag_theory"], a_p * line**p_p, d["phase_lag"], "phase lag per step (rad)",
             "lag: theory theta - arg R(i theta)", f"lag: leading order {a_p:.4g} theta^{p_p}", "phase lag")):
        # log axes show magnitudes: a negative loss is a gain, a negative lag a lead
        neg = bool(np.nanmax(th_curve) <= 0)
        ax.plot(line, np.abs(th_curve), "-", color=color, lw=1.2, label=lab)
        ax.plot(line, np.abs(lead), ":", color="0.35", lw=1.0, label=lab_lead)
        ax.plot(d["theta"], np.abs(pts), marker, mfc="none", color=color, ls="none", ms=6,
                label="measured (2000 steps)")
        _log_axes(ax)
        ax.set_xlabel("theta = omega_max h")
        ax.set_ylabel(ylabel.replace("loss", "gain").replace("lag", "lead") if neg else ylabel)
        th = np.interp(np.asarray(d["theta"], float), np.asarray(line, float), np.abs(np.asarray(th_curve, float)))
        meas = np.abs(np.asarray(pts, float))
        ok = np.isfinite(meas) & (th > 0)
        if ok.any():
            facts.append(f"measured {what} within {100 * np.max(np.abs(meas[ok] / th[ok] - 1)):.2g}% of theory "
                         f"at theta {np.min(np.asarray(d['theta'])[ok]):.3g}-{np.max(np.asarray(d['theta'])[ok]):.3g}")
    F.legend_below(fig)
    path = F.save(fig, out_dir, _stem(plot))
    facts.append(f"leading terms {a_e:.4g} theta^{p_e} (loss) and {a_p:.4g} theta^{p_p} (lag)")
    return path, _caption(F.sentence(f"{plot['scene']}: {meth}", *facts), "drift")


def _long_energy(plot, out_dir):
    series = {label: (sd["t"], sd["err"]) for label, sd in plot["data"]["series"].items()}
    return F.energy_error(
        out_dir, plot["scene"], series, stem=_stem(plot), kind="stability_long_energy",
        title=f"{plot['scene']}: relative energy error over the long horizon, the method and references")


def _roundoff(plot, out_dir):
    d = plot["data"]
    fig = F.new_figure()
    meth = d["method"]
    F.suptitle(fig, f"{plot['scene']}: {meth} error after one slow period against the step (round-off floor)")
    ax = fig.subplots()
    color, marker = F.solver_style(meth)
    h, err = np.asarray(d["h"], float), np.asarray(d["error"], float)
    order = int(d["order"])
    ax.plot(h, err, "-", color=color, marker=marker, ms=5, lw=1.2, label=f"{meth} error at t_end")
    i = int(np.nanargmin(err))
    ax.plot([d["h_best"]], [err[i]], "*", color="k", ms=14, ls="none", label=f"best h = {d['h_best']:.3g} s")
    ok = np.isfinite(err) & (err > 0)
    if ok.sum() >= 1:
        j = int(np.argmax(np.where(ok, h, -np.inf)))  # anchor the slope guide at the largest step
        xs = np.array([h[ok].min(), h[j]])
        ax.plot(xs, err[j] * (xs / h[j]) ** order, "--", color="0.35", lw=1.0,
                label=f"slope {order} (truncation, h^{order})")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_ylim(bottom=max(float(np.nanmin(np.where(ok, err, np.nan))) / 10, 1e-18) if ok.any() else None)
    _log_axes(ax)
    ax.set_xlabel("step size h (s)")
    ax.set_ylabel("max |q - q_exact| / max |q0| (relative)")
    F.legend_below(fig)
    path = F.save(fig, out_dir, _stem(plot))
    facts = [f"smallest error {err[i]:.2g} at h = {d['h_best']:.3g} s"]
    if ok.any():
        facts.append(f"error {err[j]:.2g} at the largest step h = {h[j]:.3g} s")
        small = ok & (h < d["h_best"])
        if small.any():
            k = int(np.argmin(np.where(small, h, np.inf)))
            facts.append(f"and {err[k]:.2g} at the smallest, h = {h[k]:.3g} s (round-off)")
    return path, _caption(F.sentence(f"{plot['scene']}: {meth}", *facts), "roundoff")


def _fold(x, ratio, tol=1e-9):
    """For each point, whether it is the mirror (``x < 1``) of a point ``1/x``
    with the same stiffness ratio: the same system, masses swapped and time
    rescaled, drawn at ``1/x``. Returns a boolean mask (True: mirrored)."""
    x, ratio = np.asarray(x, float), np.asarray(ratio, float)
    mirrored = np.zeros(x.shape, bool)
    for i in np.flatnonzero(x < 1):
        partner = np.isclose(x, 1.0 / x[i], rtol=tol) & np.isclose(ratio, ratio[i], rtol=1e-6)
        mirrored[i] = bool(partner.any())
    return mirrored


def _cost(plot, out_dir):
    d = plot["data"]
    fig = F.new_figure()
    what = "spring" if d["what"] == "ratio" else "mass"
    x = np.asarray(d["x"], float)
    mirrored = _fold(x, d["stiffness_ratio"]) if d["what"] != "ratio" else np.zeros(x.shape, bool)
    folded = bool(mirrored.any())
    F.suptitle(fig, f"{plot['scene']}: cost of reaching error {d['target_error']:g} (relative, one slow period) "
                     f"against the {what} ratio")
    ax_n, ax_t = fig.subplots(1, 2, sharex=True)
    xd = np.where(mirrored, 1.0 / x, x)
    main = ~mirrored
    facts = []
    for solver in F.in_palette_order(list(d["nfev"])):
        color, marker = F.solver_style(solver)
        n, w = np.asarray(d["nfev"][solver], float), np.asarray(d["wall_s"][solver], float)
        meth = BUILTIN.get(solver)
        lab = solver + (" (steps x Taylor order)" if meth is not None and meth.taylor else "")
        if not np.isfinite(n).any():
            lab += " (not run / not reached)"
        order = np.argsort(xd[main])
        for ax, y in ((ax_n, n), (ax_t, w)):
            ax.plot(xd[main][order], y[main][order], "-", color=color, marker=marker, ms=5, lw=1.2,
                    label=lab if ax is ax_n else None)
            if folded:  # the mirrored points, on the curve when the costs agree
                ax.plot(xd[mirrored], y[mirrored], marker, mfc="none", color=color, ms=9, ls="none")
    for ax, yl in ((ax_n, "right-hand-side evaluations"), (ax_t, "wall time of the run (s)")):
        _log_axes(ax)
        ax.set_xlabel("mass ratio max(mu, 1/mu)" if folded else d["xlabel"])
        ax.set_ylabel(yl)
    F.legend_below(fig, title=("hollow: mu < 1 drawn at 1/mu (masses swapped: the same omega_max/omega_min)"
                                if folded else None))
    path = F.save(fig, out_dir, _stem(plot))
    r = np.asarray(d["stiffness_ratio"], float)
    # the stiffest point, the one the study's finding and the limits table quote
    k = stiffest_index(x, r)
    status = d.get("status", {})
    for solver in F.in_palette_order(list(d["nfev"])):
        st = status[solver][k] if solver in status else ("ok" if math.isfinite(d["nfev"][solver][k]) else "not reached")
        facts.append(cost_at_point(solver, float(d["nfev"][solver][k]), st))
    name = SWEEP_NAMES.get(d["what"], f"{what} ratio")
    head = (f"{plot['scene']}: target {d['target_error']:g}, {name} {x.min():g} to {x.max():g} "
            f"({FREQUENCY_RATIO} {np.nanmin(r):.3g} to {np.nanmax(r):.3g})")
    parts = [f"RHS evaluations at the stiffest point ({FREQUENCY_RATIO} {r[k]:.3g}, {name} = {x[k]:g}): "
             f"{', '.join(facts)}"]
    if folded:
        parts.append(f"{int(mirrored.sum())} point(s) mu < 1 folded onto 1/mu, where the same {FREQUENCY_RATIO} gives "
                     f"the same system")
    return path, _caption(F.sentence(head, *parts), "cost")


def _large_n(plot, out_dir):
    d = plot["data"]
    fits = d["fits"]
    fig = F.new_figure()
    F.suptitle(fig, f"{plot['scene']}: cost per step and memory against chain length N")
    ax_t, ax_b = fig.subplots(1, 2, sharex=True)
    N = np.asarray(d["n"], float)
    meth = d["method"]
    c_rk, m_rk = F.solver_style(meth)
    ref = d.get("reference") or with_role("banded")[0]  # older plot data name no reference
    c_cv, m_cv = F.solver_style(ref)
    ax_t.plot(N, d["wall_per_step"], "-", color=c_rk, marker=m_rk, label=f"time: {meth} (slope {fits['time']:.2f})")
    ax_t.plot(N, d["cvode_wall_per_step"], "-", color=c_cv, marker=m_cv,
              label=f"time: {ref} band (slope {fits['cvode_time']:.2f})")
    ax_b.plot(N, d["peak_bytes"], "-", color=c_rk, marker=m_rk,
              label=f"memory: {meth} peak bytes (slope {fits['bytes']:.2f})")
    for ax, y in ((ax_t, d["wall_per_step"]), (ax_b, d["peak_bytes"])):
        ax.plot(N, y[0] * N / N[0], ":", color="0.35", lw=1.0, label="slope 1 (O(N))")
        _log_axes(ax)
        ax.set_xlabel("N masses")
    ax_t.set_ylabel("wall time per step (s)")
    ax_b.set_ylabel("peak bytes (tracemalloc)")
    F.legend_below(fig)
    path = F.save(fig, out_dir, _stem(plot))
    return path, _caption(
        f"{plot['scene']}: N = {N.min():g} to {N.max():g}; fitted slopes {meth} time {fits['time']:.2f}, "
        f"cvode-bdf time {fits['cvode_time']:.2f}, {meth} memory {fits['bytes']:.2f}.", "large_n")


def _amplitude(plot, out_dir):
    d = plot["data"]
    a, err = np.asarray(d["a_over_l"], float), np.asarray(d["error"], float)
    fig = F.new_figure()
    F.suptitle(fig, f"{plot['scene']}: error of the linearized model against amplitude")
    ax = fig.subplots()
    color, marker = F.solver_style(d["method"])
    ax.plot(a, err, "-", color=color, marker=marker, ms=5, lw=1.2,
            label=f"measured (slope {d['slope']:.2f} for a/l <= 1e-2)")
    sel = np.isfinite(err) & (err > 0)
    if sel.any():
        i = int(np.argmin(np.abs(np.log(a[sel]) - math.log(1e-3))))
        ax.plot(a, err[sel][i] * (a / a[sel][i]) ** 2, ":", color="0.35", lw=1.0, label="slope 2 ((r/l)^2, theory)")
    _log_axes(ax)
    ax.set_xlabel("initial amplitude / l")
    ax.set_ylabel("max |q_nl - q_lin| / r0 over 5 periods (relative)")
    F.legend_below(fig)
    path = F.save(fig, out_dir, _stem(plot))
    facts = [f"measured slope {d['slope']:.2f}"]
    for level in (1e-2, 1e-4):
        below = sel & (err <= level)
        if below.any():
            facts.append(f"error <= {level:g} up to a/l = {a[below].max():.3g}")
    return path, _caption(F.sentence(f"{plot['scene']}: a/l = {a.min():.3g} to {a.max():.3g}", *facts), "amplitude")


def _region(plot, out_dir):
    """Stability regions in the complex plane of ``z = h lambda`` (data of
    :func:`rk4h.validation.stability.region.region_plot`): classical methods'
    ``|R(z)| = 1`` (solid) left, partitioned methods' ``rho(M(z)) = 1 +
    margin`` on ``q'' = lambda^2 q`` (dashed) right, each method's stable
    interval of the imaginary axis as a bar beside the axis."""
    d = plot["data"]
    groups = [(key, d[key]) for key in ("classical", "partitioned") if d[key]]
    fig = F.new_figure(F.SIZE_TALL)
    F.suptitle(fig, f"{plot['scene']}: stability regions in the complex plane of z = h lambda; bars: the stable "
                    f"interval of the imaginary axis")
    axes = fig.subplots(1, len(groups), squeeze=False,
                        width_ratios=[3.0 if k == "classical" else 1.4 for k, _ in groups])[0]
    handles, facts, used = [], [], set()
    spare = [c for c in F.plt_colors(10) if c not in {col for col, _ in F.all_styles().values()}] + F.plt_colors(10)
    for ax, (key, regions) in zip(axes, groups):
        part = key == "partitioned"
        x_span = float(regions[0]["x"][-1] - regions[0]["x"][0])
        for k, r in enumerate(regions):
            color = F.solver_style(r["name"])[0]
            if F.solver_style(r["name"]) == F.UNKNOWN_STYLE or color in used:  # a method with no colour of its own
                color = next((c for c in spare if c not in used), color)
            used.add(color)
            level = 1.0 + (d["rho_margin"] if part else 0.0)
            ax.contour(r["x"], r["y"], r["amp"], levels=[level], colors=[color], linestyles="--" if part else "-",
                       linewidths=1.3)
            y_star = r["interval"]
            if math.isfinite(y_star) and y_star > 0:  # the bar, offset so that equal intervals stay apart
                off = (1 if part else -1) * 0.014 * x_span * (k + 1)
                ax.plot([off, off], [-y_star, y_star], color=color, lw=3.0, alpha=0.75, solid_capstyle="butt")
            text = (f"|Im z| <= {r['crossing']:.7f}" if math.isfinite(y_star) and y_star > 0 else
                    "no interval" if y_star == 0 else "the whole axis")
            handles.append(Line2D([], [], color=color, ls="--" if part else "-", lw=1.3,
                                  label=f"{r['name']}: {text}"))
            on_axis = part and float(np.nanmin(r["amp"])) >= 1.0 - 1e-9
            facts.append(f"{r['name']} " + (f"stable for |Im z| <= {r['crossing']:.7f}" if y_star > 0 and
                                             math.isfinite(y_star) else "on no interval of the imaginary axis"
                                             if y_star == 0 else "on the whole imaginary axis")
                         + (" and nowhere off it (det M = 1: symplectic)" if on_axis else ""))
        ax.axhline(0.0, color="0.6", lw=0.6)
        ax.axvline(0.0, color="0.6", lw=0.6)
        ax.set_xlim(regions[0]["x"][0], regions[0]["x"][-1])
        ax.set_ylim(-d["im_max"], d["im_max"])
        if not part:
            ax.set_aspect("equal", adjustable="box")
        ax.set_xlabel("Re z")
        ax.set_ylabel("Im z")
        ax.set_title("|R(z)| = 1 on y' = lambda y" if not part else
                     f"q'' = lambda^2 q: rho(M(z)) = {1 + d['rho_margin']:g}", fontsize=F.FONT_SMALL)
    F.legend_below(fig, handles, [h.get_label() for h in handles])
    path = F.save(fig, out_dir, _stem(plot))
    return path, _caption(F.sentence(f"{plot['scene']}", *facts), "region")


KINDS = {"growth": _growth, "drift": _drift, "long_energy": _long_energy, "roundoff": _roundoff, "cost": _cost,
         "large_n": _large_n, "amplitude": _amplitude, "region": _region}


def draw(plot: dict, out_dir) -> tuple[Path, str]:
    """Draw one plot description into ``out_dir``: ``(path, caption)``, the
    caption a :class:`rk4h.validation.figures.Caption` of kind ``"stability_" +
    plot["kind"]``. ValueError for a kind it does not know (e.g. a unit's
    part that :func:`rk4h.validation.stability.assemble` has not merged)."""
    kind = plot.get("kind") if isinstance(plot, dict) else None
    if kind not in KINDS:
        raise ValueError(f"`plot` kind {kind!r} is not drawable (kinds: {', '.join(KINDS)}; parts are merged by "
                         f"rk4h.validation.stability.assemble)")
    return KINDS[kind](plot, out_dir)
