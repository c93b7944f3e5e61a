"""Figures from figure jobs (:class:`rk4h.validation.measure.FigureJob`): the
report's only drawing entry. Each job's data came from records; nothing here
integrates. A plotting fault is a failed check of the scene, never a lost run.
"""
from __future__ import annotations

import math

import numpy as np

__all__ = ["draw", "draw_job", "sweep_jobs", "sweep_figure"]


def draw_job(job, out_dir, scene) -> list:
    """:func:`draw` for one job whose scene (or None) is passed alone: what a
    worker process runs (a function of this module, so that it pickles by
    name however ``run_all`` was started)."""
    from pathlib import Path

    if not Path(out_dir).is_dir():  # the run was stopped and its directory removed: draw nothing
        raise FileNotFoundError(f"{out_dir} is gone")
    return draw(job, out_dir, {job.scene: scene} if scene is not None else {})


def draw(job, out_dir, scenes_by_name) -> list:
    """Draw ``job`` into ``out_dir``; returns ``[(Path, sentence), ...]``, each
    sentence a :class:`rk4h.validation.figures.Caption` (a ``str`` with the
    scene-specific facts; ``sentence.kind`` keys the figure kind's reading
    guide in ``rk4h.validation.figures.GENERIC_CAPTIONS``).
    The scene's own methods (``[methods.NAME]``) are drawn in their registry styles."""
    from . import figures as f

    scene = scenes_by_name.get(job.scene) if scenes_by_name else None
    local = getattr(scene, "registry", {}) if scene is not None else {}
    with f.scene_methods(local):
        return _draw(job, out_dir, scenes_by_name)


def _state(f, out_dir, name, d, scenes_by_name):
    from .look import ModelLook

    model = ModelLook(d.get("look"))  # the recorded model's look: drawing builds no model
    thesis = d.get("thesis")
    return f.scene_figures(out_dir, name, model, d["t"], d["y"], title=d["title"],
                           thesis=f"thesis {thesis}" if thesis else None, modal=d.get("modal"))


def _stability(f, out_dir, name, d, scenes_by_name):
    from . import stability

    return [stability.draw(d["plot"], out_dir)]


def _frame(rows):
    import pandas as pd

    return pd.DataFrame(rows)


#: The figure kinds drawn here: kind -> ``fn(figures module, out_dir, scene name, job data, scenes_by_name)``
#: returning ``[(Path, sentence), ...]``. Kinds not listed are drawn by the output that declares them
#: (:func:`rk4h.validation.outputs.drawer`).
DRAWERS = {
    "work_precision": lambda f, out, name, d, sc: [f.work_precision(out, name, _frame(d["rows"]))],
    "energy_error": lambda f, out, name, d, sc: [f.energy_error(out, name, d["series"])],
    "convergence": lambda f, out, name, d, sc: [f.convergence(out, name, _frame(d["points"]), _frame(d["fits"]))],
    "modal_energy": lambda f, out, name, d, sc: [f.modal_energy(out, name, d["t"], d["series"], d["omega"],
                                                                recurrence=d.get("recurrence", True))],
    "dispersion": lambda f, out, name, d, sc: [f.dispersion(out, d["m"], d["k"], d["d"], d["n"], d["finite"],
                                                            d["packets"], scene_name=name)],
    "state": _state,
    "stability": _stability,
    "sweep": lambda f, out, name, d, sc: [sweep_figure(out, **d)],
    "crossover": lambda f, out, name, d, sc: [f.crossover(out, _frame(d["rows"]))],
}


def _draw(job, out_dir, scenes_by_name) -> list:
    from . import figures as f

    d, name = job.data, job.scene
    own = DRAWERS.get(job.kind)
    if own is not None:
        return own(f, out_dir, name, d, scenes_by_name)
    from . import outputs

    fn = outputs.drawer(job.kind)  # a figure an output draws itself (rk4h.validation.outputs.Output.draw)
    if fn is not None:
        return list(fn(out_dir, job, scenes_by_name.get(name) if scenes_by_name else None))
    raise ValueError(f"unknown figure kind {job.kind!r}")


