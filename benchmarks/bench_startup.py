"""What a fresh process pays to load the registry and the quick scenes.

    python benchmarks/bench_startup.py [--rounds 3]

Each round starts a fresh interpreter that times, with its CPU clock
(``time.process_time``): ``import numpy``, ``import
rk4h.references.registry``, importing ``rk4h.validation.scenes`` and
``load_scenes(quick=True)``. Prints each round and the medians, with the
load average; nothing is asserted.
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys

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
s = load_scenes(quick=True)
t4 = time.process_time()
print(json.dumps({"numpy": t1 - t0, "registry": t2 - t1, "scenes_import": t3 - t2, "load_quick": t4 - t3,
                  "total": t4 - t0, "scenes": len(s)}))
"""


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rounds", type=int, default=3, help="fresh processes (default 3)")
    args = ap.parse_args(argv)
    if args.rounds < 1:
        print(f"bench_startup: `--rounds` must be >= 1, got {args.rounds}", file=sys.stderr)
        return 2
    print(f"load average {' '.join(f'{v:.2f}' for v in os.getloadavg())} on {os.cpu_count()} CPUs; CPU seconds")
    runs = []
    for i in range(args.rounds):
        out = subprocess.run([sys.executable, "-c", CHILD], capture_output=True, text=True, check=True)
        r = json.loads(out.stdout.strip().splitlines()[-1])
        runs.append(r)
        print(f"round {i + 1}: " + ", ".join(f"{k} {v:.2f}" for k, v in r.items() if k != "scenes")
              + f" ({r['scenes']} quick scenes)")
    keys = ("numpy", "registry", "scenes_import", "load_quick", "total")
    print("median: " + ", ".join(f"{k} {np.median([r[k] for r in runs]):.2f}" for k in keys))
    return 0


if __name__ == "__main__":
    sys.exit(main())
