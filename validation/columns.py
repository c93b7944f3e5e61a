"""The one declaration of every column of every report table: name, unit,
dtype and description.

From it :func:`typed_frame` enforces the dtypes when a table is written
(CSV and Parquet, :func:`rk4h.validation.report.write_tables`), :func:`columns_json`
gives the ``columns.json`` written into every report, and :func:`markdown`
gives ``docs/columns.md``::

    python -m rk4h.validation.columns --markdown > docs/columns.md

(``python -m rk4h.validation.docs_gen`` writes it with the other generated documents.)

Column order comes from :data:`rk4h.validation.tables.COLUMNS`, the tables'
descriptions from :data:`rk4h.validation.tables.DESCRIPTIONS`.

The conventions (dtypes, ``setting``/``h``/``rtol``, ``passed``/``checked``)
are :data:`CONVENTIONS`.
"""
from __future__ import annotations

import argparse
import json
import math
import sys
from dataclasses import asdict, dataclass

__all__ = ["Column", "CONVENTIONS", "DTYPES", "H_SOURCES", "declared", "table_columns", "typed_frame", "columns_json",
           "markdown", "main"]

DTYPES = ("float", "int", "bool", "category", "str")

#: Term -> what it means in every table (columns.json, docs/columns.md).
CONVENTIONS = {
    "dtype": "`float` (float64, NaN where not applicable), `int` (nullable Int64, empty where not applicable), "
             "`bool` (True/False only, never empty), `category` (one of a few fixed labels; free text goes to "
             "`note` or `message`), `str` (free text, empty where none).",
    "setting, h, rtol": "`setting` is the run's setting as the scene lists it: the step `h` (s) of a fixed-step "
                        "method, the relative tolerance `rtol` of an adaptive reference "
                        "(`rk4h.references.registry.REFERENCES`). `h` and `rtol` hold it apart, each NaN where it does "
                        "not apply.",
    "passed, checked": "In the tables where some rows carry no pass/fail verdict (`energy`, `stability`, "
                       "`thesis_code`), `checked` says whether the row was judged and `passed` is True only for a "
                       "judged row that met its expectation: `df[df.passed]` are the rows that passed, "
                       "`df[~df.checked]` the informative ones.",
}

#: The categories of ``cheapest.h_source`` (how the method's step was found;
#: rk4h.validation.trust). Anything after them (``(2 runs)``, ``: why``) goes to ``note``.
H_SOURCES = ("error constant", "measured bracket", "measured run", "confirmation run", "stability", "round-off",
             "no asymptotic fit", "no run", "no fit", "other")


@dataclass(frozen=True)
class Column:
    """One column: ``unit`` is "" for text, "1" for a pure number, "per
    quantity" where the row's ``quantity`` names the unit, "state" for the
    units of the state components (m, m/s, rad, ...)."""

    name: str
    unit: str
    dtype: str
    description: str


def _c(unit, dtype, description):
    return (unit, dtype, description)


_SETTING = _c("s or 1", "float", "the run's setting as the scene lists it: the step h (s) of a fixed-step method, "
                                 "the relative tolerance rtol of an adaptive reference (see `h`, `rtol`)")
_H = _c("s", "float", "step size of a fixed-step run (= setting); NaN for an adaptive reference")
_RTOL = _c("1", "float", "relative tolerance of an adaptive reference's run (= setting); NaN for a fixed-step method")
_PASSED = _c("", "bool", "the row's expectation held")
_CHECKED = _c("", "bool", "the row carries a pass/fail verdict (False: informative only, `passed` is then False)")
_STATUS = _c("", "category", "outcome of the run: ok, unstable, failed, skipped, singular, ...")


def _cost_units() -> str:
    """Each cost unit a method declares (rk4h.references.registry.CostUnit), as text."""
    from rk4h.references.registry import CostUnit

    return "; ".join(f"`{u.value}`: {u.text}" for u in CostUnit)


def _cost_unit(what: str):
    return _c("", "category", f"what {what} counts, as the method declares it in the registry "
                              f"(rk4h.references.registry.CostUnit): {_cost_units()}")

