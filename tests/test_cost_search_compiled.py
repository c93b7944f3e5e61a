"""The stability studies' cost-at-target search (validation/stability/stiffness.py)
probes its rtol ladder on the references' compiled loops (untimed work); the
solver a user runs then confirms the boundary (``confirm_rung``): the rung reported
is a hit of the user's solver whose looser neighbour it missed, the row's numbers,
wall time and status are its run's, and the rung is the one an all-scipy search
finds, also where the compiled loop's error falls on the other side of the target
(the stiff chain at ratio 1e6: scipy's DOP853 meets 1e-6 at rtol 1e-5, the
compiled loop's step sequence parts from it and misses there)."""
import math

import numpy as np
import pytest

from rk4h.references import solvers as S
from rk4h.validation.stability import stiffness as ST

SOLVERS = ("dop853", "cvode-adams", "cvode-bdf")


def _spy(monkeypatch):
    """Count the search's calls per entry point; return the calls list."""
    calls = []
    real_c, real_i = S.integrate_compiled, S.integrate

    def compiled(solver, *a, **k):
        run = real_c(solver, *a, **k)
        calls.append(("compiled", solver, a[-1], run))
        return run

    def plain(solver, *a, **k):
        run = real_i(solver, *a, **k)
        calls.append(("integrate", solver, a[-1], run))
        return run

    monkeypatch.setattr(S, "integrate_compiled", compiled)
    monkeypatch.setattr(S, "integrate", plain)
    return calls


CASES = [("mu", 1.0), ("mu", 0.01), ("ratio", 1e4), ("ratio", 1e6)]


def _case(what, x):
    return ST.mass_ratio_chain(x) if what == "mu" else ST.stiff_chain(x)


@pytest.mark.parametrize("what,x", CASES)
def test_probes_run_compiled_and_the_boundary_as_a_user_runs_it(what, x, monkeypatch):
    model, y0 = _case(what, x)
    calls = _spy(monkeypatch)
    rows = ST.cost_at_target(model, y0, 1e-6, SOLVERS, fixed={}, rtol_ladder=ST.RTOL_LADDER)
    for row in rows:
        if row["status"] == "skipped":
            continue
        mine = [c for c in calls if c[1] == row["solver"]]
        probes = [c for c in mine if c[0] == "compiled"]
        user = {c[2]: c[3] for c in mine if c[0] == "integrate"}
        assert len(probes) >= 2 and all(c[3].extra["implementation"] == "compiled" for c in probes)
        assert all(r.extra.get("implementation") != "compiled" for r in user.values())
        run = user[row["setting"]]  # the rung reported ran as a user runs it, and its numbers are that run's
        assert row["wall_s"] == run.wall_s and row["n_steps"] == run.n_steps
        assert row["status"] == "ok" and row["error"] <= 1e-6
        k = ST.RTOL_LADDER.index(row["setting"])
        if k > 0:  # its looser neighbour ran as a user runs it too, and missed
            looser = user[ST.RTOL_LADDER[k - 1]]
            assert not (looser.ok and ST.error_rel(model, looser.y[:, -1:], _exact(model, y0), _scale(model, y0))
                        <= 1e-6)
        assert "rtol tried on the compiled loop: " in row["note"] and "; as a user runs it: " in row["note"]


def _exact(model, y0):
    from rk4h.references.exact import modal_solution

    omega = model.modes()[0]
    t_end = 2 * math.pi / float(omega[omega > 0][0])
    return modal_solution(model, y0)(np.array([t_end]))[:, :1]


def _scale(model, y0):
    return float(np.max(np.abs(y0[: model.n_dof])))


@pytest.mark.parametrize("what,x", CASES)
def test_the_rung_found_equals_an_all_scipy_search(what, x, monkeypatch):
    """With the compiled loop replaced by the solver a user runs, the search
    finds the same rung with the same numbers (wall times apart)."""
    model, y0 = _case(what, x)
    ours = ST.cost_at_target(model, y0, 1e-6, SOLVERS, fixed={}, rtol_ladder=ST.RTOL_LADDER)
    monkeypatch.setattr(S, "integrate_compiled", S.integrate)
    scipy_only = ST.cost_at_target(model, y0, 1e-6, SOLVERS, fixed={}, rtol_ladder=ST.RTOL_LADDER)
    for a, b in zip(ours, scipy_only):
        assert a["solver"] == b["solver"]
        for k in ("setting", "status", "nfev", "n_steps", "error"):
            assert a[k] == b[k] or (a[k] != a[k] and b[k] != b[k]), (a["solver"], k, a[k], b[k])


def _stub(errors):
    """A run returning the error listed for its rtol (rtol -> error)."""
    seen = []

    def run(rtol):
        seen.append(rtol)
        e = errors[rtol]
        return {"status": "failed" if e is None else "ok", "error": math.nan if e is None else e}

    return run, seen


LADDER = (1e-4, 1e-5, 1e-6, 1e-7, 1e-8)


@pytest.mark.parametrize("start,errors,found,order", [
    # the proxy was right: the start and its looser neighbour
    (2, {1e-4: 1e-3, 1e-5: 1e-5, 1e-6: 1e-7}, 2, [1e-6, 1e-5]),
    # the proxy was too strict: the user's solver already hits looser (the stiff chain's case)
    (2, {1e-4: 1e-5, 1e-5: 8.9e-7, 1e-6: 5.6e-7}, 1, [1e-6, 1e-5, 1e-4]),
    # the loosest rung hits: nothing looser to try
    (0, {1e-4: 1e-7}, 0, [1e-4]),
    # the proxy was too loose: walk to tighter rungs until one hits
    (1, {1e-5: 3e-6, 1e-6: 2e-6, 1e-7: 5e-7}, 3, [1e-5, 1e-6, 1e-7]),
    # no rung hits: the walk ends at the ladder's end
    (3, {1e-7: 2e-6, 1e-8: 2e-6}, None, [1e-7, 1e-8]),
    # a failed run ends the walk
    (1, {1e-5: 3e-6, 1e-6: None}, None, [1e-5, 1e-6]),
])
def test_confirm_rung_walks_from_the_proxys_answer(start, errors, found, order):
    run, seen = _stub(errors)
    got, runs = ST.confirm_rung(LADDER, 1e-6, start, run)
    assert got == found and seen == order and [LADDER[i] for i in runs] == order


def test_a_user_solver_that_misses_everywhere_is_not_reached(monkeypatch):
    """Where the compiled loop meets the target and the run as a user runs it
    never does (faked here), the row is the tightest rung's run, not-reached."""
    model, y0 = ST.mass_ratio_chain(1.0)
    real = S.integrate

    def worse(solver, m, y, t, rtol, **k):
        run = real(solver, m, y, t, rtol, **k)
        run.y = np.asarray(run.y, float) + 1.0  # an error far above any target
        return run

    monkeypatch.setattr(S, "integrate", worse)
    (row,) = ST.cost_at_target(model, y0, 1e-6, ("dop853",), fixed={}, rtol_ladder=ST.RTOL_LADDER)
    assert row["status"] == "not-reached" and row["error"] > 1e-6 and math.isfinite(row["error"])
    assert row["setting"] == ST.RTOL_LADDER[-1]
    user = row["note"].split("; as a user runs it: ")[1].split(", ")
    assert user[-1] == f"{ST.RTOL_LADDER[-1]:.0e}" and len(user) >= 2  # walked to the ladder's end
