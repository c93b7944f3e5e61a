"""The report's figures: plots of data the runner has already computed.

Every public function draws one kind of figure from arrays or DataFrames,
writes a PNG into ``out_dir`` and returns ``(path, sentence)``, where
``sentence`` is one line telling a reader what to read from the figure (it goes
into ``index.md``). Nothing here integrates, fits or measures: the runner
computes, this module draws. The only numbers derived here are display aids
(axis windows, SI prefixes, a running maximum, slope guides).

Conventions
-----------
* Rendering is by matplotlib's Agg canvas on :class:`matplotlib.figure.Figure`
  objects created without pyplot, so no figure is ever registered with pyplot
  (nothing to close, nothing left open, no display needed) and the caller's
  pyplot backend is left alone.
* One colour and marker per solver across all figures (:data:`SOLVER_STYLE`);
  the exact/reference solution is black.
* Sizes: :data:`SIZE` (7 x 4.5 in) at :data:`DPI` (120), i.e. 840 x 540 px;
  the dispersion figure is :data:`SIZE_TALL` (7 x 6 in, 840 x 720 px).
* File names are lowercase with underscores and start with the scene name made
  so (:func:`slug`): ``thesis-2dof-case1`` -> ``thesis_2dof_case1_displacement.png``.
* Units are SI; small quantities get an SI prefix on the axis label (mm, mm/s,
  mrad) so tick labels stay plain numbers.

References
----------
The figures regenerate the thesis' Figs 4.1-4.20 (chapter 4 of the seed) with
the corrected physics listed in DESIGN.md's errata.
"""
from __future__ import annotations

import contextlib
import io
import math
import re
import textwrap
from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from PIL import Image

from references.registry import BUILTIN, UNDER_TEST, resolve

__all__ = ["scene_figures", "work_precision", "convergence", "energy_error", "dispersion",
           "crossover", "slug", "SOLVER_STYLE", "SIZE", "SIZE_TALL", "DPI"]

SIZE = (7.0, 4.5)        # inches
SIZE_TALL = (7.0, 6.0)   # inches, the three-panel dispersion figure
DPI = 120

#: colour and marker of each built-in method (``references.registry``), the
#: same in every figure; a scene's own methods get theirs from the registry
#: while :func:`scene_methods` is in effect.
SOLVER_STYLE = {name: (m.style.color, m.style.marker) for name, m in BUILTIN.items()}
SOLVER_STYLE.update({"exact": ("#000000", "."), "reference": ("#000000", ".")})
#: the methods of the scene being drawn (set by :func:`scene_methods`)
_LOCAL: dict = {}
_UNKNOWN_STYLE = ("#7f7f7f", "x")
# Per-coordinate colours in state plots (mass 1 red, mass 2 blue as in the thesis).
_COORD_COLORS = ["#d62728", "#1f77b4", "#2ca02c", "#ff7f0e", "#9467bd",
                 "#8c564b", "#e377c2", "#7f7f7f", "#bcbd22", "#17becf"]
_LINESTYLES = ["-", "--", ":", "-."]
_GUIDE_STYLES = ["--", ":", "-.", (0, (5, 1, 1, 1))]
LONG_CHAIN = 10          # chains with more masses get a space-time image
_ZOOM_PERIODS = 3        # the zoom panel shows this many slowest periods

# Set by tests to inspect each figure just before it is written.
_SAVE_HOOK = None


# -- shared helpers -------------------------------------------------------------
def slug(name: str) -> str:
    """Lowercase file-name stem: runs of characters other than ``a-z0-9`` -> ``_``."""
    s = re.sub(r"[^a-z0-9]+", "_", str(name).lower()).strip("_")
    if not s:
        raise ValueError(f"`scene_name` must contain a letter or digit, got {name!r}")
    return s


@contextlib.contextmanager
def scene_methods(local):
    """Draw with the styles and orders of a scene's own methods (name ->
    ``references.registry.Method``) besides the built-ins."""
    global _LOCAL
    saved, _LOCAL = _LOCAL, dict(local or {})
    try:
        yield
    finally:
        _LOCAL = saved


def _all_styles() -> dict:
    return {**SOLVER_STYLE, **{n: (m.style.color, m.style.marker) for n, m in _LOCAL.items()}}


def solver_style(label: str):
    """``(colour, marker)`` of the solver ``label`` names (its longest known prefix)."""
    return _all_styles().get(_solver_of(label), _UNKNOWN_STYLE)


def _solver_of(label: str) -> str:
    lab = str(label).lower()
    for name in sorted(_all_styles(), key=len, reverse=True):
        if lab == name or lab.startswith(name + " ") or lab.startswith(name + ","):
            return name
    return lab


def _order_of(solver):
    """Expected order of ``solver`` (built-in or the drawn scene's), None if unknown."""
    try:
        return resolve(solver, _LOCAL).order
    except ValueError:
        return None


def _new_figure(size=SIZE, **kw) -> Figure:
    fig = Figure(figsize=size, dpi=DPI, layout="constrained", **kw)
    FigureCanvasAgg(fig)
    return fig


def _suptitle(fig, text):
    fig.suptitle("\n".join(textwrap.wrap(str(text), 90)) or None, fontsize=10)


