"""Per-call fixed cost of ``rk4h.references.solvers.integrate`` (issue 29).

    python benchmarks/bench_fixed_cost.py              # 300 calls per figure (about 10 s)
    python benchmarks/bench_fixed_cost.py --calls 30   # quicker, noisier

A tiny run (5 RK4 steps of an FPUT chain, N = 32, alpha = 0.25; CVODE-Adams
over 0.05 s of a linear chain, N = 32, rtol 1e-8) is timed many times; every
figure is a median (microseconds) of wall-clock times of whole calls.

``loop``
    The compiled RK4 loop called directly with prepared arguments (what
    ``integrate`` finally runs).
``rk4 warm``
    ``integrate("rk4", ...)`` with the model's constants (Gershgorin bound,
    warmed loop, validated ``y0``) already computed: the per-call cost.
``rk4 cold``
    The same call with every model's constants forgotten before it
    (``rk4h.models.base.clear_constants``, the warm-up record and the short
    path's record on the model), i.e. what each call cost when nothing was
    kept (an estimate of the behaviour before issue 29, measured in this run).
``new y0``
    ``rk4 warm`` with another initial state each call (an ensemble): the
    state is checked on each, by the compiled test of
    ``rk4h.fast.statecheck`` (the numpy check only where it does not accept).
``numpy check``
    ``new y0`` with the compiled test switched off on the model's record:
    each new state checked by ``Model.state_problem`` (one numpy force and
    energy evaluation), as before that test (measured in this run).
``fixed``
    ``rk4 warm - loop``, printed with its ratio to ``loop`` (target of
    issue 29: at most 50 us).
``cvode warm`` / ``cvode cold``, ``cvode solver``
    ``integrate("cvode-adams", ...)`` and the median of its ``wall_s`` (the
    solver's own clock); ``fixed = warm - solver`` (target: at most 0.5 ms).
``truth hit``
    ``rk4h.references.truth.reference_solution`` answered from the memory cache.
``CPU clock``
    ``loop`` and ``rk4 warm`` again, timed by the process's CPU clock
    (``time.process_time``): on a shared machine less inflated by other
    processes than the wall clock, which a user waits for.

Timings depend on the machine and its load (printed: ``os.getloadavg``);
nothing is asserted on them. Lines starting with ``check`` compare results
of cold and warm calls bit for bit.
"""
from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))  # the repository, installed or not

import rk4h  # noqa: E402
import rk4h.fast as fast  # noqa: E402
import rk4h.fast.solve as fast_solve  # noqa: E402
from rk4h.references.solvers import integrate  # noqa: E402
from rk4h.references.truth import reference_solution  # noqa: E402
from rk4h.fast.codegen import array_kernel  # noqa: E402
from rk4h.models.base import clear_constants  # noqa: E402
from rk4h.solver import growth_bound, step_count  # noqa: E402

N = 32
T = np.array([0.0, 0.05])
H = 0.01
RTOL = 1e-8


def median_us(fn, calls: int, before=None, clock=time.perf_counter) -> float:
    times = []
    for _ in range(calls):
        if before is not None:
            before()
        start = clock()
        fn()
        times.append(clock() - start)
    return float(np.median(times)) * 1e6


#: The models whose short-path records ``forget`` drops (set in ``main``).
MODELS: list = []


def forget() -> None:
    clear_constants()
    fast_solve._WARMED.clear()
    for model in MODELS:  # the short path's record (rk4h.references.solvers.fixed.run_fixed_short)
        model.__dict__.pop("_fixed_short", None)


