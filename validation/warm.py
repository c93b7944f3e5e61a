"""Compile each numba loop of a plan once per machine, before the runs (issue 29).

The compiled loops (:mod:`rk4h.fast`) are kept in numba's on-disk cache
under ``RK4H_CACHE``; a loop missing there is compiled on its first call in a
process. With several worker processes and a cold cache, every worker used
to compile the same loops at the same time (each loop's compile time paid
once per worker). :func:`warm_pools` instead hands each *distinct* loop the
plan needs, as the output owning each spec's purpose declares them
(:attr:`rk4h.validation.outputs.Output.loops`) -- a fixed-step method on a
force structure (the scene's runs, confirmations, convergence sweeps, the
state figures' run, the energy work-precision runs), or the compiled
right-hand side DOP853 and CVODE call, or their compiled loops for the
confirmation runs (a round of those is planned from the records and warmed
like the plan), or a stability study's method on the scene's model, or an
ensemble's batch loop -- to one worker, the loops spread over
all workers, and waits; the runs after it load the loops from the cache
(about 0.2 s per process for all of them).

Nothing here decides a result: a loop that fails to compile here is compiled
(and fails, as a record) again in its run; a warm cache makes every job here
a cache load. One-process runs (``--workers 1``) skip it: the one process
compiles each loop once anyway.
"""
from __future__ import annotations

import time

__all__ = ["loop_jobs", "warm_one", "warm_pools", "STABILITY", "BATCH", "COMPILED"]

#: Reference adapters (``Method.adapter``) that call the model's compiled right-hand side.
_COMPILED_REFERENCES = ("dop853", "cvode-adams", "cvode-bdf")
#: The adapters that call the compiled right-hand side on a read-only state
#: (scikit-sundae hands CVODE's state over read-only). Since round 3 of the
#: cold start the right-hand side is compiled for that one signature only
#: (``rk4h.fast.solve._one_signature``); CVODE's job is still preferred.
_READONLY_STATE = ("cvode-adams", "cvode-bdf")


#: The ``solver`` of a job that prepares a stability study's loop: the scene's
#: ``stability.method`` on its model (a stability spec names no solver; the
#: studies other than ``boundary`` integrate that method, on the scene's model
#: or on others, e.g. a linearized one, that are not prepared here).
STABILITY = "<stability.method>"
#: The prefix of a job's ``solver`` that prepares that solver's ensemble loop
#: (``rk4h.ensemble``'s numba backend: the fixed-step loop's text with a
#: parallel ``batch`` function after it, a module of its own) on the scene's
#: model: ``BATCH + "rk4"``.
BATCH = "<batch>"
#: The prefix of a job's ``solver`` that prepares that reference's compiled
#: loop for untimed work (``rk4h.references.solvers.integrate_compiled``:
#: DOP853's loop on the model's right-hand side, CVODE's C callbacks), which
#: the confirmation runs step: ``COMPILED + "dop853"``.
COMPILED = "<compiled>"


def _stability_tableau(scene):
    """The tableau of ``scene``'s ``stability.method``."""
    from .stability.params import validate_params
    from .stability.studies import context_method

    return context_method(scene, validate_params(dict(scene.stability or {})))[1]


def _adapter(scene, solver) -> str:
    """The registry adapter of ``solver`` in ``scene`` (its name for a method without one)."""
    return scene.method(solver).runner_key


def _loop_key(scene, solver):
    """What identifies the compiled code ``solver`` runs on ``scene``'s model
    (None: nothing compiled ahead: no compiled force, heyoka, a command...)."""
    from rk4h import fast
    from rk4h.fast.codegen import array_loop, loop_key

    from .execute import problem

    model, y0 = problem(scene)
    kern = fast.force_kernel(model)
    if kern is None:
        return None
    if solver.startswith(BATCH):
        from rk4h.batch._numba import batch_key

        tab = _tableau(scene.method(solver[len(BATCH):]))
        return None if tab is None else ("batch",) + batch_key(tab, kern, len(y0))[0]
    if solver.startswith(COMPILED):
        from rk4h.references.solvers import COMPILED_LOOPS

        loop = COMPILED_LOOPS.get(scene.method(solver[len(COMPILED):]).runner_key)
        return None if loop is None else ("compiled", loop, kern.key())
    if solver == STABILITY:
        tab = _stability_tableau(scene)
    else:
        method = scene.method(solver)
        tab = _tableau(method)
    if tab is not None:  # the key of the generated module rk4h.fast.solve_model loads
        array = array_loop(kern, 2 * model.n_dof)
        return ("array" if array else "scalar",) + loop_key(tab, kern, array)[1:]
    if method.runner_key in _COMPILED_REFERENCES:
        return ("rhs", kern.key())
    return None


def _tableau(method):
    """The tableau of ``method`` (a ``scene.method``), or None (not a fixed-step tableau)."""
    from rk4h.references.registry import Kind

    return method.tableau if method.kind in (Kind.TABLEAU, Kind.PARTITIONED) else None


def _solvers(scene, spec) -> list:
    """The job ``solver`` strings of the loops ``spec`` runs (see
    :func:`loop_jobs`), as the output that owns its purpose declares them
    (:attr:`rk4h.validation.outputs.Output.loops`)."""
    from .outputs import loops

    declared = loops(getattr(spec, "purpose", ""))
    if declared is None:
        return []
    prefix = {"batch": BATCH, "compiled": COMPILED}
    return [STABILITY if kind == "stability" else prefix.get(kind, "") + name for kind, name in declared(scene, spec)]


