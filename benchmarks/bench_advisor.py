"""The advisor's wall and CPU time, before and after a change, interleaved (issue 29).

    python benchmarks/bench_advisor.py --before /tmp/venv-base/bin/python          # this tree = after
    python benchmarks/bench_advisor.py --before PY --rounds 3 --scenes thesis-2dof-case1
    python benchmarks/bench_advisor.py --rounds 1                                    # this tree only
    python benchmarks/bench_advisor.py --threads-vs-one --rounds 4                   # --threads 1 vs default
    python benchmarks/bench_advisor.py --ledger                                      # where the CPU goes
    python benchmarks/bench_advisor.py --loop                                        # planar4's RK4 ns/step

Each ``PY`` is a Python whose ``rk4h`` is the tree to measure (a virtual
environment with that checkout installed editable); ``--after`` defaults to
the Python running this script. For every round and scene (``--scenes``,
default ``thesis-2dof-case1 planar4-case2``) it runs, as a subprocess,
``PY -m rk4h.validation.advise SCENE --target T --json`` (``--target``,
default 1e-3) with before and after alternated (before, after, after,
before, ...), after one untimed warm-up call of each (truths, numba and
heyoka caches on disk; ``--no-warm-up``: none). Printed per call: wall s (``time.perf_counter``
around the subprocess), CPU s (user + system of the child,
``resource.getrusage(RUSAGE_CHILDREN)``), the 1-minute load average before
it, and the answer (method, setting). The last lines per scene are the
medians and the ratios before/after of wall and CPU time.
``--threads-vs-one``: "before" is ``--threads 1`` (the sampled runs one
after the other), "after" the default (side by side on the cores this
process may use), both in the ``--after`` tree.

``--ledger``: where one advisor call's CPU goes, per scene, in a fresh
process each (``time.process_time``, which counts the interpreter's start),
its runs one at a time (``advise(..., threads=1)``; the advice is the same):
start-up, the advisor's import, the scene's load, the problem (model, truth,
stability scale), each integration by method and phase (calibration,
confirmation, timing repeats) with its RHS calls, the first run of each
method apart (imports it triggers, numba's cache load, heyoka's JIT), and
the (method, setting) pairs run more than once outside the timing repeats
(none expected: a confirmation at a setting already run reuses that run).

``--loop``: RK4's CPU ns per step on planar4-case2 through
``rk4h.references.solvers.integrate`` (the advisor's runs) beside a
hand-written numba loop of the same model (one mass, four anchored springs of
natural length ``l``; final state only) and the 2-DOF chain
thesis-2dof-case1, best of ``--rounds`` runs of ``--loop-steps`` steps.

Timings are machine- and load-dependent and never asserted; on a shared
machine read the CPU seconds beside the wall seconds, and the load.
"""
from __future__ import annotations

import argparse
import json
import math
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))  # the benchmarks' own helpers
from _child import timed_run  # noqa: E402


def _call(python: str, scene: str, target: str, extra=()) -> tuple:
    """``(wall s, cpu s, load, answer)`` of one advisor call (``extra``: more arguments)."""
    r, wall, cpu, load = timed_run([python, "-m", "rk4h.validation.advise", scene, "--target", target, "--json",
                                    *extra])
    if r.returncode != 0:
        raise SystemExit(f"bench_advisor: {python} failed on {scene}: {r.stderr.strip()[-500:]}")
    d = json.loads(r.stdout)
    return wall, cpu, load, f"{d['method']} {d['setting_name']} = {d['setting']:.4g}"


#: The advisor's helpers and the phase their runs belong to (``--ledger``).
_PHASES = (("_fixed_candidate", "calibration"), ("_adaptive_candidate", "calibration"),
           ("_late_candidate", "calibration"), ("_confirm_fixed", "confirmation"),
           ("_confirm_adaptive", "confirmation"), ("_timed", "timing"))


