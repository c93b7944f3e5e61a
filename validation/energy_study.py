"""The opt-in energy study: energy work-precision and energy growth over long horizons.

    python -m rk4h.validation.energy_study SCENE... --out DIR [--periods 1e2 1e4] [--full] [--steps 8 16 32 64]

The numbers come from :mod:`rk4h.validation.energy_time`, the figures from
:mod:`rk4h.validation.energy_figures`; the default report does not run it. A
scene runs the same numbers in the report by listing the
``energy_work_precision`` output (:mod:`rk4h.validation.outputs.energy_work_precision`).
"""
from __future__ import annotations

import math

import numpy as np

from .energy_time import (STEP_CAP_STATUS, WP_HORIZONS, WP_SCENES, dense_samples, equal_cost_step,
                          growth_exponent, long_run, slowest_period, work_precision_rows)

__all__ = ["main"]


def _methods(scene):
    """The registry's tableaux and the scene's own (every fixed-step method the study runs)."""
    from rk4h.references.registry import Kind
    from rk4h.methods import METHODS

    out = dict(METHODS)
    for name in scene.solvers:
        m = scene.method(name)
        if m.kind in (Kind.TABLEAU, Kind.PARTITIONED) and m.tableau is not None:
            out.setdefault(m.tableau.name, m.tableau)
    return list(out.values())


def main(argv=None) -> int:
    """``python -m rk4h.validation.energy_study SCENE ... --out DIR``: the opt-in energy study.

    Writes ``energy_work_precision.csv`` (:func:`work_precision_rows`), one
    ``<scene>_energy_work_precision.png`` and one ``<scene>_energy_growth.png``
    (every method at RK4's cost at 16 steps per fastest period, over the
    longest horizon) per scene into ``DIR``, which must be absent or empty.
    Each reference runs under a step cap sized from its horizon
    (:func:`rk4h.validation.energy_time.reference_step_cap`); a run that
    reaches it (or would need more than ``STEP_CAP_CEILING``) is a row with
    status ``step_cap`` and a line on stderr. Exit 0; 1 when a reference hit
    its step cap (the rest is written); 2 on bad input (one line).
    """
    from rk4h import _heyoka

    _heyoka.own_process()  # this process is rk4h's: heyoka may come without sympy
    import argparse
    import csv
    import pathlib
    import sys

    p = argparse.ArgumentParser(prog="python -m rk4h.validation.energy_study",
                                description="energy work-precision and energy growth over long horizons")
    p.add_argument("scenes", nargs="+", help="scene files or shipped scene names (e.g. " + ", ".join(WP_SCENES) + ")")
    p.add_argument("--out", required=True, help="output folder (absent or empty)")
    p.add_argument("--periods", nargs="+", default=[str(x) for x in WP_HORIZONS],
                   help="horizons in periods of the slowest mode (default 1e2 1e4)")
    p.add_argument("--full", action="store_true", help="add the 1e6-period horizon (long)")
    p.add_argument("--steps", nargs="+", default=["8", "16", "32", "64"], help="steps per fastest period")
    p.add_argument("--references", nargs="*", default=["heyoka"],
                   help="adaptive references also run at rtol 1e-6..1e-12 (default: heyoka; none: --references)")
    a = p.parse_args(argv)
    try:
        periods = [float(x) for x in a.periods]
        steps = [int(x) for x in a.steps]
        assert all(math.isfinite(x) and x > 0 for x in periods) and all(s > 0 for s in steps)
    except (ValueError, AssertionError):
        print(f"energy_study: --periods/--steps: must be positive numbers, got {a.periods} / {a.steps}",
              file=sys.stderr)
        return 2
    from rk4h.references.registry import REFERENCES

    bad = [r for r in a.references if r not in REFERENCES]
    if bad:
        print(f"energy_study: --references: must be among {list(REFERENCES)}, got {bad[0]!r}", file=sys.stderr)
        return 2
    out = pathlib.Path(a.out)
    if out.exists() and (not out.is_dir() or any(out.iterdir())):
        print(f"energy_study: --out: {str(out)!r} exists and is not an empty folder; nothing written",
              file=sys.stderr)
        return 2
    from rk4h.validation.execute import problem
    from rk4h.validation.scenes import SceneError, load_scenes

    try:
        scenes = load_scenes(a.scenes)
    except SceneError as e:
        print(str(e).splitlines()[0], file=sys.stderr)
        return 2
    from rk4h.energy import relative_energy_error
    from rk4h.methods import RK4

    from . import energy_figures

    out.mkdir(parents=True, exist_ok=True)
    rows = []
    for scene in scenes:
        model, y0 = problem(scene)
        methods = _methods(scene)
        mine = work_precision_rows(scene.name, model, y0, methods, steps, periods, full=a.full,
                                   references=[r for r in a.references if r in scene.solvers])
        rows += mine
        energy_figures.energy_work_precision(out, scene.name, mine)
        T = max(periods + ([1e6] if a.full else [])) * slowest_period(model)
        h_rk4 = 2 * math.pi / float(np.max(model.modes()[0])) / 16
        series, ks = {}, {}
        for tab in methods:
            res, _ = long_run(model, y0, tab, equal_cost_step(tab, h_rk4, RK4.nfev_per_step), T,
                              dense_samples(model, T, cap=200_000))
            if not res.success:
                continue
            with np.errstate(all="ignore"):
                e = relative_energy_error(model, res.y)
            lab = f"{tab.name} h={res.h:.3g}"
            series[lab], ks[lab] = (res.t, np.abs(e)), growth_exponent(res.t, e)[0]
        energy_figures.energy_growth(out, scene.name, series, ks)
    with open(out / "energy_work_precision.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(dict.fromkeys(k for r in rows for k in r)) or ["scene"])
        w.writeheader()
        w.writerows(rows)
    print(f"energy_study: {len(rows)} rows and {2 * len(scenes)} figures in {out}")
    capped = [r for r in rows if r["status"] == STEP_CAP_STATUS]
    for r in capped:
        print(f"energy_study: {r['scene']}: {r['solver']} at rtol {r['rtol']:g} over {r['periods']:g} periods: "
              f"{r['message']}", file=sys.stderr)
    return 1 if capped else 0


if __name__ == "__main__":
    raise SystemExit(main())
