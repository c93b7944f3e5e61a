"""The runner: scenes in, a report directory and a :class:`RunReport` out.

:func:`execute` takes the options of a run (:class:`RunOptions`, what
``run_all.py`` / ``rk4h run`` parse from the command line), loads and checks
the scenes, chooses the workers (:func:`rk4h.validation.workers.choose_workers`),
runs the plan into a fresh directory beside ``--out``, swaps it into place
and returns what happened: the exit status, the report's path, the counts,
the failed checks. It prints nothing itself: the caller gets its notes
through ``notify`` and its progress through ``progress``, and prints the
report value (:mod:`rk4h.validation.run_all` is that caller; it also owns the
signal handlers and the process's exit).

:func:`run` is the pipeline under it (``rk4h.validation.plan`` ->
``rk4h.validation.engine`` -> ``rk4h.validation.measure`` -> ``rk4h.validation.draw`` /
``rk4h.validation.report``) for scenes already loaded, into an existing
directory; the cross-scene steps (the crossover figure, the time verdicts
gated by the machine's load) are here too.
"""
from __future__ import annotations

import dataclasses
import errno
import os
import signal
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

__all__ = ["RunOptions", "RunReport", "execute", "run", "Interrupted", "DEFAULT_OUT", "REPEATS_FULL",
           "REPEATS_QUICK", "MAX_REPEATS"]

#: The default --out: ``reports`` in the working directory (in a checkout
#: run from its root, the committed report).
DEFAULT_OUT = Path("reports")
REPEATS_FULL, REPEATS_QUICK = 3, 1
#: Largest --repeats (each timed run is repeated this often at most).
MAX_REPEATS = 100


class Interrupted(KeyboardInterrupt):
    """SIGINT or SIGTERM arrived; ``signum`` says which."""

    def __init__(self, signum):
        super().__init__(signal.Signals(signum).name)
        self.signum = signum


@dataclass
class RunOptions:
    """The options of a run, as the command line names them (``run_all.py
    --help``). ``scenes``: the ``--scene`` arguments (empty: every shipped
    scene, or the quick ones); ``workers`` None: chosen from the plan's
    estimated work (:func:`rk4h.validation.workers.choose_workers`), else exactly
    that many local processes; ``repeats`` None: 3, or 1 with ``quick``."""

    scenes: list = field(default_factory=list)
    quick: bool = False
    out: str = str(DEFAULT_OUT)
    repeats: int | None = None
    replace: bool = False
    figures: bool = True
    workers: int | None = None
    exclusive_timing: bool = False
    scheduler: str | None = None
    resume: bool = False
    fresh: bool = False
    allow_code: bool = False
    max_output_points: int | None = None
    max_steps: float | None = None
    max_truth_steps: float | None = None

    @classmethod
    def from_namespace(cls, args) -> "RunOptions":
        """From ``run_all``'s parsed arguments (an ``argparse.Namespace``)."""
        names = {f.name for f in dataclasses.fields(cls)} - {"scenes", "figures"}
        return cls(scenes=list(args.scene), figures=not args.no_figures,
                   **{n: getattr(args, n) for n in names})


@dataclass
class RunReport:
    """What :func:`execute` did.

    ``status`` is the exit status (0 every expectation held, 1 one failed, 2
    bad input, 3 the environment refused, 128 + the signal number when
    interrupted); ``message`` the one line that says why a run with status 2,
    3 or >= 128 stopped (None otherwise). ``out`` is the report directory when
    a report was swapped into place (else None); ``scenes`` the scenes
    loaded, ``completed`` those whose records are all complete; ``planned``,
    ``resumed``, ``executed`` count the plan's specs; ``workers`` the local
    processes used and ``workers_why`` how that number was chosen;
    ``phases`` seconds per phase; ``failures`` the failed expectations;
    ``records_found`` and ``audit`` describe the records of an earlier run
    (:meth:`rk4h.validation.records.RecordStore.audit`); ``kept_aside`` is
    ``(path, why)`` when the previous report could not be removed."""

    status: int
    message: str | None = None
    out: Path | None = None
    scenes: list = field(default_factory=list)
    completed: list = field(default_factory=list)
    planned: int = 0
    resumed: int = 0
    executed: int = 0
    workers: int = 0
    workers_why: str = ""
    scheduler: str | None = None
    phases: dict = field(default_factory=dict)
    failures: list = field(default_factory=list)
    records_found: int = 0
    audit: dict = field(default_factory=dict)
    kept_aside: tuple | None = None


