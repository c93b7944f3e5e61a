"""Run the validation scenes and write the report.

Usage::

    python validation/run_all.py [--quick] [--out DIR] [--scene PATH ...] [--repeats N] [--no-figures]
                                 [--max-output-points N] [--max-steps N] [--max-truth-steps N]
                                 [--replace] [--workers N] [--exclusive-timing] [--scheduler ADDRESS]
                                 [--resume | --fresh] [--allow-code]
    python -m validation.run_all ...

Runs every scene in ``validation/scenes/`` (``--quick``: those marked
``quick = true``; ``--scene``: the files named) and writes CSV tables,
figures and ``index.md`` into ``DIR`` (default: ``reports/`` at the
repository root). All scenes are validated, and their cost estimated
(:mod:`validation.budget`), before anything runs.

``DIR`` is replaced only if it is absent, empty, or a report this tool wrote
and nothing has changed in since (:mod:`validation.atomic`: a marker file with
a manifest); anything else is refused before any work, untouched. A ``--quick``
or ``--scene`` run never replaces a full report unless ``--replace`` is given.

A scene the project does not ship may name code (a ``command`` or ``python``
method, a ``module:Class`` model): it is refused, exit 2, before anything is
imported or started, unless ``--allow-code`` (or ``RK4H_ALLOW_CODE=1``) is
given (:mod:`validation.scenes`, "Code in a scene").
Runs into one ``DIR`` are serialized by ``flock`` on ``.<DIR>.lock`` beside it.
The report is written into a fresh directory beside ``DIR`` and swapped into
place at the end (one atomic ``renameat2`` exchange where the filesystem has
it), so an interrupted or killed run never leaves a half-written or mixed
report; leftovers of killed runs are cleaned at the next start. SIGINT
(Ctrl-C) and SIGTERM stop the run, remove its temporary directory and print
which scenes had finished.

The work is a plan (:mod:`validation.plan`): one record per spec, executed
on ``--workers`` local processes (default: every core this process may use)
or on a Dask cluster (``--scheduler``); the timed runs come last, one per
worker (``--exclusive-timing``: one at a time, the other workers idle; see
:mod:`validation.engine`). Each record is written to ``.<DIR>.records``
beside ``DIR`` as it arrives (:mod:`validation.records`). After an interrupted
or failed run, ``--resume`` reruns only the specs that have no usable record
(none, one that does not verify, or one made by other code, user code,
libraries or BLAS kernel: the summary line counts them); ``--fresh`` moves
the earlier records aside (``.<DIR>.records-aside-<UTC time>``, named on
stderr) and runs everything; with neither, a run that finds records of an
earlier run refuses (exit 2) and leaves them. A run that stops (interrupt,
crash, environment) keeps its records; they are removed once the report is
in place.

Exit status: 0 every expectation held; 1 at least one failed (``index.md``
lists them first); 2 bad input (one line on stderr naming the file and the
field, or the flag, or an ``--out`` it must not replace); 3 the environment
refused (lock held, not writable, disk full, mount point, name too long: one
line); 130 interrupted by SIGINT, 143 by SIGTERM.
"""
from __future__ import annotations

try:
    import os
    import signal

    if __name__ == "__main__":
        # Until main() installs its handlers (imports take a while), a signal ends
        # the process with one line; nothing has been written yet.
        def _early_exit(signum, frame):
            os.write(2, f"run_all: interrupted ({signal.Signals(signum).name}) before any scene ran\n".encode())
            os._exit(128 + signum)

        signal.signal(signal.SIGINT, _early_exit)
        signal.signal(signal.SIGTERM, _early_exit)
except KeyboardInterrupt:  # SIGINT while the early handler was being installed
    import sys as _sys

    _sys.stderr.write("run_all: interrupted (SIGINT) before any scene ran\n")
    _sys.stderr.flush()
    raise SystemExit(130) from None

import argparse
import errno
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
if __name__ == "__main__" and __package__ in (None, ""):
    # Run as a script: import the package `validation`, not its modules as top-level names.
    sys.path[:] = [p for p in sys.path if Path(p or ".").resolve() != REPO / "validation"]
    sys.path.insert(0, str(REPO))

__all__ = ["main", "run", "Interrupted", "exit_process"]

#: The default --out: ``reports`` in the working directory (in a checkout
#: run from its root, the committed report).
DEFAULT_OUT = Path("reports")
REPEATS_FULL, REPEATS_QUICK = 3, 1
#: Largest --repeats (each timed run is repeated this often at most).
MAX_REPEATS = 100


class _Parser(argparse.ArgumentParser):
    def error(self, message):  # one line, exit 2, no usage dump
        sys.stderr.write(f"run_all: {message}\n")
        raise SystemExit(2)


