"""Writing the report: CSV tables (one row per measurement) and ``index.md``.

Column order is fixed by :data:`COLUMNS`. Timing columns (:data:`TIMING`) are
the only ones that change between two runs on one machine; every other column
is a deterministic function of the code and the scenes (``tests/
test_reports_committed.py`` compares them with the committed ``reports/``).
"""
from __future__ import annotations

import math
import os
import platform
import sys
from pathlib import Path

import numpy as np

__all__ = ["COLUMNS", "TIMING", "DESCRIPTIONS", "write_tables", "write_index", "versions",
           "errata_rows"]

COLUMNS = {
    "accuracy": ["scene", "solver", "setting", "error_max", "error_rel", "error_final",
                 "energy_drift_max", "nfev", "n_steps", "wall_s", "compile_s", "status", "message"],
    "convergence": ["scene", "solver", "quantity", "observed_order", "expected_order", "passed",
                    "h_min", "h_max", "n_points", "t_end"],
    "modes": ["scene", "mode", "omega_rad_s", "freq_hz", "linearized"],
    "work_precision": ["scene", "solver", "setting", "error_max", "error_rel", "wall_s", "nfev",
                       "n_steps", "taylor_order", "status"],
    "energy": ["scene", "solver", "setting", "drift_per_time", "theory_drift_per_time",
               "energy_drift_max", "passed", "status"],
    "cheapest": ["scene", "target_error", "solver", "setting", "wall_s", "rk4_h", "rk4_wall_s",
                 "rk4_is_cheapest"],
    "dispersion": ["scene", "quantity", "index", "kp_rad_m", "measured", "theory", "rel_error",
                   "passed"],
    "stability": None,  # validation.stability.COLUMNS (filled below)
    "linearization": ["scene", "amplitude_q", "error_max_q", "error_rel_q"],
    "modal_energy": ["scene", "solver", "setting", "mode", "omega_rad_s", "fraction_start", "fraction_min",
                     "t_min", "fraction_peak", "t_peak", "status"],
    "thesis_code": ["scene", "program", "variant", "case", "quantity", "value", "expected", "tolerance",
                    "passed", "status", "message"],
    "thesis_errata": ["scene", "item", "quantity", "thesis", "corrected", "note"],
}

#: Columns that hold timings (not reproducible); whole tables built on timings.
TIMING = {"accuracy": {"wall_s", "compile_s"}, "work_precision": {"wall_s"},
          "cheapest": None, "stability": None}


def _stability_columns():
    from validation.stability import COLUMNS as cols, TIMING_COLUMNS as timing

    COLUMNS["stability"] = list(cols)
    TIMING["stability"] = set(timing)


_stability_columns()

DESCRIPTIONS = {
    "accuracy": "one row per (scene, solver, setting): largest error against the reference over all "
                "output times and state components (absolute, and relative to the largest state "
                "component), final-time error, largest relative energy error, cost and status.",
    "convergence": "observed order of each fixed-step method (least-squares slope of log error vs "
                   "log h over the range h_min..h_max listed) beside the expected order; for adaptive "
                   "solvers, whether the error falls as the tolerance tightens (h_min/h_max are then "
                   "the tolerance range).",
    "modes": "natural angular frequencies (rad/s) and frequencies (Hz) of each scene's model "
             "(of its linearization where `linearized` is true).",
    "work_precision": "the speed-accuracy trade: error against wall time and RHS evaluations for "
                      "every solver and setting (the data of the work-precision figures).",
    "energy": "energy drift per unit time (E(T) - E0)/(|E0| T); for RK4 on linear models beside the "
              "exact theory from the per-step factor 1 - theta^6/72 + theta^8/576 of each mode, "
              "weighted by the modal energy fractions.",
    "cheapest": "for each scene and target relative error (1e-3 ... 1e-12), the cheapest solver by "
                "median wall time that reaches it, and RK4's cheapest run; `rk4_is_cheapest` "
                "turning false marks the crossover.",
    "dispersion": "the 100-mass chain's eigenfrequencies against the lattice dispersion relation "
                  "omega(kp_n), and wave packets integrated by RK4 against the group velocity.",
    "modal_energy": "energy of the lowest linear modes over time (FPUT recurrence): per solver and mode, "
                    "the fraction of the initial energy at the start, its minimum (and when), and its "
                    "peak (and when): for mode 1 its largest return after that minimum, for the "
                    "others their largest share.",
    "linearization": "a nonlinear scene's linearized model (its exact modal solution) against the "
                     "nonlinear truth: largest coordinate error over the output grid, absolute and relative "
                     "to the largest coordinate (amplitude_q): what modelling only the small-amplitude "
                     "physics costs at this amplitude.",
    "stability": "the stability study: step-size boundaries, stiffness, long horizons, large N and "
                 "singular geometry, measured beside theory.",
    "thesis_code": "the thesis' own programs (Code 01, 02, 03, transcribed in rk4core/thesis_code, run in "
                   "GNU Octave through the command protocol): as printed and corrected, each against rk4core "
                   "on the same right-hand side (expected at round-off) and against the truth, and the "
                   "consequences of the printed code's errors computed from the runs.",
    "thesis_errata": "the thesis' code errata computed from runs of its programs: what the printed "
                     "program gives (`thesis`) beside the corrected one (`corrected`).",
}


