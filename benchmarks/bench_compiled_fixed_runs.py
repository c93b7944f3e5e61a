"""Two fixed-step RK4 runs of every report, on the compiled loop against the
generic solver (issue 29): the dispersion output's wave packets and erratum
4's planar4 runs.

    python benchmarks/bench_compiled_fixed_runs.py [--rounds 5]

``rk4h.references.wavepacket.measure_group_velocity`` (the thesis lattice,
400 sites; one call per carrier of the report's ``PACKET_KP``) and
``rk4h.references.errata.errata_rows`` (whose two repaired planar4 runs step
the compiled loop) are timed ``--rounds`` times each way, alternated, in
this process after one untimed call of each way: as shipped
(``rk4h.fast.solve_model``) and with ``solve_model`` replaced by
``rk4h.solve`` on the model's numpy right-hand side (the generic path, what
both ran before). Printed per case: the median wall seconds of each way,
their ratio, and whether the two ways' results are equal (the packet's
centroid track and fitted speed; every errata row). The load average is
printed before and after. Timings depend on the machine and are never
asserted.
"""
from __future__ import annotations

import argparse
import math
import os
import statistics
import sys
import time
from contextlib import contextmanager
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))


def _generic(model, t_span, y0, **kw):
    import rk4h

    return rk4h.solve(model.rhs, t_span, y0, **kw)


@contextmanager
def generic_path():
    """``rk4h.fast.solve_model`` (where both callers look it up) replaced by the generic solver."""
    from rk4h import fast

    saved = fast.solve_model
    fast.solve_model = _generic
    try:
        yield
    finally:
        fast.solve_model = saved


def _timed(fn, rounds):
    """``(median wall s of each way, results of each way)``: ``fn()`` as shipped and on the generic path."""
    with generic_path():
        slow = fn()
    fast = fn()
    walls = {"compiled": [], "generic": []}
    for r in range(rounds):
        for way in (("compiled", "generic") if r % 2 == 0 else ("generic", "compiled")):
            t0 = time.perf_counter()
            if way == "generic":
                with generic_path():
                    fn()
            else:
                fn()
            walls[way].append(time.perf_counter() - t0)
    return {k: statistics.median(v) for k, v in walls.items()}, fast, slow


def _same_rows(a, b) -> bool:
    def same(x, y):
        if isinstance(x, float) and isinstance(y, float):
            return x == y or (math.isnan(x) and math.isnan(y))
        return x == y
    return len(a) == len(b) and all(ra.keys() == rb.keys() and all(same(ra[k], rb[k]) for k in ra)
                                    for ra, rb in zip(a, b))


def main(argv=None) -> int:
    from rk4h.references import errata, wavepacket
    from rk4h.references.dispersion import THESIS_LATTICE
    from rk4h.validation.plan import PACKET_KP

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rounds", type=int, default=5)
    args = ap.parse_args(argv)
    if args.rounds < 1:
        ap.error(f"--rounds: must be at least 1, got {args.rounds}")
    print(f"load {os.getloadavg()[0]:.2f}; medians of {args.rounds} rounds, alternated")
    d = THESIS_LATTICE["d"]
    for frac in PACKET_KP:
        kp0 = frac * math.pi / d
        med, a, b = _timed(lambda: wavepacket.measure_group_velocity(
            kp0, m=THESIS_LATTICE["m"], k=THESIS_LATTICE["k"], d=d), args.rounds)
        equal = bool(np.array_equal(a.centroid, b.centroid) and a.v_measured == b.v_measured)
        n = round(a.t_end / a.h)
        print(f"wave packet kp0 = {frac} pi/d ({a.N} sites, {n} steps): generic {med['generic']:.4f} s, "
              f"compiled {med['compiled']:.4f} s, generic / compiled = {med['generic'] / med['compiled']:.1f}; "
              f"equal: {equal}")
    med, a, b = _timed(errata.errata_rows, args.rounds)
    print(f"errata_rows (erratum 4's planar4 runs): generic {med['generic']:.4f} s, compiled {med['compiled']:.4f} s, "
          f"generic / compiled = {med['generic'] / med['compiled']:.1f}; equal: {_same_rows(a, b)}")
    print(f"load {os.getloadavg()[0]:.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