def _save(fig, out_dir, stem) -> Path:
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    path = out / f"{stem}.png"
    if _SAVE_HOOK is not None:
        _SAVE_HOOK(fig, path)
    # Fixed canvas (no bbox_inches), so the pixel size is size * DPI. Rendered to
    # RGB, then stored as a 256-colour palette PNG: a third of the bytes, and
    # plots have few colours.
    fig.patch.set_alpha(1.0)
    buf = io.BytesIO()
    fig.savefig(buf, dpi=DPI, format="png", facecolor="white")
    with Image.open(buf) as im:
        pal = im.convert("RGB").quantize(colors=256, method=Image.Quantize.MEDIANCUT, dither=Image.Dither.NONE)
        pal.save(path, format="PNG", optimize=True)
    return path


def _si(values, unit):
    """``(factor, label_unit)``: the SI prefix that puts max |values| in [1, 1000)."""
    a = np.asarray(values, dtype=float)
    a = a[np.isfinite(a)]
    amax = float(np.max(np.abs(a))) if a.size else 0.0
    if not amax > 0.0:
        return 1.0, unit
    exp3 = min(0, max(-9, 3 * math.floor(math.log10(amax) / 3)))
    prefix = {0: "", -3: "m", -6: "\u00b5", -9: "n"}[exp3]
    return 10.0 ** (-exp3), prefix + unit


def _fmt(x) -> str:
    return f"{x:.3g}"


def _check_trajectory(model, t, y):
    t = np.asarray(t, dtype=float)
    y = np.asarray(y, dtype=float)
    if t.ndim != 1 or t.size < 2:
        raise ValueError(f"`t` must be 1-D with at least 2 times, got shape {t.shape}")
    if y.shape != (2 * model.n_dof, t.size):
        raise ValueError(f"`y` must have shape {(2 * model.n_dof, t.size)} for {model.name}, got {y.shape}")
    return t, y


def _zoom_end(model, t):
    """End of a window of ``_ZOOM_PERIODS`` periods of the slowest non-zero mode
    of the linearization, or None when that covers most of the horizon."""
    try:
        omega, _ = model.modes()
    except (NotImplementedError, ValueError, np.linalg.LinAlgError):
        return None
    omega = omega[omega > 0]
    if omega.size == 0:
        return None
    t_end = t[0] + _ZOOM_PERIODS * 2.0 * math.pi / float(omega.min())
    return t_end if t_end < t[0] + 0.5 * (t[-1] - t[0]) else None


# -- scene figures (thesis Figs 4.1-4.20) ---------------------------------------
def _time_series(title, what, t, series, unit, zoom_end, ylabel):
    """One or two panels (full horizon, then the first few periods) of ``series``:
    list of (label, values)."""
    fig = _new_figure()
    _suptitle(fig, f"{title}: {what}")
    factor, u = _si(np.concatenate([np.ravel(v) for _, v in series]), unit)
    axes = fig.subplots(2 if zoom_end is not None else 1, 1, squeeze=False)[:, 0]
    for i, ax in enumerate(axes):
        for j, (label, v) in enumerate(series):
            # Later curves thinner and dashed, so coinciding curves stay visible.
            lw = (1.0 if i == 0 else 2.2) * (1.0 - 0.5 * j / max(1, len(series) - 1))
            ax.plot(t, factor * np.asarray(v), color=_COORD_COLORS[j % len(_COORD_COLORS)],
                    lw=lw, ls=_LINESTYLES[j % 2] if i else "-", label=label if i == 0 else None)
        ax.set_ylabel(f"{ylabel} ({u})")
        ax.grid(alpha=0.3)
        ax.axhline(0.0, color="0.5", lw=0.5)
    axes[0].set_xlim(t[0], t[-1])
    axes[0].set_title(f"whole run, 0 to {_fmt(t[-1])} s", fontsize=9, loc="left")
    if zoom_end is not None:
        axes[1].set_xlim(t[0], zoom_end)
        axes[1].set_title(f"first {_fmt(zoom_end - t[0])} s", fontsize=9, loc="left")
    axes[-1].set_xlabel("time t (s)")
    leg = fig.legend(loc="outside lower center", ncol=min(len(series), 5), fontsize=8, frameon=False)
    for handle in leg.legend_handles:
        handle.set_linewidth(2.0)  # thin curves' colours must still read in the key
    return fig


def _path_panel(ax, x, y, factor, u, label_x, label_y, color="#1f77b4"):
    ax.plot(factor * x, factor * y, color=color, lw=0.6)
    ax.plot(factor * x[0], factor * y[0], "o", color="k", ms=4, label="start")
    ax.set_xlabel(f"{label_x} ({u})")
    ax.set_ylabel(f"{label_y} ({u})")
    ax.set_aspect("equal", adjustable="datalim")
    ax.grid(alpha=0.3)


def _xy_path(title, x, y, unit="m", what="trajectory in the x-y plane"):
    fig = _new_figure()
    _suptitle(fig, f"{title}: {what}")
    factor, u = _si(np.concatenate([x, y]), unit)
    ax = fig.subplots()
    _path_panel(ax, x, y, factor, u, "x", "y")
    ax.legend(loc="upper right", fontsize=8)
    return fig