#: Columns shared by several tables, unless a table overrides them.
_COMMON = {
    "scene": _c("", "str", "scene name (validation/scenes/*.toml)"),
    "solver": _c("", "category", "method name (rk4h.references.registry)"),
    "setting": _SETTING, "h": _H, "rtol": _RTOL, "passed": _PASSED, "checked": _CHECKED, "status": _STATUS,
    "error_max": _c("state", "float", "largest absolute difference from the truth over output times and state "
                                      "components (in the state's units: m, m/s, rad, ...)"),
    "error_rel": _c("1", "float", "error_max / max |y_ref| over the scene's horizon"),
    "energy_drift_max": _c("1", "float", "max |E(t) - E0| / E_motion, E_motion = E0 - V(q*)"),
    "nfev": _c("1", "int", "right-hand-side evaluations of the run, in the unit `cost_unit` names"),
    "cost_unit": _cost_unit("`nfev` of the run"),
    "n_steps": _c("1", "int", "steps taken"),
    "wall_s": _c("s", "float", "wall time of the run (median of the repeats; timing, not reproducible)"),
    "compile_s": _c("s", "float", "compile time kept apart (heyoka JIT, numba; timing)"),
    "message": _c("", "str", "the solver's message"),
    "note": _c("", "str", "free text: why a value is missing or how it was obtained"),
    "quantity": _c("", "category", "what the row measures"),
    "mode": _c("1", "int", "mode number (1 = slowest)"),
    "omega_rad_s": _c("rad/s", "float", "natural angular frequency"),
    "measured": _c("per quantity", "float", "measured value of `quantity` (its unit is in the quantity's name)"),
    "theory": _c("per quantity", "float", "the theory's value of `quantity`"),
    "target_error": _c("1", "float", "target relative error"),
    "order": _c("1", "int", "order of accuracy of the method"),
    "method": _c("", "category", "method name (rk4h.references.registry)"),
    "tolerance": _c("per quantity", "float", "allowed difference"),
}

