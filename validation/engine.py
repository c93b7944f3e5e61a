"""Executing a plan: in this process, on a local process pool, or on a Dask cluster.

:func:`run_plan` takes ``(scene, spec)`` pairs (:func:`rk4h.validation.plan.plan_all`)
and returns their records, key -> :class:`~rk4h.validation.records.RunRecord`.
Records already in the store (``--resume``) are not run again; every new
record is written to the store as soon as it arrives, so an interrupted run
loses at most the runs in flight.

Order: the references (``truth`` specs) run first, so that the runs that
measure against them find them in the truth cache instead of computing them
in two workers at once; then every untimed spec, on all workers, longest
estimated first; then the timed specs.

Timing
------
Timed specs (:attr:`RunSpec.timed`: the solver runs whose wall times feed the
work-precision tables and verdicts) run last, after every untimed spec has
finished, so that a timed run shares the machine with no untimed run of the
report: one per worker process, each single-threaded (``benchmarks/bench_timing_lane.py``
measures what a neighbour integrating on the other core does to a timing).
Other processes on the machine are not under the report's control: the load
average just before and after the timed stage is recorded
(``PlanStats.load_before``/``load_after``, :mod:`rk4h.validation.timing_context`),
and under a load above the CPU count every time verdict between two measured
sides is a tie.
``exclusive_timing=True`` (``run_all.py --exclusive-timing``) runs them one at
a time in one worker process (the *timing lane*) with the other workers idle,
for a machine where parallel runs do disturb each other's timings.
``--workers 1`` runs everything in this process, in the same order.

On a Dask cluster (``--scheduler ADDRESS``) the same three stages run in
order; timed specs ask for the worker resource ``timing`` when a worker
offers it (start one worker with ``--resources timing=1 --nthreads 1``,
alone on its machine); without such a worker they run wherever Dask puts them
and the report says that its timings came from a shared cluster.

Workers that die, clusters that go quiet
----------------------------------------
A local worker process that dies (the OOM killer's SIGKILL, a segfault in an
extension) breaks its pool; the pool is replaced, the spec the dead process
was running is run once more and, if its worker dies again, becomes a failed
record (``WorkerDied: worker died (SIGKILL) twice``); the other specs in
flight there are resubmitted. The run goes on (:class:`_Dispatch`).

Before a Dask worker gets a spec it proves its code: it runs
:func:`_worker_digest` (:func:`rk4h.validation.plan.code_digest` of the packages
it imports), and a worker whose digest is not ours is refused, named on
stderr, and gets no work. Every wait on the cluster is bounded by
:func:`scheduler_timeout`: no scheduler answering, no worker, no verified
worker, or a scheduler that goes quiet or away mid-run ends the run with
:class:`SchedulerLost` (exit 3; the records so far stay for ``--resume``;
``docs/workers.md``).
"""
from __future__ import annotations

import atexit
import errno
import math
import os
import signal
import sys
import time

from .atomic import EnvironmentRefused
from .process_exit import flush_streams
from .records import failed_record

__all__ = ["run_plan", "default_workers", "PlanStats", "LocalPools", "WorkerDied", "SchedulerLost"]


