"""Reproducibility: two runs of the runner (separate processes, different hash
seeds, each computing its own quadruple-precision reference) write
byte-identical CSVs once the timing columns are dropped, and the report records
the versions of the numerical stack and the machine."""
import io
import os
import subprocess
import sys
from pathlib import Path

import pandas as pd
import pytest

from rk4h.validation import report

from _scenes import one_mass

REPO = Path(__file__).resolve().parent.parent
# Two full runs in fresh processes with fresh references (about 15 s): in the
# slow set. The default set checks rerun identity through the resume test
# (tests/test_pipeline.py: a resumed run against an uninterrupted one), the Dask
# test (a cluster run against a local one) and tests/test_stability_units.py.
pytestmark = pytest.mark.slow

SCENES = {
    "det-a": one_mass("det-a", solvers='["rk4", "dop853", "cvode-bdf", "heyoka"]',
                      outputs='["state", "energy", "convergence", "work_precision", "modes"]'),
    "det-b": """
name = "det-b"
model = "pendulums"
[params]
m = 1.0
length = 1.0
g = 9.81
k = 2.0
linear = false
[initial]
x = [0.3, 0.0]
v = [0.0, 0.0]
[run]
t_end = 1.0
h = [0.02, 0.01]
tolerances = [1e-7, 1e-9]
solvers = ["rk4", "symplectic-euler", "cvode-adams", "dop853"]
outputs = ["state", "energy", "work_precision"]
""",
}


@pytest.fixture(scope="module")
def two_runs(tmp_path_factory):
    d = tmp_path_factory.mktemp("det")
    paths = []
    for name, text in SCENES.items():
        paths.append(d / f"{name}.toml")
        paths[-1].write_text(text)
    outs, procs = [], []
    for seed in ("1", "2"):  # the two runs at once, one per core
        out = d / f"run{seed}"
        args = [a for p in paths for a in ("--scene", str(p))]
        procs.append(subprocess.Popen(
            [sys.executable, "validation/run_all.py", *args, "--out", str(out), "--repeats", "1", "--no-figures",
             "--workers", "1"],
            cwd=REPO, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
            # each run computes its own reference (no shared truth cache)
            env={**os.environ, "PYTHONHASHSEED": seed, "MPLBACKEND": "Agg", "RK4H_CACHE": str(d / f"cache{seed}")}))
        outs.append(out)
    for p in procs:
        stdout, stderr = p.communicate(timeout=300)
        assert p.returncode == 0, stdout + stderr
    return outs


def _deterministic_csv(path: Path) -> bytes:
    """The CSV without its timing columns, as bytes (tables built on timings: nothing)."""
    name = path.stem
    timing = report.TIMING.get(name, set())
    if name in report.TIMING and timing is None:
        return b""
    df = pd.read_csv(path, dtype=str, keep_default_na=False)  # the text as written, no re-parsing
    buf = io.StringIO()
    df.drop(columns=sorted(timing or ())).to_csv(buf, index=False, lineterminator="\n")
    return buf.getvalue().encode()


def test_both_runs_write_the_same_tables(two_runs):
    a, b = two_runs
    assert sorted(p.name for p in a.glob("*.csv")) == sorted(p.name for p in b.glob("*.csv"))
    assert {"accuracy.csv", "convergence.csv", "energy.csv", "work_precision.csv",
            "modes.csv"} <= {p.name for p in a.glob("*.csv")}


@pytest.mark.parametrize("table", ["accuracy", "convergence", "energy", "work_precision", "modes"])
def test_deterministic_columns_are_byte_identical(two_runs, table):
    a, b = two_runs
    x, y = _deterministic_csv(a / f"{table}.csv"), _deterministic_csv(b / f"{table}.csv")
    assert x and x == y
    if table == "accuracy":  # the comparison covers every solver of both scenes
        acc = pd.read_csv(a / "accuracy.csv")
        assert len(acc) == 16 and set(acc.status) == {"ok"}


def test_timing_columns_are_the_only_ones_left_out(two_runs):
    # guards the comparison above: the dropped columns are exactly report.TIMING's
    a, _ = two_runs
    acc = pd.read_csv(a / "accuracy.csv")
    kept = set(acc.columns) - report.TIMING["accuracy"]
    assert {"error_max", "error_final", "energy_drift_max", "nfev", "n_steps", "status"} <= kept


@pytest.mark.parametrize("label", ["python", "numpy", "scipy", "scikit-sundae", "heyoka", "numba", "machine",
                                   "processor", "BLAS"])
def test_report_records_versions_and_machine(two_runs, label):
    import importlib.metadata as md
    import platform

    index = (two_runs[0] / "index.md").read_text()
    env = index[index.index("## Environment"):]
    line = next((ln for ln in env.splitlines() if ln.startswith(f"- {label}: ")), None)
    assert line is not None, env
    value = line.split(": ", 1)[1]
    expected = {"python": platform.python_version(), "machine": platform.machine()}
    if label in ("numpy", "scipy", "scikit-sundae", "heyoka", "numba"):
        expected[label] = md.version(label)
    if label in expected:
        assert expected[label] in value
    else:
        assert value and value != "unknown"
