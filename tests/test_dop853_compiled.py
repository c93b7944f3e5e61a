"""The compiled DOP853 loop (rk4h.fast.dop853, rk4h.references.solvers.run_dop853_compiled)
against scipy's DOP853 (rk4h.references.solvers.run_dop853): same steps, same
right-hand-side calls, states and errors equal to round-off, same statuses.

The two differ only in how the stage sums are formed (BLAS ``np.dot`` in
scipy, left to right here). DOP853's error estimate is a sum that cancels, so
its round-off is amplified (where the estimate is far below the tolerance,
as after Henon-Heiles' first step at rtol 1e-7, the next step differs by
9e-8 relative, and the states by 4e-13 of their scale; on a 10-mass chain at
rtol 1e-4 by 1e-9): the step sizes then differ at that level, and over a long horizon
an accept/reject decision can flip (chain10-mode2 over its whole 100 s at
rtol 1e-4: 245 steps both, nfev 4601 vs 4613). The horizons here are a few
periods, where the test requires equal counts.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from rk4h.references.solvers import absolute_tolerance, integrate, integrate_compiled
from rk4h.references.solvers.base import Status
from rk4h.references.solvers.dop853 import run_dop853, run_dop853_compiled
from rk4h.validation.execute import problem
from rk4h.validation.scenes import load_scene

SCENES = Path(__file__).resolve().parent.parent / "validation" / "scenes"
EPS = np.finfo(float).eps
RTOLS = (1e-4, 1e-7, 1e-10, 1e-13)
#: (scene file, horizon in s): a chain kernel, a potential (Henon-Heiles), a
#: planar spring network (planar4) -- three model structures, three compiles.
CASES = (("thesis_2dof_case1", 6.0), ("henon_heiles", 20.0), ("planar4_case1", 3.0))


def _problem(stem, horizon, points=121):
    model, y0 = problem(load_scene(SCENES / f"{stem}.toml"))
    return model, y0, np.linspace(0.0, horizon, points)


@pytest.mark.parametrize("stem,horizon", CASES)
def test_compiled_dop853_equals_scipys_to_round_off(stem, horizon):
    model, y0, t = _problem(stem, horizon)
    ref = run_dop853(model, y0, t, 1e-13, absolute_tolerance(model, y0, 1e-13))
    scale = float(np.max(np.abs(ref.y)))
    for rtol in RTOLS:
        atol = absolute_tolerance(model, y0, rtol)
        a = run_dop853(model, y0, t, rtol, atol)
        b = run_dop853_compiled(model, y0, t, rtol, atol)
        where = f"{stem} rtol {rtol:g}"
        assert a.status is Status.OK and b.status is Status.OK, where
        assert b.extra["implementation"] == "compiled", where
        assert (b.n_steps, b.nfev) == (a.n_steps, a.nfev), where
        assert b.extra["first_step"] == a.extra["first_step"], where
        assert b.message == a.message, where
        # states: round-off of the sums, accumulated over the steps, and the
        # amplified round-off of the error estimate through the step sizes
        diff = float(np.max(np.abs(a.y - b.y))) / scale
        assert diff <= 1e-4 * rtol + 10 * EPS * a.n_steps, (where, diff)
        # the error against a tight run: the same to a small fraction of it
        ea = float(np.max(np.abs(a.y - ref.y))) / scale
        eb = float(np.max(np.abs(b.y - ref.y))) / scale
        assert abs(ea - eb) <= 1e-3 * ea + 10 * EPS * a.n_steps, (where, ea, eb)
        assert np.array_equal(a.y[:, 0], b.y[:, 0]), where


def test_a_loose_tolerance_is_not_a_copy_of_a_tight_one():
    """The comparison above can fail: the runs at two tolerances differ."""
    model, y0, t = _problem("thesis_2dof_case1", 6.0)
    a = run_dop853_compiled(model, y0, t, 1e-4, absolute_tolerance(model, y0, 1e-4))
    b = run_dop853_compiled(model, y0, t, 1e-10, absolute_tolerance(model, y0, 1e-10))
    assert a.n_steps < b.n_steps and np.max(np.abs(a.y - b.y)) > 1e3 * EPS * np.max(np.abs(b.y))


def test_the_step_cap_ends_both_at_the_same_step_with_the_same_message():
    model, y0, t = _problem("henon_heiles", 20.0)
    atol = absolute_tolerance(model, y0, 1e-10)
    a = run_dop853(model, y0, t, 1e-10, atol, max_steps=7)
    b = run_dop853_compiled(model, y0, t, 1e-10, atol, max_steps=7)
    assert a.status is b.status is Status.FAILED and "step cap max_steps = 7" in b.message
    assert (b.n_steps, b.nfev, b.message) == (a.n_steps, a.nfev, a.message)
    assert b.t_fail == pytest.approx(a.t_fail, rel=1e-5)  # the step sizes' amplified round-off
    reached = np.all(np.isfinite(a.y), axis=0)
    assert np.array_equal(reached, np.all(np.isfinite(b.y), axis=0)) and 1 < reached.sum() < len(t)
    np.testing.assert_allclose(b.y[:, reached], a.y[:, reached], rtol=0,
                               atol=(1e-4 * 1e-10 + 10 * EPS * a.n_steps) * np.max(np.abs(a.y[:, reached])))


def test_rtol_below_scipys_floor_is_clipped_and_said():
    model, y0, t = _problem("thesis_2dof_case1", 2.0)
    atol = absolute_tolerance(model, y0, 1e-13)
    a, b = run_dop853(model, y0, t, 1e-15, atol), run_dop853_compiled(model, y0, t, 1e-15, atol)
    assert b.extra["rtol_used"] == a.extra["rtol_used"] == 100 * EPS
    assert b.message == a.message and "clipped" in b.message and (b.n_steps, b.nfev) == (a.n_steps, a.nfev)


def test_a_finite_time_blow_up_fails_in_both_at_the_same_step():
    """Henon-Heiles three times its scene's amplitude escapes, and its cubic
    force blows up in finite time: the step shrinks below 10 ulps of t
    (scipy's "Required step size is less than spacing between numbers.")."""
    model, y0, t = _problem("henon_heiles", 20.0)
    y0 = 3.0 * np.asarray(y0, float)
    atol = absolute_tolerance(model, y0, 1e-6)
    a = run_dop853(model, y0, t, 1e-6, atol, max_steps=20000)
    b = run_dop853_compiled(model, y0, t, 1e-6, atol, max_steps=20000)
    assert a.status is b.status is Status.FAILED and "less than spacing" in b.message
    assert (b.n_steps, b.nfev, b.message) == (a.n_steps, a.nfev, a.message)
    assert b.t_fail == pytest.approx(a.t_fail, rel=1e-12) and 0 < b.t_fail < t[-1]
    assert np.array_equal(np.isnan(a.y), np.isnan(b.y)) and np.isnan(b.y[:, -1]).all()


def test_integrate_compiled_runs_the_compiled_loop_only_for_dop853():
    model, y0, t = _problem("thesis_2dof_case1", 2.0)
    run = integrate_compiled("dop853", model, y0, t, 1e-8)
    assert run.solver == "dop853" and run.extra["implementation"] == "compiled"
    plain = integrate("dop853", model, y0, t, 1e-8)
    assert "implementation" not in plain.extra and (plain.n_steps, plain.nfev) == (run.n_steps, run.nfev)
    other = integrate_compiled("rk4", model, y0, t, 0.01)
    assert other.solver == "rk4" and "implementation" not in other.extra
    with pytest.raises(ValueError, match="rtol"):
        integrate_compiled("dop853", model, y0, t, 2.0)


def test_a_loop_that_cannot_be_built_falls_back_to_scipy(monkeypatch):
    import rk4h.fast.dop853 as fd

    def broken(kern):
        raise RuntimeError("no compiler here")

    monkeypatch.setattr(fd, "dop853_loop", broken)
    model, y0, t = _problem("thesis_2dof_case1", 2.0)
    atol = absolute_tolerance(model, y0, 1e-8)
    run = run_dop853_compiled(model, y0, t, 1e-8, atol)
    plain = run_dop853(model, y0, t, 1e-8, atol)
    assert run.extra["implementation"] == "scipy" and "no compiler here" in run.extra["compiled_error"]
    assert run.ok and np.array_equal(run.y, plain.y) and (run.n_steps, run.nfev) == (plain.n_steps, plain.nfev)


def test_a_confirmation_run_of_dop853_runs_the_compiled_loop_and_its_row_says_so(tmp_path):
    from _scenes import one_mass
    from rk4h.validation import confirm
    from rk4h.validation.execute import execute
    from rk4h.validation.plan import RunSpec, scene_digest

    path = tmp_path / "dop.toml"
    path.write_text(one_mass("dop-confirm", t_end=4.0))
    scene = load_scene(path)
    dig = scene_digest(scene)
    specs = [RunSpec(scene.name, dig, purpose, solver="dop853", setting=1e-10, grid="scene", repeats=1)
             for purpose in ("run", confirm.PURPOSE)]
    recs = {s.key: execute(scene, s) for s in specs}
    run_rec, conf_rec = (recs[s.key] for s in specs)
    assert run_rec.status == conf_rec.status == "ok"
    assert run_rec.values["implementation"] == "" and conf_rec.values["implementation"] == "compiled"
    assert (conf_rec.values["nfev"], conf_rec.values["n_steps"]) == (run_rec.values["nfev"], run_rec.values["n_steps"])
    assert abs(conf_rec.values["error_rel"] - run_rec.values["error_rel"]) <= 1e-3 * run_rec.values["error_rel"]
    rows = confirm.rows_of(specs, recs)
    assert [r["implementation"] for r in rows] == ["", "compiled"]


def test_the_trust_note_names_a_compiled_alternative():
    import math

    from rk4h.references.registry import BUILTIN
    from rk4h.validation import trust

    rk4 = [dict(solver="rk4", setting=h, error_rel=1e3 * h**4, nfev=4 * round(100 / h), n_steps=round(100 / h),
                wall_s=1e-3, wall_min=1e-3, wall_max=1e-3, compile_s=0.0, status="ok", taylor_order=0)
           for h in (0.1, 0.05, 0.025, 0.0125)]
    alt = dict(solver="dop853", setting=1e-12, error_rel=4e-13, nfev=5000, n_steps=400, wall_s=1e-3, wall_min=1e-3,
               wall_max=1e-3, compile_s=0.0, status="ok", taylor_order=0)
    notes = [trust.trust_rows("s", rk4, BUILTIN["rk4"], 100.0, math.inf, [1e-12],
                              confirmations=[{**alt, "implementation": impl}])[0]["note"] for impl in ("", "compiled")]
    assert "compiled loop" not in notes[0] and "dop853 setting 1e-12 reached 4e-13 (its compiled loop" in notes[1]
