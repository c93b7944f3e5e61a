"""Benchmark of the compiled RK4 fast path (issue 5): prints the README's ratios.

    python benchmarks/bench_rk4.py            # full sizes (about a minute)
    python benchmarks/bench_rk4.py --tiny     # same code, tiny sizes (seconds)

Every figure is the median of ``--repeats`` timed runs after one untimed
warm-up run; numba's compile (or cache-load) time and heyoka's JIT time are
printed apart and never included. Lines starting with ``ratio`` and
``exponent`` are the results; the targets of issue 5 are printed beside them
but not enforced (timings are machine- and load-dependent).

1. fast RK4 vs a plain-Python RK4 loop (numpy ``model.rhs``), 2-DOF case 1
   (thesis Table 4.1), every step stored by both.
2. Matched error: over ``t_end`` s of 2-DOF case 1 with outputs every 0.1 s,
   error_max (all state components, all outputs) against the modal solution
   ``rk4h.references.exact``. For each solver the largest setting with
   ``error_max <= 1e-6``, found the same way: bisection on log h for RK4 (to
   0.1 %), on log rtol for DOP853 and heyoka (to 1 %, their shared
   absolute-tolerance rule). All three are then timed through
   ``rk4h.references.solvers.integrate`` (its ``wall_s``: the integration only,
   numba loading and heyoka's JIT apart); ratio of the median wall times.
3. Chains of N equal masses (walls both) from N = 10 up: time per step per mass,
   its max/min ratio and the exponent p of a least-squares fit cost ~ N^p.
4. Design check: a numpy RK4 vectorised over B trajectories at once
   (``model.rhs`` on (n, B) columns) vs the compiled single trajectory, per
   trajectory-step.
5. Generated vs hand-written: ``fast.solve_model`` (the loop generated from
   the model's definition) on 2-DOF case 1 vs the hand-unrolled numba loop
   ``benchmarks/_tight.py:rk4_two_mass`` doing the same arithmetic in the same
   order, ns/step over ``--tight-steps`` steps (only the final state kept);
   the final states must be bit-identical (a ``check`` line).
6. The same for uniform fixed-end chains (masses 1, springs 1), N = 10 up:
   ``solve_model`` vs ``_tight.rk4_chain`` (stage arrays, tension carried to
   the next mass, division by the mass), ns/step/mass; the step count of each
   N is set by one calibration run so that a run takes ``--chain-seconds``.
   Final states checked bit-identical.
7. References on the compiled right-hand side: DOP853 and CVODE (Adams, BDF)
   over ``--periods`` periods of the slowest mode of 2-DOF case 1 at
   ``--rtol`` (absolute tolerance by the shared rule), wall time (``wall_s``,
   the integration only) with ``rk4h.references.solvers.base.compiled_rhs`` vs the
   numpy ``model.rhs`` (``model.__dict__["_references_rhs"] = None``), runs
   of the two alternated; the cost of one right-hand-side call of each. Both
   runs must give the same ``nfev`` and ``y`` to 1e-12 relative (``check``).

Lines starting with ``check`` are correctness checks (True/False), asserted
by ``tests/test_benchmarks.py``; the timings never are.
"""
from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))  # the repository, installed or not

import rk4h
import rk4h.fast as fast
from rk4h.references.exact import modal_solution
from rk4h.references.solvers import absolute_tolerance, integrate
from rk4h.references.solvers.base import compiled_rhs
from rk4h.references.solvers.cvode import run_cvode
from rk4h.references.solvers.dop853 import run_dop853

sys.path.insert(0, str(Path(__file__).resolve().parent))  # benchmarks/_tight.py, beside this script
import _tight  # noqa: E402
from _timing import median_time  # noqa: E402 - the wall clock

CASE1 = {"masses": [0.815, 3.099], "springs": [41.5, 138.0, 157.8], "walls": "both"}
X0 = [0.005, 0.005]
TARGET_ERROR = 1e-6

