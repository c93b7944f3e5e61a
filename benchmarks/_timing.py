"""The benchmarks' one timing rule: the median of repeated calls after one
untimed call (which compiles, loads caches, warms the memory)."""
from __future__ import annotations

import statistics
import time

__all__ = ["median_time"]


def median_time(fn, repeats: int, clock=time.perf_counter) -> float:
    """Median time (s, by ``clock``: the wall clock by default,
    ``time.process_time`` for the process's CPU clock, which other processes
    inflate less) of ``repeats`` calls of ``fn`` after one untimed call."""
    fn()
    times = []
    for _ in range(repeats):
        start = clock()
        fn()
        times.append(clock() - start)
    return float(statistics.median(times))
