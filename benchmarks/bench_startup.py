"""What a fresh process pays to load the registry and the quick scenes, and
what a worker pays to receive a scene.

    python benchmarks/bench_startup.py [--rounds 3]
    python benchmarks/bench_startup.py --before /tmp/venv-base/bin/python --rounds 5   # this tree = after

Each round starts a fresh interpreter that times, with its CPU clock
(``time.process_time``): ``import numpy``, ``import
rk4h.references.registry``, importing ``rk4h.validation.scenes``,
loading thesis-2dof-case1 (``load_one``: the scene an advisor call loads,
with the schema's first use) and then ``load_scenes(quick=True)``
(``load_quick``: the other quick scenes' models and variants). A second
fresh interpreter does what a spawned worker process of ``run_all.py`` does
before its first run: imports what ``run_all.py`` imports at its top
(``worker_main``: the spawn start method runs the parent's main module
again), ``engine._worker_init()`` and ``engine._warm()`` (``worker_warm``:
the modules a run needs, heyoka's start), then unpickles the quick scenes
(``unpickle``: its jobs' scenes; the pickle is written by the same Python
first, untimed); ``worker`` is that process's CPU time in all, its
interpreter's start included.

``--before PY``: a Python whose ``rk4h`` is the tree to compare with (a
virtual environment with that checkout installed); rounds alternate before
and after (before, after, after, before, ...) and the medians and their
ratios before/after are printed. Prints each round with the load average;
nothing is asserted. Python's bytecode cache is used as the interpreter
finds it (``PYTHONDONTWRITEBYTECODE=1`` makes every process compile the
package's sources again: read the figures of a run without it).
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile

import numpy as np

CHILD = r"""
import json, time
t0 = time.process_time()
import numpy
t1 = time.process_time()
import rk4h.references.registry
t2 = time.process_time()
from rk4h.validation.scenes import load_scenes
t3 = time.process_time()
load_scenes(["thesis-2dof-case1"])
t4 = time.process_time()
s = load_scenes(quick=True)
t5 = time.process_time()
print(json.dumps({"numpy": t1 - t0, "registry": t2 - t1, "scenes_import": t3 - t2, "load_one": t4 - t3,
                  "load_quick": t5 - t4, "total": t5 - t0, "scenes": len(s)}))
"""

DUMP = r"""
import pickle, sys
from rk4h.validation.scenes import load_scenes
open(sys.argv[1], "wb").write(pickle.dumps(load_scenes(quick=True)))
"""

UNPICKLE = r"""
import json, pickle, sys, time
t0 = time.process_time()
import rk4h.validation.runner
t1 = time.process_time()
from rk4h.validation import engine
engine._worker_init()
engine._warm()
t2 = time.process_time()
s = pickle.loads(open(sys.argv[1], "rb").read())
t3 = time.process_time()
print(json.dumps({"worker_main": t1 - t0, "worker_warm": t2 - t1, "unpickle": t3 - t2, "worker": t3}))
"""

KEYS = ("numpy", "registry", "scenes_import", "load_one", "load_quick", "total", "worker_main", "worker_warm",
        "unpickle", "worker")


def _round(python: str, blob: str) -> dict:
    out = subprocess.run([python, "-c", CHILD], capture_output=True, text=True, check=True)
    r = json.loads(out.stdout.strip().splitlines()[-1])
    out = subprocess.run([python, "-c", UNPICKLE, blob], capture_output=True, text=True, check=True)
    r.update(json.loads(out.stdout.strip().splitlines()[-1]))
    return r


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rounds", type=int, default=3, help="fresh processes per tree (default 3)")
    ap.add_argument("--before", metavar="PY", help="Python of the tree to compare with (rounds alternate)")
    args = ap.parse_args(argv)
    if args.rounds < 1:
        print(f"bench_startup: `--rounds` must be >= 1, got {args.rounds}", file=sys.stderr)
        return 2
    trees = {"after": sys.executable} if args.before is None else {"before": args.before, "after": sys.executable}
    print(f"load average {' '.join(f'{v:.2f}' for v in os.getloadavg())} on {os.cpu_count()} CPUs; CPU seconds")
    runs = {k: [] for k in trees}
    with tempfile.TemporaryDirectory() as tmp:
        blobs = {}
        for k, py in trees.items():
            blobs[k] = os.path.join(tmp, f"{k}.pkl")
            subprocess.run([py, "-c", DUMP, blobs[k]], capture_output=True, text=True, check=True)
        for i in range(args.rounds):
            order = list(trees) if i % 2 == 0 else list(reversed(trees))
            for k in order:
                r = _round(trees[k], blobs[k])
                runs[k].append(r)
                print(f"round {i + 1} {k}: " + ", ".join(f"{key} {r[key]:.3f}" for key in KEYS)
                      + f" ({r['scenes']} quick scenes; load {os.getloadavg()[0]:.2f})")
    med = {k: {key: float(np.median([r[key] for r in runs[k]])) for key in KEYS} for k in trees}
    for k in trees:
        print(f"median {k}: " + ", ".join(f"{key} {med[k][key]:.3f}" for key in KEYS))
    if args.before is not None:
        print("ratio before/after: " + ", ".join(
            f"{key} {med['before'][key] / med['after'][key]:.2f}" if med["after"][key] > 0 else f"{key} -"
            for key in KEYS))
    return 0


if __name__ == "__main__":
    sys.exit(main())
