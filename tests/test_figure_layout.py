"""Layout of every figure kind the report draws (issue 14, "Figures fixed").

Each kind is built once from small synthetic data shaped like the shipped
scenes' (or a short exact / RK4 trajectory), rendered by the figure code
itself (Agg, through ``figures.save``) and inspected with matplotlib's
bounding boxes:

* ``legend``: no legend box contains a drawn data point (the vertices of the
  axes' lines -- slope guides and reference lines included, no exemption --,
  scatter offsets, the centres of patches such as the crossover's cells, and
  the anchors of text in the axes such as setting labels) inside the axes;
* ``ticks``: the tick labels (major and minor) of each axis do not overlap;
* ``title``: the figure has a title;
* ``fonts``: no visible text is smaller than 8 pt;
* ``inside``: no visible text runs off the canvas (a clipped axis label).

The cases are parametrized over (figure kind, check), so a failure names
both. Content tests below check that sentences are computed from the data
(a straight path is called a line, a single-mode start is not promised
beats), the generic captions, and the other defects of the issue (heyoka's
points, the folded mass-ratio sweep, panels that fit their paths, a legible
long-chain image, the crossover's key).
"""
import math

import numpy as np
import pandas as pd
import pytest
from matplotlib.collections import Collection
from matplotlib.patches import Rectangle
from matplotlib.text import Text

import rk4h
import rk4h.validation.stability as S
from rk4h.references.exact import modal_solution
from rk4h.validation import draw as D
from rk4h.validation import figures
from rk4h.validation.execute import modal_content
from rk4h.validation.outputs import energy_work_precision as EWP

MIN_PT = 8.0


# -- synthetic inputs shaped like the shipped scenes' -------------------------------------------------
def _wp_rows():
    """oscillator-iso-delta0 (reports/): RK4's nfev spans under two decades
    (minor tick labels collided), heyoka's rtol settings all cost the same."""
    rows = []
    for h, n, e, w in ((0.1, 4e3, 1.0, 1.6e-4), (0.05, 8e3, 0.5, 2e-4), (0.02, 2e4, 1.4e-2, 2.8e-4),
                       (0.01, 4e4, 8e-4, 4e-4), (0.005, 8e4, 5e-5, 6e-4)):
        rows.append(dict(solver="rk4", setting=h, nfev=n, error_max=e, wall_s=w, n_steps=n / 4, taylor_order=0))
    for r, n, e, w in ((1e-4, 7.6e3, 1.6e-2, 0.09), (1e-7, 1.7e4, 1.6e-5, 0.2), (1e-10, 3.6e4, 1.6e-8, 0.37),
                       (1e-12, 6.3e4, 1.7e-10, 0.85)):
        rows.append(dict(solver="dop853", setting=r, nfev=n, error_max=e, wall_s=w, n_steps=n / 12, taylor_order=0))
    for r, e, w in ((1e-4, 1.8e-4, 7e-4), (1e-7, 4e-8, 6e-4), (1e-10, 8e-11, 5.8e-4), (1e-12, 1.4e-12, 5.9e-4)):
        rows.append(dict(solver="heyoka", setting=r, nfev=0, error_max=e, wall_s=w, n_steps=650, taylor_order=30))
    df = pd.DataFrame(rows)
    df["error_rel"] = df["error_max"]  # amplitude 1 m
    df["status"] = "ok"
    return df


def _ewp_rows():
    """energy-henon-heiles (measured 2026-11-26): two horizons, a fixed-step
    method, a symplectic one and heyoka at its tolerances."""
    rows = []
    for per, scale in ((1e2, 1.0), (1e4, 100.0)):
        for solver, sym, pts in (("rk4", False, ((3200, 0.95, 0.66), (6400, 0.156, 0.97), (12800, 5.7e-3, 0.99))),
                                 ("stormer-verlet", True, ((801, 0.22, 0.04), (1601, 0.045, 0.0),
                                                           (3201, 0.011, 0.0))),
                                 ("heyoka", False, ((18376, 5.5e-7, 0.72), (28200, 5.2e-13, 0.82)))):
            for n, e, k in pts:
                rows.append(dict(scene="energy-henon-heiles", solver=solver, symplectic=sym, periods=per,
                                 t_end=per * 2 * math.pi, h=math.nan, rtol=math.nan,
                                 energy_drift_max=min(1.0, e * (scale if not sym else 1.0)),
                                 energy_growth_exponent=k, nfev=int(n * scale), wall_s=1e-7 * n * scale,
                                 status="ok"))
    return rows


