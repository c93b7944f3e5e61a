"""Scene figures: the physics drawings of one trajectory of a scene (the
thesis' Figs 4.1-4.20): displacements, velocities, spring elongations, paths
in the plane, angles, coordinates and space-time images of long chains.

The figures are chosen from the model's drawing (``model.drawing()``), never
from its name. Nothing here integrates or solves an eigenproblem: the modal
content the sentences quote (frequencies, the initial state's energy per
mode, how the dominant mode keeps its energy) comes with the trajectory, as
the run's record holds it (:func:`rk4h.validation.execute.modal_content`). The
numbers derived here are display aids (axis windows, SI prefixes) and facts
read off the data drawn (a path's principal axes, peak values, ranges).

References
----------
The figures regenerate the thesis' Figs 4.1-4.20 (chapter 4) with the
corrected physics listed in the errata (docs/scenes.md).
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from . import style as kit
from .captions import Caption

__all__ = ["scene_figures", "LONG_CHAIN", "PX_PER_PERIOD", "MAX_PATH_PANELS"]

LONG_CHAIN = 10          # chains with more masses get a space-time image
_ZOOM_PERIODS = 3        # the zoom panel shows this many slowest periods
PX_PER_PERIOD = 8        # a space-time image needs this many pixels per period of the fastest excited mode


def _check_trajectory(model, t, y):
    t = np.asarray(t, dtype=float)
    y = np.asarray(y, dtype=float)
    if t.ndim != 1 or t.size < 2:
        raise ValueError(f"`t` must be 1-D with at least 2 times, got shape {t.shape}")
    if y.shape != (2 * model.n_dof, t.size):
        raise ValueError(f"`y` must have shape {(2 * model.n_dof, t.size)} for {model.name}, got {y.shape}")
    return t, y


def _omega(modal):
    """The recorded angular frequencies (rad/s) of the linearization, or None."""
    omega = None if not modal else modal.get("omega")
    if omega is None:
        return None
    omega = np.asarray(omega, dtype=float)
    return omega if omega.ndim == 1 and omega.size and np.isfinite(omega).all() else None


def _fractions(modal, omega):
    """The recorded fraction of the initial energy in each mode, or None."""
    frac = None if omega is None else modal.get("fraction0")
    if frac is None:
        return None
    frac = np.asarray(frac, dtype=float)
    return frac if frac.shape == omega.shape and np.isfinite(frac).all() else None


def _zoom_end(modal, t):
    """End of a window of ``_ZOOM_PERIODS`` periods of the slowest non-zero mode
    of the linearization, or None when that covers most of the horizon."""
    omega = _omega(modal)
    if omega is None:
        return None
    omega = omega[omega > 0]
    if omega.size == 0:
        return None
    t_end = t[0] + _ZOOM_PERIODS * 2.0 * math.pi / float(omega.min())
    return t_end if t_end < t[0] + 0.5 * (t[-1] - t[0]) else None


def _modal_text(model, modal, t) -> tuple[str, bool]:
    """``(text, single)``: what the recorded modal content of the run
    (:func:`rk4h.validation.execute.modal_content`) says about the motion drawn --
    the initial state's modes (one frequency, or which modes and whether they
    beat) and, for a one-frequency start, whether that mode keeps its energy
    over the run (a nonlinear model may share it) -- and whether the motion
    drawn is one frequency throughout. Modes of equal frequency count as one
    frequency. ``("", False)`` without modal content."""
    omega = _omega(modal)
    frac = _fractions(modal, omega)
    if frac is None:
        return "", False
    groups = []  # [omega, fraction, first mode number, mode indices]
    for k in np.argsort(omega, kind="stable"):
        if groups and abs(omega[k] - groups[-1][0]) <= 1e-9 * max(1.0, omega[k]):
            groups[-1][1] += frac[k]
            groups[-1][3].append(int(k))
        else:
            groups.append([float(omega[k]), float(frac[k]), int(k) + 1, [int(k)]])
    groups.sort(key=lambda g: -g[1])
    lin = "" if getattr(model, "linear", False) else " of the linearization"
    w, f, k, idx = groups[0]
    if f >= 0.999:
        start = (f"the initial state is {100 * f:.1f}% rigid motion{lin} (zero frequency)" if w == 0.0 else
                 f"the initial state is {100 * f:.1f}% mode {k}{lin} (omega = {w:.4g} rad/s)")
        low = (float(modal.get("share_min", math.nan)), float(modal.get("share_t", math.nan)))
        low = low if math.isfinite(low[0]) and math.isfinite(low[1]) else None
        if low is None or low[0] >= 0.99:
            kept = f", which keeps at least {100 * low[0]:.1f}% of the energy over the run" if low else ""
            return f"{start}{kept}: one frequency, so no beats and no exchange between modes", True
        return (f"{start}, but its share of the linear modal energy falls to {100 * low[0]:.0f}% at t = "
                f"{kit.fmt_t(low[1])} s: the nonlinearity passes energy to other modes"), False
    main = [g for g in groups if g[1] >= 0.01]
    if len(main) > 4:  # a broadband start: say how broad, not which modes
        w_sig = [g[0] for g in main]
        return (f"the initial energy is spread over {len(groups)} modes{lin} ({len(main)} of them hold >= 1% each, "
                f"the largest {100 * f:.1f}%; {min(w_sig):.3g} to {max(w_sig):.3g} rad/s)"), False
    text = (f"initial energy by mode{lin}: "
            + ", ".join(f"mode {k} ({w:.3g} rad/s) {100 * f:.1f}%" for w, f, k, _ in main))
    if len(main) >= 2 and main[1][1] >= 0.1:
        dw = abs(main[0][0] - main[1][0])
        if 0 < dw <= 0.2 * max(main[0][0], main[1][0]):
            text += (f"; modes {main[0][2]} and {main[1][2]} beat with period 2 pi/|delta omega| = "
                     f"{kit.fmt_t(2 * math.pi / dw)} s")
        else:
            text += "; their frequencies are too far apart to beat"
    return text, False


def _fast_omega(modal):
    """Frequency (rad/s) below which 99% of the initial energy lies: the
    fastest mode the figure must resolve; None without modal content."""
    omega = _omega(modal)
    frac = _fractions(modal, omega)
    if frac is None:
        return None
    order = np.argsort(omega)
    cum = np.cumsum(frac[order])
    w = float(omega[order][min(int(np.searchsorted(cum, 0.99)), order.size - 1)])
    return w if w > 0 else None


def _legible_end(modal, t):
    """End of the first part of the run that a space-time image can show
    without aliasing (at least :data:`PX_PER_PERIOD` pixels per period of the
    fastest excited mode), or None when the whole run is legible."""
    w = _fast_omega(modal)
    if w is None:
        return None
    axes_px = 0.75 * kit.SIZE[0] * kit.DPI
    span = axes_px * (2.0 * math.pi / w) / PX_PER_PERIOD
    if span >= 0.8 * (t[-1] - t[0]) or np.count_nonzero(t <= t[0] + span) < 3:
        return None
    return t[0] + span


def _path_shape(x, y):
    """``(ratio, major, minor, angle_deg)`` of a path's finite points: the
    ratio of its principal axes (0 for a straight segment), their extents
    (peak-to-peak along each axis) and the major axis' angle to x; None
    without two finite points."""
    ok = np.isfinite(x) & np.isfinite(y)
    if ok.sum() < 2:
        return None
    p = np.vstack([x[ok], y[ok]])
    p = p - p.mean(axis=1, keepdims=True)
    lam, vec = np.linalg.eigh(p @ p.T / p.shape[1])
    major_dir, minor_dir = vec[:, 1], vec[:, 0]
    along, across = major_dir @ p, minor_dir @ p
    major, minor = float(np.ptp(along)), float(np.ptp(across))
    ratio = math.sqrt(max(lam[0], 0.0) / lam[1]) if lam[1] > 0 else 0.0
    angle = math.degrees(math.atan2(major_dir[1], major_dir[0])) % 180.0
    return ratio, major, minor, angle


# -- scene figures (thesis Figs 4.1-4.20) ---------------------------------------
def _time_series(title, what, t, series, unit, zoom_end, ylabel):
    """One or two panels (full horizon, then the first few periods) of ``series``:
    list of (label, values)."""
    fig = kit.new_figure()
    kit.suptitle(fig, f"{title}: {what}")
    factor, u = kit.si(np.concatenate([np.ravel(v) for _, v in series]), unit)
    axes = fig.subplots(2 if zoom_end is not None else 1, 1, squeeze=False)[:, 0]
    for i, ax in enumerate(axes):
        for j, (label, v) in enumerate(series):
            # Later curves thinner and dashed, so coinciding curves stay visible.
            lw = (1.0 if i == 0 else 2.2) * (1.0 - 0.5 * j / max(1, len(series) - 1))
            ax.plot(t, factor * np.asarray(v), color=kit.COORD_COLORS[j % len(kit.COORD_COLORS)],
                    lw=lw, ls=kit.LINESTYLES[j % 2] if i else "-", label=label if i == 0 else None)
        ax.set_ylabel(f"{ylabel} ({u})")
        ax.grid(alpha=0.3)
        ax.axhline(0.0, color="0.5", lw=0.5)
    axes[0].set_xlim(t[0], t[-1])
    axes[0].set_title(f"whole run, 0 to {kit.fmt_t(t[-1])} s", fontsize=kit.FONT_SMALL + 1, loc="left")
    if zoom_end is not None:
        axes[1].set_xlim(t[0], zoom_end)
        axes[1].set_title(f"first {kit.fmt_t(zoom_end - t[0])} s", fontsize=kit.FONT_SMALL + 1, loc="left")
    axes[-1].set_xlabel("time t (s)")
    leg = kit.legend_below(fig)
    for handle in leg.legend_handles:
        handle.set_linewidth(2.0)  # thin curves' colours must still read in the key
    return fig


def _path_panel(ax, x, y, factor, u, label_x, label_y, color="#1f77b4"):
    ax.plot(factor * x, factor * y, color=color, lw=0.6)
    ax.plot(factor * x[0], factor * y[0], "o", color="k", ms=4, label="start")
    ax.set_xlabel(f"{label_x} ({u})")
    ax.set_ylabel(f"{label_y} ({u})")
    ax.grid(alpha=0.3)


def _xy_path(title, x, y, unit="m", what="trajectory in the x-y plane"):
    fig = kit.new_figure()
    kit.suptitle(fig, f"{title}: {what}")
    factor, u = kit.si(np.concatenate([x, y]), unit)
    ax = fig.subplots()
    _path_panel(ax, x, y, factor, u, "x", "y")
    ax.margins(0.04)
    ax.set_aspect("equal", adjustable="datalim")
    kit.legend_below(fig)
    return fig


def _space_time(title, what, t, values, unit, label, t_window=None, period=None):
    """Image of ``values`` (n_masses, m): mass index vs time, colour = value;
    with ``t_window``, that image covers ``t <= t_window`` only and a second
    panel shows the amplitude ``max |value|`` per time bin (at least two
    ``period`` s long, so the envelope does not alias) over the whole run."""
    fig = kit.new_figure()
    factor, u = kit.si(values, unit)
    n = values.shape[0]
    if t_window is None:
        kit.suptitle(fig, f"{title}: {what}")
        ax = fig.subplots()
        _signed_image(fig, ax, t, factor * values, label, u, n)
        ax.set_xlabel("time t (s)")
        return fig
    kit.suptitle(fig, f"{title}: {what}, first {kit.fmt_t(t_window - t[0])} s and amplitude over the whole run")
    ax_s, ax_a = fig.subplots(2, 1)
    keep = t <= t_window
    _signed_image(fig, ax_s, t[keep], factor * values[:, keep], label, u, n)
    ax_s.set_title(f"first {kit.fmt_t(t_window - t[0])} s: signed {label}", fontsize=kit.FONT_SMALL + 1, loc="left")
    # amplitude per time bin: bins of >= 2 fast periods and >= 2 pixels, so nothing aliases
    n_bins = min(t.size, 320)
    if period:
        n_bins = max(2, min(n_bins, int((t[-1] - t[0]) / (2.0 * period))))
    edges = np.linspace(0, t.size, n_bins + 1).astype(int)
    starts = np.unique(edges[:-1])
    mag = np.abs(factor * values)
    env = np.fmax.reduceat(np.where(np.isfinite(mag), mag, np.nan), starts, axis=1)
    t_mid = t[np.minimum(starts, t.size - 1)]
    finite = env[np.isfinite(env)]
    vmax = float(np.percentile(finite, 99.5)) if finite.size else 1.0
    vmax = vmax if vmax > 0 else 1.0
    im = ax_a.pcolormesh(np.append(t_mid, t[-1]), np.arange(0.5, n + 1.0), env, cmap="viridis", vmin=0.0,
                         vmax=vmax, shading="flat")
    fig.colorbar(im, ax=ax_a, label=f"max |{label}| ({u})",
                 extend="max" if finite.size and finite.max() > vmax * (1 + 1e-9) else "neither")
    ax_a.set_title(f"whole run, 0 to {kit.fmt_t(t[-1])} s: amplitude max |{label}| per time bin",
                   fontsize=kit.FONT_SMALL + 1, loc="left")
    ax_a.set_ylabel("mass index n")
    ax_a.set_xlabel("time t (s)")
    return fig


def _signed_image(fig, ax, t, values, label, u, n):
    mag = np.abs(values[np.isfinite(values)])
    # Colour limit at the 99.5th percentile: a short initial kick must not wash
    # out the waves that follow (values beyond it are clipped, the bar says so).
    vmax = float(np.percentile(mag, 99.5)) if mag.size else 0.0
    peak = float(mag.max()) if mag.size else 0.0
    vmax = vmax if vmax > 0 else (peak if peak > 0 else 1.0)
    dt = np.diff(t)
    if t.size > 1 and np.allclose(dt, dt.mean(), rtol=1e-6, atol=0.0):
        im = ax.imshow(values, origin="lower", aspect="auto", cmap="RdBu_r", vmin=-vmax, vmax=vmax,
                       interpolation="antialiased",
                       extent=(t[0] - dt.mean() / 2, t[-1] + dt.mean() / 2, 0.5, n + 0.5))
    else:
        im = ax.pcolormesh(t, np.arange(1, n + 1), values, cmap="RdBu_r", vmin=-vmax, vmax=vmax,
                           shading="nearest")
    ax.set_ylabel("mass index n")
    fig.colorbar(im, ax=ax, label=f"{label} ({u})", extend="both" if peak > vmax * (1 + 1e-9) else "neither")


_LAYOUTS = ("line", "plane", "angles", "coordinates")
_WORDS = ("no", "one", "two", "three", "four", "five", "six", "seven", "eight", "nine", "ten")
MAX_PATH_PANELS = 12     # more points in the plane: one panel with every point


def _count(n, noun):
    """``"three masses"``: the number in words up to ten, then digits."""
    return f"{_WORDS[n] if n < len(_WORDS) else n} {noun}{'' if n == 1 else 'es' if noun.endswith('s') else 's'}"


def _check_drawing(model, d):
    """The fields of ``model.drawing()`` the figures use, checked against the
    model's size; a ValueError names the field."""
    if d.layout not in _LAYOUTS:
        raise ValueError(f"`drawing().layout` of {model.name} must be one of {', '.join(_LAYOUTS)}, "
                         f"got {d.layout!r}")
    if d.layout != "plane":
        return
    n = model.n_dof
    if not d.points or any(len(p) != 2 or not all(0 <= int(i) < n for i in p) for p in d.points):
        raise ValueError(f"`drawing().points` of {model.name} must be non-empty (x, y) coordinate index "
                         f"pairs below {n}, got {d.points!r}")
    if len(d.reference) != len(d.points):
        raise ValueError(f"`drawing().reference` of {model.name} must have one position per point "
                         f"({len(d.points)}), got {len(d.reference)}")
    nodes = len(d.points) + len(d.anchors)
    if any(not (0 <= int(a) < nodes and 0 <= int(b) < nodes) for a, b, _ in d.springs):
        raise ValueError(f"`drawing().springs` of {model.name} must join nodes below {nodes} "
                         f"(points, then anchors), got {d.springs!r}")
    if len(d.rest) != len(d.springs):
        raise ValueError(f"`drawing().rest` of {model.name} must have one length per spring "
                         f"({len(d.springs)}), got {len(d.rest)}")


