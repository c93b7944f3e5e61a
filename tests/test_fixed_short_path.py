"""The short path of a repeated ``integrate`` with a fixed-step method
(issue 29: ``rk4h.references.solvers.fixed.run_fixed_short``): the numbers,
counters and messages of the general path bit for bit, the general path's
refusals, and nothing stale after a user changes ``y0``, ``t_eval`` or the
model in place."""
from __future__ import annotations

import numpy as np
import pytest

import rk4h
import rk4h.references.solvers as solvers
from rk4h.models import BUILTIN_CLASSES, example_parameters
from rk4h.references.registry import BUILTIN_TABLEAUX
from rk4h.references.solvers import integrate
from rk4h.references.solvers.fixed import run_fixed


def _chain(n, **extra):
    return rk4h.make_model("chain", {"masses": [1.0 + 0.1 * i for i in range(n)],
                                        "springs": [1.0 + 0.05 * i for i in range(n + 1)], **extra})


def _state(model, seed=1, size=0.01):
    return size * np.random.default_rng(seed).standard_normal(2 * model.n_dof)


@pytest.fixture
def general_only(monkeypatch):
    """Make the general path raise: a call that still returns ran the short path."""
    def boom(*args, **kwargs):
        raise AssertionError("the general path ran")

    def arm():
        monkeypatch.setattr(solvers, "run_fixed", boom)

    return arm


def _same(a, b):
    np.testing.assert_array_equal(a.y, b.y)
    np.testing.assert_array_equal(a.t, b.t)
    assert (a.solver, a.setting, a.nfev, a.n_steps, a.status, a.message, a.t_fail, a.extra) == \
           (b.solver, b.setting, b.nfev, b.n_steps, b.status, b.message, b.t_fail, b.extra)
    assert a.y.flags.c_contiguous and a.y.dtype == b.y.dtype


#: Every built-in mechanical model but the chain (built above in three shapes), from the registry.
_OTHER_MODELS = [c.name for c in BUILTIN_CLASSES if not c.first_order and c.name != "chain"]
MODELS = [("chain2", lambda: _chain(2)), ("fput32", lambda: _chain(32, alpha=0.25)),
          ("beta7", lambda: _chain(7, beta=2.0))] + \
         [(name, lambda name=name: rk4h.make_model(name, example_parameters(name)))
          for name in _OTHER_MODELS]


@pytest.mark.parametrize("name, build", MODELS, ids=[m[0] for m in MODELS])
@pytest.mark.parametrize("method", BUILTIN_TABLEAUX)
@pytest.mark.parametrize("t", [np.array([0.0, 0.05]), np.array([0.0, 0.013, 0.05, 0.0712, 0.3]),
                               np.linspace(0.0, 1.0, 101)], ids=["2", "5", "101"])
def test_repeated_call_equals_the_general_path(name, build, method, t, general_only):
    model = build()
    y0, y1 = _state(model, 1), _state(model, 2)
    first = integrate(method, model, y0, t, 0.01)  # the general path, which records the model
    ref1 = run_fixed(method, model, y0.copy(), t.copy(), 0.01)
    ref2 = run_fixed(method, model, y1.copy(), t.copy(), 0.01)
    general_only()
    again = integrate(method, model, y0, t, 0.01)
    other = integrate(method, model, y1, t, 0.01)  # a new initial state: checked on the short path
    _same(again, first)
    _same(again, ref1)
    _same(other, ref2)
    assert again.compile_s == 0.0 and again.extra["path"] == "numba"


def test_unstable_run_same_status_time_and_message(general_only):
    model = _chain(4)
    y0 = model.state([0.01, 0.0, -0.01, 0.02])
    t = np.array([0.0, 0.7, 50.0])
    integrate("euler", model, y0, t, 0.05)
    ref = run_fixed("euler", model, y0, t, 0.9)  # far outside Euler's stability region
    general_only()
    run = integrate("euler", model, y0, t, 0.9)
    assert run.status.name == "UNSTABLE"
    _same(run, ref)