#: Quantities drawn against a swept parameter: (table, column, per-curve keys, y label, log y).
SWEEP_QUANTITIES = (
    ("accuracy", "error_rel", ("solver", "setting"),
     "relative error\nmax |y - y_ref| / max |y_ref|", True),
    ("accuracy", "energy_drift_max", ("solver", "setting"), "max |E - E0| / E_motion (relative)", True),
    ("accuracy", "nfev", ("solver", "setting"), "RHS evaluations", True),
    ("convergence", "observed_order", ("solver", "quantity"), "observed order", False),
    ("modes", "omega_rad_s", ("mode",), "omega (rad/s)", True),
    ("linearization", "error_rel_q", (), "linear model position error / amplitude (relative)", True),
)


def sweep_jobs(scenes, results) -> list:
    """One figure job per (swept scene, swept parameter, measured quantity):
    the quantity against the parameter, one curve per solver and setting,
    read from the measured tables of the sweep's points."""
    from .measure import FigureJob

    groups = {}
    for scene, res in zip(scenes, results):
        sweep = dict(getattr(scene, "sweep", None) or {})
        if sweep:
            groups.setdefault(getattr(scene, "base", scene.name), []).append((sweep, res))
    jobs = []
    for base, points in groups.items():
        if len(points) < 2:
            continue
        for param in points[0][0]:
            if not all(isinstance(sw.get(param), (int, float)) for sw, _ in points):
                continue
            for table, col, keys, ylabel, logy in SWEEP_QUANTITIES:
                curves = {}
                for sw, res in points:
                    others = ", ".join(f"{k}={v:g}" for k, v in sw.items() if k != param)
                    for row in res.tables.get(table, []):
                        y = row.get(col)
                        if not isinstance(y, (int, float)) or not math.isfinite(y):
                            continue
                        label = ", ".join(f"{row[k]:g}" if isinstance(row[k], float) else str(row[k])
                                          for k in keys) or col
                        if others:
                            label += f" ({others})"
                        curves.setdefault(label, []).append((float(sw[param]), float(y)))
                if curves:
                    jobs.append(FigureJob(base, "sweep", {"base": base, "param": param, "quantity": col,
                                                          "ylabel": ylabel, "logy": logy,
                                                          "curves": {k: sorted(v) for k, v in curves.items()}}))
    return jobs


def sweep_figure(out_dir, base, param, quantity, ylabel, logy, curves):
    """A measured quantity against a swept parameter (log x when the values
    span more than a decade), one line per curve; the legend (up to 12
    curves) sits below the axes. Returns ``(Path, Caption)``, ``kind``
    ``"sweep"``: the sentence names the points and the quantity's range."""
    from . import figures as f

    fig = f.new_figure(f.SIZE)
    f.suptitle(fig, f"{base}: {quantity} against {param}")
    ax = fig.subplots()
    xs_all, ys_all, seen = [], [], {}
    for label, pts in curves.items():
        x, y = np.array(pts, float).T
        xs_all += list(x)
        ys_all += list(y)
        solver = label.split(",")[0]
        color, marker = f.solver_style(solver)
        ls = f.LINESTYLES[seen.get(solver, 0) % len(f.LINESTYLES)]  # a solver's settings told apart
        seen[solver] = seen.get(solver, 0) + 1
        ax.plot(x, y, marker=marker, color=color if color != "#7f7f7f" else None, lw=1.2, ms=4, ls=ls, label=label)
    xs, ys = np.array(xs_all), np.array(ys_all)
    log_x = bool(xs.size and np.all(xs > 0) and xs.max() / xs.min() > 10)
    log_y = bool(logy and all(np.all(np.array(p)[:, 1] > 0) for p in curves.values()))
    if log_x or log_y:
        f.log_axes(ax, x=log_x, y=log_y)
    ax.grid(True, which="major", alpha=0.3)
    ax.set_xlabel(param)
    ax.set_ylabel(ylabel)
    if len(curves) <= 12:  # more would crush the axes; the sentence says so
        f.legend_below(fig)
    path = f.save(fig, out_dir, f"{f.slug(base)}_sweep_{f.slug(param)}_{f.slug(quantity)}")
    fin = ys[np.isfinite(ys)]
    sentence = (f"{base}: {quantity} over {len(set(xs_all))} values of {param} ({xs.min():g} to {xs.max():g}), "
                f"{len(curves)} curve(s), values {fin.min():.3g} to {fin.max():.3g}"
                + ("" if len(curves) <= 12 else " (too many curves for a key: colour = solver, see the table)") + "."
                if fin.size else f"{base}: no finite {quantity} to draw against {param}.")
    return path, f.Caption(sentence, "sweep")
