"""The figures' style kit: sizes, fonts, solver colours, the figure canvas,
titles, legends, log axes, the final draw with its house rules, the PNG
writer and the number formats every figure's text uses.

Every figure of the report (:mod:`rk4h.validation.figures.scene`,
:mod:`rk4h.validation.figures.measurement`, :mod:`rk4h.validation.stability.plots`,
:mod:`rk4h.validation.draw`) is drawn with these functions, so one style holds
everywhere.

Conventions
-----------
* Rendering is by matplotlib's Agg canvas on :class:`matplotlib.figure.Figure`
  objects created without pyplot, so no figure is ever registered with pyplot
  (nothing to close, nothing left open, no display needed) and the caller's
  pyplot backend is left alone. The canvas's renderer (:class:`_Renderer`)
  looks each font's line metrics up once instead of once per text extent.
* Layout: a figure is laid out once by matplotlib's constrained layout
  engine just before it is drawn (:func:`lay_out`, from :func:`finish`);
  the legend sits outside the axes, below them (:func:`legend_below`,
  never over data).
* One colour and marker per solver across all figures (:data:`SOLVER_STYLE`);
  the exact/reference solution is black.
* Sizes: :data:`SIZE` (7 x 4.5 in) at :data:`DPI` (120), i.e. 840 x 540 px;
  the dispersion figure is :data:`SIZE_TALL` (7 x 6 in, 840 x 720 px); a
  figure whose key needs more than :data:`LEGEND_ROWS` rows grows by them.
* File names are lowercase with underscores and start with the scene name made
  so (:func:`slug`): ``thesis-2dof-case1`` -> ``thesis_2dof_case1_displacement.png``.
* Units are SI; small quantities get an SI prefix on the axis label (mm, mm/s,
  mrad; :func:`si`) so tick labels stay plain numbers.
* A title on every figure (:func:`suptitle`), no text under :data:`FONT_MIN`
  (8 pt), log axes by :func:`log_axes` (no minor tick labels; 1-2-5 ticks on
  short spans), and :func:`save` thins any axis whose tick labels still
  overlap after drawing.
* Tests and benchmarks set :data:`SAVE_HOOK` (and :data:`MINOR_SUBS`) on this
  module, where the functions read them.
"""
from __future__ import annotations

import contextlib
import math
import re
import textwrap
from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg, RendererAgg
from matplotlib.figure import Figure
from PIL import Image

from rk4h.references.registry import BUILTIN, resolve

__all__ = ["SIZE", "SIZE_TALL", "DPI", "FONT_MIN", "FONT_SMALL", "FONT_TITLE", "SOLVER_STYLE", "UNKNOWN_STYLE",
           "COORD_COLORS", "LINESTYLES", "GUIDE_STYLES", "LEGEND_ROWS", "slug", "scene_methods", "all_styles",
           "solver_style", "solver_of", "method_of", "order_of", "in_palette_order", "plt_colors",
           "new_figure", "suptitle", "legend_below", "log_tick_text", "log_decade_text", "log_axes",
           "tick_labels", "overlapping", "thin_ticks", "texts", "layout_on_edges_only", "lay_out",
           "finish", "save", "si", "fmt", "fmt_t", "sentence"]

SIZE = (7.0, 4.5)        # inches
SIZE_TALL = (7.0, 6.0)   # inches, the three-panel dispersion figure
DPI = 120
FONT_MIN = 8.0           # pt: no text smaller, anywhere
FONT_SMALL = 8.0         # pt: legends, panel titles, annotations
FONT_TITLE = 10.0        # pt: figure titles

#: colour and marker of each built-in method (``rk4h.references.registry``), the
#: same in every figure; a scene's own methods get theirs from the registry
#: while :func:`scene_methods` is in effect.
SOLVER_STYLE = {name: (m.style.color, m.style.marker) for name, m in BUILTIN.items()}
SOLVER_STYLE.update({"exact": ("#000000", "."), "reference": ("#000000", ".")})
#: the methods of the scene being drawn (set by :func:`scene_methods`)
_LOCAL: dict = {}
UNKNOWN_STYLE = ("#7f7f7f", "x")
# Per-coordinate colours in state plots (mass 1 red, mass 2 blue as in the thesis).
COORD_COLORS = ["#d62728", "#1f77b4", "#2ca02c", "#ff7f0e", "#9467bd",
                 "#8c564b", "#e377c2", "#7f7f7f", "#bcbd22", "#17becf"]
