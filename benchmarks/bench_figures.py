"""What a figure costs to draw, per figure kind, and what the log axes' minor
ticks cost.

Draws every figure kind of ``tests/test_figure_layout.py`` (its synthetic
inputs, shaped like the shipped scenes') with the log axes' minor ticks at
2 and 5 of each decade (``validation.figures.style.MINOR_SUBS``, the default) and at
matplotlib's 2..9, alternating the two settings round by round so machine
drift hits both alike. Prints, per kind, the median seconds per call of its
builder (one or more figures, PNG written) under each setting and their
ratio, then the median ratio over kinds and the total. Run::

    python benchmarks/bench_figures.py [--rounds 5]
"""
from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO))
sys.path.insert(0, str(REPO / "tests"))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rounds", type=int, default=5)
    args = ap.parse_args(argv)
    import test_figure_layout as layout  # the synthetic inputs of every figure kind

    from validation.figures import style

    settings = {"2,5": (2.0, 5.0), "2..9": None}
    times = {(k, s): [] for k in layout.BUILDERS for s in settings}
    with tempfile.TemporaryDirectory(prefix="rk4h-bench-figures-") as tmp:
        out = Path(tmp)
        for kind, build in layout.BUILDERS.items():  # warm: imports, fonts, caches
            build(out)
        for _ in range(args.rounds):
            for name, subs in settings.items():
                style.MINOR_SUBS = subs
                for kind, build in layout.BUILDERS.items():
                    t0 = time.perf_counter()
                    build(out)
                    times[(kind, name)].append(time.perf_counter() - t0)
    print(f"{'figure kind':28s} {'2,5 (s)':>9s} {'2..9 (s)':>9s} {'ratio':>6s}")
    ratios, tot = [], {s: 0.0 for s in settings}
    for kind in layout.BUILDERS:
        a, b = (statistics.median(times[(kind, s)]) for s in settings)
        tot["2,5"] += a
        tot["2..9"] += b
        ratios.append(b / a)
        print(f"{kind:28s} {a:9.3f} {b:9.3f} {b / a:6.2f}")
    print(f"median ratio 2..9 / 2,5 over {len(ratios)} kinds: {statistics.median(ratios):.2f}; "
          f"sum of medians {tot['2,5']:.2f} s vs {tot['2..9']:.2f} s ({args.rounds} rounds)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
