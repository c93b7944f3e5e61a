"""Where the report's time goes: execute the plan of every shipped scene (or
the scenes named) on 2 worker processes and sum each record's execution time
by purpose and solver, by scene, and over the timed runs.

    python benchmarks/plan_cost.py [SCENE,SCENE,...] [--quick] [--purposes P,P] [--workers N] [--ledger]

``--purposes``: only the specs of these purposes (``stability``,
``energy_wp``, ``run``, ...); ``--workers``: worker processes (default 2;
1 runs the plan in this process). The first line gives the runs' wall
seconds and the CPU seconds of this process and its workers
(``resource.getrusage``), the 1-minute load average before and after.
To compare two trees, run each tree's Python on the same arguments,
alternated (before, after, after, before).

``--ledger`` (in this process: ``--workers 1``) also records every call of
``rk4h.references.solvers.integrate`` and ``integrate_compiled`` (their
common ``_integrate``) with the spec it ran for and its CPU seconds
(``time.process_time``), and prints them by purpose and solver, the timed
rows' first runs apart from their timing repeats, and the integrations
made with the same inputs (solver, model and its parameters, initial state,
output times, setting, ``atol``) by more than one spec: work the plan
could share.
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
    ap.add_argument("--ledger", action="store_true", help="every integration, by purpose and solver (--workers 1)")
    args = ap.parse_args()
    if args.ledger and args.workers != 1:
        ap.error(f"--ledger: needs --workers 1 (the integrations are recorded in this process), got {args.workers}")
    ledger = _Ledger() if args.ledger else None
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
    if ledger is not None:
        ledger.report()


class _Ledger:
    """Every ``_integrate`` call of this process: ``(purpose, spec key, solver, inputs digest, CPU s)``."""

    def __init__(self):
        import hashlib

        import numpy as np

        import rk4h.references.solvers as solvers
        import rk4h.validation.execute as execute

        self.entries, spec = [], [("-", "-")]
        inner, run_spec = solvers._integrate, execute.execute

        def digest(solver, model, y0, t_eval, setting, atol):
            h = hashlib.sha256()
            try:
                params = model.params()
            except Exception:  # noqa: BLE001 - a model without plain parameters (a function): its identity
                params = id(model)
            for part in (getattr(solver, "name", solver), type(model).__name__, params, setting, atol):
                h.update(repr(part).encode())
            for a in (y0, t_eval):
                h.update(np.asarray(a, float).tobytes())
            return h.hexdigest()[:16]

        def _integrate(solver, model, y0, t_eval, setting, atol, max_steps, runners):
            t0 = time.process_time()
            try:
                return inner(solver, model, y0, t_eval, setting, atol, max_steps, runners)
            finally:
                self.entries.append((*spec[0], str(getattr(solver, "name", solver)),
                                     digest(solver, model, y0, t_eval, setting, atol), time.process_time() - t0))

        def execute_spec(scene, s, quick=False):
            spec[0] = (s.purpose, s.key)
            return run_spec(scene, s, quick)

        solvers._integrate, execute.execute = _integrate, execute_spec

    def report(self):
        E = self.entries
        print(f"ledger: {len(E)} integrations, {sum(e[4] for e in E):.1f} s CPU")
        by = collections.Counter()
        n = collections.Counter()
        for purpose, _, solver, _, cpu in E:
            by[(purpose, solver)] += cpu
            n[(purpose, solver)] += 1
        for (purpose, solver), v in by.most_common(15):
            print(f"{v:8.2f} s {n[(purpose, solver)]:5d} x {purpose} {solver}")
        first, repeats, seen = 0.0, 0.0, set()
        for purpose, key, solver, d, cpu in E:
            if purpose == "run":
                if (key, d) in seen:
                    repeats += cpu
                else:
                    seen.add((key, d))
                    first += cpu
        print(f"timed rows (purpose run): first runs {first:.1f} s CPU, timing repeats {repeats:.1f} s CPU")
        specs, cpus = collections.defaultdict(set), collections.defaultdict(list)
        for purpose, key, solver, d, cpu in E:
            specs[(solver, d)].add(key)
            cpus[(solver, d)].append(cpu)
        shared = {k: v for k, v in specs.items() if len(v) > 1}
        extra = sum(sum(cpus[k]) - max(cpus[k]) for k in shared)
        print(f"same inputs in more than one spec: {len(shared)} integrations, {extra:.2f} s CPU beyond one run each")
        for k in sorted(shared, key=lambda k: -sum(cpus[k]))[:10]:
            print(f"    {sum(cpus[k]):8.3f} s {len(cpus[k])} runs {k[0]} in {len(shared[k])} specs")


def _cpu() -> float:
    """User + system CPU seconds of this process and its finished children."""
    return sum(r.ru_utime + r.ru_stime for r in (resource.getrusage(resource.RUSAGE_SELF),
                                                  resource.getrusage(resource.RUSAGE_CHILDREN)))


if __name__ == "__main__":
    main()
