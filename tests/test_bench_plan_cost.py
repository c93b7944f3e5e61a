"""benchmarks/plan_cost.py: record times by purpose and solver, and with --ledger every
integration of an in-process plan; timings are not asserted."""
import pathlib
import re
import subprocess
import sys

ROOT = pathlib.Path(__file__).resolve().parents[1]


def _run(*args, code=0):
    proc = subprocess.run([sys.executable, str(ROOT / "benchmarks" / "plan_cost.py"), *args],
                          cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert proc.returncode == code, proc.stderr
    return proc


def test_ledger_counts_the_integrations_of_the_specs_run():
    out = _run("methods-2dof", "--purposes", "order", "--workers", "1", "--ledger").stdout
    m = re.search(r"^runs: (\d+) specs", out, flags=re.M)
    (ledger,) = [s for s in out.splitlines() if s.startswith("ledger: ")]
    n = int(re.match(r"ledger: (\d+) integrations, [0-9.]+ s CPU$", ledger).group(1))
    # each order spec integrates at least once; only order specs ran
    assert m and n >= int(m.group(1)) > 0
    rows = re.findall(r"^ +[0-9.]+ s +(\d+) x (\S+) (\S+)$", out, flags=re.M)
    assert rows and all(purpose == "order" for _, purpose, _ in rows)
    assert re.search(r"^timed rows \(purpose run\): first runs 0\.0 s CPU, timing repeats 0\.0 s CPU$", out, flags=re.M)
    assert re.search(r"^same inputs in more than one spec: \d+ integrations, [0-9.]+ s CPU beyond one run each$",
                     out, flags=re.M)


def test_ledger_with_workers_is_refused_in_one_line():
    proc = _run("methods-2dof", "--workers", "2", "--ledger", code=2)
    assert "--ledger: needs --workers 1" in proc.stderr and "Traceback" not in proc.stderr
