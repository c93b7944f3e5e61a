"""Test-wide settings. ``run_all`` subprocesses started by the tests run
in-process (``RK4H_WORKERS=1``) unless a test passes ``--workers``: a spawned
pool's start-up (a fresh interpreter per worker, numba and heyoka imports)
costs seconds per run and tests nothing a small scene needs. The tests of the
pool itself (``test_kill.py``, ``test_pipeline.py``, ``test_dask.py``) ask for
it explicitly."""
import gc
import os

import pytest

os.environ.setdefault("RK4H_WORKERS", "1")

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


@pytest.hookimpl(wrapper=True)
def pytest_collection(session):
    """No cyclic garbage collection while the tests are collected; then one full
    collection, ``gc.freeze()`` and the collector back on.

    Collecting imports every test module (pytest's assertion rewriting builds and
    compiles an AST per module) and the libraries they import; the allocations
    triggered about 25 full collections, each walking the whole growing heap of
    numpy, scipy, pandas and the package: 5.6 of 10.1 s of CPU of a
    ``--collect-only -n 0`` (load 3.5), paid again by every xdist worker; 0.35 s
    with this. The one collection at the end runs every finalizer of the
    collection's garbage. What is left (imported modules, the collected items)
    lives for the whole session; frozen, the full collections during the tests
    no longer walk it. (On an xdist controller, which collects nothing, this
    wraps a hook that returns at once.)"""
    enabled = gc.isenabled()
    gc.disable()
    try:
        return (yield)
    finally:
        gc.collect()
        gc.freeze()
        if enabled:
            gc.enable()


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
