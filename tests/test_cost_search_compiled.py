"""The stability studies' cost-at-target search (validation/stability/stiffness.py)
probes its rtol ladder on the references' compiled loops (untimed work) and runs
the rung it reports once more as a user runs it: the row's numbers, wall time and
status are that run's, and the rung is the one an all-scipy search finds."""
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


@pytest.mark.parametrize("mu", [1.0, 0.01])
def test_probes_run_compiled_and_the_reported_rung_as_a_user_runs_it(mu, monkeypatch):
    model, y0 = ST.mass_ratio_chain(mu)
    calls = _spy(monkeypatch)
    rows = ST.cost_at_target(model, y0, 1e-6, SOLVERS, fixed={}, rtol_ladder=ST.RTOL_LADDER)
    for row in rows:
        mine = [c for c in calls if c[1] == row["solver"]]
        probes = [c for c in mine if c[0] == "compiled"]
        (timed,) = [c for c in mine if c[0] == "integrate"]
        assert len(probes) >= 2 and all(c[3].extra["implementation"] == "compiled" for c in probes)
        assert timed[3].extra.get("implementation") != "compiled"
        assert timed[2] == row["setting"]  # the rung reported is the one run as a user runs it
        run = timed[3]
        assert row["wall_s"] == run.wall_s and row["n_steps"] == run.n_steps
        assert row["status"] == "ok" and row["error"] <= 1e-6
        assert "rtol tried (compiled loop): " in row["note"]


def test_the_rung_found_equals_an_all_scipy_search(monkeypatch):
    """With the compiled loop replaced by the solver a user runs, the search
    finds the same rung with the same numbers (wall times apart)."""
    model, y0 = ST.mass_ratio_chain(0.01)
    ours = ST.cost_at_target(model, y0, 1e-6, SOLVERS, fixed={}, rtol_ladder=ST.RTOL_LADDER)
    monkeypatch.setattr(S, "integrate_compiled", S.integrate)
    scipy_only = ST.cost_at_target(model, y0, 1e-6, SOLVERS, fixed={}, rtol_ladder=ST.RTOL_LADDER)
    for a, b in zip(ours, scipy_only):
        assert a["solver"] == b["solver"]
        for k in ("setting", "status", "nfev", "n_steps", "error"):
            assert a[k] == b[k], (a["solver"], k, a[k], b[k])
        assert "(compiled loop)" in a["note"] and "(compiled loop)" not in b["note"]


def test_a_reported_run_that_misses_is_not_ok(monkeypatch):
    """Where the compiled loop meets the target and the run as a user runs it
    does not (round-off at the boundary, faked here), the row says not-reached."""
    model, y0 = ST.mass_ratio_chain(1.0)
    real = S.integrate

    def worse(solver, m, y, t, rtol, **k):
        run = real(solver, m, y, t, rtol, **k)
        run.y = np.asarray(run.y, float) + 1.0  # an error far above any target
        return run

    monkeypatch.setattr(S, "integrate", worse)
    (row,) = ST.cost_at_target(model, y0, 1e-6, ("dop853",), fixed={}, rtol_ladder=ST.RTOL_LADDER)
    assert row["status"] == "not-reached" and row["error"] > 1e-6 and math.isfinite(row["error"])
    assert "missed where the compiled loop met the target" in row["note"]
