"""``amplitude_ensemble``: a nonlinear model's ``[ensemble]`` run as one batch
at a fine step, against each instance's exact solution of the model's
linearization: how far the linearized model is from the exact one as a
function of the initial amplitude (statistics per amplitude bin, the local
log-log slope, and the integration error of a few instances rerun at half the
step, which must lie far below the deviation)."""
from rk4h.validation.outputs import Output, Table
from rk4h.validation.outputs._batch import STAT_WORDS, one_solver

#: Log-spaced amplitude bins of the table and the figure.
N_BINS = 10
#: Instances per bin rerun at h/2 to estimate the integration error.
N_CHECK = 2
#: The integration error estimate must stay below this fraction of the deviation, per rerun instance.
ERROR_FRACTION = 1e-2
#: Instances per batch (states: chunk x rows x n float64).
CHUNK = 2000


def plan(p) -> list:
    if not p.scene.ensemble:
        return []
    return [p.spec("amplitude_ensemble", solver=one_solver(p.scene), setting=float(min(p.scene.h)))]


def linearized_batch(model, y0, t):
    """The exact solutions of ``model``'s linearization from every row of ``y0``.

    Parameters
    ----------
    model : rk4h.models.Model
        A model with ``modes()`` (its linearization about ``q = 0``).
    y0 : ndarray, shape (B, 2 n)
        Initial states ``[q, v]`` (the model's units).
    t : ndarray, shape (m,)
        Times (s).

    Returns
    -------
    ndarray, shape (B, m, 2 n)
        Modal superposition (zero-frequency modes move uniformly), as
        :class:`rk4h.references.exact.ModalSolution` per instance.
    """
    import numpy as np

    omega, phi = model.modes()
    n = model.n_dof
    M = np.asarray(model.mass, float)
    eta0 = (y0[:, :n] * M) @ phi            # (B, n): phi^T M q0 per instance
    deta0 = (y0[:, n:] * M) @ phi
    zero = omega == 0.0
    w = np.where(zero, 1.0, omega)
    wt = t[:, None] * w[None, :]            # (m, n)
    c, s = np.cos(wt), np.sin(wt)
    eta = np.where(zero, eta0[:, None, :] + deta0[:, None, :] * t[None, :, None],
                   eta0[:, None, :] * c + deta0[:, None, :] * s / w)
    deta = np.where(zero, deta0[:, None, :] + 0.0 * t[None, :, None],
                    -eta0[:, None, :] * w * s + deta0[:, None, :] * c)
    return np.concatenate([eta @ phi.T, deta @ phi.T], axis=2)


def execute(scene, spec, quick):
    """Every instance at ``spec.setting`` (s) over the scene's output grid;
    per instance its amplitude ``max |q0|`` and the largest position
    deviation ``max_t |q - q_lin|_inf`` from the linearization's exact
    solution; ``N_CHECK`` instances per amplitude bin rerun at half the step
    (integration error estimate ``16/15 max_t |q_h - q_{h/2}|_inf``, RK4's
    Richardson factor; an upper estimate for higher orders)."""
    import numpy as np

    import rk4h
    from rk4h.validation.ensemble import draw_instances
    from rk4h.validation.records import RunRecord

    model = scene.build_model()
    n = model.n_dof
    y0, params = draw_instances(scene.ensemble, model, scene.initial_x, scene.initial_v)
    if params:
        raise ValueError("`ensemble`: amplitude_ensemble draws initial values only (one linearization)")
    t = np.asarray(scene.t_eval(), float)
    tableau = scene.method(spec.solver).tableau
    B = y0.shape[0]
    amp = np.max(np.abs(y0[:, :n]), axis=1)
    dev = np.full(B, np.nan)
    scale = np.full(B, np.nan)
    status = np.zeros(B, int)
    for lo in range(0, B, CHUNK):
        sl = slice(lo, min(B, lo + CHUNK))
        res = rk4h.ensemble(model, y0[sl], (0.0, scene.t_end), h=spec.setting, method=tableau, t_eval=t,
                            backend="numba")
        lin = linearized_batch(model, y0[sl], t)
        dev[sl] = np.max(np.abs(res.y[:, :, :n] - lin[:, :, :n]), axis=(1, 2))
        scale[sl] = np.max(np.abs(lin[:, :, :n]), axis=(1, 2))
        status[sl] = res.status
    edges = bin_edges(amp)
    which = np.clip(np.searchsorted(edges, amp, side="right") - 1, 0, edges.size - 2)
    check = np.concatenate([np.flatnonzero(which == k)[:N_CHECK] for k in range(edges.size - 1)]).astype(int)
    fine = rk4h.ensemble(model, y0[check], (0.0, scene.t_end), h=spec.setting / 2, method=tableau, t_eval=t,
                         backend="numba")
    coarse = rk4h.ensemble(model, y0[check], (0.0, scene.t_end), h=spec.setting, method=tableau, t_eval=t,
                           backend="numba")
    err = 16.0 / 15.0 * np.max(np.abs(coarse.y[:, :, :n] - fine.y[:, :, :n]), axis=(1, 2))
    err[(fine.status != 0) | (coarse.status != 0)] = np.nan
    return RunRecord(spec.key, values={"instances": int(B)},
                     arrays={"amplitude": amp, "deviation": dev, "scale": scale, "status": status,
                             "edges": edges, "check": check, "check_error": err})