def default_workers() -> int:
    """The cores this process may use."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except (AttributeError, OSError):
        return max(1, os.cpu_count() or 1)


class PlanStats:
    """What :func:`run_plan` did: specs ``planned``, ``resumed`` (read from the
    store), ``executed``; ``timing`` says how timed runs were placed.
    ``audit`` (:meth:`rk4h.validation.records.RecordStore.audit`): of the executed
    specs, how many had a record that did not verify (``mismatch``) or one
    made by other code or libraries (``stale``); records matching no planned
    spec (``unused``)."""

    def __init__(self):
        self.planned = self.resumed = self.executed = 0
        self.audit = {"mismatch": 0, "stale": 0, "unused": 0}
        self.timing = "one at a time in the main process (--workers 1)"
        self.phases = {}
        #: rk4h.validation.timing_context.snapshot() just before / after the timed stage ran (None: not run)
        self.load_before = self.load_after = None
        self.timed_executed = self.timed_resumed = 0

    def __repr__(self):
        return (f"PlanStats(planned={self.planned}, resumed={self.resumed}, executed={self.executed}, "
                f"timing={self.timing!r})")


#: In a worker process: the pipe on which it says which job it starts (see _tracked).
_TELL = None


def _worker_init(tell=None):
    global _TELL
    _TELL = tell
    from rk4h import _heyoka

    _heyoka.own_process()  # a worker of rk4h's runner: heyoka may come without sympy
    # Ctrl-C reaches the whole process group: the parent decides, workers stay quiet.
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    # A worker dies with its parent (kill -9 of run_all): an orphan would go on
    # computing and hold the parent's stdout and stderr open.
    try:
        import ctypes
        import multiprocessing

        ctypes.CDLL(None, use_errno=True).prctl(1, signal.SIGKILL)  # PR_SET_PDEATHSIG (Linux)
        parent = multiprocessing.parent_process()
        if parent is not None and os.getppid() != parent.pid:  # the parent died before prctl
            os._exit(1)
    except (OSError, AttributeError):
        pass
    # A worker that was told to stop ends here, without the interpreter's
    # teardown of what its runs built (JIT-compiled models, caches), which is
    # slow and has nothing left to save. atexit runs handlers last
    # registered first: those of modules the runs import still run, then this
    # one; handlers registered before it (at interpreter start, e.g. coverage's
    # subprocess measurement) do not run in a worker. Every file a run writes
    # is closed by then; results travel through a pipe written synchronously
    # (no feeder thread to wait for).
    atexit.register(_exit_now)


def _tracked(tag, fn, *args):
    """Run ``fn(*args)`` in a worker, first telling the parent (``tag``, this
    process's id) so that the job a dead worker was running is known. The
    message is one ``write`` of a few bytes on a pipe, atomic below
    ``PIPE_BUF``: no lock that a killed writer could leave held."""
    if _TELL is not None:
        try:
            _TELL.send_bytes(f"{os.getpid()} {tag}".encode())
        except (OSError, ValueError):
            pass
    return fn(*args)


def _exit_now():
    """Flush the standard streams and end the process (exit status 0)."""
    flush_streams()
    os._exit(0)


def _warm():
    """Import what executing a spec needs and start heyoka (run in a fresh
    worker; heyoka's start-up is untimed in any case, see
    ``rk4h.references.solvers.taylor``)."""
    import rk4h.validation.execute  # noqa: F401
    import rk4h.validation.measure  # noqa: F401

    from rk4h.references.solvers import taylor

    try:
        taylor.start_up()
    except ImportError:  # no heyoka: its runs fail with a status of their own
        pass


def _execute(scene, spec, quick):
    from rk4h.validation.execute import execute
    from rk4h.validation.sweep_batch import SpecGroup, execute_group

    if isinstance(spec, SpecGroup):  # sweep points' untimed runs as one batch: a list of records
        return execute_group(spec, quick)
    return execute(scene, spec, quick)


def run_plan(jobs, *, quick=False, workers=1, scheduler=None, store=None, progress=None, cost=None,
             stats=None, records=None, pools=None, exclusive_timing=False):
    """Execute ``jobs`` (``[(scene, spec), ...]``); see the module docstring.

    Parameters
    ----------
    jobs : list of (Scene, RunSpec)
    quick : bool
        Passed to each execution (the stability units' quick settings).
    workers : int
        Local processes (1: in this process). Ignored with ``scheduler``.
    scheduler : str or None
        Address of a Dask distributed scheduler (``tcp://host:port``).
    store : RecordStore or None
        Where records are read (resume) and written.
    progress : callable(str) or None
        Called once per spec, resumed ones included.
    cost : callable(scene, spec) -> float or None
        Estimated cost, to start the longest runs first.
    stats : PlanStats or None
        Filled with the counts.
    records : dict or None
        Filled in place as records arrive (and returned).
    pools : LocalPools or None
        Worker processes to use (and keep); default: started and stopped here.
    exclusive_timing : bool
        Timed specs one at a time in the timing lane, the other workers idle
        (default: one per worker process, after the untimed work).
    """
    stats = stats if stats is not None else PlanStats()
    stats.planned = len(jobs)
    tick = progress or (lambda msg: None)
    records = records if records is not None else {}
    todo = []
    have = store.keys() if store is not None else set()
    for scene, spec in jobs:
        rec = store.get(spec.key) if spec.key in have else None
        if rec is not None:
            records[spec.key] = rec
            stats.resumed += 1
            stats.timed_resumed += bool(spec.timed)
            tick(f"{spec.label()} (resumed)")
        else:
            todo.append((scene, spec))
    if store is not None and hasattr(store, "audit"):
        stats.audit = store.audit([s for _, s in todo], [s.key for _, s in jobs])
    stages = [[j for j in todo if j[1].purpose == "truth"],
              [j for j in todo if j[1].purpose != "truth" and not j[1].timed],
              [j for j in todo if j[1].purpose != "truth" and j[1].timed]]
    if cost is not None:
        stages = [sorted(s, key=lambda j: -cost(*j)) for s in stages]
    stats.timed_executed = len(stages[-1])
    if not scheduler:  # untimed fixed-step runs of sweep points as one batch (rk4h.validation.sweep_batch)
        from .sweep_batch import group

        stages[1] = group(stages[1])

    def done(spec, rec):
        if hasattr(spec, "split"):  # a SpecGroup: its records, or its failure given to each spec
            for one, r in spec.split(rec):
                done(one, r)
            return
        if store is not None:
            store.put(rec, spec)
        records[spec.key] = rec
        stats.executed += 1
        tick(spec.label())

    if scheduler:
        _dask(stages, quick, scheduler, done, stats)
    elif workers <= 1:
        from .execute import clear_problems, execute

        clear_problems()  # models built by an earlier run in this process are not reused

        for i, stage in enumerate(stages):
            _load_mark(stats, stages, i)
            for scene, spec in stage:
                done(spec, _execute(scene, spec, quick) if scene is None else execute(scene, spec, quick))
        _load_mark(stats, stages, len(stages))
    else:
        own = pools is None
        pools = pools or LocalPools(workers)
        try:
            from .warm import warm_pools

            warm_pools(pools, todo)  # each numba loop compiled by one worker, not by every worker
            _pool(stages, quick, pools, done, stats, exclusive_timing)
        finally:
            if own:
                pools.close()
    return records


#: Warning filter passed to the resource tracker's interpreter (see LocalPools.start).
_TRACKER_QUIET = "ignore:resource_tracker:UserWarning"


class LocalPools:
    """Worker processes kept for a whole report: the timing lane (one process)
    and ``workers - 1`` general processes, started on first use (``spawn``:
    no fork of a process holding LLVM/numba threads). Used for the plan and
    then for drawing the figures."""

    def __init__(self, workers: int):
        self.workers = int(workers)
        self.general = self.lane = None

    def start(self):
        if self.general is None:
            import multiprocessing as mp
            from concurrent.futures import ProcessPoolExecutor

            # An interrupted run ends with os._exit (run_all.exit_process) after killing
            # these workers; multiprocessing's resource tracker, a separate process
            # started with this interpreter's -W options, then unlinks the pools'
            # semaphores itself and would print a UserWarning saying so.
            if _TRACKER_QUIET not in sys.warnoptions:
                sys.warnoptions.append(_TRACKER_QUIET)

            self._ctx = mp.get_context("spawn")
            if getattr(self, "_heard", None) is None:
                self._heard, self._tell = self._ctx.Pipe(duplex=False)
            self.general = self._new("general")
            self.lane = self._new("lane")
        return self

    def _new(self, name):
        from concurrent.futures import ProcessPoolExecutor

        return ProcessPoolExecutor(max_workers=1 if name == "lane" else max(1, self.workers - 1),
                                   mp_context=self._ctx, initializer=_worker_init, initargs=(self._tell,))

    def renew(self, name):
        """Replace the pool ``name`` (``"lane"`` or ``"general"``), broken by
        a worker that died, by a fresh one (its processes start on first use)."""
        setattr(self, name, self._new(name))

    def heard(self):
        """``[(pid, tag), ...]``: the jobs the workers said they started since
        the last call (see :func:`_tracked`)."""
        out = []
        conn = getattr(self, "_heard", None)
        try:
            while conn is not None and conn.poll(0):
                pid, tag = conn.recv_bytes().split()
                out.append((int(pid), int(tag)))
        except (OSError, EOFError, ValueError):
            pass
        return out

    def warm(self):
        """Start the worker processes now, each importing the execution
        modules, so that a plan's first spec does not wait for them (the
        CLI calls this before it plans)."""
        self.start()
        for pool, n in ((self.lane, 1), (self.general, max(1, self.workers - 1))):
            for _ in range(n):  # one task per idle process makes the pool start it
                pool.submit(_warm)
        return self

    def map(self, fn, items, cost=None):
        """``[fn(*item) ...]`` over both pools, in order; an exception is
        returned in place of its result. Each process takes the next item
        when it is done with its last, the largest ``cost`` (one number per
        item) first, so that a long item does not leave one process idle at
        the end."""
        self.start()
        out = [None] * len(items)
        free = {"lane": 1, "general": max(1, self.workers - 1)}
        todo = list(range(len(items)))
        if cost is not None:
            todo.sort(key=lambda i: -cost[i])
        jobs = _Dispatch(self)
        try:
            while todo or jobs.pending:
                for name in ("lane", "general"):
                    while todo and free[name]:
                        i = todo.pop(0)
                        free[name] -= 1
                        jobs.submit(name, fn, items[i], i)
                for job, result in jobs.wait():
                    free[job.name] += 1
                    out[job.what] = result  # an exception is returned: the caller reports it
        except BaseException:
            self.close(kill=True)
            raise
        return out

    def close(self, kill=False):
        """Stop the workers: at once (``kill``: an interrupt or a fault), or
        after their current work."""
        for pool in (self.general, self.lane):
            if pool is None:
                continue
            if kill:
                for proc in list((getattr(pool, "_processes", None) or {}).values()):
                    try:
                        proc.kill()
                    except (OSError, AttributeError):
                        pass
            pool.shutdown(wait=not kill, cancel_futures=True)
        self.general = self.lane = None
        for conn in (getattr(self, "_heard", None), getattr(self, "_tell", None)):
            if conn is not None:
                conn.close()
        self._heard = self._tell = None


def _pool(stages, quick, pools, done, stats, exclusive_timing=False):
    pools.start()
    others = pools.workers - 1
    stats.timing = (f"one at a time after the untimed work, in one process with the other {others} worker(s) "
                    f"idle (--exclusive-timing, --workers {pools.workers})" if exclusive_timing or not others else
                    f"after the untimed work, {pools.workers} at a time, one per worker process "
                    f"(--workers {pools.workers}): no untimed run of this report overlaps them (other processes "
                    f"on the machine: see the load average)")
    jobs = _Dispatch(pools)
    try:
        for i, stage in enumerate(stages):
            _load_mark(stats, stages, i)
            queue = list(stage)
            free = {"lane": 1, "general": max(1, others)}
            while queue or jobs.pending:
                # keep every process busy with one spec (timed runs only in the lane
                # when timing is exclusive)
                while queue:
                    alone = exclusive_timing and queue[0][1].timed
                    name = "lane" if free["lane"] and (alone or not free["general"]) else \
                        ("general" if free["general"] and not alone else None)
                    if name is None:
                        break
                    scene, spec = queue.pop(0)
                    free[name] -= 1
                    jobs.submit(name, _execute, (scene, spec, quick), spec)
                for job, rec in jobs.wait():
                    free[job.name] += 1
                    if isinstance(rec, BaseException) and not hasattr(job.what, "split"):
                        rec = failed_record(job.what.key, rec)  # the run raised, or its worker died twice
                    done(job.what, rec)
        _load_mark(stats, stages, len(stages))
    except BaseException:
        pools.close(kill=True)
        raise


def _load_mark(stats, stages, i):
    """Record the machine's load (:func:`rk4h.validation.timing_context.snapshot`)
    when the timed stage (the last) is about to start (``i`` its index) or
    has ended (``i == len(stages)``), if it has specs."""
    from .timing_context import snapshot

    if not stages[-1]:
        return
    if i == len(stages) - 1:
        stats.load_before = snapshot()
    elif i == len(stages):
        stats.load_after = snapshot()


class WorkerDied(RuntimeError):
    """A local worker process died (a signal, or an exit) while running the
    same job twice: the job's outcome, in place of its result."""


def _death(code) -> str:
    """How a process ended, from its exit code (negative: the signal)."""
    if code is not None and code < 0:
        try:
            return signal.Signals(-code).name
        except ValueError:
            return f"signal {-code}"
    return f"exit status {code}"


class _Job:
    __slots__ = ("tag", "name", "fn", "args", "what", "deaths")

    def __init__(self, tag, name, fn, args, what):
        self.tag, self.name, self.fn, self.args, self.what, self.deaths = tag, name, fn, args, what, []


class _Dispatch:
    """Jobs on the pools of a :class:`LocalPools` (``"lane"``, ``"general"``),
    surviving the death of a worker process.

    A worker that dies (killed by the OOM killer, a segfault in an extension)
    breaks its whole ``ProcessPoolExecutor``: every job in flight there fails
    with ``BrokenProcessPool``. The pool is then replaced by a fresh one; the
    job the dead process was running (it said so on starting, see
    :func:`_tracked`) is run once more, and if its worker dies again its
    outcome is a :class:`WorkerDied` naming the signals; the other jobs of the
    broken pool are simply resubmitted. When the dead process ran none of the
    jobs (it died starting up or idle) nobody is charged, except after two
    such deaths in a row; when no process can be singled out (all ended with
    SIGTERM, which the executor sends to the survivors) every job in flight is
    charged.
    """

    def __init__(self, pools):
        self.pools = pools
        self.pending = {}  # future -> _Job
        self.ready = []  # (job, outcome) not yet returned by wait()
        self.started = {}  # pid -> tag of the last job it said it started
        self.tags = 0
        self.idle_deaths = 0
        # pool name -> {pid: Process} of every worker seen since the pool was made: the
        # executor forgets a dead worker as it breaks, and the dead one is the one to name
        self.seen = {}

    def submit(self, name, fn, args, what):
        """Run ``fn(*args)`` on the pool ``name``; ``what`` comes back with its outcome."""
        self.tags += 1
        self._submit(_Job(self.tags, name, fn, tuple(args), what))

    def _submit(self, job):
        from concurrent.futures.process import BrokenProcessPool

        try:
            fut = getattr(self.pools, job.name).submit(_tracked, job.tag, job.fn, *job.args)
        except BrokenProcessPool:  # broke with none of its jobs collected yet
            self._recover(job.name)
            fut = getattr(self.pools, job.name).submit(_tracked, job.tag, job.fn, *job.args)
        self.pending[fut] = job
        self._see(job.name)

    def _see(self, name):
        procs = getattr(getattr(self.pools, name), "_processes", None) or {}
        self.seen.setdefault(name, {}).update(dict(procs))

    def _listen(self):
        heard = getattr(self.pools, "heard", None)
        for pid, tag in (heard() if heard is not None else ()):
            self.started[pid] = tag

    def wait(self):
        """Block until at least one job has an outcome (none pending: return
        at once); returns ``[(job, result or exception), ...]``."""
        from concurrent.futures import FIRST_COMPLETED, wait
        from concurrent.futures.process import BrokenProcessPool

        while not self.ready and self.pending:
            finished, _ = wait(list(self.pending), return_when=FIRST_COMPLETED)
            self._listen()
            broken = set()
            for fut in finished:
                job = self.pending[fut]
                exc = fut.exception()
                if isinstance(exc, BrokenProcessPool):
                    broken.add(job.name)
                    continue
                del self.pending[fut]
                self.idle_deaths = 0
                self.ready.append((job, exc if exc is not None else fut.result()))
            for name in sorted(broken):
                self._recover(name)
        out, self.ready = self.ready, []
        return out

    def _recover(self, name):
        pool = getattr(self.pools, name)
        self._see(name)
        procs = list(self.seen.pop(name, {}).values())
        # The executor's manager thread fails every job and terminates the other
        # workers (SIGTERM); waiting for the processes, not for that thread, cannot hang.
        pool.shutdown(wait=False, cancel_futures=True)
        codes = {}
        for p in procs:
            p.join(timeout=30)
            # the executor's thread may reap the same process at the same moment, and
            # then this thread's poll reads no status for a while: look again
            for _ in range(40):
                if p.exitcode is not None:
                    break
                time.sleep(0.025)
            codes[p.pid] = p.exitcode
            if p.exitcode is None:  # not terminated: ended here, and not taken for the dead one
                p.kill()
                p.join(timeout=5)
                codes[p.pid] = -signal.SIGTERM
        self._listen()
        jobs = [j for j in self.pending.values() if j.name == name]
        self.pending = {f: j for f, j in self.pending.items() if j.name != name}
        died = {pid: c for pid, c in codes.items() if c is not None and c != -signal.SIGTERM}
        charged = {}
        for pid, code in died.items():
            for j in jobs:
                if self.started.get(pid) == j.tag:
                    charged[j.tag] = _death(code)
        if not charged and (not died or self.idle_deaths >= 2):
            how = _death(next(iter(died.values()), -signal.SIGTERM))
            charged = {j.tag: how for j in jobs}
        elif not charged:
            self.idle_deaths += 1
        for pid in codes:
            self.started.pop(pid, None)
        self.pools.renew(name)
        again = 0
        for j in jobs:
            if j.tag in charged:
                j.deaths.append(charged[j.tag])
            if len(j.deaths) >= 2:
                self.ready.append((j, WorkerDied(
                    f"worker died ({j.deaths[0]}) twice" if len(set(j.deaths)) == 1
                    else f"worker died twice ({', then '.join(j.deaths)})")))
            else:
                again += 1
                self._submit(j)
        what = ", ".join(_death(c) for c in died.values()) or "SIGTERM"
        sys.stderr.write(f"run_all: a local worker process died ({what}); its pool was replaced, "
                         f"{again} of the {len(jobs)} job(s) it held run again\n")


#: Seconds to wait for a Dask scheduler (and a worker) before the run ends
#: with exit 3; also each worker's time for its code check, and the silence
#: mid-run after which the scheduler is asked whether it is still there; the
#: environment variable ``RK4H_SCHEDULER_TIMEOUT`` replaces it.
SCHEDULER_TIMEOUT_S = 20.0


def scheduler_timeout() -> float:
    """:data:`SCHEDULER_TIMEOUT_S`, or ``RK4H_SCHEDULER_TIMEOUT`` (seconds, > 0) when set."""
    text = os.environ.get("RK4H_SCHEDULER_TIMEOUT")
    if text is None:
        return SCHEDULER_TIMEOUT_S
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not (math.isfinite(value) and value > 0):
        raise ValueError(f"`RK4H_SCHEDULER_TIMEOUT` must be a number of seconds > 0, got {text!r}")
    return value


class SchedulerLost(EnvironmentRefused):
    """The Dask cluster refused or was lost: no scheduler answered within
    :func:`scheduler_timeout`, it has no worker running this code, or it
    stopped answering mid-run (exit 3). The records made so far are kept
    for ``--resume``."""

    def __init__(self, message):
        super().__init__(errno.ECONNREFUSED, message)


class _NoAnswer(Exception):
    pass


def _bounded(fn, seconds):
    """``fn()``, or :class:`_NoAnswer` after ``seconds``: a call into
    ``distributed`` that waits on a peer which accepts and never answers (a
    frozen scheduler, a socket that is not one) does not return, whatever
    its own timeout says; it is left behind in a daemon thread."""
    import threading

    box = {}

    def call():
        try:
            box["value"] = fn()
        except BaseException as e:  # noqa: BLE001 - handed to the caller
            box["error"] = e

    t = threading.Thread(target=call, name="rk4h-dask-call", daemon=True)
    t.start()
    t.join(seconds)
    if t.is_alive():
        raise _NoAnswer
    if "error" in box:
        raise box["error"]
    return box["value"]


def _worker_digest():
    """:func:`rk4h.validation.plan.code_digest` of the code this process imports
    (run on each Dask worker before it gets work)."""
    from rk4h.validation.plan import code_digest

    return code_digest()


def _first_line(e) -> str:
    text = str(e).splitlines()[0] if str(e) else ""
    return f"{type(e).__name__}: {text}" if text else type(e).__name__


def _verified_workers(client, address, timeout, deadline):
    """The addresses of the Dask workers whose code digest is ours, and what
    the scheduler says of every worker. A worker must have joined by
    ``deadline`` (``time.monotonic()``); each then has ``timeout`` seconds to
    run the code check. A worker that fails it is named on stderr (refused);
    none left: :class:`SchedulerLost`."""
    import time

    from distributed import wait as dask_wait

    from .plan import code_digest

    def left():
        return max(0.1, deadline - time.monotonic())

    try:
        _bounded(lambda: client.wait_for_workers(1, timeout=left()), left() + 0.5)
        workers = _bounded(lambda: client.scheduler_info(n_workers=-1), left()).get("workers", {})
    except (_NoAnswer, TimeoutError, OSError) as e:
        why = "none joined" if isinstance(e, TimeoutError) else "the scheduler did not answer"
        raise SchedulerLost(f"the Dask scheduler at {address} has no workers ({why} within {timeout:g} s)") from None
    ours = code_digest()
    probes = {a: client.submit(_worker_digest, workers=[a], allow_other_workers=False, pure=False)
              for a in workers}
    try:
        _bounded(lambda: dask_wait(list(probes.values()), timeout=timeout), timeout + 1)
    except (_NoAnswer, TimeoutError):
        pass
    good, refused = [], []
    for a, fut in probes.items():
        if fut.status == "finished":
            digest = _bounded(lambda: fut.result(timeout=timeout), timeout + 1)
            if digest == ours:
                good.append(a)
                continue
            why = f"it runs other code: code digest {digest!r}, ours {ours!r}"
        elif fut.status == "error":
            why = f"its code check raised {_first_line(_bounded(fut.exception, timeout))}"
        else:
            why = f"it did not run the code check within {timeout:g} s"
            fut.cancel()
        refused.append(a)
        sys.stderr.write(f"run_all: Dask worker {a} refused: {why}\n")
    if not good:
        raise SchedulerLost(f"no worker of the Dask scheduler at {address} runs this code "
                            f"(refused: {', '.join(refused)})")
    return good, workers


def _connection_trouble(record) -> bool:
    """False for a ``distributed`` log record whose exception is a lost or
    refused connection (the run reports those itself, in one line, instead
    of their tracebacks); True for any other record."""
    import asyncio

    exc = record.exc_info[1] if record.exc_info else None
    return not isinstance(exc, (OSError, TimeoutError, asyncio.CancelledError))


def _dask(stages, quick, address, done, stats):
    import logging

    try:
        import distributed  # noqa: F401 - configures its loggers
    except ImportError:  # pragma: no cover - a dependency of the project
        raise RuntimeError("--scheduler needs the `distributed` package (pip install distributed)") from None
    handlers = list(logging.getLogger("distributed").handlers)
    for h in handlers:
        h.addFilter(_connection_trouble)
    _dask_run(stages, quick, address, done, stats)
    # (after a failure the filter stays: a client left behind may still log its reconnection)
    for h in handlers:
        h.removeFilter(_connection_trouble)


def _dask_run(stages, quick, address, done, stats):
    import asyncio
    import time

    from distributed import Client
    from distributed import wait as dask_wait

    timeout = scheduler_timeout()
    deadline = time.monotonic() + timeout  # a scheduler with a worker, or exit 3
    try:
        client = _bounded(lambda: Client(address, timeout=f"{timeout:g}s"), timeout)
    except (_NoAnswer, OSError) as e:
        why = f"no answer within {timeout:g} s" if isinstance(e, _NoAnswer) else _first_line(e)
        raise SchedulerLost(f"cannot reach the Dask scheduler at {address} ({why})") from None
    lost = None
    try:
        good, workers = _verified_workers(client, address, timeout, deadline)
        timing_worker = any("timing" in (workers[a].get("resources") or {}) for a in good)
        stats.timing = ("Dask: timed runs on the worker with the `timing` resource" if timing_worker
                        else "Dask: timed runs wherever the scheduler put them (no worker offers `timing`)")

        def alive(what):
            """Raise SchedulerLost unless the scheduler answers and a verified worker is left."""
            try:
                now = _bounded(lambda: client.scheduler_info(n_workers=-1), timeout).get("workers", {})
            except (_NoAnswer, OSError) as e:
                why = f"no answer within {timeout:g} s" if isinstance(e, _NoAnswer) else _first_line(e)
                raise SchedulerLost(f"lost the Dask scheduler at {address} {what} ({why})") from None
            if not set(now) & set(good):
                raise SchedulerLost(f"no verified worker is left at the Dask scheduler at {address} "
                                    f"({len(good)} ran this code: {', '.join(good)})")

        def outcome(fut, spec):
            """The record of a future Dask calls done; None: not done (any more), wait on."""
            for _ in range(3):
                status = fut.status
                if status == "pending":  # its result was lost with a worker: Dask runs it again
                    return None
                if status not in ("finished", "error"):  # cancelled, lost: the cluster's doing
                    raise SchedulerLost(f"lost the Dask scheduler at {address} mid-run (the run "
                                        f"{spec.label()} was {status})")
                try:
                    if status == "finished":
                        return _bounded(lambda: fut.result(timeout=timeout), timeout + 1)
                    # the run raised, or Dask gave up on it (KilledWorker)
                    return failed_record(spec.key, _bounded(lambda: fut.exception(timeout=timeout), timeout + 1))
                except (_NoAnswer, TimeoutError):
                    alive(f"while fetching the record of {spec.label()}")
                except (Exception, asyncio.CancelledError) as e:  # noqa: BLE001
                    alive(f"while fetching the record of {spec.label()}")
                    if fut.status == status:  # a record that does not unpickle here, say
                        return failed_record(spec.key, e)
            return None

        for i, stage in enumerate(stages):
            _load_mark(stats, stages, i)
            pending = {}
            for scene, spec in stage:
                kw = {"resources": {"timing": 1}} if spec.timed and timing_worker else {}
                fut = client.submit(_execute, scene, spec, quick, key=f"rk4h-{spec.key}", pure=False,
                                    workers=good, allow_other_workers=False, **kw)
                pending[fut] = spec
            while pending:
                try:
                    finished = _bounded(lambda: dask_wait(list(pending), timeout=timeout,
                                                          return_when="FIRST_COMPLETED").done, timeout + 1)
                except (_NoAnswer, TimeoutError):  # a long run, or a cluster gone quiet
                    alive("mid-run")
                    continue
                except Exception as e:  # noqa: BLE001 - FuturesCancelledError: the scheduler is gone
                    finished = [f for f in pending if f.status != "pending"]
                    if not finished:
                        raise SchedulerLost(f"lost the Dask scheduler at {address} mid-run "
                                            f"({_first_line(e)})") from None
                for fut in finished:
                    spec = pending.pop(fut)
                    rec = outcome(fut, spec)
                    if rec is None:
                        pending[fut] = spec
                    else:
                        done(spec, rec)
        _load_mark(stats, stages, len(stages))
    except SchedulerLost as e:
        lost = e
        raise
    finally:
        try:
            _bounded(lambda: client.close(timeout=timeout), timeout + 1)
        except Exception:  # noqa: BLE001 - closing a dead connection
            if lost is None:
                print("run_all: the Dask client did not close cleanly", file=sys.stderr)
