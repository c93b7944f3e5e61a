"""The report's figures (validation/figures/): files, sizes, what is drawn.

Inputs are realistic but short: real RK4 trajectories (rk4h.solve) and the
modal exact solution of the seed's models. Each figure is inspected just
before it is written through ``figures.style.SAVE_HOOK``.
"""
import math

import matplotlib.colors as mcolors
import matplotlib.image as mimage
import numpy as np
import pandas as pd
import pytest

import rk4h
from rk4h.references.exact import modal_solution
from rk4h.validation import figures
from rk4h.validation.execute import modal_content

PX = (round(figures.SIZE[1] * figures.DPI), round(figures.SIZE[0] * figures.DPI))  # (rows, cols)
PX_TALL = (round(figures.SIZE_TALL[1] * figures.DPI), round(figures.SIZE_TALL[0] * figures.DPI))
MAX_BYTES = 200_000


@pytest.fixture(autouse=True)
def no_open_figures():
    import matplotlib.pyplot as plt

    yield
    assert plt.get_fignums() == []


@pytest.fixture
def captured(monkeypatch):
    """List of (Figure, path) of every figure saved during the test."""
    seen = []
    monkeypatch.setattr(figures.style, "SAVE_HOOK", lambda fig, path: seen.append((fig, path)))
    return seen


def check_png(path, shape=PX):
    assert path.suffix == ".png" and path.exists()
    assert 0 < path.stat().st_size < MAX_BYTES
    img = mimage.imread(path)
    assert img.shape[:2] == shape


def check_sentence(s):
    assert isinstance(s, str) and len(s) > 30 and "\n" not in s


def labelled_lines(ax):
    return [ln for ln in ax.get_lines() if not ln.get_label().startswith("_")]


def scene_figures(out_dir, scene_name, model, t, y, **kw):
    """``figures.scene_figures`` as the pipeline calls it: with the modal
    content execute records for the trajectory."""
    return figures.scene_figures(out_dir, scene_name, model, t, y, modal=modal_content(model, t, y), **kw)


def rk4_run(name, params, x, v=None, t_end=3.0, h=0.01):
    model = rk4h.make_model(name, params)
    res = rk4h.solve(model.rhs, (0.0, t_end), model.state(x, v), h=h)
    assert res.success
    return model, res.t, res.y


CASE1 = {"masses": [0.815, 3.099], "springs": [41.5, 138.0, 157.8], "walls": "both"}


# -- scene figures -------------------------------------------------------------------
WEB = {"dim": 2, "masses": [0.5, 0.8], "positions": [-0.2, 0.0, 0.2, 0.0],
       "anchors": [-0.6, 0.0, 0.0, 0.5, 0.6, 0.0, 0.0, -0.5],
       "springs": [[0, 2, 30.0], [0, 3, 20.0], [1, 4, 30.0], [1, 5, 20.0], [0, 1, 50.0]]}
LINE = {"dim": 1, "masses": [1.0, 2.0], "positions": [0.0, 1.0], "anchors": [-1.0, 2.0],
        "springs": [[2, 0, 10.0], [0, 1, 10.0], [1, 3, 10.0]]}
