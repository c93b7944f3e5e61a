"""``stability_map``: the largest stable ``omega_max h`` over a 2-D grid of
(one model parameter, h), from a scene's ``[ensemble]`` table."""
from rk4h.validation.outputs import Output, Table
from rk4h.validation.outputs._batch import one_solver


def plan(p) -> list:
    if not p.scene.ensemble:
        return []
    return [p.spec("stability_map", solver=one_solver(p.scene))]


def execute(scene, spec, quick):
    """One batch per grid step ``h``, every parameter value in it
    (:func:`rk4h.batch.maps.stability_map`), from the scene's initial state."""
    from rk4h.batch.maps import stability_map
    from rk4h.validation.ensemble import map_settings
    from rk4h.validation.records import RunRecord

    model = scene.build_model()
    param, values, h, n_steps = map_settings(scene.ensemble, model)
    smap = stability_map(model, param, values, h, y0=scene.y0(), n_steps=n_steps,
                         method=scene.method(spec.solver).tableau, backend="numba")
    return RunRecord(spec.key, values={"param": param, "n_steps": int(n_steps)},
                     arrays={"values": smap.values, "h": smap.h, "stable": smap.stable,
                             "omega_max": smap.omega_max, "h_max": smap.h_max})


def _limit(method):
    """The imaginary-axis stability boundary (``omega h``, rad) of ``method``'s
    tableau (:func:`rk4h.stability_function.imaginary_axis_boundary`: RK4 and
    the 3/8 rule 2 sqrt(2), Heun3 sqrt(3), Stormer-Verlet 2), or None when it
    has no tableau or no finite positive boundary (Euler: 0)."""
    import math

    from rk4h.stability_function import imaginary_axis_boundary

    if method.tableau is None:
        return None
    b = float(imaginary_axis_boundary(method.tableau))
    return b if math.isfinite(b) and b > 0 else None


def measure(m) -> None:
    import numpy as np

    from rk4h.validation.measure import FigureJob
    from rk4h.validation.outputs._batch import ok_records

    for spec, rec in ok_records(m, "stability_map", "stability map"):
        a, param = rec.arrays, rec.values["param"]
        values, h, omega, h_max = (np.asarray(a[k], float) for k in ("values", "h", "omega_max", "h_max"))
        idx = np.searchsorted(h, h_max)  # index of h_max in the grid (NaN: past the end)
        h_next = np.where(np.isfinite(h_max) & (idx + 1 < h.size), h[np.minimum(idx + 1, h.size - 1)], np.nan)
        for i, val in enumerate(values):
            m.res.add("stability_map", {"scene": m.scene.name, "solver": spec.solver, "parameter": param,
                                        "value": float(val), "omega_max_rad_s": float(omega[i]),
                                        "h_max_s": float(h_max[i]), "z_max": float(omega[i] * h_max[i]),
                                        "z_next": float(omega[i] * h_next[i]),
                                        "n_steps": rec.values["n_steps"]})
        limit = _limit(m.scene.method(spec.solver))
        if limit is not None:
            # the boundary found (the largest stable grid step) lies within one grid spacing of the limit at
            # every value; just past the limit |R| - 1 is small, so a step there may stay inside the growth
            # bound for map_steps steps: z_max may exceed the limit by less than a cell
            cell = omega * (h_next - h_max)
            ok = np.isfinite(cell) & (np.abs(omega * h_max - limit) < cell)
            worst = float(np.nanmax(np.abs(omega * h_max - limit) / cell)) if np.isfinite(cell).any() else np.nan
            m.res.check(f"stability map boundary {spec.solver}", bool(ok.all()),
                        f"{m.scene.name}: the largest stable omega_max h is not within one grid spacing of "
                        f"{limit:.4f} at {int((~ok).sum())} of {ok.size} values of {param} (worst: "
                        f"{worst:.2f} spacings)",
                        measured=worst, expected=0.0, tolerance=1.0)
        # the map is the output's point: drawn whatever run.outputs says (as the stability study's figures)
        m.res.figures.append(FigureJob(m.scene.name, "stability_map", {
            "param": param, "values": values, "h": h, "stable": np.asarray(a["stable"], bool),
            "omega_max": omega, "h_max": h_max, "solver": spec.solver, "limit": limit,
            "n_steps": rec.values["n_steps"]}))


def draw(out_dir, job, scene):
    """The map's figure and its caption (generated from the grid and the boundary found)."""
    from pathlib import Path

    import numpy as np

    from rk4h.batch.maps import StabilityMap
    from rk4h.validation.ensemble import stability_map_figure

    d = job.data
    smap = StabilityMap(param=d["param"], values=np.asarray(d["values"]), h=np.asarray(d["h"]),
                        stable=np.asarray(d["stable"]), omega_max=np.asarray(d["omega_max"]),
                        h_max=np.asarray(d["h_max"]))
    path = Path(out_dir) / f"{job.scene}-stability-map.png"
    stability_map_figure(smap, path, limit=d["limit"], label=d["param"])
    z = smap.z_max
    caption = (f"{job.scene}: {d['solver']} stable (light) or not (dark) after {d['n_steps']} steps over "
               f"{smap.values.size} values of {d['param']} x {smap.h.size} steps h from {smap.h[0]:g} to "
               f"{smap.h[-1]:g} s ({smap.stable.size} instances); the largest stable omega_max h on the grid "
               f"lies in {np.nanmin(z):.3f}-{np.nanmax(z):.3f}")
    if d["limit"] is not None:
        caption += f" (the imaginary-axis limit {d['limit']:.4f})"
    return [(path, caption)]


_COLUMNS = (("scene", "", "str", "scene name"),
            ("solver", "", "category", "fixed-step method"),
            ("parameter", "", "category", "the swept model parameter ([ensemble] grid key)"),
            ("value", "as the parameter", "float", "its value"),
            ("omega_max_rad_s", "rad/s", "float", "fastest linearised angular frequency at that value"),
            ("h_max_s", "s", "float", "largest grid step below which every grid step stayed stable (NaN: none)"),
            ("z_max", "rad", "float", "omega_max h_max: the largest stable omega_max h on the grid"),
            ("z_next", "rad", "float", "omega_max h at the next grid step (unstable; NaN: h_max is the last)"),
            ("n_steps", "1", "int", "steps per run (map_steps)"))

OUTPUT = Output(
    name="stability_map", rank=140, plan_rank=96, measure_rank=96,
    when="never by default (needs an `[ensemble]` table with one parameter grid and `map_h`)",
    what="stable or not over (parameter, h) as batches, the largest stable omega_max h per value: "
         "`stability_map.csv` and its figure",
    plan=plan, measure=measure, execute={"stability_map": execute}, draw={"stability_map": draw},
    loops={"stability_map": lambda scene, spec: [("batch", spec.solver)]},
    purposes={"stability_map": "one batch per grid step h over every value of the [ensemble] grid parameter"},
    tables=(Table("stability_map", columns=_COLUMNS,
                  description="the largest stable omega_max h per value of a swept parameter"),),
)
