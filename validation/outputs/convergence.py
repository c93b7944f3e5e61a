"""``convergence``: the observed order of every fixed-step method."""
from rk4h.validation.outputs import Output, Table, solver_loop


def plan(p) -> list:
    """Per method (:func:`rk4h.validation.plan.order_methods`), a reference on the
    sweep's grid and one run per ``theta = omega_max h`` of ``[convergence]``."""
    from rk4h.validation.plan import order_methods

    out = []
    for method, key, default in order_methods(p.scene):
        thetas = tuple(sorted(p.scene.convergence.get(key, default), reverse=True))
        theta0 = (("theta0", float(thetas[0])),)
        out.append(p.spec("truth", grid="order", params=theta0))
        out += [p.spec("order", solver=method, setting=float(th), grid="order", params=theta0) for th in thetas]
    return out


def measure(m) -> None:
    from rk4h.validation.measure import measure_convergence

    if m.specs("order"):
        measure_convergence(m.scene, m.specs("order"), m.records, m.res, m.draw)


OUTPUT = Output(
    name="convergence", rank=30, plan_rank=40, measure_rank=40,
    when="models with a linearization (modes); first-order ODEs (model `ode`: theta = rate h, rate the "
         "spectral radius of the Jacobian at y0)",
    what="observed order of every fixed-step method from a sweep of omega_max h (`[convergence]`): "
         "`convergence.csv`",
    applies=lambda facts: facts.dense and (facts.linearized or facts.first_order),
    plan=plan, measure=measure,
    purposes={"order": "one fixed-step run of a convergence sweep: its step and its error against the truth"},
    loops={"order": solver_loop},
    tables=(Table("convergence"),),
)
