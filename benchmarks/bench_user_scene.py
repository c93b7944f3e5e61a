"""A user's small scene end to end: wall and CPU seconds, before and after a change, interleaved (issue 29).

    python benchmarks/bench_user_scene.py                                  # the README's own scene, this tree
    python benchmarks/bench_user_scene.py --before /tmp/venv-base/bin/python --rounds 3
    python benchmarks/bench_user_scene.py --scene validation/scenes/three_blocks.toml --rounds 3

The scene is the README's "your own scene" (the first TOML block of
README.md holding ``name = ``: a 3-mass chain with the default outputs),
written to a temporary folder, or the file ``--scene``. Each round runs, as
a subprocess, ``PY -m rk4h.validation.run_all --scene FILE --out DIR`` (a
fresh ``DIR`` each time) for ``--before`` and ``--after`` (default: the
Python running this script), alternated (before, after, after, before,
...), after one untimed warm-up call of each (numba's and the truths'
caches on disk). Each ``PY`` is a Python whose ``rk4h`` is the tree to
measure (a virtual environment with that checkout installed editable).

Printed per call: wall s (``time.perf_counter`` around the subprocess), CPU
s (user + system of the child, ``resource.getrusage(RUSAGE_CHILDREN)``), the
1-minute load average before it, and the run's own phase line (plan, runs,
measure, figures, write: wall seconds inside the process; what is left of
the wall time is the interpreter's start, the imports and the scene's
load). The last lines are the medians and the ratios before/after. Timings
depend on the machine and its load and are never asserted.
"""
from __future__ import annotations

import argparse
import os
import re
import statistics
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))  # the benchmarks' own helpers
from _child import timed_run  # noqa: E402

REPO = Path(__file__).resolve().parent.parent
PHASES = re.compile(r"plan [0-9.]+ s, runs [0-9.]+ s, measure [0-9.]+ s, figures [0-9.]+ s, write [0-9.]+ s")


def readme_scene() -> str:
    """The README's own scene: the first ```toml block holding ``name = ``."""
    text = (REPO / "README.md").read_text(encoding="utf-8")
    for block in re.findall(r"```toml\n(.*?)```", text, flags=re.S):
        if "name = " in block:
            return block
    raise SystemExit("bench_user_scene: README.md holds no ```toml block with `name = `")


def call(python: str, scene: Path, work: Path) -> tuple:
    """``(wall s, cpu s, load, phases)`` of one run of ``scene`` by ``python``."""
    out = Path(tempfile.mkdtemp(dir=work)) / "out"
    proc, wall, cpu, load = timed_run([python, "-m", "rk4h.validation.run_all", "--scene", str(scene), "--out",
                                       str(out)], cwd=work)
    if proc.returncode not in (0, 1):
        raise SystemExit(f"bench_user_scene: {python} exited {proc.returncode}:\n{proc.stderr[-2000:]}")
    m = PHASES.search(proc.stdout + proc.stderr)
    return wall, cpu, load, m.group(0) if m else "(no phase line)"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--before", help="a Python whose rk4h is the tree before the change")
    ap.add_argument("--after", default=sys.executable, help="a Python whose rk4h is the tree after (default: this one)")
    ap.add_argument("--scene", help="a scene file (default: the README's own scene)")
    ap.add_argument("--rounds", type=int, default=3)
    args = ap.parse_args(argv)
    if args.rounds < 1:
        ap.error(f"--rounds: must be at least 1, got {args.rounds}")
    sides = [("before", args.before)] if args.before else []
    sides.append(("after", args.after))
    with tempfile.TemporaryDirectory(prefix="bench-user-scene-") as tmp:
        work = Path(tmp)
        if args.scene:
            scene = Path(args.scene).resolve()
        else:
            scene = work / "my_chain.toml"
            scene.write_text(readme_scene(), encoding="utf-8")
        print(f"scene {scene.name}; {os.cpu_count()} CPUs; load {os.getloadavg()[0]:.2f}")
        for _, py in sides:  # warm-up: caches on disk
            call(py, scene, work)
        results = {name: [] for name, _ in sides}
        for r in range(args.rounds):
            order = sides if r % 2 == 0 else sides[::-1]
            for name, py in order:
                wall, cpu, load, phases = call(py, scene, work)
                results[name].append((wall, cpu))
                print(f"round {r + 1} {name:6s} wall {wall:6.2f} s  cpu {cpu:6.2f} s  load {load:4.2f}  {phases}")
        med = {name: (statistics.median(w for w, _ in v), statistics.median(c for _, c in v))
               for name, v in results.items()}
        for name, (w, c) in med.items():
            print(f"median {name:6s} wall {w:6.2f} s  cpu {c:6.2f} s  ({args.rounds} rounds)")
        if args.before:
            (wb, cb), (wa, ca) = med["before"], med["after"]
            print(f"ratio before/after: wall {wb / wa:.2f}, cpu {cb / ca:.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
