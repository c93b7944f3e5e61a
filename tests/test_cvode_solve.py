"""CVODE driven by one ``solve`` call (issue 12): its counters read from CVODE's
statistics against the one-step loop that counts them itself, the banded
difference-quotient calls in ``nfev``, and the total step cap."""
import numpy as np
import pytest

from rk4h.references.solvers import Status, absolute_tolerance
from rk4h.references.solvers import cvode

from _cvode_cases import CASES, T, case


def both(solver, model, y0, t, rtol, max_steps=cvode.DEFAULT_MAX_STEPS):
    atol = absolute_tolerance(model, y0, rtol)
    new = cvode.run_cvode(solver, model, y0, t, rtol, atol, max_steps)
    loop = cvode._run_cvode(solver, model, y0, t, rtol, atol, max_steps, one_step_loop=True)
    assert new.extra["counters"] == "cvode-stats"  # the statistics were readable here
    assert loop.extra["counters"] == "one-step-loop"
    return new, loop


@pytest.mark.parametrize("name", sorted(CASES))
@pytest.mark.parametrize("solver", ["cvode-adams", "cvode-bdf"])
@pytest.mark.parametrize("rtol", [1e-6, 1e-11])
def test_solve_counters_equal_the_one_step_loop(name, solver, rtol):
    # The loop counts its steps in Python and the RHS calls in its wrapper; the
    # single solve reads CVodeGetNumSteps & co. Same internal steps, so every
    # counter and every output must agree exactly.
    model, y0 = case(name)
    new, loop = both(solver, model, y0, T, rtol)
    assert new.status is Status.OK and loop.status is Status.OK
    assert new.n_steps == loop.n_steps > 0
    assert new.nfev == loop.nfev > new.n_steps
    for key in ("nfev_cvode", "nfev_jac_dq", "njev"):
        assert new.extra[key] == loop.extra[key], key
    assert new.nfev == new.extra["nfev_cvode"] + new.extra["nfev_jac_dq"]
    np.testing.assert_array_equal(new.y, loop.y)


def test_band_nfev_includes_the_difference_quotient_calls(monkeypatch):
    model, y0 = case("chain-12")
    fast = cvode.compiled_rhs(model)
    counted = [0]

    class Counting:  # an independent count of every right-hand-side call CVODE makes
        def permuted(self, perm):
            fun = fast.permuted(perm)

            def f(z, zp):
                counted[0] += 1
                return fun(z, zp)

            return f

    monkeypatch.setattr(cvode, "compiled_rhs", lambda m: Counting())
    rtol = 1e-9
    run = cvode.run_cvode("cvode-bdf", model, y0, T, rtol, absolute_tolerance(model, y0, rtol))
    assert run.status is Status.OK and run.extra["linsolver"] == "band"
    width = run.extra["lband"] + run.extra["uband"] + 1
    assert width == 5 and run.extra["njev"] > 0
    assert run.extra["nfev_jac_dq"] == width * run.extra["njev"]  # CVodeGetNumLinRhsEvals
    assert run.nfev == counted[0] == run.extra["nfev_cvode"] + run.extra["nfev_jac_dq"]
    assert run.nfev > run.extra["nfev_cvode"]  # scikit-sundae's nfev leaves them out


def test_statistics_unreadable_falls_back_to_the_loop(monkeypatch):
    model, y0 = case("chain-12")
    rtol = 1e-8
    atol = absolute_tolerance(model, y0, rtol)
    new = cvode.run_cvode("cvode-adams", model, y0, T, rtol, atol)
    monkeypatch.setattr(cvode, "_cvode_library", lambda: None)
    fallback = cvode.run_cvode("cvode-adams", model, y0, T, rtol, atol)
    assert fallback.extra["counters"] == "one-step-loop" and fallback.status is Status.OK
    assert (fallback.n_steps, fallback.nfev) == (new.n_steps, new.nfev)
    np.testing.assert_array_equal(fallback.y, new.y)


@pytest.mark.parametrize("solver", ["cvode-adams", "cvode-bdf"])
def test_step_cap_is_on_the_total(solver):
    # The cap falls in a late output interval, far below CVODE's per-interval
    # max_num_steps: only the total cap can stop it, at the loop's step and time.
    model, y0 = case("chain-12")
    full, _ = both(solver, model, y0, T, 1e-9)
    need = full.n_steps
    cap = need - need // 5
    new, loop = both(solver, model, y0, T, 1e-9, max_steps=cap)
    for run in (new, loop):
        assert run.status is Status.FAILED and f"step cap max_steps = {cap} reached" in run.message
        assert run.n_steps == cap
    assert new.t_fail == loop.t_fail and 2.5 < new.t_fail < 5.0
    np.testing.assert_array_equal(new.y, loop.y)  # outputs up to the cap kept, NaN after
    reached = T <= new.t_fail
    assert np.all(np.isfinite(new.y[:, reached])) and np.all(np.isnan(new.y[:, ~reached]))
    # exactly enough steps is not a failure
    exact, _ = both(solver, model, y0, T, 1e-9, max_steps=need)
    assert exact.status is Status.OK and exact.n_steps == need
    np.testing.assert_array_equal(exact.y, full.y)


@pytest.mark.parametrize("solver", ["cvode-adams", "cvode-bdf"])
def test_two_output_times_give_the_end_state_of_a_longer_grid(solver):
    # scikit-sundae's solve returns every internal step when given two times;
    # the wrapper asks for one midpoint more: same steps, same end state.
    from rk4h.references.solvers import integrate
    from rk4h import make_model

    model = make_model("chain", {"masses": [0.815, 3.099], "springs": [41.5, 138.0, 157.8], "walls": "both"})
    y0 = np.array([0.005, 0.005, 0.0, 0.0])
    two = integrate(solver, model, y0, np.array([0.0, 10.0]), 1e-8)
    three = integrate(solver, model, y0, np.linspace(0.0, 10.0, 3), 1e-8)
    assert two.ok and three.ok, (two.message, three.message)
    assert two.y.shape == (4, 2)
    assert (two.n_steps, two.nfev) == (three.n_steps, three.nfev)
    assert np.array_equal(two.y[:, -1], three.y[:, -1])
