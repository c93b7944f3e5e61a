"""The untimed fixed-step runs of a ``[sweep]``'s points, as one batch each.

The points of a sweep (:mod:`rk4h.validation.sweeps`) are scenes of their
own, each with its own specs. Where several points need a fixed-step run of
one method at one step on one output grid -- the same untimed purpose
(:data:`BATCH_PURPOSES`), a model of one compiled-force structure, states of
one size -- and differ only in numeric parameters or initial values, those
runs are one :func:`rk4h.ensemble` call (numba backend): :func:`group`
turns their jobs into one :class:`SpecGroup`, which the engine runs as one
task, and :func:`execute_group` splits the batch back into one record per
spec, made by the very code that makes the record of a run of its own
(:func:`rk4h.validation.execute.execute`, handed the batch's run for the
spec). The numba batch runs, per instance, the loop the scalar path runs
(:func:`rk4h.references.solvers.fixed.run_fixed`), with the same growth
bound (``MAX_GROWTH`` times the instance's own position and velocity
scales): every record equals the one its spec would make alone, bit for
bit. An instance the instability rule stops is rerun alone (its record, its
message and its ``t_fail``, are then exactly those of a run of its own);
the others keep their batch results.

Timed specs (``run``, ``confirm``) are never grouped: their wall times are
what a user runs per point. Nor are specs whose point cannot be batched
(no compiled force, a method without a tableau, a state scale that is not
finite, a first-order model): they run as before.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["BATCH_PURPOSES", "SpecGroup", "group", "execute_group", "batch_key"]

#: A batch is formed only when its points together take at least this many
#: steps (instances x steps each): below it, separate runs cost less than
#: loading the batch's ``prange`` wrapper (generated beside the loop and kept
#: in numba's on-disk cache, :func:`rk4h.batch._numba.batch_loop`: 0.47-0.59 s
#: for the first batch of a process with a warm cache, 3.8-4.1 s when it is
#: compiled, ``benchmarks/bench_batch_load.py`` on the loaded 2-core
#: development machine), against about 30 ns per RK4 step of a small model.
BATCH_MIN_STEPS = 2 * 10 ** 7
#: Untimed purposes whose run is one fixed-step integration from the scene's
#: initial state (:mod:`rk4h.validation.execute`): the state figures' run, a
#: convergence sweep's run, the modal-energy run.
BATCH_PURPOSES = ("figure", "order", "modal")


@dataclass(frozen=True)
class SpecGroup:
    """Jobs ``((scene, spec), ...)`` of several sweep points run as one batch.

    The engine treats it as one untimed spec: :attr:`key` (the first spec's,
    for a failed record that :meth:`split` hands to every spec),
    :meth:`label`, :attr:`timed` (False)."""

    jobs: tuple

    @property
    def specs(self) -> tuple:
        return tuple(s for _, s in self.jobs)

    @property
    def key(self) -> str:
        return self.jobs[0][1].key

    @property
    def purpose(self) -> str:
        return self.jobs[0][1].purpose

    timed = False

    def label(self) -> str:
        return f"{self.jobs[0][1].label()} and {len(self.jobs) - 1} more sweep point(s), as one batch"

    def split(self, result) -> list:
        """``[(spec, record), ...]`` of :func:`execute_group`'s list, or of one
        failure (a record or an exception) given to every spec."""
        from .records import RunRecord, failed_record

        if isinstance(result, list):
            return list(zip(self.specs, result))
        out = []
        for spec in self.specs:
            if isinstance(result, BaseException):
                rec = failed_record(spec.key, result)
            else:
                rec = RunRecord(spec.key, status=result.status, message=result.message)
            out.append((spec, rec))
        return out


def _step(scene, model, spec, t) -> float:
    """The step (s) the spec's executor integrates with (see
    :func:`rk4h.validation.execute._order_spec` for ``order``)."""
    if spec.purpose == "order":
        n0 = t.shape[0] - 1
        return float(t[-1]) / (n0 * max(1, round(spec.param("theta0") / spec.setting)))
    return float(spec.setting)


def _prepare(scene, spec):
    """What a batch needs of one job, or None when it cannot be batched:
    ``(key, model, y0, t, h, tableau, kern, y_scale)``."""
    from rk4h import fast
    from rk4h.fast import force_kernel
    from rk4h.references.solvers.tolerances import group_scales

    from .execute import grid, problem

    if not getattr(scene, "sweep", None) or spec.purpose not in BATCH_PURPOSES or spec.timed:
        return None
    method = scene.method(spec.solver)
    if method.tableau is None:
        return None
    model, y0 = problem(scene)
    if getattr(model, "first_order", False) or not fast.supports(model):
        return None
    kern = force_kernel(model)
    if kern is None or y0.shape != (2 * model.n_dof,) or not np.isfinite(y0).all():
        return None
    s_q, s_v = group_scales(model, y0)
    if not (math.isfinite(s_q) and math.isfinite(s_v)):
        return None
    t = np.asarray(grid(scene, model, spec), float)
    h = _step(scene, model, spec, t)
    n = model.n_dof
    y_scale = np.concatenate([np.full(n, s_q), np.full(n, s_v)])
    structure = (kern.key(), kern.scalar_key() if kern.has_scalar() else None, kern.ip.tobytes(), kern.fp.shape,
                 np.shape(model.mass), type(model).__name__)
    key = (scene.base, spec.purpose, spec.solver, repr(method.tableau), h, t.tobytes(), structure)
    return key, model, y0, t, h, method.tableau, kern, y_scale


def batch_key(scene, spec):
    """The key under which ``spec`` of ``scene`` joins a batch (jobs of one
    key run as one), or None when it runs alone."""
    p = _prepare(scene, spec)
    return None if p is None else p[0]


def _steps(key) -> int:
    """Steps of one run of the batch ``key`` (its step and output grid)."""
    from rk4h import step_count

    t = np.frombuffer(key[5], dtype=np.float64)
    return int(step_count((float(t[0]), float(t[-1])), key[4]))


def _bound(scene, spec):
    """``(key, steps)`` without building the model: a coarser key than
    :func:`batch_key`'s (points of one batch share it) and an upper bound on
    the steps of the spec's run (inf when unknown); None when it runs alone."""
    if not getattr(scene, "sweep", None) or spec.purpose not in BATCH_PURPOSES or spec.timed:
        return None
    key = (scene.base, spec.purpose, spec.solver, spec.setting, spec.grid, spec.params)
    if spec.purpose != "order":  # the figure and modal grids end at t_end, stepped by h = setting
        return key, math.ceil(scene.t_end / spec.setting) + 1
    if "t_end" in scene.convergence:
        return key, math.inf
    # one period of the fastest mode, n0 = ceil(T omega_max / theta0) <= ceil(2 pi / theta0) intervals
    theta0 = spec.param("theta0")
    return key, (math.ceil(2.0 * math.pi / theta0) + 1) * max(1, round(theta0 / spec.setting)) + 1