def _space_time(title, what, t, values, unit, label):
    """Image of ``values`` (n_masses, m): mass index vs time, colour = value."""
    fig = _new_figure()
    _suptitle(fig, f"{title}: {what}")
    factor, u = _si(values, unit)
    mag = np.abs(values[np.isfinite(values)])
    # Colour limit at the 99.5th percentile: a short initial kick must not wash
    # out the waves that follow (values beyond it are clipped, the bar says so).
    vmax = factor * float(np.percentile(mag, 99.5)) if mag.size else 0.0
    peak = factor * float(mag.max()) if mag.size else 0.0
    vmax = vmax if vmax > 0 else (peak if peak > 0 else 1.0)
    ax = fig.subplots()
    n = values.shape[0]
    dt = np.diff(t)
    if np.allclose(dt, dt.mean(), rtol=1e-6, atol=0.0):
        im = ax.imshow(factor * values, origin="lower", aspect="auto", cmap="RdBu_r",
                       vmin=-vmax, vmax=vmax, interpolation="nearest",
                       extent=(t[0] - dt.mean() / 2, t[-1] + dt.mean() / 2, 0.5, n + 0.5))
    else:
        im = ax.pcolormesh(t, np.arange(1, n + 1), factor * values, cmap="RdBu_r",
                           vmin=-vmax, vmax=vmax, shading="nearest")
    ax.set_xlabel("time t (s)")
    ax.set_ylabel("mass index n")
    fig.colorbar(im, ax=ax, label=f"{label} ({u})", extend="both" if peak > vmax * (1 + 1e-9) else "neither")
    return fig


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


def _sentence(head, tail=""):
    """``head`` with ``": tail"`` when there is one, ended by a full stop."""
    return f"{head}: {tail}." if tail else f"{head}."


def _line_specs(ctx):
    title, t, q, v, n, zoom, ref, cap, zoom_txt = (ctx[k] for k in (
        "title", "t", "q", "v", "n", "zoom", "ref", "caption", "zoom_txt"))
    if n > LONG_CHAIN:
        return [
            ("displacement", lambda: _space_time(title, "displacement of each mass", t, q, ctx["unit"],
                                                 "displacement"),
             _sentence(f"Space-time image of the {n}-mass chain's displacements{ref} (mass index vs time, red "
                       f"right, blue left; colours clipped at the 99.5th percentile)",
                       cap or "a wave or packet shows as a band whose slope is its speed in masses per second")),
            ("velocity", lambda: _space_time(title, "velocity of each mass", t, v, f"{ctx['unit']}/s", "velocity"),
             f"Space-time image of the {n}-mass chain's velocities (mass index vs time); "
             f"read it beside the displacement image."),
        ]
    labels, vlabels = _chain_labels(ctx["mass"])
    return [
        ("displacement", lambda: _time_series(title, "displacement of each mass", t,
                                              list(zip(labels, q)), ctx["unit"], zoom, "displacement"),
         _sentence(f"Displacement of each of the {n} masses vs time{zoom_txt}{ref}",
                   cap or f"read the superposition of the {n} normal modes (beats when two are close)")),
        ("velocity", lambda: _time_series(title, "velocity of each mass", t,
                                          list(zip(vlabels, v)), f"{ctx['unit']}/s", zoom, "velocity"),
         f"Velocity of each of the {n} masses vs time{zoom_txt}{ref}."),
    ]


def _plane_specs(ctx):
    d, title, t, q, v, zoom, ref, cap, zoom_txt, unit = (ctx[k] for k in (
        "drawing", "title", "t", "q", "v", "zoom", "ref", "caption", "zoom_txt", "unit"))
    labels = list(d.point_labels) + [f"point {i + 1}" for i in range(len(d.point_labels), len(d.points))]
    if len(d.points) > 1:
        n = len(d.points)
        return [("paths", lambda: _plane_paths(title, d, q, labels),
                 _sentence(f"Displacement path of each of the {_count(n, 'mass')} about its rest position (equal "
                           f"axes, same scale in every panel){ref}" if n <= MAX_PATH_PANELS else
                           f"Paths of the {n} points in the plane (rest position plus displacement, equal axes; "
                           f"anchors: black crosses){ref}", cap))]
    (ix, iy), (rx, ry) = d.points[0], d.reference[0]
    who = labels[0]
    at_origin = rx == 0.0 and ry == 0.0
    pos = "position" if at_origin else "displacement"
    specs = [
        ("displacement", lambda: _time_series(title, f"{pos} of the {who}", t, [("x", q[ix]), ("y", q[iy])],
                                              unit, zoom, pos),
         f"{pos.capitalize()} x, y of the {who}{'' if at_origin else ' from its rest position'} vs "
         f"time{zoom_txt}{ref}."),
        ("velocity", lambda: _time_series(title, f"velocity of the {who}", t, [("vx", v[ix]), ("vy", v[iy])],
                                          f"{unit}/s", zoom, "velocity"),
         f"Velocity of the {who} vs time{zoom_txt}{ref}."),
    ]
    if d.springs:
        note = d.extra.get("rest_note")
        anchored = sum(1 for a, b, _ in d.springs if max(int(a), int(b)) >= len(d.points))
        specs.append(
            ("springs", lambda: _time_series(title, "spring elongations (length - natural length)", t,
                                             _spring_elongations(d, q), unit, zoom, "elongation"),
             f"Elongation (length - natural length{'; ' + note if note else ''}) of each of the "
             f"{_count(len(d.springs), 'spring')}{f' ({anchored} of them anchored)' if anchored else ''} vs "
             f"time{zoom_txt}{ref}."))
    specs.append(
        ("trajectory", lambda: _xy_path(title, q[ix], q[iy], unit,
                                        what=d.extra.get("path_title", "trajectory in the x-y plane")),
         f"Path of the {who} in the x-y plane (equal axes){ref}" + (f"; {cap}." if cap else ".")))
    return specs


