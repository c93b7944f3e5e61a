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

Long chains (``--chains``, default 1e5 1e6 1e7 masses; ``--chain-steps``,
default 300): ns per mass-step of ONE uniform chain between walls (the
thesis lattice, m = 0.815 kg, k = 41.5 N/m, h = 0.01 s, omega_max h = 0.14,
random displacements of +-1 mm, seed 2), float64: the numba loop
:func:`rk4h.fast.solve_model` generates for the chain (one core: one
instance) against a plain jax ``lax.scan`` RK4 whose force is written here for
the uniform chain (``w^2 (q[i-1] - 2 q[i] + q[i+1])``: rk4h's jax backend
takes models of at most 8 degrees of freedom). The two end states must agree
to 1e-12 relative (round-off of two force expressions), else the row says
so. A state of 1e7 masses is 160 MB; RK4's stages and the loops' work arrays
take about 10 states (1.6 GB) per backend.

diffrax beside (``--diffrax``, default B = 1e3 1e5; skipped with one line
when diffrax is not importable): Tsit5 with a PID controller (rtol 1e-8,
atol 1e-8 x 5 mm) on the ensemble case (the 2-DOF chain, ``jax.vmap`` over
the instances, 1 s), its wall time and mean accepted steps, beside the numba
RK4 batch (h = 1e-3 s) over the same instances and span.

jax's loop kernels (``--kernels V [V ...]``): ``xla:U`` is jax's own loops
with ``U`` steps written out per iteration (``rk4h.batch._jax.UNROLL``),
``pallas:L`` the Pallas kernel that keeps ``L`` instances' states in
registers for a whole output row (``_jax.LANES``). The sweep times each
variant at the largest B over ``--kernel-steps`` steps (default 1e4), says
whether each gives the first variant's states bit for bit, and gives the
largest per-instance relative difference from the numba batch (issue 31: at
most 1e-13). The main table's jax column uses the package's own choice
(``_jax.KERNEL``); it also gives, per B, the largest per-instance relative
difference of jax from numba.

``--max-steps`` caps the steps of a row (B = 1 on a GPU: one instance-step is
a whole kernel launch). ``--commit`` names the code when the benchmark runs
outside a git checkout (a device machine gets a copy of the working tree).

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


CHAIN_M, CHAIN_K, CHAIN_H = 0.815, 41.5, 0.01


def _jax64():
    import jax

    jax.config.update("jax_enable_x64", True)
    return jax


def bench_chain(N, steps, repeats, with_jax=True):
    """``(N, steps, numba ns/mass-step, jax ns/mass-step or None, max relative
    difference of the end states or None)`` for one chain of ``N`` masses."""
    import rk4h.fast

    model = rk4h.make_model("chain", {"masses": CHAIN_M, "springs": CHAIN_K, "n": N, "walls": "both"})
    rng = np.random.default_rng(2)
    y0 = np.concatenate([rng.uniform(-1e-3, 1e-3, N), np.zeros(N)])
    t1 = steps * CHAIN_H

    def numba_run():
        return rk4h.fast.solve_model(model, (0.0, t1), y0, h=CHAIN_H, t_eval=[0.0, t1])

    t = time.perf_counter()
    y_nb = numba_run().y[:, -1]
    first = time.perf_counter() - t
    nb = timed(numba_run, repeats) / (N * steps) * 1e9
    print(f"chain N={N:.0e} steps={steps}: numba {nb:.3f} ns/mass-step (first call {first:.1f} s)", flush=True)
    jx = diff = None
    if with_jax:
        try:
            jax = _jax64()
        except ImportError:
            return N, steps, nb, None, None
        import jax.numpy as jnp

        w2, h = CHAIN_K / CHAIN_M, CHAIN_H

        def f(y):
            q, v = y[0], y[1]
            z = jnp.zeros(1, q.dtype)
            return jnp.stack([v, w2 * (jnp.concatenate([z, q[:-1]]) - 2.0 * q + jnp.concatenate([q[1:], z]))])

        def step(y, _):
            k1 = f(y)
            k2 = f(y + (0.5 * h) * k1)
            k3 = f(y + (0.5 * h) * k2)
            k4 = f(y + h * k3)
            return y + (h / 6.0) * (k1 + 2.0 * k2 + 2.0 * k3 + k4), None

        run = jax.jit(lambda y: jax.lax.scan(step, y, None, length=steps)[0])
        yj0 = jnp.asarray(y0.reshape(2, N))
        t = time.perf_counter()
        y_jx = np.asarray(run(yj0).block_until_ready()).reshape(-1)
        first = time.perf_counter() - t
        jx = timed(lambda: run(yj0).block_until_ready(), repeats) / (N * steps) * 1e9
        diff = float(np.max(np.abs(y_jx - y_nb)) / np.max(np.abs(y_nb)))
        ok = "" if diff <= 1e-12 else "  DIFFERS beyond 1e-12"
        print(f"chain N={N:.0e} steps={steps}: jax {jx:.3f} ns/mass-step (first call {first:.1f} s), "
              f"max relative difference {diff:.1e}{ok}", flush=True)
    return N, steps, nb, jx, diff


