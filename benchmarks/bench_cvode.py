"""CVODE driven by one ``solve`` call vs the Python loop of ``CV_ONE_STEP`` calls (issue 12).

    python benchmarks/bench_cvode.py                 # the three scenes below, 5 repeats
    python benchmarks/bench_cvode.py --tiny          # same code, t_end 5 s, 2 repeats (seconds)
    git show <commit>:references/solvers/cvode.py > /tmp/old_cvode.py
    python benchmarks/bench_cvode.py --old /tmp/old_cvode.py   # "old" = that file's run_cvode

For every CVODE solver and tolerance of each scene (``--scenes``, default
``thesis_2dof_case1 lattice100 pendulums_beats``), on the scene's own output
grid and absolute-tolerance rule (``rk4h.references.solvers.integrate``'s), it runs

- new: ``rk4h.references.solvers.cvode.run_cvode`` (one ``CVODE.solve`` call), and
- old: the one-step loop, ``cvode._run_cvode(..., one_step_loop=True)`` (the
  fallback kept in the module), or ``run_cvode`` of the file given by ``--old``,

``--repeats`` times each, alternated (old, new, old, new, ...), after one
untimed warm-up run of each. Printed per row: ``error_max`` of each against
the scene's truth (``rk4h.references.truth``, exact-modal or real128; the disk
cache is used), n_steps, nfev, the median wall time (``wall_s``: the
integration only) of each with its spread (min-max) and the ratio old/new.
The last lines are the results:

    ratio old/new total wall time (sum of the medians): X
    ratio old/new wall time per row: median X, min X, max X
    check same n_steps and nfev: True/False
    check max |y_old - y_new| / state scale: X
    check max error_max ratio new/old: X

``--per-call`` (issue 29) prints instead where one right-hand-side call's
time goes, per CVODE solver at ``--rtol`` (default 1e-7) on the first of
``--scenes`` (default ``thesis_2dof_case1``), every figure the least of
``--repeats`` runs (15 interleaved rounds of calls for the callbacks alone) measured in
this one process (the least disturbed by a shared machine's load), in
microseconds per RHS call:

    python benchmarks/bench_cvode.py --per-call
    python benchmarks/bench_cvode.py --per-call --old /tmp/old_cvode.py   # old glue beside

- ``run``: a whole ``run_cvode`` (``wall_s / nfev``);
- ``replay``: the same CVODE run (same options, same steps and nfev, checked)
  with a right-hand side that copies the recorded result of each call
  (``zp[:] = next(rows)``): scikit-sundae's wrapper and CVODE itself plus a
  one-line Python frame, the floor for any Python right-hand side;
- ``glue``: the ``rhsfn`` that ``run_cvode`` hands CVODE (captured from the
  ``CVODE`` constructor), called from a Python loop with the read-only state
  and writable output scikit-sundae passes: our frame(s) plus the compiled
  right-hand side and its numba call; ``jac``: the Jacobian callback per
  call, and times ``njev / nfev`` per RHS call;
- ``dispatch``: the compiled right-hand side through numba's dispatcher
  (8 arguments, type resolution per call); ``entry``: the same through its
  compiled entry point (no type resolution); ``empty``: a Python function of
  ``(t, z, zp)`` that does nothing; ``replay frame``: the replay function
  alone;
- ``sundae+cvode`` = ``run - glue - jac per RHS call``: scikit-sundae's
  wrapper (two ndarrays made from CVODE's vectors, the Python call) and
  CVODE's own work, what a user with any Python right-hand side pays;
- scipy's DOP853 (``run_dop853``, the timed rows) at the same ``--rtol``:
  the run per RHS call and the right-hand-side wrapper it hands scipy (our
  share), beside ``--old-dop853 FILE``'s when given.

The one-step loop of the module takes the same internal steps as ``solve``,
so the ``check`` lines must show equal counters and identical trajectories
(0.0); against an older file (``--old``) whose loop aimed its first step at
``t_end`` rather than at the first output time, the first step differs and so
do the counters, a little, and the trajectories, within the tolerance.
Timings are machine- and load-dependent and never asserted.

``--compiled`` (issue 29) compares, in one run with the load, scikit-sundae's
CVODE (``cvode.run_cvode``: a Python callback per evaluation, the timed rows)
with the same CVODE driven through ``ctypes`` with compiled callbacks
(``cvode_compiled.run_cvode_compiled``: untimed work) on ``--compiled-scenes``
(default ``chain10_mode2 planar4_case2 thesis_2dof_case1``) at rtol 1e-8 and
1e-12, both CVODE methods, ``--repeats`` interleaved runs after one untimed
warm-up each. Per row: steps, nfev, the median wall time of each, the
microseconds per right-hand-side call (``wall_s / nfev``) and the ratio
compiled/scikit-sundae; then the whole-run ratio (sum of the medians) and the
check that states, steps and nfev are equal (bit for bit):

    python benchmarks/bench_cvode.py --compiled
"""
from __future__ import annotations