LINESTYLES = ["-", "--", ":", "-."]
GUIDE_STYLES = ["--", ":", "-.", (0, (5, 1, 1, 1))]

# Set by tests to inspect each figure just before it is written (drawn, layout done).
SAVE_HOOK = None


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
    ``rk4h.references.registry.Method``) besides the built-ins."""
    global _LOCAL
    saved, _LOCAL = _LOCAL, dict(local or {})
    try:
        yield
    finally:
        _LOCAL = saved


def all_styles() -> dict:
    return {**SOLVER_STYLE, **{n: (m.style.color, m.style.marker) for n, m in _LOCAL.items()}}


def solver_style(label: str):
    """``(colour, marker)`` of the solver ``label`` names (its longest known prefix)."""
    return all_styles().get(solver_of(label), UNKNOWN_STYLE)


def solver_of(label: str) -> str:
    lab = str(label).lower()
    for name in sorted(all_styles(), key=len, reverse=True):
        if lab == name or lab.startswith(name + " ") or lab.startswith(name + ","):
            return name
    return lab


def method_of(solver):
    """The registry method (``rk4h.references.registry.Method``) ``solver`` names:
    a built-in or one of the drawn scene's own; ValueError when unknown."""
    return resolve(solver, _LOCAL)


def order_of(solver):
    """Expected order of ``solver`` (built-in or the drawn scene's), None if unknown."""
    try:
        return method_of(solver).order
    except ValueError:
        return None


class _Renderer(RendererAgg):
    """Matplotlib's Agg renderer that looks each font's line metrics up once.

    Every extent of a text (``Text._get_layout``: the constrained layout
    measures each tick label about four times, the draw once more) resolves
    the font files of its properties and reads two of the font's tables
    (``OS/2`` or ``hhea``, and ``head``) to find its ascent, descent and line
    gap, unless the renderer answers ``_get_font_height_metrics``, as the
    PDF/PS renderers do. This one answers with the same numbers, computed as
    ``Text._get_layout`` computes them, once per font properties and kept
    for the renderer's life (one figure at one size, so one dpi and one set
    of rcParams). In pixels: ``(ascent, descent, line_gap)``, or Nones (the
    caller then measures the text) when the font has neither table."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self._line_metrics = {}

    def _get_font_height_metrics(self, prop):
        from matplotlib.font_manager import fontManager, get_font

        key = (tuple(prop.get_family()), prop.get_slant(), prop.get_variant(), prop.get_weight(),
               prop.get_stretch(), prop.get_size_in_points(), prop.get_file(), prop.get_math_fontfamily())
        found = self._line_metrics.get(key)
        if found is None:
            found = (None, None, None)
            try:
                font = get_font(fontManager._find_fonts_by_props(prop))
                for table_name, gap_key, ascent_key, descent_key in (
                        ("OS/2", "sTypoLineGap", "sTypoAscender", "sTypoDescender"),
                        ("hhea", "lineGap", "ascent", "descent")):
                    table = font.get_sfnt_table(table_name)
                    if table is None:
                        continue
                    # the expression of Text._get_layout, so the numbers are its numbers to the last bit
                    scale = (1 / font.get_sfnt_table("head")["unitsPerEm"] * prop.get_size_in_points()
                             * self.dpi / 72)
                    found = (table[ascent_key] * scale, -table[descent_key] * scale, table[gap_key] * scale)
                    break
            except Exception:  # noqa: BLE001 - matplotlib's internals moved: Nones, and it measures as before
                found = (None, None, None)
            self._line_metrics[key] = found
        return found


class _Canvas(FigureCanvasAgg):
    """The Agg canvas, drawing with :class:`_Renderer`."""

    def get_renderer(self):
        w, h = self.get_width_height(physical=True)
        key = w, h, self.figure.dpi
        if getattr(self, "_lastKey", None) != key:
            self.renderer = _Renderer(w, h, self.figure.dpi)
            self._lastKey = key
        return self.renderer


def new_figure(size=SIZE, **kw) -> Figure:
    fig = Figure(figsize=size, dpi=DPI, layout="constrained", **kw)
    _Canvas(fig)
    return fig


def suptitle(fig, text):
    fig.suptitle("\n".join(textwrap.wrap(str(text), 90)) or None, fontsize=FONT_TITLE)


LEGEND_ROWS = 5  # legend rows below the axes that fit a figure of its nominal height


def legend_below(fig, handles=None, labels=None, *, ncol=None, title=None, width=None):
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
    if rows > LEGEND_ROWS:  # a tall key would squeeze the axes: the figure grows by its extra rows
        w, h = fig.get_size_inches()
        fig.set_size_inches(w, h + (rows - LEGEND_ROWS) * 1.45 * FONT_SMALL / 72.0)
    return fig.legend(handles, labels, loc="outside lower center", ncol=ncol, fontsize=FONT_SMALL,
                      frameon=False, title=title, title_fontsize=FONT_SMALL if title else None)


def log_tick_text(v, _pos=None):
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


def log_decade_text(v, _pos=None):
    """``10^k`` (Unicode superscripts, ``a x 10^k`` off the decades): the
    tick labels of a log axis spanning two decades or more, as matplotlib's
    default draws them but without mathtext, whose parser was a sixth of a
    figure's draw (``python benchmarks/bench_figures.py``)."""
    if not np.isfinite(v) or v <= 0:
        return ""
    e = math.floor(math.log10(v) + 1e-9)
    m = v / 10.0 ** e
    power = "10" + str(e).translate(_SUPERSCRIPT)
    return power if abs(m - 1.0) < 1e-6 else f"{m:g}\u00d7{power}"


