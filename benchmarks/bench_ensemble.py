"""Benchmark of ``rk4h.ensemble`` (issue 31): ns per instance-step.

    python benchmarks/bench_ensemble.py                 # B = 1, 1e3, 1e5, 1e6
    python benchmarks/bench_ensemble.py --tiny          # same code, small sizes (seconds)
    python benchmarks/bench_ensemble.py --docs docs/performance.md   # also write the table

The thesis 2-DOF chain (case 1: masses 0.815, 3.099 kg; springs 41.5, 138.0,
157.8 N/m), RK4, h = 1e-3 s, initial states drawn uniformly in +-5 mm (seed
1), only the first and last states kept (``t_eval = [t0, t1]``). Each B runs
``--work`` instance-steps in all (at least ``--min-steps`` steps), timed as
the median of ``--repeats`` runs after one untimed warm-up (numba's and jax's
compile times printed apart, never included).

Backends: ``numba`` (all cores of this machine) and ``jax`` on jax's default
device; the device of each column is named. The yardstick is the
hand-unrolled single-instance loop ``benchmarks/_tight.py:rk4_two_mass``:
``tight / cores`` is what a perfectly parallel batch of it would cost per
instance-step, and the numba column is printed as a multiple of it (issue 31's
target: within 1.5x at B = 1e5). Where jax's device is not a GPU the GPU
column says so; nothing is measured for it.

With ``--docs PATH`` the markdown table replaces the block between
``<!-- bench_ensemble:begin -->`` and ``<!-- bench_ensemble:end -->`` of that
file (the markers must be there; nothing else is touched).
"""
from __future__ import annotations

import argparse
import datetime
import os
import pathlib
import platform
import statistics
import subprocess
import sys
import time

import numpy as np

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))

import rk4h  # noqa: E402

BEGIN, END = "<!-- bench_ensemble:begin -->", "<!-- bench_ensemble:end -->"
MASSES, SPRINGS = [0.815, 3.099], [41.5, 138.0, 157.8]


def cpu_name() -> str:
    try:
        for line in pathlib.Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown CPU"


def timed(fn, repeats):
    fn()  # warm-up (compiles on the first call)
    ts = []
    for _ in range(repeats):
        t = time.perf_counter()
        fn()
        ts.append(time.perf_counter() - t)
    return statistics.median(ts)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--tiny", action="store_true", help="small sizes (a smoke run)")
    ap.add_argument("--sizes", type=float, nargs="+", default=None, help="batch sizes B (default 1 1e3 1e5 1e6)")
    ap.add_argument("--work", type=float, default=2e7, help="instance-steps per timed run (default 2e7)")
    ap.add_argument("--min-steps", type=int, default=20)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--backends", nargs="+", default=["numba", "jax"], choices=["numba", "jax"])
    ap.add_argument("--docs", type=pathlib.Path, default=None, help="markdown file holding the table's markers")
    a = ap.parse_args(argv)
    sizes = [int(s) for s in (a.sizes or ([1, 100, 1000] if a.tiny else [1, 1e3, 1e5, 1e6]))]
    work = 2e5 if a.tiny else a.work
    if a.docs is not None:
        text = a.docs.read_text()
        if text.count(BEGIN) != 1 or text.count(END) != 1:
            print(f"error: --docs {a.docs}: needs exactly one {BEGIN} and one {END} line", file=sys.stderr)
            return 2
    model = rk4h.make_model("chain", {"masses": MASSES, "springs": SPRINGS})
    h = 1e-3
    import numba

    cores = numba.get_num_threads()
    from _tight import rk4_two_mass

    y1 = np.array([0.005, 0.005, 0.0, 0.0])
    n_tight = 200_000 if a.tiny else 2_000_000
    rk4_two_mass(*MASSES, *SPRINGS, y1, h, 10)
    tight = timed(lambda: rk4_two_mass(*MASSES, *SPRINGS, y1, h, n_tight), a.repeats) / n_tight * 1e9
    print(f"tight single-instance loop: {tight:.2f} ns/step; numba threads: {cores}")
    devices = {"numba": f"{cpu_name()}, {cores} threads"}
    gpu_note = "no GPU was lent"
    if "jax" in a.backends:
        try:
            import jax
            d = jax.devices()[0]
            devices["jax"] = f"jax {jax.__version__} {d.platform}: {getattr(d, 'device_kind', d)}"
            if jax.default_backend() == "gpu":
                gpu_note = None
        except ImportError:
            print("jax is not installed: its column is skipped")
            a.backends = [b for b in a.backends if b != "jax"]
    rng = np.random.default_rng(1)
    rows = []
    for B in sizes:
        steps = max(a.min_steps, int(round(work / B)))
        y0 = rng.uniform(-0.005, 0.005, (B, 4))
        t1 = steps * h
        cells = {}
        for backend in a.backends:
            def run():
                return rk4h.ensemble(model, y0, (0.0, t1), h=h, t_eval=[0.0, t1], backend=backend)
            t = time.perf_counter()
            r = run()
            first = time.perf_counter() - t
            assert (r.status == 0).all()
            s = timed(run, a.repeats)
            cells[backend] = s / (B * steps) * 1e9
            print(f"B={B:>8} steps={steps:>7} {backend:>5}: {cells[backend]:8.3f} ns/instance-step "
                  f"(first call incl. compile {first:.1f} s)", flush=True)
        rows.append((B, steps, cells))
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    try:
        commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True,
                                check=True).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        commit = "unknown"
    stamp = datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
    cmd = "python benchmarks/bench_ensemble.py " + " ".join(argv if argv is not None else sys.argv[1:])
    L = [f"`{cmd.strip()}` at {commit}, {stamp}, load average {load:.1f} on {os.cpu_count()} CPUs "
         f"(medians of {a.repeats}; ns per instance-step, RK4, 2-DOF case 1; "
         f"tight single-instance loop {tight:.2f} ns/step, so tight / {cores} threads = {tight / cores:.2f}).",
         "", "| B | steps | numba | numba / (tight / threads) | jax | GPU |", "|---|---|---|---|---|---|"]
    for B, steps, cells in rows:
        nb = cells.get("numba")
        jx = cells.get("jax")
        L.append(f"| {B:.0e} | {steps} | {'%.3f' % nb if nb else '-'} | "
                 f"{'%.2f' % (nb / (tight / cores)) if nb else '-'} | {'%.3f' % jx if jx else '-'} | "
                 f"{gpu_note or '%.3f' % jx} |")
    L += ["", "Devices: " + "; ".join(f"{k}: {v}" for k, v in devices.items()) + "."]
    table = "\n".join(L)
    print()
    print(table)
    if a.docs is not None:
        text = a.docs.read_text()
        head, rest = text.split(BEGIN)
        _, tail = rest.split(END)
        a.docs.write_text(head + BEGIN + "\n" + table + "\n" + END + tail)
        print(f"wrote the table into {a.docs}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
