"""``ensemble``: error and energy-error statistics over a scene's ``[ensemble]``,
run as one batch per fixed-step solver and step."""
from rk4h.validation.outputs import Output, Table

#: The statistics of each quantity (median, 95th percentile, maximum over the instances).
STATS = ("median", "p95", "max")
#: Bytes of states one batch may hold (the rest runs in further chunks of instances).
CHUNK_BYTES = 256 * 2**20


def _methods(scene) -> list:
    """The scene's fixed-step solvers the batch can run (a tableau or a built-in name)."""
    return [s for s in scene.fixed_solvers if scene.method(s).tableau is not None]


def plan(p) -> list:
    if not p.scene.ensemble:
        return []
    return [p.spec("ensemble", solver=solver, setting=float(h)) for solver in _methods(p.scene)
            for h in p.scene.h]


def execute(scene, spec, quick):
    """One batch: every instance of ``[ensemble]`` with ``spec.solver`` at step
    ``spec.setting`` (s) over the scene's output grid, against each instance's
    exact modal solution."""
    import numpy as np

    import rk4h
    from rk4h.validation.ensemble import draw_instances, instance_errors, statistics
    from rk4h.validation.records import RunRecord

    model = scene.build_model()
    y0, params = draw_instances(scene.ensemble, model, scene.initial_x, scene.initial_v)
    t_eval = np.asarray(scene.t_eval(), float)
    tableau = scene.method(spec.solver).tableau
    B = y0.shape[0]
    # chunks of instances so the batch's states (B x rows x n float64) stay within CHUNK_BYTES
    chunk = max(1, int(CHUNK_BYTES // (8 * t_eval.size * y0.shape[1])))
    errs, eerrs, failed, built = [], [], 0, {}
    for lo in range(0, B, chunk):
        sl = slice(lo, min(B, lo + chunk))
        part = {k: np.asarray(v)[sl] for k, v in params.items()}
        res = rk4h.ensemble(model, y0[sl], (0.0, scene.t_end), h=spec.setting, method=tableau,
                               params=part or None, t_eval=t_eval, backend="numba")
        e, ee, f = instance_errors(model, res, y0[sl], part or None, built)
        errs.append(e)
        eerrs.append(ee)
        failed += f
    errs, eerrs = np.concatenate(errs), np.concatenate(eerrs)
    st = {"error": statistics(errs) if errs.size else None,
          "energy_error": statistics(eerrs) if eerrs.size else None, "failed": failed}
    values = {"instances": int(y0.shape[0]), "failed": st["failed"]}
    for q in ("error", "energy_error"):
        for k in STATS:
            values[f"{q}_{k}"] = float("nan") if st[q] is None else st[q][k]
    return RunRecord(spec.key, values=values)


def measure(m) -> None:
    for spec in m.specs("ensemble"):
        rec = m.records[spec.key]
        if not rec.ok:
            m.res.check(f"ensemble {spec.solver} h={spec.setting:g}", False,
                        f"{m.scene.name}: ensemble {spec.solver} h={spec.setting:g}: {rec.message}")
            continue
        v = rec.values
        m.res.add("ensemble", {"scene": m.scene.name, "solver": spec.solver, "h_s": spec.setting,
                               "instances": v["instances"], "failed": v["failed"],
                               **{f"{q}_{k}": v[f"{q}_{k}"] for q in ("error", "energy_error") for k in STATS}})


_COLUMNS = (("scene", "", "str", "scene name"),
            ("solver", "", "category", "fixed-step method"),
            ("h_s", "s", "float", "step"),
            ("instances", "1", "int", "instances in the batch ([ensemble] size)"),
            ("failed", "1", "int", "instances stopped by the instability rule (left out of the statistics)"),
            *((f"error_{k}", "1", "float", f"{w} over the instances of max_t |y - y_exact|_inf / max_t "
               f"|y_exact|_inf (each instance's exact modal solution)")
              for k, w in zip(STATS, ("median", "95th percentile", "maximum"))),
            *((f"energy_error_{k}", "1", "float", f"{w} over the instances of max_t |E - E0| / E0")
              for k, w in zip(STATS, ("median", "95th percentile", "maximum"))))

OUTPUT = Output(
    name="ensemble", rank=130, plan_rank=95, measure_rank=95,
    when="never by default (needs an `[ensemble]` table and a linear model)",
    what="the `[ensemble]` run as one batch per fixed-step solver and step: median, p95 and max of the error "
         "and the energy error against each instance's exact modal solution, `ensemble.csv`",
    plan=plan, measure=measure, execute={"ensemble": execute},
    purposes={"ensemble": "one batch of every instance of [ensemble] at one solver and step: error statistics"},
    tables=(Table("ensemble", columns=_COLUMNS,
                  description="error and energy-error statistics over each scene's [ensemble] instances"),),
)
