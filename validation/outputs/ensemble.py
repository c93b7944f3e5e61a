"""``ensemble``: error and energy-error statistics over a scene's ``[ensemble]``,
run as one batch per fixed-step solver and step, against each instance's exact
modal solution (a linear model) or a reference run as a batch too (a nonlinear
model: :func:`rk4h.validation.ensemble.batch_reference`)."""
from rk4h.validation.outputs import Output, Table
from rk4h.validation.outputs._batch import STAT_WORDS, tableau_solvers

#: The statistics of each quantity (median, 95th percentile, maximum over the instances).
STATS = tuple(k for k, _ in STAT_WORDS)
#: Bytes of states one batch may hold (the rest runs in further chunks of instances).
CHUNK_BYTES = 256 * 2**20
#: The reference: "auto" (a linear model's exact modal solutions, else a batch reference); "batch" runs the
#: batch reference for a linear model too (what the tests compare with the modal solutions).
REFERENCE = "auto"


def plan(p) -> list:
    if not p.scene.ensemble:
        return []
    return [p.spec("ensemble", solver=solver, setting=float(h)) for solver in tableau_solvers(p.scene)
            for h in p.scene.h]


def reference_step(scene, model):
    """The confirmation step of a scene's batch reference (s); the reference
    runs at half of it.

    ``min(run.h) / r`` with ``r`` from
    :func:`rk4h.validation.ensemble.reference_refinement`: the highest order
    among the scene's batch solvers, the order of
    :data:`~rk4h.validation.ensemble.REFERENCE_METHOD` (6), and ``omega_max``
    of the model's linearization (``model.modes()``; unknown: ``z`` taken as
    1). An integer ``r`` keeps every grid point of the scene's steps a grid
    point of both reference runs.
    """
    import numpy as np

    import rk4h
    from rk4h.validation.ensemble import REFERENCE_METHOD, reference_refinement

    h = float(min(scene.h))
    order = max((scene.method(s).tableau.order for s in tableau_solvers(scene)), default=4)
    try:
        omega = float(np.max(model.modes()[0]))
    except Exception:  # a model without a linearization: z = 1 (see reference_refinement)
        omega = float("nan")
    return h / reference_refinement(h, order, omega, ref_order=rk4h.METHODS[REFERENCE_METHOD].order)