SCENES = {
    # kind: (model, params, x0, v0, expected file suffixes, lines per time-series panel
    #        or, for "_paths", panels)
    "chain": ("chain", CASE1, [0.005, 0.0], None, {"displacement", "velocity"}, 2),
    "planar4": ("planar4", {"m": 0.815, "k": 41.5, "l": 0.01}, [0.005, 0.03], None,
                {"displacement", "velocity", "springs", "trajectory"}, 2),
    "oscillator2d": ("oscillator2d", {"m": 0.815, "kx": 4 * 41.5, "ky": 41.5}, [0.0, 1.0], [7.0, 0.0],
                     {"displacement", "velocity", "trajectory"}, 2),
    "pendulums": ("pendulums", {"m": 0.5, "length": 1.0, "g": 9.81, "k": 0.2}, [0.1, 0.0], None,
                  {"angles"}, 2),
    "triangle": ("triangle", {"m": 1.0, "k": 10.0, "side": 1.0}, [0.01, 0, -0.01, 0.005, 0, -0.004], None,
                 {"paths"}, 3),
    "long chain": ("chain", {"masses": [0.815] * 12, "springs": [41.5] * 13}, [0.005] + [0.0] * 11, None,
                   {"displacement", "velocity"}, None),
    # no model-specific code in the figures: these come from the drawings alone
    "web": ("network", WEB, [0.02, 0.0, -0.01, 0.015], None, {"paths"}, 2),
    "line": ("network", LINE, [0.01, 0.0], None, {"displacement", "velocity"}, 2),
    "potential": ("potential", {"coordinates": ["x", "y"], "masses": 1.0, "potential": "(x^2 + y^2)/2 + x^2*y",
                                "constants": {}}, [0.1, 0.0], None, {"coordinates"}, 2),
}


@pytest.mark.parametrize("kind", list(SCENES))
def test_scene_figures_writes_the_set_of_its_model_kind(kind, tmp_path, captured):
    name, params, x0, v0, suffixes, n_lines = SCENES[kind]
    model, t, y = rk4_run(name, params, x0, v0)
    out = scene_figures(tmp_path, f"My-Scene {kind}", model, t, y, title=f"my scene ({kind})")
    stem = "my_scene_" + kind.replace(" ", "_") + "_"
    assert {p.name for p, _ in out} == {f"{stem}{s}.png" for s in suffixes}
    for path, sentence in out:
        check_png(path)
        check_sentence(sentence)
    assert len(captured) == len(out)
    for fig, path in captured:
        if kind == "long chain":
            (ax,) = [a for a in fig.axes if a.images]  # one image (plus its colour bar)
            assert ax.images[0].get_array().shape == (model.n_dof, t.size)
            assert labelled_lines(ax) == []
        elif path.name.endswith("_paths.png"):
            panels = [a for a in fig.axes if a.get_lines()]
            assert len(panels) == n_lines
        elif path.name.endswith("_trajectory.png"):
            assert len([ln for ln in fig.axes[0].get_lines() if len(ln.get_xdata()) == t.size]) == 1
        else:
            n_expect = 4 if path.name.endswith("_springs.png") else n_lines
            assert len(labelled_lines(fig.axes[0])) == n_expect


def _renamed(model, name):
    """``model`` under another name: the figures must not notice."""
    model.name = name
    return model


def test_figures_come_from_the_drawing_not_the_name(tmp_path, captured):
    # A network of one mass off the origin on three springs (one of them pre-stretched):
    # drawn as a point in the plane with springs, whatever the model is called.
    X0, anchors = (0.1, 0.2), [(-0.4, 0.2), (0.6, 0.2), (0.1, -0.3)]
    params = {"dim": 2, "masses": [0.5], "positions": list(X0), "anchors": [c for a in anchors for c in a],
              "springs": [[0, 1, 10.0], [0, 2, 20.0, 0.4], [0, 3, 30.0]]}
    model, t, y = rk4_run("network", params, [0.01, -0.02], t_end=1.0)
    out = scene_figures(tmp_path, "w", _renamed(model, "chain"), t, y, title="web")
    assert {p.name for p, _ in out} == {"w_displacement.png", "w_velocity.png", "w_springs.png",
                                        "w_trajectory.png"}
    fig = dict((p.name, f) for f, p in captured)["w_springs.png"]
    ax = fig.axes[0]
    assert "(mm)" in ax.get_ylabel()
    # elongation = |P_b - P_a| - rest, P = reference + displacement; rest 0.5, 0.4, 0.5 m
    px, py = X0[0] + 0.01, X0[1] - 0.02
    expect = {f"0-{j + 1} spring": math.hypot(ax_ - px, ay_ - py) - rest
              for j, ((ax_, ay_), rest) in enumerate(zip(anchors, (0.5, 0.4, 0.5)))}
    first = {ln.get_label(): ln.get_ydata()[0] for ln in labelled_lines(ax)}
    assert first == pytest.approx({k: 1e3 * v for k, v in expect.items()}, rel=1e-12)
    sentences = dict((p.name, s) for p, s in out)
    assert "from its rest position" in sentences["w_displacement.png"]  # coordinates are displacements
    assert "(3 of them anchored)" in sentences["w_springs.png"]


