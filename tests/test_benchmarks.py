"""The benchmark command runs (tiny sizes) and prints every ratio line.

Timings are not asserted (the machine is shared); only that the command
finishes and reports each figure issue 5 asks for, and that its correctness
checks hold: the generated RK4 loops give the final states of the
hand-written reference loops bit for bit, and DOP853/CVODE give the same
``nfev`` and ``y`` on the compiled right-hand side as on ``model.rhs``.
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
    r"ratio generated/tight ns/step \(2-DOF case 1\):",
    r"ratio generated/tight per mass-step \(chain N = 10\):",
    r"ratio generated/tight per mass-step \(chain N = 1000\):",
    r"ratio dop853 wall time compiled/numpy RHS:",
    r"ratio cvode-adams wall time compiled/numpy RHS:",
    r"ratio cvode-bdf wall time compiled/numpy RHS:",
    r"time compiled_rhs\(model\)\(t, y\) per call:",
    r"ratio rhs per call numpy/compiled:",
])
def test_tiny_benchmark_prints_ratio(tiny_output, label):
    assert re.search(rf"^{label} {NUMBER}", tiny_output, flags=re.MULTILINE), tiny_output


def test_tiny_benchmark_reports_repeats_and_compile_time_apart(tiny_output):
    assert re.search(r"medians of \d+ repeats", tiny_output)
    assert re.search(rf"numba compile / cache load \(apart, not in any timing\): {NUMBER} s", tiny_output)
    assert re.search(rf"heyoka .* JIT {NUMBER} s apart", tiny_output)


CHECKS = [
    r"check 2-DOF final state generated == tight \(bit-identical\)",
    r"check chain final states generated == tight \(bit-identical, N = 10\.\.1000\)",
] + [
    rf"check {solver} compiled vs numpy RHS same {what}"
    for solver in ("dop853", "cvode-adams", "cvode-bdf")
    for what in (r"nfev \(\d+ vs \d+\)", r"y to 1e-12 relative \(max relative difference \S+\)")
]


@pytest.mark.parametrize("label", CHECKS)
def test_tiny_benchmark_check_holds(tiny_output, label):
    match = re.search(rf"^{label}: (True|False)$", tiny_output, flags=re.MULTILINE)
    assert match, f"no line matching {label!r} in:\n{tiny_output}"
    assert match.group(1) == "True", match.group(0)


def test_tiny_benchmark_every_check_line_is_true(tiny_output):
    checks = [line for line in tiny_output.splitlines() if line.startswith("check ")]
    assert len(checks) == len(CHECKS), checks
    assert all(line.endswith(": True") for line in checks), checks


def test_references_ran_on_the_rhs_they_were_given(tiny_output):
    """Each reference ran once on the compiled and once on the numpy right-hand side."""
    for solver in ("dop853", "cvode-adams", "cvode-bdf"):
        assert re.search(rf"^  {solver} +compiled RHS .*rhs used: compiled / numpy; status ok / ok\)$",
                         tiny_output, flags=re.MULTILINE), tiny_output


@pytest.mark.slow
def test_heyoka_startup_benchmark_prints_its_three_medians():
    proc = subprocess.run([sys.executable, str(ROOT / "benchmarks" / "bench_heyoka_startup.py"), "--rounds", "1"],
                          cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    for label in ("first compile in a process:", "the same system compiled again after it:",
                  "first compile after taylor.start_up:"):
        assert re.search(re.escape(label) + r"\s+" + NUMBER + r"$", proc.stdout, flags=re.M), (label, proc.stdout)