def _conv_inputs():
    """thesis-2dof-case1 (reports/): RK4's smallest-h points lie in the lower
    right, where a legend in the axes used to sit."""
    h4 = np.array([0.0121, 0.00606, 0.00303, 0.00151])
    h1 = np.array([6.14e-4, 3.07e-4, 1.53e-4, 7.67e-5])
    points = pd.concat([pd.DataFrame({"solver": "rk4", "h": h4, "error_max": 4.2e-8 * (h4 / h4[0]) ** 4}),
                        pd.DataFrame({"solver": "euler", "h": h1, "error_max": 1.5e-4 * h1 / h1[0]}),
                        pd.DataFrame({"solver": "symplectic-euler", "h": h1, "error_max": 1.1e-5 * h1 / h1[0]})])
    fits = pd.DataFrame({"solver": ["rk4", "euler", "symplectic-euler"], "observed_order": [3.99, 1.0, 1.0],
                         "h_min": [0.00151, 7.67e-5, 7.67e-5], "h_max": [0.0121, 6.14e-4, 6.14e-4]})
    return points, fits


def _conv_methods(out):
    """methods-2dof (the quick report): the scene's own methods (rk38, heun3,
    ralston2, hand-rk4) beside built-ins, four expected orders (4, 3, 2, 1),
    so four slope guides, drawn in the scene's registry styles."""
    from rk4h.validation.scenes import load_scene, resolve_scene

    reg = load_scene(resolve_scene("methods-2dof")).registry
    h4, h1 = np.array([0.0121, 0.00606, 0.00303, 0.00151]), np.array([6.14e-4, 3.07e-4, 1.53e-4, 7.67e-5])
    rows = [("rk4", h4, 1.2e-6, 4), ("rk38", h4, 1.1e-6, 4), ("hand-rk4", h4, 1.2e-6, 4), ("heun3", h4, 5e-5, 3),
            ("ralston2", h1, 3e-6, 2), ("stormer-verlet", h1, 2e-6, 2), ("euler", h1, 1.6e-3, 1)]
    points = pd.concat([pd.DataFrame({"solver": n, "h": h, "error_max": e * (h / h[0]) ** p}) for n, h, e, p in rows])
    fits = pd.DataFrame({"solver": [r[0] for r in rows], "observed_order": [float(r[3]) for r in rows],
                         "h_min": [r[1].min() for r in rows], "h_max": [r[1].max() for r in rows]})
    with figures.scene_methods(reg):
        return [figures.convergence(out, "methods-2dof", points, fits)]


def _R(theta):
    z = 1j * theta
    return 1 + z + z ** 2 / 2 + z ** 3 / 6 + z ** 4 / 24