SIZES = {
    "full": dict(python_steps=100_000, t_end=100.0, chain_N=[10, 100, 1000, 10_000, 100_000],
                 chain_work=4_000_000, batch=1000, batch_steps=1000, repeats=5,
                 tight_steps=2_000_000, chain_seconds=0.4, periods=100, rhs_calls=20_000),
    "tiny": dict(python_steps=2000, t_end=5.0, chain_N=[10, 100, 1000],
                 chain_work=100_000, batch=100, batch_steps=200, repeats=3,
                 tight_steps=20_000, chain_seconds=0.005, periods=5, rhs_calls=1000),
}
SECTIONS = ("python", "matched", "chains", "batch", "tight", "chains-tight", "references")
REFERENCE_SOLVERS = ("dop853", "cvode-adams", "cvode-bdf")
SAME_Y_RTOL = 1e-12


def python_rk4(fun, t0, y0, h, n):
    """The plain-Python classical RK4 loop (thesis sec. 1.1.4), every step stored."""
    ys = np.empty((n + 1, y0.shape[0]))
    ys[0] = y = y0
    for i in range(n):
        t = t0 + i * h
        k1 = fun(t, y)
        k2 = fun(t + h / 2, y + h / 2 * k1)
        k3 = fun(t + h / 2, y + h / 2 * k2)
        k4 = fun(t + h, y + h * k3)
        y = y + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        ys[i + 1] = y
    return ys


def bench_python_loop(model, y0, n, repeats):
    h = 1e-3
    t_fast = median_time(lambda: fast.solve_model(model, (0.0, n * h), y0, n_steps=n), repeats)
    t_py = median_time(lambda: python_rk4(model.rhs, 0.0, y0, h, n), repeats)
    print(f"fast RK4, {n} steps: {t_fast * 1e3:.3f} ms ({t_fast / n * 1e9:.1f} ns/step); "
          f"plain-Python RK4 loop: {t_py * 1e3:.1f} ms ({t_py / n * 1e6:.2f} us/step)")
    print(f"ratio python_loop/fast_rk4 (2-DOF case 1, {n} steps): {t_py / t_fast:.1f}  [target >= 50]")


def _error(y, exact_y):
    return float(np.max(np.abs(y - exact_y))) if np.all(np.isfinite(y)) else math.inf


def _bisect(err, ok, bad, rel):
    """Bisection in log scale between a setting ``ok`` (error <= target) and
    ``bad`` (error > target) until they differ by a factor ``1 + rel``;
    returns the largest passing setting seen and its error."""
    best, best_err = ok, err(ok)
    while abs(math.log(bad / ok)) > math.log1p(rel):
        mid = math.sqrt(ok * bad)
        e = err(mid)
        if e <= TARGET_ERROR:
            ok = mid
            best, best_err = max((best, best_err), (mid, e))
        else:
            bad = mid
    return best, best_err


def largest_rk4_step(model, y0, t_eval, exact_y):
    """Largest step ``h`` (to 0.1 %) with ``error_max <= TARGET_ERROR`` at the
    outputs ``t_eval`` (off-grid outputs by the cubic Hermite interpolant of
    ``solve_model``): halving from ``h = dt``, then bisection on log h."""
    span = (t_eval[0], t_eval[-1])

    def err(h):
        return _error(fast.solve_model(model, span, y0, h=h, t_eval=t_eval).y, exact_y)

    h = t_eval[1] - t_eval[0]
    while err(h) > TARGET_ERROR:
        h /= 2
    return _bisect(err, h, 2 * h, 1e-3)


def loosest_tolerance(solver, model, y0, t_eval, exact_y):
    """Loosest rtol (to 1 % , bisection on log rtol between 1e-3 and 1e-13)
    with ``error_max <= TARGET_ERROR`` (absolute tolerance by the shared rule
    of ``rk4h.references.solvers.integrate``), its error and the compile time of
    the first run (heyoka's JIT)."""

    def err(rtol):
        run = integrate(solver, model, y0, t_eval, rtol)
        compile_s.append(run.compile_s)
        return _error(run.y, exact_y) if run.ok else math.inf

    compile_s = []

    loose, tight = 1e-3, 1e-13
    if err(loose) <= TARGET_ERROR:
        return loose, err(loose), compile_s[0]
    if err(tight) > TARGET_ERROR:
        raise RuntimeError(f"{solver} does not reach error {TARGET_ERROR} by rtol {tight:g}")
    return (*_bisect(err, tight, loose, 1e-2), compile_s[0])