def _series_specs(ctx, stem, what, ylabel):
    d, n, title, t, q, zoom, ref, cap, zoom_txt = (ctx[k] for k in (
        "drawing", "n", "title", "t", "q", "zoom", "ref", "caption", "zoom_txt"))
    names = list(d.point_labels) if len(d.point_labels) == n else list(ctx["coord_names"])
    head = (f"Angles {', '.join(names)} vs time{zoom_txt}{ref}" if stem == "angles" else
            f"Generalized coordinates of {ctx['name']} vs time{zoom_txt}{ref}")
    return [(stem, lambda: _time_series(title, what, t, list(zip(names, q)), d.unit, zoom, ylabel),
             _sentence(head, cap))]


def _scene_specs(scene_name, model, t, y, title):
    """``[(stem_suffix, builder, sentence)]`` chosen from ``model.drawing()``
    (never from the model's name); builders are zero-argument callables
    returning a Figure (built one at a time)."""
    d = model.drawing()
    _check_drawing(model, d)
    n = model.n_dof
    zoom = None if (d.layout == "line" and n > LONG_CHAIN) else _zoom_end(model, t)
    thesis = d.extra.get("thesis")
    ctx = {"drawing": d, "title": title, "t": t, "q": y[:n], "v": y[n:], "n": n, "zoom": zoom,
           "ref": f" ({thesis})" if thesis else "", "caption": d.caption.strip().rstrip("."),
           "zoom_txt": f", whole run above and the first {_fmt(zoom - t[0])} s below" if zoom else "",
           "unit": d.unit, "mass": np.asarray(model.mass, dtype=float), "name": model.name,
           "coord_names": list(getattr(model, "coord_names", None) or [f"q{i + 1}" for i in range(n)])}
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


def _plane_paths(title, d, q, labels):
    """Displacement path of each point of the drawing about its reference
    position: one panel each (same scale), or, with more than
    :data:`MAX_PATH_PANELS` points, one panel of every point's path in the
    plane with the anchors."""
    n = len(d.points)
    fig = _new_figure()
    disp = np.concatenate([q[[ix, iy]] for ix, iy in d.points])
    if n > MAX_PATH_PANELS:
        _suptitle(fig, f"{title}: paths of the {n} points in the plane")
        nodes = _node_positions(d, q)
        factor, u = _si(np.concatenate([np.ravel(c) for xy in nodes for c in xy]), d.unit)
        ax = fig.subplots()
        for i, (x, y) in enumerate(nodes[:n]):
            _path_panel(ax, x, y, factor, u, "x", "y", color=_COORD_COLORS[i % len(_COORD_COLORS)])
        for ax_, ay_ in d.anchors:
            ax.plot(factor * ax_, factor * ay_, "x", color="k", ms=6)
        return fig
    _suptitle(fig, f"{title}: displacement paths of the {_count(n, 'mass')}")
    factor, u = _si(disp, d.unit)
    lim = 1.05 * factor * float(np.nanmax(np.abs(disp[np.isfinite(disp)]))) if np.isfinite(disp).any() else 1.0
    lim = lim if lim > 0 else 1.0
    cols = n if n <= 4 else math.ceil(math.sqrt(n))
    axes = np.atleast_1d(fig.subplots(math.ceil(n / cols), cols, sharex=True, sharey=True)).ravel()
    for i, ax in enumerate(axes):
        if i >= n:
            ax.set_visible(False)
            continue
        ix, iy = d.points[i]
        _path_panel(ax, q[ix], q[iy], factor, u, f"x{i + 1} - rest", "y - rest",
                    color=_COORD_COLORS[i % len(_COORD_COLORS)])
        ax.set_xlim(-lim, lim)
        ax.set_ylim(-lim, lim)
        ax.set_aspect("equal", adjustable="box")
        rx, ry = d.reference[i]
        ax.set_title(f"{labels[i]}, rest at ({_fmt(rx)}, {_fmt(ry)}) {d.unit}", fontsize=8)
        if i % cols:
            ax.set_ylabel("")
    axes[0].legend(loc="upper left", fontsize=7)
    return fig


