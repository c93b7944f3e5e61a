"""``stability``: the stability study of a scene's ``[stability]`` table."""
from validation.outputs import Output, Table


def plan(p) -> list:
    from validation import stability

    return [p.spec("stability", unit=u) for u in stability.units(p.scene, p.quick)]


def measure(m) -> None:
    from validation.measure import measure_stability

    if m.specs("stability"):
        measure_stability(m.scene, m.specs("stability"), m.records, m.res, m.quick)


OUTPUT = Output(
    name="stability", rank=70, plan_rank=90, measure_rank=80,
    when="scenes with a `[stability]` table",
    what="the stability study: `stability.csv` and its figures",
    applies=lambda facts: facts.stability,
    plan=plan, measure=measure,
    purposes={"stability": "one unit of the stability study (validation.stability.units)"},
    tables=(Table("stability"),),
)