class _NoGuard:
    """The signal guard of a caller that installs no handlers."""

    held, pending = False, None

    def hold(self):
        self.held = True

    def release(self):
        self.held = False


def _quiet(line, err=False):
    pass


def _check_run_args(scenes, out_dir, quick, repeats, figures, progress):
    from rk4h.validate import boolean

    from rk4h.validation.scenes import Scene

    if isinstance(scenes, (str, bytes, Path)) or not hasattr(scenes, "__iter__"):
        raise ValueError(f"`scenes` must be a list of Scene objects, got {scenes!r}")
    scenes = list(scenes)
    for i, s in enumerate(scenes):
        if not isinstance(s, Scene):
            raise ValueError(f"`scenes[{i}]` must be a Scene (rk4h.validation.scenes.load_scene), got {s!r}")
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
        scheduler=None, store=None, stats=None, exclusive_timing=False, pools=None,
        completed=None):
    """Run ``scenes`` and write the report into ``out_dir`` (which must exist).

    The pipeline (``rk4h.validation.plan`` -> ``rk4h.validation.engine`` ->
    ``rk4h.validation.measure`` -> ``rk4h.validation.draw`` / ``rk4h.validation.report``):
    every scene's plan is executed (records), then tables, checks and figures
    are computed from the records alone.

    Parameters
    ----------
    scenes : list of rk4h.validation.scenes.Scene
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
    store : rk4h.validation.records.RecordStore or None
        Records to resume from and to write.
    stats : rk4h.validation.engine.PlanStats or None
        Filled with the counts of planned, resumed and executed specs.
    exclusive_timing : bool
        Time each run alone, the other workers idle (default: the timed runs
        run one per worker after the untimed work; see ``rk4h.validation.engine``).
    pools : rk4h.validation.engine.LocalPools or None
        Worker processes started by the caller, who closes them (``workers``
        is then their number); default: started here when ``workers > 1``
        and stopped at the end.
    completed : list or None
        Filled, in order, with the names of the scenes whose records are
        complete (a caller reports them after an interrupt).

    Returns ``(results, failures)``. A fault inside a scene, solver or figure
    is a failure line (and a ``failed`` row where a row exists), never an
    exception; only ``KeyboardInterrupt`` (and :class:`Interrupted`) escape.
    Bad arguments raise ``ValueError`` naming the argument.
    """
    scenes = _check_run_args(scenes, out_dir, quick, repeats, figures, progress)
    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
        raise ValueError(f"`workers` must be an integer >= 1, got {workers!r}")
    if not isinstance(exclusive_timing, bool):
        raise ValueError(f"`exclusive_timing` must be True or False, got {exclusive_timing!r}")
    from rk4h.validation import engine, interrupt, plan

    t0 = time.perf_counter()
    if completed is None:
        completed = []
    elif not isinstance(completed, list):
        raise ValueError(f"`completed` must be a list or None, got {completed!r}")
    user_progress = progress
    broken = {}
    for scene in scenes:  # a scene whose model cannot be built is one failure line, not one per run
        try:
            scene.build_model()
        except Exception as e:  # noqa: BLE001
            from rk4h.validation.atomic import is_environment_error

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

    def complete(records):
        for scene in scenes:
            if scene.name not in finished and keys_of.get(scene.name, set()) <= records.keys():
                finished.add(scene.name)
                completed.append(scene.name)

    records = {}

    def tick(message):
        complete(records)
        progress(message)

    def grow(extra):  # confirmation runs planned after the plan: a scene is complete with them
        for scene, spec in extra:
            keys_of.setdefault(scene.name, set()).add(spec.key)
            if scene.name in finished:
                finished.discard(scene.name)
                completed.remove(scene.name)
        extend = getattr(user_progress, "extend", None)
        if callable(extend):
            extend(len(extra))

    own = pools is None
    if own:
        pools = engine.LocalPools(workers) if workers > 1 else None
    try:
        return _run(scenes, out_dir, jobs, quick, repeats, figures, scheduler, store, stats, pools, records,
                    tick, complete, t0, broken, exclusive_timing, grow)
    finally:
        if own and pools is not None:
            pools.close()