def bin_edges(amp):
    """``N_BINS + 1`` log-spaced edges from the smallest to the largest positive amplitude."""
    import numpy as np

    a = amp[amp > 0]
    return np.geomspace(a.min(), a.max(), N_BINS + 1) if a.size and a.max() > a.min() else np.array(
        [a.min(), a.min()] if a.size else [0.0, 0.0])


def bin_rows(amp, dev, scale, status, edges, check, check_error):
    """The table's rows: per amplitude bin, the instances, the deviation's
    median/p95/max (absolute and relative), the local log-log slope of the
    median deviation against the bin's median amplitude (from the previous
    bin), and the largest integration error estimate among its rerun
    instances with its ratio to their deviation."""
    import numpy as np

    ok = (status == 0) & np.isfinite(dev) & (amp > 0)
    which = np.clip(np.searchsorted(edges, amp, side="right") - 1, 0, edges.size - 2)
    rows, prev = [], None
    for k in range(edges.size - 1):
        sel = ok & (which == k)
        d, r, a = dev[sel], dev[sel] / scale[sel], amp[sel]
        row = {"amplitude_low": float(edges[k]), "amplitude_high": float(edges[k + 1]),
               "instances": int(sel.sum()), "failed": int(((which == k) & (status != 0)).sum())}
        for name, x in (("deviation", d), ("deviation_rel", r)):
            for key, f in (("median", np.median), ("p95", lambda v: np.percentile(v, 95)), ("max", np.max)):
                row[f"{name}_{key}"] = float(f(x)) if x.size else float("nan")
        a_med = float(np.median(a)) if a.size else float("nan")
        row["amplitude_median"] = a_med
        row["slope"] = (float(np.log(row["deviation_median"] / prev[1]) / np.log(a_med / prev[0]))
                        if prev and a.size and prev[1] > 0 and row["deviation_median"] > 0 else float("nan"))
        prev = (a_med, row["deviation_median"]) if a.size else prev
        c = check[which[check] == k]
        e = check_error[which[check] == k]
        row["integration_error_max"] = float(np.nanmax(e)) if np.isfinite(e).any() else float("nan")
        row["error_over_deviation"] = (float(np.nanmax(e / dev[c])) if np.isfinite(e).any() and (dev[c] > 0).all()
                                       else float("nan"))
        rows.append(row)
    return rows


def measure(m) -> None:
    import numpy as np

    from rk4h.validation.measure import FigureJob
    from rk4h.validation.outputs._batch import ok_records

    for spec, rec in ok_records(m, "amplitude_ensemble", "amplitude ensemble"):
        a = {k: np.asarray(v) for k, v in rec.arrays.items()}
        rows = bin_rows(a["amplitude"], a["deviation"], a["scale"], a["status"], a["edges"], a["check"],
                        a["check_error"])
        for row in rows:
            m.res.add("amplitude_ensemble", {"scene": m.scene.name, "solver": spec.solver, "h_s": spec.setting,
                                             **row})
        ratio = np.array([r["error_over_deviation"] for r in rows], float)
        worst = float(np.nanmax(ratio)) if np.isfinite(ratio).any() else float("nan")
        m.res.check(f"amplitude ensemble integration error {spec.solver} h={spec.setting:g}",
                    bool(np.isfinite(ratio).all() and worst < ERROR_FRACTION),
                    f"{m.scene.name}: the integration error estimate at h={spec.setting:g} s reaches {worst:.3g} "
                    f"of the deviation from the linearization (limit {ERROR_FRACTION:g})",
                    measured=worst, expected=0.0, tolerance=ERROR_FRACTION)
        m.res.figures.append(FigureJob(m.scene.name, "amplitude_ensemble", {
            "amplitude": a["amplitude"], "deviation": a["deviation"], "status": a["status"],
            "check_amplitude": a["amplitude"][a["check"]], "check_error": a["check_error"],
            "rows": rows, "solver": spec.solver, "h": spec.setting}))