#: Per table: name -> (unit, dtype, description) where it differs from :data:`_COMMON` or is its own.
_TABLES = {
    "accuracy": {
        "error_final": _c("state", "float", "largest absolute error at the final time"),
    },
    "convergence": {
        "quantity": _c("", "category", "`order in h` (fixed-step) or `error vs tolerance` (adaptive)"),
        "observed_order": _c("1", "float", "least-squares slope of log error against log h (or log rtol)"),
        "expected_order": _c("1", "float", "the method's order (NaN for adaptive references)"),
        "passed": _c("", "bool", "observed order within the tolerance of the expected one; adaptive: error falls "
                                 "as the tolerance tightens"),
        "h_min": _c("s or 1", "float", "smallest step (s) of the fit, or smallest rtol for adaptive solvers"),
        "h_max": _c("s or 1", "float", "largest step (s) of the fit, or largest rtol for adaptive solvers"),
        "n_points": _c("1", "int", "runs in the fit"),
        "t_end": _c("s", "float", "horizon of the runs"),
    },
    "modes": {
        "freq_hz": _c("Hz", "float", "natural frequency omega / 2 pi"),
        "linearized": _c("", "bool", "the frequencies are those of the model's linearization"),
    },
    "work_precision": {
        "wall_min": _c("s", "float", "fastest repeat (timing)"),
        "wall_max": _c("s", "float", "slowest repeat (timing)"),
        "taylor_order": _c("1", "int", "heyoka's Taylor order (0 for other solvers)"),
    },
    "energy": {
        "drift_per_time": _c("1/s", "float", "(E(T) - E0) / (E_motion T)"),
        "theory_drift_per_time": _c("1/s", "float", "the same from the per-step factor |R(i omega h)|^2 of each "
                                                    "mode (NaN where no theory applies)"),
        "passed": _c("", "bool", "measured drift agrees with the theory (False where `checked` is False)"),
        # rk4h.validation.energy_time.summary
        "energy_growth_exponent": _c("1", "float", "slope of log max_{s<=t} |E(s) - E0| against log t over "
                                                   "[energy_fit_t0, energy_fit_t1]: ~0 bounded, ~1 linear growth"),
        "energy_fit_t0": _c("s", "float", "start of the growth exponent's fit range (t_end / 100)"),
        "energy_fit_t1": _c("s", "float", "end of the growth exponent's fit range (t_end)"),
        "phase_error_max": _c("rad", "float", "largest |phase error| of an energetic mode against the exact "
                                              "modal solution, over the modes the method keeps resolved to the end "
                                              "(linear models; NaN otherwise or when it keeps none)"),
        "phase_growth_exponent": _c("1", "float", "slope of log max |phase error| against log t, fitted as the "
                                                  "energy's, over the modes phase_error_max reads (linear models; NaN "
                                                  "otherwise or when it reads none)"),
        "phase_modes_unresolved": _c("1", "int", "energetic modes whose angle's rounding estimate "
                                                 "(energy_time.phase_angles) exceeds energy_time.PHASE_RESOLUTION at "
                                                 "some sample, as when the method damps a mode into the round-off of "
                                                 "the rest of the motion: left out of phase_error_max (linear models "
                                                 "with an energetic mode; empty otherwise)"),
    },
    "cheapest": {
        "error_constant": _c("1", "float", "C of error_rel ~ C h^p fitted on the method's runs (s^-p)"),
        "h": _c("s", "float", "the method's step: its cheapest confirming run's, else the prediction"),
        "h_source": _c("", "category", "how `h` was found: " + ", ".join(H_SOURCES) + " (details in `note`)"),
        "n_steps": _c("1", "int", "steps at `h` over the horizon (0 when no h)"),
        "rhs": _c("1", "float", "right-hand-side calls at `h` (NaN when no h; a Taylor method's steps x order)"),
        "cost_unit": _cost_unit("`rhs` of the method"),
        "time_s": _c("s", "float", "run time at `h` (timing)"),
        "confirmed_error_rel": _c("1", "float", "measured relative error of the confirming run, else of the run "
                                                "at the predicted step (NaN when not run)"),
        "confirmed": _c("", "bool", "a measured run of the method met the target"),
        "alternative": _c("", "category", "the cheapest other method whose run reached the target (empty: none)"),
        "alt_setting": _c("s or 1", "float", "the alternative run's setting (step or rtol)"),
        "alt_h": _c("s", "float", "the alternative run's step when it is a fixed-step method"),
        "alt_rtol": _c("1", "float", "the alternative run's rtol when it is an adaptive reference"),
        "alt_error_rel": _c("1", "float", "the alternative run's relative error"),
        "alt_rhs": _c("1", "float", "the alternative run's right-hand-side calls (a Taylor method's steps x order)"),
        "alt_cost_unit": _cost_unit("`alt_rhs` of the alternative (empty: no alternative)"),
        "alt_time_s": _c("s", "float", "the alternative run's time (timing)"),
        "alt_compile_s": _c("s", "float", "the alternative's compile time (timing)"),
        "alt_confirmed_error_rel": _c("1", "float", "the alternative run's measured relative error"),
        "alt_confirmed": _c("", "bool", "the alternative has a measured run that met the target"),
        "verdict_rhs": _c("", "category", "cheaper by RHS calls: a method name, tie or unmeasured"),
        "verdict_one_run": _c("", "category", "faster for one run, compile included: a method name, tie or "
                                              "unmeasured (timing)"),
        "verdict_amortized": _c("", "category", "faster over many runs, compile excluded (timing)"),
        "time_context": _c("", "str", "load average around the timed runs and the CPUs (timing)"),
    },
    "dispersion": {
        "quantity": _c("", "category", "`finite-chain omega` or `wave-packet group velocity`"),
        "index": _c("1", "int", "mode index n of a finite-chain row"),
        "kp_rad_m": _c("rad/m", "float", "wave number k_n"),
        "measured": _c("rad/s or m/s", "float", "measured omega (rad/s) or packet speed (m/s)"),
        "theory": _c("rad/s or m/s", "float", "the dispersion relation's value"),
        "rel_error": _c("1", "float", "|measured - theory| / |theory|"),
    },
    "stability": {
        "study": _c("", "category", "which stability study the row belongs to"),
        "quantity": _c("", "category", "what the row measures; its unit is in the name (_s: s)"),
        "theta": _c("rad", "float", "omega h of the fastest mode (or of `mode`)"),
        "mu": _c("1", "float", "mass ratio m2/m1"),
        "ratio": _c("1", "float", "stiff spring / the others"),
        "stiffness_ratio": _c("1", "float", "omega_max / omega_min at the cost point"),
        "n": _c("1", "int", "masses of a chain"),
        "a_over_l": _c("1", "float", "initial amplitude / natural length"),
        "offset": _c("m", "float", "aim past an anchor"),
        "periods": _c("1", "float", "run length in periods of the slowest mode"),
        "target_error": _c("1", "float", "relative error a cost row is measured at"),
        "passed": _c("", "bool", "the measured value met the theory (False where `checked` is False)"),
        "measured_timed": _c("per quantity", "float", "the measured value when it is derived from wall times (timing)"),
    },
    "linearization": {
        "amplitude_q": _c("state", "float", "largest coordinate of the nonlinear truth"),
        "error_max_q": _c("state", "float", "largest coordinate error of the linearized model"),
        "error_rel_q": _c("1", "float", "error_max_q / amplitude_q"),
    },
    "modal_energy": {
        "fraction_start": _c("1", "float", "the mode's fraction of the energy of the motion at t = 0"),
        "fraction_min": _c("1", "float", "its minimum"),
        "t_min": _c("s", "float", "time of the minimum"),
        "fraction_peak": _c("1", "float", "mode 1: largest return after the minimum; others: largest share"),
        "t_peak": _c("s", "float", "time of the peak"),
    },
    "thesis_code": {
        "program": _c("", "category", "the thesis program (Code 01, 02, 03)"),
        "variant": _c("", "category", "printed or corrected"),
        "case": _c("", "category", "the thesis table or case the run reproduces"),
        "quantity": _c("", "category", "what the row measures; its unit is in the name"),
        "value": _c("per quantity", "float", "measured value of `quantity`"),
        "expected": _c("per quantity", "float", "expected value"),
        "tolerance": _c("per quantity", "float", "allowed |value - expected|"),
        "passed": _c("", "bool", "value within tolerance of expected (False where `checked` is False)"),
    },
    "thesis_errata": {
        "item": _c("", "str", "the erratum"),
        "quantity": _c("", "str", "what is compared, with its unit"),
        "thesis": _c("per quantity", "float", "what the printed program gives"),
        "corrected": _c("per quantity", "float", "what the corrected program gives"),
    },
    "methods": {
        "method": _c("", "category", "a tableau method the scene runs (its own or a built-in)"),
        "order_p": _c("1", "int", "order whose conditions the row checks"),
        "conditions": _c("1", "int", "number of order conditions of order p"),
        "max_residual": _c("1", "float", "largest |b^T Phi(t) - 1/gamma(t)| over them"),
        "tolerance": _c("1", "float", "residual the coefficients' precision allows (0 for exact rationals)"),
        "holds": _c("", "bool", "every condition of order p holds"),
        "order": _c("1", "int", "the computed order"),
        "precision": _c("", "str", "precision the order is judged at: `exact`, or the coefficients' precision "
                        "as text (its number is `coefficient_tol`)"),
        "coefficient_tol": _c("1", "float", "rk4h.methods.Tableau.coefficient_tol"),
        "stages": _c("1", "int", "stages of the tableau"),
        "partitioned": _c("", "bool", "a partitioned (position/velocity) tableau"),
        "error_coefficient": _c("1", "float", "principal error coefficient: 2-norm of the order-(order+1) "
                                "truncation-error coefficients (rk4h.methods.Tableau.error_coefficient)"),
        "nfev_per_step": _c("1", "int", "right-hand-side evaluations per step after the first (first-same-as-last "
                            "reuse counted)"),
        "imaginary_axis_bound": _c("1", "float", "largest y = h omega with the method stable on y' = i omega y "
                                   "(partitioned: on q'' = -omega^2 q) for every h omega in [0, y]; RK4 2 sqrt 2, "
                                   "0 for none (rk4h.stability_function.imaginary_axis_boundary)"),
        "builtin": _c("", "bool", "a built-in method (False: the scene's own `[methods]` table)"),
    },
}

