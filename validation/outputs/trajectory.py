"""``trajectory``: every run's trajectory exported to netCDF through xarray.

One file per scene, ``trajectory-<scene>.nc`` (netCDF3, xarray's ``scipy``
engine: no C library), with dimensions ``run``, ``time``, ``component``:

* ``y(run, time, component)``: the state ``[q, v]`` in the model's units
  (m and m/s, or rad and rad/s);
* ``energy(run, time)``: the model's energy (J) where it has one, else NaN;
* ``time(time)`` (s), ``component(component)`` the state's names (the
  model's coordinates, then ``d<name>/dt``), and per run ``solver``, ``setting``, ``h`` (s, NaN for
  an adaptive reference), ``rtol`` (NaN for a fixed-step method) and
  ``status``;
* attributes ``scene``, ``units`` and the convention of ``setting``.

For a first-order ODE (model ``ode``) ``y`` holds its variables (named by
``component``, in the ODE's own units), ``energy`` its invariant ``I(y)``
(NaN without one) and ``units`` says so.

Runs that kept no trajectory (a failed run) hold NaN. The table
``trajectory.csv`` lists the runs and their file.
"""
from __future__ import annotations

import math
import re

from rk4h.validation.outputs import FileJob, Output, Table, _runs

#: The state's and energy's units, written as attributes.
UNITS = "time: s; y: [q, v] in the model's units (m, m/s; rad, rad/s); energy: J"
#: The same for a first-order ODE (model ``ode``).
UNITS_ODE = "time: s; y: the ODE's variables, in its own units; energy: the ODE's invariant I(y), in its units"


def file_name(scene: str) -> str:
    """``trajectory-<scene>.nc`` (characters outside ``[A-Za-z0-9_.-]`` as ``_``)."""
    return "trajectory-" + re.sub(r"[^A-Za-z0-9_.-]", "_", scene) + ".nc"


def measure(m) -> None:
    """One ``trajectory`` row per run and one file job per scene with the
    runs' arrays (read from the records only)."""
    import numpy as np

    runs, first_order = [], False
    name = file_name(m.scene.name)
    for spec in m.specs("run"):
        rec = m.records[spec.key]
        a = rec.arrays
        t = a.get("trajectory_t")
        runs.append({"solver": spec.solver, "setting": float(spec.setting), "status": rec.status or "failed",
                     "t": None if t is None else np.asarray(t, float),
                     "y": None if t is None else np.asarray(a["trajectory_y"], float),
                     "energy": None if t is None or "trajectory_energy" not in a
                     else np.asarray(a["trajectory_energy"], float),
                     "names": None if "trajectory_names" not in a else [str(x) for x in a["trajectory_names"]]})
        first_order = first_order or bool(np.asarray(a.get("trajectory_first_order", False)))
        n_times = 0 if t is None else int(np.asarray(t).shape[0])
        n_state = 0 if t is None else int(np.asarray(a["trajectory_y"]).shape[0])
        m.res.add("trajectory", {"scene": m.scene.name, "solver": spec.solver, "setting": float(spec.setting),
                                 "file": name if t is not None else "", "n_times": n_times, "n_state": n_state,
                                 "status": rec.status or "failed"})
    if runs:
        m.res.files.append(FileJob(m.scene.name, "trajectory", {"file": name, "runs": runs,
                                                                "first_order": first_order}))