def draw(out_dir, job, scene):
    """Max deviation against amplitude, log-log: every instance (dots), the
    bins' medians, and the rerun instances' integration error estimates."""
    from pathlib import Path

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    d = job.data
    amp, dev = np.asarray(d["amplitude"]), np.asarray(d["deviation"])
    ok = (np.asarray(d["status"]) == 0) & (dev > 0) & (amp > 0)
    rows = d["rows"]
    fig, ax = plt.subplots(figsize=(6, 4.2), constrained_layout=True)
    ax.loglog(amp[ok], dev[ok], ".", ms=1.5, alpha=0.3, color="C0", label=f"{int(ok.sum())} instances")
    am = np.array([r["amplitude_median"] for r in rows])
    dm = np.array([r["deviation_median"] for r in rows])
    ax.loglog(am, dm, "o-", color="C1", ms=4, label="median per amplitude bin")
    ca, ce = np.asarray(d["check_amplitude"]), np.asarray(d["check_error"])
    good = np.isfinite(ce) & (ce > 0)
    ax.loglog(ca[good], ce[good], "x", color="C3", label=f"{d['solver']} error estimate (h vs h/2)")
    ax.set_xlabel("initial amplitude max |q0|")
    ax.set_ylabel("max_t |q - q_linearized|")
    ax.set_title(f"{job.scene}: deviation from the linearization")
    ax.legend(fontsize=8)
    path = Path(out_dir) / f"{job.scene}-amplitude-ensemble.png"
    fig.savefig(path, dpi=110)
    plt.close(fig)
    slopes = [r["slope"] for r in rows if np.isfinite(r["slope"])]
    caption = (f"{job.scene}: largest position deviation of the exact model ({d['solver']}, h = {d['h']:g} s) from "
               f"its linearization's exact solution against the initial amplitude; local log-log slopes of the "
               f"bin medians {min(slopes):.2f}-{max(slopes):.2f}" if slopes else f"{job.scene}: deviation")
    return [(path, caption)]


_COLUMNS = (("scene", "", "str", "scene name"),
            ("solver", "", "category", "fixed-step method"),
            ("h_s", "s", "float", "step (the scene's smallest run.h)"),
            ("amplitude_low", "as q", "float", "amplitude bin's lower edge: max |q0| over the coordinates"),
            ("amplitude_high", "as q", "float", "amplitude bin's upper edge"),
            ("amplitude_median", "as q", "float", "median amplitude of the bin's instances"),
            ("instances", "1", "int", "instances in the bin that reached the end"),
            ("failed", "1", "int", "instances in the bin stopped by the instability rule (left out)"),
            *((f"deviation_{k}", "as q", "float", f"{w} over the bin of max_t |q - q_lin|_inf: the exact "
               f"(nonlinear) model against its linearization's exact modal solution (not an integration error)")
              for k, w in STAT_WORDS),
            *((f"deviation_rel_{k}", "1", "float", f"{w} over the bin of max_t |q - q_lin|_inf / max_t "
               f"|q_lin|_inf") for k, w in STAT_WORDS),
            ("slope", "1", "float", "log-log slope of deviation_median against amplitude_median from the previous bin"),
            ("integration_error_max", "as q", "float", "largest integration error estimate (16/15 max_t |q_h - "
             "q_h/2|_inf) of the bin's instances rerun at half the step"),
            ("error_over_deviation", "1", "float", "largest ratio of that estimate to the instance's deviation"))

OUTPUT = Output(
    name="amplitude_ensemble", rank=135, plan_rank=95, measure_rank=95,
    when="never by default (needs an `[ensemble]` over initial values and a model with a linearization)",
    what="the `[ensemble]` of a nonlinear model as one batch at the smallest step against each instance's exact "
         "solution of the linearization: deviation statistics per amplitude bin, `amplitude_ensemble.csv` and "
         "its log-log figure",
    plan=plan, measure=measure, execute={"amplitude_ensemble": execute}, draw={"amplitude_ensemble": draw},
    loops={"amplitude_ensemble": lambda scene, spec: [("batch", spec.solver)]},
    purposes={"amplitude_ensemble": "one batch of every instance of [ensemble] at the smallest step against the "
                                    "linearization, a few rerun at half the step"},
    tables=(Table("amplitude_ensemble", columns=_COLUMNS,
                  description="deviation of a nonlinear model from its linearization per initial amplitude bin"),),
)
