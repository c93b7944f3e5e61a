"""``energy``: the energy drift of the scene's runs, against theory where one applies."""
from rk4h.validation.outputs import Output, Table, _runs

OUTPUT = Output(
    name="energy", rank=20, plan_rank=10, measure_rank=10,
    when="every mechanical model; a first-order ODE (model `ode`) with an `invariant`",
    what="energy drift of those runs, against theory for tableaux on linear models: `energy.csv`, the energy "
         "figure",
    applies=lambda facts: facts.dense and facts.conserved,
    plan=_runs.plan, measure=_runs.measure, purposes=_runs.PURPOSES, loops=_runs.LOOPS,
    run_keep=lambda draw: ("energy",) if draw else (),  # the energy figure's series
    tables=(Table("energy"),),
)