def _frame(name, rows):
    import pandas as pd

    cols = COLUMNS.get(name)
    df = pd.DataFrame(rows)
    if cols is None:
        return df
    extra = [c for c in df.columns if c not in cols]
    for c in cols:
        if c not in df.columns:
            df[c] = ""
    return df[cols + extra]


def write_tables(out_dir, tables: dict, front=()) -> dict:
    """Write ``tables`` (name -> rows) as ``name.csv``; returns name -> path.
    Columns in ``front`` (a sweep's parameters) come right after ``scene``."""
    out = {}
    for name, rows in tables.items():
        if not rows:
            continue
        path = Path(out_dir) / f"{name}.csv"
        df = _frame(name, rows)
        first = [c for c in ("scene", *front) if c in df.columns]
        df = df[first + [c for c in df.columns if c not in first]]
        df.to_csv(path, index=False, lineterminator="\n")
        out[name] = path
    return out


def versions() -> dict:
    """Versions of the interpreter and the numerical stack, numpy's BLAS, and the machine."""
    import importlib.metadata as md

    v = {"python": sys.version.split()[0]}
    for label, dist in (("numpy", "numpy"), ("scipy", "scipy"), ("scikit-sundae", "scikit-sundae"),
                        ("heyoka", "heyoka"), ("numba", "numba"), ("pandas", "pandas"),
                        ("matplotlib", "matplotlib")):
        try:
            v[label] = md.version(dist)
        except md.PackageNotFoundError:
            v[label] = "not installed"
    v["BLAS"] = _blas()
    v["machine"] = f"{platform.machine()}, {os.cpu_count()} CPUs, {platform.platform()}"
    v["processor"] = _cpu_name()
    return v


def _blas() -> str:
    """numpy's BLAS/LAPACK (it decides the round-off of eigen-decompositions)."""
    try:
        deps = np.show_config(mode="dicts")["Build Dependencies"]
        blas = deps["blas"]
        return f"{blas.get('name', '?')} {blas.get('version', '?')} (numpy build)"
    except Exception:  # noqa: BLE001 - older numpy: no dict mode
        return "unknown"


def _cpu_name() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown"


def errata_rows() -> list[dict]:
    """The errata table: thesis' printed numbers beside the computed ones
    (``references.errata``, the code that also feeds the tables)."""
    from references.errata import errata_rows as rows

    return rows()


def _md_cell(x) -> str:
    if isinstance(x, float):
        return "" if math.isnan(x) else f"{x:.6g}"
    return str(x).replace("|", "\\|").replace("\n", " ")


def _md_table(header, rows) -> list[str]:
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(_md_cell(r.get(h, "")) for h in header) + " |" for r in rows]
    return lines


