"""What the first numba batch of a process costs (issue 31): compiled, or
loaded from rk4h's on-disk cache.

    python benchmarks/bench_batch_load.py [--rounds 3]

Each round makes an empty cache directory (``RK4H_CACHE``, removed after)
and starts two fresh processes on it, each running ``rk4h.ensemble`` (numba,
RK4) on 64 instances of the thesis 2-DOF chain for 1000 steps, twice. The
first process compiles the generated loop and its ``prange`` wrapper; the
second loads both. Printed per process: seconds of the first batch
(loading included) and of the second, and whether instance 5 equals
``integrate("rk4", ...)`` on its own bit for bit. Medians over the rounds
and the load average are printed last; nothing is asserted on times.
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
import numpy as np
import rk4h
from rk4h.references.solvers import integrate
m = rk4h.make_model("chain", {"masses": [0.815, 3.099], "springs": [41.5, 138.0, 157.8]})
y0 = np.tile(m.state(np.array([0.005, 0.005])), (64, 1))
y0[:, 0] *= np.linspace(0.5, 1.5, 64)
te = np.array([0.0, 1.0])
t1 = time.perf_counter()
r = rk4h.ensemble(m, y0, (0.0, 1.0), h=0.001, method="rk4", backend="numba", t_eval=te)
t2 = time.perf_counter()
rk4h.ensemble(m, y0, (0.0, 1.0), h=0.001, method="rk4", backend="numba", t_eval=te)
t3 = time.perf_counter()
s = integrate("rk4", m, y0[5].copy(), te, 0.001)
print(json.dumps({"first": t2 - t1, "second": t3 - t2, "equal": bool(np.array_equal(r.y[5], s.y.T))}))
"""


def _child(cache: str) -> dict:
    env = dict(os.environ, RK4H_CACHE=cache)
    out = subprocess.run([sys.executable, "-c", CHILD], env=env, capture_output=True, text=True, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rounds", type=int, default=3, help="rounds, each with a fresh cache (default 3)")
    args = ap.parse_args(argv)
    if args.rounds < 1:
        print(f"bench_batch_load: `--rounds` must be >= 1, got {args.rounds}", file=sys.stderr)
        return 2
    print(f"load average {' '.join(f'{v:.2f}' for v in os.getloadavg())} on {os.cpu_count()} CPUs")
    cold, warm = [], []
    for i in range(args.rounds):
        with tempfile.TemporaryDirectory() as tmp:
            os.chmod(tmp, 0o700)
            c, w = _child(tmp), _child(tmp)
        cold.append(c["first"])
        warm.append(w["first"])
        print(f"round {i + 1}: compiled {c['first']:.3f} s (then {c['second']:.4f} s), "
              f"loaded {w['first']:.3f} s (then {w['second']:.4f} s); bit for bit {c['equal'] and w['equal']}")
    print(f"median first batch: compiled {np.median(cold):.3f} s, loaded {np.median(warm):.3f} s, "
          f"ratio {np.median(cold) / np.median(warm):.1f}")
    print(f"load average {' '.join(f'{v:.2f}' for v in os.getloadavg())}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