def _node_positions(d, q):
    """Positions (m) of the drawing's nodes over time: a list of ``(x, y)``,
    points (reference + displacement, arrays) first, then anchors (floats)."""
    pts = [(rx + q[ix], ry + q[iy]) for (ix, iy), (rx, ry) in zip(d.points, d.reference)]
    return pts + [(float(ax), float(ay)) for ax, ay in d.anchors]


def _spring_elongations(d, q):
    """``[(label, |P_b - P_a| - rest)]`` of every spring of the drawing over time (m)."""
    nodes = _node_positions(d, q)
    out = []
    for (a, b, label), rest in zip(d.springs, d.rest):
        (xa, ya), (xb, yb) = nodes[int(a)], nodes[int(b)]
        length = np.hypot(np.asarray(xb - xa, dtype=float), np.asarray(yb - ya, dtype=float))
        out.append((f"{label} spring", length * np.ones(q.shape[1]) - float(rest)))
    return out



def _peak(series, unit):
    """``"4.9 mm (x2)"``: the largest finite |value| of ``[(label, values)]`` and whose it is."""
    best, who = -1.0, ""
    for label, v in series:
        a = np.abs(np.asarray(v, dtype=float))
        a = a[np.isfinite(a)]
        if a.size and a.max() > best:
            best, who = float(a.max()), str(label).split(" (")[0]
    if best < 0:
        return "no finite value"
    factor, u = kit.si([best], unit)
    return f"{factor * best:.3g} {u} ({who})"