def test_other_setting_types_take_the_same_numbers():
    model = _chain(3)
    y0, t = _state(model), np.linspace(0.0, 1.0, 5)
    first = integrate("rk4", model, y0, t, 0.25)
    _same(integrate("rk4", model, y0, t, np.float64(0.25)), first)
    _same(integrate("rk4", model, y0, t, 0.25), first)
    _same(integrate("rk4", model, list(y0), list(t), 0.25), first)  # lists: the general path


@pytest.mark.parametrize("bad_y0, match", [
    (lambda y: np.where(np.arange(y.size) == 1, np.nan, y), r"`y0` must be finite"),
    (lambda y: np.where(np.arange(y.size) == 0, np.inf, y), r"`y0` must be finite"),
    (lambda y: y[:-1], r"`y0` must have length"),
    (lambda y: y.astype(complex) + 1j, r"`y0` must be real"),
    (lambda y: np.full_like(y, 1e300), r"`y0` must be a state of chain"),
])
def test_known_model_still_refuses_a_bad_y0_with_the_general_message(bad_y0, match):
    model = _chain(3, alpha=0.5)
    y0, t = _state(model), np.array([0.0, 0.1])
    integrate("rk4", model, y0, t, 0.01)
    integrate("rk4", model, y0, t, 0.01)
    bad = bad_y0(y0)
    with pytest.raises(ValueError, match=match) as fresh:
        integrate("rk4", _chain(3, alpha=0.5), bad, t, 0.01)
    with pytest.raises(ValueError, match=match) as known:
        integrate("rk4", model, bad, t, 0.01)
    assert str(known.value) == str(fresh.value)


def test_known_planar4_refuses_a_state_on_an_anchor():
    model = rk4h.make_model("planar4", {"m": 1.0, "k": 1.0, "l": 1.0})
    y0, t = _state(model), np.array([0.0, 0.1])
    integrate("rk4", model, y0, t, 0.01)
    integrate("rk4", model, y0, t, 0.01)
    anchor = model.state(list(model.anchors[1]))  # spring 1 has length 0
    with pytest.raises(ValueError, match=r"`y0` must be a state of planar4 with finite force"):
        integrate("rk4", model, anchor, t, 0.01)


@pytest.mark.parametrize("bad_t", [np.array([0.0, 0.0]), np.array([0.0, 1.0, 0.5]), np.array([0.0, np.nan]),
                                   np.array([0.0]), np.array([[0.0, 1.0]])])
def test_known_model_still_refuses_bad_t_eval(bad_t):
    model = _chain(3)
    y0 = _state(model)
    integrate("rk4", model, y0, np.array([0.0, 0.1]), 0.01)
    integrate("rk4", model, y0, np.array([0.0, 0.1]), 0.01)
    with pytest.raises(ValueError, match=r"`t_eval` must be"):
        integrate("rk4", model, y0, bad_t, 0.01)


def test_known_model_still_fails_too_many_steps():
    model = _chain(2)
    y0 = model.state([0.01, 0.0])
    integrate("rk4", model, y0, np.array([0.0, 1.0]), 0.1)
    run = integrate("rk4", model, y0, np.array([0.0, 1.0]), 1e-12)
    assert run.status.name == "FAILED" and "MAX_STEPS" in run.message and np.isnan(run.y).all()


def test_y0_and_t_eval_changed_in_place_are_noticed():
    model = _chain(3, alpha=0.25)
    y0, t = _state(model), np.array([0.0, 0.05, 0.3])
    first = integrate("rk4", model, y0, t, 0.01)
    y0[1] += 0.004
    t[1] = 0.07
    second = integrate("rk4", model, y0, t, 0.01)
    ref = run_fixed("rk4", _chain(3, alpha=0.25), y0.copy(), t.copy(), 0.01)
    _same(second, ref)
    assert not np.array_equal(second.y, first.y)
    assert second.t[1] == 0.07 and first.t[1] == 0.05  # each run keeps its own copy of t_eval


