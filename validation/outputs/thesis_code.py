"""``thesis_code``: the thesis' own programs in GNU Octave against rk4core."""
from rk4h.validation.outputs import Output, Table


def plan(p) -> list:
    return [p.spec("thesis_code")]


def measure(m) -> None:
    from rk4h.validation.measure import measure_thesis_code

    measure_thesis_code(m.scene, m.specs("thesis_code"), m.records, m.res)


OUTPUT = Output(
    name="thesis_code", rank=110, plan_rank=80, measure_rank=90,
    when="never by default (it runs the thesis' own programs, not the scene's model)",
    what="the thesis' Code 01-03 in GNU Octave against rk4core: `thesis_code.csv`",
    plan=plan, measure=measure,
    purposes={"thesis_code": "the thesis' programs run in GNU Octave, compared with rk4core and the truth"},
    tables=(Table("thesis_code"), Table("thesis_errata")),
)