def group(jobs) -> list:
    """``jobs`` (``[(scene, spec), ...]``) with the jobs of each batch key
    held by two or more of them, with :data:`BATCH_MIN_STEPS` steps or more
    in all, replaced by one ``(None, SpecGroup)`` at the place of the first;
    the others as they were."""
    coarse = []
    for scene, spec in jobs:
        try:
            coarse.append(_bound(scene, spec))
        except Exception:  # noqa: BLE001 - runs alone, where its fault becomes its record
            coarse.append(None)
    counts: dict = {}
    for c in coarse:
        if c is not None:
            counts[c[0]] = counts.get(c[0], 0) + 1
    keys = []
    for (scene, spec), c in zip(jobs, coarse):
        if c is None or counts[c[0]] < 2 or counts[c[0]] * c[1] < BATCH_MIN_STEPS:
            keys.append(None)  # no batch can reach the threshold: no model built to find out
            continue
        try:
            keys.append(batch_key(scene, spec))
        except Exception:  # noqa: BLE001 - a point that cannot build fails at execution, with its message
            keys.append(None)
    members: dict = {}
    for i, k in enumerate(keys):
        if k is not None:
            members.setdefault(k, []).append(i)
    out, placed = [], set()
    for i, job in enumerate(jobs):
        k = keys[i]
        if k is None or len(members[k]) < 2 or len(members[k]) * _steps(k) < BATCH_MIN_STEPS:
            out.append(job)
        elif k not in placed:
            placed.add(k)
            out.append((None, SpecGroup(tuple(jobs[j] for j in members[k]))))
    return out


