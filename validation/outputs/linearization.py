"""``linearization``: the linearized model's exact solution against the nonlinear truth."""
from rk4h.validation.outputs import Output, Table


def plan(p) -> list:
    from rk4h.validation.plan import _nonlinear

    out = [p.spec("truth", grid="scene")]
    if _nonlinear(p.scene):
        out.append(p.spec("linearization", grid="scene", keep=("trajectory",) if p.draw else ()))
    return out


def measure(m) -> None:
    from rk4h.validation.measure import measure_linearization

    measure_linearization(m.scene, m.specs("linearization"), m.records, m.res)


OUTPUT = Output(
    name="linearization", rank=100, plan_rank=30, measure_rank=30,
    when="nonlinear models with a linearization",
    what="the linearized model's exact solution against the nonlinear truth: `linearization.csv`",
    applies=lambda facts: facts.dense and facts.linearized and not facts.linear,
    plan=plan, measure=measure,
    purposes={"linearization": "the linearized model's largest coordinate error against the nonlinear truth"},
    tables=(Table("linearization"),),
)
