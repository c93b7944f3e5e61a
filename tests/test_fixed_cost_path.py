"""The short path of ``integrate("rk4", ...)`` (issue 29: arguments checked
once): the same numbers, statuses and messages as ``fast.solve_model`` with
the checks it repeats, bit for bit, and the same refusals of bad input."""
from __future__ import annotations

import numpy as np
import pytest

import rk4h
import rk4h.fast as fast
from rk4h.references.solvers import integrate
from rk4h.references.solvers.fixed import MAX_GROWTH
from rk4h.references.solvers.tolerances import state_scale
from rk4h.fast import solve as fast_solve
from rk4h.validate import check_output_times, check_y0


def _chain(n, **extra):
    return rk4h.make_model("chain", {"masses": [1.0 + 0.1 * i for i in range(n)],
                                        "springs": [1.0 + 0.05 * i for i in range(n + 1)], **extra})


def _reference(model, y0, t, h, method="rk4"):
    """What run_fixed ran before the short path: solve_model with every check."""
    return fast.solve_model(model, (t[0], t[-1]), y0, h=h, t_eval=t, method=method,
                            max_growth=MAX_GROWTH, y_scale=state_scale(model, y0))


@pytest.mark.parametrize("n, extra", [(2, {}), (2, {"alpha": 0.3}), (32, {"alpha": 0.25}), (7, {"beta": 2.0})])
@pytest.mark.parametrize("t", [np.array([0.0, 0.05]), np.array([0.0, 0.013, 0.05, 0.0712, 0.3]),
                               np.linspace(0.0, 1.0, 11), np.linspace(0.0, 1.0, 101)])
@pytest.mark.parametrize("method", ["rk4", "euler", "symplectic-euler"])
def test_short_path_equals_solve_model(n, extra, t, method):
    model = _chain(n, **extra)
    y0 = model.state(0.05 * np.sin(0.7 * np.arange(1, n + 1)))
    run = integrate(method, model, y0, t, 0.01)
    ref = _reference(model, y0, t, 0.01, method)
    assert run.extra["path"] == "numba"
    np.testing.assert_array_equal(run.y, ref.y)
    assert run.y.flags.c_contiguous
    assert (run.nfev, run.n_steps, run.extra["dense"], run.extra["h_used"]) == (ref.nfev, ref.n_steps, ref.dense,
                                                                                 ref.h)


def test_unstable_run_same_status_time_and_message():
    model = _chain(4)
    y0 = model.state([0.01, 0.0, -0.01, 0.02])
    t = np.array([0.0, 0.7, 50.0])
    run = integrate("euler", model, y0, t, 0.9)  # far outside Euler's stability region
    ref = _reference(model, y0, t, 0.9, "euler")
    assert not run.ok and not ref.success
    assert (run.t_fail, run.message, run.extra["reason"]) == (ref.t_fail, ref.message, ref.reason)
    reached = ref.y.shape[1]
    np.testing.assert_array_equal(run.y[:, :reached], ref.y)
    assert np.isnan(run.y[:, reached:]).all()


@pytest.mark.parametrize("m", [2, 5, 32, 33])
def test_few_output_points_equal_the_array_computation(m):
    rng = np.random.default_rng(m)
    t0, step, n = 0.1, 0.0123, 700
    t = np.sort(np.concatenate([[t0], t0 + step * rng.integers(0, n, m // 2),
                                t0 + n * step * rng.random(m - 1 - m // 2)]))
    t[-1] = t0 + n * step
    few = fast_solve._output_points_few(t0, step, n, t)
    # the numpy path, as _output_points computes it for many points
    s = (t - t0) / step
    idx = np.minimum(np.maximum(np.floor(s + 1e-9).astype(np.int64), 0), n)
    theta = s - idx
    on_grid = np.abs(theta) <= 1e-9 * np.maximum(1.0, np.abs(s))
    theta[on_grid] = 0.0
    np.testing.assert_array_equal(few[0], idx)
    assert few[0].dtype == np.int64
    np.testing.assert_array_equal(few[1], theta)
    assert few[2] == ("grid" if on_grid.all() else "hermite")
    assert fast_solve._output_points(t0, step, n, t, 1)[2] == few[2]


def test_short_path_still_refuses_too_many_steps():
    model = _chain(2)
    run = integrate("rk4", model, model.state([0.01, 0.0]), np.array([0.0, 1.0]), 1e-12)
    assert run.status.name == "FAILED" and "MAX_STEPS" in run.message and np.isnan(run.y).all()


@pytest.mark.parametrize("bad", [np.array([0.0, np.nan]), np.array([0.0, np.inf, 1.0])])
def test_fast_y0_check_keeps_the_message(bad):
    with pytest.raises(ValueError, match=r"`y0` must be finite"):
        check_y0(bad)


def test_fast_y0_check_copies():
    y = np.array([1.0, 2.0])
    out = check_y0(y)
    assert out is not y and np.array_equal(out, y)


@pytest.mark.parametrize("bad", [np.array([0.0, 0.0]), np.array([0.0, 1.0, 0.5]), np.array([0.0, np.nan]),
                                 np.array([0.0, np.inf])])
def test_fast_output_times_check_keeps_the_refusal(bad):
    with pytest.raises(ValueError, match=r"`t_eval` must be finite and strictly increasing"):
        check_output_times(bad)


def test_fast_output_times_check_copies():
    t = np.array([0.0, 1.0])
    out = check_output_times(t)
    assert out is not t and np.array_equal(out, t)
