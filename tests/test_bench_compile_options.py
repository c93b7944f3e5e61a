"""benchmarks/bench_compile_options.py: the two array-loop designs kept for the
record (benchmarks/_loop_variants.py) give the package's loop's numbers bit for
bit, or their figures in docs/performance.md would compare different arithmetic.
Each run is a cold compile (4-10 s) or at least numba's import: slow set. Timings are not asserted."""
import pathlib
import re
import subprocess
import sys

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[1]
SCRIPT = ROOT / "benchmarks" / "bench_compile_options.py"
LINE = re.compile(r"^(\S+) N=(\d+) (\S+): compile\+1run [0-9.]+ s CPU, [0-9.]+ ns/step, y_end ([0-9a-f]{10})$")


def _digest(method, n, variant, *extra):
    proc = subprocess.run([sys.executable, str(SCRIPT), method, str(n), variant, *extra], cwd=ROOT,
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    m = LINE.match(proc.stdout.strip().replace(" fput:", ":").replace(" net:", ":"))
    assert m and m.group(3) == variant, proc.stdout
    return m.group(4)


@pytest.mark.slow
@pytest.mark.parametrize("method", ["yoshida4", "rk4"])  # velocity-first stages with FSAL; a classical method
def test_each_design_gives_the_package_loops_numbers(method):
    base = _digest(method, 3, "base")
    assert [_digest(method, 3, v) for v in ("one_call_site", "as_data", "as_data_inline")] == [base] * 3


@pytest.mark.slow
def test_a_called_slope_gives_the_same_numbers_on_an_fput_chain():
    # the variant whose speed docs/performance.md compares (twenty-second round)
    base = _digest("yoshida4", 3, "base", "fput")
    assert _digest("yoshida4", 3, "slope_call", "fput") == base
    assert base != _digest("yoshida4", 3, "base")  # the FPUT chain is another model


@pytest.mark.slow
def test_the_straight_line_variant_gives_the_array_loops_numbers():
    # docs/performance.md (twenty-second and twenty-third rounds) compares the two forms on 3-8 masses
    assert _digest("rk4", 4, "array", "fput") == _digest("rk4", 4, "base", "fput") == \
        _digest("rk4", 4, "straight_line", "fput")


@pytest.mark.slow
@pytest.mark.parametrize("n, variant", [(2, "nonrt"), (2, "nocfunc"), (2, "both"), (3, "noinline"),
                                        (3, "slope_call"), (3, "nocfunc_arr"), (3, "dense_call")])
def test_each_variant_edits_its_loop_and_keeps_the_numbers(n, variant):
    # an edit whose text is not in the loop is refused (exit 2), so a digest
    # here is that of the edited loop
    assert _digest("rk4", n, variant) == _digest("rk4", n, "base")


@pytest.mark.slow
def test_a_network_on_both_loop_forms_gives_the_same_numbers():
    assert _digest("rk4", 2, "base", "net") == _digest("rk4", 2, "array", "net")


@pytest.mark.slow
@pytest.mark.parametrize("argv, why", [
    (["rk4", "3", "nonrt"], "nonrt does not apply to the array loop of N=3"),
    (["rk4", "2", "noinline", "net"], "VARIANT one of"),
    (["rk4", "5", "straight_line", "net"], "straight_line: N must be <= 4, got 5"),
    (["rk4", "2", "as_data"], "as_data is an array loop: N must be >= 3, got 2"),
    (["rk4", "3", "no-such-design"], "VARIANT one of"),
    (["rk4", "9", "straight_line"], "straight_line: N must be <= 8, got 9"),
])
def test_bad_arguments_are_one_line_and_exit_2(argv, why):
    proc = subprocess.run([sys.executable, str(SCRIPT), *argv], cwd=ROOT, capture_output=True, text=True,
                          timeout=120)
    assert proc.returncode == 2 and why in proc.stderr and "Traceback" not in proc.stderr