def _span_text(ctx):
    t, zoom = ctx["t"], ctx["zoom"]
    return f"0 to {kit.fmt_t(t[-1])} s" + (f", first {kit.fmt_t(zoom - t[0])} s below" if zoom else "")


def _hint(ctx, modal, single):
    """The modal content, then the drawing's caption unless the start is one
    frequency (the caption describes the model in general, e.g. beats or
    mode exchange, which a single-mode start does not show)."""
    return (modal, "" if single else ctx["caption"])


def _line_specs(ctx):
    title, t, q, v, n, ref, unit = (ctx[k] for k in ("title", "t", "q", "v", "n", "ref", "unit"))
    modal, single = ctx["modal"]
    if n > LONG_CHAIN:
        win, period = ctx["window"], ctx["fast_period"]
        if win is None:
            shown = f"the whole run ({ctx['fast_txt']})"
        else:
            shown = (f"the signed image shows the first {kit.fmt_t(win - t[0])} s only (the fastest excited mode, "
                     f"{ctx['fast_txt']}, would alias over the whole run), the amplitude panel the whole run")
        head = f"{n}-mass chain, 0 to {kit.fmt_t(t[-1])} s{ref}"
        return [
            ("displacement", "space_time",
             lambda: _space_time(title, "displacement of each mass", t, q, unit, "displacement", win, period),
             kit.sentence(head, shown, f"largest |displacement| {_peak([('', q)], unit).split(' (')[0]}", modal,
                       ctx["caption"])),
            ("velocity", "space_time",
             lambda: _space_time(title, "velocity of each mass", t, v, f"{unit}/s", "velocity", win, period),
             kit.sentence(head, shown, f"largest |velocity| {_peak([('', v)], unit + '/s').split(' (')[0]}")),
        ]
    labels, vlabels = _chain_labels(ctx["mass"])
    head = f"{_count(n, 'mass').capitalize()}, {_span_text(ctx)}{ref}"
    return [
        ("displacement", "displacement",
         lambda: _time_series(title, "displacement of each mass", t, list(zip(labels, q)), unit, ctx["zoom"],
                              "displacement"),
         kit.sentence(head, *_hint(ctx, modal, single))),
        ("velocity", "velocity",
         lambda: _time_series(title, "velocity of each mass", t, list(zip(vlabels, v)), f"{unit}/s", ctx["zoom"],
                              "velocity"),
         kit.sentence(head, f"largest speed {_peak(list(zip(vlabels, v)), unit + '/s')}")),
    ]