def _run(scenes, out_dir, jobs, quick, repeats, figures, scheduler, store, stats, pools, records, tick,
         complete, t0, broken, exclusive_timing=False, grow=None):
    from rk4h.validation import atomic, budget, confirm, draw, engine, interrupt, measure, report

    t_run = time.perf_counter()
    stats = stats if stats is not None else engine.PlanStats()
    records = engine.run_plan(jobs, quick=quick, workers=pools.workers if pools else 1, scheduler=scheduler,
                              store=store, progress=tick, cost=budget.spec_cost_function(), stats=stats,
                              records=records, pools=pools, exclusive_timing=exclusive_timing)
    # Confirmation runs of the trust table (rk4h.validation.confirm): planned from the records, in rounds.
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
    complete(records)
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
    from rk4h.validation import timing_context

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
    from rk4h.validation import outputs

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


#: Relative drawing cost of a figure job by kind (a state job draws two or
#: three figures; ``python benchmarks/bench_figures.py`` gives each kind's time).
_DRAW_COST = {"state": 3.0, "dispersion": 1.5, "work_precision": 1.2}


def _crossover_job(cheapest):
    """The all-scenes crossover grid (a figure job), from the trust table's
    rows: each cell shows the RHS-call verdict (deterministic), a solver only
    where its winning run was measured and met the target (``confirmed`` /
    ``alt_confirmed``); ``tie`` and ``unmeasured`` cells name no solver."""
    import pandas as pd

    from rk4h.validation import measure
    from rk4h.validation.trust import is_confirmed

    rows = []
    for r in pd.DataFrame(cheapest).to_dict("records"):
        v = r["verdict_rhs"]
        if v == r["method"] and is_confirmed(r.get("confirmed")):
            solver, rhs = v, r["rhs"]
        elif v == r["alternative"] and v and is_confirmed(r.get("alt_confirmed")):
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
    from rk4h.validation import atomic, interrupt, measure
    from rk4h.validation.draw import draw_job

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


