"""CPU and wall time of every unit of the stability study (rk4h.validation.stability.units).

    python benchmarks/bench_stability_units.py [--quick] [--scene NAME ...] [--fresh]

Runs the units of the shipped ``stability_*`` scenes one after the other in
this process (``--fresh``: each unit in a new interpreter, as a pool worker
that has not run anything yet would) and prints, per unit, the CPU time
(``time.process_time``, this process and its threads) and the wall time,
then the total CPU. The first unit of a process also pays one-off loads
(numba's cached kernels, heyoka's JIT, sksundae): ``--fresh`` shows them on
every unit. Nothing is drawn; the rows are discarded.
"""
from __future__ import annotations

import argparse
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

SCENES = ["stability_2dof", "stability_stiff_chain", "stability_large_n", "stability_planar4"]


def _one(name, unit, quick):
    from rk4h.validation.scenes import SCENE_DIR, load_scene
    from rk4h.validation.stability import run_unit

    scene = load_scene(SCENE_DIR / f"{name}.toml")
    c0, w0 = time.process_time(), time.perf_counter()
    res = run_unit(scene, unit, quick)
    cpu, wall = time.process_time() - c0, time.perf_counter() - w0
    bad = sum(r["status"] == "failed" or r["passed"] is False for r in res.rows)
    return cpu, wall, bad


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--scene", nargs="*", default=SCENES)
    ap.add_argument("--fresh", action="store_true", help="each unit in a new interpreter")
    ap.add_argument("--unit", help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.unit:  # child of --fresh
        cpu, wall, bad = _one(args.scene[0], args.unit, args.quick)
        print(f"{cpu} {wall} {bad}")
        return 0
    from rk4h.validation.scenes import SCENE_DIR, load_scene
    from rk4h.validation.stability import units

    total_cpu = total_wall = 0.0
    print(f"{'scene':24s} {'unit':28s} {'cpu_s':>8s} {'wall_s':>8s}  failed/false rows")
    for name in args.scene:
        for unit in units(load_scene(SCENE_DIR / f"{name}.toml"), args.quick):
            if args.fresh:
                cmd = [sys.executable, __file__, "--scene", name, "--unit", unit] + (["--quick"] if args.quick else [])
                out = subprocess.run(cmd, capture_output=True, text=True, check=True).stdout.split()
                cpu, wall, bad = float(out[0]), float(out[1]), int(out[2])
            else:
                cpu, wall, bad = _one(name, unit, args.quick)
            total_cpu += cpu
            total_wall += wall
            print(f"{name:24s} {unit:28s} {cpu:8.2f} {wall:8.2f}  {bad}", flush=True)
    print(f"{'total':53s} {total_cpu:8.2f} {total_wall:8.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
