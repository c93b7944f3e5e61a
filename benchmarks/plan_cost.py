"""Where the report's time goes: execute the plan of every shipped scene (or
the scenes named) on 2 worker processes and sum each record's execution time
by purpose and solver, by scene, and over the timed runs.

    python benchmarks/plan_cost.py [SCENE,SCENE,...] [--quick] [--purposes P,P] [--workers N]

``--purposes``: only the specs of these purposes (``stability``,
``energy_wp``, ``run``, ...); ``--workers``: worker processes (default 2;
1 runs the plan in this process). The first line gives the runs' wall
seconds and the CPU seconds of this process and its workers
(``resource.getrusage``), the 1-minute load average before and after.
To compare two trees, run each tree's Python on the same arguments,
alternated (before, after, after, before).
"""
import argparse
import collections
import os
import resource
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))


def main():
    from rk4h.validation import budget, engine, plan
    from rk4h.validation.scenes import load_scenes

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scenes", nargs="?", help="comma-separated scene names (default: every shipped scene)")
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--purposes", help="comma-separated spec purposes to run (default: all)")
    ap.add_argument("--workers", type=int, default=2)
    args = ap.parse_args()
    quick = args.quick
    scenes = load_scenes(args.scenes.split(",") if args.scenes else None, quick=quick)
    jobs = plan.plan_all(scenes, quick=quick, figures=True, repeats=1 if quick else 3)
    if args.purposes:
        jobs = [(scene, s) for scene, s in jobs if s.purpose in args.purposes.split(",")]
    load = os.getloadavg()[0]
    t, cpu = time.perf_counter(), _cpu()
    stats = engine.PlanStats()
    recs = engine.run_plan(jobs, workers=args.workers, stats=stats, cost=budget.spec_cost_function(), quick=quick)
    print(f"runs: {len(jobs)} specs, {time.perf_counter() - t:.2f} s wall, {_cpu() - cpu:.2f} s CPU "
          f"(load {load:.2f} -> {os.getloadavg()[0]:.2f}), {stats}")
    by_kind, count, by_scene = collections.Counter(), collections.Counter(), collections.Counter()
    for scene, s in jobs:
        r = recs[s.key]
        k = (s.purpose, s.solver if s.purpose in ("run", "order", "figure", "modal") else s.unit.split(":")[0])
        by_kind[k] += r.seconds
        count[k] += 1
        by_scene[scene.name] += r.seconds
    for k, v in by_kind.most_common(20):
        print(f"{v:8.2f} s {count[k]:4d} x {k[0]} {k[1]}")
    print(f"sum of record times: {sum(by_kind.values()):.1f} s; timed runs: "
          f"{sum(recs[s.key].seconds for _, s in jobs if s.timed):.1f} s")
    for k, v in by_scene.most_common(10):
        print(f"{v:8.2f} s {k}")


def _cpu() -> float:
    """User + system CPU seconds of this process and its finished children."""
    return sum(r.ru_utime + r.ru_stime for r in (resource.getrusage(resource.RUSAGE_SELF),
                                                  resource.getrusage(resource.RUSAGE_CHILDREN)))


if __name__ == "__main__":
    main()