def dataset(scene: str, runs: list, references=None, first_order: bool = False):
    """The :class:`xarray.Dataset` of one scene's ``runs`` (see the module
    docstring); ``references`` the adaptive method names (default: the
    registry's references); ``first_order`` a first-order ODE's runs (``y``
    its variables, ``energy`` its invariant)."""
    import numpy as np
    import xarray as xr

    if references is None:
        from rk4h.references.registry import REFERENCES as references
    kept = [r for r in runs if r["t"] is not None]
    t = kept[0]["t"] if kept else np.zeros(0)
    n_state = kept[0]["y"].shape[0] if kept else 0
    names = next((r["names"] for r in kept if r.get("names") and len(r["names"]) == n_state), None)
    y = np.full((len(runs), t.shape[0], n_state), np.nan)
    energy = np.full((len(runs), t.shape[0]), np.nan)
    for i, r in enumerate(runs):
        if r["t"] is None or r["t"].shape != t.shape or not np.array_equal(r["t"], t):
            continue  # a run on another grid or without a trajectory: NaN
        y[i] = r["y"].T
        if r["energy"] is not None:
            energy[i] = r["energy"]
    adaptive = np.array([r["solver"] in references for r in runs], bool)
    setting = np.array([r["setting"] for r in runs], float)
    ds = xr.Dataset(
        {"y": (("run", "time", "component"), y,
               {"long_name": "the ODE's variables" if first_order else "state [q, v]",
                "units": "the ODE's units" if first_order else "model units"}),
         "energy": (("run", "time"), energy,
                    {"long_name": "invariant I(y) of the ODE" if first_order else "energy of the model",
                     "units": "the invariant's units" if first_order else "J"})},
        coords={"time": ("time", t, {"units": "s"}),
                **({"component": ("component", np.array(names, dtype=str))} if names else {}),
                "run": ("run", np.arange(len(runs))),
                "solver": ("run", np.array([r["solver"] for r in runs], dtype=str)),
                "setting": ("run", setting, {"units": "s or 1"}),
                "h": ("run", np.where(adaptive, math.nan, setting), {"units": "s"}),
                "rtol": ("run", np.where(adaptive, setting, math.nan), {"units": "1"}),
                "status": ("run", np.array([r["status"] for r in runs], dtype=str))},
        attrs={"scene": scene, "units": UNITS_ODE if first_order else UNITS,
               "setting": "the step h (s) of a fixed-step method, the rtol of an adaptive reference",
               "source": "rk4 validation harness, output trajectory"})
    return ds


def write(out_dir, jobs) -> list:
    """``trajectory-<scene>.nc`` per scene (netCDF3, engine ``scipy``);
    returns ``[(Path, sentence)]``."""
    from pathlib import Path

    try:
        import xarray  # noqa: F401
    except ImportError as e:
        raise ModuleNotFoundError("the trajectory output needs xarray: "
                                  "pip install 'rk4-validation-harness[report]'") from e
    out = []
    for job in jobs:
        path = Path(out_dir) / job.data["file"]
        ds = dataset(job.scene, job.data["runs"], first_order=job.data.get("first_order", False))
        ds.to_netcdf(path, engine="scipy", format="NETCDF3_64BIT")
        out.append((path, f"{job.scene}: `{path.name}` holds the trajectories of {ds.sizes['run']} run(s), "
                          f"{ds.sizes['time']} times each (netCDF, read with xarray.open_dataset)."))
    return out


OUTPUT = Output(
    name="trajectory", rank=120, plan_rank=10, measure_rank=100,
    when="never by default (it writes every run's states); any model that lists it, a first-order ODE included",
    what="every run's time, state and energy in `trajectory-<scene>.nc` (netCDF through xarray), listed in "
         "`trajectory.csv`",
    plan=_runs.plan, measure=measure, write=write, loops=_runs.LOOPS,
    run_keep=lambda draw: ("trajectory",),
    purposes={"run": "as for `state`, keeping the run's time, state and energy arrays"},
    tables=(Table("trajectory", columns=(
        ("scene", "", "str", "scene name"),
        ("solver", "", "category", "method name (rk4h.references.registry)"),
        ("setting", "s or 1", "float", "the run's setting: step h (s) or rtol"),
        ("h", "s", "float", "step size of a fixed-step run; NaN for an adaptive reference"),
        ("rtol", "1", "float", "relative tolerance of an adaptive reference's run; NaN for a fixed-step method"),
        ("file", "", "str", "the netCDF file holding the run's trajectory (empty: none was kept)"),
        ("n_times", "1", "int", "output times of the trajectory"),
        ("n_state", "1", "int", "state components (2 n_dof)"),
        ("status", "", "category", "outcome of the run"),
    ), description="one row per run whose trajectory the `trajectory` output exported: its netCDF file "
                   "(dimensions run, time, component; variables y, energy; per run solver, setting, h, rtol, "
                   "status) and its size."),),
)
