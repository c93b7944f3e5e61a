"""benchmarks/bench_compiled_fixed_runs.py prints, per wave packet and for the errata rows, both
ways' times, their ratio and whether the results are equal; the results must be. Timings are not asserted."""
import pathlib
import re
import subprocess
import sys

ROOT = pathlib.Path(__file__).resolve().parents[1]


def test_benchmark_prints_ratios_and_equal_results():
    proc = subprocess.run([sys.executable, str(ROOT / "benchmarks" / "bench_compiled_fixed_runs.py"), "--rounds", "1"],
                          cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    lines = proc.stdout.splitlines()
    packets = [s for s in lines if s.startswith("wave packet kp0 = ")]
    errata = [s for s in lines if s.startswith("errata_rows ")]
    assert len(packets) == 2 and len(errata) == 1, proc.stdout
    for line in packets + errata:
        assert re.search(r"generic [0-9.]+ s, compiled [0-9.]+ s, generic / compiled = [0-9.]+; equal: True$", line), line


def test_zero_rounds_is_refused():
    proc = subprocess.run([sys.executable, str(ROOT / "benchmarks" / "bench_compiled_fixed_runs.py"), "--rounds", "0"],
                          cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2 and "--rounds: must be at least 1, got 0" in proc.stderr