def test_several_points_give_one_path_panel_each_titled_by_its_reference(tmp_path, captured):
    model, t, y = rk4_run("network", WEB, [0.02, 0.0, -0.01, 0.015], t_end=1.0)
    scene_figures(tmp_path, "web", _renamed(model, "triangle"), t, y, title="web")
    (fig, path), = captured
    assert path.name == "web_paths.png"
    panels = [a for a in fig.axes if a.get_lines()]
    assert [a.get_title() for a in panels] == ["mass 1, rest at (-0.2, 0) m", "mass 2, rest at (0.2, 0) m"]
    np.testing.assert_allclose(panels[1].get_lines()[0].get_xdata(), 1e3 * y[2])  # x2 in mm


def test_sentences_quote_the_drawing(tmp_path, monkeypatch):
    import dataclasses

    model, t, y = rk4_run("planar4", {"m": 0.815, "k": 41.5, "l": 0.01}, [0.005, 0.03], t_end=1.0)
    d = dataclasses.replace(model.drawing(), caption="a custom reading hint",
                            extra={"thesis": "Fig 9.99", "rest_note": "a custom rest note"})
    monkeypatch.setattr(model, "drawing", lambda: d)
    sentences = {p.name: s for p, s in scene_figures(tmp_path, "q", model, t, y, title="q")}
    assert all("(Fig 9.99)" in s for s in sentences.values())
    assert "a custom reading hint" in sentences["q_trajectory.png"]
    assert "a custom rest note" in sentences["q_springs.png"]
    shipped_model = rk4h.make_model("planar4", {"m": 0.815, "k": 41.5, "l": 0.01})
    shipped = {p.name: s for p, s in scene_figures(tmp_path, "p", shipped_model, t, y, title="p")}
    # a model does not know whether a scene reproduces a thesis figure: the scene says so
    assert not any("(thesis" in s for s in shipped.values())
    assert "erratum 3: not length - l^2" in shipped["p_springs.png"]
    labelled = {p.name: s for p, s in scene_figures(tmp_path, "p", shipped_model, t, y, title="p",
                                                               thesis="thesis Figs 4.12-4.14")}
    assert all("(thesis Figs 4.12-4.14)" in s for s in labelled.values())


@pytest.mark.parametrize("change, field", [({"layout": "polar"}, "layout"), ({"points": ((0, 2),)}, "points"),
                                           ({"reference": ()}, "reference"),
                                           ({"springs": ((0, 9, "x"),), "rest": (1.0,)}, "springs"),
                                           ({"rest": (1.0,)}, "rest")])
def test_a_drawing_that_does_not_fit_the_model_is_refused(change, field, tmp_path, monkeypatch):
    import dataclasses

    model, t, y = rk4_run("planar4", {"m": 0.815, "k": 41.5, "l": 0.01}, [0.005, 0.03], t_end=0.1)
    d = dataclasses.replace(model.drawing(), **change)
    monkeypatch.setattr(model, "drawing", lambda: d)
    with pytest.raises(ValueError, match=f"`drawing\\(\\).{field}`"):
        scene_figures(tmp_path, "bad", model, t, y, title="bad")
    assert list(tmp_path.iterdir()) == []


