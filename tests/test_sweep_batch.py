"""Untimed fixed-step runs of a [sweep]'s points as one batch
(rk4h.validation.sweep_batch): each record equals the one its spec makes
alone, bit for bit; a point that diverges stops alone; timed runs are never
batched; the engine gives the same records with and without batches."""
import copy

import numpy as np
import pytest

from rk4h.validation import execute as ex
from rk4h.validation import sweep_batch
from rk4h.validation.plan import plan_all
from rk4h.validation.scenes import scene_points_from_dict

pytest.importorskip("numba", reason="numba is not installed (the fast extra)")

# an FPUT chain: alpha leaves the linear frequencies, hence the convergence grids, alike at every
# point; at alpha = 1e12 the motion itself blows up within 1e-4 s (no reference: its convergence
# runs fail on the truth) and the state figures' RK4 run stops on the instability rule
DOC = {
    "name": "sweep-batch", "model": "chain",
    "params": {"masses": [0.815, 3.099], "springs": [41.5, 138.0, 157.8], "walls": "both", "alpha": 1.0},
    "initial": {"x": [0.005, 0.005], "v": [0.0, 0.0]},
    "run": {"t_end": 1.0, "h": [0.01], "tolerances": [1e-8], "solvers": ["rk4", "dop853"],
            "outputs": ["convergence", "work_precision", "figures"]},
    "sweep": {"params.alpha": [1.0, 300.0, 1e12], "initial.x[0]": [0.005, 0.002]},
}


def _points(doc=DOC):
    return scene_points_from_dict(copy.deepcopy(doc))


def _untimed(scenes):
    return [(s, sp) for s, sp in plan_all(scenes) if not sp.timed and sp.purpose != "truth"]


def _same(a, b):
    assert (a.status, a.message) == (b.status, b.message)
    assert a.values.keys() == b.values.keys() and a.arrays.keys() == b.arrays.keys()
    for k in a.values:
        va, vb = a.values[k], b.values[k]
        assert va == vb or (va != va and vb != vb), (k, va, vb)
    for k in a.arrays:
        x, y = np.asarray(a.arrays[k]), np.asarray(b.arrays[k])
        assert x.dtype == y.dtype and np.array_equal(x, y, equal_nan=x.dtype.kind in "fc"), k


@pytest.fixture
def batched(monkeypatch):
    monkeypatch.setattr(sweep_batch, "BATCH_MIN_STEPS", 0)


def test_groups_hold_the_points_of_one_untimed_run(batched):
    jobs = _untimed(_points())
    out = sweep_batch.group(jobs)
    groups = [g for _, g in out if isinstance(g, sweep_batch.SpecGroup)]
    assert {g.purpose for g in groups} == {"order", "figure"}
    assert all(len(g.jobs) == 6 for g in groups)  # 3 alphas x 2 amplitudes: one grid, one step
    assert sum(len(g.jobs) for g in groups) + sum(1 for s, _ in out if s is not None) == len(jobs)
    timed = [(s, sp) for s, sp in plan_all(_points()) if sp.timed]
    assert timed and sweep_batch.group(timed) == timed  # timed runs never join a batch


def test_the_threshold_keeps_small_sweeps_apart_without_building_models(monkeypatch):
    jobs = _untimed(_points())
    monkeypatch.setattr(sweep_batch, "BATCH_MIN_STEPS", 10 ** 12)

    def no_models(scene):
        raise AssertionError("a model was built")

    monkeypatch.setattr(ex, "problem", no_models)
    assert sweep_batch.group(jobs) == jobs


def test_the_cheap_bound_bounds_the_steps():
    from rk4h import step_count

    n = 0
    for scene, spec in _untimed(_points()):
        key = sweep_batch.batch_key(scene, spec)
        if key is None:
            continue
        t = np.frombuffer(key[5], dtype=np.float64)
        steps = step_count((float(t[0]), float(t[-1])), key[4])
        bound = sweep_batch._bound(scene, spec)[1]
        assert steps <= bound < 3 * steps + 10, (spec.purpose, steps, bound)
        n += 1
    assert n > 6


def test_a_batch_equals_each_point_alone_and_a_diverging_point_stops_alone(batched, monkeypatch):
    import rk4h.references.solvers as solvers

    jobs = _untimed(_points())
    groups = [g for _, g in sweep_batch.group(jobs) if isinstance(g, sweep_batch.SpecGroup)]
    calls = []
    real = solvers.integrate
    monkeypatch.setattr(solvers, "integrate", lambda *a, **k: calls.append(1) or real(*a, **k))
    statuses = []
    for g in groups:
        calls.clear()
        recs = sweep_batch.execute_group(g)
        reruns = len(calls)
        alone = [ex.execute(s, sp) for s, sp in g.jobs]
        for a, b in zip(recs, alone):
            _same(a, b)
        st = [r.status for r in recs]
        statuses.append(st)
        # only the diverging points were integrated one by one: the others came from the batch
        assert reruns == sum(s == "unstable" for s in st)
        assert st[:4] == ["ok"] * 4  # points in grid order: alpha 1 (x2), 300 (x2), 1e12 (x2)
    figure = [st for g, st in zip(groups, statuses) if g.purpose == "figure"]
    assert figure == [["ok"] * 4 + ["unstable"] * 2]


def test_the_engine_gives_the_same_records_with_batches(monkeypatch):
    from rk4h.validation.engine import run_plan

    scenes = _points()
    jobs = [(s, sp) for s, sp in plan_all(scenes) if not sp.timed]
    monkeypatch.setattr(sweep_batch, "BATCH_MIN_STEPS", 10 ** 12)
    apart = run_plan(jobs)
    monkeypatch.setattr(sweep_batch, "BATCH_MIN_STEPS", 0)
    ticks = []
    together = run_plan(jobs, progress=ticks.append)
    assert apart.keys() == together.keys() == {sp.key for _, sp in jobs}
    for k in apart:
        _same(together[k], apart[k])
    assert len(ticks) == len(jobs)  # one progress line per spec, batched or not


def test_a_failing_batch_fails_each_spec_with_its_own_key():
    from rk4h.validation.records import RunRecord

    jobs = tuple(_untimed(_points())[:2])
    g = sweep_batch.SpecGroup(jobs)
    split = g.split(RuntimeError("worker died"))
    assert [s.key for s, _ in split] == [r.key for _, r in split] == [sp.key for _, sp in jobs]
    assert all(r.status == "failed" for _, r in split)
    split = g.split(RunRecord(jobs[0][1].key, status="failed", message="boom"))
    assert [r.key for _, r in split] == [sp.key for _, sp in jobs] and split[1][1].message == "boom"


def test_a_batch_that_raises_runs_its_points_alone(batched, monkeypatch):
    import rk4h

    jobs = _untimed(_points())
    g = next(g for _, g in sweep_batch.group(jobs) if isinstance(g, sweep_batch.SpecGroup))

    calls = []

    def broken(*a, **k):
        calls.append(1)
        raise ValueError("no batch today")

    monkeypatch.setattr(rk4h, "ensemble", broken)
    recs = sweep_batch.execute_group(g)
    assert calls == [1] and len(recs) == len(g.jobs)
    for a, (scene, spec) in zip(recs, g.jobs):
        _same(a, ex.execute(scene, spec))
