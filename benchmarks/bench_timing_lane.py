"""What a busy neighbour costs a timed run.

``run_all`` runs the timed specs (the solver runs whose wall times feed the
work-precision tables) after all untimed work, one per worker process: each
timed run has another integration beside it on a 2-core machine
(``--exclusive-timing``: one at a time, the other workers idle). This
benchmark measures the bias a neighbour leaves: the wall times of the same
timed specs, executed in one worker with the other worker idle and with it
busy integrating (RK4 and DOP853 runs of the 100-mass lattice), alternating
idle and busy rounds so that machine drift hits both alike.

Prints, per spec, the median over rounds of ``wall_s`` idle and busy and
their ratio; then the median ratio over specs and its spread (the 10th-90th
percentile of the per-spec ratios). Run::

    python benchmarks/bench_timing_lane.py [--rounds 5]
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

SCENES = ("thesis-2dof-case1", "pendulums-beats", "lattice100")


def _burn(seconds):
    """Untimed work for ``seconds``: what a neighbour worker does."""
    from rk4h.references.solvers import integrate
    from rk4h.validation.scenes import load_scenes

    scene = load_scenes(["lattice100"])[0]
    model, y0 = scene.build_model(), scene.y0()
    t = scene.t_eval()
    end, n = time.monotonic() + seconds, 0
    while time.monotonic() < end:
        integrate("rk4", model, y0, t, 0.01)
        integrate("dop853", model, y0, t[:200], 1e-8)
        n += 1
    return n


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--rounds", type=int, default=5)
    args = p.parse_args(argv)

    from rk4h.validation import engine, plan
    from rk4h.validation.scenes import load_scenes

    scenes = load_scenes(list(SCENES))
    jobs = [(sc, s) for sc, s in plan.plan_all(scenes, figures=False, repeats=3) if s.timed]
    pools = engine.LocalPools(2).start()
    try:
        for sc, s in jobs:  # warm-up: compile and fill the truth cache in the lane
            pools.lane.submit(engine._execute, sc, s, False).result()
        walls = {"idle": [], "busy": []}
        for r in range(args.rounds):
            for mode in ("idle", "busy"):
                load = None
                if mode == "busy":
                    load = pools.general.submit(_burn, 3600.0)
                    time.sleep(1.0)  # the neighbour is running
                row = [pools.lane.submit(engine._execute, sc, s, False).result().timing["wall_s"]
                       for sc, s in jobs]
                walls[mode].append(row)
                if load is not None:
                    pools.close(kill=True)  # stop the neighbour; new pools for the next round
                    pools = engine.LocalPools(2).start()
                    for sc, s in jobs[:1]:
                        pools.lane.submit(engine._execute, sc, s, False).result()
                print(f"round {r + 1}/{args.rounds} {mode}: {sum(row):.3f} s of timed runs", flush=True)
    finally:
        pools.close(kill=True)
    idle = np.median(np.array(walls["idle"]), axis=0)
    busy = np.median(np.array(walls["busy"]), axis=0)
    ratio = busy / idle
    print(f"\n{'spec':58s} {'idle s':>10s} {'busy s':>10s} {'busy/idle':>9s}")
    for (sc, s), a, b, q in zip(jobs, idle, busy, ratio):
        print(f"{s.label()[:58]:58s} {a:10.3g} {b:10.3g} {q:9.3f}")
    lo, med, hi = np.percentile(ratio, [10, 50, 90])
    big = idle > 1e-2
    print(f"\ntimed runs in the lane, busy neighbour / idle neighbour: median {med:.3f} "
          f"(10-90%: {lo:.3f}-{hi:.3f}) over {ratio.size} specs, {args.rounds} rounds; "
          f"runs above 10 ms: median {np.median(ratio[big]):.3f} over {int(big.sum())}")


if __name__ == "__main__":
    main()
