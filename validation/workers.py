"""How many local worker processes a plan repays.

A worker process costs CPU before it computes anything: a fresh interpreter
(``spawn``) imports the harness, numpy, scipy, numba's cached loops and the
drawing stack, and builds its own per-process caches; about
:data:`WORKER_START_SECONDS` each (issue 29 measured 1.9 s: imports 1.0 s,
cached loops 0.2 s, the drawing stack 0.65 s). On one process the plan costs
its estimated CPU time ``E`` (:func:`plan_seconds`); on ``w`` workers about
``E + w S`` CPU seconds in ``E / w + S`` wall seconds at best. So the
runner starts ``w > 1`` workers only when

* the pool's start-up is a small part of the work: ``w S <= MAX_EXTRA_CPU E``
  (two workers cost at most 15% more CPU than one), and
* the work can be shared: no single spec is estimated above ``E / w`` (a
  worker waiting for one long spec repays nothing).

and ``w`` is at most the cores this process may use. A small scene (a
3-mass chain, default outputs: well under a second of work) runs in the main
process and starts no pool; the full report (minutes of work) uses every
core. ``--workers N`` (or ``RK4H_WORKERS``) overrides the choice.

The estimate is coarse by design: :func:`rk4h.validation.budget.spec_steps` gives
each spec's integration steps; a cost per step and per step and degree of
freedom by kind of solver (:data:`STEP_SECONDS`) turns them into seconds, plus a fixed cost
per spec and, with figures, per scene. The constants are CPU seconds on the
2-core development machine (see ``docs/performance.md``); a machine twice as
fast halves ``E`` and ``S`` alike, which leaves the decision unchanged.
"""
from __future__ import annotations

import math

__all__ = ["choose_workers", "plan_seconds", "spec_seconds_function", "WORKER_START_SECONDS",
           "MAX_EXTRA_CPU"]

#: CPU seconds a worker process costs before its first spec (start-up, imports, caches).
WORKER_START_SECONDS = 2.0
#: Largest share of the plan's estimated CPU time the pool's start-up may add.
MAX_EXTRA_CPU = 0.15
#: CPU seconds of any spec beyond its steps (building the problem, the record, the dispatch).
SPEC_SECONDS = 0.005
#: CPU seconds per scene for drawing its figures (when figures are drawn).
FIGURE_SECONDS = 1.0
#: CPU seconds ``(per step, per step and degree of freedom)`` by the kind of
#: stepper (:class:`rk4h.references.registry.Kind` value): compiled fixed-step
#: loops; Python-stepped references (scipy's DOP853 about 124 us per step on
#: the 2-DOF case, CVODE a Python right-hand side per call); ``"native"``:
#: a reference whose registry entry has ``native_steps`` (heyoka, compiled);
#: a user's Python or command method. A quadruple-precision
#: (truth) step counts as 1e3 compiled steps, as in the budget (the cost of a
#: cold run: a warm one reads its truths from the cache).
STEP_SECONDS = {"tableau": (0.0, 3e-7), "partitioned": (0.0, 3e-7), "reference": (1.2e-4, 1e-6),
                "python": (1e-4, 1e-6), "command": (1e-4, 1e-6), "native": (1e-6, 3e-7), "compiled": (0.0, 3e-7)}


def _step_kind(scene, solver) -> str:
    """The :data:`STEP_SECONDS` key of ``solver`` in ``scene``: ``"native"``
    for a reference whose registry entry says its steps run in compiled code
    (``Method.native_steps``), else the method's kind."""
    try:
        method = scene.method(solver)
    except Exception:  # noqa: BLE001 - an estimate only; the run reports an unknown method
        return "reference"
    if getattr(method, "native_steps", False):
        return "native"
    return getattr(method.kind, "value", "reference")


def spec_seconds_function(quick: bool = False):
    """``seconds(scene, spec) -> float``: a spec's estimated CPU seconds on
    one process (see the module docstring); 0 beyond the fixed cost when its
    steps cannot be estimated."""
    from rk4h.validation import budget

    models = {}

    def seconds(scene, spec):
        if scene.name not in models:
            try:
                model = scene.build_model()
                models[scene.name] = (model, budget._omega_bound(model))
            except Exception:  # noqa: BLE001 - an estimate only; the run reports the fault
                models[scene.name] = (None, math.nan)
        model, w = models[scene.name]
        if model is None or not math.isfinite(w):
            return SPEC_SECONDS
        try:
            steps, truth = budget.spec_steps(scene, spec, model, w, quick)
        except Exception:  # noqa: BLE001
            return SPEC_SECONDS
        step, dof = STEP_SECONDS["compiled"]
        if spec.purpose in ("run", "confirm", "figure", "modal") and spec.solver:
            step, dof = STEP_SECONDS.get(_step_kind(scene, spec.solver), (step, dof))
        quad = 1e3 * truth * STEP_SECONDS["compiled"][1] * model.n_dof
        return SPEC_SECONDS + steps * (step + dof * model.n_dof) + quad

    return seconds


def plan_seconds(jobs, *, quick=False, figures=True, done=(), seconds=None):
    """``(total, longest)``: the estimated CPU seconds of ``jobs``
    (``[(scene, spec), ...]``) on one process, leaving out the specs whose
    key is in ``done`` (records to resume), and of its longest spec.
    ``seconds``: a per-spec estimate (default :func:`spec_seconds_function`)."""
    seconds = seconds or spec_seconds_function(quick)
    done = set(done)
    each = [seconds(scene, spec) for scene, spec in jobs if spec.key not in done]
    total = math.fsum(each)
    if figures:
        total += FIGURE_SECONDS * len({scene.name for scene, _ in jobs})
    return total, max(each, default=0.0)


def choose_workers(jobs, *, quick=False, figures=True, done=(), cores=None, seconds=None):
    """How many local worker processes to run ``jobs`` on (1: in this
    process, no pool) and why, in a phrase for the run's summary line.

    Parameters
    ----------
    jobs : list of (Scene, RunSpec)
        The plan.
    quick, figures : bool
        As the run's (``quick``: the stability units' quick settings).
    done : iterable of str
        Keys of specs whose records will be resumed (no work).
    cores : int or None
        At most this many workers (default: the cores this process may use,
        :func:`rk4h.validation.engine.default_workers`).
    seconds : callable(scene, spec) -> float, or None
        Per-spec CPU seconds (default :func:`spec_seconds_function`).

    Returns
    -------
    (int, str)
    """
    if cores is None:
        from rk4h.validation.engine import default_workers

        cores = default_workers()
    total, longest = plan_seconds(jobs, quick=quick, figures=figures, done=done, seconds=seconds)
    est = f"estimated work {total:.1f} CPU s"
    if cores <= 1:
        return 1, f"{est}; one core"
    best = 1
    for w in range(2, cores + 1):
        if w * WORKER_START_SECONDS > MAX_EXTRA_CPU * total or longest > total / w:
            break
        best = w
    if best == 1:
        return 1, f"{est}, too little to repay a pool ({WORKER_START_SECONDS:g} CPU s per worker)"
    return best, f"{est}" + ("" if best == cores else f"; {cores} cores")
