"""What a figure costs to draw, per figure kind; optionally against another commit.

Draws every figure kind of ``tests/test_figure_layout.py`` (its synthetic
inputs, shaped like the shipped scenes') and prints, per kind, the median
over rounds of the CPU seconds (``time.process_time``) and the wall seconds
of its builder (one or more figures, PNG written), with the load average
before and after. Each kind is drawn once first (imports, fonts, caches).

``--against REV`` draws the same kinds with the code of commit ``REV``
(``git archive`` into a temporary directory) in a second process, rounds
alternating between the two trees so machine drift hits both alike, and
prints both medians and their ratio, and per kind the number of full
(generation-2) garbage collections that fell in its timed rounds on each
side: one costs about 0.15 s and lands on whichever kind crosses the
collector's threshold, so a kind's ratio with a collection on one side only
shows the collector, not the drawing. Each process imports ``rk4h`` from the
tree it measures (a finder of its own ahead of an editable install's, which
would map ``rk4h`` to this checkout in both processes) and checks that it did. CPU seconds are the figure to read on
a shared machine; wall seconds include what the neighbours take.
``--minor-ticks`` instead compares the log axes' minor ticks at 2 and 5 of
each decade (``rk4h.validation.figures.style.MINOR_SUBS``, the default) with
matplotlib's 2..9 in this tree. Run::

    python benchmarks/bench_figures.py [--rounds 5] [--against REV | --minor-ticks]
"""
from __future__ import annotations

import argparse
import datetime
import json
import os
import statistics
import subprocess
import sys
import tarfile
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent

#: One round in a child process: every kind once (warm), then ``rounds`` timed
#: draws of each; prints ``{kind: [[cpu, wall], ...]}`` as JSON.
_CHILD = r"""
import importlib.util, json, sys, tempfile, time
from pathlib import Path
root, rounds, minor = Path(sys.argv[1]), int(sys.argv[2]), sys.argv[3]
# rk4h from the tree under test, not from the installed one: an editable install maps rk4h to its
# own checkout whatever sys.path says, so the other commit's figures would be this checkout's
_DIRS = {"rk4h": root / "rk4core", "rk4h.references": root / "references", "rk4h.validation": root / "validation"}
class _TreeFinder:
    @staticmethod
    def find_spec(name, path=None, target=None):
        if name in _DIRS:
            return importlib.util.spec_from_file_location(name, _DIRS[name] / "__init__.py",
                                                          submodule_search_locations=[str(_DIRS[name])])
        return None
sys.meta_path.insert(0, _TreeFinder)
sys.path[:0] = [str(root / "tests")]
import rk4h.validation.figures.style
assert Path(rk4h.validation.figures.style.__file__).resolve().is_relative_to(root.resolve()), \
    f"rk4h comes from {rk4h.validation.figures.style.__file__}, not from {root}"
import test_figure_layout as layout
if minor != "default":
    from rk4h.validation.figures import style
    style.MINOR_SUBS = None if minor == "2..9" else (2.0, 5.0)
import gc
full = [0]  # generation-2 (full) collections: ~0.15 s each, landing on whichever kind crosses the threshold
gc.callbacks.append(lambda phase, info: full.__setitem__(0, full[0] + (phase == "stop" and info["generation"] == 2)))
out = {}
with tempfile.TemporaryDirectory(prefix="rk4h-bench-figures-") as tmp:
    tmp = Path(tmp)
    if sys.argv[4] == "warm":
        for build in layout.BUILDERS.values():
            build(tmp)
    for _ in range(rounds):
        for kind, build in layout.BUILDERS.items():
            c0, w0, g0 = time.process_time(), time.perf_counter(), full[0]
            build(tmp)
            out.setdefault(kind, []).append([time.process_time() - c0, time.perf_counter() - w0, full[0] - g0])
print(json.dumps(out))
"""


def _child(root: Path, minor: str = "default", rounds: int = 1, warm: bool = True) -> dict:
    env = {**os.environ, "PYTHONPATH": str(root), "MPLBACKEND": "Agg"}
    res = subprocess.run([sys.executable, "-c", _CHILD, str(root), str(rounds), minor, "warm" if warm else "cold"],
                         cwd=root, env=env, capture_output=True, text=True, check=False)
    if res.returncode != 0:
        raise SystemExit(f"the figure builds of {root} failed:\n{res.stderr[-2000:]}")
    return json.loads(res.stdout.strip().splitlines()[-1])


