"""benchmarks/bench_axis_boundaries.py prints every built-in method's exact
imaginary-axis boundary with its time; the values must be the shipped
table's for the geometric tableaux. Timings are not asserted. About 2 s: slow set."""
import pathlib
import re
import subprocess
import sys

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[1]
SCRIPT = ROOT / "benchmarks" / "bench_axis_boundaries.py"


@pytest.mark.slow
def test_every_method_is_worked_out_and_the_geometric_ones_match_the_table():
    from rk4h import geometric as G
    from rk4h.methods import METHODS

    proc = subprocess.run([sys.executable, str(SCRIPT)], cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    got = dict(re.findall(r"^(\S+)\s+[0-9.]+ s  imaginary-axis boundary (\S+)$", proc.stdout, flags=re.M))
    assert set(got) == set(METHODS)
    for name, bound in G._IMAGINARY_AXIS_BOUNDS.items():
        assert float(got[name]) == bound, name
    assert re.search(r"^total [0-9.]+ s CPU$", proc.stdout, flags=re.M)


@pytest.mark.slow
def test_an_argument_is_refused_in_one_line():
    proc = subprocess.run([sys.executable, str(SCRIPT), "--rounds", "3"], cwd=ROOT, capture_output=True, text=True,
                          timeout=60)
    assert proc.returncode == 2 and "takes no arguments, got '--rounds 3'" in proc.stderr
