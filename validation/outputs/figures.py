"""``figures``: the figures of the other outputs and the state figures."""
from rk4h.validation.outputs import Output, solver_loop


def plan(p) -> list:
    """The trajectory of the state figures: the method under test at the
    scene's finest step, else the reference, on the figure grid."""
    from rk4h.validation.plan import under_test

    if not p.draw:
        return []
    if p.scene.h and under_test(p.scene):
        return [p.spec("figure", solver=under_test(p.scene), setting=float(min(p.scene.h)), grid="figure",
                       keep=("trajectory",))]
    return [p.spec("truth", grid="figure", keep=("trajectory",))]


def measure(m) -> None:
    from rk4h.validation.measure import measure_state_figure

    measure_state_figure(m.scene, m.specs("figure") + [s for s in m.specs("truth") if s.grid == "figure"],
                         m.records, m.res)


OUTPUT = Output(
    name="figures", rank=60, plan_rank=20, measure_rank=20,
    when="every model",
    what="the figures of the outputs above and the state figures (trajectory, phase portrait)",
    applies=lambda facts: facts.dense,
    plan=plan, measure=measure,
    purposes={"figure": "the trajectory of the state figures (the method under test at the finest step)"},
    loops={"figure": solver_loop},
)