def bench_diffrax(model, sizes, repeats, t1=1.0, rtol=1e-8):
    """``[(B, wall s, mean accepted steps, numba RK4 wall s, max |y_dfx - y_rk4|), ...]``;
    ``[]`` (one printed line) when diffrax is not importable."""
    try:
        jax = _jax64()
        import diffrax
    except ImportError as e:
        print(f"diffrax is not importable ({e}): its rows are skipped")
        return []
    import jax.numpy as jnp

    (m0, m1), (k0, k1, k2) = MASSES, SPRINGS

    def vf(t, y, args):
        q0, q1, v0, v1 = y[0], y[1], y[2], y[3]
        return jnp.stack([v0, v1, (-(k0 + k1) * q0 + k1 * q1) / m0, (k1 * q0 - (k1 + k2) * q1) / m1])

    term, solver = diffrax.ODETerm(vf), diffrax.Tsit5()
    ctrl = diffrax.PIDController(rtol=rtol, atol=rtol * 5e-3)

    def one(y0):
        sol = diffrax.diffeqsolve(term, solver, 0.0, t1, 1e-3, y0, stepsize_controller=ctrl,
                                  saveat=diffrax.SaveAt(t1=True), max_steps=100_000)
        return sol.ys[-1], sol.stats["num_accepted_steps"]

    run = jax.jit(jax.vmap(one))
    rng = np.random.default_rng(3)
    rows = []
    for B in sizes:
        y0 = rng.uniform(-0.005, 0.005, (B, 4))
        yj = jnp.asarray(y0)
        t = time.perf_counter()
        y_end, n_acc = (np.asarray(x) for x in jax.block_until_ready(run(yj)))
        first = time.perf_counter() - t
        wall = timed(lambda: jax.block_until_ready(run(yj)), repeats)

        def rk4_run():
            return rk4h.ensemble(model, y0, (0.0, t1), h=1e-3, t_eval=[0.0, t1], backend="numba")

        nb_wall = timed(rk4_run, repeats)
        diff = float(np.max(np.abs(rk4_run().y[:, -1] - y_end)))
        steps = float(np.mean(n_acc))
        print(f"diffrax Tsit5 B={B:.0e}: {wall:.3f} s (first call {first:.1f} s), {steps:.0f} accepted steps per "
              f"instance, {wall / (B * steps) * 1e9:.2f} ns/instance-step; numba RK4 h=1e-3: {nb_wall:.3f} s; "
              f"max difference {diff:.1e} m", flush=True)
        rows.append((B, wall, steps, nb_wall, diff))
    return rows


def rel_diff(a, ref) -> float:
    """Largest, over the instances, of ``max |a - ref| / max |ref|`` per instance
    (arrays of shape (B, rows, n))."""
    scale = np.max(np.abs(ref), axis=(1, 2))
    return float(np.max(np.max(np.abs(a - ref), axis=(1, 2)) / scale))


