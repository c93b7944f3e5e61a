"""The committed ``reports/`` is the output of the current code: the quick
scenes' deterministic tables are regenerated and compared with it (timing
columns excluded), and the errata numbers are the ones the tables compute.

The regeneration runs on the committed report's OpenBLAS kernel (its
``index.md`` names it; ``OPENBLAS_CORETYPE`` forces it): numpy's dot
products, hence scipy's DOP853 steps, round differently on another kernel
(``rk4h.validation.report.blas_kernel``). Measured here on the quick scenes:
Haswell against SkylakeX kernels move DOP853's relative errors by up to
1.2e-13 and its observed orders by 4.5e-6, nothing else (in the full
report, where the accepted steps change, up to 53%: see the README).

When this fails after a change, regenerate: ``python validation/run_all.py``.
"""
import math
import os
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from rk4h.validation import report
from rk4h.validation.scenes import load_scenes

REPO = Path(__file__).resolve().parent.parent
COMMITTED = REPO / "reports"
#: Deterministic tables and the timing columns left out of the comparison.
COMPARED = {name: cols or set() for name, cols in report.TIMING.items() if cols is not None}
COMPARED.update({name: set() for name in report.COLUMNS if name not in report.TIMING})
#: Same BLAS kernel: bit-identical. Allowance for another CPU's round-off (e.g. FMA in heyoka's JIT).
RTOL = 1e-9


#: The default suite regenerates one quick scene (the thesis' 2-DOF case 1, ~20 s);
#: ``-m slow`` regenerates every quick scene (~60 s).
DEFAULT_SCENES = ("thesis-2dof-case1",)


def _kernel(index_md: Path):
    """The OpenBLAS kernel a report's environment section names, or None."""
    m = re.search(r"^- BLAS: .*, kernel (\S+)$", index_md.read_text(), flags=re.M) if index_md.exists() else None
    return m.group(1) if m else None


def _regenerate(tmp_path_factory, only=None):
    out = tmp_path_factory.mktemp("quick") / "out"
    # the stability study's own scenes make only stability.csv, which holds timings: not compared
    names = [s.name for s in load_scenes(quick=True) if "stability" not in s.outputs and (only is None or s.name in only)]
    assert names, "no quick scene to regenerate"
    committed = _kernel(COMMITTED / "index.md")
    env = {**os.environ, "MPLBACKEND": "Agg"}
    if committed:
        env["OPENBLAS_CORETYPE"] = committed
        # a kernel this CPU lacks the instructions for may kill the process: probe it first
        probe = subprocess.run([sys.executable, "-c", "import numpy as np; from rk4h.validation import report; "
                                "a = np.ones((64, 64)); a @ a @ np.ones(64); print(report.blas_kernel())"],
                               cwd=REPO, env=env, capture_output=True, text=True, timeout=120)
        if probe.returncode != 0 or probe.stdout.strip() != committed:
            pytest.skip(f"reports/ was written on OpenBLAS kernel {committed}, which this CPU does not run "
                        f"(exit {probe.returncode}, kernel {probe.stdout.strip() or '?'}): its DOP853 round-off "
                        "differs; regenerate reports/ here to compare")
    p = subprocess.run([sys.executable, "validation/run_all.py", "--quick", *(a for n in names for a in ("--scene", n)),
                        "--out", str(out), "--repeats", "1", "--no-figures", "--workers", "1"],
                       cwd=REPO, env=env, capture_output=True, text=True, timeout=600)
    assert p.returncode in (0, 1) and (out / "index.md").exists(), p.stdout + p.stderr
    failures = [line for line in p.stdout.splitlines() if line.startswith("FAILED")]
    assert _kernel(out / "index.md") == committed, "the regenerated report ran on another BLAS kernel"
    return out, set(names), failures


@pytest.fixture(scope="module")
def regenerated(tmp_path_factory):
    # the session's fresh quick run of the work-precision scenes (which include DEFAULT_SCENES), shared with
    # test_verdict.py (tests/_quick_run.py); its tables are compared for DEFAULT_SCENES, its expectations all checked
    from _quick_run import shared_quick_run

    if not set(DEFAULT_SCENES) <= set(_quick_run_names()):
        return _regenerate(tmp_path_factory, DEFAULT_SCENES)
    run = shared_quick_run(tmp_path_factory)
    if run["blas_skip"]:
        pytest.skip(run["blas_skip"])
    out = run["out"]
    assert _kernel(out / "index.md") == run["committed_kernel"], "the regenerated report ran on another BLAS kernel"
    failures = [line for line in run["stdout"].splitlines() if line.startswith("FAILED")]
    return out, set(DEFAULT_SCENES), failures


def _quick_run_names():
    from _quick_run import work_precision_scenes

    return work_precision_scenes()


@pytest.fixture(scope="module")
def regenerated_all(tmp_path_factory):
    return _regenerate(tmp_path_factory)


def _read(path):
    return pd.read_csv(path, keep_default_na=True)


def _same(a: pd.Series, b: pd.Series) -> np.ndarray:
    if pd.api.types.is_numeric_dtype(a) and pd.api.types.is_numeric_dtype(b):
        x, y = a.to_numpy(float), b.to_numpy(float)
        return (np.isnan(x) & np.isnan(y)) | np.isclose(x, y, rtol=RTOL, atol=0.0)
    return (a.fillna("").astype(str).to_numpy() == b.fillna("").astype(str).to_numpy())


