"""Test-wide settings. ``run_all`` subprocesses started by the tests run
in-process (``RK4H_WORKERS=1``) unless a test passes ``--workers``: a spawned
pool's start-up (a fresh interpreter per worker, numba and heyoka imports)
costs seconds per run and tests nothing a small scene needs. The tests of the
pool itself (``test_kill.py``, ``test_pipeline.py``, ``test_dask.py``) ask for
it explicitly."""
import os

os.environ.setdefault("RK4H_WORKERS", "1")
