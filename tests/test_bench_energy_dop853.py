"""Two benchmark commands (energies in blocks, DOP853 runs parting) run at tiny sizes and print
what docs/performance.md quotes from them; timings are not asserted."""
import pathlib
import re
import subprocess
import sys

ROOT = pathlib.Path(__file__).resolve().parents[1]
NUMBER = r"[0-9.]+(e[-+]?[0-9]+)?"


def _run(*args):
    proc = subprocess.run([sys.executable, *map(str, args)], cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    return proc.stdout


def test_energy_blocks_benchmark_reports_the_ratio_the_peaks_and_bit_equality():
    out = _run(ROOT / "benchmarks" / "bench_energy_blocks.py", "--scenes", "energy-henon-heiles", "--rounds", "1")
    (line,) = [s for s in out.splitlines() if s.startswith("energy-henon-heiles:")]
    assert re.search(rf"one call / blocks = {NUMBER};", line)
    assert re.search(rf"temporaries' peak {NUMBER} MiB in blocks, {NUMBER} MiB in one call", line)
    assert line.endswith("equal to the bit: True")


def test_dop853_parting_prints_both_implementations_spread():
    out = _run(ROOT / "benchmarks" / "dop853_parting.py", "--ratios", "1e2", "--rtols", "1e-5", "--ulps", "1")
    lines = out.splitlines()
    assert lines[0].startswith("stiff chain, ratio 100 (omega_max/omega_min 40.8")
    for name in ("scipy", "compiled loop"):
        (line,) = [s for s in lines if s.strip().startswith(name + " ")]
        m = re.search(rf"min ({NUMBER}), median ({NUMBER}), max ({NUMBER}) \(({NUMBER})x\)", line)
        assert m, line
        lo, hi = float(m.group(1)), float(m.group(5))
        assert 0 < lo <= hi < 1e-4  # errors of a run at rtol 1e-5 against the modal solution
        assert len(re.findall(r"\(\d+\)", line)) == 2  # --ulps 1: both runs listed with their RHS calls
