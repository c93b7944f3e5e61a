"""One fresh ``--quick`` run of the work-precision scenes per test session,
shared by ``test_verdict.py`` (its ``cheapest.csv``) and
``test_reports_committed.py`` (its deterministic tables): the two used to make
one run each (about 30 s and 10 s on an idle 2-core machine).

The run is a process (``validation/run_all.py``) on the OpenBLAS kernel the
committed ``reports/index.md`` names (``OPENBLAS_CORETYPE``), so that its
DOP853 round-off is the committed report's; where this CPU cannot run that
kernel it runs on the default one and ``blas_skip`` says why (the committed
comparison skips; the verdict checks do not depend on the kernel).

Under pytest-xdist the workers share it through the session's base temporary
directory (made fresh by pytest for this session, so nothing in it was written
by anyone else): the first caller runs it under an exclusive file lock and
writes ``done.json`` only after the run ended with exit 0 or 1 and wrote
``index.md``; a later caller (same or other worker) takes the lock, reads
``done.json`` and uses the run only if it records the same command and the
files it names are there. Without ``fcntl`` (Windows) each worker makes its
own run.
"""
from __future__ import annotations

import json
import os
import re
import subprocess
import sys
from pathlib import Path

try:
    import fcntl
except ImportError:  # pragma: no cover - not POSIX
    fcntl = None

REPO = Path(__file__).resolve().parent.parent
COMMITTED = REPO / "reports"


def kernel(index_md: Path):
    """The OpenBLAS kernel a report's environment section names, or None."""
    m = re.search(r"^- BLAS: .*, kernel (\S+)$", index_md.read_text(), flags=re.M) if index_md.exists() else None
    return m.group(1) if m else None


def work_precision_scenes():
    """The quick scenes with a work-precision output (sorted names)."""
    from rk4h.validation.scenes import load_scenes

    return sorted(s.name for s in load_scenes(quick=True) if "work_precision" in s.outputs)


def _probe(committed):
    """None where this CPU runs OpenBLAS kernel ``committed``, else why not."""
    env = {**os.environ, "OPENBLAS_CORETYPE": committed}
    # a kernel this CPU lacks the instructions for may kill the process: probe it in one
    probe = subprocess.run([sys.executable, "-c", "import numpy as np; from rk4h.validation import report; "
                            "a = np.ones((64, 64)); a @ a @ np.ones(64); print(report.blas_kernel())"],
                           cwd=REPO, env=env, capture_output=True, text=True, timeout=120)
    if probe.returncode == 0 and probe.stdout.strip() == committed:
        return None
    return (f"reports/ was written on OpenBLAS kernel {committed}, which this CPU does not run "
            f"(exit {probe.returncode}, kernel {probe.stdout.strip() or '?'}): its DOP853 round-off "
            "differs; regenerate reports/ here to compare")


def _run(where: Path, names) -> dict:
    committed = kernel(COMMITTED / "index.md")
    why = _probe(committed) if committed else None
    env = {**os.environ, "MPLBACKEND": "Agg"}
    if committed and why is None:
        env["OPENBLAS_CORETYPE"] = committed
    out = where / "out"
    argv = ["validation/run_all.py", "--quick", *(a for n in names for a in ("--scene", n)), "--out", str(out),
            "--repeats", "1", "--no-figures", "--workers", "1"]
    p = subprocess.run([sys.executable, *argv], cwd=REPO, env=env, capture_output=True, text=True, timeout=600)
    assert p.returncode in (0, 1) and (out / "index.md").exists(), p.stdout + p.stderr
    return {"argv": argv, "names": list(names), "returncode": p.returncode, "stdout": p.stdout,
            "committed_kernel": committed, "blas_skip": why, "out": str(out)}


def shared_quick_run(tmp_path_factory) -> dict:
    """The session's quick run of the work-precision scenes (made on first call).

    Returns a dict: ``out`` (Path of the report), ``names`` (the scenes run),
    ``returncode`` (0 or 1), ``stdout``, ``committed_kernel`` (the kernel
    ``reports/index.md`` names, or None) and ``blas_skip`` (None, or why the
    run is not on that kernel).
    """
    names = work_precision_scenes()
    base = tmp_path_factory.getbasetemp()
    shared = fcntl is not None and os.environ.get("PYTEST_XDIST_WORKER")
    root = (base.parent if shared else base) / "shared-quick-work-precision"
    root.mkdir(exist_ok=True)
    done = root / "done.json"
    with open(root / "lock", "w") as lock:
        if fcntl is not None:
            fcntl.flock(lock, fcntl.LOCK_EX)   # released when the file closes
        rec = json.loads(done.read_text()) if done.exists() else None
        if rec is None or rec["names"] != names or not (Path(rec["out"]) / "index.md").exists():
            assert not (root / "out").exists(), f"{root / 'out'} exists without a complete record: not reused"
            rec = _run(root, names)
            done.write_text(json.dumps(rec))
    return {**rec, "out": Path(rec["out"])}