def execute(scene, spec, quick):
    """One batch: every instance of ``[ensemble]`` with ``spec.solver`` at step
    ``spec.setting`` (s) over the scene's output grid, against each
    instance's exact modal solution (a linear model) or the batch reference
    (:func:`reference_step`; shared by the scene's specs run in one process)."""
    import numpy as np

    import rk4h
    from rk4h.validation.ensemble import REFERENCE_METHOD, EnsembleSums, batch_reference, draw_instances, statistics
    from rk4h.validation.records import RunRecord

    model = scene.build_model()
    y0, params = draw_instances(scene.ensemble, model, scene.initial_x, scene.initial_v)
    t_eval = np.asarray(scene.t_eval(), float)
    tableau = scene.method(spec.solver).tableau
    B = y0.shape[0]
    batch_ref = REFERENCE == "batch" or not model.linear
    h_ref = reference_step(scene, model) if batch_ref else float("nan")
    # chunks of instances so the batch's states (B x rows x n float64; three sets with a batch reference)
    # stay within CHUNK_BYTES
    chunk = max(1, int(CHUNK_BYTES // (8 * (3 if batch_ref else 1) * t_eval.size * y0.shape[1])))
    sums, built = EnsembleSums(), {}
    for lo in range(0, B, chunk):
        sl = slice(lo, min(B, lo + chunk))
        part = {k: np.asarray(v)[sl] for k, v in params.items()}
        res = rk4h.ensemble(model, y0[sl], (0.0, scene.t_end), h=spec.setting, method=tableau,
                               params=part or None, t_eval=t_eval, backend="numba")
        if batch_ref:
            y_ref, bound, delta, rstatus = batch_reference(model, y0[sl], part or None, t_eval, scene.t_end, h_ref)
            sums.add(model, res, y0[sl], part or None, built, y_ref=y_ref, bound=bound, delta=delta,
                     ref_status=rstatus)
        else:
            sums.add(model, res, y0[sl], part or None, built)
    errs, eerrs = np.asarray(sums.errors, float), np.asarray(sums.energy_errors, float)
    st = {"error": statistics(errs) if errs.size else None,
          "energy_error": statistics(eerrs) if eerrs.size else None}
    weak, weak_e, weak_bound = sums.weak()
    values = {"instances": int(y0.shape[0]), "failed": sums.failed,
              "rhs_calls": rk4h.nfev_count(tableau, rk4h.step_count((0.0, scene.t_end), spec.setting)),
              "cost_unit": scene.method(spec.solver).cost_unit.value}
    for q in ("error", "energy_error"):
        for k in STATS:
            values[f"{q}_{k}"] = float("nan") if st[q] is None else st[q][k]
    values.update(weak_error=weak, weak_energy_error=weak_e,
                  reference=f"{REFERENCE_METHOD} h={h_ref / 2:.6g}" if batch_ref else "modal",
                  reference_h_s=h_ref / 2 if batch_ref else 0.0, reference_failed=sums.reference_failed,
                  reference_bound=(float(np.max(sums.bound)) if sums.bound else float("nan")) if batch_ref else 0.0,
                  weak_reference_bound=weak_bound)
    return RunRecord(spec.key, values=values)


def reference_check(row):
    """``(ok, worst)`` of a batch reference's check on one table row: every
    instance's reference reached the end, and ``reference_bound`` lies at
    least :data:`~rk4h.validation.ensemble.REFERENCE_MARGIN` below the
    smallest strong error statistic, ``weak_reference_bound`` as far below
    ``weak_error`` (``worst``: the larger of the two ratios bound / error;
    a missing truth is a failure)."""
    import math

    from rk4h.validation.ensemble import REFERENCE_MARGIN

    stats = [row[f"error_{k}"] for k in STATS]
    # min() skips a NaN that is not first (NaN < x is False): any NaN statistic is no error measured
    strong = min(stats) if all(math.isfinite(x) for x in stats) else math.nan
    ratios = [row["reference_bound"] / strong if strong > 0 else math.inf,
              row["weak_reference_bound"] / row["weak_error"] if row["weak_error"] > 0 else math.inf]
    worst = max(r if math.isfinite(r) else math.inf for r in ratios)
    return row["reference_failed"] == 0 and worst <= 1.0 / REFERENCE_MARGIN, worst


def measure(m) -> None:
    from rk4h.validation.outputs._batch import ok_records

    rows = []
    for spec, rec in ok_records(m, "ensemble", lambda spec: f"ensemble {spec.solver} h={spec.setting:g}"):
        v = rec.values
        row = {"scene": m.scene.name, "solver": spec.solver, "h_s": spec.setting,
               "instances": v["instances"], "failed": v["failed"], "rhs_calls": v.get("rhs_calls", -1),
               "cost_unit": v.get("cost_unit", ""),
               **{f"{q}_{k}": v[f"{q}_{k}"] for q in ("error", "energy_error") for k in STATS},
               **{k: v[k] for k in _WEAK_KEYS}}
        m.res.add("ensemble", row)
        rows.append(row)
        if row["reference"] != "modal":
            from rk4h.validation.ensemble import REFERENCE_MARGIN

            ok, worst = reference_check(row)
            m.res.check(f"ensemble reference {spec.solver} h={spec.setting:g}", bool(ok),
                        f"{m.scene.name}: ensemble {spec.solver} h={spec.setting:g}: the reference "
                        f"({row['reference']}) disagrees with its confirmation by {worst:.3g} of the errors it "
                        f"measures (limit {1 / REFERENCE_MARGIN:g}); {row['reference_failed']} instances without "
                        f"a reference", measured=worst, expected=0.0, tolerance=1 / REFERENCE_MARGIN)
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
    ax.set_ylabel("max_t |y - y_ref|_inf / max_t |y_ref|_inf")
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
    ref = rows[0].get("reference", "modal")
    truth = "its exact modal solution" if ref == "modal" else f"its batch reference ({ref})"
    caption = (f"{job.scene}: median and 95th percentile over {n} instances of each instance's error against "
               f"{truth}, against RHS calls per instance ({', '.join(solvers)}; one point per run.h)")
    return [(path, caption)]


_COLUMNS = (("scene", "", "str", "scene name"),
            ("solver", "", "category", "fixed-step method"),
            ("h_s", "s", "float", "step"),
            ("instances", "1", "int", "instances in the batch ([ensemble] size)"),
            ("failed", "1", "int", "instances stopped by the instability rule (left out of the statistics)"),
            ("rhs_calls", "1", "int", "right-hand-side calls per instance over the run (rk4h.nfev_count)"),
            ("cost_unit", "", "category", "what `rhs_calls` counts (rk4h.references.registry.CostUnit; a "
                                          "fixed-step method: rhs, every stage of every step)"),
            *((f"error_{k}", "1", "float", f"{w} over the instances of max_t |y - y_exact|_inf / max_t "
               f"|y_exact|_inf (each instance's exact modal solution)")
              for k, w in STAT_WORDS),
            *((f"energy_error_{k}", "1", "float", f"{w} over the instances of max_t |E - E0| / E0")
              for k, w in STAT_WORDS),
            ("weak_error", "1", "float", "error of the ensemble mean: max_t |mean_b (y_b - y_ref_b)|_inf / max_t "
             "mean_b |y_ref_b|_inf (the mean size of the instances, not the size of their mean; SciML's weak "
             "l-infinity error so scaled)"),
            ("weak_energy_error", "1", "float", "max_t |mean_b (E_b - E0_b)| / mean_b E0_b"),
            ("reference", "", "category", "y_ref: `modal` (each instance's exact modal solution, a linear model) "
             "or the batch reference's method and step"),
            ("reference_h_s", "s", "float", "the batch reference's step (its confirmation runs at twice it); 0 "
             "for `modal`"),
            ("reference_failed", "1", "int", "instances whose reference run did not reach the end (left out; the "
             "check then fails)"),
            ("reference_bound", "1", "float", "max over the instances of max_t |y_ref - y_confirm|_inf / max_t "
             "|y_ref|_inf (the batch reference against its confirmation at twice the step); 0 for `modal`"),
            ("weak_reference_bound", "1", "float", "max over instances and times of |y_ref - y_confirm|_inf on "
             "weak_error's scale; 0 for `modal`"))
_WEAK_KEYS = ("weak_error", "weak_energy_error", "reference", "reference_h_s", "reference_failed",
              "reference_bound", "weak_reference_bound")


def loops(scene, spec) -> list:
    """The numba loops a spec runs (:attr:`rk4h.validation.outputs.Output.loops`):
    its solver's batch loop, and the batch reference's (:data:`REFERENCE_METHOD`
    of :mod:`rk4h.validation.ensemble`) where :func:`execute` runs one."""
    from rk4h.validation.ensemble import REFERENCE_METHOD

    out = [("batch", spec.solver)]
    if REFERENCE == "batch" or not scene.build_model().linear:
        out.append(("batch", REFERENCE_METHOD))
    return out


OUTPUT = Output(
    name="ensemble", rank=130, plan_rank=95, measure_rank=95,
    when="never by default (needs an `[ensemble]` table)",
    what="the `[ensemble]` run as one batch per fixed-step solver and step: median, p95 and max of the "
         "per-instance (strong) error and energy error, and the weak errors (of the ensemble mean), against "
         "each instance's exact modal solution (a linear model) or a reference run as a batch too "
         "(blanes-moan6 at a finer step, confirmed at twice that step; the check fails unless their "
         "disagreement is 10x below the errors), `ensemble.csv` and the ensemble work-precision figure "
         "(error statistics against RHS calls)",
    plan=plan, measure=measure, execute={"ensemble": execute}, draw={"ensemble_work_precision": draw},
    loops={"ensemble": loops},
    purposes={"ensemble": "one batch of every instance of [ensemble] at one solver and step: error statistics"},
    tables=(Table("ensemble", columns=_COLUMNS,
                  description="error and energy-error statistics over each scene's [ensemble] instances"),),
)
