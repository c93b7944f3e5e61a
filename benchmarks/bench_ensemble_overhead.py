"""The fixed cost of one ``rk4h.ensemble`` call: a large batch for a few steps.

    python benchmarks/bench_ensemble_overhead.py [--B 1e6] [--steps 2] [--backends numba jax] [--repeats 7]

What a call costs beyond its steps: checking ``y0``, the per-instance growth
bounds and parameters, the chunks, the output arrays, and for jax the
transfers. On a GPU this is what stands between the kernel (about 4 us per
step at B = 1e6 on an H200) and a figure per instance-step, so it is timed on
its own here. The 2-DOF chain of bench_ensemble.py, RK4, h = 1e-3 s,
``t_eval = [t0, t1]``; the median of ``--repeats`` calls after one untimed
warm-up, with the load average. Compare two trees by running this file from
each, alternately.
"""
from __future__ import annotations

import argparse
import os
import pathlib
import statistics
import sys
import time

import numpy as np

import rk4h

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
from bench_ensemble import MASSES, SPRINGS  # noqa: E402 - the same 2-DOF case


def per_call(backend: str, B: int, steps: int, repeats: int, h: float = 1e-3) -> list[float]:
    """Seconds per call, each of ``repeats`` calls after one warm-up."""
    model = rk4h.make_model("chain", {"masses": MASSES, "springs": SPRINGS})
    y0 = np.random.default_rng(1).uniform(-0.005, 0.005, (B, 4))
    t1 = steps * h

    def call():
        return rk4h.ensemble(model, y0, (0.0, t1), h=h, t_eval=[0.0, t1], backend=backend)

    assert (call().status == 0).all()
    out = []
    for _ in range(repeats):
        t = time.perf_counter()
        call()
        out.append(time.perf_counter() - t)
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--B", type=float, default=1e6)
    ap.add_argument("--steps", type=int, default=2)
    ap.add_argument("--backends", nargs="+", default=["numba"], choices=["numba", "jax"])
    ap.add_argument("--repeats", type=int, default=7)
    a = ap.parse_args(argv)
    for backend in a.backends:
        ts = per_call(backend, int(a.B), a.steps, a.repeats)
        print(f"{backend}: B = {a.B:.0e}, {a.steps} steps: median {statistics.median(ts) * 1e3:.1f} ms per call "
              f"(min {min(ts) * 1e3:.1f}, max {max(ts) * 1e3:.1f}; {a.repeats} calls), "
              f"load average {os.getloadavg()[0]:.2f}", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