def scene_figures(out_dir, scene_name, model, t, y, *, title) -> list[tuple[Path, str]]:
    """The thesis' state figures (Figs 4.1-4.20) for one scene trajectory.

    Parameters
    ----------
    out_dir : path-like
        Directory for the PNGs (created if missing).
    scene_name : str
        Stem of the file names (made lowercase with underscores).
    model : rk4core.models.Model
        The scene's model; its :meth:`~rk4core.models.Model.drawing` (never
        its name) selects the figures by ``layout``:

        * ``"line"`` with at most 10 masses: displacement and velocity of each
          mass vs time (``_displacement``, ``_velocity``); with more masses,
          space-time images (mass index vs time, colour = displacement /
          velocity), same two names;
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

        Sentences quote the drawing's ``caption``, ``extra["thesis"]`` (the
        thesis figures reproduced) and ``extra["rest_note"]``.
        Time series show the whole run and, below it, the first three periods of
        the slowest non-zero mode of the linearization (omitted when that is
        more than half the run).
    t : array_like, shape (m,)
        Output times (s).
    y : array_like, shape (2 n_dof, m)
        States ``[q, v]`` at ``t`` (SI units; NaN after a blow-up is drawn as a gap).
    title : str
        Figure title (the scene and what the trajectory is).

    Returns
    -------
    list of (Path, str)
        Each PNG and the one-line sentence for ``index.md``.

    Raises
    ------
    ValueError
        ``t``/``y`` of the wrong shape, or a drawing whose fields do not fit
        the model (unknown layout, point indices beyond ``n_dof``, ...).
    """
    t, y = _check_trajectory(model, t, y)
    stem = slug(scene_name)
    out = []
    for suffix, build, sentence in _scene_specs(scene_name, model, t, y, title):
        fig = build()
        out.append((_save(fig, out_dir, f"{stem}_{suffix}"), sentence))
    return out


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


def _in_palette_order(solvers):
    """Solvers in the order of :data:`SOLVER_STYLE` (then the scene's own
    methods, then unknown ones), so legends list them the same way in every figure."""
    known = list(_all_styles())
    return sorted(solvers, key=lambda s: (known.index(s) if s in known else len(known), str(s)))


def _require(df, name, cols):
    missing = [c for c in cols if c not in df.columns]
    if missing:
        raise ValueError(f"`{name}` is missing column `{missing[0]}` (has {list(df.columns)})")


def work_precision(out_dir, scene_name, df) -> tuple[Path, str]:
    """Work-precision diagram: error against wall time and against RHS evaluations.

    Parameters
    ----------
    out_dir : path-like
    scene_name : str
    df : pandas.DataFrame
        Columns ``solver``, ``setting`` (h in s, or rtol), ``error_max``,
        ``wall_s`` (s), ``nfev``; optional ``status`` (rows other than ``ok``
        are dropped), ``n_steps`` and ``taylor_order``. Rows with a missing or
        non-positive error or time are dropped (they cannot be placed on log axes).

    Returns
    -------
    (Path, str)

    Notes
    -----
    heyoka's Taylor integrator makes no RHS calls: when ``n_steps`` and
    ``taylor_order`` are given it is placed on the right panel at steps x order
    (and its legend entry says so); otherwise rows with ``nfev`` <= 0 or NaN
    are left off that panel only, and the legend says which.
    """
    _require(df, "df", ["solver", "setting", "error_max", "wall_s", "nfev"])
    d = _ok_rows(df, ["error_max", "wall_s"])
    fig = _new_figure()
    _suptitle(fig, f"{scene_name}: work-precision (lower left is better)")
    ax_t, ax_n = fig.subplots(1, 2, sharey=True)
    notes = []
    for solver in _in_palette_order(d["solver"].unique()):
        rows = d[d["solver"] == solver].sort_values("setting", ascending=False)
        color, marker = solver_style(solver)
        err = rows["error_max"].to_numpy(float)
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
        ax_t.plot(rows["wall_s"].to_numpy(float), err, marker=marker, color=color, ms=5, lw=1.2, label=label)
        if good.any():
            ax_n.plot(cost[good], err[good], marker=marker, color=color, ms=5, lw=1.2)
    for ax, xl in ((ax_t, "wall time (s)"), (ax_n, "right-hand-side evaluations nfev")):
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel(xl)
        ax.grid(which="major", alpha=0.3)
        ax.grid(which="minor", alpha=0.1)
    ax_t.set_ylabel("max error over time and components")
    if len(d):
        fig.legend(loc="outside lower center", ncol=min(4, d["solver"].nunique()), fontsize=8, frameon=False)
    path = _save(fig, out_dir, f"{slug(scene_name)}_work_precision")
    dropped = len(df) - len(d)
    extra = f" {dropped} failed or error-free run(s) are not drawn." if dropped else ""
    extra += f" {', '.join(notes)} appear(s) in the wall-time panel only (no RHS count)." if notes else ""
    sentence = (f"Error against wall time (left) and against right-hand-side evaluations (right), one line per "
                f"solver, log-log: the lowest curve at a given cost is the cheapest solver for that accuracy, "
                f"and where curves cross the best choice changes.{extra}")
    return path, sentence


# -- convergence ----------------------------------------------------------------
def _guide(ax, slope, x_anchor, y_anchor, x_range, style, label):
    """Line ``y = y_anchor (x / x_anchor)^slope`` over ``x_range``."""
    x = np.array(x_range, dtype=float)
    ax.plot(x, y_anchor * (x / x_anchor) ** slope, style, color="0.35", lw=1.0, label=label,
            gid=f"guide_slope_{slope:g}")


