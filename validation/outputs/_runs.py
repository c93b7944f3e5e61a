"""The scene's timed runs, shared by the outputs they feed (``state``,
``energy``, ``work_precision``, ``trajectory``): one plan and one
measurement, called once however many of those outputs a scene lists."""
from __future__ import annotations

from rk4h.validation.outputs import solver_loop


def plan(p) -> list:
    """The reference on the scene's output grid, then every solver at every
    step or tolerance of the scene, timed ``p.repeats`` times, keeping what
    the wanted outputs ask of them (:attr:`rk4h.validation.outputs.Output.run_keep`)."""
    from rk4h.validation.plan import settings_of

    out = [p.spec("truth", grid="scene")]
    for solver in p.scene.solvers:
        for s in settings_of(p.scene, solver):
            out.append(p.spec("run", solver=solver, setting=float(s), grid="scene", repeats=int(p.repeats),
                              keep=p.keep))
    return out


def measure(m) -> None:
    """``accuracy`` rows, and the ``energy``/``work_precision``/``cheapest``
    rows and figures of the outputs the scene lists
    (:func:`rk4h.validation.measure.measure_runs`)."""
    from rk4h.validation.measure import measure_runs

    measure_runs(m.scene, m.specs("run"), m.records, m.res, m.draw, m.specs("confirm"))


#: The loops the runs run (:attr:`rk4h.validation.outputs.Output.loops`).
LOOPS = {"run": solver_loop}

#: What the runs record (the purposes' documentation).
PURPOSES = {"truth": "the reference on the scene's output grid (its kind, the state's scale)",
            "run": "one solver at one setting, timed: errors against the truth, energy drift, RHS calls, steps, "
                   "wall and compile time; the energy series and the trajectory when an output keeps them"}
