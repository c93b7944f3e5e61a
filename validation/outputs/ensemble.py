"""``ensemble``: error and energy-error statistics over a scene's ``[ensemble]``,
run as one batch per fixed-step solver and step."""
from rk4h.validation.outputs import Output, Table
from rk4h.validation.outputs._batch import STAT_WORDS, tableau_solvers

#: The statistics of each quantity (median, 95th percentile, maximum over the instances).
STATS = tuple(k for k, _ in STAT_WORDS)
#: Bytes of states one batch may hold (the rest runs in further chunks of instances).
CHUNK_BYTES = 256 * 2**20


def plan(p) -> list:
    if not p.scene.ensemble:
        return []
    return [p.spec("ensemble", solver=solver, setting=float(h)) for solver in tableau_solvers(p.scene)
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
    values = {"instances": int(y0.shape[0]), "failed": st["failed"],
              "rhs_calls": rk4h.nfev_count(tableau, rk4h.step_count((0.0, scene.t_end), spec.setting))}
    for q in ("error", "energy_error"):
        for k in STATS:
            values[f"{q}_{k}"] = float("nan") if st[q] is None else st[q][k]
    return RunRecord(spec.key, values=values)


def measure(m) -> None:
    from rk4h.validation.outputs._batch import ok_records

    rows = []
    for spec, rec in ok_records(m, "ensemble", lambda spec: f"ensemble {spec.solver} h={spec.setting:g}"):
        v = rec.values
        row = {"scene": m.scene.name, "solver": spec.solver, "h_s": spec.setting,
               "instances": v["instances"], "failed": v["failed"], "rhs_calls": v.get("rhs_calls", -1),
               **{f"{q}_{k}": v[f"{q}_{k}"] for q in ("error", "energy_error") for k in STATS}}
        m.res.add("ensemble", row)
        rows.append(row)
    if rows:
        from rk4h.validation.measure import FigureJob

        # the ensemble work-precision figure is the output's point: drawn whatever run.outputs says
        m.res.figures.append(FigureJob(m.scene.name, "ensemble_work_precision", {"rows": rows}))


def work_precision_figure(rows, path, title=""):
    """Error statistics against right-hand-side calls per instance, log-log:
    per solver one line through its steps for the median and one (dashed)
    for the 95th percentile of the ensemble's errors (``rows``: the
    ``ensemble`` table's rows of one scene). Written to ``path`` (PNG);
    returns the solvers drawn."""
    import math

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6, 4.2), constrained_layout=True)
    solvers = list(dict.fromkeys(r["solver"] for r in rows))
    for i, solver in enumerate(solvers):
        pts = sorted((r["rhs_calls"], r["error_median"], r["error_p95"]) for r in rows
                     if r["solver"] == solver and r["rhs_calls"] > 0 and math.isfinite(r["error_p95"]))
        if not pts:
            continue
        n, med, p95 = zip(*pts)
        ax.loglog(n, med, "o-", color=f"C{i}", label=f"{solver} median")
        ax.loglog(n, p95, "s--", color=f"C{i}", mfc="none", label=f"{solver} p95")
    ax.set_xlabel("right-hand-side calls per instance")
    ax.set_ylabel("max_t |y - y_exact|_inf / max_t |y_exact|_inf")
    ax.set_title(title)
    ax.legend(fontsize=8)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return solvers


def draw(out_dir, job, scene):
    """The ensemble work-precision figure and its caption."""
    from pathlib import Path

    rows = job.data["rows"]
    path = Path(out_dir) / f"{job.scene}-ensemble-work-precision.png"
    solvers = work_precision_figure(rows, path, title=f"{job.scene}: ensemble work-precision")
    n = max(r["instances"] for r in rows)
    caption = (f"{job.scene}: median and 95th percentile over {n} instances of each instance's error against "
               f"its exact modal solution, against RHS calls per instance ({', '.join(solvers)}; one point per "
               f"run.h)")
    return [(path, caption)]


_COLUMNS = (("scene", "", "str", "scene name"),
            ("solver", "", "category", "fixed-step method"),
            ("h_s", "s", "float", "step"),
            ("instances", "1", "int", "instances in the batch ([ensemble] size)"),
            ("failed", "1", "int", "instances stopped by the instability rule (left out of the statistics)"),
            ("rhs_calls", "1", "int", "right-hand-side calls per instance over the run (rk4h.nfev_count)"),
            *((f"error_{k}", "1", "float", f"{w} over the instances of max_t |y - y_exact|_inf / max_t "
               f"|y_exact|_inf (each instance's exact modal solution)")
              for k, w in STAT_WORDS),
            *((f"energy_error_{k}", "1", "float", f"{w} over the instances of max_t |E - E0| / E0")
              for k, w in STAT_WORDS))

OUTPUT = Output(
    name="ensemble", rank=130, plan_rank=95, measure_rank=95,
    when="never by default (needs an `[ensemble]` table and a linear model)",
    what="the `[ensemble]` run as one batch per fixed-step solver and step: median, p95 and max of the error "
         "and the energy error against each instance's exact modal solution, `ensemble.csv` and the ensemble "
         "work-precision figure (error statistics against RHS calls)",
    plan=plan, measure=measure, execute={"ensemble": execute}, draw={"ensemble_work_precision": draw},
    purposes={"ensemble": "one batch of every instance of [ensemble] at one solver and step: error statistics"},
    tables=(Table("ensemble", columns=_COLUMNS,
                  description="error and energy-error statistics over each scene's [ensemble] instances"),),
)
