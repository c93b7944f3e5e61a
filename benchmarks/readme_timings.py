"""Measure the README's timing figures: the full and the ``--quick`` run of
``validation/run_all.py``, wall and CPU time, and the run's own summary line.

    python benchmarks/readme_timings.py [--quick-only] [--workers N] [--exclusive-timing]

Each run writes into a fresh temporary directory (removed afterwards; the
committed ``reports/`` is never touched). Prints one Markdown paragraph per run
to paste into the README, with the date, the commit and the machine. CPU time
is the children's user + system time (``resource.getrusage``).
"""
from __future__ import annotations

import argparse
import datetime
import os
import re
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent


def _commit() -> str:
    r = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=REPO, capture_output=True, text=True)
    dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no"], cwd=REPO,
                           capture_output=True, text=True).stdout.strip()
    return (r.stdout.strip() or "?") + ("+changes" if dirty else "")


def measure(args: list[str]) -> dict:
    """Run ``run_all.py args --out TMP``: wall s, CPU s, exit status and summary line."""
    with tempfile.TemporaryDirectory(prefix="rk4h-timing-") as tmp:
        out = Path(tmp) / "report"
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        t0 = time.perf_counter()
        r = subprocess.run([sys.executable, "validation/run_all.py", *args, "--out", str(out)], cwd=REPO,
                           capture_output=True, text=True)
        wall = time.perf_counter() - t0
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    summary = next((ln for ln in r.stdout.splitlines() if re.search(r"runs planned", ln)), "")
    return {"args": args, "wall": wall, "cpu": cpu, "rc": r.returncode, "summary": summary.strip(),
            "last": (r.stdout.strip().splitlines() or [""])[-1]}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick-only", action="store_true")
    ap.add_argument("--workers", type=int, default=None)
    ap.add_argument("--exclusive-timing", action="store_true", help="passed to run_all.py")
    a = ap.parse_args(argv)
    extra = ([] if a.workers is None else ["--workers", str(a.workers)]) + \
        (["--exclusive-timing"] if a.exclusive_timing else [])
    runs = [["--quick", *extra]] + ([] if a.quick_only else [extra])
    head = (f"Measured by `python benchmarks/readme_timings.py` on {datetime.date.today().isoformat()}, commit "
            f"{_commit()}, {os.cpu_count()} CPUs:")
    print(head)
    for args in runs:
        m = measure(args)
        label = "`python validation/run_all.py " + " ".join(args) + "`" if args else "`python validation/run_all.py`"
        print(f"- {label}: {m['wall']:.1f} s wall, {m['cpu']:.0f} s CPU, exit {m['rc']}; {m['summary']}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
