"""``stability``: the stability study of a scene's ``[stability]`` table,
and the stability regions in the complex plane of the methods it is about."""
from rk4h.validation.outputs import Output, Table


def plan(p) -> list:
    from rk4h.validation import stability

    return [p.spec("stability", unit=u) for u in stability.units(p.scene, p.quick)]


def measure(m) -> None:
    from rk4h.validation.measure import FigureJob, measure_stability

    if m.specs("stability"):
        measure_stability(m.scene, m.specs("stability"), m.records, m.res, m.quick)
        m.res.figures.append(FigureJob(m.scene.name, "stability_region", {"methods": region_methods(m.scene)}))


def region_methods(scene) -> list[str]:
    """The methods of a scene's stability-region figure: its
    ``stability.method``, the tableau methods in its ``run.solvers`` (its own
    and the built-in fixed-step ones) and, when it runs the ``boundary``
    study, the built-ins every boundary study measures
    (:data:`rk4h.references.registry.BOUNDARY_ALWAYS`), in that order."""
    from rk4h.references.registry import BOUNDARY_ALWAYS, UNDER_TEST, resolve

    st = scene.stability or {}
    local = getattr(scene, "registry", None) or {}
    names = [st.get("method") or UNDER_TEST]
    for name in scene.solvers:
        try:
            if resolve(name, local).tableau is not None:
                names.append(name)
        except ValueError:  # not a method of the registry (rk4h.validation.scenes refused it before)
            continue
    if "boundary" in (st.get("studies") or ()):
        names += list(BOUNDARY_ALWAYS)
    return list(dict.fromkeys(names))


def draw_region(out_dir, job, scene) -> list:
    """The stability-region figure of ``job.data["methods"]`` (names of the
    scene's registry or built-ins): ``[(Path, Caption)]``, caption kind
    ``stability_region``. Evaluates the stability functions on the figure's
    grid (:func:`rk4h.validation.stability.region.region_plot`); integrates
    nothing."""
    from rk4h.references.registry import resolve
    from rk4h.validation.stability import draw, region

    local = getattr(scene, "registry", None) or {}
    tabs = [resolve(name, local).tableau for name in job.data["methods"]]
    if any(tab is None for tab in tabs):
        raise ValueError(f"`methods` must name tableau methods, got {job.data['methods']}")
    return [draw(region.region_plot(job.scene, tabs), out_dir)]


OUTPUT = Output(
    name="stability", rank=70, plan_rank=90, measure_rank=80,
    when="scenes with a `[stability]` table",
    what="the stability study: `stability.csv` and its figures, and the stability regions in the complex plane "
         "of the methods it is about (`<scene>_stability_region.png`)",
    applies=lambda facts: facts.stability,
    plan=plan, measure=measure, draw={"stability_region": draw_region},
    purposes={"stability": "one unit of the stability study (rk4h.validation.stability.units)"},
    # the study's loop on the scene's model (stability_planar4's RK4 on planar4)
    loops={"stability": lambda scene, spec: [("stability", "")]},
    tables=(Table("stability"),),
)