def bench_matched_error(model, y0, t_end, repeats):
    t_eval = np.linspace(0.0, t_end, int(round(t_end / 0.1)) + 1)
    exact_y = modal_solution(model, y0)(t_eval)
    print(f"matched error_max <= {TARGET_ERROR:g} over {t_end:g} s, {t_eval.size} outputs "
          f"(largest setting found by bisection; wall time through rk4h.references.solvers.integrate, "
          f"median of {repeats}, compile/JIT apart):")
    settings = {"rk4": (*largest_rk4_step(model, y0, t_eval, exact_y), 0.0)}
    for solver in ("dop853", "heyoka"):
        settings[solver] = loosest_tolerance(solver, model, y0, t_eval, exact_y)
    walls = {}
    for solver, (setting, err, compile_s) in settings.items():
        runs = [integrate(solver, model, y0, t_eval, setting) for _ in range(repeats + 1)]
        walls[solver] = float(np.median([r.wall_s for r in runs[1:]]))
        name = "h" if solver == "rk4" else "rtol"
        jit = f", JIT {compile_s:.3f} s apart" if solver == "heyoka" else ""
        print(f"  {solver:<7} {name} = {setting:.5g}, error_max {err:.4g}, {runs[-1].n_steps} steps, "
              f"nfev {runs[-1].nfev}, {walls[solver] * 1e3:.3f} ms "
              f"({walls[solver] / runs[-1].n_steps * 1e9:.0f} ns/step){jit}")
    print(f"ratio rk4/dop853 wall time at error_max <= {TARGET_ERROR:g}: {walls['rk4'] / walls['dop853']:.4f}"
          f"  [target <= 0.1]")
    print(f"ratio rk4/heyoka wall time at error_max <= {TARGET_ERROR:g}: {walls['rk4'] / walls['heyoka']:.2f}"
          f"  [target <= 2]")


