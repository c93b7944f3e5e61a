"""Drawing of the stability study's plot descriptions: the only module of the
study that imports matplotlib (through :mod:`validation.figures`, whose style
it shares: size, dpi, solver colours and markers, a title on every figure,
file names ``<scene>_stability_<name>.png``).

A plot description is plain data made by :func:`validation.stability.run_unit`
or :func:`validation.stability.assemble`: ``{"kind", "scene", "study",
"name", "data"}``. :func:`draw` computes nothing but display aids (axis
windows, guide lines).
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from .. import figures as F

__all__ = ["draw", "KINDS"]


def _stem(plot) -> str:
    return f"{F.slug(plot['scene'])}_stability_{F.slug(plot.get('name') or plot['kind'])}"


def _log_axes(ax, x=True, y=True):
    """Log scales, the figures' grid, and no minor tick labels; an axis
    spanning under two decades gets plain major ticks at 1, 2, 5 x 10^k."""
    from matplotlib import ticker

    for on, axis, lim in ((x, ax.xaxis, ax.get_xlim), (y, ax.yaxis, ax.get_ylim)):
        if not on:
            continue
        (ax.set_xscale if axis is ax.xaxis else ax.set_yscale)("log")
        lo, hi = sorted(lim())
        axis.set_minor_formatter(ticker.NullFormatter())
        if lo > 0 and math.log10(hi / lo) < 2:
            axis.set_major_locator(ticker.LogLocator(base=10, subs=(1.0, 2.0, 5.0)))
            axis.set_major_formatter(ticker.FormatStrFormatter("%g"))
    ax.grid(which="major", alpha=0.3)
    ax.grid(which="minor", alpha=0.1)


def _growth(plot, out_dir):
    d = plot["data"]
    fig = F._new_figure()
    F._suptitle(fig, f"{plot['scene']}: growth per step of the fastest mode against omega h")
    ax = fig.subplots()
    for meth, g in d["theory"].items():
        color, marker = F.solver_style(meth)
        ax.plot(d["theta_line"], g, color=color, lw=1.2, label=f"{meth} theory")
        ax.plot(d["theta"], d["measured"][meth], marker, mfc="none", color=color, ls="none", ms=6,
                label=f"{meth} measured")
    ax.axhline(1.0, color="0.35", lw=0.8, ls="-", label="growth 1")
    for meth, th in d["boundary"].items():
        color, _ = F.solver_style(meth)
        ax.axvline(th, color=color, ls=":", lw=1.0, label=f"{meth} boundary {th:.3g}")
    ax.set_yscale("log")
    ax.grid(which="major", alpha=0.3)
    ax.set_xlabel("omega_max h")
    ax.set_ylabel("growth factor per step")
    fig.legend(loc="outside lower center", ncol=3, fontsize=7, frameon=False)
    path = F._save(fig, out_dir, _stem(plot))
    return path, ("Amplitude growth per step of the fastest mode against omega*h: RK4 stays <= 1 up to 2.83, "
                  "symplectic Euler is exactly 1 up to 2, explicit Euler exceeds 1 for every step; circles are "
                  "measured from integrated runs, lines the stability functions.")


def _drift(plot, out_dir):
    d = plot["data"]
    fig = F._new_figure()
    meth = d["method"]
    F._suptitle(fig, f"{plot['scene']}: {meth} energy loss and phase lag per step against theta = omega h")
    ax_e, ax_p = fig.subplots(1, 2)
    color, marker = F.solver_style(meth)
    line = d["theta_line"]
    (a_e, p_e), (a_p, p_p) = d["loss_leading"], d["lag_leading"]
    for ax, th_curve, lead, pts, ylabel, lab, lab_lead in (
            (ax_e, d["loss_theory"], a_e * line**p_e, d["energy_loss"], "relative energy loss per step",
             "theory 1 - |R(i theta)|^2", f"leading order {a_e:.4g} theta^{p_e}"),
            (ax_p, d["lag_theory"], a_p * line**p_p, d["phase_lag"], "phase lag per step (rad)",
             "theory theta - arg R(i theta)", f"leading order {a_p:.4g} theta^{p_p}")):
        # log axes show magnitudes: a negative loss is a gain, a negative lag a lead
        neg = bool(np.nanmax(th_curve) <= 0)
        ax.plot(line, np.abs(th_curve), "-", color=color, lw=1.2, label=lab)
        ax.plot(line, np.abs(lead), ":", color="0.35", lw=1.0, label=lab_lead)
        ax.plot(d["theta"], np.abs(pts), marker, mfc="none", color=color, ls="none", ms=6,
                label="measured (2000 steps)")
        _log_axes(ax)
        ax.set_xlabel("theta = omega_max h")
        ax.set_ylabel(ylabel.replace("loss", "gain").replace("lag", "lead") if neg else ylabel)
        ax.legend(fontsize=7, loc="upper left")
    path = F._save(fig, out_dir, _stem(plot))
    return path, (f"{meth} loses energy and phase at the rates its stability function predicts per step: "
                  "measured circles on the exact curves (solid), the leading-order terms dotted.")


def _long_energy(plot, out_dir):
    series = {label: (sd["t"], sd["err"]) for label, sd in plot["data"]["series"].items()}
    return F.energy_error(
        out_dir, plot["scene"], series, stem=_stem(plot),
        title=f"{plot['scene']}: relative energy error over the long horizon, the method and references",
        sentence=("Relative energy error over the long horizon, log-log: the fixed-step method dissipates "
                  "steadily (slope 1: 1 - |R(i theta)|^2 per step per mode until the fast mode is gone), heyoka "
                  "stays near its tolerance, CVODE-BDF (a shorter run, for cost) drifts at its own rate."))


def _roundoff(plot, out_dir):
    d = plot["data"]
    fig = F._new_figure()
    meth = d["method"]
    F._suptitle(fig, f"{plot['scene']}: {meth} error after one slow period against the step (round-off floor)")
    ax = fig.subplots()
    color, marker = F.solver_style(meth)
    h, err = d["h"], d["error"]
    order = int(d["order"])
    ax.plot(h, err, "-", color=color, marker=marker, ms=5, lw=1.2, label=f"{meth} error at t_end")
    i = int(np.nanargmin(err))
    ax.plot([d["h_best"]], [err[i]], "*", color="k", ms=14, ls="none", label=f"best h = {d['h_best']:.3g} s")
    ok = np.isfinite(err) & (err > 0)
    if ok.sum() >= 1:
        j = int(np.argmax(np.where(ok, h, -np.inf)))  # anchor the slope-4 guide at the largest step
        xs = np.array([h[ok].min(), h[j]])
        ax.plot(xs, err[j] * (xs / h[j]) ** order, "--", color="0.35", lw=1.0,
                label=f"slope {order} (truncation, h^{order})")
    _log_axes(ax)
    ax.set_ylim(bottom=max(float(np.nanmin(np.where(ok, err, np.nan))) / 10, 1e-18) if ok.any() else None)
    ax.set_xlabel("step size h (s)")
    ax.set_ylabel("max |q - q_exact| / max |q0|")
    ax.legend(fontsize=8, loc="lower right")
    path = F._save(fig, out_dir, _stem(plot))
    return path, (f"{meth} error against step: slope {order} down to the star (best h), below which accumulated "
                  "round-off makes the error grow again.")


def _cost(plot, out_dir):
    d = plot["data"]
    fig = F._new_figure()
    F._suptitle(fig, f"{plot['scene']}: cost of reaching error {d['target_error']:g} against the "
                     f"{'spring' if d['what'] == 'ratio' else 'mass'} ratio")
    ax_n, ax_t = fig.subplots(1, 2, sharex=True)
    for solver in F._in_palette_order(list(d["nfev"])):
        color, marker = F.solver_style(solver)
        x = d["x"]
        n, w = np.asarray(d["nfev"][solver], float), np.asarray(d["wall_s"][solver], float)
        lab = solver + (" (steps x Taylor order)" if solver == "heyoka" else "")
        if not np.isfinite(n).any():
            lab += " (not run / not reached)"
        ax_n.plot(x, n, "-", color=color, marker=marker, ms=5, lw=1.2, label=lab)
        ax_t.plot(x, w, "-", color=color, marker=marker, ms=5, lw=1.2)
    for ax, yl in ((ax_n, "right-hand-side evaluations"), (ax_t, "wall time of the run (s)")):
        _log_axes(ax)
        ax.set_xlabel(d["xlabel"])
        ax.set_ylabel(yl)
    fig.legend(loc="outside lower center", ncol=4, fontsize=7, frameon=False)
    path = F._save(fig, out_dir, _stem(plot))
    r = d["stiffness_ratio"]
    return path, (f"Cost of reaching error {d['target_error']:g} in one slow period against the "
                  f"{'spring' if d['what'] == 'ratio' else 'mass'} ratio (omega_max/omega_min "
                  f"{np.nanmin(r):.3g} to {np.nanmax(r):.3g}): the explicit methods' cost grows with omega_max; "
                  f"BDF's stays flat when the fast mode is not excited; missing points were skipped for cost or "
                  f"did not reach the target (see stability.csv).")


def _large_n(plot, out_dir):
    d = plot["data"]
    fits = d["fits"]
    fig = F._new_figure()
    F._suptitle(fig, f"{plot['scene']}: cost per step and memory against chain length N")
    ax_t, ax_b = fig.subplots(1, 2, sharex=True)
    N = d["n"]
    meth = d["method"]
    c_rk, m_rk = F.solver_style(meth)
    c_cv, m_cv = F.solver_style("cvode-bdf")
    ax_t.plot(N, d["wall_per_step"], "-", color=c_rk, marker=m_rk, label=f"{meth} (slope {fits['time']:.2f})")
    ax_t.plot(N, d["cvode_wall_per_step"], "-", color=c_cv, marker=m_cv,
              label=f"cvode-bdf band (slope {fits['cvode_time']:.2f})")
    ax_b.plot(N, d["peak_bytes"], "-", color=c_rk, marker=m_rk,
              label=f"{meth} peak bytes (slope {fits['bytes']:.2f})")
    for ax, y in ((ax_t, d["wall_per_step"]), (ax_b, d["peak_bytes"])):
        ax.plot(N, y[0] * N / N[0], ":", color="0.35", lw=1.0, label="slope 1 (O(N))")
        _log_axes(ax)
        ax.set_xlabel("N masses")
        ax.legend(fontsize=7)
    ax_t.set_ylabel("wall time per step (s)")
    ax_b.set_ylabel("peak bytes (tracemalloc)")
    path = F._save(fig, out_dir, _stem(plot))
    return path, "Cost per step and memory against chain length N: slopes near 1 (dotted) mean O(N) work and storage."


def _amplitude(plot, out_dir):
    d = plot["data"]
    a, err = d["a_over_l"], d["error"]
    fig = F._new_figure()
    F._suptitle(fig, f"{plot['scene']}: error of the linearized model against amplitude")
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
    ax.set_ylabel("max |q_nl - q_lin| / r0 over 5 periods")
    ax.legend(fontsize=8, loc="upper left")
    path = F._save(fig, out_dir, _stem(plot))
    return path, ("Relative error of the small-oscillation model over 5 periods against amplitude: grows like "
                  "(r/l)^2; read off the largest amplitude at which the cheap model is good enough.")


KINDS = {"growth": _growth, "drift": _drift, "long_energy": _long_energy, "roundoff": _roundoff, "cost": _cost,
         "large_n": _large_n, "amplitude": _amplitude}


def draw(plot: dict, out_dir) -> tuple[Path, str]:
    """Draw one plot description into ``out_dir``: ``(path, sentence)``.
    ValueError for a kind it does not know (e.g. a unit's part that
    :func:`validation.stability.assemble` has not merged)."""
    kind = plot.get("kind") if isinstance(plot, dict) else None
    if kind not in KINDS:
        raise ValueError(f"`plot` kind {kind!r} is not drawable (kinds: {', '.join(KINDS)}; parts are merged by "
                         f"validation.stability.assemble)")
    return KINDS[kind](plot, out_dir)
