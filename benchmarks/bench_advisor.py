"""The advisor's wall and CPU time, before and after a change, interleaved (issue 29).

    python benchmarks/bench_advisor.py --before /tmp/venv-base/bin/python          # this tree = after
    python benchmarks/bench_advisor.py --before PY --rounds 3 --scenes thesis-2dof-case1
    python benchmarks/bench_advisor.py --rounds 1                                    # this tree only

Each ``PY`` is a Python whose ``rk4h`` is the tree to measure (a virtual
environment with that checkout installed editable); ``--after`` defaults to
the Python running this script. For every round and scene (``--scenes``,
default ``thesis-2dof-case1 planar4-case2``) it runs, as a subprocess,
``PY -m rk4h.validation.advise SCENE --target T --json`` (``--target``,
default 1e-3) with before and after alternated (before, after, after,
before, ...), after one untimed warm-up call of each (truths, numba and
heyoka caches on disk; ``--no-warm-up``: none). Printed per call: wall s (``time.perf_counter``
around the subprocess), CPU s (user + system of the child,
``resource.getrusage(RUSAGE_CHILDREN)``), the 1-minute load average before
it, and the answer (method, setting). The last lines per scene are the
medians and the ratios before/after of wall and CPU time.

Timings are machine- and load-dependent and never asserted; on a shared
machine read the CPU seconds beside the wall seconds, and the load.
"""
from __future__ import annotations

import argparse
import json
import os
import resource
import statistics
import subprocess
import sys
import time


def _call(python: str, scene: str, target: str) -> tuple:
    """``(wall s, cpu s, load, answer)`` of one advisor call."""
    load = os.getloadavg()[0]
    r0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    r = subprocess.run([python, "-m", "rk4h.validation.advise", scene, "--target", target, "--json"],
                       capture_output=True, text=True)
    wall = time.perf_counter() - t0
    r1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (r1.ru_utime - r0.ru_utime) + (r1.ru_stime - r0.ru_stime)
    if r.returncode != 0:
        raise SystemExit(f"bench_advisor: {python} failed on {scene}: {r.stderr.strip()[-500:]}")
    d = json.loads(r.stdout)
    return wall, cpu, load, f"{d['method']} {d['setting_name']} = {d['setting']:.4g}"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--before", help="a Python whose rk4h is the tree before the change (omit: after only)")
    ap.add_argument("--after", default=sys.executable, help="a Python whose rk4h is the tree after (default: this one)")
    ap.add_argument("--scenes", nargs="+", default=["thesis-2dof-case1", "planar4-case2"])
    ap.add_argument("--target", default="1e-3")
    ap.add_argument("--rounds", type=int, default=2)
    ap.add_argument("--no-warm-up", action="store_true", help="skip the untimed first call (caches known warm)")
    args = ap.parse_args(argv)
    sides = [("before", args.before), ("after", args.after)] if args.before else [("after", args.after)]
    for scene in args.scenes:
        for _, py in ([] if args.no_warm_up else sides):  # warm-up: disk caches
            _call(py, scene, args.target)
        got = {name: [] for name, _ in sides}
        for k in range(args.rounds):
            order = sides if k % 2 == 0 else sides[::-1]
            for name, py in order:
                wall, cpu, load, answer = _call(py, scene, args.target)
                got[name].append((wall, cpu))
                print(f"{scene} {name:6} round {k}: {wall:7.2f} s wall {cpu:7.2f} s CPU  load {load:5.2f}  {answer}",
                      flush=True)
        med = {n: (statistics.median(w for w, _ in v), statistics.median(c for _, c in v)) for n, v in got.items()}
        for n, (w, c) in med.items():
            print(f"{scene} {n:6} median: {w:.2f} s wall, {c:.2f} s CPU")
        if args.before:
            (wb, cb), (wa, ca) = med["before"], med["after"]
            print(f"{scene} ratio before/after: wall {wb / wa:.2f}, CPU {cb / ca:.2f}")
    print(f"load average at the end: {os.getloadavg()[0]:.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