import argparse
import importlib.util
import math
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))  # the repository, installed or not

from rk4h.references.solvers import absolute_tolerance  # noqa: E402
from rk4h.fast.solve import compiled_entry  # noqa: E402
from rk4h.references.solvers import cvode  # noqa: E402
from rk4h.references.truth import reference_solution  # noqa: E402
from rk4h.validation import metrics  # noqa: E402
from rk4h.validation.scenes import SCENE_DIR, load_scene  # noqa: E402

SCENES = ("thesis_2dof_case1", "lattice100", "pendulums_beats")
CVODE = ("cvode-adams", "cvode-bdf")


def problem(name, tiny):
    """``(scene, model, y0, t)`` of the shipped scene file ``name``; ``tiny``:
    outputs up to t = 5 s only."""
    scene = load_scene(SCENE_DIR / f"{name}.toml")
    model, y0, t = scene.build_model(), scene.y0(), scene.t_eval()
    return scene, model, y0, (t[t <= 5.0] if tiny else t)


def load_old(path):
    """``run_cvode`` of an older ``references/solvers/cvode.py`` (its relative
    imports resolved inside ``rk4h.references.solvers``)."""
    spec = importlib.util.spec_from_file_location("rk4h.references.solvers._cvode_old", path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod.run_cvode


class _Capture:
    """Stands in for ``sksundae.cvode.CVODE`` while a run is built: keeps the
    callbacks it is given (``rhsfn``, ``jacfn``) and builds the real solver."""

    def __init__(self, real):
        self.real, self.rhsfn, self.opts = real, None, None

    def __call__(self, rhsfn, **opts):
        self.rhsfn, self.opts = rhsfn, opts
        return self.real(rhsfn, **opts)


def _per_call_times(cases, n, rounds=15):
    """``{label: us}``: the least over ``rounds`` rounds of the time of one
    ``fn(*args)`` for each ``(label, fn, args)`` of ``cases``, ``n`` calls a
    round, the cases interleaved round by round (the same load for each)."""
    best = {label: math.inf for label, _, _ in cases}
    for _ in range(rounds):
        for label, fn, args in cases:
            k = max(1, n // 10) if label.startswith("jac") else n
            start = time.perf_counter()
            for _ in range(k):
                fn(*args)
            best[label] = min(best[label], (time.perf_counter() - start) / k * 1e6)
    return best


def per_call(args):
    """The ``--per-call`` table (module docstring)."""
    import sksundae.cvode as skc

    from rk4h.references.solvers.base import compiled_rhs

    runs = {"new": cvode.run_cvode}
    if args.old:
        runs["old"] = load_old(args.old)
    scene, model, y0, t = problem(args.scenes[0], args.tiny)
    n2 = y0.size
    print(f"{scene.name}: {model.n_dof} DOF, {t.size} outputs to t = {t[-1]:g} s, rtol {args.rtol:g}; "
          f"least of {args.repeats} runs, microseconds per right-hand-side call")
    real = skc.CVODE
    for solver in CVODE:
        atol = absolute_tolerance(model, y0, args.rtol)
        glue, ref = {}, None
        for which, fn in runs.items():
            cap = _Capture(real)
            skc.CVODE = cap
            try:
                r = fn(solver, model, y0, t, args.rtol, atol)
            finally:
                skc.CVODE = real
            assert r.ok, r.message
            ref = ref or r
            assert (r.n_steps, r.nfev) == (ref.n_steps, ref.nfev) and np.array_equal(r.y, ref.y), which
            glue[which] = (cap.rhsfn, cap.opts.get("jacfn"))
        # record every call's result, then replay it: the same steps with no model
        rows = []
        rec_rhs = glue["new"][0]

        def record(tt, z, zp):
            rec_rhs(tt, z, zp)
            rows.append(zp.copy())

        from rk4h.references.solvers.cvode import _options, interleave
        perm = interleave(n2 // 2)
        opts = _options(model, perm, {"cvode-adams": "Adams", "cvode-bdf": "BDF"}[solver], args.rtol, atol,
                        cvode.DEFAULT_MAX_STEPS)

        def replay_run(fun):
            s = real(fun, **opts)
            start = time.perf_counter()
            res = s.solve(t, y0[perm])
            return time.perf_counter() - start, res

        _, res_rec = replay_run(record)
        table = np.array(rows)

        def replay_once():
            it = iter(table)

            def replay(tt, z, zp):
                zp[:] = next(it)

            wall, res = replay_run(replay)
            assert res.success and res.nfev == res_rec.nfev and np.array_equal(res.y, res_rec.y)
            return wall / table.shape[0] * 1e6

        nfev = ref.nfev
        walls = {w: [] for w in runs}
        replays = []
        for _ in range(args.repeats):
            for which, fn in runs.items():
                walls[which].append(fn(solver, model, y0, t, args.rtol, atol).wall_s / nfev * 1e6)
            replays.append(replay_once())
        # the callbacks alone, called as scikit-sundae calls them
        z = y0[perm].copy()
        z.setflags(write=False)
        zp = np.empty(n2)
        JJ = np.zeros((n2, n2))
        n = 20000
        it = iter(np.tile(table[:1], (16 * n, 1)))

        def replay_frame(tt, z, zp):
            zp[:] = next(it)

        def empty(tt, z, zp):
            pass

        fast = compiled_rhs(model)
        parts = fast.permuted_parts(perm)
        cargs = (parts[1], parts[2], parts[3], z, zp) + parts[4:]
        entry = compiled_entry(parts[0], cargs)
        njev = ref.extra["njev"]
        cases = [("empty", empty, (0.0, z, zp)), ("replay frame", replay_frame, (0.0, z, zp)),
                 ("dispatch", parts[0], cargs), ("entry", entry, cargs)]
        for which in runs:
            rhsfn, jacfn = glue[which]
            cases.append((f"glue {which}", rhsfn, (0.0, z, zp)))
            if jacfn is not None:
                cases.append((f"jac {which}", jacfn, (0.0, z, zp, JJ)))
        line = _per_call_times(cases, n)
        print(f"\n{solver}: n_steps {ref.n_steps}, nfev {nfev}, njev {njev} ({ref.extra.get('linsolver')}); "
              f"replay: {np.min(replays):.2f} us per call")
        print(f"  compiled RHS alone: numba dispatcher {line['dispatch']:.2f}, entry point {line['entry']:.2f}; "
              f"empty Python function {line['empty']:.2f}; replay frame {line['replay frame']:.2f}")
        for which in runs:
            g, j = line[f"glue {which}"], line.get(f"jac {which}", 0.0)
            run = float(np.min(walls[which]))
            print(f"  {which}: run {run:.2f} = glue {g:.2f} + jac {j:.2f} x {njev / nfev:.4f} "
                  f"+ sundae+cvode {run - g - j * njev / nfev:.2f}; "
                  f"our frames {g - line['entry' if which == 'new' else 'dispatch']:.2f}")
    dop853_per_call(args, model, y0, t, n)


def dop853_per_call(args, model, y0, t, n):
    """The ``--per-call`` lines of scipy's DOP853 (``run_dop853``, the timed
    rows): whole run per RHS call, and its right-hand-side wrapper alone
    (captured from scipy's ``DOP853`` constructor), new and ``--old-dop853``."""
    import scipy.integrate as si

    from rk4h.references.solvers import dop853

    runs = {"new": dop853.run_dop853}
    if args.old_dop853:
        spec = importlib.util.spec_from_file_location("rk4h.references.solvers._dop853_old", args.old_dop853)
        mod = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(mod)
        runs["old"] = mod.run_dop853
    real = si.DOP853
    atol = absolute_tolerance(model, y0, args.rtol)
    funs, ref = {}, None
    for which, fn in runs.items():
        got = {}

        def capture(fun, *a, **k):
            got["fun"] = fun
            return real(fun, *a, **k)

        si.DOP853 = capture
        try:
            r = fn(model, y0, t, args.rtol, atol)
        finally:
            si.DOP853 = real
        assert r.ok, r.message
        ref = ref or r
        assert (r.n_steps, r.nfev) == (ref.n_steps, ref.nfev) and np.array_equal(r.y, ref.y), which
        funs[which] = got["fun"]
    walls = {w: [] for w in runs}
    for _ in range(args.repeats):
        for which, fn in runs.items():
            walls[which].append(fn(model, y0, t, args.rtol, atol).wall_s / ref.nfev * 1e6)
    y = y0.astype(float)
    print(f"\ndop853 (scipy, the timed rows): n_steps {ref.n_steps}, nfev {ref.nfev}")
    line = _per_call_times([(which, funs[which], (0.0, y)) for which in runs], n)
    for which in runs:
        g = line[which]
        run = float(np.min(walls[which]))
        print(f"  {which}: run {run:.2f} = RHS wrapper {g:.2f} ({100 * g / run:.1f}%) + scipy's stepping "
              f"{run - g:.2f}")


COMPILED_SCENES = ("chain10_mode2", "planar4_case2", "thesis_2dof_case1")


def compiled_table(args, repeats):
    """The ``--compiled`` table (module docstring)."""
    from rk4h.references.solvers.cvode_compiled import run_cvode_compiled, sundials_library

    paths, version = sundials_library()
    print(f"scikit-sundae: cvode.run_cvode (timed rows)\ncompiled: cvode_compiled.run_cvode_compiled, SUNDIALS "
          f"{version if paths else '(unavailable: ' + str(version) + ')'}\nrepeats: {repeats} (median), interleaved")
    print(f"\n{'scene':18s} {'solver':12s} {'rtol':>7s} {'steps':>7s} {'nfev':>7s} {'sundae s':>9s} "
          f"{'compiled s':>10s} {'us/call sundae':>14s} {'us/call compiled':>16s} {'compiled/sundae':>15s}")
    rows = []
    for name in args.compiled_scenes:
        scene, model, y0, t = problem(name, args.tiny)
        for solver in CVODE:
            for rtol in (1e-8, 1e-12):
                atol = absolute_tolerance(model, y0, rtol)
                runners = {"sundae": lambda: cvode.run_cvode(solver, model, y0, t, rtol, atol),
                           "compiled": lambda: run_cvode_compiled(solver, model, y0, t, rtol, atol)}
                first = {w: fn() for w, fn in runners.items()}  # warm-up, untimed (compiles, builds)
                walls = {w: [] for w in runners}
                for _ in range(repeats):
                    for w, fn in runners.items():
                        walls[w].append(fn().wall_s)
                med = {w: float(np.median(v)) for w, v in walls.items()}
                a, b = first["sundae"], first["compiled"]
                same = (a.n_steps == b.n_steps and a.nfev == b.nfev and a.status == b.status
                        and np.array_equal(a.y, b.y, equal_nan=True))
                rows.append(dict(sundae=med["sundae"], compiled=med["compiled"], same=same,
                                 impl=b.extra.get("implementation")))
                print(f"{scene.name:18s} {solver:12s} {rtol:7.0e} {a.n_steps:7d} {a.nfev:7d} {med['sundae']:9.4f} "
                      f"{med['compiled']:10.4f} {med['sundae'] / a.nfev * 1e6:14.2f} "
                      f"{med['compiled'] / max(b.nfev, 1) * 1e6:16.2f} {med['compiled'] / med['sundae']:15.3f}"
                      + ("" if same else "  DIFFERENT") + ("" if rows[-1]["impl"] == "compiled" else
                                                          f"  fell back: {b.extra.get('compiled_error')}"),
                      flush=True)
    ratios = [r["compiled"] / r["sundae"] for r in rows]
    print()
    print(f"ratio compiled/scikit-sundae whole run (sum of the medians): "
          f"{sum(r['compiled'] for r in rows) / sum(r['sundae'] for r in rows):.3f}")
    print(f"ratio compiled/scikit-sundae per row: median {np.median(ratios):.3f}, min {min(ratios):.3f}, "
          f"max {max(ratios):.3f}")
    print(f"check same states (bit for bit), n_steps, nfev and status: {all(r['same'] for r in rows)}")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenes", nargs="+", default=list(SCENES))
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--tiny", action="store_true", help="t_end 5 s, 2 repeats")
    ap.add_argument("--old", default=None, help="an older cvode.py whose run_cvode is 'old'")
    ap.add_argument("--per-call", action="store_true", help="where one RHS call's time goes (docstring)")
    ap.add_argument("--rtol", type=float, default=1e-7, help="the --per-call tolerance")
    ap.add_argument("--old-dop853", default=None, help="--per-call: an older dop853.py whose run_dop853 is 'old'")
    ap.add_argument("--compiled", action="store_true", help="compiled callbacks vs scikit-sundae (docstring)")
    ap.add_argument("--compiled-scenes", nargs="+", default=list(COMPILED_SCENES))
    args = ap.parse_args(argv)
    repeats = 2 if args.tiny else args.repeats
    if args.compiled:
        return compiled_table(args, repeats)
    if args.per_call:
        args.repeats = repeats
        return per_call(args)

    new = cvode.run_cvode
    if args.old:
        old = load_old(args.old)
        old_name = f"run_cvode of {args.old}"
    else:
        def old(solver, model, y0, t, rtol, atol):
            return cvode._run_cvode(solver, model, y0, t, rtol, atol, cvode.DEFAULT_MAX_STEPS,
                                    one_step_loop=True)
        old_name = "the one-step loop (cvode._run_cvode(..., one_step_loop=True))"
    print(f"old: {old_name}\nnew: cvode.run_cvode (one CVODE.solve call)\nrepeats: {repeats} (median)")

    rows = []
    for name in args.scenes:
        scene, model, y0, t = problem(name, args.tiny)
        y_ref = np.asarray(reference_solution(model, y0, t).y, float)
        scale = float(np.max(np.abs(y_ref)))
        print(f"\n{scene.name}: {model.n_dof} DOF, {t.size} outputs to t = {t[-1]:g} s")
        print(f"{'solver':12s} {'rtol':>7s} {'err old':>9s} {'err new':>9s} {'steps old':>9s} {'steps new':>9s} "
              f"{'nfev old':>9s} {'nfev new':>9s} {'wall old (spread)':>22s} {'wall new (spread)':>22s} "
              f"{'old/new':>7s}")
        for solver in [s for s in scene.solvers if s in CVODE]:
            for rtol in scene.tolerances:
                atol = absolute_tolerance(model, y0, rtol)
                first = {"old": old(solver, model, y0, t, rtol, atol),  # warm-up, untimed
                         "new": new(solver, model, y0, t, rtol, atol)}
                walls = {"old": [], "new": []}
                for _ in range(repeats):
                    for which, fn in (("old", old), ("new", new)):
                        walls[which].append(fn(solver, model, y0, t, rtol, atol).wall_s)
                r_old, r_new = first["old"], first["new"]
                med = {w: float(np.median(v)) for w, v in walls.items()}
                row = dict(scene=scene.name, solver=solver, rtol=rtol,
                           err_old=metrics.error_max(r_old.y, y_ref), err_new=metrics.error_max(r_new.y, y_ref),
                           steps=(r_old.n_steps, r_new.n_steps), nfev=(r_old.nfev, r_new.nfev),
                           status=(r_old.status.value, r_new.status.value),
                           dy=float(np.max(np.abs(r_old.y - r_new.y))) / scale,
                           wall_old=med["old"], wall_new=med["new"], ratio=med["old"] / med["new"])
                rows.append(row)
                spread = {w: f"{min(v):.4f}-{max(v):.4f}" for w, v in walls.items()}
                print(f"{solver:12s} {rtol:7.0e} {row['err_old']:9.2e} {row['err_new']:9.2e} "
                      f"{r_old.n_steps:9d} {r_new.n_steps:9d} {r_old.nfev:9d} {r_new.nfev:9d} "
                      f"{med['old']:8.4f} ({spread['old']:>13s}) {med['new']:8.4f} ({spread['new']:>13s}) "
                      f"{row['ratio']:7.2f}" + ("" if row["status"] == ("ok", "ok") else f"  status {row['status']}"),
                      flush=True)

    ratios = [r["ratio"] for r in rows]
    total = sum(r["wall_old"] for r in rows) / sum(r["wall_new"] for r in rows)
    err_ratio = max((r["err_new"] / r["err_old"] for r in rows if r["err_old"] > 0), default=math.nan)
    print()
    print(f"ratio old/new total wall time (sum of the medians): {total:.2f}")
    print(f"ratio old/new wall time per row: median {np.median(ratios):.2f}, min {min(ratios):.2f}, "
          f"max {max(ratios):.2f}")
    same = all(r["steps"][0] == r["steps"][1] and r["nfev"][0] == r["nfev"][1] for r in rows)
    print(f"check same n_steps and nfev: {same}")
    print(f"check max |y_old - y_new| / state scale: {max(r['dy'] for r in rows):.3g}")
    print(f"check max error_max ratio new/old: {err_ratio:.3g}")


if __name__ == "__main__":
    t0 = time.perf_counter()
    main()
    print(f"(benchmark took {time.perf_counter() - t0:.0f} s)")