def _stability_plots():
    line = np.linspace(0.0, 3.36, 300)
    th = np.array([0.25, 0.5, 1.0, 1.5, 1.9, 2.2, 2.6, 2.9, 3.2])

    def sympl(x):
        x = np.asarray(x, float)
        big = np.maximum(x ** 2 - 4, 0)
        return np.where(x <= 2, 1.0, np.abs((2 - x ** 2 - x * np.sqrt(big)) / 2))

    theory = {"rk4": np.abs(_R(line)), "symplectic-euler": sympl(line), "euler": np.sqrt(1 + line ** 2)}
    meas = {"rk4": np.abs(_R(th)), "symplectic-euler": sympl(th), "euler": np.sqrt(1 + th ** 2)}
    tl = np.geomspace(0.02, 0.6, 200)
    td = np.array([0.05, 0.1, 0.2, 0.3, 0.4, 0.5])
    loss, lag = (lambda x: 1 - np.abs(_R(x)) ** 2), (lambda x: x - np.angle(_R(x)))
    t_long = np.geomspace(0.1, 900.0, 400)
    h = 0.0304 / 2.0 ** np.arange(10)
    err = 2.1e-5 * (h / h[0]) ** 4 + 1e-18 / h
    n = np.array([3e3, 1e4, 3e4])
    a = np.geomspace(1e-6, 3.0, 14)
    base = {"scene": "stability_2dof"}
    return {
        "growth": {**base, "kind": "growth", "study": "boundary", "name": "growth", "data": {
            "theta_line": line, "theory": theory, "theta": th, "measured": meas,
            "boundary": {"rk4": 2.8284, "symplectic-euler": 2.0}}},
        "drift": {**base, "kind": "drift", "study": "long_horizon", "name": "drift", "data": {
            "method": "rk4", "theta_line": tl, "loss_theory": loss(tl), "lag_theory": lag(tl),
            "loss_leading": (1 / 72, 6), "lag_leading": (1 / 120, 5), "theta": td,
            "energy_loss": loss(td), "phase_lag": lag(td)}},
        "long_energy": {**base, "kind": "long_energy", "study": "long_horizon", "name": "long_energy", "data": {
            "series": {"rk4 (omega_max h = 0.2, 1000 periods)": {"t": t_long, "err": 5e-7 * t_long},
                       "heyoka (rtol 1e-12, 1000 periods)": {"t": t_long, "err": 1e-14 * (1 + t_long / 10)},
                       "cvode-bdf (rtol 1e-8, 100 periods)": {"t": t_long[:300], "err": 3e-9 * t_long[:300]}}}},
        "roundoff": {**base, "kind": "roundoff", "study": "roundoff", "name": "roundoff", "data": {
            "h": h, "error": err, "h_best": float(h[np.argmin(err)]), "omega_max": 16.3, "method": "rk4",
            "order": 4}},
        "cost_mu": {**base, "kind": "cost", "study": "mass_ratio", "name": "cost_mu", "data": {
            "what": "mu", "xlabel": "mass ratio mu = m2/m1", "x": np.array([1e-4, 1e-2, 1.0, 1e2, 1e4]),
            "stiffness_ratio": np.array([115.5, 11.6, 1.73, 11.6, 115.5]), "target_error": 1e-6,
            "nfev": {"rk4": np.array([1.3e5, 6.6e3, 256, 6.6e3, 1.3e5]),
                     "dop853": np.array([1.2e4, 941, 116, 941, 1.2e4]),
                     "cvode-bdf": np.array([3.2e4, 3.3e3, 230, 3.3e3, 3.2e4]),
                     "heyoka": np.array([1.3e4, 1.3e3, 120, 1.3e3, 1.3e4])},
            "wall_s": {"rk4": np.array([1.3e-3, 2e-4, 1e-4, 2e-4, 1.3e-3]),
                       "dop853": np.array([0.2, 0.04, 1.2e-3, 0.04, 0.2]),
                       "cvode-bdf": np.array([0.3, 0.1, 8e-3, 0.1, 0.3]),
                       "heyoka": np.array([6e-4, 2.4e-4, 1.4e-4, 2.4e-4, 6e-4])}}},
        "cost_ratio": {"scene": "stability_stiff_chain", "kind": "cost", "study": "stiffness", "name": "cost_ratio",
                       "data": {"what": "ratio", "xlabel": "spring ratio k_mid/k", "x": np.array([1.0, 1e4, 1e8]),
                                "stiffness_ratio": np.array([5.67, 400.0, 4.07e4]), "target_error": 1e-6,
                                "nfev": {"rk4": np.array([300.0, 3.6e3, 3.65e5]), "dop853": np.array([200, 900, 5.3e3]),
                                         "cvode-bdf": np.array([150.0, 200.0, 219.0]),
                                         "heyoka": np.array([130.0, np.nan, 4.8e5])},
                                "wall_s": {"rk4": np.array([1e-4, 3e-4, 2e-2]), "dop853": np.array([2e-3, 6e-3, 4e-2]),
                                           "cvode-bdf": np.array([5e-3, 6e-3, 7e-3]),
                                           "heyoka": np.array([2e-4, np.nan, 3e-2])}}},
        "large_n": {"scene": "stability_large_n", "kind": "large_n", "study": "large_n", "name": "large_n", "data": {
            "n": n, "method": "rk4", "wall_per_step": 6e-9 * n, "peak_bytes": 180.0 * n,
            "cvode_wall_per_step": 2e-7 * n, "fits": {"time": 1.1, "bytes": 1.0, "cvode_time": 1.12}}},
        "amplitude": {"scene": "stability_planar4", "kind": "amplitude", "study": "amplitude", "name": "amplitude",
                      "data": {"method": "rk4", "a_over_l": a, "error": 0.3 * a ** 2 / (1 + a), "slope": 2.0}},
    }


def _region_plot():
    """geometric-2dof's stability region: classical and partitioned methods,
    one with no colour of its own (heun3)."""
    from rk4h.methods import METHODS
    from rk4h.validation.stability.region import region_plot

    names = ("rk4", "heun3", "euler", "stormer-verlet", "forest-ruth", "yoshida4")
    return region_plot("geometric-2dof", [METHODS[n] for n in names], n=81)


def _exact_run(name, params, x0, v0=None, t_end=20.0, m=2001):
    model = rk4h.make_model(name, params)
    t = np.linspace(0.0, t_end, m)
    return model, t, modal_solution(model, model.state(x0, v0))(t)


def _rk4_run(name, params, x0, v0=None, t_end=5.0, h=0.005):
    model = rk4h.make_model(name, params)
    res = rk4h.solve(model.rhs, (0.0, t_end), model.state(x0, v0), h=h)
    assert res.success
    return model, res.t, res.y


CASE1 = {"masses": [0.815, 3.099], "springs": [41.5, 138.0, 157.8], "walls": "both"}
PLANAR4 = {"m": 0.815, "k": 41.5, "l": 0.01}
TRIANGLE = {"m": 0.815, "k": 41.5, "side": 0.1}
LATTICE = {"masses": 0.815, "springs": 41.5, "n": 100, "walls": "both"}


def _grid_network(n=13):
    """``n`` masses in a row in the plane, each on a spring to the next and to
    an anchor below it: more points than path panels."""
    pos = [c for i in range(n) for c in (0.1 * i, 0.0)]
    anchors = [c for i in range(n) for c in (0.1 * i, -0.1)]
    springs = [[i, i + 1, 40.0] for i in range(n - 1)] + [[i, n + i, 20.0] for i in range(n)]
    return {"dim": 2, "masses": [0.5] * n, "positions": pos, "anchors": anchors, "springs": springs}


def _state(out, name, run, title="RK4"):
    model, t, y = run
    return figures.scene_figures(out, name, model, t, y, title=f"{name}: {title}", modal=modal_content(model, t, y))


