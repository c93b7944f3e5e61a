"""Writing the report: tables (one row per measurement; CSV and Parquet, typed
by :mod:`rk4h.validation.columns`, described in ``columns.json``) and ``index.md``.

Column order is fixed by :data:`COLUMNS`. Timing columns (:data:`TIMING`) are
the only ones that change between two runs on one machine; every other column
is a deterministic function of the code and the scenes (``tests/
test_reports_committed.py`` compares them with the committed ``reports/``).
"""
from __future__ import annotations

import functools
import math
import os
import platform
import sys
from pathlib import Path

import numpy as np

__all__ = ["COLUMNS", "TIMING", "DESCRIPTIONS", "write_tables", "write_index", "versions",
           "errata_rows"]

from .tables import COLUMNS, DESCRIPTIONS, TIMING  # re-exported: the report's tables
from .trust import is_confirmed



def _frame(name, rows):
    """The table's rows as a frame in :data:`COLUMNS` order, typed by
    :func:`rk4h.validation.columns.typed_frame` (tables without a declaration as is)."""
    import pandas as pd

    from rk4h.validation.columns import typed_frame

    cols = COLUMNS.get(name)
    df = pd.DataFrame(rows)
    if cols is None:
        return df
    extra = [c for c in df.columns if c not in cols]
    for c in cols:
        if c not in df.columns:
            df[c] = ""
    return typed_frame(name, df[cols + extra])


def write_tables(out_dir, tables: dict, front=()) -> dict:
    """Write ``tables`` (name -> rows) as ``name.csv`` and ``name.parquet``
    (dtypes of :mod:`rk4h.validation.columns`), and ``columns.json`` describing
    the tables written; returns name -> CSV path. Columns in ``front`` (a
    sweep's parameters) come right after ``scene``."""
    from rk4h.validation import columns

    out, written = {}, set()
    for name, rows in tables.items():
        if not rows:
            continue
        path = Path(out_dir) / f"{name}.csv"
        df = _frame(name, rows)
        first = [c for c in ("scene", *front) if c in df.columns]
        df = df[first + [c for c in df.columns if c not in first]]
        df.to_csv(path, index=False, lineterminator="\n")
        df.to_parquet(path.with_suffix(".parquet"), index=False)
        out[name] = path
        written.update(df.columns)
    if out:
        columns.write_json(Path(out_dir) / "columns.json", [n for n in out if COLUMNS.get(n) is not None],
                           front=[c for c in front if c in written])
    return out


def versions() -> dict:
    """Versions of the interpreter and the numerical stack, numpy's BLAS, and the machine."""
    from rk4h.distributions import version

    v = {"python": sys.version.split()[0]}
    for dist in ("numpy", "scipy", "scikit-sundae", "heyoka", "numba", "pandas", "matplotlib"):
        v[dist] = version(dist) or "not installed"
    v["BLAS"] = _blas()
    v["machine"] = f"{platform.machine()}, {os.cpu_count()} CPUs, {platform.platform()}"
    v["processor"] = _cpu_name()
    return v


def _blas() -> str:
    """numpy's BLAS/LAPACK (it decides the round-off of eigen-decompositions)
    and, for OpenBLAS, the CPU kernel it runs (:func:`blas_kernel`)."""
    try:
        deps = np.show_config(mode="dicts")["Build Dependencies"]
        blas = deps["blas"]
        text = f"{blas.get('name', '?')} {blas.get('version', '?')} (numpy build)"
    except Exception:  # noqa: BLE001 - older numpy: no dict mode
        text = "unknown"
    kernel = blas_kernel()
    return text if kernel is None else f"{text}, kernel {kernel}"


#: Where numpy's wheels keep their OpenBLAS, and the names of its core-name query.
_OPENBLAS_DIRS = ("numpy.libs", "numpy/.dylibs")
_CORENAME = ("scipy_openblas_get_corename64_", "scipy_openblas_get_corename", "openblas_get_corename64_",
             "openblas_get_corename")