def _trajectory_text(x, y, unit, caption):
    """What the path drawn is, from its principal axes: a straight segment
    (ratio under 0.01; the drawing's caption, which may promise a curve, is
    then left out) or a curve filling a region."""
    shape = _path_shape(np.asarray(x, float), np.asarray(y, float))
    if shape is None:
        return "no finite path to draw"
    ratio, major, minor, angle = shape
    factor, u = kit.si([major], unit)
    if major == 0.0:
        return "the point does not move"
    if ratio < 0.01:
        return (f"the path is a straight segment {factor * major:.3g} {u} long at {angle:.0f} deg to the x axis "
                f"(principal-axis ratio {ratio:.2g}): the motion stays on one line, so no ellipse or curve is drawn")
    return _sentence_tail(f"the path fills {factor * major:.3g} x {factor * minor:.3g} {u} along its principal "
                          f"axes (ratio {ratio:.2f}, major axis at {angle:.0f} deg to x)", caption)


def _sentence_tail(*parts):
    return "; ".join(p for p in parts if p)


def _plane_specs(ctx):
    d, title, t, q, v, zoom, ref, cap, unit = (ctx[k] for k in (
        "drawing", "title", "t", "q", "v", "zoom", "ref", "caption", "unit"))
    labels = list(d.point_labels) + [f"point {i + 1}" for i in range(len(d.point_labels), len(d.points))]
    if len(d.points) > 1:
        n = len(d.points)
        moves = [(labels[i], np.hypot(q[ix] - q[ix][0], q[iy] - q[iy][0])) for i, (ix, iy) in enumerate(d.points)]
        head = (f"{_count(n, 'mass').capitalize()}{ref}" if n <= MAX_PATH_PANELS else
                f"{n} points in the plane{ref}")
        return [("paths", "paths", lambda: _plane_paths(title, d, q, labels),
                 kit.sentence(head, f"largest distance from the start {_peak(moves, d.unit)}", cap))]
    (ix, iy), (rx, ry) = d.points[0], d.reference[0]
    who = labels[0]
    at_origin = rx == 0.0 and ry == 0.0
    pos = "position" if at_origin else "displacement"
    span = _span_text(ctx)
    specs = [
        ("displacement", "displacement",
         lambda: _time_series(title, f"{pos} of the {who}", t, [("x", q[ix]), ("y", q[iy])], unit, zoom, pos),
         kit.sentence(f"{pos.capitalize()} x, y of the {who}{'' if at_origin else ' from its rest position'}, "
                   f"{span}{ref}", f"largest |{pos}| {_peak([('x', q[ix]), ('y', q[iy])], unit)}")),
        ("velocity", "velocity",
         lambda: _time_series(title, f"velocity of the {who}", t, [("vx", v[ix]), ("vy", v[iy])],
                              f"{unit}/s", zoom, "velocity"),
         kit.sentence(f"Velocity of the {who}, {span}{ref}",
                   f"largest speed component {_peak([('vx', v[ix]), ('vy', v[iy])], unit + '/s')}")),
    ]
    if d.springs:
        note = d.extra.get("rest_note")
        anchored = sum(1 for a, b, _ in d.springs if max(int(a), int(b)) >= len(d.points))
        specs.append(
            ("springs", "springs",
             lambda: _time_series(title, "spring elongations (length - natural length)", t,
                                  _spring_elongations(d, q), unit, zoom, "elongation"),
             kit.sentence(f"{_count(len(d.springs), 'spring').capitalize()}"
                       f"{f' ({anchored} of them anchored)' if anchored else ''}, {span}{ref}",
                       note, f"largest |elongation| {_peak(_spring_elongations(d, q), unit)}")))
    specs.append(
        ("trajectory", "trajectory",
         lambda: _xy_path(title, q[ix], q[iy], unit, what=d.extra.get("path_title", "trajectory in the x-y plane")),
         kit.sentence(f"Path of the {who}{ref}", _trajectory_text(q[ix], q[iy], unit, cap))))
    return specs