#: Minor ticks (unlabelled, a faint grid) of log axes at these multiples of
#: each decade; None: matplotlib's 2, 3, ..., 9. Each minor tick is a Tick
#: object that the constrained layout visits on every draw:
#: ``python benchmarks/bench_figures.py --minor-ticks`` measures what they cost.
MINOR_SUBS = (2.0, 5.0)


def log_axes(ax, x=True, y=True):
    """Log scales with the figures' grid and no minor tick labels; an axis
    spanning under two decades gets major ticks at 1, 2, 5 x 10^k
    (:func:`log_tick_text`), a wider one ``10^k`` (:func:`log_decade_text`);
    no label is mathtext. Call after the data are plotted (the span is read
    from the limits)."""
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
            axis.set_major_formatter(ticker.FuncFormatter(log_tick_text))
        else:
            axis.set_major_formatter(ticker.FuncFormatter(log_decade_text))
    ax.grid(which="major", alpha=0.3)
    ax.grid(which="minor", alpha=0.1)


def tick_labels(ax, axis, renderer):
    """Window extents of ``axis``'s visible, non-empty tick labels (major and
    minor) whose tick lies inside the axes."""
    from matplotlib import ticker

    box = ax.get_window_extent(renderer)
    lo, hi = (box.x0, box.x1) if axis is ax.xaxis else (box.y0, box.y1)
    out = []
    # unlabelled minor ticks (NullFormatter) are not asked for: each call re-locates the ticks
    unlabelled = isinstance(axis.get_minor_formatter(), ticker.NullFormatter)
    for lab in axis.get_ticklabels(minor=False) + ([] if unlabelled else axis.get_ticklabels(minor=True)):
        if not lab.get_visible() or not lab.get_text().strip():
            continue
        e = lab.get_window_extent(renderer)
        c = (e.x0 + e.x1) / 2 if axis is ax.xaxis else (e.y0 + e.y1) / 2
        if lo - 1.0 <= c <= hi + 1.0:
            out.append(e)
    return out


def overlapping(extents, pad=0.5) -> bool:
    """True when two of the boxes overlap by more than ``pad`` pixels."""
    for i, a in enumerate(extents):
        for b in extents[i + 1:]:
            if min(a.x1, b.x1) - max(a.x0, b.x0) > pad and min(a.y1, b.y1) - max(a.y0, b.y0) > pad:
                return True
    return False


