"""Do two workers pay? CPU and wall of ``run_all.py`` on 1 worker, 2 workers
and the runner's own choice, interleaved, with the load average beside each.

    python benchmarks/bench_workers.py [--scene NAME | --quick | --full] [--rounds N]

Default: ``--scene three-blocks`` (a 3-mass chain) and ``--quick``, one round.
Prints, per case, wall and CPU seconds (the run and its worker processes:
``getrusage(RUSAGE_CHILDREN)``), the summary line (which says how many
workers ran and why), and the ratios CPU(2) / CPU(1) and wall(1) / wall(2)
with the two-worker efficiency ``wall(1) / (2 wall(2))``. On a shared machine
the wall times follow the neighbours' load: compare the CPU seconds, and
state the load.
"""
from __future__ import annotations

import argparse
import datetime
import os
import re
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))  # the benchmarks' own helpers
from _child import timed_run  # noqa: E402

REPO = Path(__file__).resolve().parent.parent


def _load() -> str:
    return " ".join(Path("/proc/loadavg").read_text().split()[:3]) if Path("/proc/loadavg").exists() else "?"


def measure(args: list[str]) -> dict:
    """Run ``run_all.py args --out TMP``: wall s, CPU s, exit status, summary line, load before/after."""
    env = {k: v for k, v in os.environ.items() if k != "RK4H_WORKERS"}
    env.setdefault("MPLBACKEND", "Agg")
    with tempfile.TemporaryDirectory(prefix="rk4h-workers-") as tmp:
        load0 = _load()
        r, wall, cpu, _ = timed_run([sys.executable, "validation/run_all.py", *args, "--out", str(Path(tmp) / "r")],
                                    cwd=REPO, env=env)
    summary = next((ln for ln in r.stdout.splitlines() if re.search(r"runs planned", ln)), "")
    return {"wall": wall, "cpu": cpu, "rc": r.returncode, "summary": summary.strip(), "load": (load0, _load())}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scene", action="append", default=None, help="a scene to run alone (repeatable)")
    ap.add_argument("--quick", action="store_true", help="the --quick scenes")
    ap.add_argument("--full", action="store_true", help="every shipped scene (minutes)")
    ap.add_argument("--rounds", type=int, default=1, help="interleaved rounds (default 1)")
    a = ap.parse_args(argv)
    cases = [["--scene", s] for s in a.scene or []] + ([["--quick"]] if a.quick else []) + \
        ([[]] if a.full else [])
    if not cases:
        cases = [["--scene", "three-blocks"], ["--quick"]]
    print(f"python benchmarks/bench_workers.py {' '.join(argv if argv is not None else sys.argv[1:])} on "
          f"{datetime.datetime.now(datetime.timezone.utc):%Y-%m-%d %H:%M} UTC, {os.cpu_count()} CPUs")
    for case in cases:
        name = " ".join(case) or "(full)"
        got = {}
        for _ in range(a.rounds):
            for w in ("1", "2", "auto"):
                m = measure(case + ([] if w == "auto" else ["--workers", w]))
                got.setdefault(w, []).append(m)
                print(f"{name} workers={w}: {m['wall']:.1f} s wall, {m['cpu']:.1f} s CPU, exit {m['rc']}, load "
                      f"{m['load'][0]} -> {m['load'][1]}; {m['summary']}", flush=True)
        med = {w: {k: sorted(x[k] for x in ms)[len(ms) // 2] for k in ("wall", "cpu")} for w, ms in got.items()}
        c1, c2, w1, w2 = med["1"]["cpu"], med["2"]["cpu"], med["1"]["wall"], med["2"]["wall"]
        print(f"{name}: CPU(2)/CPU(1) = {c2 / c1:.2f}, wall(1)/wall(2) = {w1 / w2:.2f}, two-worker "
              f"efficiency {w1 / (2 * w2):.0%}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