@functools.lru_cache(maxsize=1)
def blas_kernel() -> str | None:
    """The CPU kernel numpy's OpenBLAS chose at start-up ("Haswell",
    "SkylakeX", "Zen", ...; the environment variable ``OPENBLAS_CORETYPE``
    forces one), or None when numpy's BLAS is not an OpenBLAS that says.

    The kernel fixes the order of the sums in numpy's dot products, hence
    the round-off of scipy's DOP853 steps (``K.T @ A``): on two kernels the
    same code gives DOP853 errors that differ at round-off level (1.2e-13 of
    the state in the quick scenes) or, where the rounding changes the
    accepted steps, by up to 53% (planar4-case2, rtol 1e-7; see the README).
    ``tests/test_reports_committed.py`` regenerates on the committed
    report's kernel.
    """
    import ctypes
    import glob

    site = Path(np.__file__).resolve().parent.parent
    for d in _OPENBLAS_DIRS:
        for path in sorted(glob.glob(str(site / d / "*openblas*"))):
            try:
                lib = ctypes.CDLL(path)  # already loaded by numpy: the same handle
            except OSError:
                continue
            for name in _CORENAME:
                fn = getattr(lib, name, None)
                if fn is not None:
                    fn.restype = ctypes.c_char_p
                    core = fn()
                    return (core.decode().strip() or None) if core else None
    return None


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
    (``rk4h.references.errata``, the code that also feeds the tables)."""
    from rk4h.references.errata import errata_rows as rows

    return rows()


def _md_cell(x) -> str:
    if isinstance(x, float):
        return "" if math.isnan(x) else f"{x:.6g}"
    return str(x).replace("|", "\\|").replace("\n", " ")


def _md_table(header, rows) -> list[str]:
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(_md_cell(r.get(h, "")) for h in header) + " |" for r in rows]
    return lines


def _g(x, unit="") -> str:
    if x is None or (isinstance(x, float) and not math.isfinite(x)):
        return "-"
    return f"{x:.2g}{unit}"


def trust_lines(rows) -> list[str]:
    """The trust table of index.md: one line per scene, one cell per target
    (from ``cheapest.csv``, :mod:`rk4h.validation.trust`)."""
    if not rows:
        return []
    targets = sorted({float(r["target_error"]) for r in rows}, reverse=True)
    scenes = list(dict.fromkeys(r["scene"] for r in rows))
    method = {r["scene"]: r["method"] for r in rows}
    lines = ["| scene | method | " + " | ".join(f"{t:.0e}" for t in targets) + " |",
             "|---|---|" + "---|" * len(targets)]
    by = {(r["scene"], float(r["target_error"])): r for r in rows}
    for sc in scenes:
        cells = []
        for t in targets:
            r = by.get((sc, t))
            if r is None:
                cells.append("")
                continue
            cells.append(_trust_cell(r))
        lines.append(f"| {sc} | {method[sc]} | " + " | ".join(cells) + " |")
    return lines


def _trust_cell(r) -> str:
    """One cell of the trust table: the method's step and calls, marked
    "measured E" when a run at that step met the target (``confirmed``) and
    "predicted, unconfirmed" otherwise; the verdicts, the calls verdict in
    bold only when it names a solver whose run was measured (never a
    ``tie`` or ``unmeasured``)."""
    h = r["h"]
    if isinstance(h, float) and math.isfinite(h):
        step = f"h {_g(h, ' s')}, {_g(r['rhs'])} calls"
        step += (f", measured {r['confirmed_error_rel']:.3g}" if is_confirmed(r.get("confirmed"))
                 else ", predicted, unconfirmed")
    else:
        step = f"no h ({r['h_source']})"
    v = r["verdict_rhs"]
    side = ((v == r["method"] and is_confirmed(r.get("confirmed")))
            or (v == r.get("alternative") and is_confirmed(r.get("alt_confirmed"))))
    calls = f"**{v}**" if side else v
    if v == "unmeasured":
        return f"{step}; unmeasured"
    return (f"{step}; calls: {calls}; time: {r['verdict_amortized']}"
            + (f" (1 run: {r['verdict_one_run']})" if r["verdict_one_run"] != r["verdict_amortized"] else ""))


def limits_rows(stability_rows, methods=None) -> list[dict]:
    """The limits a user needs, one line each, from the stability study's
    rows: the largest stable omega_max h, the round-off floor, the long-run
    energy change and the cost at the stiffest point of each cost sweep.

    ``methods`` maps a scene to the method its study is about (its
    ``stability.method``: given, or the first classical tableau it runs);
    a scene not in it gets the fixed-step method of its round-off or
    long-horizon rows, else the registry's method under test (rk4)."""
    from rk4h.references.registry import BUILTIN, UNDER_TEST

    adaptive = {n for n, m in BUILTIN.items() if m.adaptive}  # the references, not the method under study
    out = []
    rows = list(stability_rows or [])
    method = dict(methods or {})
    for r in rows:
        if r["study"] in ("roundoff", "long_horizon") and r["solver"] != "-" and r["solver"] not in adaptive:
            method.setdefault(r["scene"], r["solver"])
    for r in rows:
        sc, q = r["scene"], r["quantity"]
        m = method.get(sc, UNDER_TEST)
        if q == "largest_stable_h_s" and r["solver"] == m and r["measured"] > 0:
            out.append({"scene": sc, "limit": f"{m} stable up to", "value": f"omega_max h = {r['theta']:.4g}",
                        "detail": f"h = {r['measured']:.4g} s (theory {r['theory']:.4g} s)"})
        elif q == "roundoff_floor_error":
            turned = any(x["scene"] == sc and x["quantity"] == "error_turns_up_below_best_h" and x["measured"] == 1
                         for x in rows)
            out.append({"scene": sc, "limit": f"{r['solver']} round-off floor" if turned else
                        f"{r['solver']} smallest error reached", "value": f"error {r['measured']:.2g}",
                        "detail": f"best omega_max h = {r['theta']:.3g}; " + (
                            "smaller steps lose to round-off" if turned else
                            "still falling at the smallest step probed (truncation, not round-off)")})
        elif q == "energy_drift_per_period" and r["solver"] == m and math.isfinite(r["measured"]):
            out.append({"scene": sc, "limit": f"{m} long-run energy change",
                        "value": f"{r['measured'] * r['periods']:.3g} relative",
                        "detail": f"over {r['periods']:.3g} slow periods at omega_max h = {r['theta']:.3g}"})
    from rk4h.validation.stability._common import FREQUENCY_RATIO, SWEEP_NAMES, stiffest_index

    for study, col in (("stiffness", "ratio"), ("mass_ratio", "mu")):
        pts = [r for r in rows if r["study"] == study and r["quantity"] == "nfev_at_error"]
        for sc in dict.fromkeys(r["scene"] for r in pts):
            mine = [r for r in pts if r["scene"] == sc]
            ratio = {r[col]: r["stiffness_ratio"] for r in mine if math.isfinite(r.get("stiffness_ratio", math.nan))}
            if not ratio:
                continue
            xs = list(ratio)
            x = xs[stiffest_index(xs, [ratio[k] for k in xs])]  # the point the study's finding and caption quote
            at = {r["solver"]: r for r in mine if r[col] == x}
            m = method.get(sc, next(iter(at)))
            ok = {k: v for k, v in at.items() if v["status"] == "ok"}
            if m not in ok or len(ok) < 2:
                continue
            best = min((k for k in ok if k != m), key=lambda k: ok[k]["measured"])
            out.append({"scene": sc, "limit": f"cost at {FREQUENCY_RATIO} {ratio[x]:.3g}",
                        "value": f"{m} {ok[m]['measured']:.3g} RHS calls vs {best} {ok[best]['measured']:.3g}",
                        "detail": f"{SWEEP_NAMES[col]} = {x:g}, target {ok[m]['target_error']:g}"})
    return out