def _series_specs(ctx, stem, what, ylabel):
    d, n, title, t, q, zoom, ref = (ctx[k] for k in ("drawing", "n", "title", "t", "q", "zoom", "ref"))
    modal, single = ctx["modal"]
    names = list(d.point_labels) if len(d.point_labels) == n else list(ctx["coord_names"])
    head = (f"Angles {', '.join(names)}, {_span_text(ctx)}{ref}" if stem == "angles" else
            f"Coordinates of {ctx['name']}, {_span_text(ctx)}{ref}")
    return [(stem, stem, lambda: _time_series(title, what, t, list(zip(names, q)), d.unit, zoom, ylabel),
             kit.sentence(head, *_hint(ctx, modal, single)))]


def _scene_specs(scene_name, model, t, y, title, thesis=None, modal=None):
    """``[(stem_suffix, kind, builder, sentence)]`` chosen from
    ``model.drawing()`` (never from the model's name); builders are
    zero-argument callables returning a Figure (built one at a time)."""
    d = model.drawing()
    _check_drawing(model, d)
    n = model.n_dof
    long_line = d.layout == "line" and n > LONG_CHAIN
    zoom = None if long_line else _zoom_end(modal, t)
    thesis = thesis or d.extra.get("thesis")
    ctx = {"drawing": d, "title": title, "t": t, "q": y[:n], "v": y[n:], "n": n, "zoom": zoom,
           "ref": f" ({thesis})" if thesis else "", "caption": d.caption.strip().rstrip("."),
           "unit": d.unit, "mass": np.asarray(model.mass, dtype=float), "name": model.name,
           "coord_names": list(getattr(model, "coord_names", None) or [f"q{i + 1}" for i in range(n)]),
           "modal": _modal_text(model, modal, t)}
    if long_line:
        ctx["window"] = _legible_end(modal, t)
        w = _fast_omega(modal)
        ctx["fast_period"] = 2 * math.pi / w if w else None
        ctx["fast_txt"] = (f"99% of the initial energy below {w:.3g} rad/s, period {2 * math.pi / w:.3g} s"
                           if w else "modal content unknown")
    if d.layout == "line":
        return _line_specs(ctx)
    if d.layout == "plane":
        return _plane_specs(ctx)
    if d.layout == "angles":
        return _series_specs(ctx, "angles", "angles", "angle")
    return _series_specs(ctx, "coordinates", "coordinates", "coordinate")


