"""Where the report's time goes: execute the plan of every shipped scene (or
the scenes named) on 2 worker processes and sum each record's execution time
by purpose and solver, by scene, and over the timed runs.

    python benchmarks/plan_cost.py [SCENE,SCENE,...] [--quick]
"""
import collections
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))


def main():
    from rk4h.validation import budget, engine, plan
    from rk4h.validation.scenes import load_scenes

    args = [a for a in sys.argv[1:] if not a.startswith("--")]
    quick = "--quick" in sys.argv
    scenes = load_scenes(args[0].split(",") if args else None, quick=quick)
    jobs = plan.plan_all(scenes, quick=quick, figures=True, repeats=1 if quick else 3)
    t = time.perf_counter()
    stats = engine.PlanStats()
    recs = engine.run_plan(jobs, workers=2, stats=stats, cost=budget.spec_cost_function(), quick=quick)
    print(f"runs: {time.perf_counter() - t:.1f} s wall, {stats}")
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


if __name__ == "__main__":
    main()