def test_chain_time_series_panels_show_whole_run_then_first_periods(tmp_path, captured):
    model, t, y = rk4_run("chain", CASE1, [0.005, 0.0], t_end=20.0)
    scene_figures(tmp_path, "case1", model, t, y, title="case 1")
    fig = dict((p.name, f) for f, p in captured)["case1_displacement.png"]
    top, zoom = fig.axes[:2]
    assert top.get_xlim() == (0.0, 20.0)
    # Zoom: three periods of the slowest mode, omega_1 = 7.1358 rad/s (thesis erratum 1: Table 4.3 prints omega^2).
    assert zoom.get_xlim()[1] == pytest.approx(3 * 2 * math.pi / 7.1358, rel=1e-4)
    # Displacements of 5 mm are drawn in mm: the data are 1e3 * x.
    assert "(mm)" in top.get_ylabel()
    np.testing.assert_allclose(labelled_lines(top)[0].get_ydata(), 1e3 * y[0])


def test_planar4_spring_elongation_is_length_minus_l(tmp_path, captured):
    x0, y0, l = 0.005, 0.03, 0.01
    model, t, y = rk4_run("planar4", {"m": 0.815, "k": 41.5, "l": l}, [x0, y0], t_end=1.0)
    scene_figures(tmp_path, "p4", model, t, y, title="planar4")
    fig = dict((p.name, f) for f, p in captured)["p4_springs.png"]
    ax = fig.axes[0]
    assert "(mm)" in ax.get_ylabel()
    first = {ln.get_label(): ln.get_ydata()[0] for ln in labelled_lines(ax)}
    # Anchors at (-l, 0), (l, 0), (0, -l), (0, l); elongation = |r - a| - l (erratum 3), in mm.
    expect = {"left spring": math.hypot(x0 + l, y0) - l, "right spring": math.hypot(x0 - l, y0) - l,
              "bottom spring": math.hypot(x0, y0 + l) - l, "top spring": math.hypot(x0, y0 - l) - l}
    assert first == pytest.approx({k: 1e3 * v for k, v in expect.items()}, rel=1e-12)


def test_lissajous_is_drawn_with_equal_axes(tmp_path, captured):
    model = rk4h.make_model("oscillator2d", {"m": 0.815, "kx": 4 * 41.5, "ky": 41.5})
    t = np.linspace(0.0, 2.0, 401)
    y = modal_solution(model, model.state([0.0, 1.0], [7.0, 0.0]))(t)
    scene_figures(tmp_path, "liss", model, t, y, title="lissajous")
    fig = dict((p.name, f) for f, p in captured)["liss_trajectory.png"]
    ax = fig.axes[0]
    assert ax.get_aspect() == 1.0
    (path,) = [ln for ln in ax.get_lines() if len(ln.get_xdata()) == t.size]
    np.testing.assert_allclose(path.get_xdata(), y[0])
    np.testing.assert_allclose(path.get_ydata(), y[1])


