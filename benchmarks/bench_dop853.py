"""scipy's DOP853 (``run_dop853``) vs its compiled loop (``run_dop853_compiled``).

    python benchmarks/bench_dop853.py                      # four scenes, rtol 1e-4 ... 1e-13, 3 repeats
    python benchmarks/bench_dop853.py --scenes henon_heiles --repeats 1

For each scene (``validation/scenes/<name>.toml``, its whole horizon and output
grid, the absolute-tolerance rule of ``rk4h.references.solvers.integrate``) and
rtol, both runs are made ``--repeats`` times, alternated, after one untimed
run of each (numba compile or cache load excluded, printed apart). Printed
per row: steps and nfev of each, the largest state difference over the
state scale, the median wall times and their ratio. Last lines:

    ratio scipy/compiled total wall time (sum of the medians): X
    check rows with equal n_steps and nfev: K of N
    check max |y_scipy - y_compiled| / state scale: X
    load average before, after: ...

Unequal counts on a row are the round-off of the error estimate, amplified
through the step sizes (docs/performance.md, "DOP853 for untimed work").
"""
from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from rk4h.references.solvers import absolute_tolerance  # noqa: E402
from rk4h.references.solvers.dop853 import run_dop853, run_dop853_compiled  # noqa: E402
from rk4h.validation.execute import problem  # noqa: E402
from rk4h.validation.scenes import load_scene  # noqa: E402

SCENES = ("thesis_2dof_case1", "henon_heiles", "planar4_case2", "chain10_mode2")
RTOLS = (1e-4, 1e-7, 1e-10, 1e-13)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenes", nargs="+", default=list(SCENES))
    ap.add_argument("--repeats", type=int, default=3)
    args = ap.parse_args(argv)
    load0 = os.getloadavg()
    tot_a = tot_b = 0.0
    same = rows = 0
    worst = 0.0
    print(f"{'scene':<20} {'rtol':>7} {'steps':>13} {'nfev':>15} {'dy/scale':>9} {'scipy s':>9} {'compiled s':>10} "
          f"{'ratio':>7}")
    for name in args.scenes:
        scene = load_scene(ROOT / "validation" / "scenes" / f"{name}.toml")
        model, y0 = problem(scene)
        t = scene.t_eval()
        for rtol in RTOLS:
            atol = absolute_tolerance(model, y0, rtol)
            a, b = run_dop853(model, y0, t, rtol, atol), run_dop853_compiled(model, y0, t, rtol, atol)
            wa, wb = [], []
            for _ in range(args.repeats):
                wa.append(run_dop853(model, y0, t, rtol, atol).wall_s)
                wb.append(run_dop853_compiled(model, y0, t, rtol, atol).wall_s)
            ma, mb = float(np.median(wa)), float(np.median(wb))
            tot_a, tot_b = tot_a + ma, tot_b + mb
            dy = float(np.nanmax(np.abs(a.y - b.y)) / np.nanmax(np.abs(a.y)))
            worst = max(worst, dy)
            rows += 1
            same += (a.n_steps, a.nfev) == (b.n_steps, b.nfev)
            print(f"{name:<20} {rtol:>7.0e} {a.n_steps:>6}/{b.n_steps:<6} {a.nfev:>7}/{b.nfev:<7} {dy:>9.2e} "
                  f"{ma:>9.4f} {mb:>10.5f} {ma / mb:>7.1f}   (compile/load {b.compile_s:.2f} s)")
    print(f"ratio scipy/compiled total wall time (sum of the medians): {tot_a / tot_b:.1f}")
    print(f"check rows with equal n_steps and nfev: {same} of {rows}")
    print(f"check max |y_scipy - y_compiled| / state scale: {worst:.2e}")
    print(f"load average before, after: {load0[0]:.2f}, {os.getloadavg()[0]:.2f} on {os.cpu_count()} CPUs")
    return 0


if __name__ == "__main__":
    sys.exit(main())