@pytest.mark.parametrize("table", sorted(COMPARED))
def test_committed_tables_match_regenerated_quick_run(regenerated, table):
    _compare(regenerated, table)


@pytest.mark.slow
@pytest.mark.parametrize("table", sorted(COMPARED))
def test_committed_tables_match_every_regenerated_quick_scene(regenerated_all, table):
    _compare(regenerated_all, table)


def _compare(regenerated, table):
    out, names, _ = regenerated
    new_path = out / f"{table}.csv"
    if not new_path.exists():
        pytest.skip(f"the quick scenes produce no {table}.csv")
    assert (COMMITTED / f"{table}.csv").exists(), "reports/ is missing: run python validation/run_all.py"
    new = _read(new_path)
    new = new[new["scene"].isin(names)].reset_index(drop=True)   # a shared run may hold more scenes
    old = _read(COMMITTED / f"{table}.csv")
    old = old[old["scene"].isin(names)].reset_index(drop=True)
    if new.empty and old.empty:
        pytest.skip(f"the compared scenes have no {table}.csv rows")
    # sweep parameter columns (empty for the quick scenes, which sweep nothing)
    old = old[[c for c in old.columns if c in new.columns or old[c].notna().any()]]
    cols = [c for c in new.columns if c not in COMPARED[table]]
    assert list(old.columns) == list(new.columns), (
        f"columns changed (new: {[c for c in new.columns if c not in old.columns]}, dropped: "
        f"{[c for c in old.columns if c not in new.columns]}): regenerate reports/")
    assert len(old) == len(new), f"{table}: {len(new)} rows now, {len(old)} committed: regenerate reports/"
    for c in cols:
        same = _same(new[c], old[c])
        bad = np.flatnonzero(~same)
        assert same.all(), (f"{table}.csv column {c} differs from the committed report at rows "
                            f"{bad[:5].tolist()}: now {new[c].iloc[bad[:3]].tolist()}, committed "
                            f"{old[c].iloc[bad[:3]].tolist()}; regenerate reports/")


def test_quick_run_meets_every_expectation(regenerated):
    assert regenerated[2] == []


def _errata(quantity_start):
    return [r for r in report.errata_rows() if str(r["quantity"]).startswith(quantity_start)]


@pytest.mark.parametrize("where", ["regenerated", "committed"])
@pytest.mark.parametrize("case, scene", [("case 1", "thesis-2dof-case1"), ("case 3", "thesis-2dof-case3")])
def test_errata_frequencies_are_the_tables_frequencies(regenerated, where, case, scene):
    # Erratum 1: Table 4.3 prints omega^2; the corrected omega must be the value modes.csv holds
    # (the same eigenproblem), and the printed number its square.
    path = (regenerated[0] if where == "regenerated" else COMMITTED) / "modes.csv"
    modes = _read(path)
    rows = modes[modes["scene"] == scene]
    if rows.empty:
        pytest.skip(f"{scene} is not in the {where} tables")
    omega = rows.sort_values("mode")["omega_rad_s"].to_numpy()
    errata = _errata(f"Table 4.3 {case}: omega_")
    assert len(errata) == 2
    for j, row in enumerate(sorted(errata, key=lambda r: r["quantity"])):
        assert row["corrected"] == pytest.approx(omega[j], rel=1e-12)
        assert row["thesis"] == pytest.approx(omega[j] ** 2, abs=5e-5)  # printed to 4 decimals


def test_errata_table_in_committed_index_is_the_computed_one():
    index = (COMMITTED / "index.md").read_text()
    section = index[index.index("## Errata"):]
    for row in report.errata_rows():
        assert report._md_cell(row["corrected"]) in section, row


def test_table_4_6_frequency_is_the_oscillator_scenes_frequency():
    modes = _read(COMMITTED / "modes.csv")
    iso = modes[modes["scene"] == "oscillator-iso-delta-pi4"]["omega_rad_s"].to_numpy()
    (row,) = _errata("Table 4.6 omega")
    assert iso == pytest.approx([row["corrected"]] * 2, rel=1e-12)
    assert math.isclose(row["corrected"], math.sqrt(2 * 41.5 / 0.815), rel_tol=1e-15)


def test_blas_kernel_names_the_kernel_openblas_runs():
    """``OPENBLAS_CORETYPE`` forces the kernel the report names (Nehalem: the
    x86-64-v2 level numpy 2 requires, so every x86 CPU that runs numpy runs it)."""
    import platform

    if report.blas_kernel() is None or platform.machine() not in ("x86_64", "AMD64"):
        pytest.skip("numpy's BLAS here is not an x86 OpenBLAS that names its kernel")
    p = subprocess.run([sys.executable, "-c", "from rk4h.validation import report; print(report._blas())"], cwd=REPO,
                       env={**os.environ, "OPENBLAS_CORETYPE": "Nehalem"}, capture_output=True, text=True,
                       timeout=60)
    assert p.returncode == 0, p.stderr
    assert p.stdout.strip().endswith(", kernel Nehalem")
    assert _kernel(COMMITTED / "index.md") is not None, "reports/index.md names no BLAS kernel: regenerate reports/"
