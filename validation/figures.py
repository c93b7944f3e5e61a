"""The report's figures: plots of data the runner has already computed.

Every public function draws one kind of figure from arrays or DataFrames,
writes a PNG into ``out_dir`` and returns ``(path, sentence)``, where
``sentence`` is a :class:`Caption`: one line (a ``str``) of what is specific
to the data drawn, whose ``kind`` keys the figure kind's generic reading
guide in :data:`GENERIC_CAPTIONS` (``index.md`` prints that once per kind).
Nothing here integrates, fits or measures: the runner computes, this module
draws. The only numbers derived here are display aids (axis windows, SI
prefixes, a running maximum, slope guides) and the facts the sentences quote
from the data drawn (a path's principal axes, the initial state's modal
content, peak values, ranges).

Conventions
-----------
* Rendering is by matplotlib's Agg canvas on :class:`matplotlib.figure.Figure`
  objects created without pyplot, so no figure is ever registered with pyplot
  (nothing to close, nothing left open, no display needed) and the caller's
  pyplot backend is left alone.
* One colour and marker per solver across all figures (:data:`SOLVER_STYLE`);
  the exact/reference solution is black.
* Sizes: :data:`SIZE` (7 x 4.5 in) at :data:`DPI` (120), i.e. 840 x 540 px;
  the dispersion figure is :data:`SIZE_TALL` (7 x 6 in, 840 x 720 px); a
  figure whose key needs more than :data:`_LEGEND_ROWS` rows grows by them.
* File names are lowercase with underscores and start with the scene name made
  so (:func:`slug`): ``thesis-2dof-case1`` -> ``thesis_2dof_case1_displacement.png``.
* Units are SI; small quantities get an SI prefix on the axis label (mm, mm/s,
  mrad) so tick labels stay plain numbers.
* One style for every figure, the stability study's included
  (:mod:`validation.stability.plots` draws with these helpers): a title on
  every figure (:func:`_suptitle`), no text under :data:`FONT_MIN` (8 pt),
  legends below the axes (:func:`_legend_below`, never over data), log axes
  by :func:`_log_axes` (no minor tick labels; 1-2-5 ticks on short spans), and
  :func:`_save` thins any axis whose tick labels still overlap after drawing.
* Sentences: each function returns, beside its PNG, a :class:`Caption` (a
  ``str``) holding only what is specific to the data drawn (numbers, solvers,
  what the data shows), computed from the data; ``caption.kind`` names the
  figure kind, whose reading guide, the same for every scene, is
  ``GENERIC_CAPTIONS[caption.kind]``.

References
----------
The figures regenerate the thesis' Figs 4.1-4.20 (chapter 4 of the seed) with
the corrected physics listed in the errata (docs/scenes.md).
"""
from __future__ import annotations

import contextlib
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
           "crossover", "slug", "SOLVER_STYLE", "SIZE", "SIZE_TALL", "DPI", "FONT_MIN", "Caption",
           "GENERIC_CAPTIONS"]

SIZE = (7.0, 4.5)        # inches
SIZE_TALL = (7.0, 6.0)   # inches, the three-panel dispersion figure
DPI = 120
FONT_MIN = 8.0           # pt: no text smaller, anywhere
FONT_SMALL = 8.0         # pt: legends, panel titles, annotations
FONT_TITLE = 10.0        # pt: figure titles

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
MAX_MODAL_DOF = 500      # modal content (a dense eigenproblem) only up to this size
PX_PER_PERIOD = 8        # a space-time image needs this many pixels per period of the fastest excited mode

# Set by tests to inspect each figure just before it is written (drawn, layout done).
_SAVE_HOOK = None


class Caption(str):
    """A figure's sentence for ``index.md``: a plain ``str`` with only what is
    specific to the data drawn, plus ``kind``, the key of the figure kind's
    generic reading guide in :data:`GENERIC_CAPTIONS`."""

    def __new__(cls, text, kind):
        if kind not in GENERIC_CAPTIONS:
            raise ValueError(f"`kind` must be one of {', '.join(GENERIC_CAPTIONS)}, got {kind!r}")
        obj = super().__new__(cls, text)
        obj.kind = kind
        return obj

    def __reduce__(self):  # pickled across worker processes with its kind
        return (Caption, (str(self), self.kind))


