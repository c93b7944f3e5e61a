"""The benchmark command runs (tiny sizes) and prints every ratio line.

Timings are not asserted (the machine is shared); only that the command
finishes and reports each figure issue 5 asks for.
"""
import pathlib
import re
import subprocess
import sys

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[1]
BENCH = ROOT / "benchmarks" / "bench_rk4.py"
NUMBER = r"[0-9]+(\.[0-9]+)?(e[-+]?[0-9]+)?"


@pytest.fixture(scope="module")
def tiny_output():
    proc = subprocess.run([sys.executable, str(BENCH), "--tiny"], cwd=ROOT, capture_output=True,
                          text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    return proc.stdout


@pytest.mark.parametrize("label", [
    r"ratio python_loop/fast_rk4 \(2-DOF case 1, \d+ steps\):",
    r"ratio rk4/dop853 wall time at error_max <= 1e-06:",
    r"ratio rk4/heyoka wall time at error_max <= 1e-06:",
    r"ratio chain time/step/mass max/min \(N = 10\.\.\d+\):",
    r"exponent chain cost per step ~ N\^p: p =",
    r"ratio numpy_batch/compiled per trajectory-step:",
])
def test_tiny_benchmark_prints_ratio(tiny_output, label):
    assert re.search(rf"^{label} {NUMBER}", tiny_output, flags=re.MULTILINE), tiny_output


def test_tiny_benchmark_reports_repeats_and_compile_time_apart(tiny_output):
    assert re.search(r"medians of \d+ repeats", tiny_output)
    assert re.search(rf"numba compile / cache load \(apart, not in any timing\): {NUMBER} s", tiny_output)
    assert re.search(rf"heyoka .* JIT {NUMBER} s apart", tiny_output)