def convergence(out_dir, scene_name, points, fits) -> tuple[Path, str]:
    """Error against step size on log-log axes with slope guides.

    Parameters
    ----------
    out_dir : path-like
    scene_name : str
    points : pandas.DataFrame
        Columns ``solver``, ``h`` (s), ``error_max``. Non-positive or NaN
        errors are left off.
    fits : pandas.DataFrame
        Columns ``solver``, ``observed_order``, ``h_min``, ``h_max`` (s): the
        least-squares order and the step range it was fitted over. Points
        inside the range are filled, those outside hollow.

    Returns
    -------
    (Path, str)

    Notes
    -----
    The slope-4 guide (error proportional to h^4, classical RK4) runs under
    the RK4 points over their step range, through a third of the error at
    their smallest step inside the fit range; the slope-1 guide likewise under
    Euler's (or symplectic Euler's), when present. Without RK4 points the
    slope-4 guide is anchored on the first solver's.
    """
    _require(points, "points", ["solver", "h", "error_max"])
    _require(fits, "fits", ["solver", "observed_order", "h_min", "h_max"])
    p = _ok_rows(points, ["h", "error_max"])
    fig = _new_figure()
    _suptitle(fig, f"{scene_name}: convergence of the error with the step size")
    ax = fig.subplots()
    fit_of = {r.solver: r for r in fits.itertuples()}
    orders = []
    for solver in _in_palette_order(p["solver"].unique()):
        rows = p[p["solver"] == solver].sort_values("h")
        h, e = rows["h"].to_numpy(float), rows["error_max"].to_numpy(float)
        color, marker = solver_style(solver)
        f = fit_of.get(solver)
        if f is not None and np.isfinite(f.observed_order):
            inside = (h >= f.h_min * (1 - 1e-9)) & (h <= f.h_max * (1 + 1e-9))
            label = f"{solver}: order {f.observed_order:.2f} (fit h {_fmt(f.h_min)}-{_fmt(f.h_max)} s)"
            orders.append(f"{solver} {f.observed_order:.2f}")
        else:
            inside = np.ones_like(h, dtype=bool)
            label = f"{solver} (no fit)"
        ax.plot(h, e, "-", color=color, lw=1.0, label=label)
        ax.plot(h[inside], e[inside], marker, color=color, ms=6, ls="none")
        ax.plot(h[~inside], e[~inside], marker, mfc="none", color=color, ms=6, ls="none")
    by_order = {}  # expected order -> its solvers, highest order first
    for solver in _in_palette_order(p["solver"].unique()):
        order = _order_of(solver)
        if order is not None:
            by_order.setdefault(int(order), []).append(solver)
    if not by_order and not p.empty:
        by_order = {4: list(p["solver"].unique()[:1])}
    for i, (slope, solvers) in enumerate(sorted(by_order.items(), reverse=True)):
        style = _GUIDE_STYLES[i % len(_GUIDE_STYLES)]
        sel = p[p["solver"].isin(solvers)]
        sel = sel[sel["solver"] == sel["solver"].iloc[0]]
        h_range = (sel["h"].min(), sel["h"].max())  # the guide spans its solver's steps only
        f = fit_of.get(sel["solver"].iloc[0])
        if f is not None:
            in_fit = sel[(sel["h"] >= f.h_min * (1 - 1e-9)) & (sel["h"] <= f.h_max * (1 + 1e-9))]
            sel = in_fit if len(in_fit) else sel
        anchor = sel.sort_values("h").iloc[0]
        _guide(ax, slope, float(anchor["h"]), float(anchor["error_max"]) / 3.0, h_range, style,
               f"slope {slope} guide (error ~ h^{slope})")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("step size h (s)")
    ax.set_ylabel("max error over time and components")
    ax.grid(which="major", alpha=0.3)
    ax.grid(which="minor", alpha=0.1)
    ax.legend(loc="lower right", fontsize=8)  # large h with small error: empty for any consistent method
    path = _save(fig, out_dir, f"{slug(scene_name)}_convergence")
    got = "; observed orders: " + ", ".join(orders) if orders else ""
    guides = ", ".join(f"slope {o} ({'/'.join(m)})" for o, m in sorted(by_order.items(), reverse=True))
    sentence = (f"Max error against step size h, log-log, with slope guides ({guides}): a method parallel to its "
                f"guide has that order; filled points are the fitted range, hollow "
                f"ones lie outside it (pre-asymptotic or at the round-off floor){got}.")
    return path, sentence