def execute(options: RunOptions, *, progress=None, notify=None, guard=None) -> RunReport:
    """Run ``options`` (see the module docstring) and return the
    :class:`RunReport`.

    Parameters
    ----------
    options : RunOptions
    progress : callable(total) -> callable(str), or None
        Makes the progress sink once the plan's length is known; the sink is
        called once per spec, may have ``extend(n)`` (confirmation runs added)
        and ``close()``.
    notify : callable(line, err=False) or None
        Gets each note of the run as it happens (records resumed or moved
        aside, leftovers of killed runs cleaned); ``err``: a warning.
    guard : object or None
        The caller's signal guard (``hold()``, ``release()``, ``held``,
        ``pending``): the swap into place and the clean-up run held.

    Bad input, a refused environment and an interrupt are statuses with a
    one-line ``message``, never exceptions (``KeyboardInterrupt`` before the
    run started excepted).
    """
    from rk4h.validation import atomic, budget
    from rk4h.validation.scenes import SceneError, load_scenes

    notify = notify or _quiet
    guard = guard or _NoGuard()
    try:
        scenes = load_scenes(options.scenes or None, quick=options.quick,
                             allow_code=True if options.allow_code else None)
        if options.max_output_points is not None:
            scenes = [s if s.max_output_points is not None else _with_max_points(s, options.max_output_points)
                      for s in scenes]
        caps = {k: v for k, v in (("max_steps", options.max_steps), ("max_truth_steps", options.max_truth_steps))
                if v is not None}
        for s in scenes:
            budget.check(s, **caps)
    except SceneError as e:
        return RunReport(2, str(e))
    if options.scheduler:
        if options.exclusive_timing:
            return _bad("--exclusive-timing applies to local workers; on a Dask cluster start one worker "
                        "with --resources timing=1 --nthreads 1, alone on its machine")
        try:
            _check_scheduler(options.scheduler)
        except _BadInput as e:
            return _bad(str(e))
    if options.workers is None and os.environ.get("RK4H_WORKERS"):
        text = os.environ["RK4H_WORKERS"]
        try:
            workers = int(text)
        except ValueError:
            workers = 0
        if not 1 <= workers <= 1024:
            return _bad(f"RK4H_WORKERS: must be an integer from 1 to 1024, got {text!r}")
        options = dataclasses.replace(options, workers=workers)
    if not scenes:
        return _bad("no scenes to run" + (" (none is marked quick = true)" if options.quick else ""))
    repeats = options.repeats if options.repeats is not None else (REPEATS_QUICK if options.quick
                                                                   else REPEATS_FULL)
    scope = "subset" if options.scenes else ("quick" if options.quick else "full")
    target = Path(os.path.abspath(options.out))
    try:
        _check_name_length(target)
        if target.is_symlink() and target.is_dir():
            target = target.resolve()
        atomic.check_target(target, scope=scope, n_scenes=len(scenes), replace=options.replace)
        target.parent.mkdir(parents=True, exist_ok=True)
        with atomic.Lock(target):
            for line in atomic.recover(target):
                notify(f"run_all: {line}", err=True)
            # checked again under the lock: another run may have written meanwhile
            atomic.check_target(target, scope=scope, n_scenes=len(scenes), replace=options.replace)
            return _run_into(target, scenes, options, repeats, scope, guard, progress, notify)
    except atomic.TargetRefused as e:
        return _bad(str(e))
    except OSError as e:
        if isinstance(e, atomic.EnvironmentRefused) or e.errno in atomic.ENVIRONMENT_ERRNOS:
            where = f" ({e.filename})" if getattr(e, "filename", None) else ""
            text = e.strerror if isinstance(e.strerror, str) and not isinstance(e, atomic.EnvironmentRefused) \
                else (e.strerror or str(e))
            note = f"; {e.records_note}" if getattr(e, "records_note", None) else ""
            return RunReport(3, f"run_all: the environment refused: {text}{where}; {options.out} left "
                                f"unchanged{note}")
        raise


def _bad(message) -> RunReport:
    return RunReport(2, f"run_all: {message}")