def ledger_child(scene: str, target: float) -> dict:
    """One advisor call in this (fresh) process, with every integration and
    phase timed by ``time.process_time``; the ledger as a dict (CPU s)."""
    import time

    t_start = time.process_time()  # the interpreter's start and this script's imports
    from rk4h import _heyoka

    _heyoka.own_process()  # as advise.main does
    from rk4h.validation import advise as adv_mod

    t_import = time.process_time()
    from rk4h.validation.scenes import load_scenes

    sc = load_scenes([scene])[0]
    t_scene = time.process_time()
    stack, rows, problem_s = ["other"], [], [0.0]

    def phased(fn, phase):
        def inner(*a, **k):
            stack.append(phase if stack[-1] in ("other", phase) else stack[-1])  # the outermost phase wins
            try:
                return fn(*a, **k)
            finally:
                stack.pop()
        return inner

    for name, phase in _PHASES:
        setattr(adv_mod, name, phased(getattr(adv_mod, name), phase))
    real_run, real_init = adv_mod._Problem.run, adv_mod._Problem.__init__

    def run(self, method, setting):
        a = time.process_time()
        out = real_run(self, method, setting)
        rows.append([method.name, float(setting), stack[-1], float(out[1]), time.process_time() - a, float(out[2])])
        return out

    def init(self, scene_, *more):
        a = time.process_time()
        real_init(self, scene_, *more)
        problem_s[0] = time.process_time() - a

    adv_mod._Problem.run, adv_mod._Problem.__init__ = run, init
    advice = adv_mod.advise(sc, target, threads=1)  # one run at a time: each run's CPU is its own
    t_end = time.process_time()
    return {"scene": scene, "target": target, "start": t_start, "import": t_import - t_start,
            "scene_load": t_scene - t_import, "problem": problem_s[0], "advise": t_end - t_scene,
            "total": t_end, "rows": rows, "answer": f"{advice.method} {advice.setting_name} = {advice.setting:.4g}",
            "listed": sorted(f"{c['method']} {c['setting']:.4g}" for c in advice.candidates)}


def print_ledger(d: dict) -> None:
    """The table of :func:`ledger_child`'s ledger."""
    rows = d["rows"]
    runs_s = sum(r[4] for r in rows)
    print(f"{d['scene']} --target {d['target']:g}: {d['total']:.2f} s CPU in all: interpreter start "
          f"{d['start']:.2f}, advisor import {d['import']:.2f}, scene load {d['scene_load']:.2f}, problem (model, "
          f"truth, modes) {d['problem']:.2f}, integrations {runs_s:.2f} ({len(rows)} runs), the rest of advise "
          f"{d['advise'] - d['problem'] - runs_s:.2f}")
    print(f"  answer {d['answer']}; listed: {', '.join(d['listed'])}")
    print(f"  {'method':<18} {'phase':<20} {'runs':>4} {'RHS calls':>10} {'CPU s':>7} {'wall s':>7}  "
          f"first run of the method")
    first = {}
    for r in rows:
        first.setdefault(r[0], r)
    groups = {}
    for r in rows:
        g = groups.setdefault((r[0], r[2]), [0, 0.0, 0.0, 0.0])
        g[0] += 1
        g[1] += r[3]
        g[2] += r[4]
        g[3] += r[5]
    for (name, phase), (n, rhs, cpu, wall) in groups.items():
        f = first[name]
        rest = [r for r in rows if r[0] == name and r is not f and r[3] > 0]
        rate = min((r[4] / r[3] for r in rest), default=math.nan)  # CPU s per RHS call, best of the others
        extra = f[4] - rate * f[3] if math.isfinite(rate) else math.nan
        note = (f"{f[4]:.3f} s CPU ({extra:.3f} s above its calls at the method's best rate)"
                if f[2] == phase else "")
        print(f"  {name:<18} {phase:<20} {n:>4} {rhs:>10.3g} {cpu:>7.3f} {wall:>7.3f}  {note}")
    seen = {}
    for r in rows:
        if r[2] != "timing":
            seen[(r[0], r[1])] = seen.get((r[0], r[1]), 0) + 1
    twice = [f"{k[0]} {k[1]:.4g} x{v}" for k, v in seen.items() if v > 1]
    print(f"  run more than once outside timing repeats: {', '.join(twice) if twice else 'none'}")