BUILDERS = {
    "work_precision": lambda out: [figures.work_precision(out, "oscillator-iso-delta0", _wp_rows())],
    "convergence": lambda out: [figures.convergence(out, "thesis-2dof-case1", *_conv_inputs())],
    "convergence_methods": _conv_methods,
    "energy_error": lambda out: [figures.energy_error(out, "thesis-2dof-case1", {
        lab: (np.linspace(0, 100, 1001), c * np.linspace(0, 100, 1001) * (1.2 + np.sin(np.linspace(0, 300, 1001))))
        for lab, c in (("rk4 h=0.001", 2e-12), ("symplectic-euler h=0.001", 3e-5), ("dop853 rtol=1e-12", 4e-13),
                       ("cvode-adams rtol=1e-12", 2e-11), ("cvode-bdf rtol=1e-12", 4e-10),
                       ("heyoka rtol=1e-12", 2e-14))})],
    "energy_work_precision": lambda out: [EWP.figure(out, "energy-henon-heiles", _ewp_rows())],
    "modal_energy": lambda out: [figures.modal_energy(
        out, "fput-alpha", np.linspace(0, 12000, 600),
        {"rk4 h=0.5": np.vstack([0.55 + 0.45 * np.cos(np.linspace(0, 2 * np.pi, 600)),
                                 0.3 * np.sin(np.linspace(0, np.pi, 600)) ** 2,
                                 0.15 * np.sin(np.linspace(0, np.pi, 600)) ** 2])},
        np.array([0.0952, 0.19, 0.285]))],
    "dispersion": lambda out: [figures.dispersion(
        out, 0.815, 41.5, 0.01, 100, rk4h.make_model("chain", LATTICE).modes()[0],
        [(0.3 * math.pi / 0.01, 0.063272), (0.6 * math.pi / 0.01, 0.041737)], scene_name="lattice100")],
    "crossover": lambda out: [figures.crossover(out, pd.DataFrame([
        {"scene": f"scene-number-{i:02d}" + ("@masses1=0.8150" if i % 5 == 0 else ""), "target_error": te,
         "solver": ["rk4", "dop853", "cvode-adams", "heyoka", ""][(i + j) % 5], "wall_s": 1.5e-3 * (j + 1)}
        for i in range(39) for j, te in enumerate((1e-3, 1e-6, 1e-9, 1e-12))]))],
    "sweep": lambda out: [D.sweep_figure(out, "sweep-2dof-mass-ratio", "masses1", "error_rel",
                                         "max error / max |y_ref|", True,
                                         {f"{s}, {h:g}": [(m, e * (1 + m)) for m in (0.08, 0.24, 0.8, 3.1, 8.2)]
                                          for s, h, e in (("rk4", 0.01, 1e-8), ("rk4", 0.001, 1e-12),
                                                          ("dop853", 1e-8, 1e-9), ("heyoka", 1e-10, 1e-11))})],
    "state_chain": lambda out: _state(out, "thesis-2dof-case1", _exact_run("chain", CASE1, [0.005, 0.005])),
    "state_space_time": lambda out: _state(out, "lattice100", _exact_run(
        "chain", LATTICE, [0.005] + [0.0] * 99, t_end=100.0, m=2001)),
    "state_planar": lambda out: _state(out, "planar4-case2", _rk4_run("planar4", PLANAR4, [0.0, 0.03])),
    "state_paths": lambda out: _state(out, "triangle", _rk4_run(
        "triangle", TRIANGLE, [0.0, 0.0, 0.0, 0.0, 0.005, 0.005], t_end=10.0)),
    "state_paths_many": lambda out: _state(out, "grid-network", _rk4_run(
        "network", _grid_network(), [0.01] + [0.0] * 25, t_end=2.0, h=0.01)),
    "state_angles": lambda out: _state(out, "pendulums-beats", _rk4_run(
        "pendulums", {"m": 0.5, "length": 1.0, "g": 9.81, "k": 0.2}, [0.1, 0.0], t_end=20.0, h=0.01)),
    "state_coordinates": lambda out: _state(out, "henon-heiles", _rk4_run(
        "potential", {"coordinates": ["x", "y"], "masses": 1.0, "potential": "(x^2 + y^2)/2 + x^2*y - y^3/3",
                      "constants": {}}, [0.1, 0.05], t_end=20.0, h=0.01)),
    **{f"stability_{k}": (lambda k: lambda out: [S.draw(_stability_plots()[k], out)])(k)
       for k in ("growth", "drift", "long_energy", "roundoff", "cost_mu", "cost_ratio", "large_n", "amplitude")},
    "stability_region": lambda out: [S.draw(_region_plot(), out)],
}
KINDS = list(BUILDERS)
CHECKS = ["legend", "ticks", "title", "fonts", "inside"]


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    """kind -> [(Figure, path, sentence)], each kind built once, on demand."""
    cache = {}

    def get(kind):
        if kind not in cache:
            seen = []
            saved = figures.style.SAVE_HOOK
            figures.style.SAVE_HOOK = lambda fig, path: seen.append((fig, path))
            try:
                out = BUILDERS[kind](tmp_path_factory.mktemp(kind))
            finally:
                figures.style.SAVE_HOOK = saved
            by_path = {p.name: s for p, s in out}
            cache[kind] = [(fig, path, by_path.get(path.name)) for fig, path in seen]
            assert cache[kind], f"{kind}: no figure drawn"
        return cache[kind]

    return get


