"""``work_precision``: error against cost, and the trust table of the method under test."""
from rk4h.validation.outputs import Output, Table, _runs, solver_loop

OUTPUT = Output(
    name="work_precision", rank=40, plan_rank=10, measure_rank=10,
    when="every model",
    what="error against wall time and RHS calls, the cheapest solver per target: `work_precision.csv`, the "
         "work-precision figure",
    applies=lambda facts: facts.dense,
    plan=_runs.plan, measure=_runs.measure,
    purposes={**_runs.PURPOSES, "confirm": "a run confirming a verdict of the trust table, planned from the "
                                           "records (rk4h.validation.confirm)"},
    # a confirmation steps a reference's compiled loop (rk4h.validation.execute)
    loops={**_runs.LOOPS, "confirm": lambda scene, spec: solver_loop(scene, spec) + [("compiled", spec.solver)]},
    tables=(Table("work_precision"), Table("cheapest")),
)