def _ledger(args) -> None:
    for scene in args.scenes:
        r = subprocess.run([args.after, __file__, "--ledger-child", scene, "--target", args.target],
                           capture_output=True, text=True)
        if r.returncode != 0:
            raise SystemExit(f"bench_advisor: the ledger of {scene} failed: {r.stderr.strip()[-500:]}")
        print_ledger(json.loads(r.stdout.strip().splitlines()[-1]))


def _tight_planar4():
    """A hand-written numba RK4 loop of planar4 (one mass ``m`` on four springs
    ``k`` of natural length ``l`` to anchors ``(ax[j], ay[j])``), state
    ``(x, y, vx, vy)``; returns the final state only."""
    from numba import njit

    @njit(error_model="numpy")
    def force(x, y, k, l_, ax, ay):
        fx = fy = 0.0
        for j in range(4):
            dx, dy = x - ax[j], y - ay[j]
            r = math.sqrt(dx * dx + dy * dy)
            s = -k * (r - l_) / r
            fx += s * dx
            fy += s * dy
        return fx, fy

    @njit(error_model="numpy")
    def loop(m, k, l_, ax, ay, y0, h, n):
        x, y, vx, vy = y0[0], y0[1], y0[2], y0[3]
        for _ in range(n):
            f1x, f1y = force(x, y, k, l_, ax, ay)
            x2, y2, u2, w2 = x + 0.5 * h * vx, y + 0.5 * h * vy, vx + 0.5 * h * f1x / m, vy + 0.5 * h * f1y / m
            f2x, f2y = force(x2, y2, k, l_, ax, ay)
            x3, y3, u3, w3 = x + 0.5 * h * u2, y + 0.5 * h * w2, vx + 0.5 * h * f2x / m, vy + 0.5 * h * f2y / m
            f3x, f3y = force(x3, y3, k, l_, ax, ay)
            x4, y4, u4, w4 = x + h * u3, y + h * w3, vx + h * f3x / m, vy + h * f3y / m
            f4x, f4y = force(x4, y4, k, l_, ax, ay)
            x += h / 6 * (vx + 2 * u2 + 2 * u3 + u4)
            y += h / 6 * (vy + 2 * w2 + 2 * w3 + w4)
            vx += h / 6 * (f1x + 2 * f2x + 2 * f3x + f4x) / m
            vy += h / 6 * (f1y + 2 * f2y + 2 * f3y + f4y) / m
        out = [x, y, vx, vy]
        return out

    return loop


