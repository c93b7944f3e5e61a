"""The energies of a long trajectory, evaluated in blocks of columns or in one
call (``rk4h.energy.motion_energies``, issue 29).

    python benchmarks/bench_energy_blocks.py [--scenes energy-lattice,energy-fput] [--rounds 5]

For each scene: RK4 on the compiled loop over 1e4 periods of the slowest mode
at 16 steps per fastest period, 16 states kept per fastest period (the energy
work-precision output's sampling); then ``motion_energies`` of that
trajectory ``--rounds`` times with the shipped block size and as many times in
one call (``BLOCK_BYTES`` set above the trajectory's size), alternated.
Printed: the trajectory's shape and size, the median wall seconds of each
way, their ratio, the peak of numpy's temporaries of each way
(``tracemalloc``, one extra call each, not timed), and whether the two
results are equal to the bit. The load average is printed before and after.
"""
from __future__ import annotations

import argparse
import math
import os
import statistics
import sys
import time
import tracemalloc
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))


def _trajectory(name):
    from rk4h.validation.energy_time import dense_samples, long_run, slowest_period
    from rk4h.validation.execute import problem
    from rk4h.validation.scenes import load_scenes

    (scene,) = load_scenes([name])
    model, y0 = problem(scene)
    t_end = 1e4 * slowest_period(model)
    h = 2 * math.pi / float(np.max(model.modes()[0])) / 16
    res, _ = long_run(model, y0, "rk4", h, t_end, dense_samples(model, t_end))
    return model, res.y


def _peak(fn) -> float:
    tracemalloc.start()
    fn()
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    return peak / 2**20


def main():
    import rk4h.energy as EN

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenes", default="energy-lattice,energy-fput")
    ap.add_argument("--rounds", type=int, default=5)
    args = ap.parse_args()
    shipped = EN.BLOCK_BYTES
    print(f"load {os.getloadavg()[0]:.2f}")
    for name in args.scenes.split(","):
        model, y = _trajectory(name)
        whole = max(shipped, y.nbytes + 1)

        def call(size):
            EN.BLOCK_BYTES = size
            try:
                return EN.motion_energies(model, y)
            finally:
                EN.BLOCK_BYTES = shipped

        times = {shipped: [], whole: []}
        for _ in range(args.rounds):
            for size in (shipped, whole):
                t = time.perf_counter()
                call(size)
                times[size].append(time.perf_counter() - t)
        same = np.array_equal(call(shipped), call(whole))
        b, w = statistics.median(times[shipped]), statistics.median(times[whole])
        print(f"{name}: trajectory {y.shape[0]} x {y.shape[1]} ({y.nbytes / 2**20:.0f} MiB); blocks of "
              f"{shipped / 2**20:g} MiB {b:.3f} s, one call {w:.3f} s (medians of {args.rounds}): one call / "
              f"blocks = {w / b:.2f}; temporaries' peak {_peak(lambda: call(shipped)):.1f} MiB in blocks, "
              f"{_peak(lambda: call(whole)):.0f} MiB in one call; equal to the bit: {same}")
    print(f"load {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