#: A sweep's parameter columns (named after the swept scene key, e.g. ``masses[1]``).
SWEEP = Column("<sweep key>", "as the scene key", "float",
               "a sweep's parameter value (right after `scene`; NaN for rows of unswept scenes)")


#: The dtype :func:`table_columns` gives a column missing from the declaration
#: when not ``strict`` (left as pandas infers it; ``tests/test_columns.py`` fails on it).
UNDECLARED = "undeclared"


def table_columns(name: str, strict: bool = True) -> list[Column]:
    """The declared columns of table ``name`` in their written order.

    A column of :data:`rk4h.validation.tables.COLUMNS` without a declaration
    raises ``KeyError`` when ``strict``, else gets dtype :data:`UNDECLARED`
    (a report run is not lost to a column someone forgot to declare)."""
    from rk4h.validation import outputs
    from rk4h.validation.tables import COLUMNS

    own = _TABLES.get(name, {})
    declared_by_output = outputs.own_table(name)
    if declared_by_output is not None:  # an output's own table (rk4h.validation.outputs.Table)
        own = {c[0]: tuple(c[1:]) for c in declared_by_output.columns}
    out = []
    for c in COLUMNS[name]:
        spec = own.get(c) or _COMMON.get(c)
        if spec is None:
            if strict:
                raise KeyError(f"column {c!r} of table {name!r} is not declared in rk4h.validation.columns")
            spec = ("", UNDECLARED, "")
        out.append(Column(c, *spec))
    return out