@pytest.mark.parametrize("change", ["k", "mass", "alpha"])
def test_model_changed_in_place_is_noticed(change):
    """Models are not meant to change after construction; one that does is
    integrated as it now is (its per-object caches dropped), never with the
    kernel or constants of its old parameters."""
    masses, springs = [1.0, 1.1, 1.2], [1.0, 1.05, 1.1, 1.15]
    model = rk4h.make_model("chain", {"masses": masses, "springs": springs, "alpha": 0.25})
    y0, t = _state(model), np.array([0.0, 0.05, 0.3])
    first = integrate("rk4", model, y0, t, 0.01)
    integrate("rk4", model, y0, t, 0.01)  # the short path, on the record
    if change == "k":
        model.k[1] *= 3.0
        springs = list(model.k)
    elif change == "mass":
        model.mass[0] *= 2.0
        masses = list(model.mass)
    else:
        model.alpha = 0.5
    new = rk4h.make_model("chain", {"masses": masses, "springs": springs,
                                    "alpha": 0.5 if change == "alpha" else 0.25})
    changed = integrate("rk4", model, y0, t, 0.01)
    _same(changed, integrate("rk4", new, y0, t, 0.01))
    assert not np.array_equal(changed.y, first.y)
    _same(integrate("rk4", model, y0, t, 0.01), changed)  # recorded again, as it now is


def test_a_scenes_own_tableau_takes_the_short_path(general_only):
    from rk4h.methods import METHODS
    from rk4h.references.registry import methods_from_tables

    tab = METHODS["heun3"]
    own = methods_from_tables({"my-heun3": {"A": [[str(x) for x in row] for row in tab.A_exact],
                                            "b": [str(x) for x in tab.b_exact]}})["my-heun3"]
    model = _chain(5, alpha=0.25)
    y0, t = _state(model), np.array([0.0, 0.013, 0.2])
    first = integrate(own, model, y0, t, 0.01)
    ref = run_fixed(own.tableau, model, y0.copy(), t.copy(), 0.01)
    general_only()
    again = integrate(own, model, y0, t, 0.01)
    assert again.solver == "my-heun3"
    _same(again, first)
    _same(again, ref)


def test_large_plans_and_states_are_not_kept_and_still_equal():
    from rk4h.references.solvers import fixed

    model = _chain(3)
    y0, t = _state(model), np.linspace(0.0, 1.0, fixed._KEEP_SIZE + 1)
    first = integrate("rk4", model, y0, t, 0.01)
    again = integrate("rk4", model, y0, t, 0.01)
    _same(again, first)
    assert not any(len(k[0]) > 8 * fixed._KEEP_SIZE for k in model.__dict__[fixed._RECORD].plans)


def test_an_exception_in_the_loop_is_a_failed_status_not_a_raise(monkeypatch):
    from rk4h.fast import solve as fast_solve

    model = _chain(3)
    y0, t = _state(model), np.array([0.0, 0.1])
    integrate("rk4", model, y0, t, 0.01)

    def broken(*a, **k):
        raise RuntimeError("loop broke")

    monkeypatch.setattr(fast_solve, "run_loop", broken)
    run = integrate("rk4", model, y0, t, 0.01)
    assert run.status.name == "FAILED" and "loop broke" in run.message and np.isnan(run.y).all()


def test_a_change_inside_a_wrapped_model_drops_the_record():
    from rk4h.references.solvers import fixed

    model = rk4h.make_model("planar4", {"m": 1.0, "k": 1.0, "l": 1.0})
    y0, t = _state(model), np.array([0.0, 0.1])
    integrate("rk4", model, y0, t, 0.01)
    record = model.__dict__[fixed._RECORD]
    integrate("rk4", model, y0, t, 0.01)
    assert model.__dict__[fixed._RECORD] is record  # unchanged: kept
    model.definition.mass[0] *= 2.0
    integrate("rk4", model, y0, t, 0.01)
    assert model.__dict__[fixed._RECORD] is not record