def bench_kernels(model, B, steps, variants, repeats, h=1e-3):
    """``[(variant, ns per instance-step, bit-identical to the first variant,
    relative difference from numba), ...]`` of the jax backend at ``B``
    instances; a variant is ``"xla:U"`` (jax's loops, ``U`` steps per
    iteration) or ``"pallas:L"`` (the Pallas kernel, ``L`` instances per
    program)."""
    from rk4h.batch import _jax

    rng = np.random.default_rng(4)
    y0 = rng.uniform(-0.005, 0.005, (B, 4))
    t1 = steps * h
    ref = rk4h.ensemble(model, y0, (0.0, t1), h=h, t_eval=[0.0, t1], backend="numba").y
    platform_ = _jax.jax.default_backend()
    saved = dict(_jax.UNROLL), dict(_jax.KERNEL), _jax.LANES
    rows, first = [], None
    try:
        for variant in variants:
            kernel, number = variant.split(":")
            _jax.KERNEL[platform_] = kernel
            if kernel == "xla":
                _jax.UNROLL[platform_] = int(number)
            else:
                _jax.LANES = int(number)

            def run():
                return rk4h.ensemble(model, y0, (0.0, t1), h=h, t_eval=[0.0, t1], backend="jax")

            t = time.perf_counter()
            y = run().y
            compile_s = time.perf_counter() - t
            s = timed(run, repeats) / (B * steps) * 1e9
            first = y if first is None else first
            same, diff = bool(np.array_equal(y, first)), rel_diff(y, ref)
            print(f"{variant:>10} B={B:.0e} steps={steps}: jax {s:.4f} ns/instance-step (first call {compile_s:.1f} s), "
                  f"bit-identical to {variants[0]}: {same}, relative difference from numba {diff:.1e}", flush=True)
            rows.append((variant, s, same, diff))
    finally:
        for d, old in zip((_jax.UNROLL, _jax.KERNEL), saved[:2]):
            d.clear()
            d.update(old)
        _jax.LANES = saved[2]
    return rows


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--tiny", action="store_true", help="small sizes (a smoke run)")
    ap.add_argument("--sizes", type=float, nargs="+", default=None, help="batch sizes B (default 1 1e3 1e5 1e6)")
    ap.add_argument("--work", type=float, default=2e7, help="instance-steps per timed run (default 2e7)")
    ap.add_argument("--min-steps", type=int, default=20)
    ap.add_argument("--max-steps", type=float, default=None, help="cap on the steps of a row (default: none)")
    ap.add_argument("--kernels", nargs="*", default=None,
                    help="jax loop variants to compare at the largest B: xla:U, pallas:L (default: none)")
    ap.add_argument("--jax-kernel", default=None, help="the jax loop kernel of the main table (default: the package's)")
    ap.add_argument("--kernel-steps", type=float, default=1e4, help="steps of the kernel sweep (default 1e4)")
    ap.add_argument("--commit", default=None, help="the code's commit, when not run in a git checkout")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--backends", nargs="+", default=["numba", "jax"], choices=["numba", "jax"])
    ap.add_argument("--docs", type=pathlib.Path, default=None, help="markdown file holding the table's markers")
    ap.add_argument("--chains", type=float, nargs="*", default=None,
                    help="masses of the one-chain runs (default 1e5 1e6 1e7; none: skip)")
    ap.add_argument("--chain-steps", type=int, default=300, help="RK4 steps of each chain run (default 300)")
    ap.add_argument("--diffrax", type=float, nargs="*", default=None,
                    help="instances of the diffrax Tsit5 runs (default 1e3 1e5; none: skip)")
    a = ap.parse_args(argv)
    chains = [int(n) for n in (a.chains if a.chains is not None else ([1e4, 1e5] if a.tiny else [1e5, 1e6, 1e7]))]
    dfx_sizes = [int(n) for n in (a.diffrax if a.diffrax is not None else ([100] if a.tiny else [1e3, 1e5]))]
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
    gpu_note = "no GPU lent to this session"
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
    if "jax" in a.backends:
        from rk4h.batch import _jax
        asked = [a.jax_kernel or _jax.KERNEL.get(_jax.jax.default_backend(), "xla")]
        asked += [v.split(":")[0] for v in a.kernels or []]
        if any(k != "xla" for k in asked) and not _jax._has_pallas_triton():
            # rk4h would run jax's own loops instead (with a warning): a row named pallas would not be
            print(f"error: this jax ({_jax.jax.__version__}) has no Pallas Triton backend: the Pallas kernel "
                  f"cannot be measured; ask for --jax-kernel xla and xla:U variants only", file=sys.stderr)
            return 2
        if a.jax_kernel is not None:
            _jax.KERNEL[_jax.jax.default_backend()] = a.jax_kernel
    rng = np.random.default_rng(1)
    rows = []
    for B in sizes:
        steps = max(a.min_steps, int(round(work / B)))
        if a.max_steps is not None:
            steps = min(steps, int(a.max_steps))
        y0 = rng.uniform(-0.005, 0.005, (B, 4))
        t1 = steps * h
        cells, ys = {}, {}
        for backend in a.backends:
            def run():
                return rk4h.ensemble(model, y0, (0.0, t1), h=h, t_eval=[0.0, t1], backend=backend)
            t = time.perf_counter()
            r = run()
            first = time.perf_counter() - t
            assert (r.status == 0).all()
            ys[backend] = r.y
            s = timed(run, a.repeats)
            cells[backend] = s / (B * steps) * 1e9
            print(f"B={B:>8} steps={steps:>7} {backend:>5}: {cells[backend]:8.3f} ns/instance-step "
                  f"(first call incl. compile {first:.1f} s)", flush=True)
        diff = rel_diff(ys["jax"], ys["numba"]) if len(ys) == 2 else None
        if diff is not None:
            print(f"B={B:>8}: jax differs from numba by at most {diff:.1e} relative per instance", flush=True)
        rows.append((B, steps, cells, diff))
    kernel_rows = (bench_kernels(model, max(sizes), int(a.kernel_steps), a.kernels, a.repeats)
                   if a.kernels and "jax" in a.backends and "numba" in a.backends else [])
    chain_rows = [bench_chain(N, 20 if a.tiny else a.chain_steps, a.repeats, "jax" in a.backends) for N in chains]
    dfx_rows = bench_diffrax(model, dfx_sizes, a.repeats) if dfx_sizes else []
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    try:
        commit = a.commit or subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True,
                                            text=True, check=True).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        commit = "unknown"
    stamp = datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
    cmd = "python benchmarks/bench_ensemble.py " + " ".join(argv if argv is not None else sys.argv[1:])
    L = [f"`{cmd.strip()}` at {commit}, {stamp}, load average {load:.1f} on {os.cpu_count()} CPUs "
         f"(medians of {a.repeats}; ns per instance-step, RK4, 2-DOF case 1; "
         f"tight single-instance loop {tight:.2f} ns/step, so tight / {cores} threads = {tight / cores:.2f}).",
         "", "| B | steps | numba | numba / (tight / threads) | jax | GPU | jax vs numba (relative, per instance) |",
         "|---|---|---|---|---|---|---|"]
    for B, steps, cells, diff in rows:
        nb = cells.get("numba")
        jx = cells.get("jax")
        L.append(f"| {B:.0e} | {steps} | {'%.3f' % nb if nb else '-'} | "
                 f"{'%.2f' % (nb / (tight / cores)) if nb else '-'} | {'%.4f' % jx if jx else '-'} | "
                 f"{gpu_note or '%.4f' % jx} | {'%.1e' % diff if diff is not None else '-'} |")
    if kernel_rows:
        B, jx = max(sizes), rk4h.batch._jax
        L += ["", f"jax's loop kernels, B = {B:.0e}, {int(a.kernel_steps)} RK4 steps, ns per instance-step "
              f"(xla:U: jax's loops, U steps per iteration; pallas:L: one Pallas kernel per output row, L instances "
              f"per program); the package's choice: kernel {jx.KERNEL}, UNROLL {jx.UNROLL}, LANES {jx.LANES}:", "",
              f"| kernel | jax | bit-identical to {a.kernels[0]} | jax vs numba (relative, per instance) |",
              "|---|---|---|---|"]
        for variant, s_, same, diff in kernel_rows:
            L.append(f"| {variant} | {s_:.4f} | {'yes' if same else 'no'} | {diff:.1e} |")
    if chain_rows:
        L += ["", f"One uniform chain between walls (m = {CHAIN_M} kg, k = {CHAIN_K} N/m, h = {CHAIN_H} s), "
              "RK4, float64, ns per mass-step (numba: one core, one instance):", "",
              "| masses | steps | numba loop | jax lax.scan | max relative difference | GPU |", "|---|---|---|---|---|---|"]
        for N, steps, nb, jx, diff in chain_rows:
            L.append(f"| {N:.0e} | {steps} | {nb:.3f} | {'%.4f' % jx if jx is not None else '-'} | "
                     f"{'%.1e' % diff if diff is not None else '-'} | {gpu_note or '%.4f' % jx} |")
    if dfx_rows:
        L += ["", "diffrax Tsit5 (rtol 1e-8) beside the numba RK4 batch (h = 1e-3 s) on the 2-DOF ensemble over "
              "1 s:", "", "| B | diffrax wall (s) | accepted steps (mean) | ns per instance-step | "
              "numba RK4 wall (s) | max difference (m) |", "|---|---|---|---|---|---|"]
        for B, wall, steps, nb_wall, diff in dfx_rows:
            L.append(f"| {B:.0e} | {wall:.3f} | {steps:.0f} | {wall / (B * steps) * 1e9:.2f} | {nb_wall:.3f} | "
                     f"{diff:.1e} |")
    if "jax" in a.backends:
        from rk4h.batch import _jax
        L += ["", f"The jax column's loop kernel: {_jax.KERNEL.get(_jax.jax.default_backend(), 'xla')}."]
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
