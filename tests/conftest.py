"""Test-wide settings. ``run_all`` subprocesses started by the tests run
in-process (``RK4H_WORKERS=1``) unless a test passes ``--workers``: a spawned
pool's start-up (a fresh interpreter per worker, numba and heyoka imports)
costs seconds per run and tests nothing a small scene needs. The tests of the
pool itself (``test_kill.py``, ``test_pipeline.py``, ``test_dask.py``) ask for
it explicitly."""
import gc
import os
import sys

import pytest

os.environ.setdefault("RK4H_WORKERS", "1")

# Bytecode: with PYTHONDONTWRITEBYTECODE set (as on the shared development machine), every test session
# re-compiled the package's sources and pytest re-did its assertion rewriting of every test module, in each
# worker (about 10 s of a 17 s collection per worker, load 5) and in every process a test starts (about
# 0.25-0.8 s each). The test session writes Python's usual __pycache__ (ignored by git) for itself and for the
# processes it starts; outside the tests the setting is the user's.
if sys.dont_write_bytecode:
    sys.dont_write_bytecode = False
    os.environ.pop("PYTHONDONTWRITEBYTECODE", None)

#: Test modules holding the suite's longest tests (a fresh quick run, the process-level safety tests,
#: exact-arithmetic data checks, numba compiles; listed by hand from the times that
#: benchmarks/suite_durations.py prints). They are collected first, whole and in this order, so that under
#: pytest-xdist's work stealing (which hands each worker a contiguous share of the collection and steals
#: from the end of a share) they start at once on the first worker while the other runs the short tests,
#: and the run ends on short tests that both workers share out. test_verdict and test_reports_committed
#: stay adjacent: they share one quick run (tests/_quick_run.py), made once per session.
LONG_FIRST = ("test_verdict.py", "test_reports_committed.py", "test_startup.py", "test_kill.py",
              "test_output_safety.py", "test_dask.py", "test_runner.py", "test_benchmarks.py",
              "test_network_compiled.py", "test_fixed_cost_cache.py", "test_advise.py", "test_ensemble.py",
              "test_scene_facts.py", "test_captions_tables.py", "test_trust.py", "test_stability_units.py")


def pytest_collection_modifyitems(config, items):
    """Move the modules in ``LONG_FIRST`` to the front (a stable sort: every module's own order is kept)."""
    rank = {name: i for i, name in enumerate(LONG_FIRST)}
    items.sort(key=lambda item: rank.get(item.path.name, len(rank)))


@pytest.hookimpl(trylast=True)
def pytest_unconfigure(config):
    """End of the session: one full garbage collection, then ``gc.freeze()``.

    pytest then collects garbage five times more (``gc_collect_harder``, to
    report exceptions raised in finalizers), and the interpreter tears down
    what the tests built (numba and JAX compilations, heyoka's JIT, figures);
    each full pass walked the whole heap again, about 10 s in all at load 5,
    long enough that pytest-xdist's controller waited its 10 s limit for each
    worker to exit and then killed it. The one collection here still runs
    every finalizer of the garbage there is at the end; the frozen objects
    are only skipped by the later passes."""
    gc.collect()
    gc.freeze()