# -- energy error ---------------------------------------------------------------
def energy_error(out_dir, scene_name, series, *, title=None, stem=None, sentence=None) -> tuple[Path, str]:
    """Relative energy error ``|E(t) - E0| / |E0|`` of several runs on log-log axes.

    Parameters
    ----------
    out_dir : path-like
    scene_name : str
    series : dict
        ``label -> (t, rel_energy_error)``, arrays of equal length; ``t`` in s.
        A label starting with a solver name (``"rk4 h=0.01"``) takes that
        solver's colour; labels of the same solver get different line styles.
    title, stem, sentence : str, optional
        The figure's title, file stem and reading (defaults: the scene's
        energy-error figure); the stability study's long-horizon figure
        passes its own.

    Returns
    -------
    (Path, str)

    Notes
    -----
    Times ``t <= 0`` (the initial state, error 0) are left off the log time
    axis, which so starts at the first step. Thin lines are the instantaneous error, thick lines its
    running maximum (the envelope, readable where the error oscillates down
    to zero twice a period). Zero errors are not drawn.
    """
    if not isinstance(series, dict):
        raise ValueError(f"`series` must be a dict label -> (t, error), got {type(series).__name__}")
    fig = _new_figure()
    _suptitle(fig, title or f"{scene_name}: relative energy error")
    ax = fig.subplots()
    seen: dict[str, int] = {}
    floor = np.inf
    for label, (t, err) in series.items():
        t, err = np.asarray(t, dtype=float), np.abs(np.asarray(err, dtype=float))
        if t.shape != err.shape or t.ndim != 1:
            raise ValueError(f"`series[{label!r}]` must be two 1-D arrays of equal length, "
                             f"got shapes {t.shape} and {err.shape}")
        color, _ = solver_style(label)
        solver = _solver_of(label)
        ls = _LINESTYLES[seen.get(solver, 0) % len(_LINESTYLES)]
        seen[solver] = seen.get(solver, 0) + 1
        show = t > 0
        env = np.fmax.accumulate(np.where(np.isfinite(err), err, np.nan)) if err.size else err
        inst = np.where(err > 0, err, np.nan)
        env = np.where(env > 0, env, np.nan)
        ax.plot(t[show], inst[show], color=color, lw=0.4, alpha=0.25, ls="-")
        ax.plot(t[show], env[show], color=color, lw=1.6, ls=ls, label=str(label))
        if np.isfinite(env[show]).any():
            floor = min(floor, float(np.nanmin(env[show])))
    ax.set_xscale("log")
    ax.set_yscale("log")
    if np.isfinite(floor):
        # The instantaneous error dips to zero twice a period; do not let those
        # dips stretch the axis below the smallest envelope value.
        ax.set_ylim(bottom=max(floor / 10.0, 1e-18))
    ax.set_xlabel("time t (s)")
    ax.set_ylabel("|E(t) - E0| / |E0|")
    ax.grid(which="major", alpha=0.3)
    ax.grid(which="minor", alpha=0.1)
    if series:
        fig.legend(loc="outside lower center", fontsize=8, ncol=min(4, len(series)), frameon=False,
                   title="thick: running maximum, thin: instantaneous value", title_fontsize=7)
    path = _save(fig, out_dir, stem or f"{slug(scene_name)}_energy_error")
    sentence = sentence or ("Relative energy error against time, log-log (thick: running maximum, thin: "
                            "instantaneous): a line of slope 1 is a steady drift (RK4 loses energy at a rate set "
                            "by (omega h)^6/72 per step), a flat band a bounded error (symplectic methods).")
    return path, sentence


def modal_energy(out_dir, scene_name, t, series, omega) -> tuple[Path, str]:
    """Fraction of the initial energy in each of the lowest linear modes against time.

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
    """
    if not isinstance(series, dict) or not series:
        raise ValueError("`series` must be a non-empty dict label -> (modes, m) array")
    t = np.asarray(t, dtype=float)
    fig = _new_figure()
    _suptitle(fig, f"{scene_name}: energy in the lowest modes (FPUT recurrence)")
    ax = fig.subplots()
    colors = plt_colors(len(omega))
    for s_i, (label, frac) in enumerate(series.items()):
        frac = np.asarray(frac, dtype=float)
        if frac.shape != (len(omega), t.size):
            raise ValueError(f"`series[{label!r}]` must have shape ({len(omega)}, {t.size}), got {frac.shape}")
        for j in range(frac.shape[0]):
            ax.plot(t, frac[j], color=colors[j], lw=1.4 if s_i == 0 else 1.0,
                    ls=_LINESTYLES[s_i % len(_LINESTYLES)],
                    label=f"mode {j + 1} ({omega[j]:.3g} rad/s), {label}")
    ax.set_xlabel("time t (s)")
    ax.set_ylabel("E_k(t) / E(0)")
    ax.set_ylim(bottom=0.0)
    ax.grid(alpha=0.3)
    fig.legend(loc="outside lower center", fontsize=7, ncol=2, frameon=False)
    path = _save(fig, out_dir, f"{slug(scene_name)}_modal_energy")
    sentence = ("Energy in the lowest linear modes against time, as a fraction of the initial energy: "
                "started in mode 1, an FPUT chain shares its energy with a few low modes and then returns "
                "almost all of it to mode 1 (the recurrence); a solver that reproduces the return time "
                "and height keeps the physics, one that does not has lost it.")
    return path, sentence