#: One reading guide per figure kind, the same for every scene (``index.md``
#: prints it once per kind); a function's returned :class:`Caption` holds the
#: scene-specific sentence and ``caption.kind`` its key here.
GENERIC_CAPTIONS = {
    # scene trajectories (scene_figures)
    "displacement": "Displacement of each mass (or point) against time: the whole run above and, when the run is "
                    "longer than six periods of the slowest mode of the linearization, its first three periods "
                    "below; later curves are thinner and dashed so coinciding curves stay visible.",
    "velocity": "Velocity of each mass (or point) against time, laid out like the displacement figure.",
    "springs": "Elongation of each drawn spring (its length minus its natural length) against time, laid out like "
               "the displacement figure.",
    "trajectory": "Path of the point in the x-y plane on equal axes (same scale in x and y); the black dot is the "
                  "start.",
    "paths": "Displacement path of each mass about its rest position, one panel per mass, equal axes and the same "
             "scale in every panel (with more than 12 points: one panel of every point in the plane, anchors as "
             "black crosses).",
    "angles": "Angles against time, laid out like the displacement figure.",
    "coordinates": "Generalized coordinates against time, laid out like the displacement figure.",
    "space_time": "Space-time image of a long chain: mass index against time, colour = displacement (or velocity), "
                  "red positive, blue negative, colours clipped at the 99.5th percentile; a wave or packet shows as "
                  "a band whose slope is its speed in masses per second. When the whole run has too many "
                  "oscillations for the image's pixels, the signed image shows the first seconds only and a "
                  "second panel the amplitude max |value| per time bin over the whole run.",
    "work_precision": "Error against wall time (left) and against right-hand-side evaluations (right), log-log, "
                      "one line per solver: the lowest curve at a given cost is the cheapest solver for that "
                      "accuracy, and where curves cross the best choice changes. A solver whose settings all cost "
                      "about the same (within a factor 1.5) is drawn as points labelled with their setting instead "
                      "of a line. heyoka makes no RHS calls: it is placed at Taylor steps x order. The error is the largest "
                      "|y - y_ref| over output times and state components, over max |y_ref| (relative).",
    "convergence": "Error against step size h, log-log, with slope guides (error ~ h^p for each expected order p, "
                   "under the solver's points): a method parallel to its guide has that order; filled points are "
                   "the range the order was fitted over, hollow ones lie outside it (pre-asymptotic or at the "
                   "round-off floor). Error as in the work-precision figure.",
    "energy_error": "Relative energy error |E(t) - E0| / E_motion (E_motion = E0 - V at equilibrium) against "
                    "time, log-log (thick: running maximum, thin: instantaneous): a line of slope 1 is a steady "
                    "drift (RK4 loses energy at a rate set by (omega h)^6/72 per step), a flat band a bounded "
                    "error (symplectic methods).",
    "modal_energy": "Energy in each of the lowest linear modes as a fraction of the energy of the motion "
                    "(E0 - V at equilibrium), against time: "
                    "started in mode 1, an FPUT chain shares its energy with a few low modes and then returns "
                    "almost all of it to mode 1 (the recurrence); a solver that reproduces the return time and "
                    "height keeps the physics.",
    "dispersion": "omega(kp), phase velocity omega/kp and group velocity d omega/d kp of the monatomic lattice over "
                  "two Brillouin zones (the first shaded); dots: a finite chain's eigenfrequencies, which should sit "
                  "on the curve; circles: group velocities measured from RK4 wave packets, to compare with v_g "
                  "(not omega/kp, erratum 7).",
    "crossover": "For each scene (row) and target relative error (column), the solver whose measured run "
                 "reached the target with the fewest right-hand-side evaluations, a count that is the same on "
                 "every rerun (cell colour and its count, key below). RK4 is named only where a run at its "
                 "recommended step was made and met the target (a predicted step is not enough); 'tie': equal "
                 "counts; 'unmeasured': no measured run confirmed a winner. Read where RK4 stops being the "
                 "cheapest choice as the target tightens.",
    "sweep": "A measured quantity against a swept scene parameter, one line per solver and setting (or per "
             "quantity), over the points of the sweep.",
    "stability_growth": "Amplitude growth factor per step of the fastest mode against omega_max h: lines are the "
                        "methods' stability functions |R(i omega h)|, hollow markers are measured from integrated "
                        "runs; a method is stable while its growth stays <= 1 (dotted: each method's boundary).",
    "stability_drift": "Energy loss (left) and phase lag (right) per step against theta = omega h, log-log: the "
                       "exact curves from the method's stability function (solid), their leading-order terms "
                       "(dotted) and values measured from integrated runs (hollow markers).",
    "stability_long_energy": "Relative energy error over the long horizon, log-log (thick: running maximum, thin: "
                             "instantaneous): the fixed-step method dissipates steadily (slope 1) until its fast "
                             "mode is gone, the adaptive references stay near their tolerances.",
    "stability_roundoff": "Error after one slow period against the step, log-log: the truncation error falls "
                          "along the slope-p guide down to the best step (star), below which accumulated round-off "
                          "makes the error grow again.",
    "stability_cost": "Cost of reaching the target error in one slow period (RHS evaluations left, wall time "
                      "right) against the swept ratio, log-log, one curve per solver: the explicit methods' cost "
                      "grows with omega_max, BDF's stays flat when the fast mode is not excited; missing points "
                      "were skipped for cost or did not reach the target (stability.csv says which).",
    "stability_large_n": "Wall time per step (left) and peak memory (right) against the chain length N, log-log: "
                         "slopes near the dotted slope-1 line mean O(N) work and storage.",
    "stability_amplitude": "Relative error of the linearized (small-oscillation) model against the initial "
                           "amplitude, log-log, beside the slope-2 theory ((r/l)^2): read off the largest amplitude "
                           "at which the cheap model is good enough.",
}


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
    fig.suptitle("\n".join(textwrap.wrap(str(text), 90)) or None, fontsize=FONT_TITLE)


_LEGEND_ROWS = 5  # legend rows below the axes that fit a figure of its nominal height