def _int_at_least(lo, hi=None):
    want = f"an integer >= {lo}" if hi is None else f"an integer from {lo} to {hi}"

    def parse(text):
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"must be {want}, got {text!r}") from None
        if value < lo or (hi is not None and value > hi):
            raise argparse.ArgumentTypeError(f"must be {want}, got {text!r}")
        return value
    return parse


def _positive_float(text):
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be a positive number, got {text!r}") from None
    if not value > 0 or value == float("inf"):
        raise argparse.ArgumentTypeError(f"must be a positive finite number, got {text!r}")
    return value


_EXAMPLES = """examples:
  %(prog)s --quick --out /tmp/quick               the quick scenes (a minute), report in /tmp/quick
  %(prog)s --scene thesis-2dof-case1 --out /tmp/c1  one shipped scene, by name or path
  %(prog)s --scene my.toml --allow-code --out /tmp/m  a scene of yours that names code (read it first)
  %(prog)s --out /tmp/r --resume                  finish an interrupted run from its records
  %(prog)s                                        every shipped scene into ./reports

exit status: 0 every expectation held; 1 one failed (listed first in index.md); 2 bad input;
3 the environment refused (lock held, disk full, unwritable); 130/143 interrupted (SIGINT/SIGTERM)."""


def _parser(prog="run_all.py"):
    from validation.budget import MAX_STEPS, MAX_TRUTH_STEPS

    p = _Parser(prog=prog, description="Run the validation scenes (every shipped one by default) and write the "
                "report: tables, figures and index.md.", epilog=_EXAMPLES,
                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--quick", action="store_true", help="run only the scenes marked quick = true")
    p.add_argument("--out", default=str(DEFAULT_OUT), help="output directory (default: ./reports of the working directory)")
    p.add_argument("--scene", action="append", default=[], metavar="PATH",
                   help="scene file to run (repeatable; default: all in validation/scenes/)")
    p.add_argument("--repeats", type=_int_at_least(1, MAX_REPEATS), default=None,
                   help=f"timing repeats per run, 1..{MAX_REPEATS} (median; default {REPEATS_FULL}, "
                        f"--quick {REPEATS_QUICK})")
    p.add_argument("--replace", action="store_true",
                   help="let a --quick or --scene run replace a full report in --out")
    p.add_argument("--no-figures", action="store_true", help="tables and index.md only")
    p.add_argument("--workers", type=_int_at_least(1, 1024), default=None, metavar="N",
                   help="local worker processes (default: $RK4H_WORKERS, else the cores this process may "
                        "use; 1: no pool)")
    p.add_argument("--exclusive-timing", action="store_true",
                   help="time each run alone, the other workers idle (slower; for a machine where parallel "
                        "runs disturb each other's timings)")
    p.add_argument("--scheduler", default=None, metavar="ADDRESS",
                   help="run the plan on the Dask distributed scheduler at ADDRESS (tcp://host:port)")
    again = p.add_mutually_exclusive_group()
    again.add_argument("--resume", action="store_true",
                       help="use the records of an interrupted run into the same --out and run only the rest "
                            "(records that do not verify or were made by other code or libraries are rerun)")
    again.add_argument("--fresh", action="store_true",
                       help="move the records of an earlier run into the same --out aside and run everything")
    p.add_argument("--allow-code", action="store_true",
                   help="run the programs and import the Python modules that scenes not shipped with the "
                        "project name (command/python methods, module:Class models); read them first "
                        "(default: refused; also RK4H_ALLOW_CODE=1)")
    p.add_argument("--max-output-points", type=_int_at_least(2), default=None, metavar="N",
                   help="decimate each scene's output grid to at most N points (every k-th point; "
                        "a scene's own [run] max_output_points wins)")
    p.add_argument("--max-steps", type=_positive_float, default=MAX_STEPS, metavar="N",
                   help=f"refuse scenes estimated above N integration steps (default {MAX_STEPS:g})")
    p.add_argument("--max-truth-steps", type=_positive_float, default=MAX_TRUTH_STEPS, metavar="N",
                   help=f"refuse scenes whose quadruple-precision reference is estimated above N Taylor "
                        f"steps (default {MAX_TRUTH_STEPS:g})")
    return p


class Progress:
    """A bar on a terminal, plain lines otherwise: ``total`` is the plan's
    length; the ETA assumes the remaining specs cost the mean so far (the plan
    starts the longest ones, so it errs high early)."""

    def __init__(self, total, stream=None):
        self.total, self.done = max(total, 1), 0
        self.stream = stream or sys.stdout
        self.tty = hasattr(self.stream, "isatty") and self.stream.isatty()
        self.t0 = time.perf_counter()

    def __call__(self, msg):
        self.done += 1
        if self.done > self.total:
            raise RuntimeError(f"progress: unit {self.done} of a plan of {self.total}")
        el = time.perf_counter() - self.t0
        eta = f" ETA {el / self.done * (self.total - self.done):.0f}s" if self.done < self.total else ""
        if self.tty:
            width = 30
            fill = int(width * self.done / self.total)
            line = (f"\r[{'#' * fill}{'.' * (width - fill)}] {self.done}/{self.total} {el:5.0f}s{eta:>10} "
                    f"{msg[:55]:<55}")
            self.stream.write(line)
        elif self._due(el):
            self.stream.write(f"[{self.done}/{self.total}] {el:.1f}s{eta} {msg}\n")
        else:
            return
        self.stream.flush()

    #: Off a terminal (a log file, CI) the first line, then a line at most
    #: every this fraction of the plan or this many seconds, and the last.
    LOG_FRACTION, LOG_SECONDS = 0.05, 10.0

    def _due(self, elapsed) -> bool:
        last_done, last_t = getattr(self, "_last", (0, 0.0))
        if (self.done == 1 or self.done >= self.total or self.done - last_done >= self.LOG_FRACTION * self.total
                or elapsed - last_t >= self.LOG_SECONDS):
            self._last = (self.done, elapsed)
            return True
        return False

    def extend(self, n: int):
        """``n`` more specs to come (confirmation runs planned from the records)."""
        self.total += int(n)

    def close(self):
        if self.tty:
            self.stream.write("\n")
            self.stream.flush()


def _check_run_args(scenes, out_dir, quick, repeats, figures, progress):
    from rk4core.validate import boolean

    from validation.scenes import Scene

    if isinstance(scenes, (str, bytes, Path)) or not hasattr(scenes, "__iter__"):
        raise ValueError(f"`scenes` must be a list of Scene objects, got {scenes!r}")
    scenes = list(scenes)
    for i, s in enumerate(scenes):
        if not isinstance(s, Scene):
            raise ValueError(f"`scenes[{i}]` must be a Scene (validation.scenes.load_scene), got {s!r}")
    if not isinstance(out_dir, (str, Path)) or not Path(out_dir).is_dir():
        raise ValueError(f"`out_dir` must be an existing directory, got {out_dir!r}")
    if isinstance(repeats, bool) or not isinstance(repeats, int) or not 1 <= repeats <= MAX_REPEATS:
        raise ValueError(f"`repeats` must be an integer from 1 to {MAX_REPEATS}, got {repeats!r}")
    boolean("quick", quick)
    boolean("figures", figures)
    if progress is not None and not callable(progress):
        raise ValueError(f"`progress` must be callable or None, got {progress!r}")
    return scenes


def run(scenes, out_dir, *, quick=False, repeats=REPEATS_FULL, figures=True, progress=None, workers=1,
        scheduler=None, store=None, stats=None, exclusive_timing=False, pools=None):
    """Run ``scenes`` and write the report into ``out_dir`` (which must exist).

    The pipeline (``validation.plan`` -> ``validation.engine`` ->
    ``validation.measure`` -> ``validation.draw`` / ``validation.report``):
    every scene's plan is executed (records), then tables, checks and figures
    are computed from the records alone.

    Parameters
    ----------
    scenes : list of validation.scenes.Scene
    out_dir : str or Path
        An existing directory; tables, figures and ``index.md`` are written
        straight into it (:func:`main` passes a fresh temporary directory).
    quick : bool
        Quick mode (the stability study's ``*_quick`` settings).
    repeats : int >= 1
        Timing repeats per run (median).
    figures : bool
        Draw the figures.
    progress : callable(str) or None
        Called once per spec of the plan.
    workers : int >= 1
        Local processes (1: this process).
    scheduler : str or None
        A Dask scheduler's address.
    store : validation.records.RecordStore or None
        Records to resume from and to write.
    stats : validation.engine.PlanStats or None
        Filled with the counts of planned, resumed and executed specs.
    exclusive_timing : bool
        Time each run alone, the other workers idle (default: the timed runs
        run one per worker after the untimed work; see ``validation.engine``).
    pools : validation.engine.LocalPools or None
        Worker processes started by the caller, who closes them (``workers``
        is then their number); default: started here when ``workers > 1``
        and stopped at the end.

    Returns ``(results, failures)``. A fault inside a scene, solver or figure
    is a failure line (and a ``failed`` row where a row exists), never an
    exception; only ``KeyboardInterrupt`` (and :class:`Interrupted`) escape.
    Bad arguments raise ``ValueError`` naming the argument. The names of the
    scenes whose records are complete are kept in ``run.completed``.
    """
    scenes = _check_run_args(scenes, out_dir, quick, repeats, figures, progress)
    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
        raise ValueError(f"`workers` must be an integer >= 1, got {workers!r}")
    if not isinstance(exclusive_timing, bool):
        raise ValueError(f"`exclusive_timing` must be True or False, got {exclusive_timing!r}")
    from validation import engine, interrupt, plan

    t0 = time.perf_counter()
    run.completed = []
    user_progress = progress
    broken = {}
    for scene in scenes:  # a scene whose model cannot be built is one failure line, not one per run
        try:
            scene.build_model()
        except Exception as e:  # noqa: BLE001
            from validation.atomic import is_environment_error

            if is_environment_error(e) or interrupt.pending():
                raise
            broken[scene.name] = f"{scene.name}: the scene raised {type(e).__name__}: " \
                                 f"{str(e).splitlines()[0] if str(e) else ''}"
    jobs = plan.plan_all([s for s in scenes if s.name not in broken], quick=quick, figures=figures,
                         repeats=repeats)
    keys_of = {}
    for scene, spec in jobs:
        keys_of.setdefault(scene.name, set()).add(spec.key)
    finished = set()

    def progress(message):
        # A signal whose exception was swallowed (raised inside a ctypes
        # callback, e.g. numba's compiler notifying its object cache) is
        # recorded: it stops the run at the next work unit.
        if interrupt.pending():
            raise Interrupted(interrupt.pending())
        if user_progress is not None:
            user_progress(message)

    def completed(records):
        for scene in scenes:
            if scene.name not in finished and keys_of.get(scene.name, set()) <= records.keys():
                finished.add(scene.name)
                run.completed.append(scene.name)

    records = {}

    def tick(message):
        completed(records)
        progress(message)

    def grow(extra):  # confirmation runs planned after the plan: a scene is complete with them
        for scene, spec in extra:
            keys_of.setdefault(scene.name, set()).add(spec.key)
            if scene.name in finished:
                finished.discard(scene.name)
                run.completed.remove(scene.name)
        extend = getattr(user_progress, "extend", None)
        if callable(extend):
            extend(len(extra))

    own = pools is None
    if own:
        pools = engine.LocalPools(workers) if workers > 1 else None
    try:
        return _run(scenes, out_dir, jobs, quick, repeats, figures, scheduler, store, stats, pools, records,
                    tick, completed, t0, broken, exclusive_timing, grow)
    finally:
        if own and pools is not None:
            pools.close()


def _run(scenes, out_dir, jobs, quick, repeats, figures, scheduler, store, stats, pools, records, tick,
         completed, t0, broken, exclusive_timing=False, grow=None):
    from validation import atomic, budget, confirm, draw, engine, interrupt, measure, report

    t_run = time.perf_counter()
    stats = stats if stats is not None else engine.PlanStats()
    records = engine.run_plan(jobs, quick=quick, workers=pools.workers if pools else 1, scheduler=scheduler,
                              store=store, progress=tick, cost=budget.spec_cost_function(), stats=stats,
                              records=records, pools=pools, exclusive_timing=exclusive_timing)
    # Confirmation runs of the trust table (validation.confirm): planned from the records, in rounds.
    unplanned = {}
    for _ in range(confirm.MAX_ROUNDS):
        extra = []
        for scene in scenes:
            if scene.name in broken or scene.name in unplanned:
                continue
            try:
                extra += [(scene, s) for s in confirm.next_specs(scene, [s for sc, s in jobs if sc is scene],
                                                                 records)]
            except Exception as e:  # noqa: BLE001 - one scene's fault is its failure line
                if atomic.is_environment_error(e) or interrupt.pending():
                    raise
                unplanned[scene.name] = (f"{scene.name}: the confirmation runs could not be planned: "
                                         f"{type(e).__name__}: {str(e).splitlines()[0] if str(e) else ''}")
        if not extra:
            break
        if grow is not None:
            grow(extra)
        jobs = jobs + extra
        more = engine.PlanStats()
        engine.run_plan(extra, quick=quick, workers=pools.workers if pools else 1, scheduler=scheduler,
                        store=store, progress=tick, cost=budget.spec_cost_function(), stats=more,
                        records=records, pools=pools, exclusive_timing=exclusive_timing)
        if stats is not None:
            stats.planned += more.planned
            stats.resumed += more.resumed
            stats.executed += more.executed
    completed(records)
    t_measure = time.perf_counter()
    results, tables, failures, findings = [], {}, [], []
    for scene in scenes:
        specs = [s for sc, s in jobs if sc is scene]
        if scene.name in broken:
            r = measure.SceneTables(scene.name)
            r.check("scene", False, broken[scene.name])
            results.append(r)
            continue
        try:
            r = measure.measure(scene, specs, records, quick=quick, figures=figures)
        except Exception as e:  # noqa: BLE001 - one scene's fault does not stop the run
            if interrupt.pending():
                raise Interrupted(interrupt.pending()) from e
            if atomic.is_environment_error(e):
                raise
            r = measure.SceneTables(scene.name)
            r.check("scene", False, f"{scene.name}: the scene raised {type(e).__name__}: "
                                    f"{str(e).splitlines()[0] if str(e) else ''}")
        if scene.name in unplanned:
            r.check("confirmation runs planned", False, unplanned[scene.name])
        results.append(r)
    figure_jobs = draw.sweep_jobs(scenes, results) if figures else []
    by_name = {s.name: s for s in scenes}
    for r in results:
        for name, rows in r.tables.items():
            tables.setdefault(name, []).extend(rows)
    from validation import timing_context

    load = timing_context.load_context(
        stats.load_before, stats.load_after, executed_timed=stats.timed_executed,
        resumed_timed=stats.timed_resumed,
        where="of the machine running run_all.py, not of the Dask workers" if scheduler else "")
    if tables.get("cheapest"):
        tables["cheapest"] = timing_context.gate_time_verdicts(tables["cheapest"], load)
    extra = []
    if figures and tables.get("cheapest"):
        try:
            extra.append(_crossover_job(tables["cheapest"]))
        except Exception as e:  # noqa: BLE001
            if atomic.is_environment_error(e) or interrupt.pending():
                raise
            findings.append(f"(crossover figure not drawn: {type(e).__name__}: {e})")
    t_draw = time.perf_counter()
    if figures:
        _draw_all(results, figure_jobs, out_dir, by_name, pools, extra=extra)
    t_write = time.perf_counter()
    for r in results:
        failures += r.failures
        findings += r.findings
    findings = timing_context.findings(load) + report.summarize(tables) + findings
    from validation import outputs

    files, file_failures = outputs.write_files(out_dir, results)  # e.g. the trajectory output's netCDF
    findings += [str(sentence) for _, sentence in files]
    failures += file_failures
    front = list(dict.fromkeys(k for s in scenes for k in (getattr(s, "sweep", None) or {})))
    paths = report.write_tables(out_dir, tables, front=front)
    report.write_index(out_dir, results=results, tables=tables, table_paths=paths,
                       failures=failures, findings=findings, mode="quick" if quick else "full",
                       repeats=repeats, seconds=time.perf_counter() - t0, n_scenes=len(scenes),
                       timing=getattr(stats, "timing", None), load=load,
                       stability_methods={s.name: (s.stability or {}).get("method") for s in scenes
                                          if (s.stability or {}).get("method")})
    if stats is not None:
        stats.phases = {"plan": t_run - t0, "runs": t_measure - t_run, "measure": t_draw - t_measure,
                        "figures": t_write - t_draw, "write": time.perf_counter() - t_write}
    return results, failures


def _true(x) -> bool:
    """A ``confirmed`` cell: True, or its CSV spelling."""
    return str(x).strip().lower() == "true"  # bool, numpy.bool_ or the CSV's text


#: Relative drawing cost of a figure job by kind (a state job draws two or
#: three figures; ``python benchmarks/bench_figures.py`` gives each kind's time).
_DRAW_COST = {"state": 3.0, "dispersion": 1.5, "work_precision": 1.2}


def _crossover_job(cheapest):
    """The all-scenes crossover grid (a figure job), from the trust table's
    rows: each cell shows the RHS-call verdict (deterministic), a solver only
    where its winning run was measured and met the target (``confirmed`` /
    ``alt_confirmed``); ``tie`` and ``unmeasured`` cells name no solver."""
    import pandas as pd

    from validation import measure

    rows = []
    for r in pd.DataFrame(cheapest).to_dict("records"):
        v = r["verdict_rhs"]
        if v == r["method"] and _true(r.get("confirmed")):
            solver, rhs = v, r["rhs"]
        elif v == r["alternative"] and v and _true(r.get("alt_confirmed")):
            solver, rhs = v, r["alt_rhs"]
        else:
            solver, rhs = "", float("nan")
        rows.append({"scene": r["scene"], "target_error": r["target_error"], "solver": solver, "rhs": rhs,
                     "cell": "" if solver else (v if v in ("tie", "unmeasured") else "unmeasured")})
    res = measure.SceneTables("all scenes")
    res.figures.append(measure.FigureJob("all scenes", "crossover", {"rows": rows}))
    return res


def _draw_all(results, sweep_jobs, out_dir, by_name, pools, extra=()):
    """Draw every figure job of ``results``, of ``sweep_jobs`` and of
    ``extra`` (on the worker processes when there are any); a plotting fault
    is a failed check of its scene. The sweeps' and ``extra``'s results are
    appended to ``results``."""
    from validation import atomic, interrupt, measure
    from validation.draw import draw_job

    sweeps = {}
    for job in sweep_jobs:
        sweeps.setdefault(job.scene, measure.SceneTables(f"sweep {job.scene}"))
    work = ([(r, j) for r in results for j in r.figures] + [(sweeps[j.scene], j) for j in sweep_jobs]
            + [(r, j) for r in extra for j in r.figures])
    # Every job gets its scene: state figures build the model from it, all draw its own methods' styles.
    items = [(j, out_dir, by_name.get(j.scene)) for _, j in work]
    if pools is not None and len(items) > 1:
        outs = pools.map(draw_job, items, cost=[_DRAW_COST.get(j.kind, 1.0) for _, j in work])
    else:
        outs = []
        for item in items:
            try:
                outs.append(draw_job(*item))
            except Exception as e:  # noqa: BLE001
                if atomic.is_environment_error(e) or interrupt.pending():
                    raise
                outs.append(e)
    for (r, job), out in zip(work, outs):
        if isinstance(out, BaseException):
            if atomic.is_environment_error(out):
                raise out
            r.check(f"{job.kind} figure", False, f"{job.scene}: the {job.kind} figure failed: "
                                                  f"{type(out).__name__}: {str(out).splitlines()[0] if str(out) else ''}")
        else:
            r.drawn.extend(out)
    results.extend(sweeps.values())
    results.extend(extra)


run.completed = []


class Interrupted(KeyboardInterrupt):
    """SIGINT or SIGTERM arrived; ``signum`` says which."""

    def __init__(self, signum):
        super().__init__(signal.Signals(signum).name)
        self.signum = signum


class _Signals:
    """SIGINT/SIGTERM raise :class:`Interrupted`, except inside ``critical()``
    sections, where they are held until the section ends."""

    SIGNALS = (signal.SIGINT, signal.SIGTERM)

    def __init__(self, restore=True):
        self.held, self.pending, self.saved, self.restore = False, None, {}, restore

    def _handler(self, signum, frame):
        from validation import interrupt

        interrupt.record(signum)
        if self.held:
            self.pending = self.pending or signum
            return
        raise Interrupted(signum)

    def _unraisable(self, info):
        # An Interrupted raised where Python cannot propagate it (a ctypes
        # callback) is already recorded (interrupt.pending); say nothing.
        if isinstance(info.exc_value, Interrupted):
            return
        self.saved_hook(info)

    def __enter__(self):
        for s in self.SIGNALS:
            self.saved[s] = signal.signal(s, self._handler)
        self.saved_hook, sys.unraisablehook = sys.unraisablehook, self._unraisable
        return self

    def __exit__(self, *exc):
        for s, h in self.saved.items():
            # the command line's outcome is decided: a late signal no longer changes it
            signal.signal(s, h if self.restore else signal.SIG_IGN)
        sys.unraisablehook = self.saved_hook
        return False

    def hold(self):
        self.held = True

    def release(self):
        """End a held section; an interrupt that came meanwhile is raised now."""
        self.held = False
        if self.pending is not None:
            signum, self.pending = self.pending, None
            raise Interrupted(signum)


def _fail(message) -> int:
    sys.stderr.write(f"run_all: {message}\n")
    return 2


def main(argv=None, *, restore_signals=True, prog="run_all.py") -> int:
    """The command line (see the module docstring); returns the exit status.

    SIGINT and SIGTERM handlers are installed for the call and restored after
    it (``restore_signals=False``: ignored after it, for the process's exit)."""
    from validation import extras, interrupt

    lack = extras.message("run", prog)
    if lack is None and argv is not None and "--scheduler" in argv:
        lack = extras.message("cluster", prog)
    if lack:
        print(lack, file=sys.stderr)
        return 2
    interrupt.reset()
    with _Signals(restore_signals) as sig:
        try:
            return _main(argv, sig, prog)
        except BaseException as e:  # noqa: BLE001 - before any output directory was made
            # A signal inside a C extension's initialization can surface as another exception.
            signum = getattr(e, "signum", None) or interrupt.pending()
            if signum is None and isinstance(e, KeyboardInterrupt):
                signum = signal.SIGINT
            if signum is None:
                raise
            sys.stderr.write(f"run_all: interrupted ({signal.Signals(signum).name}) before any scene ran\n")
            return 128 + signum


def _scope(args) -> str:
    """What the run covers: ``full`` (every shipped scene), ``quick`` or ``subset``."""
    return "subset" if args.scene else ("quick" if args.quick else "full")


def _environment(message) -> int:
    sys.stderr.write(f"run_all: {message}\n")
    return 3


def _check_name_length(target: Path) -> None:
    """The temporary names beside ``target`` must fit the filesystem's limit."""
    from validation import atomic

    longest = max(len(os.fsencode(f".{target.name}.kept-{'0' * 12}")),
                  len(os.fsencode(f".{target.name}.records-aside-{'0' * 16}-999")))
    probe = target.parent
    while not probe.exists() and probe != probe.parent:
        probe = probe.parent
    try:
        limit = os.pathconf(probe, "PC_NAME_MAX")
    except (OSError, ValueError):
        limit = 255
    if longest > limit:
        raise atomic.EnvironmentRefused(errno.ENAMETOOLONG, f"--out {target}: its name ({len(target.name)} "
                                        f"characters) leaves no room for the temporary names beside it "
                                        f"(limit {limit} bytes); choose a shorter name")


def _main(argv, sig, prog="run_all.py") -> int:
    args = _parser(prog).parse_args(argv)
    from validation import atomic, budget
    from validation.scenes import SceneError, load_scenes

    try:
        scenes = load_scenes(args.scene or None, quick=args.quick, allow_code=True if args.allow_code else None)
        if args.max_output_points is not None:
            scenes = [s if s.max_output_points is not None else _with_max_points(s, args.max_output_points)
                      for s in scenes]
        for s in scenes:
            budget.check(s, max_steps=args.max_steps, max_truth_steps=args.max_truth_steps)
    except SceneError as e:
        sys.stderr.write(f"{e}\n")
        return 2
    if args.scheduler:
        if args.exclusive_timing:
            return _fail("--exclusive-timing applies to local workers; on a Dask cluster start one worker "
                         "with --resources timing=1 --nthreads 1, alone on its machine")
        try:
            _check_scheduler(args.scheduler)
        except _BadInput as e:
            return _fail(str(e))
    if args.workers is None and os.environ.get("RK4H_WORKERS"):
        try:
            args.workers = _int_at_least(1, 1024)(os.environ["RK4H_WORKERS"])
        except argparse.ArgumentTypeError as e:
            return _fail(f"RK4H_WORKERS: {e}")
    if not scenes:
        return _fail("no scenes to run" + (" (none is marked quick = true)" if args.quick else ""))
    repeats = args.repeats if args.repeats is not None else (REPEATS_QUICK if args.quick else REPEATS_FULL)
    scope = _scope(args)
    target = Path(os.path.abspath(args.out))
    try:
        _check_name_length(target)
        if target.is_symlink() and target.is_dir():
            target = target.resolve()
        atomic.check_target(target, scope=scope, n_scenes=len(scenes), replace=args.replace)
        target.parent.mkdir(parents=True, exist_ok=True)
        with atomic.Lock(target):
            for line in atomic.recover(target):
                sys.stderr.write(f"run_all: {line}\n")
            # checked again under the lock: another run may have written meanwhile
            atomic.check_target(target, scope=scope, n_scenes=len(scenes), replace=args.replace)
            return _run_into(target, scenes, args, repeats, scope, sig)
    except atomic.TargetRefused as e:
        return _fail(str(e))
    except OSError as e:
        if isinstance(e, atomic.EnvironmentRefused) or e.errno in atomic.ENVIRONMENT_ERRNOS:
            where = f" ({e.filename})" if getattr(e, "filename", None) else ""
            text = e.strerror if isinstance(e.strerror, str) and not isinstance(e, atomic.EnvironmentRefused) \
                else (e.strerror or str(e))
            note = f"; {e.records_note}" if getattr(e, "records_note", None) else ""
            return _environment(f"the environment refused: {text}{where}; {args.out} left unchanged{note}")
        raise


def _run_into(target: Path, scenes, args, repeats: int, scope: str, sig) -> int:
    """Run ``scenes`` into a fresh directory beside ``target`` and swap it in
    (the caller holds the lock)."""
    import shutil

    from validation import atomic, engine, records
    from validation.plan import plan_all

    figures = not args.no_figures
    store = records.RecordStore(target, resume=args.resume, fresh=args.fresh)
    if store.moved_aside is not None:
        aside, n = store.moved_aside
        sys.stderr.write(f"run_all: --fresh: moved {n} record(s) of an earlier run aside to {aside}\n")
    elif store.found:
        print(f"resuming from {store.found} record(s) of an earlier run in {store.path}")
    tmp = atomic.fresh_dir(target)
    workers = args.workers or engine.default_workers()
    stats = engine.PlanStats()
    progress, swapped = None, False
    run.completed = []
    # the workers start (and import) while this process plans
    pools = engine.LocalPools(workers).warm() if workers > 1 and not args.scheduler else None
    try:
        try:
            total = len(plan_all(scenes, quick=args.quick, figures=figures, repeats=repeats))
            progress = Progress(total)
            _, failures = run(scenes, tmp, quick=args.quick, repeats=repeats, figures=figures,
                              progress=progress, workers=workers, scheduler=args.scheduler, store=store,
                              stats=stats, exclusive_timing=args.exclusive_timing, pools=pools)
            progress.close()
            sig.hold()  # the swap is not interrupted half-way
            atomic.swap_into_place(tmp, target, scope=scope, scenes=[s.name for s in scenes])
            swapped = True
            if not store.remove():
                sys.stderr.write(f"run_all: {store.path} kept: it holds files this tool did not write\n")
        finally:
            sig.held = True  # cleanup is not interrupted either
            if pools is not None:
                pools.close(kill=not swapped)
            if not swapped:
                shutil.rmtree(tmp, ignore_errors=True)
                # the records of a run that stopped (interrupt, crash, environment) stay
                # for --resume; an empty store goes
                _keep_records(store, sys.exc_info()[1])
        sig.release()
    except KeyboardInterrupt as e:
        if progress is not None:
            progress.close()
        signum = getattr(e, "signum", signal.SIGINT)
        done = run.completed
        names = ", ".join(done) or "none"
        state = (f"the report was written to {target}" if swapped
                 else f"{args.out} left unchanged")
        kept = "" if swapped or not store.keys() else (
            f"; {stats.executed + stats.resumed} of {stats.planned} runs are recorded in {store.path}: "
            f"rerun with --resume to run only the rest")
        sys.stderr.write(f"run_all: interrupted ({signal.Signals(signum).name}); scenes completed "
                         f"({len(done)} of {len(scenes)}): {names}; {state}{kept}\n")
        return 128 + signum
    except engine.SchedulerLost as e:
        if progress is not None:
            progress.close()
        try:
            recorded = len(store.keys())
        except OSError:  # removed: it held nothing
            recorded = 0
        kept = "" if not recorded else (f"; {recorded} of {stats.planned} runs are recorded: rerun with "
                                        f"--resume to run only the rest")
        return _environment(f"{e.strerror}; {args.out} left unchanged{kept}")
    finally:
        sig.held, sig.pending = False, None
    if atomic.swap_into_place.kept is not None:
        sys.stderr.write(f"run_all: the previous report was not removed ({atomic.swap_into_place.why}); it "
                         f"was kept aside as {atomic.swap_into_place.kept}\n")
    phases = ", ".join(f"{k} {v:.1f} s" for k, v in getattr(stats, "phases", {}).items())
    print(f"{stats.planned} runs planned, {stats.resumed} resumed, {stats.executed} executed "
          f"({'Dask at ' + args.scheduler if args.scheduler else f'{workers} worker(s)'}); {phases}")
    if store.found:
        a = stats.audit
        print(f"records: {stats.resumed} resumed, {a['mismatch'] + a['stale']} rerun ({a['mismatch']} digest "
              f"mismatch, {a['stale']} stale: made by other code or libraries)"
              + (f", {a['unused']} unused (no planned run)" if a["unused"] else ""))
    print(f"report written to {target} ({len(scenes)} scene(s)); "
          f"{'all expectations held' if not failures else f'{len(failures)} expectation(s) failed'}")
    for f in failures:
        print(f"FAILED: {f}")
    return 1 if failures else 0


def _keep_records(store, exc) -> None:
    """After a run that did not swap its report in: remove the store if it
    holds no record; else keep it and, for an error other than an interrupt
    (whose line says so itself), say where (appended to an ``OSError``'s
    line by :func:`main`, else one line on stderr)."""
    n = len(store.keys())
    if not n:
        store.remove()
        return
    if exc is None or isinstance(exc, KeyboardInterrupt):
        return
    note = f"{n} record(s) kept in {store.path}: rerun with --resume to use them"
    if isinstance(exc, OSError):
        exc.records_note = note
    else:
        sys.stderr.write(f"run_all: {note}\n")


def _check_scheduler(address):
    """A Dask scheduler address: ``tcp://host:port`` (or ``host:port``)."""
    import re

    if not re.fullmatch(r"(tcp|tls|inproc|ws|wss)://[^\s/]+|[^\s/:]+:\d+", address):
        raise _BadInput(f"--scheduler: must be an address like tcp://127.0.0.1:8786, got {address!r}")
    from validation import engine

    try:
        engine.scheduler_timeout()
    except ValueError as e:
        raise _BadInput(str(e)) from None


class _BadInput(ValueError):
    pass


def _with_max_points(scene, max_points):
    import dataclasses

    return dataclasses.replace(scene, max_output_points=max_points)


def exit_process(code: int):
    """End the process with ``code``. After an interrupt (``code >= 128``)
    everything the run owns is settled (report swapped or untouched,
    temporary directory removed, records kept for ``--resume``), so the
    process ends at once with ``os._exit``: the worker processes it killed
    can leave a ``concurrent.futures`` manager thread waiting on a queue
    forever, and the interpreter joins those threads at exit (seen once in
    CI under load: a SIGTERM'd run printed its line, then hung 120 s)."""
    if code >= 128:
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(code)
    sys.exit(code)


if __name__ == "__main__":
    exit_process(main(restore_signals=False))
