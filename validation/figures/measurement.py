"""Measurement figures: work-precision, convergence, energy error, modal
energy, dispersion and the cross-scene crossover grid, each drawn from
measured tables or arrays the runner has already computed (nothing here
integrates, fits or measures). Every function writes one PNG and returns
``(path, Caption)``.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from rk4h.references.registry import UNDER_TEST

from . import style as kit
from .captions import Caption

__all__ = ["work_precision", "convergence", "energy_error", "modal_energy", "dispersion", "crossover",
           "ERROR_LABELS", "SAME_COST", "CROSSOVER_NONE", "CROSSOVER_EMPTY"]


# -- work-precision -------------------------------------------------------------
def _ok_rows(df, cols):
    """Rows with finite positive values in ``cols`` and, if there is a status
    column, status ``ok``."""
    keep = np.ones(len(df), dtype=bool)
    if "status" in df.columns:
        keep &= df["status"].astype(str).str.lower().str.replace("status.", "", regex=False).eq("ok").to_numpy()
    for c in cols:
        vals = np.asarray(df[c], dtype=float)
        keep &= np.isfinite(vals) & (vals > 0)
    return df[keep]



def _require(df, name, cols):
    missing = [c for c in cols if c not in df.columns]
    if missing:
        raise ValueError(f"`{name}` is missing column `{missing[0]}` (has {list(df.columns)})")


#: Axis label of the error the work-precision and convergence figures draw:
#: relative when the data carry ``error_rel`` (``error_max / max |y_ref|``,
#: dimensionless), else the absolute ``error_max``, whose components keep
#: their own SI units (positions in m, velocities in m/s).
ERROR_LABELS = {
    "error_rel": "relative error\nmax |y - y_ref| / max |y_ref|",
    "error_max": "max |y - y_ref| (each component\nin its unit: m, m/s, rad, rad/s)",
}
#: A solver whose costs on a panel span less than this factor is drawn there
#: as points labelled with their settings (a line would read as a wall).
SAME_COST = 1.5


def _error_column(df):
    """``"error_rel"`` when the frame has finite relative errors, else ``"error_max"``."""
    if "error_rel" in df.columns and np.isfinite(np.asarray(df["error_rel"], dtype=float)).any():
        return "error_rel"
    return "error_max"


def _setting_name(solver):
    try:
        return kit.method_of(solver).setting_name
    except (ValueError, AttributeError):
        return "setting"


def _label_settings(ax, x, y, settings, name, color):
    """Each point's setting beside it (skipping points within half a decade
    of error of the last labelled one, so labels do not collide)."""
    last = None
    for xi, yi, s in sorted(zip(x, y, settings), key=lambda r: r[1]):
        if last is not None and abs(math.log10(yi / last)) < 0.5:
            continue
        ax.annotate(f"{name} {s:g}", (xi, yi), xytext=(6, 0), textcoords="offset points", va="center",
                    ha="left", fontsize=kit.FONT_SMALL, color=color)
        last = yi


def work_precision(out_dir, scene_name, df) -> tuple[Path, str]:
    """Work-precision diagram: error against wall time and against RHS evaluations.

    Parameters
    ----------
    out_dir : path-like
    scene_name : str
    df : pandas.DataFrame
        Columns ``solver``, ``setting`` (h in s, or rtol), ``error_max``,
        ``wall_s`` (s), ``nfev``; optional ``error_rel`` (drawn instead of
        ``error_max`` when present: relative, dimensionless), ``status``
        (rows other than ``ok`` are dropped), ``n_steps`` and
        ``taylor_order``. Rows with a missing or non-positive error or time
        are dropped (they cannot be placed on log axes).

    Returns
    -------
    (Path, Caption)
        ``kind`` ``"work_precision"``.

    Notes
    -----
    heyoka's Taylor integrator makes no RHS calls: when ``n_steps`` and
    ``taylor_order`` are given it is placed on the right panel at steps x order
    (and its legend entry says so); otherwise rows with ``nfev`` <= 0 or NaN
    are left off that panel only, and the legend says which. A solver whose
    costs on a panel span less than :data:`SAME_COST` is drawn there as
    points, each labelled with its setting.
    """
    _require(df, "df", ["solver", "setting", "error_max", "wall_s", "nfev"])
    ycol = _error_column(df)
    d = _ok_rows(df, [ycol, "wall_s"])
    fig = kit.new_figure()
    kit.suptitle(fig, f"{scene_name}: work-precision (lower left is better)")
    ax_t, ax_n = fig.subplots(1, 2, sharey=True)
    notes, as_points = [], []
    for solver in kit.in_palette_order(d["solver"].unique()):
        rows = d[d["solver"] == solver].sort_values("setting", ascending=False)
        color, marker = kit.solver_style(solver)
        err = rows[ycol].to_numpy(float)
        wall, settings = rows["wall_s"].to_numpy(float), rows["setting"].to_numpy(float)
        cost, label = rows["nfev"].to_numpy(float), solver
        if not (np.isfinite(cost) & (cost > 0)).any() and {"n_steps", "taylor_order"} <= set(rows.columns):
            cost = rows["n_steps"].to_numpy(float) * rows["taylor_order"].to_numpy(float)
            label = f"{solver} (steps x Taylor order)"
        good = np.isfinite(cost) & (cost > 0)
        if not good.any():
            label = f"{solver} (no nfev: wall time only)"
            notes.append(solver)
        elif not good.all():
            label = f"{solver} ({(~good).sum()} point(s) without nfev)"
        name = _setting_name(solver)
        for ax, x, y, s, lab in ((ax_t, wall, err, settings, label), (ax_n, cost[good], err[good], settings[good], None)):
            if x.size == 0:
                continue
            flat = x.size >= 2 and x.max() / x.min() < SAME_COST
            ax.plot(x, y, marker=marker, color=color, ms=5, lw=1.2, ls="none" if flat else "-", label=lab)
            if flat:
                _label_settings(ax, x, y, s, name, color)
                if ax is ax_n or not good.any():
                    as_points.append(f"{solver} ({x.size} settings, {name} {kit.fmt(s.max())} to {kit.fmt(s.min())}, "
                                     f"all at {kit.fmt(x.min())}-{kit.fmt(x.max())} "
                                     f"{'s' if ax is ax_t else ('steps x order' if 'Taylor' in label else 'RHS calls')})")
    for ax, xl in ((ax_t, "wall time (s)"), (ax_n, "right-hand-side evaluations nfev")):
        kit.log_axes(ax)
        ax.set_xlabel(xl)
    ax_t.set_ylabel(ERROR_LABELS[ycol])
    if len(d):
        kit.legend_below(fig)
    path = kit.save(fig, out_dir, f"{kit.slug(scene_name)}_work_precision")
    parts = []
    if len(d):
        e = d[ycol].to_numpy(float)
        parts.append(f"{d['solver'].nunique()} solvers, {len(d)} runs; {'relative ' if ycol == 'error_rel' else ''}"
                     f"errors {e.min():.2g} to {e.max():.2g}, wall times {kit.fmt(d['wall_s'].min())} to "
                     f"{kit.fmt(d['wall_s'].max())} s")
    if as_points:
        parts.append("drawn as points, settings labelled: " + ", ".join(as_points))
    dropped = len(df) - len(d)
    if dropped:
        parts.append(f"{dropped} failed or error-free run(s) not drawn")
    if notes:
        parts.append(f"{', '.join(notes)} in the wall-time panel only (no RHS count)")
    sentence = kit.sentence(f"{scene_name}", *parts) if parts else f"{scene_name}: no run to draw."
    return path, Caption(sentence, "work_precision")


# -- convergence ----------------------------------------------------------------
def _guide(ax, slope, x_anchor, y_anchor, x_range, style, label):
    """Line ``y = y_anchor (x / x_anchor)^slope`` over ``x_range``."""
    x = np.array(x_range, dtype=float)
    ax.plot(x, y_anchor * (x / x_anchor) ** slope, ls=style, color="0.35", lw=1.0, label=label,
            gid=f"guide_slope_{slope:g}")


def convergence(out_dir, scene_name, points, fits) -> tuple[Path, str]:
    """Error against step size on log-log axes with slope guides.

    Parameters
    ----------
    out_dir : path-like
    scene_name : str
    points : pandas.DataFrame
        Columns ``solver``, ``h`` (s), ``error_max``; optional ``error_rel``
        (``error_max / max |y_ref|``), drawn instead when present, so the
        axis is dimensionless. Non-positive or NaN errors are left off.
    fits : pandas.DataFrame
        Columns ``solver``, ``observed_order``, ``h_min``, ``h_max`` (s): the
        least-squares order and the step range it was fitted over. Points
        inside the range are filled, those outside hollow.

    Returns
    -------
    (Path, Caption)
        ``kind`` ``"convergence"``.

    Notes
    -----
    The slope-4 guide (error proportional to h^4, classical RK4) runs under
    the RK4 points over their step range, through a third of the error at
    their smallest step inside the fit range; the slope-1 guide likewise under
    Euler's (or symplectic Euler's), when present. Without RK4 points the
    slope-4 guide is anchored on the first solver's. The legend is below the
    axes: it never covers points or guides.
    """
    _require(points, "points", ["solver", "h", "error_max"])
    _require(fits, "fits", ["solver", "observed_order", "h_min", "h_max"])
    ycol = _error_column(points)
    p = _ok_rows(points, ["h", ycol])
    fig = kit.new_figure()
    kit.suptitle(fig, f"{scene_name}: convergence of the error with the step size")
    ax = fig.subplots()
    fit_of = {r.solver: r for r in fits.itertuples()}
    orders, hollow = [], 0
    for solver in kit.in_palette_order(p["solver"].unique()):
        rows = p[p["solver"] == solver].sort_values("h")
        h, e = rows["h"].to_numpy(float), rows[ycol].to_numpy(float)
        color, marker = kit.solver_style(solver)
        f = fit_of.get(solver)
        if f is not None and np.isfinite(f.observed_order):
            inside = (h >= f.h_min * (1 - 1e-9)) & (h <= f.h_max * (1 + 1e-9))
            label = f"{solver}: order {f.observed_order:.2f} (fit h {kit.fmt(f.h_min)}-{kit.fmt(f.h_max)} s)"
            orders.append(f"{solver} {f.observed_order:.2f} (fit h {kit.fmt(f.h_min)}-{kit.fmt(f.h_max)} s)")
        else:
            inside = np.ones_like(h, dtype=bool)
            label = f"{solver} (no fit)"
            orders.append(f"{solver} not fitted")
        hollow += int((~inside).sum())
        ax.plot(h, e, "-", color=color, lw=1.0, label=label)
        ax.plot(h[inside], e[inside], marker, color=color, ms=6, ls="none")
        ax.plot(h[~inside], e[~inside], marker, mfc="none", color=color, ms=6, ls="none")
    by_order = {}  # expected order -> its solvers, highest order first
    for solver in kit.in_palette_order(p["solver"].unique()):
        order = kit.order_of(solver)
        if order is not None:
            by_order.setdefault(int(order), []).append(solver)
    if not by_order and not p.empty:
        by_order = {4: list(p["solver"].unique()[:1])}
    for i, (slope, solvers) in enumerate(sorted(by_order.items(), reverse=True)):
        style = kit.GUIDE_STYLES[i % len(kit.GUIDE_STYLES)]
        sel = p[p["solver"].isin(solvers)]
        sel = sel[sel["solver"] == sel["solver"].iloc[0]]
        h_range = (sel["h"].min(), sel["h"].max())  # the guide spans its solver's steps only
        f = fit_of.get(sel["solver"].iloc[0])
        if f is not None:
            in_fit = sel[(sel["h"] >= f.h_min * (1 - 1e-9)) & (sel["h"] <= f.h_max * (1 + 1e-9))]
            sel = in_fit if len(in_fit) else sel
        anchor = sel.sort_values("h").iloc[0]
        _guide(ax, slope, float(anchor["h"]), float(anchor[ycol]) / 3.0, h_range, style,
               f"slope {slope} guide (error ~ h^{slope})")
    kit.log_axes(ax)
    ax.set_xlabel("step size h (s)")
    ax.set_ylabel(ERROR_LABELS[ycol])
    kit.legend_below(fig)
    path = kit.save(fig, out_dir, f"{kit.slug(scene_name)}_convergence")
    guides = ", ".join(f"slope {o} under {'/'.join(m)}" for o, m in sorted(by_order.items(), reverse=True))
    sentence = kit.sentence(f"{scene_name}", "observed orders " + ", ".join(orders) if orders else "no point to draw",
                         f"guides: {guides}" if guides else "",
                         f"{hollow} hollow point(s) outside the fitted ranges" if hollow else "every point inside "
                         "its fitted range")
    return path, Caption(sentence, "convergence")


# -- energy error ---------------------------------------------------------------
def energy_error(out_dir, scene_name, series, *, title=None, stem=None, sentence=None,
                 kind="energy_error") -> tuple[Path, str]:
    """Relative energy error ``|E(t) - E0| / E_motion`` of several runs on log-log axes.

    Parameters
    ----------
    out_dir : path-like
    scene_name : str
    series : dict
        ``label -> (t, rel_energy_error)``, arrays of equal length; ``t`` in s.
        A label starting with a solver name (``"rk4 h=0.01"``) takes that
        solver's colour; labels of the same solver get different line styles.
    title, stem, sentence : str, optional
        The figure's title, file stem and specific sentence (defaults: the
        scene's energy-error figure; the sentence, by default, gives the
        range of the running maxima at the end of the run); the stability
        study's long-horizon figure passes its own title and stem.
    kind : str
        The figure kind (key of :data:`GENERIC_CAPTIONS`) of the returned caption.

    Returns
    -------
    (Path, Caption)

    Notes
    -----
    Times ``t <= 0`` (the initial state, error 0) are left off the log time
    axis, which so starts at the first step. Thin lines are the instantaneous error, thick lines its
    running maximum (the envelope, readable where the error oscillates down
    to zero twice a period). Zero errors are not drawn.
    """
    if not isinstance(series, dict):
        raise ValueError(f"`series` must be a dict label -> (t, error), got {type(series).__name__}")
    fig = kit.new_figure()
    kit.suptitle(fig, title or f"{scene_name}: relative energy error")
    ax = fig.subplots()
    seen: dict[str, int] = {}
    floor = np.inf
    final = []  # (last finite running maximum, its time, label)
    for label, (t, err) in series.items():
        t, err = np.asarray(t, dtype=float), np.abs(np.asarray(err, dtype=float))
        if t.shape != err.shape or t.ndim != 1:
            raise ValueError(f"`series[{label!r}]` must be two 1-D arrays of equal length, "
                             f"got shapes {t.shape} and {err.shape}")
        color, _ = kit.solver_style(label)
        solver = kit.solver_of(label)
        ls = kit.LINESTYLES[seen.get(solver, 0) % len(kit.LINESTYLES)]
        seen[solver] = seen.get(solver, 0) + 1
        show = t > 0
        env = np.fmax.accumulate(np.where(np.isfinite(err), err, np.nan)) if err.size else err
        inst = np.where(err > 0, err, np.nan)
        env = np.where(env > 0, env, np.nan)
        ax.plot(t[show], inst[show], color=color, lw=0.4, alpha=0.25, ls="-")
        ax.plot(t[show], env[show], color=color, lw=1.6, ls=ls, label=str(label))
        if np.isfinite(env[show]).any():
            floor = min(floor, float(np.nanmin(env[show])))
            last = np.flatnonzero(np.isfinite(env) & show)[-1]
            final.append((float(env[last]), float(t[last]), str(label)))
    ax.set_xscale("log")
    ax.set_yscale("log")
    if np.isfinite(floor):
        # The instantaneous error dips to zero twice a period; do not let those
        # dips stretch the axis below the smallest envelope value.
        ax.set_ylim(bottom=max(floor / 10.0, 1e-18))
    kit.log_axes(ax)
    ax.set_xlabel("time t (s)")
    ax.set_ylabel("|E(t) - E0| / E_motion (relative)")
    if series:
        kit.legend_below(fig, title="thick: running maximum, thin: instantaneous value")
    path = kit.save(fig, out_dir, stem or f"{kit.slug(scene_name)}_energy_error")
    if sentence is None:
        if final:
            lo, hi = min(final), max(final)
            sentence = (f"{scene_name}: at the end of the run the running maximum ranges from {lo[0]:.2g} "
                        f"({lo[2]}, t = {kit.fmt(lo[1])} s) to {hi[0]:.2g} ({hi[2]}, t = {kit.fmt(hi[1])} s).")
        else:
            sentence = f"{scene_name}: no finite non-zero energy error to draw."
    return path, Caption(sentence, kind)


def modal_energy(out_dir, scene_name, t, series, omega, *, recurrence=True) -> tuple[Path, str]:
    """Fraction of the energy of the motion in each of the lowest linear modes against time.

    Parameters
    ----------
    out_dir : path-like
    scene_name : str
    t : ndarray, shape (m,)
        Times (s).
    series : dict
        ``label -> fractions``, arrays of shape (modes, m); a label starting
        with a solver name takes that solver's line style (the first series
        solid, the others dashed), modes take colours.
    omega : ndarray, shape (modes,)
        The modes' angular frequencies (rad/s), for the legend.
    recurrence : bool
        Whether an FPUT recurrence can happen (a nonlinear model, two or more
        modes): the title names it and the sentence says how low mode 1's
        share falls and how high it comes back. False (a linear model, or one
        mode): no recurrence is named; the sentence gives the range of mode 1's
        share.

    Returns
    -------
    (Path, Caption)
        ``kind`` ``"modal_energy"``; the sentence as above, per series.
    """
    if not isinstance(series, dict) or not series:
        raise ValueError("`series` must be a non-empty dict label -> (modes, m) array")
    t = np.asarray(t, dtype=float)
    fig = kit.new_figure()
    kit.suptitle(fig, f"{scene_name}: energy in the lowest modes" + (" (FPUT recurrence)" if recurrence else ""))
    ax = fig.subplots()
    colors = kit.plt_colors(len(omega))
    facts = []
    for s_i, (label, frac) in enumerate(series.items()):
        frac = np.asarray(frac, dtype=float)
        if frac.shape != (len(omega), t.size):
            raise ValueError(f"`series[{label!r}]` must have shape ({len(omega)}, {t.size}), got {frac.shape}")
        for j in range(frac.shape[0]):
            ax.plot(t, frac[j], color=colors[j], lw=1.4 if s_i == 0 else 1.0,
                    ls=kit.LINESTYLES[s_i % len(kit.LINESTYLES)],
                    label=f"mode {j + 1} ({omega[j]:.3g} rad/s), {label}")
        f1 = np.where(np.isfinite(frac[0]), frac[0], np.nan) if frac.shape[0] else np.array([np.nan])
        if np.isfinite(f1).any() and not recurrence:
            facts.append(f"{label}: mode 1's share stays between {100 * np.nanmin(f1):.1f}% and "
                         f"{100 * np.nanmax(f1):.1f}%")
        elif np.isfinite(f1).any():
            i = int(np.nanargmin(f1))
            back = f1[i:]
            k = i + int(np.nanargmax(back)) if np.isfinite(back).any() else i
            facts.append(f"{label}: mode 1 falls to {100 * f1[i]:.0f}% at t = {kit.fmt_t(t[i])} s"
                         + (f" and returns to {100 * f1[k]:.0f}% at t = {kit.fmt_t(t[k])} s" if k > i else
                            " (no return within the run)"))
    ax.set_xlabel("time t (s)")
    ax.set_ylabel("E_k(t) / E_motion")
    ax.set_ylim(bottom=0.0)
    ax.grid(alpha=0.3)
    kit.legend_below(fig)
    path = kit.save(fig, out_dir, f"{kit.slug(scene_name)}_modal_energy")
    return path, Caption(kit.sentence(f"{scene_name}", *facts), "modal_energy")



# -- dispersion (thesis Fig 4.8) --------------------------------------------------
def dispersion(out_dir, m, k, d, finite_n, finite_omega, packets, *, scene_name=None) -> tuple[Path, str]:
    """Thesis Fig 4.8, corrected: omega(kp), v_phase and v_group of the monatomic lattice.

    Parameters
    ----------
    out_dir : path-like
    m : float
        Mass of each particle (kg).
    k : float
        Spring constant (N/m).
    d : float
        Lattice spacing (m).
    finite_n : int
        Masses N of the finite chain with fixed ends (0: no finite chain).
    finite_omega : array_like, shape (N,)
        Its eigenfrequencies (rad/s), ascending; drawn at ``kp_n = n pi / ((N + 1) d)``.
    packets : list of (float, float)
        ``(kp0, v_measured)``: carrier wavenumber (rad/m) of a wave packet and
        the group velocity (m/s) measured from its RK4 integration.
    scene_name : str, optional
        Prefix of the file name (default: none, ``dispersion.png``).

    Returns
    -------
    (Path, Caption)
        ``kind`` ``"dispersion"``; the sentence gives the lattice's constants and
        each packet's measured group velocity against v_g.

    Notes
    -----
    ``omega = sqrt(4k/m) |sin(kp d / 2)|``, ``v_p = omega / kp`` and
    ``v_g = d omega / d kp = d sqrt(k/m) cos(kp d / 2) sign(kp)`` for
    ``|kp| < 2 pi / d`` (thesis eqs. 2.49-2.54 with erratum 7), all from
    :mod:`rk4h.references.dispersion`. Both velocities jump at ``kp = 0`` (where
    ``|sin|`` has its kink); the curves are drawn in two pieces there, not
    joined by a vertical line. The first Brillouin zone ``|kp| <= pi / d`` is
    shaded.
    """
    from rk4h.references.dispersion import finite_chain_wavenumbers, group_velocity, omega, phase_velocity
    from rk4h.validate import positive

    m, k, d = positive("m", m), positive("k", k), positive("d", d)
    finite_omega = np.asarray(finite_omega, dtype=float).ravel()
    if isinstance(finite_n, bool) or int(finite_n) != finite_n or finite_omega.size != int(finite_n):
        raise ValueError(f"`finite_n` must be the number of entries of `finite_omega` "
                         f"({finite_omega.size}), got {finite_n!r}")
    n_fin = int(finite_n)
    pk = np.asarray(packets, dtype=float).reshape(-1, 2) if len(packets) else np.empty((0, 2))
    kz = math.pi / d
    half = np.linspace(1e-6 * kz, 2 * kz, 1000)
    pieces = (-half[::-1], half)  # kp < 0 and kp > 0 drawn apart (jump of v_p, v_g at 0)
    w0, v0 = 2.0 * math.sqrt(k / m), d * math.sqrt(k / m)

    fig = kit.new_figure(kit.SIZE_TALL)
    kit.suptitle(fig, f"{scene_name + ': ' if scene_name else ''}dispersion of the monatomic lattice "
                   f"(m = {kit.fmt(m)} kg, k = {kit.fmt(k)} N/m, d = {kit.fmt(d)} m)")
    axes = fig.subplots(3, 1, sharex=True)
    curve = "#1f77b4"
    ylabels = ("\u03c9 (rad/s)", "v_p = \u03c9/k_p (m/s)", "v_g = d\u03c9/dk_p (m/s)")
    for ax, f, lab in zip(axes, (omega, phase_velocity, group_velocity), ylabels):
        ax.axvspan(-kz, kz, color="#ffe9a8", alpha=0.6, lw=0,
                   label="first Brillouin zone" if ax is axes[0] else None)
        for j, kp in enumerate(pieces):
            ax.plot(kp, f(kp, m, k, d), color=curve, lw=1.5,
                    label="infinite lattice (analytic)" if (ax is axes[0] and j) else None)
        ax.set_ylabel(lab)
        ax.grid(alpha=0.3)
        ax.axhline(0.0, color="0.5", lw=0.5)
    axes[0].axhline(w0, color="0.4", ls="--", lw=0.8)
    axes[0].text(0.0, 0.97 * w0, f"\u03c9_0 = \u221a(4k/m) = {w0:.4g} rad/s", ha="center", va="top",
                 fontsize=8, color="0.3")
    for ax in axes[1:]:
        ax.set_ylim(-1.25 * v0, 1.25 * v0)
    if n_fin:
        axes[0].plot(finite_chain_wavenumbers(n_fin, d), finite_omega, "o", color="k",
                     ms=4 if n_fin <= 30 else (2.5 if n_fin <= 60 else 1.8), ls="none",
                     label=f"finite chain, N = {n_fin}: eigenfrequencies at k_n = n\u03c0/((N+1)d)")
    if len(pk):
        color, _ = kit.solver_style(UNDER_TEST)
        axes[2].plot(pk[:, 0], pk[:, 1], "o", color=color, ms=7, mfc="none", mew=1.5, ls="none",
                     label="wave packet integrated by RK4: measured group velocity")
    axes[-1].set_xticks(np.arange(-2, 3) * kz, ["\u22122\u03c0/d", "\u2212\u03c0/d", "0", "\u03c0/d", "2\u03c0/d"])
    axes[-1].set_xlim(-2 * kz, 2 * kz)
    axes[-1].set_xlabel(f"wavenumber k_p (rad/m; \u03c0/d = {kit.fmt(kz)} rad/m)")
    kit.legend_below(fig)
    stem = f"{kit.slug(scene_name)}_dispersion" if scene_name else "dispersion"
    path = kit.save(fig, out_dir, stem)
    facts = [f"m = {kit.fmt(m)} kg, k = {kit.fmt(k)} N/m, d = {kit.fmt(d)} m, omega_0 = {w0:.4g} rad/s"]
    if n_fin:
        facts.append(f"dots: the {n_fin}-mass chain's eigenfrequencies")
    for kp0, v in pk:
        vg = float(group_velocity(np.array([kp0]), m, k, d)[0])
        facts.append(f"packet at kp0 = {kp0 / kz:.3g} pi/d: measured {v:.5g} m/s against v_g = {vg:.5g} m/s "
                     f"({100 * (v - vg) / vg:+.2f}%)" if vg else f"packet at kp0 = {kp0 / kz:.3g} pi/d: "
                     f"measured {v:.5g} m/s")
    return path, Caption(kit.sentence(f"{scene_name or 'Monatomic lattice'}", *facts), "dispersion")


# -- crossover (optional) ---------------------------------------------------------
CROSSOVER_NONE = "none: no solver reached this target with the scene's settings"
#: Keys of the cells that name no solver, by the cell's text (column ``cell``).
CROSSOVER_EMPTY = {"tie": "tie: both sides' measured runs need the same RHS calls",
                   "unmeasured": "unmeasured: no measured run confirmed a winner for this target"}
_ROW_IN = 0.36           # inches per scene row of the crossover grid (two 8-pt lines)


def crossover(out_dir, df) -> tuple[Path, str]:
    """Which solver is cheapest for each scene and target error, as a coloured grid.

    Parameters
    ----------
    out_dir : path-like
    df : pandas.DataFrame
        One row per (scene, target): columns ``scene``, ``target_error`` (or
        ``target``), ``solver`` (the cheapest one reaching the target; empty
        or NaN when none does) and optionally its cost: ``rhs`` (right-hand-side
        calls; the grid then ranks by RHS calls, as the trust table's
        ``verdict_rhs``) or else ``wall_s`` (s; ranked by wall time), and
        ``cell``: the text of a cell without a solver (``tie``,
        ``unmeasured``: :data:`CROSSOVER_EMPTY`; default "none").

    Returns
    -------
    (Path, Caption)
        ``kind`` ``"crossover"``; the sentence counts the cells per solver.

    Notes
    -----
    The figure is :data:`SIZE` wide and at least :data:`SIZE` tall, taller
    with many scenes (:data:`_ROW_IN` per row) so every cell's text stays at
    8 pt; a key below names each colour's solver and explains "none".
    """
    from matplotlib.patches import Patch

    tcol = "target_error" if "target_error" in df.columns else "target"
    _require(df, "df", ["scene", tcol, "solver"])
    scenes = list(dict.fromkeys(df["scene"]))
    targets = sorted(set(df[tcol].astype(float)), reverse=True)
    height = max(kit.SIZE[1], 1.9 + _ROW_IN * len(scenes))
    fig = kit.new_figure((kit.SIZE[0], height))
    by_rhs = "rhs" in df.columns or "wall_s" not in df.columns
    kit.suptitle(fig, "cheapest solver for each target error " + ("(fewest RHS calls)" if by_rhs else "(wall time)"))
    ax = fig.subplots()
    counts: dict = {}
    empty: dict = {}
    for r in df.itertuples():
        i, j = scenes.index(r.scene), targets.index(float(getattr(r, tcol)))
        solver = r.solver if isinstance(r.solver, str) and r.solver else None
        cell = getattr(r, "cell", "")
        blank = cell if isinstance(cell, str) and cell in CROSSOVER_EMPTY else "none"
        if solver is None:
            empty[blank] = empty.get(blank, 0) + 1
        counts[solver] = counts.get(solver, 0) + 1
        color = kit.solver_style(solver)[0] if solver else "#ffffff"
        # add_artist, not add_patch: the limits are set below, and add_patch's update of the data
        # limits per cell was a fifth of the figure
        ax.add_artist(_rect(j, i, color, alpha=0.45 if solver else 1.0))
        txt = solver or blank
        cost = getattr(r, "rhs" if by_rhs else "wall_s", None)
        if solver and cost is not None and np.isfinite(cost):
            txt += f"\n{cost:.2g} RHS" if by_rhs else f"\n{cost:.2g} s"
        # inside its cell, so inside the axes: left out of the layout, which measured every cell's text
        ax.text(j, i, txt, ha="center", va="center", fontsize=kit.FONT_SMALL, linespacing=1.0, in_layout=False)
    ax.set_xlim(-0.5, len(targets) - 0.5)
    ax.set_ylim(len(scenes) - 0.5, -0.5)
    ax.set_xticks(range(len(targets)), [f"{t:.0e}" for t in targets])
    ax.set_yticks(range(len(scenes)), scenes, fontsize=kit.FONT_SMALL)
    ax.set_xlabel("target relative error (error_max / max |y_ref|)")
    ax.tick_params(length=0)
    solvers = kit.in_palette_order([s for s in counts if s])
    handles = [Patch(facecolor=kit.solver_style(s)[0], alpha=0.45, edgecolor="0.6", label=s) for s in solvers]
    for key in ("none", *CROSSOVER_EMPTY):
        if key in empty:
            handles.append(Patch(facecolor="#ffffff", edgecolor="0.6",
                                 label=CROSSOVER_NONE if key == "none" else CROSSOVER_EMPTY[key]))
    kit.legend_below(fig, handles, [h.get_label() for h in handles], title="cell colour: the cheapest solver")
    path = kit.save(fig, out_dir, "crossover")
    tally = ", ".join([f"{s} {counts[s]}" for s in solvers]
                      + [f"{k} {empty[k]}" for k in ("none", *CROSSOVER_EMPTY) if k in empty])
    sentence = (f"{len(scenes)} scenes x {len(targets)} targets ({kit.fmt(targets[0])} to {kit.fmt(targets[-1])}); "
                f"cells per cheapest solver: {tally}." if targets else "No scene or target to draw.")
    return path, Caption(sentence, "crossover")


def _rect(x, y, color, alpha):
    from matplotlib.patches import Rectangle

    return Rectangle((x - 0.5, y - 0.5), 1.0, 1.0, facecolor=color, alpha=alpha, edgecolor="white", lw=2)
