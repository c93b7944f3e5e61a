"""Networks compiled like chains (issue 29): the generated RK4 loop of a
``network`` against a hand-written one (``benchmarks/_tight.py``).

    python benchmarks/bench_network.py               # about 20 s
    python benchmarks/bench_network.py --repeats 3   # quicker, noisier

Two planar networks of harmonic springs:

``network_web``
    The scene ``validation/scenes/network_web.toml``: 2 masses, 4 anchors,
    5 springs (8 state components: the straight-line loop, from the
    twenty-third round; the array loop before).
``lattice 30x30``
    900 masses (0.5 kg) on a square grid of spacing 0.1 m, springs
    (k = 40 N/m) between horizontal and vertical neighbours, each edge mass
    tied to an anchor one spacing outside the grid: 1860 springs.

For each: the generated loop (``rk4h.fast.solve_model`` with only the
final state kept, ``record_every = n``) and ``_tight.rk4_network`` (the same
arithmetic in the same order, nothing else: no output rows, no instability
test) over the same ``n`` RK4 steps from the same state; medians of
``--repeats`` runs after one untimed call (numba compile / cache load
apart), timed by the process's CPU clock. Printed: ns per spring-step of each, their ratio (target of issue
29: at most 1.5), and whether the final states are equal bit for bit. The
load average (``os.getloadavg``) is printed: timings on a shared machine
wander; read the ratio, measured in one run.
"""
from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))  # the repository, installed or not
sys.path.insert(0, str(Path(__file__).resolve().parent))

import _tight  # noqa: E402
from _timing import median_time  # noqa: E402

import rk4h  # noqa: E402
import rk4h.fast as fast  # noqa: E402


def web():
    params = {"dim": 2, "masses": [0.5, 0.8], "positions": [-0.2, 0.0, 0.2, 0.0],
              "anchors": [-0.6, 0.0, 0.0, 0.5, 0.6, 0.0, 0.0, -0.5],
              "springs": [[0, 2, 30.0], [0, 3, 20.0], [1, 4, 30.0], [1, 5, 20.0], [0, 1, 50.0]]}
    return rk4h.make_model("network", params), np.array([0.02, 0.0, -0.01, 0.015, 0.0, 0.0, 0.0, 0.0])


def lattice(side: int = 30, d: float = 0.1):
    n = side * side
    node = lambda i, j: i * side + j  # noqa: E731
    positions = [c for i in range(side) for j in range(side) for c in (j * d, i * d)]
    springs, anchors = [], []
    for i in range(side):
        for j in range(side):
            if j + 1 < side:
                springs.append([node(i, j), node(i, j + 1), 40.0])
            if i + 1 < side:
                springs.append([node(i, j), node(i + 1, j), 40.0])
    for i in range(side):
        for j in range(side):
            for di, dj in ((-1, 0), (1, 0), (0, -1), (0, 1)):
                if not (0 <= i + di < side and 0 <= j + dj < side):
                    anchors += [(j + dj) * d, (i + di) * d]
                    springs.append([node(i, j), n + len(anchors) // 2 - 1, 40.0])
    model = rk4h.make_model("network", {"dim": 2, "masses": [0.5] * n, "positions": positions,
                                           "springs": springs, "anchors": anchors})
    rng = np.random.default_rng(1)
    y0 = np.concatenate([0.01 * d * rng.standard_normal(2 * n), np.zeros(2 * n)])
    return model, y0


def compare(label, model, y0, n, h, repeats):
    X = model.X.ravel().copy()
    A = model.A.ravel().copy()
    args = (X, A, model.a.copy(), model.b.copy(), model.k.copy(), model.rest.copy(), model.mass.copy())
    gen = lambda: fast.solve_model(model, (0.0, n * h), y0, n_steps=n, record_every=n)  # noqa: E731
    res = gen()
    tight_y = _tight.rk4_network(*args, y0, res.h, n)
    t_gen = median_time(gen, repeats, time.process_time)
    t_tight = median_time(lambda: _tight.rk4_network(*args, y0, res.h, n), repeats, time.process_time)
    ns = model.k.shape[0]
    per_gen, per_tight = t_gen / (n * ns) * 1e9, t_tight / (n * ns) * 1e9
    same = np.array_equal(res.y[:, -1], tight_y)
    print(f"{label:16s} springs {ns:5d}  steps {n:7d}  generated {per_gen:7.2f} ns  tight {per_tight:7.2f} ns "
          f"per spring-step  ratio {per_gen / per_tight:5.2f} (target <= 1.5)  bit-identical {same}")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=7, help="timed runs per figure (default 7)")
    args = ap.parse_args(argv)
    if args.repeats < 1:
        print(f"bench_network: `--repeats` must be >= 1, got {args.repeats}", file=sys.stderr)
        return 2
    print(f"load average {' '.join(f'{v:.2f}' for v in os.getloadavg())} on {os.cpu_count()} CPUs")
    start = time.perf_counter()
    _tight.compile_network()
    m_web, y_web = web()
    m_lat, y_lat = lattice()
    for m, y in ((m_web, y_web), (m_lat, y_lat)):
        fast.solve_model(m, (0.0, 0.01), y, n_steps=1)
    print(f"numba compile / cache load (apart, not in any timing): {time.perf_counter() - start:.2f} s")
    compare("network_web", m_web, y_web, 200_000, 0.001, args.repeats)
    compare("lattice 30x30", m_lat, y_lat, 200, 0.001, args.repeats)
    return 0


if __name__ == "__main__":
    sys.exit(main())