def _loop(args) -> None:
    import time

    import numpy as np

    from rk4h.references.solvers import integrate
    from rk4h.validation.execute import problem
    from rk4h.validation.scenes import load_scenes

    def best(fn):
        out = math.inf
        for _ in range(max(1, args.rounds)):
            a = time.process_time()
            fn()
            out = min(out, time.process_time() - a)
        return out

    figures = {}
    for name in ("thesis-2dof-case1", "planar4-case2"):
        sc = load_scenes([name])[0]
        model, y0 = problem(sc)
        h = sc.t_end / args.loop_steps
        t = np.array([0.0, sc.t_end])
        integrate("rk4", model, y0, t, h)  # numba's cache load
        figures[name] = best(lambda: integrate("rk4", model, y0, t, h)) / args.loop_steps
        print(f"{name}: integrate('rk4'), {args.loop_steps} steps: {figures[name] * 1e9:.1f} ns/step (CPU)")
        if name == "planar4-case2":
            pm = model.params()
            l_ = pm["l"]
            ax, ay = np.array([-l_, l_, 0.0, 0.0]), np.array([0.0, 0.0, -l_, l_])
            loop = _tight_planar4()
            y = np.asarray(y0, float)
            loop(pm["m"], pm["k"], l_, ax, ay, y, h, 2)  # compile
            tight = best(lambda: loop(pm["m"], pm["k"], l_, ax, ay, y, h, args.loop_steps)) / args.loop_steps
            ref = integrate("rk4", model, y0, t, h).y[:, -1]
            got = loop(pm["m"], pm["k"], l_, ax, ay, y, h, args.loop_steps)
            apart = float(np.max(np.abs(np.asarray(got) - ref)) / np.max(np.abs(ref)))
            print(f"{name}: hand-written loop, same steps: {tight * 1e9:.1f} ns/step; ratio integrate/tight "
                  f"{figures[name] / tight:.2f} (final states {apart:.1e} apart, relative)")
    print(f"ratio planar4-case2 / thesis-2dof-case1 per step: "
          f"{figures['planar4-case2'] / figures['thesis-2dof-case1']:.2f}")
    print(f"load average at the end: {os.getloadavg()[0]:.2f}")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--before", help="a Python whose rk4h is the tree before the change (omit: after only)")
    ap.add_argument("--after", default=sys.executable, help="a Python whose rk4h is the tree after (default: this one)")
    ap.add_argument("--scenes", nargs="+", default=["thesis-2dof-case1", "planar4-case2"])
    ap.add_argument("--target", default="1e-3")
    ap.add_argument("--rounds", type=int, default=2)
    ap.add_argument("--no-warm-up", action="store_true", help="skip the untimed first call (caches known warm)")
    ap.add_argument("--threads-vs-one", action="store_true",
                    help="compare --threads 1 (before) with the default (after), both in the --after tree")
    ap.add_argument("--ledger", action="store_true", help="where one call's CPU goes (a fresh process per scene)")
    ap.add_argument("--ledger-child", metavar="SCENE", help=argparse.SUPPRESS)
    ap.add_argument("--loop", action="store_true", help="planar4-case2's RK4 ns/step beside a hand-written loop")
    ap.add_argument("--loop-steps", type=int, default=2_000_000, help="steps per --loop run (default 2e6)")
    args = ap.parse_args(argv)
    if args.ledger_child:
        print(json.dumps(ledger_child(args.ledger_child, float(args.target))))
        return 0
    if args.ledger or args.loop:
        if args.ledger:
            _ledger(args)
        if args.loop:
            _loop(args)
        return 0
    if args.threads_vs_one:
        sides = [("before", args.after, ("--threads", "1")), ("after", args.after, ())]
    elif args.before:
        sides = [("before", args.before, ()), ("after", args.after, ())]
    else:
        sides = [("after", args.after, ())]
    for scene in args.scenes:
        for _, py, extra in ([] if args.no_warm_up else sides):  # warm-up: disk caches
            _call(py, scene, args.target, extra)
        got = {name: [] for name, _, _ in sides}
        for k in range(args.rounds):
            order = sides if k % 2 == 0 else sides[::-1]
            for name, py, extra in order:
                wall, cpu, load, answer = _call(py, scene, args.target, extra)
                got[name].append((wall, cpu))
                print(f"{scene} {name:6} round {k}: {wall:7.2f} s wall {cpu:7.2f} s CPU  load {load:5.2f}  {answer}",
                      flush=True)
        med = {n: (statistics.median(w for w, _ in v), statistics.median(c for _, c in v)) for n, v in got.items()}
        for n, (w, c) in med.items():
            print(f"{scene} {n:6} median: {w:.2f} s wall, {c:.2f} s CPU")
        if len(sides) == 2:
            (wb, cb), (wa, ca) = med["before"], med["after"]
            print(f"{scene} ratio before/after: wall {wb / wa:.2f}, CPU {cb / ca:.2f}")
    print(f"load average at the end: {os.getloadavg()[0]:.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