def execute_group(group_: SpecGroup, quick: bool = False) -> list:
    """The records of ``group_``'s specs, in order: one batch
    (:func:`rk4h.ensemble`, numba), each ok instance's run handed to
    :func:`rk4h.validation.execute.execute` for its spec; an instance that
    failed, a job that cannot join, and every job of a batch that raised run
    alone."""
    import time

    import rk4h
    from rk4h.references.solvers.base import SolverRun, Status
    from rk4h.references.solvers.fixed import MAX_GROWTH

    from . import execute as ex

    prepared = []
    for scene, spec in group_.jobs:
        try:
            prepared.append(_prepare(scene, spec))
        except Exception:  # noqa: BLE001 - runs alone, where its fault becomes its record
            prepared.append(None)
    keys = [p[0] if p is not None else None for p in prepared]
    first = next((i for i, k in enumerate(keys) if k is not None), None)
    batch = [i for i, k in enumerate(keys) if first is not None and k == keys[first]]
    runs = {}
    if len(batch) >= 2:
        _, model, _, t, h, tab, kern, _ = prepared[batch[0]]
        y0 = np.stack([prepared[i][2] for i in batch])
        y_scale = np.stack([prepared[i][7] for i in batch])
        fp = np.stack([np.asarray(prepared[i][6].fp, np.float64) for i in batch])
        mass = np.stack([np.asarray(prepared[i][1].mass, np.float64) for i in batch])
        groups = [(np.arange(len(batch)), np.ascontiguousarray(fp), np.ascontiguousarray(mass), kern)]
        start = time.perf_counter()
        try:
            res = rk4h.ensemble(model, y0, (float(t[0]), float(t[-1])), h=h, method=tab, t_eval=t,
                                backend="numba", max_growth=MAX_GROWTH, y_scale=y_scale, groups=groups)
        except Exception as e:  # noqa: BLE001 - the points run alone, where a fault becomes their record
            from . import interrupt
            from .atomic import is_environment_error

            if is_environment_error(e) or interrupt.pending():
                raise
            batch = []
        wall = (time.perf_counter() - start) / max(1, len(batch))
        for b, i in enumerate(batch):
            if res.status[b] != 0:
                continue  # rerun alone: its failure is a run of its own
            spec = group_.jobs[i][1]
            runs[spec.key] = SolverRun(
                res.method, h, t, np.ascontiguousarray(res.y[b].T), int(rk4h.nfev_count(tab, int(res.n_steps[b]))),
                int(res.n_steps[b]), wall, 0.0, status=Status.OK,
                message="The solver successfully reached the end of the integration interval.",
                t_fail=None, extra={"h_used": res.h, "path": "numba", "batch": len(batch), "reason": "ok"})
    records = []
    for scene, spec in group_.jobs:
        run = runs.pop(spec.key, None)
        if run is not None:
            ex.PREPARED[spec.key] = run
        try:
            records.append(ex.execute(scene, spec, quick))
        finally:
            ex.PREPARED.pop(spec.key, None)
    return records
