"""``modal_energy``: the energy in the lowest linear modes against time (FPUT)."""
from rk4h.validation.outputs import Output, Table


def plan(p) -> list:
    from rk4h.validation.plan import settings_of

    return [p.spec("modal", solver=solver, setting=float(min(settings_of(p.scene, solver))), grid="scene",
                   keep=("modal",)) for solver in p.scene.solvers]


def measure(m) -> None:
    from rk4h.validation.measure import measure_modal

    measure_modal(m.scene, m.specs("modal"), m.records, m.res, m.draw)


OUTPUT = Output(
    name="modal_energy", rank=90, plan_rank=70, measure_rank=70,
    when="models with a linearization",
    what="energy in each of the lowest four modes against time (FPUT): `modal_energy.csv` and its figure",
    applies=lambda facts: facts.dense and facts.linearized,
    plan=plan, measure=measure,
    purposes={"modal": "per solver at its finest setting, the energy fractions of the lowest modes over time"},
    tables=(Table("modal_energy"),),
)
