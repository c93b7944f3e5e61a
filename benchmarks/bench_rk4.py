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
   ``references.exact``. For each solver the largest setting with
   ``error_max <= 1e-6``, found the same way: bisection on log h for RK4 (to
   0.1 %), on log rtol for DOP853 and heyoka (to 1 %, their shared
   absolute-tolerance rule). All three are then timed through
   ``references.solvers.integrate`` (its ``wall_s``: the integration only,
   numba loading and heyoka's JIT apart); ratio of the median wall times.
3. Chains of N equal masses (walls both) from N = 10 up: time per step per mass,
   its max/min ratio and the exponent p of a least-squares fit cost ~ N^p.
4. Design check: a numpy RK4 vectorised over B trajectories at once
   (``model.rhs`` on (n, B) columns) vs the compiled single trajectory, per
   trajectory-step.
"""
from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))  # the repository, installed or not

import rk4core
import rk4core.fast as fast
from references.exact import modal_solution
from references.solvers import integrate

CASE1 = {"masses": [0.815, 3.099], "springs": [41.5, 138.0, 157.8], "walls": "both"}
X0 = [0.005, 0.005]
TARGET_ERROR = 1e-6

SIZES = {
    "full": dict(python_steps=100_000, t_end=100.0, chain_N=[10, 100, 1000, 10_000, 100_000],
                 chain_work=4_000_000, batch=1000, batch_steps=1000, repeats=5),
    "tiny": dict(python_steps=2000, t_end=5.0, chain_N=[10, 100, 1000],
                 chain_work=100_000, batch=100, batch_steps=200, repeats=3),
}


def median_time(fn, repeats):
    """Median wall time (s) of ``repeats`` calls of ``fn`` after one untimed call."""
    fn()
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return float(np.median(times))


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
    of ``references.solvers.integrate``), its error and the compile time of
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
          f"(largest setting found by bisection; wall time through references.solvers.integrate, "
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
        model = rk4core.make_model("chain", {"masses": [1.0] * N, "springs": [1.0] * (N + 1)})
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


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--tiny", action="store_true", help="tiny sizes (for the test suite)")
    ap.add_argument("--repeats", type=int, default=None, help="timed runs per figure (median)")
    args = ap.parse_args(argv)
    cfg = SIZES["tiny" if args.tiny else "full"]
    repeats = args.repeats or cfg["repeats"]
    if repeats < 1:
        ap.error(f"--repeats must be >= 1, got {repeats}")
    print(f"bench_rk4 ({'tiny' if args.tiny else 'full'} sizes): medians of {repeats} repeats after "
          f"one warm-up run")
    print(f"numba compile / cache load (apart, not in any timing): {fast.warm_up():.3f} s")
    model = rk4core.make_model("chain", CASE1)
    y0 = model.state(X0)
    bench_python_loop(model, y0, cfg["python_steps"], repeats)
    bench_matched_error(model, y0, cfg["t_end"], repeats)
    bench_chains(cfg["chain_N"], cfg["chain_work"], repeats)
    bench_batch(model, y0, cfg["batch"], cfg["batch_steps"], repeats)


if __name__ == "__main__":
    main()