def _run_into(target: Path, scenes, options, repeats: int, scope: str, guard, progress_factory,
              notify) -> RunReport:
    """Run ``scenes`` into a fresh directory beside ``target`` and swap it in
    (the caller holds the lock)."""
    import shutil

    from rk4h.validation import atomic, engine, records
    from rk4h.validation.plan import plan_all
    from rk4h.validation.workers import choose_workers

    figures = options.figures
    store = records.RecordStore(target, resume=options.resume, fresh=options.fresh)
    if store.moved_aside is not None:
        aside, n = store.moved_aside
        notify(f"run_all: --fresh: moved {n} record(s) of an earlier run aside to {aside}", err=True)
    elif store.found:
        notify(f"resuming from {store.found} record(s) of an earlier run in {store.path}")
    tmp = atomic.fresh_dir(target)
    report = RunReport(0, scenes=[s.name for s in scenes], scheduler=options.scheduler,
                       records_found=store.found)
    stats = engine.PlanStats()
    progress, swapped, pools = None, False, None
    completed = report.completed
    if options.workers is not None or options.scheduler:
        workers, report.workers_why = options.workers or 1, "as asked"
        if workers > 1 and not options.scheduler:
            # the workers start (and import) while this process plans
            pools = engine.LocalPools(workers).warm()
    try:
        try:
            jobs = plan_all(scenes, quick=options.quick, figures=figures, repeats=repeats)
            if options.workers is None and not options.scheduler:
                workers, report.workers_why = choose_workers(
                    jobs, quick=options.quick, figures=figures, done=store.keys() if store.found else ())
                if workers > 1 and not options.scheduler:
                    pools = engine.LocalPools(workers).warm()
            report.workers = workers
            if progress_factory is not None:
                progress = progress_factory(len(jobs))
            _, failures = run(scenes, tmp, quick=options.quick, repeats=repeats, figures=figures,
                              progress=progress, workers=workers, scheduler=options.scheduler, store=store,
                              stats=stats, exclusive_timing=options.exclusive_timing, pools=pools,
                              completed=completed)
            if progress is not None and hasattr(progress, "close"):
                progress.close()
            guard.hold()  # the swap is not interrupted half-way
            swap = atomic.swap_into_place(tmp, target, scope=scope, scenes=[s.name for s in scenes])
            swapped = True
            if not store.remove():
                notify(f"run_all: {store.path} kept: it holds files this tool did not write", err=True)
        finally:
            guard.held = True  # cleanup is not interrupted either
            if pools is not None:
                pools.close(kill=not swapped)
            if not swapped:
                shutil.rmtree(tmp, ignore_errors=True)
                # the records of a run that stopped (interrupt, crash, environment) stay
                # for --resume; an empty store goes
                _keep_records(store, sys.exc_info()[1], notify)
        guard.release()
    except KeyboardInterrupt as e:
        if progress is not None and hasattr(progress, "close"):
            progress.close()
        signum = getattr(e, "signum", signal.SIGINT)
        names = ", ".join(completed) or "none"
        state = f"the report was written to {target}" if swapped else f"{options.out} left unchanged"
        kept = "" if swapped or not _recorded(store) else (
            f"; {stats.executed + stats.resumed} of {stats.planned} runs are recorded in {store.path}: "
            f"rerun with --resume to run only the rest")
        _counts(report, stats)
        report.status = 128 + signum
        report.out = target if swapped else None
        report.message = (f"run_all: interrupted ({signal.Signals(signum).name}); scenes completed "
                          f"({len(completed)} of {len(scenes)}): {names}; {state}{kept}")
        return report
    except engine.SchedulerLost as e:
        if progress is not None and hasattr(progress, "close"):
            progress.close()
        recorded = _recorded(store)
        kept = "" if not recorded else (f"; {recorded} of {stats.planned} runs are recorded: rerun with "
                                        f"--resume to run only the rest")
        _counts(report, stats)
        report.status, report.message = 3, f"run_all: {e.strerror}; {options.out} left unchanged{kept}"
        return report
    finally:
        guard.held, guard.pending = False, None
    if swap.kept is not None:
        report.kept_aside = (swap.kept, swap.why)
    _counts(report, stats)
    report.out, report.failures = target, list(failures)
    report.status = 1 if failures else 0
    return report


def _recorded(store) -> int:
    """The number of records in ``store`` (0 once removed: it held none)."""
    try:
        return len(store.keys())
    except OSError:
        return 0


def _counts(report, stats) -> None:
    report.planned, report.resumed, report.executed = stats.planned, stats.resumed, stats.executed
    report.audit = dict(stats.audit)
    report.phases = dict(getattr(stats, "phases", {}) or {})


def _check_name_length(target: Path) -> None:
    """The temporary names beside ``target`` must fit the filesystem's limit."""
    from rk4h.validation import atomic

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


def _keep_records(store, exc, notify) -> None:
    """After a run that did not swap its report in: remove the store if it
    holds no record; else keep it and, for an error other than an interrupt
    (whose line says so itself), say where (appended to an ``OSError``'s
    line by :func:`execute`, else a warning through ``notify``)."""
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
        notify(f"run_all: {note}", err=True)


def _check_scheduler(address):
    """A Dask scheduler address: ``tcp://host:port`` (or ``host:port``)."""
    import re

    if not re.fullmatch(r"(tcp|tls|inproc|ws|wss)://[^\s/]+|[^\s/:]+:\d+", address):
        raise _BadInput(f"--scheduler: must be an address like tcp://127.0.0.1:8786, got {address!r}")
    from rk4h.validation import engine

    try:
        engine.scheduler_timeout()
    except ValueError as e:
        raise _BadInput(str(e)) from None


class _BadInput(ValueError):
    pass


def _with_max_points(scene, max_points):
    import dataclasses

    return dataclasses.replace(scene, max_output_points=max_points)