# -- the checks ------------------------------------------------------------------------------------------
def _renderer(fig):
    """The renderer of the figure as drawn for its PNG (every figure function
    draws before it returns; inspecting the ticks marks a figure stale without
    changing its layout, so it is not drawn again)."""
    return fig.canvas.get_renderer()


def _data_points(ax, renderer):
    """Display coordinates of what the axes draw inside its window."""
    pts = []
    for line in ax.get_lines():
        if line.get_visible():
            xy = np.asarray(line.get_xydata(), float)
            xy = xy[np.isfinite(xy).all(axis=1)] if xy.size else xy.reshape(0, 2)
            if len(xy):
                pts.append(line.get_transform().transform(xy))
    for coll in ax.collections:
        if isinstance(coll, Collection) and coll.get_visible() and len(coll.get_offsets()):
            off = np.asarray(coll.get_offsets(), float)
            pts.append(coll.get_offset_transform().transform(off[np.isfinite(off).all(axis=1)]))
    for patch in ax.patches:
        if isinstance(patch, Rectangle) and patch.get_visible():
            e = patch.get_window_extent(renderer)
            pts.append(np.array([[(e.x0 + e.x1) / 2, (e.y0 + e.y1) / 2]]))
    for text in ax.texts:
        if text.get_visible() and text.get_text().strip():
            pts.append(text.get_transform().transform(np.array([text.get_position()], float)))
    if not pts:
        return np.empty((0, 2))
    pts = np.vstack(pts)
    box = ax.get_window_extent(renderer)
    inside = (pts[:, 0] >= box.x0) & (pts[:, 0] <= box.x1) & (pts[:, 1] >= box.y0) & (pts[:, 1] <= box.y1)
    return pts[inside]


def check_legend(fig, renderer):
    legends = list(fig.legends) + [ax.get_legend() for ax in fig.axes if ax.get_legend() is not None]
    bad = []
    for leg in legends:
        box = leg.get_window_extent(renderer)
        for ax in fig.axes:
            if not ax.get_visible():
                continue
            pts = _data_points(ax, renderer)
            hit = ((pts[:, 0] > box.x0 + 1) & (pts[:, 0] < box.x1 - 1) &
                   (pts[:, 1] > box.y0 + 1) & (pts[:, 1] < box.y1 - 1))
            if hit.any():
                bad.append(f"legend {[t.get_text() for t in leg.get_texts()][:2]}... covers {int(hit.sum())} "
                           f"point(s) of axes {ax.get_title() or ax.get_ylabel()!r}")
    return bad


def _axis_labels(ax, axis, renderer):
    box = ax.get_window_extent(renderer)
    lo, hi = (box.x0, box.x1) if axis is ax.xaxis else (box.y0, box.y1)
    out = []
    for lab in list(axis.get_ticklabels()) + list(axis.get_ticklabels(minor=True)):
        if not lab.get_visible() or not lab.get_text().strip():
            continue
        e = lab.get_window_extent(renderer)
        c = (e.x0 + e.x1) / 2 if axis is ax.xaxis else (e.y0 + e.y1) / 2
        if lo - 1 <= c <= hi + 1:
            out.append((lab.get_text(), e))
    return out


def check_ticks(fig, renderer):
    bad = []
    for ax in fig.axes:
        if not ax.get_visible():
            continue
        for name, axis in (("x", ax.xaxis), ("y", ax.yaxis)):
            labs = _axis_labels(ax, axis, renderer)
            for i, (ta, a) in enumerate(labs):
                for tb, b in labs[i + 1:]:
                    if min(a.x1, b.x1) - max(a.x0, b.x0) > 0.5 and min(a.y1, b.y1) - max(a.y0, b.y0) > 0.5:
                        bad.append(f"{name} tick labels {ta!r} and {tb!r} overlap in axes "
                                   f"{ax.get_title() or ax.get_ylabel()!r}")
    return bad


def check_title(fig, renderer):
    return [] if fig.get_suptitle().strip() else ["no figure title"]


def check_fonts(fig, renderer):
    small = {(t.get_text()[:30], round(t.get_fontsize(), 2)) for t in fig.findobj(Text)
             if t.get_visible() and t.get_text().strip() and t.get_fontsize() < MIN_PT - 1e-9}
    return [f"text {s!r} at {pt} pt" for s, pt in sorted(small)]