@pytest.mark.parametrize("solver, setting", [("rk4", 0.01), ("cvode-adams", 1e-8), ("dop853", 1e-8)])
def test_every_cached_path_sees_a_model_changed_in_place(solver, setting):
    """One change detection (``rk4h.models.base.model_current``) serves every
    per-object cache: after an in-place change between two calls, the short
    path, the fingerprint, the kept constants (Gershgorin bound, modes,
    CVODE's Jacobian), the compiled kernels and the kept state checks all
    give what a new model with the new parameters gives."""
    from rk4h.models.base import model_fingerprint

    def build(k):
        return rk4h.make_model("chain", {"masses": [1.0, 1.1, 1.2], "springs": k})

    springs = [1.0, 1.05, 1.1, 1.15]
    model = build(springs)
    y0, t = model.state([0.01, -0.02, 0.015]), np.array([0.0, 0.05, 0.3])
    for _ in range(2):  # the second call answers from every cache
        first = integrate(solver, model, y0, t, setting)
    old_print, old_modes = model_fingerprint(model), model.modes()[0]
    model.k[1] *= 3.0  # in place, between two calls
    new = build(list(model.k))
    changed = integrate(solver, model, y0, t, setting)
    expected = integrate(solver, new, y0, t, setting)
    np.testing.assert_array_equal(changed.y, expected.y)
    assert (changed.nfev, changed.n_steps, changed.status, changed.message) == \
           (expected.nfev, expected.n_steps, expected.status, expected.message)
    assert not np.array_equal(changed.y, first.y)
    assert model_fingerprint(model) == model_fingerprint(new) != old_print
    np.testing.assert_array_equal(model.modes()[0], new.modes()[0])
    assert not np.array_equal(model.modes()[0], old_modes)
    # a state accepted before is refused once the change makes its energy overflow, on every path
    model.k[0] = 1e300
    big = model.state([1e5, 0.0, 0.0])
    with pytest.raises(ValueError, match=r"`y0` must be a state of chain") as known:
        integrate(solver, model, big, t, setting)
    with pytest.raises(ValueError) as fresh:
        integrate(solver, build(list(model.k)), big, t, setting)
    assert str(known.value) == str(fresh.value)


@pytest.mark.parametrize("entry", ["ensemble", "solve_model"])
@pytest.mark.parametrize("change", ["in place", "rebinding"])
def test_the_compiled_entry_points_see_a_changed_model(entry, change):
    """``rk4h.ensemble`` and ``rk4h.fast.solve_model`` take the model's kept
    compiled kernel without a state check first: after a change between two
    calls they too give what a new model with the new parameters gives (they
    used to run the old kernel)."""
    import rk4h.fast

    def build():
        return rk4h.make_model("chain", {"masses": [1.0, 2.0, 0.5], "springs": [1.0, 3.0, 2.0, 1.0],
                                         "alpha": 0.25, "beta": 1.5})

    def change_it(m):
        if change == "in place":
            m.k[1] = 30.0
        else:
            m.beta = 5.0

    y0 = np.array([[0.1, 0.0, -0.1, 0.0, 0.0, 0.0], [0.05, 0.02, 0.0, 0.0, 0.1, 0.0]])
    t = np.linspace(0.0, 1.0, 11)
    if entry == "ensemble":
        def run(m):
            return rk4h.ensemble(m, y0, (0.0, 1.0), h=0.01, t_eval=t, backend="numba").y
    else:
        def run(m):
            return rk4h.fast.solve_model(m, (0.0, 1.0), y0[0], h=0.01, t_eval=t).y
    model = build()
    first = run(model)
    run(model)  # the second call answers from the kept kernel
    change_it(model)
    new = build()
    change_it(new)
    got, expected = run(model), run(new)
    assert not np.array_equal(expected, first)
    np.testing.assert_array_equal(got, expected)