def write_index(out_dir, *, results, tables, table_paths, failures, findings, mode, repeats,
                seconds, n_scenes=None, timing=None) -> Path:
    """Write ``index.md``: failures first, findings, tables, figures, errata, versions."""
    out_dir = Path(out_dir)
    lines = ["# RK4 validation report", ""]
    lines.append(f"Mode: **{mode}**, {n_scenes if n_scenes is not None else len(results)} scene(s), wall time {seconds:.0f} s. Each timed run is "
                 f"the median of {repeats} repeat(s) (runs longer than 0.1 s: one); compile time (heyoka JIT, numba) is kept apart in "
                 f"`compile_s`. Errors are measured against exact modal solutions (linear models) or "
                 f"heyoka in quadruple precision (nonlinear models)."
                 + (f" Timed runs: {timing}." if timing else ""))
    lines.append("")
    if failures:
        lines += ["## Failures", "", f"{len(failures)} expectation(s) did not hold:", ""]
        lines += [f"- {f}" for f in failures]
    else:
        lines += ["## Failures", "", "None: every expectation held (convergence orders, RK4 energy theory, "
                  "tolerance monotonicity, dispersion, stability)."]
    lines += ["", "## Main findings", ""]
    lines += [f"- {f}" for f in findings] or ["- (none)"]
    lines += ["", "## Tables", ""]
    for name, path in table_paths.items():
        lines.append(f"- [{path.name}]({path.name}): {DESCRIPTIONS.get(name, '')}")
    lines += ["", "## Figures", ""]
    for r in results:
        drawn = getattr(r, "drawn", None)
        drawn = drawn if drawn is not None else r.figures
        if not drawn:
            continue
        lines += [f"### {r.scene}", ""]
        for path, sentence in drawn:
            rel = Path(path).relative_to(out_dir) if Path(path).is_absolute() else Path(path)
            lines.append(f"- [{Path(path).name}]({rel.as_posix()}): {sentence}")
        lines.append("")
    lines += ["## Errata of the thesis", "",
              "Printed values beside the values the harness computes (`references.errata`, the same "
              "closed forms and eigenproblems that feed the tables above).", ""]
    try:
        lines += _md_table(["item", "quantity", "thesis", "corrected", "note"], errata_rows())
    except Exception as e:  # noqa: BLE001 - the report still gets written
        lines.append(f"(errata table unavailable: {type(e).__name__}: {e})")
    code = tables.get("thesis_errata") or []
    if code:
        lines += ["", "### Errata of the thesis' code, computed from runs of its programs", "",
                  "The printed programs (GNU Octave, `rk4core/thesis_code`) beside the corrected ones "
                  "([thesis_code.csv](thesis_code.csv) holds every comparison).", ""]
        lines += _md_table(["item", "quantity", "thesis", "corrected", "note"], code)
    lines += ["", "## Environment", ""]
    lines += [f"- {k}: {v}" for k, v in versions().items()]
    lines.append("")
    path = out_dir / "index.md"
    path.write_text("\n".join(lines), encoding="utf-8")
    return path


def summarize(tables: dict) -> list[str]:
    """Headline findings computed from the tables (a few lines)."""
    out = []
    conv = [r for r in tables.get("convergence", []) if r.get("quantity") == "order in h"]
    for method in dict.fromkeys(r["solver"] for r in conv):  # in report order
        orders = np.array([r["observed_order"] for r in conv if r["solver"] == method], float)
        orders = orders[np.isfinite(orders)]
        if orders.size:
            out.append(f"{method}: observed order {orders.min():.3f} to {orders.max():.3f} over "
                       f"{orders.size} scene(s).")
    energy = [r for r in tables.get("energy", []) if r.get("passed") in (True, False)]
    if energy:
        good = sum(r["passed"] is True for r in energy)
        out.append(f"The energy decay of the tableau methods matches the theory |R(i omega h)|^2 per step "
                   f"(RK4: 1 - theta^6/72 + theta^8/576) in {good} of {len(energy)} linear-model runs.")
    return out
