"""The exact stability boundaries of every built-in method, timed.

    python benchmarks/bench_axis_boundaries.py
    /path/to/other/venv/bin/python benchmarks/bench_axis_boundaries.py   # another tree's rk4h

For each method of ``rk4h.methods.METHODS``: the CPU seconds
(``time.process_time``) of ``rk4h.stability_function._imaginary_axis_boundary``
(worked out in exact arithmetic, never read from the shipped table), and the
boundary's ``repr``; then the total and the load average. Run it under two
trees' Pythons to compare both the times and the values (the values must be
equal, repr for repr).
"""
from __future__ import annotations

import os
import sys
import time


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if argv:
        print(f"bench_axis_boundaries.py takes no arguments, got {' '.join(argv)!r}", file=sys.stderr)
        return 2
    from rk4h import stability_function as sf
    from rk4h.methods import METHODS

    print(f"load average {os.getloadavg()[0]:.2f}; rk4h from {sf.__file__}")
    total = 0.0
    for name, tab in sorted(METHODS.items()):
        t0 = time.process_time()
        value = sf._imaginary_axis_boundary(tab)
        dt = time.process_time() - t0
        total += dt
        print(f"{name:18s} {dt:7.3f} s  imaginary-axis boundary {value!r}")
    print(f"total {total:.2f} s CPU")
    return 0


if __name__ == "__main__":
    sys.exit(main())
