"""CVODE driven by one ``solve`` call vs the Python loop of ``CV_ONE_STEP`` calls (issue 12).

    python benchmarks/bench_cvode.py                 # the three scenes below, 5 repeats
    python benchmarks/bench_cvode.py --tiny          # same code, t_end 5 s, 2 repeats (seconds)
    git show <commit>:references/solvers/cvode.py > /tmp/old_cvode.py
    python benchmarks/bench_cvode.py --old /tmp/old_cvode.py   # "old" = that file's run_cvode

For every CVODE solver and tolerance of each scene (``--scenes``, default
``thesis_2dof_case1 lattice100 pendulums_beats``), on the scene's own output
grid and absolute-tolerance rule (``rk4h.references.solvers.integrate``'s), it runs

- new: ``rk4h.references.solvers.cvode.run_cvode`` (one ``CVODE.solve`` call), and
- old: the one-step loop, ``cvode._run_cvode(..., one_step_loop=True)`` (the
  fallback kept in the module), or ``run_cvode`` of the file given by ``--old``,

``--repeats`` times each, alternated (old, new, old, new, ...), after one
untimed warm-up run of each. Printed per row: ``error_max`` of each against
the scene's truth (``rk4h.references.truth``, exact-modal or real128; the disk
cache is used), n_steps, nfev, the median wall time (``wall_s``: the
integration only) of each with its spread (min-max) and the ratio old/new.
The last lines are the results:

    ratio old/new total wall time (sum of the medians): X
    ratio old/new wall time per row: median X, min X, max X
    check same n_steps and nfev: True/False
    check max |y_old - y_new| / state scale: X
    check max error_max ratio new/old: X

The one-step loop of the module takes the same internal steps as ``solve``,
so the ``check`` lines must show equal counters and identical trajectories
(0.0); against an older file (``--old``) whose loop aimed its first step at
``t_end`` rather than at the first output time, the first step differs and so
do the counters, a little, and the trajectories, within the tolerance.
Timings are machine- and load-dependent and never asserted.
"""
from __future__ import annotations

import argparse
import importlib.util
import math
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))  # the repository, installed or not

from rk4h.references.solvers import absolute_tolerance  # noqa: E402
from rk4h.references.solvers import cvode  # noqa: E402
from rk4h.references.truth import reference_solution  # noqa: E402
from rk4h.validation import metrics  # noqa: E402
from rk4h.validation.scenes import SCENE_DIR, load_scene  # noqa: E402

SCENES = ("thesis_2dof_case1", "lattice100", "pendulums_beats")
CVODE = ("cvode-adams", "cvode-bdf")


def load_old(path):
    """``run_cvode`` of an older ``references/solvers/cvode.py`` (its relative
    imports resolved inside ``rk4h.references.solvers``)."""
    spec = importlib.util.spec_from_file_location("rk4h.references.solvers._cvode_old", path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod.run_cvode


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenes", nargs="+", default=list(SCENES))
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--tiny", action="store_true", help="t_end 5 s, 2 repeats")
    ap.add_argument("--old", default=None, help="an older cvode.py whose run_cvode is 'old'")
    args = ap.parse_args(argv)
    repeats = 2 if args.tiny else args.repeats

    new = cvode.run_cvode
    if args.old:
        old = load_old(args.old)
        old_name = f"run_cvode of {args.old}"
    else:
        def old(solver, model, y0, t, rtol, atol):
            return cvode._run_cvode(solver, model, y0, t, rtol, atol, cvode.DEFAULT_MAX_STEPS,
                                    one_step_loop=True)
        old_name = "the one-step loop (cvode._run_cvode(..., one_step_loop=True))"
    print(f"old: {old_name}\nnew: cvode.run_cvode (one CVODE.solve call)\nrepeats: {repeats} (median)")

    rows = []
    for name in args.scenes:
        scene = load_scene(SCENE_DIR / f"{name}.toml")
        model, y0, t = scene.build_model(), scene.y0(), scene.t_eval()
        if args.tiny:
            t = t[t <= 5.0]
        y_ref = np.asarray(reference_solution(model, y0, t).y, float)
        scale = float(np.max(np.abs(y_ref)))
        print(f"\n{scene.name}: {model.n_dof} DOF, {t.size} outputs to t = {t[-1]:g} s")
        print(f"{'solver':12s} {'rtol':>7s} {'err old':>9s} {'err new':>9s} {'steps old':>9s} {'steps new':>9s} "
              f"{'nfev old':>9s} {'nfev new':>9s} {'wall old (spread)':>22s} {'wall new (spread)':>22s} "
              f"{'old/new':>7s}")
        for solver in [s for s in scene.solvers if s in CVODE]:
            for rtol in scene.tolerances:
                atol = absolute_tolerance(model, y0, rtol)
                first = {"old": old(solver, model, y0, t, rtol, atol),  # warm-up, untimed
                         "new": new(solver, model, y0, t, rtol, atol)}
                walls = {"old": [], "new": []}
                for _ in range(repeats):
                    for which, fn in (("old", old), ("new", new)):
                        walls[which].append(fn(solver, model, y0, t, rtol, atol).wall_s)
                r_old, r_new = first["old"], first["new"]
                med = {w: float(np.median(v)) for w, v in walls.items()}
                row = dict(scene=scene.name, solver=solver, rtol=rtol,
                           err_old=metrics.error_max(r_old.y, y_ref), err_new=metrics.error_max(r_new.y, y_ref),
                           steps=(r_old.n_steps, r_new.n_steps), nfev=(r_old.nfev, r_new.nfev),
                           status=(r_old.status.value, r_new.status.value),
                           dy=float(np.max(np.abs(r_old.y - r_new.y))) / scale,
                           wall_old=med["old"], wall_new=med["new"], ratio=med["old"] / med["new"])
                rows.append(row)
                spread = {w: f"{min(v):.4f}-{max(v):.4f}" for w, v in walls.items()}
                print(f"{solver:12s} {rtol:7.0e} {row['err_old']:9.2e} {row['err_new']:9.2e} "
                      f"{r_old.n_steps:9d} {r_new.n_steps:9d} {r_old.nfev:9d} {r_new.nfev:9d} "
                      f"{med['old']:8.4f} ({spread['old']:>13s}) {med['new']:8.4f} ({spread['new']:>13s}) "
                      f"{row['ratio']:7.2f}" + ("" if row["status"] == ("ok", "ok") else f"  status {row['status']}"),
                      flush=True)

    ratios = [r["ratio"] for r in rows]
    total = sum(r["wall_old"] for r in rows) / sum(r["wall_new"] for r in rows)
    err_ratio = max((r["err_new"] / r["err_old"] for r in rows if r["err_old"] > 0), default=math.nan)
    print()
    print(f"ratio old/new total wall time (sum of the medians): {total:.2f}")
    print(f"ratio old/new wall time per row: median {np.median(ratios):.2f}, min {min(ratios):.2f}, "
          f"max {max(ratios):.2f}")
    same = all(r["steps"][0] == r["steps"][1] and r["nfev"][0] == r["nfev"][1] for r in rows)
    print(f"check same n_steps and nfev: {same}")
    print(f"check max |y_old - y_new| / state scale: {max(r['dy'] for r in rows):.3g}")
    print(f"check max error_max ratio new/old: {err_ratio:.3g}")


if __name__ == "__main__":
    t0 = time.perf_counter()
    main()
    print(f"(benchmark took {time.perf_counter() - t0:.0f} s)")