def declared() -> dict[str, list[Column]]:
    """Every table -> its columns."""
    from rk4h.validation.tables import COLUMNS

    return {name: table_columns(name) for name in COLUMNS}


# -- enforcing the declaration -----------------------------------------------------
def _references() -> set:
    from rk4h.references.registry import REFERENCES

    return set(REFERENCES)


def _split_setting(df, setting, solver, h, rtol):
    import numpy as np
    import pandas as pd

    s = pd.to_numeric(df[setting], errors="coerce").astype(float)
    adaptive = df[solver].astype(str).isin(_references()).to_numpy()
    named = df[solver].fillna("").astype(str).ne("").to_numpy()
    df[h] = np.where(named & ~adaptive, s, np.nan)
    df[rtol] = np.where(named & adaptive, s, np.nan)


def _verdict(x):
    if isinstance(x, bool):
        return x
    if type(x).__name__ == "bool_":
        return bool(x)
    if isinstance(x, str) and x.strip().lower() in ("true", "false"):
        return x.strip().lower() == "true"
    return None


def _h_source(df):
    """Split ``h_source`` into its category and the detail, which goes to ``note``."""
    cats, notes = [], []
    for src, note in zip(df["h_source"].fillna("").astype(str), df.get("note", [""] * len(df))):
        note = "" if note is None or (isinstance(note, float) and math.isnan(note)) else str(note)
        cat = next((c for c in H_SOURCES if src == c or src.startswith(c + " ") or src.startswith(c + ":")), None)
        if cat is None:
            cat, detail = ("other", src) if src else ("", "")
        else:
            detail = src[len(cat):].lstrip(": ").strip()
        cats.append(cat)
        notes.append(f"{note}; h_source detail: {detail}" if detail and note else
                     f"h_source detail: {detail}" if detail else note)
    df["h_source"] = cats
    df["note"] = notes


def _numeric(series, table, column):
    """``series`` as numbers, empty/None as NaN; text that is no number raises
    ``ValueError`` naming the table, column and value (never a silent NaN)."""
    import pandas as pd

    raw = series.map(lambda x: None if isinstance(x, str) and x.strip() == "" else x)
    v = pd.to_numeric(raw, errors="coerce")
    bad = v.isna() & raw.notna() & ~raw.map(lambda x: isinstance(x, float) and math.isnan(x))
    if bad.any():
        raise ValueError(f"table {table!r} column {column!r} is declared numeric, got {raw[bad].iloc[0]!r}")
    return v


def _cast(series, dtype, table="", column=""):
    import numpy as np

    if dtype == "float":
        return _numeric(series, table, column).astype("float64")
    if dtype == "int":
        v = _numeric(series, table, column).astype("float64")
        return v.where(np.isfinite(v)).round().astype("Int64")
    if dtype == "bool":
        return series.map(lambda x: _verdict(x) is True).astype(bool)
    text = series.map(lambda x: "" if x is None or (isinstance(x, float) and math.isnan(x)) else str(x))
    return text.astype("category") if dtype == "category" else text.astype(object)