def _figure_lines(results, out_dir) -> list[str]:
    """The figures section: each figure kind's reading guide once
    (``rk4h.validation.figures.GENERIC_CAPTIONS``, in the order kinds first
    appear), then per scene one line per figure with its own sentence."""
    from rk4h.validation.figures import GENERIC_CAPTIONS

    per_scene, kinds = [], {}
    for r in results:
        drawn = getattr(r, "drawn", None)
        drawn = drawn if drawn is not None else r.figures
        if drawn:
            per_scene.append((r.scene, drawn))
            for _, sentence in drawn:
                kind = getattr(sentence, "kind", None)
                if kind in GENERIC_CAPTIONS:
                    kinds.setdefault(kind, GENERIC_CAPTIONS[kind])
    lines = []
    if kinds:
        lines += ["### How to read each kind of figure", ""]
        lines += [f"- **{kind}**: {guide}" for kind, guide in kinds.items()]
        lines.append("")
    for scene, drawn in per_scene:
        lines += [f"### {scene}", ""]
        for path, sentence in drawn:
            rel = Path(path).relative_to(out_dir) if Path(path).is_absolute() else Path(path)
            kind = getattr(sentence, "kind", None)
            lines.append(f"- [{Path(path).name}]({rel.as_posix()})" + (f" ({kind})" if kind else "")
                         + f": {sentence}")
        lines.append("")
    return lines