def _batched_keys(jobs) -> set:
    """Keys of the specs of ``jobs`` the engine runs as one batch of a sweep's
    points (:func:`rk4h.validation.sweep_batch.group`, the engine's grouping of
    the untimed specs), whose loop is the batch's, compiled where it runs."""
    try:
        from .sweep_batch import BATCH_PURPOSES, group

        untimed = [(scene, spec) for scene, spec in jobs
                   if getattr(spec, "purpose", "") in BATCH_PURPOSES and not getattr(spec, "timed", False)]
        if not untimed:
            return set()
        alone = {spec.key for scene, spec in group(untimed) if scene is not None}
        return {spec.key for _, spec in untimed} - alone
    except Exception:  # noqa: BLE001 - an estimate of what to prepare: prepare everything
        return set()


def loop_jobs(jobs) -> list:
    """``(scene, solver)`` pairs, one per distinct compiled loop the plan's
    ``jobs`` (``(scene, spec)`` pairs) will run."""
    seen, out = {}, []
    batched = _batched_keys(jobs)
    for scene, spec in jobs:
        if getattr(spec, "key", None) in batched:  # runs in a sweep's batch loop, not this one
            continue
        try:
            solvers = _solvers(scene, spec)
        except Exception:  # noqa: BLE001 - the run itself will report it
            continue
        for solver in solvers:
            try:
                key = _loop_key(scene, solver)
            except Exception:  # noqa: BLE001 - the run itself will report it
                continue
            if key is None:
                continue
            if key not in seen:
                seen[key] = len(out)
                out.append((scene, solver))
            elif (key[0] == "rhs" and _adapter(scene, solver) in _READONLY_STATE
                  and _adapter(*out[seen[key]]) not in _READONLY_STATE):
                # one job per module (two jobs on one module, in two workers, would race on
                # numba's index file); CVODE's, which also calls the read-only form
                out[seen[key]] = (scene, solver)
    return out


def warm_one(scene, solver) -> float:
    """In a worker: compile (or load) the loop ``solver`` runs on ``scene``'s
    model; returns the seconds it took. Never raises."""
    start = time.perf_counter()
    try:
        from rk4h.references.solvers.base import compiled_rhs
        from rk4h import fast

        from .execute import problem

        model, y0 = problem(scene)
        if solver.startswith(BATCH):
            _warm_batch(model, y0, _tableau(scene.method(solver[len(BATCH):])))
            return time.perf_counter() - start
        if solver == STABILITY:
            fast.warm_up(model, _stability_tableau(scene))
            return time.perf_counter() - start
        if solver.startswith(COMPILED):
            _warm_compiled(scene.method(solver[len(COMPILED):]), model, y0)
            return time.perf_counter() - start
        method = scene.method(solver)
        tab = _tableau(method)
        if tab is not None:
            fast.warm_up(model, tab)
        else:
            rhs = compiled_rhs(model)
            if rhs is not None:
                rhs.checked(y0)  # compiles rhs_permuted, the one entry point of the references
                if method.runner_key in _READONLY_STATE:
                    _warm_readonly(rhs, y0)
    except Exception:  # noqa: BLE001 - best effort: the run compiles it again and reports
        pass
    return time.perf_counter() - start


def _warm_batch(model, y0, tab) -> None:
    """Compile (or load) ``tab``'s ensemble loop on ``model``: a batch of one
    instance, one step, through ``rk4h.ensemble``'s numba backend (the
    argument types of every batch it runs, so nothing more is compiled)."""
    import numpy as np

    import rk4h

    y = np.asarray(y0, dtype=float)[None, :]
    rk4h.ensemble(model, y, (0.0, 1e-3), h=1e-3, method=tab, backend="numba")


def _warm_compiled(method, model, y0) -> None:
    """Compile (or load) ``method``'s compiled loop for untimed work on
    ``model``: one run over a span of a millionth of a second through
    :func:`rk4h.references.solvers.integrate_compiled`, which builds what
    every confirmation run of that reference on a model of that structure
    calls (DOP853's right-hand side, CVODE's callbacks of the model's kind)."""
    import numpy as np

    from rk4h.references.solvers import integrate_compiled

    integrate_compiled(method, model, np.asarray(y0, dtype=float), np.array([0.0, 1e-6]), 1e-6)


def _warm_readonly(rhs, y0) -> None:
    """Call ``rhs``'s entry point on a read-only state, the form CVODE's
    callback calls (the computed values are discarded): the one signature
    :class:`rk4h.fast.CompiledRHS` compiles, so nothing more is compiled."""
    import numpy as np

    z = np.array(y0, dtype=float)
    z.flags.writeable = False
    n = z.shape[0]
    perm = np.arange(n, dtype=np.int64)
    rhs._perm(rhs.fp, rhs.ip, rhs.mass, z, np.zeros(n), perm, np.zeros((3, n)), np.zeros_like(rhs.w))


def warm_pools(pools, jobs) -> int:
    """Compile every distinct loop of ``jobs`` once, spread over the worker
    processes of ``pools`` (:class:`rk4h.validation.engine.LocalPools`, started
    here), and wait for them; returns how many loops were handed out."""
    from concurrent.futures import wait

    pairs = loop_jobs(jobs)
    if not pairs:
        return 0
    pools.start()
    futures = []
    for i, (scene, solver) in enumerate(pairs):
        # the references' compiled loops share one loop compiled inside the package for every
        # model (DOP853's, CVODE's constant Jacobian): all in the lane's one process, one after
        # the other, so that it is compiled once, not once by each worker that meets it first
        name = "lane" if i % pools.workers == 0 or solver.startswith(COMPILED) else "general"
        futures.append((name, getattr(pools, name).submit(warm_one, scene, solver)))
    wait([f for _, f in futures])
    broken = {name for name, f in futures if f.exception() is not None}
    for name in broken:  # a worker died compiling: its pool is replaced, the runs compile for themselves
        pools.renew(name)
    return len(pairs)