def _export(rev: str, dest: Path) -> Path:
    """The tree of commit ``rev`` (``git archive``) under ``dest``."""
    data = subprocess.run(["git", "-C", str(REPO), "archive", rev], capture_output=True, check=True).stdout
    tar = dest / "tree.tar"
    tar.write_bytes(data)
    with tarfile.open(tar) as tf:
        tf.extractall(dest / "tree", filter="data")
    return dest / "tree"


def _merge(into: dict, part: dict) -> None:
    for kind, rows in part.items():
        into.setdefault(kind, []).extend(rows)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rounds", type=int, default=5)
    group = ap.add_mutually_exclusive_group()
    group.add_argument("--against", metavar="REV", help="compare with the figures of commit REV")
    group.add_argument("--minor-ticks", action="store_true", help="compare minor ticks at 2,5 with 2..9")
    args = ap.parse_args(argv)
    head = subprocess.run(["git", "-C", str(REPO), "rev-parse", "--short", "HEAD"], capture_output=True,
                          text=True, check=False).stdout.strip() or "?"
    print(f"# {datetime.datetime.now(datetime.timezone.utc):%Y-%m-%d %H:%M} UTC, tree {REPO} (HEAD {head}), "
          f"{args.rounds} rounds, load average before {os.getloadavg()[0]:.2f}")
    with tempfile.TemporaryDirectory(prefix="rk4h-bench-figures-") as tmp:
        if args.against:
            sides = {args.against: (_export(args.against, Path(tmp)), "default"), "this tree": (REPO, "default")}
        elif args.minor_ticks:
            sides = {"minor 2..9": (REPO, "2..9"), "minor 2,5": (REPO, "2,5")}
        else:
            sides = {"this tree": (REPO, "default")}
        times = {name: {} for name in sides}
        if len(sides) == 1:  # one process: warm once, then the rounds
            _merge(times["this tree"], _child(REPO, rounds=args.rounds))
        else:
            for r in range(args.rounds):  # alternate the sides, each round in a fresh process
                for name, (root, minor) in (sides.items() if r % 2 == 0 else reversed(sides.items())):
                    _merge(times[name], _child(root, minor))
    names = list(sides)
    kinds = list(times[names[-1]])
    cols = "".join(f" {n[:16] + ' cpu':>21s} {'wall':>7s}" for n in names)
    print(f"{'figure kind':24s}{cols}" + (f" {'cpu ratio':>9s}" if len(names) == 2 else "")
          + "  full gc")
    total = {n: [0.0, 0.0] for n in names}
    for kind in kinds:
        line = f"{kind:24s}"
        med = {}
        for n in names:
            rows = times[n].get(kind)
            if not rows:
                line += f" {'-':>21s} {'-':>7s}"
                continue
            med[n] = (statistics.median(r[0] for r in rows), statistics.median(r[1] for r in rows))
            total[n][0] += med[n][0]
            total[n][1] += med[n][1]
            line += f" {med[n][0]:21.3f} {med[n][1]:7.3f}"
        if len(names) == 2 and len(med) == 2:
            line += f" {med[names[1]][0] / med[names[0]][0]:9.2f}"
        # full collections in all rounds of the kind, per side: a kind that had one on one side only
        # differs by that (~0.15 s), not by its drawing
        line += "  " + "/".join(str(sum(r[2] for r in times[n].get(kind, []) if len(r) > 2)) for n in names)
        print(line)
    line = f"{'sum of medians':24s}" + "".join(f" {total[n][0]:21.2f} {total[n][1]:7.2f}" for n in names)
    if len(names) == 2:
        line += f" {total[names[1]][0] / total[names[0]][0]:9.2f}"
    print(line)
    print(f"# load average after {os.getloadavg()[0]:.2f}; {time.strftime('%H:%M', time.gmtime())} UTC")
    return 0


if __name__ == "__main__":
    sys.exit(main())