def test_scene_figures_draw_a_blown_up_run_with_a_gap(tmp_path, captured):
    # A failed run is NaN from the blow-up on (rk4h.references.solvers.base); +-inf may come from a user.
    model, t, y = rk4_run("chain", CASE1, [0.005, 0.0], t_end=2.0)
    y = y.copy()
    y[:, t.size // 2:] = np.nan
    y[0, -1] = np.inf
    out = scene_figures(tmp_path, "boom", model, t, y, title="blown up")
    assert len(out) == 2
    fig = dict((p.name, f) for f, p in captured)["boom_displacement.png"]
    assert "(mm)" in fig.axes[0].get_ylabel()  # the scale comes from the finite part


@pytest.mark.parametrize("bad", ["short_y", "wrong_dof"])
def test_scene_figures_refuses_mismatched_trajectory(bad, tmp_path):
    model, t, y = rk4_run("chain", CASE1, [0.005, 0.0], t_end=0.1)
    y = y[:, :-1] if bad == "short_y" else y[:2]
    with pytest.raises(ValueError, match="`y`"):
        scene_figures(tmp_path, "x", model, t, y, title="x")
    assert list(tmp_path.iterdir()) == []


# -- work-precision ------------------------------------------------------------------
def wp_frame(with_steps):
    rows = []
    for solver, c in (("rk4", 1e-3), ("dop853", 3e-3), ("heyoka", 1e-2)):
        for i, e in enumerate((1e-4, 1e-7, 1e-10)):
            rows.append({"solver": solver, "setting": 10.0 ** -(i + 1), "error_max": e,
                         "wall_s": c * 3 ** i, "nfev": 0 if solver == "heyoka" else 100 * 4 ** i,
                         "n_steps": 10 * 2 ** i, "taylor_order": 20 if solver == "heyoka" else 0,
                         "status": "ok"})
    rows.append({"solver": "rk4", "setting": 1.0, "error_max": math.nan, "wall_s": 1e-4, "nfev": 4,
                 "n_steps": 1, "taylor_order": 0, "status": "unstable"})
    rows.append({"solver": "dop853", "setting": 1e-14, "error_max": 1e-13, "wall_s": 1.0, "nfev": 1e5,
                 "n_steps": 1000, "taylor_order": 0, "status": "failed"})
    df = pd.DataFrame(rows)
    return df if with_steps else df.drop(columns=["n_steps", "taylor_order"])


@pytest.mark.parametrize("with_steps", [True, False], ids=["heyoka-steps-x-order", "no-step-columns"])
def test_work_precision_drops_failed_rows_and_places_heyoka(with_steps, tmp_path, captured):
    df = wp_frame(with_steps)
    path, sentence = figures.work_precision(tmp_path, "Case 1", df)
    assert path.name == "case_1_work_precision.png"
    check_png(path)
    check_sentence(sentence)
    (fig, _), = captured
    ax_t, ax_n = fig.axes
    assert ax_t.get_xscale() == ax_t.get_yscale() == ax_n.get_xscale() == "log"
    by_label = {ln.get_label(): ln for ln in ax_t.get_lines()}
    assert len(ax_t.get_lines()) == 3  # one line per solver
    rk4 = by_label["rk4"]
    # The unstable (NaN) and failed rows are not drawn: 3 ok points each.
    np.testing.assert_allclose(rk4.get_ydata(), [1e-4, 1e-7, 1e-10])
    np.testing.assert_allclose(by_label["dop853"].get_xdata(), [3e-3, 9e-3, 2.7e-2])
    assert mcolors.same_color(rk4.get_color(), figures.SOLVER_STYLE["rk4"][0])
    costs = sorted(tuple(ln.get_xdata()) for ln in ax_n.get_lines())
    if with_steps:
        assert "heyoka (steps x Taylor order)" in by_label
        assert (200.0, 400.0, 800.0) in costs  # steps (10, 20, 40) x order 20
        assert len(costs) == 3
    else:
        assert "heyoka (no nfev: wall time only)" in by_label
        assert len(costs) == 2


def test_work_precision_names_a_missing_column(tmp_path):
    with pytest.raises(ValueError, match="`wall_s`"):
        figures.work_precision(tmp_path, "x", wp_frame(True).drop(columns=["wall_s"]))


# -- convergence ---------------------------------------------------------------------
def conv_inputs():
    h = np.array([0.1, 0.05, 0.02, 0.01, 0.005, 0.001])
    rk4_err = np.maximum(2e-2 * h ** 4, 1e-13)  # round-off floor at the smallest h
    points = pd.concat([pd.DataFrame({"solver": "rk4", "h": h, "error_max": rk4_err}),
                        pd.DataFrame({"solver": "euler", "h": h, "error_max": 0.3 * h})])
    fits = pd.DataFrame({"solver": ["rk4", "euler"], "observed_order": [4.0, 1.0],
                         "h_min": [0.005, 0.001], "h_max": [0.1, 0.1]})
    return points, fits


def slope(line):
    x, y = np.asarray(line.get_xdata(), float), np.asarray(line.get_ydata(), float)
    return math.log(y[-1] / y[0]) / math.log(x[-1] / x[0])


def test_convergence_draws_slope_guides(tmp_path, captured):
    points, fits = conv_inputs()
    path, sentence = figures.convergence(tmp_path, "case1", points, fits)
    check_png(path)
    check_sentence(sentence)
    assert "rk4 4.00" in sentence and "euler 1.00" in sentence
    (fig, _), = captured
    (ax,) = fig.axes
    assert ax.get_xscale() == ax.get_yscale() == "log"
    guides = {ln.get_gid(): ln for ln in ax.get_lines() if (ln.get_gid() or "").startswith("guide")}
    assert set(guides) == {"guide_slope_4", "guide_slope_1"}
    assert slope(guides["guide_slope_4"]) == pytest.approx(4.0, rel=1e-12)
    assert slope(guides["guide_slope_1"]) == pytest.approx(1.0, rel=1e-12)
    # Guide 4 runs a factor 3 under RK4's smallest-h point inside the fit range (h = 0.005).
    g = guides["guide_slope_4"]
    e_at = np.interp(math.log(0.005), np.log(g.get_xdata()), np.log(g.get_ydata()))
    assert math.exp(e_at) == pytest.approx(2e-2 * 0.005 ** 4 / 3, rel=1e-9)
    # Points inside the fitted range are filled, the round-off point is hollow.
    rk4_color = figures.SOLVER_STYLE["rk4"][0]
    marks = [ln for ln in ax.get_lines() if ln.get_linestyle() == "None"
             and mcolors.same_color(ln.get_color(), rk4_color)]
    hollow = [ln for ln in marks if ln.get_markerfacecolor() == "none"]
    filled = [ln for ln in marks if ln.get_markerfacecolor() != "none"]
    assert [len(ln.get_xdata()) for ln in filled] == [5]
    assert [list(ln.get_xdata()) for ln in hollow] == [[0.001]]


def test_convergence_without_euler_has_only_the_slope4_guide(tmp_path, captured):
    points, fits = conv_inputs()
    figures.convergence(tmp_path, "c", points[points.solver == "rk4"], fits[fits.solver == "rk4"])
    (fig, _), = captured
    gids = [ln.get_gid() for ln in fig.axes[0].get_lines() if ln.get_gid()]
    assert gids == ["guide_slope_4"]


# -- energy error --------------------------------------------------------------------
def test_energy_error_log_axes_from_first_step(tmp_path, captured):
    model, t, y = rk4_run("chain", CASE1, [0.005, 0.0], t_end=5.0, h=0.05)
    e = model.energy(y)
    rel = np.abs(e - e[0]) / abs(e[0])
    series = {"rk4 h=0.05": (t, rel), "rk4 h=0.1": (t, 30 * rel), "dop853 rtol=1e-8": (t, 1e-3 * rel)}
    path, sentence = figures.energy_error(tmp_path, "case1", series)
    check_png(path)
    check_sentence(sentence)
    (fig, _), = captured
    ax = fig.axes[0]
    assert ax.get_xscale() == ax.get_yscale() == "log"
    lines = {ln.get_label(): ln for ln in labelled_lines(ax)}
    assert set(lines) == set(series)
    env = lines["rk4 h=0.05"]
    # t = 0 (error 0 by definition) is not on the log axis; the rest is the running maximum.
    np.testing.assert_array_equal(env.get_xdata(), t[1:])
    np.testing.assert_allclose(env.get_ydata(), np.maximum.accumulate(rel)[1:])
    assert mcolors.same_color(env.get_color(), figures.SOLVER_STYLE["rk4"][0])
    assert mcolors.same_color(lines["dop853 rtol=1e-8"].get_color(), figures.SOLVER_STYLE["dop853"][0])
    assert env.get_linestyle() != lines["rk4 h=0.1"].get_linestyle()  # same solver, told apart


# -- dispersion ------------------------------------------------------------------------
def test_dispersion_curves_points_and_zone(tmp_path, captured):
    m, k, d, N = 0.815, 41.5, 0.01, 8
    chain = rk4h.make_model("chain", {"masses": [m] * N, "springs": [k] * (N + 1)})
    finite = chain.modes()[0]
    packets = [(0.3 * math.pi / d, 0.066), (0.6 * math.pi / d, 0.05)]
    path, sentence = figures.dispersion(tmp_path, m, k, d, N, finite, packets)
    assert path.name == "dispersion.png"
    check_png(path, PX_TALL)
    check_sentence(sentence)
    (fig, _), = captured
    ax_w, ax_p, ax_g = fig.axes
    assert ax_g.get_xlim() == pytest.approx((-2 * math.pi / d, 2 * math.pi / d))
    # First Brillouin zone shaded: one span from -pi/d to pi/d on each panel.
    span = ax_w.patches[0]
    assert (span.get_x(), span.get_x() + span.get_width()) == pytest.approx((-math.pi / d, math.pi / d))
    curves = [ln for ln in ax_w.get_lines() if len(ln.get_xdata()) > 100]
    assert len(curves) == 2  # kp < 0 and kp > 0
    for ln in curves:
        kp = np.asarray(ln.get_xdata())
        # omega = sqrt(4k/m) |sin(kp d / 2)| (thesis eq. 2.49)
        np.testing.assert_allclose(ln.get_ydata(), np.sqrt(4 * k / m) * np.abs(np.sin(kp * d / 2)), rtol=1e-12)
    # v_g jumps at kp = 0: no drawn piece crosses it.
    for ln in ax_g.get_lines():
        x = np.asarray(ln.get_xdata(), float)
        assert x.size < 3 or not (x.min() < 0 < x.max())
    dots = [ln for ln in ax_w.get_lines() if len(ln.get_xdata()) == N]
    assert len(dots) == 1
    # Fixed-end chain: kp_n = n pi / ((N + 1) d)
    np.testing.assert_allclose(dots[0].get_xdata(), np.arange(1, N + 1) * math.pi / ((N + 1) * d))
    np.testing.assert_allclose(dots[0].get_ydata(), finite)
    (pk,) = [ln for ln in ax_g.get_lines() if ln.get_label().startswith("wave packet")]
    np.testing.assert_allclose(np.c_[pk.get_xdata(), pk.get_ydata()], packets)


def test_dispersion_refuses_mismatched_finite_chain(tmp_path):
    with pytest.raises(ValueError, match="`finite_n`"):
        figures.dispersion(tmp_path, 1.0, 1.0, 0.01, 5, [1.0, 2.0], [])


# -- crossover and helpers -----------------------------------------------------------
def test_crossover_one_cell_per_scene_and_target(tmp_path, captured):
    df = pd.DataFrame([{"scene": s, "target_error": te, "solver": sv, "wall_s": 0.1}
                       for s in ("a", "b") for te, sv in ((1e-3, "rk4"), (1e-6, "rk4"), (1e-9, "dop853"),
                                                          (1e-12, ""))])
    path, sentence = figures.crossover(tmp_path, df)
    check_png(path)
    check_sentence(sentence)
    (fig, _), = captured
    ax = fig.axes[0]
    assert len(ax.patches) == 8
    texts = [t.get_text().split("\n")[0] for t in ax.texts]
    assert sorted(texts) == sorted(["rk4", "rk4", "dop853", "none"] * 2)


@pytest.mark.parametrize("name, expected", [("thesis-2dof-case1", "thesis_2dof_case1"),
                                            ("Planar4 Case 2 (l=1)", "planar4_case_2_l_1")])
def test_slug(name, expected):
    assert figures.slug(name) == expected

