"""``state``: every solver at every step or tolerance against the reference."""
from rk4h.validation.outputs import Output, Table, _runs

OUTPUT = Output(
    name="state", rank=10, plan_rank=10, measure_rank=10,
    when="every model",
    what="every solver at every step or tolerance against the reference: `accuracy.csv`",
    applies=lambda facts: facts.dense,
    plan=_runs.plan, measure=_runs.measure, purposes=_runs.PURPOSES, loops=_runs.LOOPS,
    tables=(Table("accuracy"),),
)