def _chain_labels(masses):
    """Legend labels of a short chain's displacements and velocities, with the
    masses (kg) when there are few or they differ."""
    n = len(masses)
    if n <= 4:
        tail = [f" (m{i + 1} = {m:.4g} kg)" for i, m in enumerate(masses)]
    elif np.all(masses == masses[0]):
        tail = [""] * n
    else:
        tail = [f" ({m:.4g} kg)" for m in masses]
    return ([f"x{i + 1}{tail[i]}" for i in range(n)], [f"v{i + 1}{tail[i]}" for i in range(n)])


def _plane_paths(title, d, q, labels, margin=0.06):
    """Displacement path of each point of the drawing about its reference
    position: one panel each, every panel centred on its own path, all on one
    scale (equal axes) and sized to the data, so no panel is mostly empty; or,
    with more than :data:`MAX_PATH_PANELS` points, one panel of every point's
    path in the plane with the anchors."""
    n = len(d.points)
    fig = kit.new_figure()
    if n > MAX_PATH_PANELS:
        kit.suptitle(fig, f"{title}: paths of the {n} points in the plane")
        nodes = _node_positions(d, q)
        factor, u = kit.si(np.concatenate([np.ravel(c) for xy in nodes for c in xy]), d.unit)
        ax = fig.subplots()
        for i, (x, y) in enumerate(nodes[:n]):
            _path_panel(ax, x, y, factor, u, "x", "y", color=kit.COORD_COLORS[i % len(kit.COORD_COLORS)])
        for ax_, ay_ in d.anchors:
            ax.plot(factor * ax_, factor * ay_, "x", color="k", ms=6)
        ax.margins(0.04)
        ax.set_aspect("equal", adjustable="datalim")
        kit.legend_below(fig)
        return fig
    kit.suptitle(fig, f"{title}: displacement paths of the {_count(n, 'mass')}")
    factor, u = kit.si(np.concatenate([q[[ix, iy]] for ix, iy in d.points]), d.unit)
    boxes = []
    for ix, iy in d.points:
        x, y = factor * q[ix], factor * q[iy]
        ok = np.isfinite(x) & np.isfinite(y)
        boxes.append((float(x[ok].min()), float(x[ok].max()), float(y[ok].min()), float(y[ok].max()))
                     if ok.any() else (-1.0, 1.0, -1.0, 1.0))
    wy = max(max(b[3] - b[2] for b in boxes), 1e-300)
    wx = [max(b[1] - b[0], 0.3 * wy, 1e-300) for b in boxes]
    titles = [f"{labels[i]}, rest at ({kit.fmt(rx)}, {kit.fmt(ry)}) {d.unit}" for i, (rx, ry) in enumerate(d.reference)]
    if n <= 4:  # one row, each panel as wide as its path needs on the common scale
        rows, cols = 1, n
        avail = kit.SIZE[0] - 0.8 - 0.45 * n  # inches for the panels (labels, ticks and gaps off)
        for _ in range(3):  # ... and never narrower than its title
            per_unit = avail / sum(wx)
            wx = [max(w, (0.56 * len(tt) * kit.FONT_SMALL / 72.0) / per_unit) for w, tt in zip(wx, titles)]
        axes = fig.subplots(1, n, squeeze=False, gridspec_kw={"width_ratios": wx}).ravel()
    else:
        cols = math.ceil(math.sqrt(n))
        rows = math.ceil(n / cols)
        axes = fig.subplots(rows, cols, squeeze=False).ravel()
        wx = [max(wx)] * n
    for i, ax in enumerate(axes):
        if i >= n:
            ax.set_visible(False)
            continue
        ix, iy = d.points[i]
        _path_panel(ax, q[ix], q[iy], factor, u, f"x{i + 1} - rest", "y - rest",
                    color=kit.COORD_COLORS[i % len(kit.COORD_COLORS)])
        ax.set_title(titles[i], fontsize=kit.FONT_SMALL)
        if i % cols:
            ax.set_ylabel("")
    kit.legend_below(fig)
    axes = axes[:n]
    centres = [((b[0] + b[1]) / 2, (b[2] + b[3]) / 2) for b in boxes]
    for ax, (cx, cy), w in zip(axes, centres, wx):  # provisional limits, for the layout
        ax.set_xlim(cx - w * (0.5 + margin), cx + w * (0.5 + margin))
        ax.set_ylim(cy - wy * (0.5 + margin), cy + wy * (0.5 + margin))
    kit.layout_on_edges_only(fig)
    fig.get_layout_engine().execute(fig)  # lays the panels out (no rendering); their sizes set the common scale
    fw, fh = fig.get_size_inches()
    size = [(ax.get_position().width * fw, ax.get_position().height * fh) for ax in axes]
    scale = max(max(w * (1 + 2 * margin) / sw, wy * (1 + 2 * margin) / sh) for w, (sw, sh) in zip(wx, size))
    for ax, (cx, cy), (sw, sh) in zip(axes, centres, size):
        ax.set_xlim(cx - scale * sw / 2, cx + scale * sw / 2)
        ax.set_ylim(cy - scale * sh / 2, cy + scale * sh / 2)
        ax.set_aspect("equal", adjustable="box")
    return fig