def bench_chains(sizes, work, repeats):
    per = []
    for N in sizes:
        model = rk4h.make_model("chain", {"masses": [1.0] * N, "springs": [1.0] * (N + 1)})
        y0 = np.zeros(2 * N)
        y0[: N] = 1e-3 * np.sin(np.pi * np.arange(1, N + 1) / (N + 1))  # lowest mode shape
        n = max(20, work // N)
        t = median_time(lambda: fast.solve_model(model, (0.0, 0.01 * n), y0, n_steps=n, record_every=n),
                        repeats)
        per.append(t / n / N)
        print(f"  chain N = {N:>6}: {n:>6} steps, {t / n * 1e6:10.2f} us/step, {per[-1] * 1e9:.2f} ns/step/mass")
    per = np.array(per)
    p = np.polyfit(np.log(sizes), np.log(per * np.array(sizes)), 1)[0]
    print(f"ratio chain time/step/mass max/min (N = {sizes[0]}..{sizes[-1]}): {per.max() / per.min():.2f}"
          f"  [target <= 2]")
    print(f"exponent chain cost per step ~ N^p: p = {p:.3f}  [target ~ 1]")


def bench_batch(model, y0, B, n, repeats):
    h = 1e-3
    rng = np.random.default_rng(0)
    Y0 = y0[:, None] * (1.0 + 0.1 * rng.standard_normal((1, B)))

    def numpy_batch():
        y = Y0.copy()
        f = model.rhs
        for i in range(n):
            k1 = f(0.0, y)
            k2 = f(0.0, y + h / 2 * k1)
            k3 = f(0.0, y + h / 2 * k2)
            k4 = f(0.0, y + h * k3)
            y = y + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        return y

    def compiled_each():
        for b in range(B):
            fast.solve_model(model, (0.0, n * h), Y0[:, b], n_steps=n, record_every=n)

    t_np = median_time(numpy_batch, repeats)
    t_c = median_time(compiled_each, repeats)
    print(f"design: {B} trajectories x {n} steps: numpy-vectorised batch {t_np / (B * n) * 1e9:.1f} "
          f"ns/trajectory-step; compiled, one trajectory at a time {t_c / (B * n) * 1e9:.1f} "
          f"ns/trajectory-step")
    print(f"ratio numpy_batch/compiled per trajectory-step: {t_np / t_c:.2f}")


def bit_identical(a, b) -> bool:
    """Same shape and the same float64 bits (so also -0.0 vs 0.0 and NaNs)."""
    a, b = np.ascontiguousarray(a, dtype=np.float64), np.ascontiguousarray(b, dtype=np.float64)
    return a.shape == b.shape and a.tobytes() == b.tobytes()


def bench_tight_two_mass(model, y0, n, repeats):
    """Section 5: the generated loop vs ``_tight.rk4_two_mass`` (same arithmetic)."""
    span = (0.0, n * 1e-3)
    res = fast.solve_model(model, span, y0, n_steps=n, record_every=n)
    k0, k1, k2 = (float(k) for k in model.k)
    m0, m1 = (float(m) for m in model.mass)
    y_tight = _tight.rk4_two_mass(m0, m1, k0, k1, k2, y0, res.h, n)
    t_call = median_time(lambda: fast.solve_model(model, (0.0, 1e-3), y0, n_steps=1), repeats)
    t_gen = median_time(lambda: fast.solve_model(model, span, y0, n_steps=n, record_every=n), repeats)
    t_tight = median_time(lambda: _tight.rk4_two_mass(m0, m1, k0, k1, k2, y0, res.h, n), repeats)
    print(f"generated vs hand-written RK4, 2-DOF case 1, {n} steps of h = {res.h:g} s (final state only): "
          f"solve_model {t_gen / n * 1e9:.2f} ns/step (its per-call cost, a one-step call: "
          f"{t_call * 1e6:.1f} us), tight unrolled loop {t_tight / n * 1e9:.2f} ns/step")
    print(f"ratio generated/tight ns/step (2-DOF case 1): {t_gen / t_tight:.2f}  [target <= 1.3]")
    same = res.success and bit_identical(res.y[:, -1], y_tight)
    print(f"check 2-DOF final state generated == tight (bit-identical): {same}")
    if not same:
        print(f"  generated {res.y[:, -1].tolist()}\n  tight     {y_tight.tolist()}")


def bench_tight_chains(sizes, seconds, repeats):
    """Section 6: ``solve_model`` on uniform fixed-end chains vs ``_tight.rk4_chain``.

    ``solve_model`` has a per-call cost besides its loop (argument checks,
    building the force kernel and its cache key); it is measured apart (the
    median of one-step calls) and the step count of each N is calibrated on
    the loop alone (step count doubled until the loop takes as long as that
    cost, then scaled), so the loop takes about ``seconds``. Ratios are
    printed for the whole call and for the loop alone."""
    h = 0.01
    print(f"generated vs hand-written RK4, uniform chains (masses 1 kg, springs 1 N/m, walls both, h = {h:g} s; "
          f"steps set so that the loop takes about {seconds:g} s; ns/step/mass of the whole call, and of the "
          f"loop alone = (call - one-step call) / steps):")
    ratios, all_same = [], True
    for N in sizes:
        model = rk4h.make_model("chain", {"masses": [1.0] * N, "springs": [1.0] * (N + 1)})
        mass, k = np.ascontiguousarray(model.mass, dtype=float), np.ascontiguousarray(model.k, dtype=float)
        y0 = np.zeros(2 * N)
        y0[:N] = 1e-3 * np.sin(np.pi * np.arange(1, N + 1) / (N + 1))  # lowest mode shape

        def gen(n):
            return fast.solve_model(model, (0.0, n * h), y0, n_steps=n, record_every=n)

        def timed(n):
            start = time.perf_counter()
            gen(n)
            return time.perf_counter() - start

        t_call = median_time(lambda: gen(1), repeats)  # the per-call cost (and a warm-up)
        n = max(10, 20_000 // N)  # calibration of the loop's time per step
        while True:
            t_loop = timed(n) - t_call
            if t_loop >= max(t_call, 0.1 * seconds) or n > 10**9:
                break
            n *= 2
        n = max(10, int(round(n * seconds / max(t_loop, 1e-9))))
        res = gen(n)
        y_tight = _tight.rk4_chain(mass, k, y0, res.h, n)
        t_gen = median_time(lambda: gen(n), repeats)
        t_tight = median_time(lambda: _tight.rk4_chain(mass, k, y0, res.h, n), repeats)
        t_loop = max(t_gen - t_call, 0.0)
        same = res.success and bit_identical(res.y[:, -1], y_tight)
        all_same = all_same and same
        ratios.append((N, t_gen / t_tight, t_loop / t_tight))
        print(f"  chain N = {N:>6}: {n:>8} steps; solve_model {t_gen / n / N * 1e9:7.2f} ns/step/mass "
              f"(per-call cost {t_call * 1e3:7.3f} ms, loop alone {t_loop / n / N * 1e9:7.2f}); "
              f"tight {t_tight / n / N * 1e9:6.2f} ns/step/mass; final state bit-identical {same}")
    for N, whole, loop in ratios:
        print(f"ratio generated/tight per mass-step (chain N = {N}): {whole:.2f}  [target <= 1.5]"
              f"  (loop alone: {loop:.2f})")
    print(f"check chain final states generated == tight (bit-identical, N = {sizes[0]}..{sizes[-1]}): {all_same}")


def _relative_difference(y, y_ref) -> float:
    """Largest ``|y - y_ref|`` of each state component relative to that
    component's largest ``|y_ref|``, maximum over the components (inf if
    either is not finite)."""
    if not (np.all(np.isfinite(y)) and np.all(np.isfinite(y_ref))):
        return math.inf
    scale = np.max(np.abs(y_ref), axis=1)
    scale[scale == 0.0] = 1.0
    return float(np.max(np.max(np.abs(y - y_ref), axis=1) / scale))


def _per_call_us(fn, calls, repeats):
    def loop():
        for _ in range(calls):
            fn()
    return median_time(loop, repeats) / calls * 1e6


def bench_references(periods, rtol, calls, repeats):
    """Section 7: DOP853 and CVODE on the compiled vs the numpy right-hand side."""
    model = rk4h.make_model("chain", CASE1)  # its own object: the references cache the RHS on it
    y0 = model.state(X0)
    w_min = model.frequency_range()[0]
    t_end = periods * 2 * math.pi / w_min
    t_eval = np.linspace(0.0, t_end, periods + 1)  # one output per period
    atol = absolute_tolerance(model, y0, rtol)
    fast_rhs = compiled_rhs(model)  # compiled (or loaded) here, never in a timed run
    modes = {"compiled": fast_rhs, "numpy": None}
    print(f"references on 2-DOF case 1, {periods} periods of the slowest mode (t_end = {t_end:.4g} s, "
          f"{t_eval.size} outputs), rtol {rtol:g}, atol by the shared rule; wall time (integration only) "
          f"median of {repeats} after one warm-up, compiled and numpy right-hand side alternated:")
    checks = []
    for solver in REFERENCE_SOLVERS:
        def run():
            if solver == "dop853":
                return run_dop853(model, y0, t_eval, rtol, atol)
            return run_cvode(solver, model, y0, t_eval, rtol, atol)

        runs = {mode: [] for mode in modes}
        for _ in range(repeats + 1):
            for mode, rhs in modes.items():
                model.__dict__["_references_rhs"] = rhs
                runs[mode].append(run())
        model.__dict__["_references_rhs"] = fast_rhs
        wall = {mode: float(np.median([r.wall_s for r in rs[1:]])) for mode, rs in runs.items()}
        rc, rn = runs["compiled"][-1], runs["numpy"][-1]
        print(f"  {solver:<11} compiled RHS {wall['compiled'] * 1e3:8.2f} ms, numpy RHS {wall['numpy'] * 1e3:8.2f} ms"
              f" ({rc.n_steps} steps, nfev {rc.nfev}; rhs used: {rc.extra.get('rhs')} / {rn.extra.get('rhs')}; "
              f"status {rc.status.value} / {rn.status.value})")
        diff = _relative_difference(rc.y, rn.y)
        same_nfev = rc.nfev == rn.nfev and rc.n_steps == rn.n_steps
        ok = (rc.ok and rn.ok and rc.extra.get("rhs") == "compiled" and rn.extra.get("rhs") == "numpy")
        checks.append((solver, same_nfev, rc.nfev, rn.nfev, diff, ok))
        print(f"ratio {solver} wall time compiled/numpy RHS: {wall['compiled'] / wall['numpy']:.3f}")
    for solver, same_nfev, nc, nn, diff, ok in checks:
        print(f"check {solver} compiled vs numpy RHS same nfev ({nc} vs {nn}): {same_nfev and ok}")
        print(f"check {solver} compiled vs numpy RHS same y to {SAME_Y_RTOL:g} relative "
              f"(max relative difference {diff:.3g}): {diff <= SAME_Y_RTOL and ok}")
    y = np.array(y0, dtype=float)
    us_call = _per_call_us(lambda: fast_rhs(0.0, y), calls, repeats)
    us_checked = _per_call_us(lambda: fast_rhs.checked(y), calls, repeats)
    us_numpy = _per_call_us(lambda: model.rhs(0.0, y), calls, repeats)
    print(f"right-hand side per call ({calls} calls, median of {repeats}): compiled_rhs(model)(t, y) "
          f"{us_call:.3f} us, .checked(y) (DOP853's) {us_checked:.3f} us; model.rhs(t, y) {us_numpy:.3f} us")
    print(f"time compiled_rhs(model)(t, y) per call: {us_call:.3f} us  [target <= 2 us]")
    print(f"ratio rhs per call numpy/compiled: {us_numpy / us_call:.1f}")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--tiny", action="store_true", help="tiny sizes (for the test suite)")
    ap.add_argument("--repeats", type=int, default=None, help="timed runs per figure (median)")
    ap.add_argument("--only", action="append", choices=SECTIONS, default=None, metavar="SECTION",
                    help=f"run only this section (repeatable): {', '.join(SECTIONS)}")
    ap.add_argument("--tight-steps", type=int, default=None,
                    help="steps of the 2-DOF generated-vs-tight comparison (section 5)")
    ap.add_argument("--chain-seconds", type=float, default=None,
                    help="target seconds of one chain run in the generated-vs-tight comparison (section 6)")
    ap.add_argument("--periods", type=int, default=None,
                    help="periods of the slowest mode integrated by the references (section 7)")
    ap.add_argument("--rtol", type=float, default=1e-8, help="relative tolerance of the references (section 7)")
    args = ap.parse_args(argv)
    cfg = SIZES["tiny" if args.tiny else "full"]
    repeats = args.repeats or cfg["repeats"]
    if repeats < 1:
        ap.error(f"--repeats must be >= 1, got {repeats}")
    tight_steps = args.tight_steps or cfg["tight_steps"]
    chain_seconds = args.chain_seconds or cfg["chain_seconds"]
    periods = args.periods or cfg["periods"]
    if tight_steps < 1 or periods < 1 or not chain_seconds > 0 or not 0 < args.rtol < 1:
        ap.error("--tight-steps and --periods must be >= 1, --chain-seconds > 0, 0 < --rtol < 1")
    sections = set(args.only or SECTIONS)
    print(f"bench_rk4 ({'tiny' if args.tiny else 'full'} sizes): medians of {repeats} repeats after "
          f"one warm-up run")
    print(f"numba compile / cache load (apart, not in any timing): {fast.warm_up():.3f} s")
    if sections & {"tight", "chains-tight"}:
        start = time.perf_counter()
        _tight.compile_all()
        print(f"hand-written loops compile / cache load (apart, not in any timing): "
              f"{time.perf_counter() - start:.3f} s")
    model = rk4h.make_model("chain", CASE1)
    y0 = model.state(X0)
    if "python" in sections:
        bench_python_loop(model, y0, cfg["python_steps"], repeats)
    if "matched" in sections:
        bench_matched_error(model, y0, cfg["t_end"], repeats)
    if "chains" in sections:
        bench_chains(cfg["chain_N"], cfg["chain_work"], repeats)
    if "batch" in sections:
        bench_batch(model, y0, cfg["batch"], cfg["batch_steps"], repeats)
    if "tight" in sections:
        bench_tight_two_mass(model, y0, tight_steps, repeats)
    if "chains-tight" in sections:
        bench_tight_chains(cfg["chain_N"], chain_seconds, repeats)
    if "references" in sections:
        bench_references(periods, args.rtol, cfg["rhs_calls"], repeats)


if __name__ == "__main__":
    main()