def _legend_below(fig, handles=None, labels=None, *, ncol=None, title=None, width=None):
    """The figure's legend below its axes (``outside lower center``, so it
    never covers data), :data:`FONT_SMALL`, as many columns as fit the width."""
    if handles is None:
        handles, labels = [], []
        for ax in fig.axes:
            for h, lab in zip(*ax.get_legend_handles_labels()):
                if lab not in labels:
                    handles.append(h)
                    labels.append(lab)
    if not handles:
        return None
    if ncol is None:
        longest = max(len(str(lab)) for lab in labels)
        # ~0.62 em per character at 8 pt, plus the handle and the gap (~4 em)
        per_col = (longest * 0.62 + 4.0) * FONT_SMALL / 72.0
        avail = (width or fig.get_size_inches()[0]) - 0.3
        ncol = max(1, min(len(handles), int(avail // per_col)))
    rows = -(-len(handles) // ncol)
    if rows > _LEGEND_ROWS:  # a tall key would squeeze the axes: the figure grows by its extra rows
        w, h = fig.get_size_inches()
        fig.set_size_inches(w, h + (rows - _LEGEND_ROWS) * 1.45 * FONT_SMALL / 72.0)
    return fig.legend(handles, labels, loc="outside lower center", ncol=ncol, fontsize=FONT_SMALL,
                      frameon=False, title=title, title_fontsize=FONT_SMALL if title else None)


def _log_tick_text(v, _pos=None):
    """Plain numbers from 1e-3 to 1e6, ``a x 10^b`` outside."""
    if not np.isfinite(v) or v <= 0:
        return ""
    if 1e-3 <= v < 1e6:
        return f"{v:g}"
    e = math.floor(math.log10(v) + 1e-9)
    m = v / 10.0 ** e
    # Unicode superscripts, not mathtext: parsing ``$10^{-6}$`` was a tenth of a figure's draw
    power = "10" + str(e).translate(_SUPERSCRIPT)
    return power if abs(m - 1.0) < 1e-6 else f"{m:g}\u00d7{power}"


_SUPERSCRIPT = str.maketrans("-0123456789", "\u207b\u2070\u00b9\u00b2\u00b3\u2074\u2075\u2076\u2077\u2078\u2079")


#: Minor ticks (unlabelled, a faint grid) of log axes at these multiples of
#: each decade; None: matplotlib's 2, 3, ..., 9. Each minor tick is a Tick
#: object that the constrained layout visits on every draw:
#: ``python benchmarks/bench_figures.py`` measures what they cost.
MINOR_SUBS = (2.0, 5.0)


def _log_axes(ax, x=True, y=True):
    """Log scales with the figures' grid and no minor tick labels; an axis
    spanning under two decades gets major ticks at 1, 2, 5 x 10^k. Call after
    the data are plotted (the span is read from the limits)."""
    from matplotlib import ticker

    for on, axis, set_scale, lim in ((x, ax.xaxis, ax.set_xscale, ax.get_xlim),
                                     (y, ax.yaxis, ax.set_yscale, ax.get_ylim)):
        if not on:
            continue
        set_scale("log")
        lo, hi = sorted(lim())
        axis.set_minor_formatter(ticker.NullFormatter())
        if MINOR_SUBS is not None:
            axis.set_minor_locator(ticker.LogLocator(base=10, subs=MINOR_SUBS, numticks=100))
        if lo > 0 and math.log10(hi / lo) < 2:
            axis.set_major_locator(ticker.LogLocator(base=10, subs=(1.0, 2.0, 5.0)))
            axis.set_major_formatter(ticker.FuncFormatter(_log_tick_text))
    ax.grid(which="major", alpha=0.3)
    ax.grid(which="minor", alpha=0.1)


def _tick_labels(ax, axis, renderer):
    """Window extents of ``axis``'s visible, non-empty tick labels (major and
    minor) whose tick lies inside the axes."""
    box = ax.get_window_extent(renderer)
    lo, hi = (box.x0, box.x1) if axis is ax.xaxis else (box.y0, box.y1)
    out = []
    for lab in axis.get_ticklabels(minor=False) + axis.get_ticklabels(minor=True):
        if not lab.get_visible() or not lab.get_text().strip():
            continue
        e = lab.get_window_extent(renderer)
        c = (e.x0 + e.x1) / 2 if axis is ax.xaxis else (e.y0 + e.y1) / 2
        if lo - 1.0 <= c <= hi + 1.0:
            out.append(e)
    return out


def _overlapping(extents, pad=0.5) -> bool:
    """True when two of the boxes overlap by more than ``pad`` pixels."""
    for i, a in enumerate(extents):
        for b in extents[i + 1:]:
            if min(a.x1, b.x1) - max(a.x0, b.x0) > pad and min(a.y1, b.y1) - max(a.y0, b.y0) > pad:
                return True
    return False


def _thin_ticks(ax, axis, n_labels):
    """Fewer tick labels on ``axis``: first none on minor ticks, then about
    half the major ones."""
    from matplotlib import ticker

    if not isinstance(axis.get_minor_formatter(), ticker.NullFormatter) and axis.get_ticklabels(minor=True):
        axis.set_minor_formatter(ticker.NullFormatter())
        return
    n = max(2, n_labels // 2)
    if axis.get_scale() == "log":
        axis.set_major_locator(ticker.LogLocator(base=10, numticks=n + 1))
        axis.set_major_formatter(ticker.FuncFormatter(_log_tick_text))
    elif axis.get_scale() == "linear":
        axis.set_major_locator(ticker.MaxNLocator(nbins=n))


def _texts(fig):
    """The figure's texts but tick labels: titles, axis labels, annotations,
    legends. (``fig.findobj(Text)`` would also build every axis' ticks before
    the draw does, a third of a figure's time; tick labels take rcParams'
    sizes, which are above :data:`FONT_MIN`.)"""
    out = list(fig.texts)
    if fig._suptitle is not None:
        out.append(fig._suptitle)
    legends = list(fig.legends)
    for ax in fig.axes:
        out += [*ax.texts, ax.title, ax._left_title, ax._right_title, ax.xaxis.label, ax.yaxis.label]
        if ax.get_legend() is not None:
            legends.append(ax.get_legend())
    for leg in legends:
        out += [*leg.get_texts(), leg.get_title()]
    return out


def _finish(fig):
    """Draw ``fig`` (layout included) with the house rules enforced: no text
    under :data:`FONT_MIN`, white background, and axes whose tick labels
    overlap thinned until they do not (at most three redraws)."""
    fig.patch.set_facecolor("white")
    fig.patch.set_alpha(1.0)
    for t in _texts(fig):
        if t.get_fontsize() < FONT_MIN:
            t.set_fontsize(FONT_MIN)
    fig.canvas.draw()
    for _ in range(3):
        renderer = fig.canvas.get_renderer()
        crowded = []
        for ax in fig.axes:
            if not ax.get_visible():
                continue
            for axis in (ax.xaxis, ax.yaxis):
                ext = _tick_labels(ax, axis, renderer)
                if _overlapping(ext):
                    crowded.append((ax, axis, len(ext)))
        if not crowded:
            return
        for ax, axis, n in crowded:
            _thin_ticks(ax, axis, n)
        fig.canvas.draw()


def _save(fig, out_dir, stem) -> Path:
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    path = out / f"{stem}.png"
    _finish(fig)
    if _SAVE_HOOK is not None:
        _SAVE_HOOK(fig, path)
    # Fixed canvas (no bbox_inches), so the pixel size is size * DPI. The canvas
    # drawn by _finish is stored as a 256-colour palette PNG: a third of the
    # bytes, and plots have few colours.
    w, h = fig.canvas.get_width_height()
    rgba = Image.frombuffer("RGBA", (w, h), bytes(fig.canvas.buffer_rgba()), "raw", "RGBA", 0, 1)
    # Fast octree: a quarter of median cut's bytes less, a smaller colour error and
    # a fifth of its time (with zlib level 6 instead of PNG's optimize search).
    pal = rgba.convert("RGB").quantize(colors=256, method=Image.Quantize.FASTOCTREE, dither=Image.Dither.NONE)
    pal.save(path, format="PNG", compress_level=6)
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


def _fmt_t(x) -> str:
    """A time in s: four significant digits, whole seconds from 1000 s, no exponent below 1e6."""
    return f"{x:.4g}" if abs(x) < 1000 else (f"{x:.0f}" if abs(x) < 1e6 else f"{x:.3g}")


def _check_trajectory(model, t, y):
    t = np.asarray(t, dtype=float)
    y = np.asarray(y, dtype=float)
    if t.ndim != 1 or t.size < 2:
        raise ValueError(f"`t` must be 1-D with at least 2 times, got shape {t.shape}")
    if y.shape != (2 * model.n_dof, t.size):
        raise ValueError(f"`y` must have shape {(2 * model.n_dof, t.size)} for {model.name}, got {y.shape}")
    return t, y


def _modes_of(model):
    """``(omega, phi)`` of the model's linearization, or None when it has none
    (or is too large for a dense eigenproblem in a figure)."""
    if model.n_dof > MAX_MODAL_DOF:
        return None
    try:
        omega, phi = model.modes()
    except (NotImplementedError, ValueError, AttributeError, TypeError, np.linalg.LinAlgError):
        return None
    omega, phi = np.asarray(omega, dtype=float), np.asarray(phi, dtype=float)
    if omega.ndim != 1 or phi.shape != (model.n_dof, omega.size) or not np.isfinite(omega).all():
        return None
    return omega, phi


def _zoom_end(modes, t):
    """End of a window of ``_ZOOM_PERIODS`` periods of the slowest non-zero mode
    of the linearization, or None when that covers most of the horizon."""
    if modes is None:
        return None
    omega = modes[0][modes[0] > 0]
    if omega.size == 0:
        return None
    t_end = t[0] + _ZOOM_PERIODS * 2.0 * math.pi / float(omega.min())
    return t_end if t_end < t[0] + 0.5 * (t[-1] - t[0]) else None


def _modal_energies(model, modes, y):
    """Energy in each linear mode, shape (modes,) or (modes, m) for states
    ``y`` of shape (2n,) or (2n, m): ``E_k = (b_k^2 + omega_k^2 a_k^2) / 2``
    with ``a = phi^T M q``, ``b = phi^T M v`` (``phi`` mass-normalised)."""
    omega, phi = modes
    n = model.n_dof
    mass = np.asarray(model.mass, dtype=float)
    y = np.asarray(y, dtype=float)
    col = y.ndim == 1
    y2 = y[:, None] if col else y
    a, b = phi.T @ (mass[:, None] * y2[:n]), phi.T @ (mass[:, None] * y2[n:])
    e = 0.5 * (b ** 2 + omega[:, None] ** 2 * a ** 2)
    return e[:, 0] if col else e


def _modal_fractions(model, modes, y0):
    """Fraction of the initial state's energy in each linear mode (ascending
    frequency); None without modes."""
    if modes is None or np.asarray(model.mass).shape != (model.n_dof,) or not np.isfinite(y0).all():
        return None
    e = _modal_energies(model, modes, y0)
    total = float(e.sum())
    return e / total if np.isfinite(total) and total > 0 else None


def _share_over_run(model, modes, t, y, idx, max_points=4000):
    """``(lowest share, its time)`` of the modes ``idx`` in the linear modal
    energy along the run (finite states, at most ``max_points`` of them)."""
    step = max(1, t.size // max_points)
    ts, ys = t[::step], y[:, ::step]
    ok = np.isfinite(ys).all(axis=0)
    if not ok.any():
        return None
    e = _modal_energies(model, modes, ys[:, ok])
    tot = e.sum(axis=0)
    share = np.where(tot > 0, e[idx].sum(axis=0) / np.where(tot > 0, tot, 1.0), 1.0)
    i = int(np.argmin(share))
    return float(share[i]), float(ts[ok][i])


def _modal_text(model, modes, t, y) -> tuple[str, bool]:
    """``(text, single)``: what the modal content of the run says about the
    motion drawn -- the initial state's modes (one frequency, or which modes
    and whether they beat) and, for a one-frequency start, whether that mode
    keeps its energy over the run (a nonlinear model may share it) -- and
    whether the motion drawn is one frequency throughout. Modes of equal
    frequency count as one frequency. ``("", False)`` without modes."""
    frac = _modal_fractions(model, modes, y[:, 0])
    if frac is None:
        return "", False
    omega = modes[0]
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
        low = _share_over_run(model, modes, t, y, idx)
        if low is None or low[0] >= 0.99:
            kept = f", which keeps at least {100 * low[0]:.1f}% of the energy over the run" if low else ""
            return f"{start}{kept}: one frequency, so no beats and no exchange between modes", True
        return (f"{start}, but its share of the linear modal energy falls to {100 * low[0]:.0f}% at t = "
                f"{_fmt_t(low[1])} s: the nonlinearity passes energy to other modes"), False
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
                     f"{_fmt_t(2 * math.pi / dw)} s")
        else:
            text += "; their frequencies are too far apart to beat"
    return text, False


def _fast_omega(model, modes, y0):
    """Frequency (rad/s) below which 99% of the initial energy lies: the
    fastest mode the figure must resolve; None without modes."""
    frac = _modal_fractions(model, modes, y0)
    if frac is None:
        return None
    order = np.argsort(modes[0])
    cum = np.cumsum(frac[order])
    w = float(modes[0][order][min(int(np.searchsorted(cum, 0.99)), order.size - 1)])
    return w if w > 0 else None


def _legible_end(model, modes, t, y0):
    """End of the first part of the run that a space-time image can show
    without aliasing (at least :data:`PX_PER_PERIOD` pixels per period of the
    fastest excited mode), or None when the whole run is legible."""
    w = _fast_omega(model, modes, y0)
    if w is None:
        return None
    axes_px = 0.75 * SIZE[0] * DPI
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
    axes[0].set_title(f"whole run, 0 to {_fmt_t(t[-1])} s", fontsize=FONT_SMALL + 1, loc="left")
    if zoom_end is not None:
        axes[1].set_xlim(t[0], zoom_end)
        axes[1].set_title(f"first {_fmt_t(zoom_end - t[0])} s", fontsize=FONT_SMALL + 1, loc="left")
    axes[-1].set_xlabel("time t (s)")
    leg = _legend_below(fig)
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
    fig = _new_figure()
    _suptitle(fig, f"{title}: {what}")
    factor, u = _si(np.concatenate([x, y]), unit)
    ax = fig.subplots()
    _path_panel(ax, x, y, factor, u, "x", "y")
    ax.margins(0.04)
    ax.set_aspect("equal", adjustable="datalim")
    _legend_below(fig)
    return fig


def _space_time(title, what, t, values, unit, label, t_window=None, period=None):
    """Image of ``values`` (n_masses, m): mass index vs time, colour = value;
    with ``t_window``, that image covers ``t <= t_window`` only and a second
    panel shows the amplitude ``max |value|`` per time bin (at least two
    ``period`` s long, so the envelope does not alias) over the whole run."""
    fig = _new_figure()
    factor, u = _si(values, unit)
    n = values.shape[0]
    if t_window is None:
        _suptitle(fig, f"{title}: {what}")
        ax = fig.subplots()
        _signed_image(fig, ax, t, factor * values, label, u, n)
        ax.set_xlabel("time t (s)")
        return fig
    _suptitle(fig, f"{title}: {what}, first {_fmt_t(t_window - t[0])} s and amplitude over the whole run")
    ax_s, ax_a = fig.subplots(2, 1)
    keep = t <= t_window
    _signed_image(fig, ax_s, t[keep], factor * values[:, keep], label, u, n)
    ax_s.set_title(f"first {_fmt_t(t_window - t[0])} s: signed {label}", fontsize=FONT_SMALL + 1, loc="left")
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
    ax_a.set_title(f"whole run, 0 to {_fmt_t(t[-1])} s: amplitude max |{label}| per time bin",
                   fontsize=FONT_SMALL + 1, loc="left")
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


def _sentence(head, *tails):
    """``head`` with ``": tail; tail"`` for the non-empty tails, ended by a full stop."""
    tail = "; ".join(t for t in tails if t)
    return f"{head}: {tail}." if tail else f"{head}."


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
    factor, u = _si([best], unit)
    return f"{factor * best:.3g} {u} ({who})"


def _span_text(ctx):
    t, zoom = ctx["t"], ctx["zoom"]
    return f"0 to {_fmt_t(t[-1])} s" + (f", first {_fmt_t(zoom - t[0])} s below" if zoom else "")


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
            shown = (f"the signed image shows the first {_fmt_t(win - t[0])} s only (the fastest excited mode, "
                     f"{ctx['fast_txt']}, would alias over the whole run), the amplitude panel the whole run")
        head = f"{n}-mass chain, 0 to {_fmt_t(t[-1])} s{ref}"
        return [
            ("displacement", "space_time",
             lambda: _space_time(title, "displacement of each mass", t, q, unit, "displacement", win, period),
             _sentence(head, shown, f"largest |displacement| {_peak([('', q)], unit).split(' (')[0]}", modal,
                       ctx["caption"])),
            ("velocity", "space_time",
             lambda: _space_time(title, "velocity of each mass", t, v, f"{unit}/s", "velocity", win, period),
             _sentence(head, shown, f"largest |velocity| {_peak([('', v)], unit + '/s').split(' (')[0]}")),
        ]
    labels, vlabels = _chain_labels(ctx["mass"])
    head = f"{_count(n, 'mass').capitalize()}, {_span_text(ctx)}{ref}"
    return [
        ("displacement", "displacement",
         lambda: _time_series(title, "displacement of each mass", t, list(zip(labels, q)), unit, ctx["zoom"],
                              "displacement"),
         _sentence(head, *_hint(ctx, modal, single))),
        ("velocity", "velocity",
         lambda: _time_series(title, "velocity of each mass", t, list(zip(vlabels, v)), f"{unit}/s", ctx["zoom"],
                              "velocity"),
         _sentence(head, f"largest speed {_peak(list(zip(vlabels, v)), unit + '/s')}")),
    ]


def _trajectory_text(x, y, unit, caption):
    """What the path drawn is, from its principal axes: a straight segment
    (ratio under 0.01; the drawing's caption, which may promise a curve, is
    then left out) or a curve filling a region."""
    shape = _path_shape(np.asarray(x, float), np.asarray(y, float))
    if shape is None:
        return "no finite path to draw"
    ratio, major, minor, angle = shape
    factor, u = _si([major], unit)
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
                 _sentence(head, f"largest distance from the start {_peak(moves, d.unit)}", cap))]
    (ix, iy), (rx, ry) = d.points[0], d.reference[0]
    who = labels[0]
    at_origin = rx == 0.0 and ry == 0.0
    pos = "position" if at_origin else "displacement"
    span = _span_text(ctx)
    specs = [
        ("displacement", "displacement",
         lambda: _time_series(title, f"{pos} of the {who}", t, [("x", q[ix]), ("y", q[iy])], unit, zoom, pos),
         _sentence(f"{pos.capitalize()} x, y of the {who}{'' if at_origin else ' from its rest position'}, "
                   f"{span}{ref}", f"largest |{pos}| {_peak([('x', q[ix]), ('y', q[iy])], unit)}")),
        ("velocity", "velocity",
         lambda: _time_series(title, f"velocity of the {who}", t, [("vx", v[ix]), ("vy", v[iy])],
                              f"{unit}/s", zoom, "velocity"),
         _sentence(f"Velocity of the {who}, {span}{ref}",
                   f"largest speed component {_peak([('vx', v[ix]), ('vy', v[iy])], unit + '/s')}")),
    ]
    if d.springs:
        note = d.extra.get("rest_note")
        anchored = sum(1 for a, b, _ in d.springs if max(int(a), int(b)) >= len(d.points))
        specs.append(
            ("springs", "springs",
             lambda: _time_series(title, "spring elongations (length - natural length)", t,
                                  _spring_elongations(d, q), unit, zoom, "elongation"),
             _sentence(f"{_count(len(d.springs), 'spring').capitalize()}"
                       f"{f' ({anchored} of them anchored)' if anchored else ''}, {span}{ref}",
                       note, f"largest |elongation| {_peak(_spring_elongations(d, q), unit)}")))
    specs.append(
        ("trajectory", "trajectory",
         lambda: _xy_path(title, q[ix], q[iy], unit, what=d.extra.get("path_title", "trajectory in the x-y plane")),
         _sentence(f"Path of the {who}{ref}", _trajectory_text(q[ix], q[iy], unit, cap))))
    return specs


def _series_specs(ctx, stem, what, ylabel):
    d, n, title, t, q, zoom, ref = (ctx[k] for k in ("drawing", "n", "title", "t", "q", "zoom", "ref"))
    modal, single = ctx["modal"]
    names = list(d.point_labels) if len(d.point_labels) == n else list(ctx["coord_names"])
    head = (f"Angles {', '.join(names)}, {_span_text(ctx)}{ref}" if stem == "angles" else
            f"Coordinates of {ctx['name']}, {_span_text(ctx)}{ref}")
    return [(stem, stem, lambda: _time_series(title, what, t, list(zip(names, q)), d.unit, zoom, ylabel),
             _sentence(head, *_hint(ctx, modal, single)))]


def _scene_specs(scene_name, model, t, y, title, thesis=None):
    """``[(stem_suffix, kind, builder, sentence)]`` chosen from
    ``model.drawing()`` (never from the model's name); builders are
    zero-argument callables returning a Figure (built one at a time)."""
    d = model.drawing()
    _check_drawing(model, d)
    n = model.n_dof
    modes = _modes_of(model)
    long_line = d.layout == "line" and n > LONG_CHAIN
    zoom = None if long_line else _zoom_end(modes, t)
    thesis = thesis or d.extra.get("thesis")
    ctx = {"drawing": d, "title": title, "t": t, "q": y[:n], "v": y[n:], "n": n, "zoom": zoom,
           "ref": f" ({thesis})" if thesis else "", "caption": d.caption.strip().rstrip("."),
           "unit": d.unit, "mass": np.asarray(model.mass, dtype=float), "name": model.name,
           "coord_names": list(getattr(model, "coord_names", None) or [f"q{i + 1}" for i in range(n)]),
           "modal": _modal_text(model, modes, t, y)}
    if long_line:
        ctx["window"] = _legible_end(model, modes, t, y[:, 0])
        w = _fast_omega(model, modes, y[:, 0])
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
    fig = _new_figure()
    if n > MAX_PATH_PANELS:
        _suptitle(fig, f"{title}: paths of the {n} points in the plane")
        nodes = _node_positions(d, q)
        factor, u = _si(np.concatenate([np.ravel(c) for xy in nodes for c in xy]), d.unit)
        ax = fig.subplots()
        for i, (x, y) in enumerate(nodes[:n]):
            _path_panel(ax, x, y, factor, u, "x", "y", color=_COORD_COLORS[i % len(_COORD_COLORS)])
        for ax_, ay_ in d.anchors:
            ax.plot(factor * ax_, factor * ay_, "x", color="k", ms=6)
        ax.margins(0.04)
        ax.set_aspect("equal", adjustable="datalim")
        _legend_below(fig)
        return fig
    _suptitle(fig, f"{title}: displacement paths of the {_count(n, 'mass')}")
    factor, u = _si(np.concatenate([q[[ix, iy]] for ix, iy in d.points]), d.unit)
    boxes = []
    for ix, iy in d.points:
        x, y = factor * q[ix], factor * q[iy]
        ok = np.isfinite(x) & np.isfinite(y)
        boxes.append((float(x[ok].min()), float(x[ok].max()), float(y[ok].min()), float(y[ok].max()))
                     if ok.any() else (-1.0, 1.0, -1.0, 1.0))
    wy = max(max(b[3] - b[2] for b in boxes), 1e-300)
    wx = [max(b[1] - b[0], 0.3 * wy, 1e-300) for b in boxes]
    titles = [f"{labels[i]}, rest at ({_fmt(rx)}, {_fmt(ry)}) {d.unit}" for i, (rx, ry) in enumerate(d.reference)]
    if n <= 4:  # one row, each panel as wide as its path needs on the common scale
        rows, cols = 1, n
        avail = SIZE[0] - 0.8 - 0.45 * n  # inches for the panels (labels, ticks and gaps off)
        for _ in range(3):  # ... and never narrower than its title
            per_unit = avail / sum(wx)
            wx = [max(w, (0.56 * len(tt) * FONT_SMALL / 72.0) / per_unit) for w, tt in zip(wx, titles)]
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
                    color=_COORD_COLORS[i % len(_COORD_COLORS)])
        ax.set_title(titles[i], fontsize=FONT_SMALL)
        if i % cols:
            ax.set_ylabel("")
    _legend_below(fig)
    axes = axes[:n]
    centres = [((b[0] + b[1]) / 2, (b[2] + b[3]) / 2) for b in boxes]
    for ax, (cx, cy), w in zip(axes, centres, wx):  # provisional limits, for the layout
        ax.set_xlim(cx - w * (0.5 + margin), cx + w * (0.5 + margin))
        ax.set_ylim(cy - wy * (0.5 + margin), cy + wy * (0.5 + margin))
    fig.canvas.draw()  # lays the panels out; their sizes set the common scale
    fw, fh = fig.get_size_inches()
    size = [(ax.get_position().width * fw, ax.get_position().height * fh) for ax in axes]
    scale = max(max(w * (1 + 2 * margin) / sw, wy * (1 + 2 * margin) / sh) for w, (sw, sh) in zip(wx, size))
    for ax, (cx, cy), (sw, sh) in zip(axes, centres, size):
        ax.set_xlim(cx - scale * sw / 2, cx + scale * sw / 2)
        ax.set_ylim(cy - scale * sh / 2, cy + scale * sh / 2)
        ax.set_aspect("equal", adjustable="box")
    return fig


def scene_figures(out_dir, scene_name, model, t, y, *, title, thesis=None) -> list[tuple[Path, str]]:
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
        more than half the run).
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
    if getattr(model, "first_order", False):  # any ODE: its variables against time, no drawing
        return _first_order_state(out_dir, scene_name, model, t, y, title)
    t, y = _check_trajectory(model, t, y)
    stem = slug(scene_name)
    out = []
    for suffix, kind, build, sentence in _scene_specs(scene_name, model, t, y, title, thesis):
        fig = build()
        out.append((_save(fig, out_dir, f"{stem}_{suffix}"), Caption(sentence, kind)))
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
    head = f"Variables of the ODE ({', '.join(names[:6])}{', ...' if n > 6 else ''}), 0 to {_fmt_t(t[-1])} s"
    fig = _new_figure()
    _suptitle(fig, f"{title}: variables")
    ax = fig.subplots()
    for j, (label, v) in enumerate(series):
        lw = 1.0 * (1.0 - 0.5 * j / max(1, n - 1))  # later curves thinner: coinciding curves stay visible
        ax.plot(t, v, color=_COORD_COLORS[j % len(_COORD_COLORS)], lw=lw, label=label)
    ax.set_xlim(t[0], t[-1])
    ax.set_ylabel("value (the equations' units)")
    ax.set_xlabel("time t (s)")
    ax.grid(alpha=0.3)
    _legend_below(fig)
    sentence = _sentence(head, f"largest |value| {_peak(series, '')}")
    return [(_save(fig, out_dir, f"{slug(scene_name)}_variables"), Caption(sentence, "coordinates"))]


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
        return resolve(solver, _LOCAL).setting_name
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
                    ha="left", fontsize=FONT_SMALL, color=color)
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
    fig = _new_figure()
    _suptitle(fig, f"{scene_name}: work-precision (lower left is better)")
    ax_t, ax_n = fig.subplots(1, 2, sharey=True)
    notes, as_points = [], []
    for solver in _in_palette_order(d["solver"].unique()):
        rows = d[d["solver"] == solver].sort_values("setting", ascending=False)
        color, marker = solver_style(solver)
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
                    as_points.append(f"{solver} ({x.size} settings, {name} {_fmt(s.max())} to {_fmt(s.min())}, "
                                     f"all at {_fmt(x.min())}-{_fmt(x.max())} "
                                     f"{'s' if ax is ax_t else ('steps x order' if 'Taylor' in label else 'RHS calls')})")
    for ax, xl in ((ax_t, "wall time (s)"), (ax_n, "right-hand-side evaluations nfev")):
        _log_axes(ax)
        ax.set_xlabel(xl)
    ax_t.set_ylabel(ERROR_LABELS[ycol])
    if len(d):
        _legend_below(fig)
    path = _save(fig, out_dir, f"{slug(scene_name)}_work_precision")
    parts = []
    if len(d):
        e = d[ycol].to_numpy(float)
        parts.append(f"{d['solver'].nunique()} solvers, {len(d)} runs; {'relative ' if ycol == 'error_rel' else ''}"
                     f"errors {e.min():.2g} to {e.max():.2g}, wall times {_fmt(d['wall_s'].min())} to "
                     f"{_fmt(d['wall_s'].max())} s")
    if as_points:
        parts.append("drawn as points, settings labelled: " + ", ".join(as_points))
    dropped = len(df) - len(d)
    if dropped:
        parts.append(f"{dropped} failed or error-free run(s) not drawn")
    if notes:
        parts.append(f"{', '.join(notes)} in the wall-time panel only (no RHS count)")
    sentence = _sentence(f"{scene_name}", *parts) if parts else f"{scene_name}: no run to draw."
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
    fig = _new_figure()
    _suptitle(fig, f"{scene_name}: convergence of the error with the step size")
    ax = fig.subplots()
    fit_of = {r.solver: r for r in fits.itertuples()}
    orders, hollow = [], 0
    for solver in _in_palette_order(p["solver"].unique()):
        rows = p[p["solver"] == solver].sort_values("h")
        h, e = rows["h"].to_numpy(float), rows[ycol].to_numpy(float)
        color, marker = solver_style(solver)
        f = fit_of.get(solver)
        if f is not None and np.isfinite(f.observed_order):
            inside = (h >= f.h_min * (1 - 1e-9)) & (h <= f.h_max * (1 + 1e-9))
            label = f"{solver}: order {f.observed_order:.2f} (fit h {_fmt(f.h_min)}-{_fmt(f.h_max)} s)"
            orders.append(f"{solver} {f.observed_order:.2f} (fit h {_fmt(f.h_min)}-{_fmt(f.h_max)} s)")
        else:
            inside = np.ones_like(h, dtype=bool)
            label = f"{solver} (no fit)"
            orders.append(f"{solver} not fitted")
        hollow += int((~inside).sum())
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
        _guide(ax, slope, float(anchor["h"]), float(anchor[ycol]) / 3.0, h_range, style,
               f"slope {slope} guide (error ~ h^{slope})")
    _log_axes(ax)
    ax.set_xlabel("step size h (s)")
    ax.set_ylabel(ERROR_LABELS[ycol])
    _legend_below(fig)
    path = _save(fig, out_dir, f"{slug(scene_name)}_convergence")
    guides = ", ".join(f"slope {o} under {'/'.join(m)}" for o, m in sorted(by_order.items(), reverse=True))
    sentence = _sentence(f"{scene_name}", "observed orders " + ", ".join(orders) if orders else "no point to draw",
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
    fig = _new_figure()
    _suptitle(fig, title or f"{scene_name}: relative energy error")
    ax = fig.subplots()
    seen: dict[str, int] = {}
    floor = np.inf
    final = []  # (last finite running maximum, its time, label)
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
            last = np.flatnonzero(np.isfinite(env) & show)[-1]
            final.append((float(env[last]), float(t[last]), str(label)))
    ax.set_xscale("log")
    ax.set_yscale("log")
    if np.isfinite(floor):
        # The instantaneous error dips to zero twice a period; do not let those
        # dips stretch the axis below the smallest envelope value.
        ax.set_ylim(bottom=max(floor / 10.0, 1e-18))
    _log_axes(ax)
    ax.set_xlabel("time t (s)")
    ax.set_ylabel("|E(t) - E0| / E_motion (relative)")
    if series:
        _legend_below(fig, title="thick: running maximum, thin: instantaneous value")
    path = _save(fig, out_dir, stem or f"{slug(scene_name)}_energy_error")
    if sentence is None:
        if final:
            lo, hi = min(final), max(final)
            sentence = (f"{scene_name}: at the end of the run the running maximum ranges from {lo[0]:.2g} "
                        f"({lo[2]}, t = {_fmt(lo[1])} s) to {hi[0]:.2g} ({hi[2]}, t = {_fmt(hi[1])} s).")
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
    fig = _new_figure()
    _suptitle(fig, f"{scene_name}: energy in the lowest modes" + (" (FPUT recurrence)" if recurrence else ""))
    ax = fig.subplots()
    colors = plt_colors(len(omega))
    facts = []
    for s_i, (label, frac) in enumerate(series.items()):
        frac = np.asarray(frac, dtype=float)
        if frac.shape != (len(omega), t.size):
            raise ValueError(f"`series[{label!r}]` must have shape ({len(omega)}, {t.size}), got {frac.shape}")
        for j in range(frac.shape[0]):
            ax.plot(t, frac[j], color=colors[j], lw=1.4 if s_i == 0 else 1.0,
                    ls=_LINESTYLES[s_i % len(_LINESTYLES)],
                    label=f"mode {j + 1} ({omega[j]:.3g} rad/s), {label}")
        f1 = np.where(np.isfinite(frac[0]), frac[0], np.nan) if frac.shape[0] else np.array([np.nan])
        if np.isfinite(f1).any() and not recurrence:
            facts.append(f"{label}: mode 1's share stays between {100 * np.nanmin(f1):.1f}% and "
                         f"{100 * np.nanmax(f1):.1f}%")
        elif np.isfinite(f1).any():
            i = int(np.nanargmin(f1))
            back = f1[i:]
            k = i + int(np.nanargmax(back)) if np.isfinite(back).any() else i
            facts.append(f"{label}: mode 1 falls to {100 * f1[i]:.0f}% at t = {_fmt_t(t[i])} s"
                         + (f" and returns to {100 * f1[k]:.0f}% at t = {_fmt_t(t[k])} s" if k > i else
                            " (no return within the run)"))
    ax.set_xlabel("time t (s)")
    ax.set_ylabel("E_k(t) / E_motion")
    ax.set_ylim(bottom=0.0)
    ax.grid(alpha=0.3)
    _legend_below(fig)
    path = _save(fig, out_dir, f"{slug(scene_name)}_modal_energy")
    return path, Caption(_sentence(f"{scene_name}", *facts), "modal_energy")


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
    (Path, Caption)
        ``kind`` ``"dispersion"``; the sentence gives the lattice's constants and
        each packet's measured group velocity against v_g.

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
    _legend_below(fig)
    stem = f"{slug(scene_name)}_dispersion" if scene_name else "dispersion"
    path = _save(fig, out_dir, stem)
    facts = [f"m = {_fmt(m)} kg, k = {_fmt(k)} N/m, d = {_fmt(d)} m, omega_0 = {w0:.4g} rad/s"]
    if n_fin:
        facts.append(f"dots: the {n_fin}-mass chain's eigenfrequencies")
    for kp0, v in pk:
        vg = float(group_velocity(np.array([kp0]), m, k, d)[0])
        facts.append(f"packet at kp0 = {kp0 / kz:.3g} pi/d: measured {v:.5g} m/s against v_g = {vg:.5g} m/s "
                     f"({100 * (v - vg) / vg:+.2f}%)" if vg else f"packet at kp0 = {kp0 / kz:.3g} pi/d: "
                     f"measured {v:.5g} m/s")
    return path, Caption(_sentence(f"{scene_name or 'Monatomic lattice'}", *facts), "dispersion")


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
    height = max(SIZE[1], 1.9 + _ROW_IN * len(scenes))
    fig = _new_figure((SIZE[0], height))
    by_rhs = "rhs" in df.columns or "wall_s" not in df.columns
    _suptitle(fig, "cheapest solver for each target error " + ("(fewest RHS calls)" if by_rhs else "(wall time)"))
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
        color = solver_style(solver)[0] if solver else "#ffffff"
        ax.add_patch(_rect(j, i, color, alpha=0.45 if solver else 1.0))
        txt = solver or blank
        cost = getattr(r, "rhs" if by_rhs else "wall_s", None)
        if solver and cost is not None and np.isfinite(cost):
            txt += f"\n{cost:.2g} RHS" if by_rhs else f"\n{cost:.2g} s"
        ax.text(j, i, txt, ha="center", va="center", fontsize=FONT_SMALL, linespacing=1.0)
    ax.set_xlim(-0.5, len(targets) - 0.5)
    ax.set_ylim(len(scenes) - 0.5, -0.5)
    ax.set_xticks(range(len(targets)), [f"{t:.0e}" for t in targets])
    ax.set_yticks(range(len(scenes)), scenes, fontsize=FONT_SMALL)
    ax.set_xlabel("target relative error (error_max / max |y_ref|)")
    ax.tick_params(length=0)
    solvers = _in_palette_order([s for s in counts if s])
    handles = [Patch(facecolor=solver_style(s)[0], alpha=0.45, edgecolor="0.6", label=s) for s in solvers]
    for key in ("none", *CROSSOVER_EMPTY):
        if key in empty:
            handles.append(Patch(facecolor="#ffffff", edgecolor="0.6",
                                 label=CROSSOVER_NONE if key == "none" else CROSSOVER_EMPTY[key]))
    _legend_below(fig, handles, [h.get_label() for h in handles], title="cell colour: the cheapest solver")
    path = _save(fig, out_dir, "crossover")
    tally = ", ".join([f"{s} {counts[s]}" for s in solvers]
                      + [f"{k} {empty[k]}" for k in ("none", *CROSSOVER_EMPTY) if k in empty])
    sentence = (f"{len(scenes)} scenes x {len(targets)} targets ({_fmt(targets[0])} to {_fmt(targets[-1])}); "
                f"cells per cheapest solver: {tally}." if targets else "No scene or target to draw.")
    return path, Caption(sentence, "crossover")


def _rect(x, y, color, alpha):
    from matplotlib.patches import Rectangle

    return Rectangle((x - 0.5, y - 0.5), 1.0, 1.0, facecolor=color, alpha=alpha, edgecolor="white", lw=2)