def check_inside(fig, renderer):
    """Every visible text (labels, title, legend, annotations) lies on the canvas."""
    w, h = fig.bbox.width, fig.bbox.height
    ticks, shown = set(), []  # matplotlib keeps labels of ticks outside the view, undrawn: only drawn ones count
    for ax in fig.axes:
        for axis in (ax.xaxis, ax.yaxis):
            ticks.update(id(t) for t in list(axis.get_ticklabels()) + list(axis.get_ticklabels(minor=True)))
            if ax.get_visible():
                shown += [e for _, e in _axis_labels(ax, axis, renderer)]
    out = []
    texts = [(t.get_text(), t.get_window_extent(renderer)) for t in fig.findobj(Text)
             if id(t) not in ticks and t.get_visible() and t.get_text().strip()]
    for text, e in texts + [("tick label", e) for e in shown]:
        if e.x0 < -1 or e.y0 < -1 or e.x1 > w + 1 or e.y1 > h + 1:
            out.append(f"text {text[:40]!r} runs off the canvas ({e.x0:.0f}, {e.y0:.0f}, "
                       f"{e.x1:.0f}, {e.y1:.0f}) of ({w:.0f}, {h:.0f})")
    return out


CHECK = {"legend": check_legend, "ticks": check_ticks, "title": check_title, "fonts": check_fonts,
         "inside": check_inside}


@pytest.mark.parametrize("check", CHECKS)
@pytest.mark.parametrize("kind", KINDS)
def test_layout(kind, check, built):
    problems = []
    for fig, path, _ in built(kind):
        problems += [f"{path.name}: {p}" for p in CHECK[check](fig, _renderer(fig))]
    assert not problems, f"{kind} {check}:\n" + "\n".join(problems)


# -- sentences: generic once per kind, specific ones from the data --------------------------------------
@pytest.mark.parametrize("kind", KINDS)
def test_each_sentence_has_a_generic_caption(kind, built):
    for _, path, sentence in built(kind):
        assert isinstance(sentence, str) and sentence.endswith("."), (path.name, sentence)
        assert sentence.kind in figures.GENERIC_CAPTIONS, (path.name, sentence.kind)
        generic = figures.GENERIC_CAPTIONS[sentence.kind]
        assert generic not in sentence and len(generic) > 40


def test_generic_captions_cover_every_kind_drawn(built):
    drawn = {s.kind for k in KINDS for _, _, s in built(k)}
    assert drawn == set(figures.GENERIC_CAPTIONS)


def test_a_caption_survives_pickling_with_its_kind():
    import pickle

    c = figures.Caption("three masses: x.", "paths")
    back = pickle.loads(pickle.dumps(c))
    assert back == c and back.kind == "paths"


def _sentences(built, kind):
    return {p.name.rsplit("_", 1)[-1][:-4]: s for _, p, s in built(kind)}


def test_a_straight_path_is_called_a_line_not_an_ellipse(tmp_path):
    # planar4-case1: displaced along x, a symmetry direction: the path is a segment
    out = _state(tmp_path, "planar4-case1", _rk4_run("planar4", PLANAR4, [0.005, 0.0], t_end=1.5))
    sentence = {p.name: s for p, s in out}["planar4_case1_trajectory.png"]
    assert "straight segment" in sentence and "ellipse" not in sentence.replace("no ellipse", "")
    # off the axes it is a curve, and the drawing's reading hint is quoted
    curved = {p.name: s for p, s in _state(tmp_path, "q", _rk4_run("planar4", PLANAR4, [0.005, 0.03], t_end=1.5))}
    assert "straight" not in curved["q_trajectory.png"] and "precessing" in curved["q_trajectory.png"]


def test_a_single_mode_start_is_not_promised_beats(built):
    s = _sentences(built, "state_chain")["displacement"]
    assert "100.0% mode 1" in s and "no beats" in s and "beats when" not in s
    beats = _sentences(built, "state_angles")["angles"]
    assert "beat with period" in beats  # two pendulums, one displaced: two close modes


def test_heyoka_same_cost_settings_are_labelled_points_not_a_wall(built):
    (fig, _, sentence), = built("work_precision")
    for ax in fig.axes[:2]:
        (hey,) = [ln for ln in ax.get_lines() if len(ln.get_xdata()) == 4 and
                  np.ptp(np.log10(np.asarray(ln.get_xdata(), float))) < math.log10(1.5)]
        assert hey.get_linestyle() == "None"
        assert sorted(t.get_text() for t in ax.texts) == sorted(
            f"rtol {r:g}" for r in (1e-4, 1e-7, 1e-10, 1e-12))
    assert "relative" in fig.axes[0].get_ylabel() and "heyoka (4 settings" in sentence


def test_error_axis_is_relative_or_says_its_units(built, tmp_path, monkeypatch):
    (fig, _, _), = built("convergence")  # points without error_rel: absolute, mixed units said
    assert "m/s" in fig.axes[0].get_ylabel() and "in its unit" in fig.axes[0].get_ylabel()
    seen = []
    monkeypatch.setattr(figures.style, "SAVE_HOOK", lambda f, p: seen.append(f))
    points, fits = _conv_inputs()
    figures.convergence(tmp_path, "c", points.assign(error_rel=points["error_max"] / 0.005), fits)
    assert seen[0].axes[0].get_ylabel().startswith("relative error")


