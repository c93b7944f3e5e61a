"""benchmarks/bench_integer_powers.py times numpy's integer powers against
the products rk4h.expr prints and counts where the roundings differ. Timings
are not asserted; the script checks that its products are lambdify's."""
import pathlib
import re
import subprocess
import sys

ROOT = pathlib.Path(__file__).resolve().parents[1]
SCRIPT = ROOT / "benchmarks" / "bench_integer_powers.py"


def test_prints_both_powers_for_every_sign_and_the_spring_energy():
    proc = subprocess.run([sys.executable, str(SCRIPT), "--size", "2000", "--repeats", "3"], cwd=ROOT,
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    rows = re.findall(r"^([34])  (positive|mixed|negative)\s+[0-9.]+\s+[0-9.]+\s+[0-9.]+\s+([0-9.]+)\s+([0-9.]+)$",
                      proc.stdout, flags=re.M)
    assert {(n, b) for n, b, _, _ in rows} == {(n, b) for n in "34" for b in ("positive", "mixed", "negative")}
    # binary powering rounds twice: it cannot equal a (nearly) correctly rounded pow everywhere
    assert all(float(pr) > 0.05 for _, _, _, pr in rows)
    assert re.search(r"^FPUT spring energy, one block of 5 x 16384: numpy \*\* [0-9.]+ ns, products [0-9.]+ ns",
                     proc.stdout, flags=re.M)