def scene_figures(out_dir, scene_name, model, t, y, *, title, thesis=None, modal=None) -> list[tuple[Path, str]]:
    """The thesis' state figures (Figs 4.1-4.20) for one scene trajectory.

    Parameters
    ----------
    out_dir : path-like
        Directory for the PNGs (created if missing).
    scene_name : str
        Stem of the file names (made lowercase with underscores).
    model : rk4h.models.Model
        The scene's model; its :meth:`~rk4h.models.Model.drawing` (never
        its name) selects the figures by ``layout``:

        * ``"line"`` with at most 10 masses: displacement and velocity of each
          mass vs time (``_displacement``, ``_velocity``); with more masses,
          space-time images (mass index vs time, colour = displacement /
          velocity), same two names; when the whole run has more oscillations
          of the fastest excited mode than the image can resolve, the signed
          image shows the first part of the run and a second panel the
          amplitude over the whole run;
        * ``"plane"`` with one point: its x, y and velocity vs time
          (``_displacement``, ``_velocity``), the elongation ``|P_b - P_a| -
          rest`` of each of the drawing's springs when it has any
          (``_springs``; ``P`` = reference + displacement for a point, the
          anchor's position for an anchor) and the x-y path (``_trajectory``,
          titled by ``extra["path_title"]``);
        * ``"plane"`` with several points: each point's displacement path
          about its reference position (``_paths``);
        * ``"angles"``: the angles vs time (``_angles``);
        * ``"coordinates"``: the coordinates vs time (``_coordinates``).

        Time series show the whole run and, below it, the first three periods of
        the slowest non-zero mode of the linearization (omitted when that is
        more than half the run, or without ``modal``).
    t : array_like, shape (m,)
        Output times (s).
    y : array_like, shape (2 n_dof, m)
        States ``[q, v]`` at ``t`` (SI units; NaN after a blow-up is drawn as a gap).
    title : str
        Figure title (the scene and what the trajectory is).
    thesis : str or None
        The thesis figures the scene reproduces (the scene's ``thesis_figures``,
        e.g. ``"thesis Figs 4.1-4.2"``), quoted in parentheses in every
        sentence; None: the drawing's ``extra["thesis"]`` if any, else nothing.
        The shipped models carry none: a model does not know whether a scene
        reproduces a thesis figure.
    modal : dict or None
        The trajectory's modal content as its record holds it
        (:func:`rk4h.validation.execute.modal_content`): ``"omega"`` (rad/s, one
        per mode of the linearization), ``"fraction0"`` (the initial state's
        share of the linear modal energy per mode), ``"share_min"`` and
        ``"share_t"`` (s) (the lowest share of the dominant mode over the run
        and when). It sets the zoom window (three periods of the slowest mode)
        and the sentences' modal facts; None or ``{}``: neither is drawn.

    Returns
    -------
    list of (Path, Caption)
        Each PNG and its scene-specific sentence (``caption.kind``: the
        figure kind in :data:`GENERIC_CAPTIONS`). Sentences are computed from
        the data: the initial state's modal content (one frequency, or which
        modes and whether they beat), a path's shape from its principal axes,
        peak values, the window shown; they quote ``extra["thesis"]`` and
        ``extra["rest_note"]``, and the drawing's ``caption`` only where the
        data do not contradict it (not for a single-mode start, not for a
        path that is a straight line).

    Raises
    ------
    ValueError
        ``t``/``y`` of the wrong shape, or a drawing whose fields do not fit
        the model (unknown layout, point indices beyond ``n_dof``, ...).
    """
    if model.first_order:  # any ODE: its variables against time, no drawing
        return _first_order_state(out_dir, scene_name, model, t, y, title)
    t, y = _check_trajectory(model, t, y)
    stem = kit.slug(scene_name)
    out = []
    for suffix, kind, build, sentence in _scene_specs(scene_name, model, t, y, title, thesis, modal):
        fig = build()
        out.append((kit.save(fig, out_dir, f"{stem}_{suffix}"), Caption(sentence, kind)))
    return out