_NO_LOAD = object()  # write_index called without a timing context


def write_index(out_dir, *, results, tables, table_paths, failures, findings, mode, repeats,
                seconds, n_scenes=None, timing=None, stability_methods=None, load=_NO_LOAD) -> Path:
    """Write ``index.md``: the trust table, the limits and the failures first;
    then findings, tables, figures, errata, versions.

    ``stability_methods``: scene -> the method its stability study is about
    (:func:`limits_rows`). ``load``: the timing context
    (:func:`rk4h.validation.timing_context.load_context`; None: no timed run),
    said in the header and the environment section; not given: not said."""
    from rk4h.validation import timing_context

    out_dir = Path(out_dir)
    lines = ["# RK4 validation report", ""]
    lines.append(f"Mode: **{mode}**, {n_scenes if n_scenes is not None else len(results)} scene(s), wall time {seconds:.0f} s. Each timed run is "
                 f"the median of {repeats} repeat(s) (runs longer than 0.1 s: one); compile time (heyoka JIT, numba) is kept apart in "
                 f"`compile_s`. Errors are measured against exact modal solutions (linear models) or "
                 f"heyoka in quadruple precision (nonlinear models)."
                 + (f" Timed runs: {timing}." if timing else "")
                 + (" " + timing_context.sentence(load) if load is not _NO_LOAD else ""))
    lines.append("")
    trust = trust_lines(tables.get("cheapest"))
    if trust:
        lines += ["## Can the method under test be trusted here, and is it the cheapest?", "",
                  "Per scene and target relative error (error_max / max |y_ref| over the scene's horizon): the "
                  "step the method needs (from its error constant C h^p, fitted only on runs that show the order p, "
                  "so not limited to the scene's step list; else between the two runs that bracket the target; "
                  "\"no h (no asymptotic fit)\" when the runs show neither: `rk4h advise SCENE "
                  "--target T` then halves the step until it brackets the target; capped at 0.9 of its stability limit; "
                  "\"no h (round-off)\" where sqrt(n) eps exceeds the target), run at that step to confirm it "
                  "(\"measured E\": the run's error met the target; \"predicted, unconfirmed\": no run of the "
                  "method met it, so it wins nothing), its right-hand-side calls, and the verdicts against the "
                  "cheapest other run that reached the target (the references run tighter where none did): "
                  "**calls** (deterministic; bold only for a measured winner; equal counts: `tie`), time "
                  "amortized over many runs (compile excluded) and, where it differs, for one run (compile and "
                  "start-up included). A time verdict is `tie` unless the medians differ 3x and the repeats do "
                  "not overlap"
                  + (", and every one between two measured sides is `tie` here: the load average exceeded the "
                     "CPUs during the timed runs (see the header)" if load is not _NO_LOAD and timing_context.is_loaded(load) else "")
                  + ". `unmeasured`: no run of any method reached the target. Details: "
                  "[cheapest.csv](cheapest.csv).", ""]
        lines += trust
        lines.append("")
    limits = limits_rows(tables.get("stability"), stability_methods)
    if limits:
        lines += ["## Limits: stability, round-off, long horizons, stiffness", ""]
        lines += _md_table(["scene", "limit", "value", "detail"], limits)
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
    if table_paths:
        lines += ["Each table is also written as `NAME.parquet` (typed columns); [columns.json](columns.json) "
                  "gives every column's unit, dtype and description.", ""]
    for name, path in table_paths.items():
        lines.append(f"- [{path.name}]({path.name}): {DESCRIPTIONS.get(name, '')}")
    lines += ["", "## Figures", ""]
    lines += _figure_lines(results, out_dir)
    lines += ["## Errata of the thesis", "",
              "Printed values beside the values the harness computes (`rk4h.references.errata`, the same "
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
    if load is not _NO_LOAD:
        lines += timing_context.environment_lines(load)
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
