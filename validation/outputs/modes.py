"""``modes``: the natural frequencies of the model's linearization."""
from rk4h.validation.outputs import Output, Table


def plan(p) -> list:
    return [p.spec("modes")]


def measure(m) -> None:
    from rk4h.validation.measure import measure_modes

    measure_modes(m.scene, m.specs("modes"), m.records, m.res)


OUTPUT = Output(
    name="modes", rank=50, plan_rank=50, measure_rank=50,
    when="models with a linearization",
    what="natural frequencies of the linearization: `modes.csv`",
    applies=lambda facts: facts.dense and facts.linearized,
    plan=plan, measure=measure,
    purposes={"modes": "the natural angular frequencies and whether the model is linear"},
    tables=(Table("modes"),),
)