def _first_order_state(out_dir, scene_name, model, t, y, title):
    """The state figure of a first-order ODE (``model.first_order``): each
    variable against time (kind ``coordinates``); its units are the user's."""
    t = np.asarray(t, dtype=float)
    y = np.asarray(y, dtype=float)
    n = model.n_state
    if t.ndim != 1 or t.size < 2 or y.shape != (n, t.size):
        raise ValueError(f"`y` must have shape {(n, t.size)} for {model.name} (and `t` 1-D, >= 2 times), "
                         f"got {y.shape}")
    names = list(model.coord_names)
    series = list(zip(names, y))
    head = f"Variables of the ODE ({', '.join(names[:6])}{', ...' if n > 6 else ''}), 0 to {kit.fmt_t(t[-1])} s"
    fig = kit.new_figure()
    kit.suptitle(fig, f"{title}: variables")
    ax = fig.subplots()
    for j, (label, v) in enumerate(series):
        lw = 1.0 * (1.0 - 0.5 * j / max(1, n - 1))  # later curves thinner: coinciding curves stay visible
        ax.plot(t, v, color=kit.COORD_COLORS[j % len(kit.COORD_COLORS)], lw=lw, label=label)
    ax.set_xlim(t[0], t[-1])
    ax.set_ylabel("value (the equations' units)")
    ax.set_xlabel("time t (s)")
    ax.grid(alpha=0.3)
    kit.legend_below(fig)
    text = kit.sentence(head, f"largest |value| {_peak(series, '')}")
    return [(kit.save(fig, out_dir, f"{kit.slug(scene_name)}_variables"), Caption(text, "coordinates"))]
