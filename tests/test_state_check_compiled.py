"""The compiled state test of a new ``y0`` (``rk4h.fast.statecheck``, issue 29):
it accepts only states ``Model.state_problem`` accepts, so the short path
refuses every ``y0`` the numpy check refuses, with the general path's message;
and it does accept ordinary states (else it would save nothing)."""
from __future__ import annotations

import numpy as np
import pytest

import rk4h
from rk4h.fast.statecheck import LIMIT, state_checker
from rk4h.models import example_parameters
from rk4h.references.solvers import integrate


def _models():
    return {
        "fput": rk4h.make_model("chain", {"masses": [1.0, 2.0, 0.5, 1.5], "springs": [1.0, 3.0, 2.0, 1.0, 0.5],
                                          "alpha": 0.25, "beta": 1.5}),
        "linear-free": rk4h.make_model("chain", {"masses": [1.0, 2.0, 0.5], "springs": [1.0, 3.0],
                                                 "walls": "none"}),
        "left-wall": rk4h.make_model("chain", {"masses": [1.0, 2.0], "springs": [1.0, 3.0], "walls": "left",
                                               "beta": -0.5}),
        "network": rk4h.make_model("network", example_parameters("network")),
        "triangle": rk4h.make_model("triangle", example_parameters("triangle")),
    }


def _states(model, rng):
    """Ordinary states, then states at and past every overflow edge, states
    with a spring of zero length, and non-finite ones."""
    n = model.n_dof
    out = [0.01 * rng.standard_normal(2 * n) for _ in range(5)] + [np.zeros(2 * n)]
    for e in (50, 75, 76, 77, 100, 101, 102, 150, 153, 154, 155, 160, 200, 300, 307, 308):
        y = rng.standard_normal(2 * n)
        with np.errstate(over="ignore"):
            out.append(y * 10.0**e)
        z = 0.01 * rng.standard_normal(2 * n)
        z[rng.integers(2 * n)] = 1.7e308 / 10.0**(308 - e) * rng.choice([-1.0, 1.0])
        out.append(z)
    for bad in (np.nan, np.inf, -np.inf):
        y = 0.01 * rng.standard_normal(2 * n)
        y[rng.integers(2 * n)] = bad
        out.append(y)
    return out


def _zero_length_states(model):
    """States putting a spring of a network at zero length (its two ends at
    one point), where the numpy force divides by zero."""
    out = []
    kern = model.force_kernel()
    X = kern.fp[: kern.n_masses * kern.dim].reshape(kern.n_masses, kern.dim)
    A = kern.fp[kern.n_masses * kern.dim:(kern.n_masses + kern.n_anchors) * kern.dim].reshape(-1, kern.dim)
    for a, b in zip(kern.a, kern.b):
        u = np.zeros((kern.n_masses, kern.dim))
        target = A[b - kern.n_masses] if b >= kern.n_masses else X[b]
        if a < kern.n_masses:
            u[a] = target - X[a]
            out.append(np.concatenate([u.ravel(), np.zeros(model.n_dof)]))
    return out


@pytest.mark.parametrize("name", list(_models()))
def test_accepts_only_what_the_numpy_check_accepts(name):
    model = _models()[name]
    accepts = state_checker(model)
    assert accepts is not None
    rng = np.random.default_rng(7)
    states = _states(model, rng)
    if name in ("network", "triangle"):
        zero = _zero_length_states(model)
        assert zero and all(model.state_problem(y) is not None for y in zero)  # the case is really built
        states += zero
    accepted = refused_by_numpy = 0
    for y in states:
        y = np.ascontiguousarray(y, dtype=float)
        problem = model.state_problem(y)
        if accepts(y):
            accepted += 1
            assert problem is None, (y, problem)
        refused_by_numpy += problem is not None
    assert accepted >= 6  # ordinary states are accepted: the test saves the numpy check
    assert refused_by_numpy >= 4  # and the refusals were there to be missed


@pytest.mark.parametrize("name", list(_models()))
def test_short_path_refuses_what_the_general_path_refuses_with_its_message(name):
    """Every state the general path (numpy check) refuses is refused on the
    short path of a model that has run, with the same one-line message."""
    model = _models()[name]
    t = np.array([0.0, 0.01])
    rng = np.random.default_rng(11)
    y_ok = 0.01 * rng.standard_normal(2 * model.n_dof)
    integrate("rk4", model, y_ok, t, 0.01)
    integrate("rk4", model, y_ok, t, 0.01)
    states = _states(model, rng) + (_zero_length_states(model) if name in ("network", "triangle") else [])
    refused = 0
    for y in states:
        fresh = _models()[name]  # a model that never ran: the general path, every check
        try:
            expected = integrate("rk4", fresh, y, t, 0.01)
        except ValueError as e:
            refused += 1
            with pytest.raises(ValueError) as got:
                integrate("rk4", model, y, t, 0.01)
            assert str(got.value) == str(e)
        else:
            run = integrate("rk4", model, y, t, 0.01)
            np.testing.assert_array_equal(run.y, expected.y)
            assert (run.status, run.message) == (expected.status, expected.message)
    assert refused >= 4


def test_the_numpy_check_is_not_run_for_an_accepted_state(monkeypatch):
    """The short path takes the compiled test's word for an ordinary state
    (what makes a new ``y0`` cheap), and the numbers stay the general path's."""
    model = rk4h.make_model("chain", {"masses": [1.0] * 8, "springs": [1.0] * 9, "alpha": 0.25})
    t = np.array([0.0, 0.05])
    y0 = model.state(0.1 * np.sin(0.3 * np.arange(8)))
    integrate("rk4", model, y0, t, 0.01)
    y1 = 1.01 * y0
    expected = integrate("rk4", rk4h.make_model("chain", {"masses": [1.0] * 8, "springs": [1.0] * 9,
                                                          "alpha": 0.25}), y1, t, 0.01)

    def boom(self, y):
        raise AssertionError("the numpy check ran")

    monkeypatch.setattr(type(model), "state_problem", boom)
    run = integrate("rk4", model, y1, t, 0.01)
    np.testing.assert_array_equal(run.y, expected.y)


def test_no_checker_where_a_subclass_redefines_the_energy():
    from rk4h.models.chain import Chain

    class Heavier(Chain):
        def _potential(self, x, ops):
            return 2.0 * super()._potential(x, ops)

    assert state_checker(Heavier([1.0, 1.0], [1.0, 1.0, 1.0])) is None
    assert state_checker(rk4h.make_model("planar4", example_parameters("planar4"))) is None  # a potential: numpy


def test_limit_is_far_below_overflow():
    assert LIMIT * 1e6 < np.finfo(float).max