def typed_frame(name: str, df):
    """``df`` (a table's rows, declared columns present) with the derived
    columns filled (``h``/``rtol`` from ``setting``, ``checked`` from
    ``passed``, ``h_source``'s detail moved to ``note``) and every declared
    column cast to its dtype. Undeclared columns (a sweep's parameters)
    become float where they are numeric. Returns a new frame."""
    df = df.copy()
    names = set(df.columns)
    if {"setting", "solver", "h", "rtol"} <= names:
        _split_setting(df, "setting", "solver", "h", "rtol")
    if {"alt_setting", "alternative", "alt_h", "alt_rtol"} <= names:
        _split_setting(df, "alt_setting", "alternative", "alt_h", "alt_rtol")
    if "checked" in names and "passed" in names:
        verdicts = df["passed"].map(_verdict)
        given = df["checked"].map(_verdict)  # a row (or a table read back) may say it already
        df["checked"] = [bool(g) if g is not None else v is not None for g, v in zip(given, verdicts)]
        df["passed"] = [v is True and c for v, c in zip(verdicts, df["checked"])]
    if "h_source" in names:
        _h_source(df)
    cols = {c.name: c for c in table_columns(name, strict=False)} if name in _known() else {}
    for c in df.columns:
        if c in cols and cols[c].dtype != UNDECLARED:
            df[c] = _cast(df[c], cols[c].dtype, name, c)
            continue
        try:
            df[c] = _numeric(df[c], name, c).astype("float64")
        except (ValueError, TypeError):
            df[c] = _cast(df[c], "str")  # text (pyarrow refuses a column of mixed types)
    return df


def _known():
    from rk4h.validation.tables import COLUMNS

    return {n for n, c in COLUMNS.items() if c is not None}


# -- columns.json and docs/columns.md -------------------------------------------------
def columns_json(tables=None, front=()) -> dict:
    """The content of ``columns.json``: per table (``tables``: names; None:
    all) its description, files and columns; ``front`` the sweep parameters."""
    from rk4h.validation.tables import DESCRIPTIONS

    names = list(declared()) if tables is None else list(tables)
    return {
        "conventions": dict(CONVENTIONS),
        "tables": {n: {"files": [f"{n}.csv", f"{n}.parquet"], "description": DESCRIPTIONS.get(n, ""),
                       "columns": [asdict(c) for c in table_columns(n, strict=False)]} for n in names},
        "sweep_parameters": [{**asdict(SWEEP), "name": k} for k in front],
    }


def write_json(path, tables=None, front=()) -> None:
    with open(path, "w", encoding="utf-8") as f:
        json.dump(columns_json(tables, front), f, indent=1)
        f.write("\n")


def _cell(text: str) -> str:
    return str(text).replace("|", "\\|").replace("\n", " ")


def markdown() -> str:
    """``docs/columns.md``: every table's columns (generated; do not edit)."""
    from rk4h.validation.tables import DESCRIPTIONS

    lines = ["# Report table columns", "",
             "Generated by `python -m rk4h.validation.columns --markdown > docs/columns.md` from "
             "`validation/columns.py`; do not edit by hand. Every report holds the same as `columns.json`, "
             "and each table as `NAME.csv` and `NAME.parquet` (the Parquet file keeps the dtypes).", "",
             "## Conventions", ""]
    lines += [f"- **{term}**: {text}" for term, text in CONVENTIONS.items()]
    lines += ["", f"A sweep's parameter columns (e.g. `masses[1]`) follow `scene`: {SWEEP.description}.", ""]
    for name, cols in declared().items():
        lines += [f"## {name}", "", _cell(DESCRIPTIONS.get(name, "")), "",
                  "| column | unit | dtype | description |", "|---|---|---|---|"]
        lines += [f"| `{c.name}` | {_cell(c.unit)} | {c.dtype} | {_cell(c.description)} |" for c in cols]
        lines.append("")
    return "\n".join(lines)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(prog="python -m rk4h.validation.columns", description=__doc__.splitlines()[0])
    g = p.add_mutually_exclusive_group()
    g.add_argument("--markdown", action="store_true", help="print docs/columns.md (default)")
    g.add_argument("--json", action="store_true", help="print columns.json for every table")
    a = p.parse_args(argv)
    sys.stdout.write(json.dumps(columns_json(), indent=1) + "\n" if a.json else markdown())
    return 0


if __name__ == "__main__":
    sys.exit(main())