def thin_ticks(ax, axis, n_labels):
    """Fewer tick labels on ``axis``: first none on minor ticks, then about
    half the major ones."""
    from matplotlib import ticker

    if not isinstance(axis.get_minor_formatter(), ticker.NullFormatter) and axis.get_ticklabels(minor=True):
        axis.set_minor_formatter(ticker.NullFormatter())
        return
    n = max(2, n_labels // 2)
    if axis.get_scale() == "log":
        axis.set_major_locator(ticker.LogLocator(base=10, numticks=n + 1))
        axis.set_major_formatter(ticker.FuncFormatter(log_tick_text))
    elif axis.get_scale() == "linear":
        axis.set_major_locator(ticker.MaxNLocator(nbins=n))


def texts(fig):
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


def layout_on_edges_only(fig):
    """Leave the axes' spines out of the constrained layout. A spine lies on
    its axes' edge and reaches out only by its tick marks (3.5 pt, inside the
    tick labels' pad); matplotlib measures it by updating its axis' ticks
    again, four spines per axes and twice per layout: half of the layout's
    tick updates, for no change of its margins (within the tick marks'
    length where a shared axis hides a panel's tick labels). Tick labels, axis labels,
    titles, legends and texts stay in the layout."""
    for ax in fig.axes:
        for spine in ax.spines.values():
            spine.set_in_layout(False)


def minor_grid_lines(fig):
    """The faint grid of the log axes' unlabelled minor ticks (``NullFormatter``,
    :func:`log_axes`) drawn as one line collection per axis at the ticks'
    final places, and those ticks removed: a minor tick is an object of five
    artists that the layout and the draw update one by one: a third to a
    half of a log-log figure's Python calls, for lines that carry no label. The grid keeps the
    minor gridlines' colour, width and alpha; the short minor tick marks on
    the frame go. Call when the limits are final (:func:`finish` does)."""
    from matplotlib import ticker
    from matplotlib.collections import LineCollection

    found = []
    for ax in fig.axes:
        for axis, to_axes in ((ax.xaxis, ax.get_xaxis_transform()), (ax.yaxis, ax.get_yaxis_transform())):
            locator = axis.get_minor_locator()
            if (axis.get_scale() != "log" or isinstance(locator, ticker.NullLocator)
                    or not isinstance(axis.get_minor_formatter(), ticker.NullFormatter)):
                continue
            lo, hi = sorted(axis.get_view_interval())
            # matplotlib leaves out minor ticks on a major one (a log axis of under
            # two decades has majors at 2 and 5 x 10^k): so does the grid
            major = np.log10(np.asarray([v for v in axis.get_majorticklocs() if v > 0], dtype=float))
            tol = 1e-5 * max(1.0, math.log10(hi / lo)) if lo > 0 else 0.0
            found.append((ax, axis, to_axes, [v for v in locator() if lo <= v <= hi and v > 0
                                              and not np.any(np.abs(major - math.log10(v)) <= tol)]))
    for ax, axis, to_axes, locs in found:  # located first: shared axes share one locator
        tick = axis.get_minor_ticks(1)[0] if locs else None  # its gridline carries ax.grid's settings
        if tick is not None and tick.gridline.get_visible():
            g = tick.gridline
            segments = [[(v, 0.0), (v, 1.0)] if axis is ax.xaxis else [(0.0, v), (1.0, v)] for v in locs]
            ax.add_collection(LineCollection(segments, transform=to_axes, colors=[g.get_color()],
                                             linewidths=g.get_linewidth(), linestyles=g.get_linestyle(),
                                             alpha=g.get_alpha(), zorder=axis.get_zorder()),
                              autolim=False)
        axis.set_minor_locator(ticker.NullLocator())


def lay_out(fig, engine):
    """Lay ``fig`` out once with ``engine`` (its constrained layout engine)
    and keep the result: the draw that follows runs no layout of its own.

    The layout leaves the spines out (:func:`layout_on_edges_only`: the same
    margins, half the tick updates); the log axes' unlabelled minor ticks are
    already gone when :func:`finish` calls it (:func:`minor_grid_lines`).
    Any other engine (or none) is left to the draw."""
    from matplotlib.layout_engine import ConstrainedLayoutEngine

    if not isinstance(engine, ConstrainedLayoutEngine):
        return
    layout_on_edges_only(fig)
    fig.set_layout_engine(engine)
    try:
        engine.execute(fig)
    finally:
        fig.set_layout_engine("none")  # the positions just computed stand for the draw


def finish(fig):
    """Draw ``fig`` (layout included, :func:`lay_out`) with the house rules
    enforced: no text under :data:`FONT_MIN`, white background, and axes
    whose tick labels overlap thinned until they do not (at most three
    redraws, each laid out again)."""
    fig.patch.set_facecolor("white")
    fig.patch.set_alpha(1.0)
    for t in texts(fig):
        if t.get_fontsize() < FONT_MIN:
            t.set_fontsize(FONT_MIN)
    minor_grid_lines(fig)
    engine = fig.get_layout_engine()
    try:
        lay_out(fig, engine)
        fig.canvas.draw()
        for _ in range(3):
            renderer = fig.canvas.get_renderer()
            crowded = []
            for ax in fig.axes:
                if not ax.get_visible():
                    continue
                for axis in (ax.xaxis, ax.yaxis):
                    ext = tick_labels(ax, axis, renderer)
                    if overlapping(ext):
                        crowded.append((ax, axis, len(ext)))
            if not crowded:
                return
            for ax, axis, n in crowded:
                thin_ticks(ax, axis, n)
            lay_out(fig, engine)
            fig.canvas.draw()
    finally:  # the figure keeps its engine: a later draw lays out what was added since
        if engine is not None:
            fig.set_layout_engine(engine)


def save(fig, out_dir, stem) -> Path:
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    path = out / f"{stem}.png"
    finish(fig)
    if SAVE_HOOK is not None:
        SAVE_HOOK(fig, path)
    # Fixed canvas (no bbox_inches), so the pixel size is size * DPI. The canvas
    # drawn by finish is stored as a 256-colour palette PNG: a third of the
    # bytes, and plots have few colours.
    w, h = fig.canvas.get_width_height()
    rgba = Image.frombuffer("RGBA", (w, h), bytes(fig.canvas.buffer_rgba()), "raw", "RGBA", 0, 1)
    # Fast octree: a quarter of median cut's bytes less, a smaller colour error and
    # a fifth of its time (with zlib level 6 instead of PNG's optimize search).
    pal = rgba.convert("RGB").quantize(colors=256, method=Image.Quantize.FASTOCTREE, dither=Image.Dither.NONE)
    pal.save(path, format="PNG", compress_level=6)
    return path


def si(values, unit):
    """``(factor, label_unit)``: the SI prefix that puts max |values| in [1, 1000)."""
    a = np.asarray(values, dtype=float)
    a = a[np.isfinite(a)]
    amax = float(np.max(np.abs(a))) if a.size else 0.0
    if not amax > 0.0:
        return 1.0, unit
    exp3 = min(0, max(-9, 3 * math.floor(math.log10(amax) / 3)))
    prefix = {0: "", -3: "m", -6: "\u00b5", -9: "n"}[exp3]
    return 10.0 ** (-exp3), prefix + unit


def fmt(x) -> str:
    return f"{x:.3g}"


def fmt_t(x) -> str:
    """A time in s: four significant digits, whole seconds from 1000 s, no exponent below 1e6."""
    return f"{x:.4g}" if abs(x) < 1000 else (f"{x:.0f}" if abs(x) < 1e6 else f"{x:.3g}")


def sentence(head, *tails):
    """``head`` with ``": tail; tail"`` for the non-empty tails, ended by a full stop."""
    tail = "; ".join(t for t in tails if t)
    return f"{head}: {tail}." if tail else f"{head}."


def in_palette_order(solvers):
    """Solvers in the order of :data:`SOLVER_STYLE` (then the scene's own
    methods, then unknown ones), so legends list them the same way in every figure."""
    known = list(all_styles())
    return sorted(solvers, key=lambda s: (known.index(s) if s in known else len(known), str(s)))


def plt_colors(n):
    """``n`` distinct colours of matplotlib's default cycle (repeated if needed)."""
    import matplotlib

    cycle = matplotlib.rcParams["axes.prop_cycle"].by_key()["color"]
    return [cycle[i % len(cycle)] for i in range(n)]
