"""One child process, timed: what four benchmarks (bench_advisor,
bench_user_scene, bench_cold, bench_workers) measure of each run."""
from __future__ import annotations

import os
import resource
import subprocess
import time


def timed_run(argv, **kwargs) -> tuple:
    """``(completed process, wall s, CPU s, 1-minute load before)`` of
    ``subprocess.run(argv, capture_output=True, text=True, **kwargs)``.

    Wall: ``time.perf_counter`` around the call. CPU: user + system time of
    the child and its own children (``getrusage(RUSAGE_CHILDREN)`` before
    and after; a worker pool's processes count once they have been waited
    for). Load: ``os.getloadavg()[0]`` just before the start."""
    load = os.getloadavg()[0]
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    proc = subprocess.run(argv, capture_output=True, text=True, **kwargs)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return proc, wall, cpu, load