def plt_colors(n):
    """``n`` distinct colours of matplotlib's default cycle (repeated if needed)."""
    import matplotlib

    cycle = matplotlib.rcParams["axes.prop_cycle"].by_key()["color"]
    return [cycle[i % len(cycle)] for i in range(n)]


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
    (Path, str)

    Notes
    -----
    ``omega = sqrt(4k/m) |sin(kp d / 2)|``, ``v_p = omega / kp`` and
    ``v_g = d omega / d kp = d sqrt(k/m) cos(kp d / 2) sign(kp)`` for
    ``|kp| < 2 pi / d`` (thesis eqs. 2.49-2.54 with erratum 7), all from
    :mod:`references.dispersion`. Both velocities jump at ``kp = 0`` (where
    ``|sin|`` has its kink); the curves are drawn in two pieces there, not
    joined by a vertical line. The first Brillouin zone ``|kp| <= pi / d`` is
    shaded.
    """
    from references.dispersion import finite_chain_wavenumbers, group_velocity, omega, phase_velocity
    from rk4core.validate import positive

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

    fig = _new_figure(SIZE_TALL)
    _suptitle(fig, f"{scene_name + ': ' if scene_name else ''}dispersion of the monatomic lattice "
                   f"(m = {_fmt(m)} kg, k = {_fmt(k)} N/m, d = {_fmt(d)} m)")
    axes = fig.subplots(3, 1, sharex=True)
    curve = "#1f77b4"
    ylabels = (r"$\omega$ (rad/s)", r"$v_p = \omega/k_p$ (m/s)", r"$v_g = d\omega/dk_p$ (m/s)")
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
    axes[0].text(0.0, 0.97 * w0, r"$\omega_0 = \sqrt{4k/m}$" + f" = {w0:.4g} rad/s", ha="center", va="top",
                 fontsize=8, color="0.3")
    for ax in axes[1:]:
        ax.set_ylim(-1.25 * v0, 1.25 * v0)
    if n_fin:
        axes[0].plot(finite_chain_wavenumbers(n_fin, d), finite_omega, "o", color="k",
                     ms=4 if n_fin <= 30 else (2.5 if n_fin <= 60 else 1.8), ls="none",
                     label=f"finite chain, N = {n_fin}: eigenfrequencies at $k_n = n\\pi/((N+1)d)$")
    if len(pk):
        color, _ = solver_style(UNDER_TEST)
        axes[2].plot(pk[:, 0], pk[:, 1], "o", color=color, ms=7, mfc="none", mew=1.5, ls="none",
                     label="wave packet integrated by RK4: measured group velocity")
    axes[-1].set_xticks(np.arange(-2, 3) * kz, [r"$-2\pi/d$", r"$-\pi/d$", "0", r"$\pi/d$", r"$2\pi/d$"])
    axes[-1].set_xlim(-2 * kz, 2 * kz)
    axes[-1].set_xlabel(f"wavenumber $k_p$ (rad/m; $\\pi/d$ = {_fmt(kz)} rad/m)")
    fig.legend(loc="outside lower center", ncol=2, fontsize=7.5, frameon=False)
    stem = f"{slug(scene_name)}_dispersion" if scene_name else "dispersion"
    path = _save(fig, out_dir, stem)
    sentence = ("omega(kp), phase and group velocity of the monatomic lattice over two Brillouin zones (first "
                "shaded)" + (f"; dots: the {n_fin}-mass chain's eigenfrequencies, which should sit on the "
                             f"curve" if n_fin else "")
                + (f"; circles: group velocities measured from {len(pk)} RK4 wave packet(s), to compare "
                   f"with v_g = d omega/d kp (not omega/kp, erratum 7)" if len(pk) else "") + ".")
    return path, sentence


# -- crossover (optional) ---------------------------------------------------------
def crossover(out_dir, df) -> tuple[Path, str]:
    """Which solver is cheapest for each scene and target error, as a coloured grid.

    Parameters
    ----------
    out_dir : path-like
    df : pandas.DataFrame
        One row per (scene, target): columns ``scene``, ``target_error`` (or
        ``target``), ``solver`` (the cheapest one reaching the target; empty
        or NaN when none does) and optionally ``wall_s`` (its cost, s).

    Returns
    -------
    (Path, str)
    """
    tcol = "target_error" if "target_error" in df.columns else "target"
    _require(df, "df", ["scene", tcol, "solver"])
    scenes = list(dict.fromkeys(df["scene"]))
    targets = sorted(set(df[tcol].astype(float)), reverse=True)
    fig = _new_figure(SIZE)
    _suptitle(fig, "cheapest solver for each target error (wall time)")
    ax = fig.subplots()
    for r in df.itertuples():
        i, j = scenes.index(r.scene), targets.index(float(getattr(r, tcol)))
        solver = r.solver if isinstance(r.solver, str) and r.solver else None
        color = solver_style(solver)[0] if solver else "#ffffff"
        ax.add_patch(_rect(j, i, color, alpha=0.45 if solver else 1.0))
        txt = solver or "none"
        cost = getattr(r, "wall_s", None)
        if solver and cost is not None and np.isfinite(cost):
            txt += f"\n{cost:.2g} s"
        ax.text(j, i, txt, ha="center", va="center", fontsize=6.5 if len(scenes) > 10 else 8)
    ax.set_xlim(-0.5, len(targets) - 0.5)
    ax.set_ylim(len(scenes) - 0.5, -0.5)
    ax.set_xticks(range(len(targets)), [f"{t:.0e}" for t in targets])
    ax.set_yticks(range(len(scenes)), scenes, fontsize=7 if len(scenes) > 10 else 8)
    ax.set_xlabel("target relative error (error_max / max |y_ref|)")
    ax.tick_params(length=0)
    path = _save(fig, out_dir, "crossover")
    sentence = ("For each scene (row) and target error (column), the solver that reaches the target in the least "
                "wall time: read where RK4 stops being the cheapest choice as the target tightens.")
    return path, sentence


def _rect(x, y, color, alpha):
    from matplotlib.patches import Rectangle

    return Rectangle((x - 0.5, y - 0.5), 1.0, 1.0, facecolor=color, alpha=alpha, edgecolor="white", lw=2)