def test_mass_ratio_cost_is_one_curve_per_solver_against_the_folded_ratio(built):
    (fig, _, sentence), = built("stability_cost_mu")
    assert "1e-06" in fig.get_suptitle()
    ax_n = fig.axes[0]
    curves = [ln for ln in ax_n.get_lines() if ln.get_linestyle() == "-"]
    assert len(curves) == 4  # one per solver
    for ln in curves:
        x = np.asarray(ln.get_xdata(), float)
        assert np.all(x >= 1.0) and len(set(x)) == len(x) == 3
    assert ax_n.get_xscale() == "log" and "folded" in sentence


def test_path_panels_fit_their_paths(built):
    (fig, _, _), = built("state_paths")
    renderer = _renderer(fig)
    panels = [ax for ax in fig.axes if ax.get_visible() and ax.get_lines()]
    assert len(panels) == 3
    fills = []
    for ax in panels:
        assert ax.get_aspect() == 1.0
        path = max(ax.get_lines(), key=lambda ln: len(ln.get_xdata()))
        pts = path.get_transform().transform(path.get_xydata())
        box = ax.get_window_extent(renderer)
        fills.append(max(np.ptp(pts[:, 0]) / box.width, np.ptp(pts[:, 1]) / box.height))
    assert max(fills) > 0.8, fills  # the path that sets the common scale fills its panel
    area = sum(ax.get_window_extent(renderer).width * ax.get_window_extent(renderer).height for ax in panels)
    assert area / (fig.bbox.width * fig.bbox.height) > 0.4


def test_long_chain_image_shows_a_legible_window_and_the_whole_run_amplitude(built):
    figs = {p.name: (f, s) for f, p, s in built("state_space_time")}
    fig, sentence = figs["lattice100_displacement.png"]
    (signed,) = [ax for ax in fig.axes if ax.images]
    n, cols = signed.images[0].get_array().shape
    assert n == 100 and cols < 2001  # a window of the run
    px = signed.get_window_extent(_renderer(fig)).width
    period = 2 * math.pi / 14.13  # the fastest excited mode of a plucked end mass
    assert px / (signed.get_xlim()[1] / period) >= figures.PX_PER_PERIOD * 0.9
    assert [ax for ax in fig.axes if ax.collections and not ax.images]  # the amplitude panel
    assert "first 35" in sentence and "whole run" in sentence


def test_crossover_has_a_key_that_explains_none(built):
    (fig, _, _), = built("crossover")
    (leg,) = fig.legends
    labels = [t.get_text() for t in leg.get_texts()]
    assert labels[:4] == ["rk4", "dop853", "cvode-adams", "heyoka"]
    assert labels[-1].startswith("none: no solver reached")


def test_scene_methods_are_drawn_in_their_registry_styles(built):
    """Each of a scene's own methods has its own colour (not the grey of an
    unknown solver) and every expected order its slope guide."""
    (fig, _, _), = built("convergence_methods")
    ax = fig.axes[0]
    colours = {line.get_label().split(":")[0]: line.get_color() for line in ax.get_lines()
               if ":" in line.get_label()}
    assert figures.UNKNOWN_STYLE[0] not in colours.values(), colours
    assert len(set(colours.values())) == len(colours), colours
    guides = sorted(line.get_gid() for line in ax.get_lines() if (line.get_gid() or "").startswith("guide"))
    assert guides == ["guide_slope_1", "guide_slope_2", "guide_slope_3", "guide_slope_4"]


# -- the cheaper layout and the minor grid (figures at a fraction of their cost) -----------------------
@pytest.mark.parametrize("kind", ["convergence", "energy_work_precision", "dispersion"])
def test_the_layout_from_cheaper_inputs_is_the_constrained_layout(kind, tmp_path, monkeypatch):
    """Laid out without the spines (``style.lay_out``), every axes sits where
    the full constrained layout puts it, give or take the tick marks' length
    (3.5 pt) where a panel's tick labels are hidden (shared axes): its tick
    marks then reach into the gap instead of widening it."""
    import matplotlib

    seen = []
    monkeypatch.setattr(figures.style, "SAVE_HOOK", lambda fig, path: seen.append(fig))
    BUILDERS[kind](tmp_path)
    tick_px = matplotlib.rcParams["xtick.major.size"] / 72.0 * figures.DPI
    for fig in seen:
        size = np.array(fig.canvas.get_width_height() * 2, float)
        fast = np.array([ax.get_position().bounds for ax in fig.axes]) * size
        for ax in fig.axes:
            for spine in ax.spines.values():
                spine.set_in_layout(True)
        fig.set_layout_engine("constrained")
        fig.canvas.draw()
        full = np.array([ax.get_position().bounds for ax in fig.axes]) * size
        assert np.abs(fast - full).max() <= tick_px, (kind, fast - full)