def direct_loop(model, y0):
    """The compiled loop and its arguments as ``solve_model`` prepares them
    for ``t_eval = T``, step ``H`` (all output points on the grid)."""
    kern = fast.force_kernel(model)
    tab = rk4h.get_method("rk4")
    n = step_count((float(T[0]), float(T[-1])), H)
    step = (T[-1] - T[0]) / n
    idx = np.array([0, n], dtype=np.int64)
    theta = np.zeros(2)
    ys = np.empty((2, y0.shape[0]))
    scale = np.ones(y0.shape[0])
    bound, pending = growth_bound(y0, 1e6, scale)
    args = (np.ascontiguousarray(kern.fp, dtype=float), np.ascontiguousarray(kern.ip, dtype=np.int64),
            np.ascontiguousarray(model.mass, dtype=float), np.zeros(kern.work_size), y0, float(T[0]), step, n,
            idx, theta, ys, bound, pending, np.empty(y0.shape[0]))
    loop = array_kernel(tab, kern)
    return lambda: loop(*args)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--calls", type=int, default=300, help="timed calls per figure (default 300)")
    args = ap.parse_args(argv)
    if args.calls < 3:
        print(f"bench_fixed_cost: `--calls` must be >= 3, got {args.calls}", file=sys.stderr)
        return 2
    calls = args.calls
    fput = rk4h.make_model("chain", {"masses": [1.0] * N, "springs": [1.0] * (N + 1), "alpha": 0.25})
    lin = rk4h.make_model("chain", {"masses": [1.0] * N, "springs": [1.0] * (N + 1)})
    y0 = fput.state(0.1 * np.sin(0.3 * np.arange(N)))
    MODELS[:] = [fput, lin]

    print(f"load average {' '.join(f'{v:.2f}' for v in os.getloadavg())} on {os.cpu_count()} CPUs; "
          f"{calls} calls per figure; medians in us")
    # compile / load everything once, untimed
    r_first = integrate("rk4", fput, y0, T, H)
    c_first = integrate("cvode-adams", lin, y0, T, RTOL)
    loop = direct_loop(fput, y0)
    loop()

    t_loop = median_us(loop, calls)
    t_warm = median_us(lambda: integrate("rk4", fput, y0, T, H), calls)
    t_cold = median_us(lambda: integrate("rk4", fput, y0, T, H), calls, before=forget)
    fresh = iter([y0 * (1.0 + 1e-3 * i) for i in range(1, calls + 1)])
    t_new = median_us(lambda: integrate("rk4", fput, next(fresh), T, H), calls)
    integrate("rk4", fput, y0, T, H)
    fput.__dict__["_fixed_short"].accepts = None  # the numpy check of each new state
    fresh = iter([y0 * (1.0 - 1e-3 * i) for i in range(1, calls + 1)])
    t_numpy = median_us(lambda: integrate("rk4", fput, next(fresh), T, H), calls)
    fput.__dict__.pop("_fixed_short")
    integrate("rk4", fput, y0, T, H)
    print(f"rk4   loop {t_loop:9.1f}  warm {t_warm:9.1f}  cold {t_cold:9.1f}  new y0 {t_new:9.1f}  "
          f"(numpy check {t_numpy:9.1f})")
    # The process's CPU clock: less inflated than the wall clock when other processes share the cores.
    p_loop = median_us(loop, calls, clock=time.process_time)
    p_warm = median_us(lambda: integrate("rk4", fput, y0, T, H), calls, clock=time.process_time)
    print(f"rk4   CPU clock: loop {p_loop:9.1f}  warm {p_warm:9.1f}  fixed (warm - loop) {p_warm - p_loop:9.1f} us")
    print(f"rk4   fixed (warm - loop) {t_warm - t_loop:9.1f} us = {(t_warm - t_loop) / t_loop:.1f} x loop  "
          f"(target <= 50 us); cold - loop {t_cold - t_loop:9.1f} us = {(t_cold - t_loop) / t_loop:.1f} x loop")

    cv_runs = []

    def cv():
        cv_runs.append(integrate("cvode-adams", lin, y0, T, RTOL).wall_s)

    c_warm = median_us(cv, calls)
    c_solver = float(np.median(cv_runs)) * 1e6
    c_cold = median_us(cv, calls, before=forget)
    print(f"cvode warm {c_warm:9.1f}  cold {c_cold:9.1f}  solver (wall_s) {c_solver:9.1f}")
    print(f"cvode fixed (warm - solver) {c_warm - c_solver:9.1f} us (target <= 500 us); "
          f"cold - solver {c_cold - c_solver:9.1f} us")

    t_truth = np.linspace(0.0, 1.0, 11)
    with tempfile.TemporaryDirectory() as tmp:  # never the user's truth cache
        reference_solution(lin, y0, t_truth, path=tmp)
        t_hit = median_us(lambda: reference_solution(lin, y0, t_truth, path=tmp), calls)
    print(f"truth hit (memory) {t_hit:9.1f}")

    forget()
    r_cold = integrate("rk4", fput, y0, T, H)
    r_warm = integrate("rk4", fput, y0, T, H)
    c_cold_run = integrate("cvode-adams", lin, y0, T, RTOL)
    c_warm_run = integrate("cvode-adams", lin, y0, T, RTOL)
    print(f"check rk4 cold == warm == first (bit for bit) "
          f"{np.array_equal(r_cold.y, r_warm.y) and np.array_equal(r_first.y, r_warm.y)}")
    print(f"check cvode cold == warm == first (bit for bit) "
          f"{np.array_equal(c_cold_run.y, c_warm_run.y) and np.array_equal(c_first.y, c_warm_run.y)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