def test_a_changed_model_refuses_a_state_its_short_path_accepted_before():
    model = rk4h.make_model("chain", {"masses": [1.0, 1.1], "springs": [1.0, 1.0, 1.0], "alpha": 0.25})
    t = np.array([0.0, 0.05])
    y_big = model.state([1e5, 0.0])
    integrate("rk4", model, model.state([0.01, 0.0]), t, 0.01)
    integrate("rk4", model, y_big, t, 0.01)  # accepted on the short path (compiled state test)
    integrate("rk4", model, y_big, t, 0.01)  # and kept
    model.k[0] = 1e300  # k r^2 / 2 overflows at r = 1e5
    with pytest.raises(ValueError, match=r"its energy is not finite"):
        integrate("rk4", model, y_big, t, 0.01)


def test_a_copied_model_changed_after_the_copy_is_noticed():
    """``copy.copy`` shares the change record in the copy's attributes: the
    copy is checked against its own attributes, not the original's."""
    import copy

    model = _chain(3, alpha=0.25)
    y0, t = _state(model), np.array([0.0, 0.05, 0.3])
    integrate("rk4", model, y0, t, 0.01)
    integrate("rk4", model, y0, t, 0.01)
    twin = copy.copy(model)
    twin.k = model.k * 2.0  # rebound on the copy only
    expected = integrate("rk4", rk4h.make_model("chain", {"masses": list(model.mass), "springs": list(twin.k),
                                                          "alpha": 0.25}), y0, t, 0.01)
    _same(integrate("rk4", twin, y0, t, 0.01), expected)
    _same(integrate("rk4", model, y0, t, 0.01), integrate("rk4", _chain(3, alpha=0.25), y0, t, 0.01))


def test_a_rebinding_inside_a_held_model_is_noticed():
    """An attribute rebound on a model a Defined model holds (its
    definition) is found by identity; one rebound on the model itself voids
    its change record at once (``Model.__setattr__``)."""
    from rk4h.models.base import model_current

    model = rk4h.make_model("triangle", example_parameters("triangle"))
    y0, t = _state(model), np.array([0.0, 0.1])
    first = integrate("rk4", model, y0, t, 0.01)
    integrate("rk4", model, y0, t, 0.01)
    assert model_current(model)
    model.definition.k = model.definition.k * 2.0  # rebound, not changed in place
    assert not model_current(model)  # noticed, every per-object cache dropped
    assert model_current(model)  # and recorded as it now is
    changed = integrate("rk4", model, y0, t, 0.01)
    assert not np.array_equal(changed.y, first.y)
    _same(integrate("rk4", model, y0, t, 0.01), changed)
    model.mass = model.mass  # a rebinding on the model itself, even to the same array
    assert not model_current(model)


@pytest.mark.parametrize("how", ["pickle", "deepcopy", "copy"])
def test_a_model_that_ran_every_path_pickles_and_copies(how):
    """Per-object caches (compiled loops, the compiled state test, the change
    record) are not part of a model's state: a model that ran the general
    and short paths (with a new ``y0``) and CVODE pickles and copies, and the
    copy gives the same numbers."""
    import copy
    import pickle

    model = _chain(3, alpha=0.25)
    y0, t = _state(model), np.array([0.0, 0.1])
    first = integrate("rk4", model, y0, t, 0.01)
    integrate("rk4", model, 1.1 * y0, t, 0.01)
    integrate("cvode-adams", model, y0, t, 1e-8)
    twin = {"pickle": lambda m: pickle.loads(pickle.dumps(m)), "deepcopy": copy.deepcopy,
            "copy": copy.copy}[how](model)
    assert not any(k.startswith("_fixed") or k.startswith("_rk4h") for k in twin.__dict__)
    _same(integrate("rk4", twin, y0, t, 0.01), first)
    _same(integrate("rk4", twin, 1.1 * y0, t, 0.01), integrate("rk4", model, 1.1 * y0, t, 0.01))