def test_log_axes_draw_their_minor_grid_as_lines_not_ticks(built):
    """The unlabelled minor ticks of a log axis (2 and 5 x 10^k) are drawn as
    one faint line collection at every such value inside the view that is
    not a major tick (as matplotlib's minor ticks were), and no minor tick
    objects are left to lay out and draw."""
    from matplotlib.collections import LineCollection

    (fig, _, _), = built("convergence")
    ax = fig.axes[0]
    grids = [c for c in ax.collections if isinstance(c, LineCollection)]
    assert len(grids) == 2  # one per log axis
    for axis, grid, col in ((ax.xaxis, grids[0], 0), (ax.yaxis, grids[1], 1)):
        assert len(axis.get_minorticklocs()) == 0
        lo, hi = sorted(axis.get_view_interval())
        values = np.array([seg[0][col] for seg in grid.get_segments()])
        major = list(axis.get_majorticklocs())
        want = [m * 10.0 ** e for e in range(math.floor(math.log10(lo)), math.ceil(math.log10(hi)) + 1)
                for m in figures.style.MINOR_SUBS if lo <= m * 10.0 ** e <= hi
                and not any(math.isclose(m * 10.0 ** e, v, rel_tol=1e-9) for v in major)]
        assert want
        np.testing.assert_allclose(np.sort(values), np.sort(want), rtol=1e-12)
        assert 0 < grid.get_alpha() < 0.5


def test_log_minor_grid_leaves_out_the_major_ticks():
    """A log axis of under two decades has major ticks at 2 and 5 x 10^k:
    the minor grid draws no second line there (matplotlib's minor ticks did
    not either); on a wide axis it draws at every 2 and 5 x 10^k."""
    from matplotlib.collections import LineCollection

    fig = figures.style.new_figure()
    ax = fig.add_subplot()
    ax.plot([1.0, 50.0], [1e-8, 1e2])
    ax.set_xlim(1.0, 50.0)
    ax.set_ylim(1e-8, 1e2)
    figures.style.log_axes(ax)
    figures.style.finish(fig)
    grids = [c for c in ax.collections if isinstance(c, LineCollection)]
    # x (1 to 50): majors at 1, 2, 5 x 10^k, so every 2 and 5 x 10^k is a major: no minor line
    xmajor = [v for v in ax.xaxis.get_majorticklocs() if 1.0 <= v <= 50.0]
    assert all(any(math.isclose(v, m) for v in xmajor) for m in (2.0, 5.0, 20.0, 50.0))
    assert len(grids) == 1 and len(ax.xaxis.get_minorticklocs()) == 0
    ys = sorted(seg[0][1] for seg in grids[0].get_segments())
    assert len(ys) == 2 * 10  # 2 and 5 x 10^k for k = -8 ... 1


def test_the_renderer_gives_matplotlibs_own_line_metrics():
    """``style._Renderer`` answers a text's line metrics (ascent, descent,
    line gap) from a per-font memo; every text's extent is then the one
    matplotlib computes from the font's tables (a plain Agg renderer), to the
    last bit, for one- and two-line texts, other sizes, weights and rotations,
    and the memo holds one entry per font, not per text."""
    from matplotlib.backends.backend_agg import RendererAgg

    fig = figures.style.new_figure()
    renderer = fig.canvas.get_renderer()
    assert isinstance(renderer, figures.style._Renderer)
    w, h = fig.canvas.get_width_height()
    plain = RendererAgg(w, h, fig.dpi)
    assert not hasattr(plain, "_get_font_height_metrics")  # the plain renderer measures from the tables
    texts = [fig.text(0.1, 0.1, "0.5"), fig.text(0.2, 0.3, "10\u207b\u2076", fontsize=8),
             fig.text(0.5, 0.5, "a title\nof two lines", fontsize=10, weight="bold"),
             fig.text(0.4, 0.6, "Im z", rotation=90), fig.text(0.3, 0.2, "g", fontsize=13)]
    for t in texts:
        a = t.get_window_extent(renderer).bounds
        b = t.get_window_extent(plain).bounds
        assert a == b, (t.get_text(), a, b)
    import inspect

    from matplotlib.text import Text

    if "_get_font_height_metrics" not in inspect.getsource(Text._get_layout):
        pytest.skip("this matplotlib does not ask the renderer for line metrics (the extents above still match)")
    assert len(renderer._line_metrics) == 4  # 10 pt, 10 pt bold, 8 pt, 13 pt: "0.5" and "Im z" share one
    for key, (ascent, descent, gap) in renderer._line_metrics.items():
        assert ascent > 0 and descent > 0 and gap >= 0, key


def test_the_renderer_falls_back_to_matplotlibs_measure(monkeypatch):
    """Where the matplotlib font internals it reads are gone, the renderer
    answers Nones, which tells matplotlib to measure the text itself, as
    without the renderer: a changed matplotlib never fails a figure here."""
    from matplotlib import font_manager

    fig = figures.style.new_figure()
    renderer = fig.canvas.get_renderer()
    t = fig.text(0.1, 0.1, "0.5 and more")
    monkeypatch.delattr(font_manager.FontManager, "_find_fonts_by_props")
    assert renderer._get_font_height_metrics(t.get_fontproperties()) == (None, None, None)
