"""The compiled fast path (rk4h.fast) against the generic rk4h.solve.

The fast path repeats the generic path's floating-point operations in the same
order, so the numbers must agree bit for bit where only + - * / sqrt are
involved (correctly rounded everywhere) and to round-off (1e-14 relative, as
issue 5 asks) where numpy's and libm's sin/cos may differ in the last bit --
including where and how a run blows up.
"""
import re

import numpy as np
import pytest

import rk4h
import rk4h.fast as fast
from rk4h.methods import METHODS as METHODS_ALL
from rk4h.methods import Tableau, make_tableau

CASE1 = {"masses": [0.815, 3.099], "springs": [41.5, 138.0, 157.8]}

# (id, model name, parameters, x0, v0): every built-in model and chain wall variant.
MODEL_CASES = [
    ("chain-2dof-case1", "chain", CASE1, [0.005, 0.005], [0.0, 0.0]),
    # nine masses: above the straight-line loop's 8 degrees of freedom, the array loop
    ("chain-walls-none", "chain", {"masses": [1.0, 2.0, 1.5, 0.7, 1.2, 0.9, 1.8, 1.1, 0.6],
                                   "springs": [3.0, 5.0, 4.0, 2.5, 6.0, 3.5, 4.5, 5.5], "walls": "none"},
     [0.003, -0.001, 0.002, 0.0, -0.002, 0.001, 0.0, 0.004, -0.003],
     [0.01, 0.0, -0.02, 0.005, 0.0, 0.0, -0.01, 0.0, 0.02]),
    ("chain-walls-left", "chain", {"masses": [1.0, 2.0, 1.5], "springs": [3.0, 5.0, 4.0], "walls": "left"},
     [0.003, -0.001, 0.002], [0.0, 0.01, 0.0]),
    ("chain-walls-right", "chain", {"masses": [1.0, 2.0, 1.5], "springs": [3.0, 5.0, 4.0], "walls": "right"},
     [0.003, -0.001, 0.002], [0.0, 0.01, 0.0]),
    ("planar4-exact", "planar4", {"m": 0.5, "k": 20.0, "l": 0.01}, [0.004, -0.003], [0.02, 0.05]),
    ("planar4-linear", "planar4", {"m": 0.5, "k": 20.0, "l": 0.01, "linear": True}, [0.004, -0.003], [0.02, 0.05]),
    ("pendulums-exact", "pendulums", {"m": 1.0, "length": 1.0, "g": 9.81, "k": 2.0}, [0.6, -0.2], [0.0, 0.5]),
    ("pendulums-linear", "pendulums", {"m": 1.0, "length": 1.0, "g": 9.81, "k": 2.0, "linear": True},
     [0.6, -0.2], [0.0, 0.5]),
    ("triangle", "triangle", {"m": 1.0, "k": 10.0, "side": 1.0},
     [0.05, -0.02, 0.0, 0.03, -0.04, 0.01], [0.0, 0.1, -0.1, 0.0, 0.05, 0.0]),
    ("oscillator2d", "oscillator2d", {"m": 1.0, "kx": 2.0, "ky": 4.0}, [0.005, 0.002], [0.0, 0.01]),
    # Integer powers above 2 in the force (the FPUT beta tension, a quartic and a
    # quintic potential): products in both paths, so exact (rk4h.expr.POWER_PRODUCTS_MAX)
    ("chain-fput-alpha-beta", "chain", {"masses": [1.0, 1.5, 0.8], "springs": [1.0, 2.0, 1.5, 1.0],
                                        "alpha": 0.25, "beta": 0.5}, [0.6, -0.8, 0.4], [0.0, 0.1, 0.0]),
    ("potential-quintic", "potential", {"coordinates": ["x", "y"], "masses": 1.0, "constants": {"c": 0.5},
                                        "potential": "x^4/4 + y^4/4 + c*x^2*y^2 - y^3/3 + x^5/5"},
     [0.9, -0.7], [0.1, 0.0]),
]
METHODS = ["rk4", "euler", "symplectic-euler"]


def _model(case):
    _, name, params, x0, v0 = case
    model = rk4h.make_model(name, params)
    return model, model.state(x0, v0)


def _exact(model) -> bool:
    """True when the model's compiled force uses no transcendental function."""
    kern = fast.force_kernel(model)
    text = kern.array_source() + kern.slope_source()
    return not any(f"math.{f}" in text for f in ("sin", "cos", "tan", "exp", "log"))


def _assert_same(fast_res, gen_res, rtol=1e-14, exact=False):
    """Same grid, counters, status and message; states bit-identical when
    ``exact``, else within rtol of the generic path's largest component."""
    assert fast_res.success == gen_res.success
    assert fast_res.status == gen_res.status
    assert fast_res.message == gen_res.message
    assert fast_res.t_fail == gen_res.t_fail
    assert (fast_res.n_steps, fast_res.nfev, fast_res.h) == (gen_res.n_steps, gen_res.nfev, gen_res.h)
    assert fast_res.dense == gen_res.dense and fast_res.method == gen_res.method
    np.testing.assert_array_equal(fast_res.t, gen_res.t)
    assert fast_res.y.shape == gen_res.y.shape
    if exact:
        np.testing.assert_array_equal(fast_res.y, gen_res.y)
    scale = np.max(np.abs(gen_res.y))
    assert np.max(np.abs(fast_res.y - gen_res.y)) <= rtol * scale


# Every model with RK4 (the models of up to 8 degrees of freedom on the
# straight-line loop, the 9-mass chain on the array loop), and every method on
# the two loop forms (a 2-mass chain: straight-line; a 9-mass chain: arrays). The method is data the generator
# reads; the model is the force text it inlines: together they cover the
# product without compiling a loop for each (model, method) pair (each costs
# about a second on a cold cache).
FAST_CASES = [(c, "rk4") for c in MODEL_CASES] + \
    [(MODEL_CASES[i], m) for i in (0, 1) for m in METHODS if m != "rk4"]


@pytest.mark.parametrize("case, method", FAST_CASES, ids=[f"{c[0]}-{m}" for c, m in FAST_CASES])
def test_fast_equals_generic_every_step(case, method):
    model, y0 = _model(case)
    assert fast.supports(model)
    kw = dict(h=0.01, method=method)
    _assert_same(fast.solve_model(model, (0.0, 1.5), y0, **kw), rk4h.solve(model.rhs, (0.0, 1.5), y0, **kw),
                 exact=_exact(model))


@pytest.mark.parametrize("case", MODEL_CASES, ids=[c[0] for c in MODEL_CASES])
def test_fast_equals_generic_t_eval(case):
    # Off-grid points (Hermite), grid points, repeated points and both ends.
    model, y0 = _model(case)
    t_eval = np.array([0.0, 0.0, 0.013, 0.25, 0.25, 0.2501, 0.7, 1.0 / 3.0 + 0.5, 1.5])
    t_eval.sort()
    kw = dict(h=0.01, t_eval=t_eval)
    res = fast.solve_model(model, (0.0, 1.5), y0, **kw)
    assert res.dense == "hermite"
    _assert_same(res, rk4h.solve(model.rhs, (0.0, 1.5), y0, **kw), exact=_exact(model))


def test_t_eval_on_grid_is_returned_exactly():
    model, y0 = _model(MODEL_CASES[0])
    every = fast.solve_model(model, (0.0, 2.0), y0, h=0.01)
    t_eval = every.t[::7]
    res = fast.solve_model(model, (0.0, 2.0), y0, h=0.01, t_eval=t_eval)
    assert res.dense == "grid"
    np.testing.assert_array_equal(res.y, every.y[:, ::7])
    assert res.nfev == 4 * res.n_steps  # no Hermite end slopes needed


def test_custom_tableau_is_data_not_code():
    # Heun's second-order method: a tableau neither path has seen by name.
    heun = Tableau("heun", np.array([[0.0, 0.0], [1.0, 0.0]]), np.array([0.5, 0.5]), np.array([0.0, 1.0]), 2)
    model, y0 = _model(MODEL_CASES[6])
    kw = dict(n_steps=120, method=heun)
    _assert_same(fast.solve_model(model, (0.0, 1.2), y0, **kw), rk4h.solve(model.rhs, (0.0, 1.2), y0, **kw))


def test_large_chain_equals_generic():
    # O(N) tridiagonal kernel on a random 2000-mass chain, free ends.
    rng = np.random.default_rng(5)
    N = 2000
    model = rk4h.make_model("chain", {"masses": list(rng.uniform(0.5, 2.0, N)),
                                         "springs": list(rng.uniform(1.0, 3.0, N - 1)), "walls": "none"})
    y0 = np.concatenate([rng.normal(0, 1e-3, N), rng.normal(0, 1e-3, N)])
    kw = dict(n_steps=50, method="rk4")
    _assert_same(fast.solve_model(model, (0.0, 1.0), y0, **kw), rk4h.solve(model.rhs, (0.0, 1.0), y0, **kw))


# Blow-ups: RK4 on an undamped mode is stable for h omega < 2 sqrt(2) and
# amplifies by |R(i h omega)| > 1 per step beyond; explicit Euler by
# sqrt(1 + (h omega)^2) always. Planar4 with a huge step throws the mass through
# an anchor region where the force is huge or undefined.
BLOWUP_CASES = [
    ("chain-rk4", 0, "rk4", 0.5),           # h omega_max = 8.1 > 2.83
    ("chain-euler", 0, "euler", 0.3),
    ("chain-symplectic-euler", 0, "symplectic-euler", 0.5),  # stable only for h omega < 2
    ("planar4-exact-rk4", 4, "rk4", 1.0),
    ("pendulums-linear-rk4", 7, "rk4", 2.0),
    ("triangle-rk4", 8, "rk4", 1.5),
    ("chain9-array-rk4", 1, "rk4", 1.5),   # the array loop
]


# Each blow-up is stopped either by the growth test (default max_growth = 1e8:
# a component past 1e8 times max|y0|) or, with the growth test off, when the
# state becomes non-finite; both paths must stop at the same step, bit for bit.
STOP_RULES = [("growth", {}), ("non-finite", {"max_growth": None})]


@pytest.mark.parametrize("case_i, method, h", [c[1:] for c in BLOWUP_CASES], ids=[c[0] for c in BLOWUP_CASES])
@pytest.mark.parametrize("with_t_eval", [False, True], ids=["every-step", "t_eval"])
@pytest.mark.parametrize("reason, rule", STOP_RULES, ids=[r[0] for r in STOP_RULES])
def test_blow_up_same_as_generic(case_i, method, h, with_t_eval, reason, rule):
    model, y0 = _model(MODEL_CASES[case_i])
    t_span = (0.0, 2000.0)
    kw = dict(h=h, method=method, **rule)
    if with_t_eval:
        kw["t_eval"] = np.linspace(*t_span, 1001)
    gen = rk4h.solve(model.rhs, t_span, y0, **kw)
    assert not gen.success  # the case must actually blow up
    res = fast.solve_model(model, t_span, y0, **kw)
    assert res.status == -1 and res.reason == gen.reason == reason
    assert ("non-finite" if reason == "non-finite" else "grew past max_growth") in res.message
    _assert_same(res, gen)
    np.testing.assert_array_equal(res.y, gen.y)  # bit for bit up to the stop
    assert np.all(np.isfinite(res.y))


# Growth stops named in the task: explicit Euler on 2-DOF case 1 (|R| =
# sqrt(1 + (h w)^2) > 1 every step) for 1e5 steps, and RK4 at omega_max h = 3,
# beyond its stability limit 2 sqrt(2) = 2.83 (|R(3i)| = 1.505 per step).
def _case1_rk4_beyond_limit():
    model, y0 = _model(MODEL_CASES[0])
    w = float(model.modes()[0][-1])
    return model, y0, (0.0, 2000 * 3.0 / w), dict(n_steps=2000, method="rk4")


def _case1_euler_1e5():
    model, y0 = _model(MODEL_CASES[0])
    return model, y0, (0.0, 1000.0), dict(n_steps=100_000, method="euler")


GROWTH_CASES = {"euler-case1-1e5-steps": _case1_euler_1e5, "rk4-case1-omega-h-3": _case1_rk4_beyond_limit}


@pytest.mark.parametrize("scale", ["initial", "given"])
@pytest.mark.parametrize("name", sorted(GROWTH_CASES))
def test_growth_stop_bit_identical_to_generic(name, scale):
    model, y0, t_span, kw = GROWTH_CASES[name]()
    if scale == "given":  # per-group scales: positions 5 mm, velocities 0.1 m/s
        kw["y_scale"] = [0.005, 0.005, 0.1, 0.1]
    gen = rk4h.solve(model.rhs, t_span, y0, **kw)
    res = fast.solve_model(model, t_span, y0, **kw)
    assert gen.reason == res.reason == "growth" and gen.status == res.status == -1
    assert f"its {scale} scale" in res.message
    assert res.n_steps < kw["n_steps"] and res.t_fail == gen.t_fail and res.message == gen.message
    np.testing.assert_array_equal(res.t, gen.t)
    np.testing.assert_array_equal(res.y, gen.y)
    assert (res.nfev, res.n_steps) == (gen.nfev, gen.n_steps)


def test_symplectic_euler_stable_below_its_limit():
    # Symplectic Euler on x'' = -w^2 x is stable for h w < 2 (trace of the
    # one-step matrix is 2 - (h w)^2): just below the limit no blow-up.
    model = rk4h.make_model("oscillator2d", {"m": 1.0, "kx": 1.0, "ky": 1.0})
    res = fast.solve_model(model, (0.0, 2000.0), model.state([1.0, 0.5]), h=1.99, method="symplectic-euler",
                           record_every=1000)
    assert res.success


@pytest.mark.parametrize("every", [1, 7, 150])
def test_record_every_keeps_every_kth_step_and_the_last(every):
    model, y0 = _model(MODEL_CASES[4])
    full = rk4h.solve(model.rhs, (0.0, 1.0), y0, n_steps=100)
    res = fast.solve_model(model, (0.0, 1.0), y0, n_steps=100, record_every=every)
    cols = sorted(set(range(0, 101, every)) | {100})
    np.testing.assert_array_equal(res.t, full.t[cols])
    assert np.max(np.abs(res.y - full.y[:, cols])) <= 1e-14 * np.max(np.abs(full.y))
    assert res.n_steps == 100 and res.nfev == 400


def test_supports_only_builtin_models():
    model, _ = _model(MODEL_CASES[0])

    class MyChain(type(model)):
        def _force(self, x, ops):  # a user's change the compiled kernel does not know
            return 2.0 * super()._force(x, ops)

    assert fast.supports(model)
    assert not fast.supports(MyChain(**model.params()))
    assert not fast.supports(object())
    with pytest.raises(ValueError, match="`model`"):
        fast.solve_model(MyChain(**model.params()), (0.0, 1.0), [0.0] * 4, h=0.1)


@pytest.mark.parametrize("kwargs, name", [
    (dict(y0=[0.0, 0.0, 0.0], h=0.1), "y0"),
    (dict(y0=[0.0] * 4, h=0.1, record_every=0), "record_every"),
    (dict(y0=[0.0] * 4, h=0.1, record_every=2, t_eval=[0.0, 1.0]), "record_every"),
    (dict(y0=[0.0] * 4, h=-0.1), "h"),
    (dict(y0=[0.0] * 4, h=0.1, method="rk5"), "method"),
    (dict(y0=[0.0] * 4, h=0.1, t_eval=[0.0, 2.0]), "t_eval"),
])
def test_bad_arguments_raise_value_error_naming_them(kwargs, name):
    model, _ = _model(MODEL_CASES[0])
    y0 = kwargs.pop("y0")
    with pytest.raises(ValueError, match=f"`{name}"):
        fast.solve_model(model, (0.0, 1.0), y0, **kwargs)


def test_warm_up_reports_compile_time_apart_and_signatures_stay_few():
    from rk4h.fast import codegen

    assert fast.warm_up() >= 0.0
    assert fast.compile_time() is not None and fast.compile_time() >= 0.0
    for case, method in [(MODEL_CASES[0], m) for m in METHODS] + [(MODEL_CASES[i], "rk4") for i in (6, 8)]:
        model, y0 = _model(case)
        assert fast.warm_up(model, method) >= 0.0
        fast.solve_model(model, (0.0, 0.1), y0, h=0.01, method=method, t_eval=[0.0, 0.055, 0.1])
    # Each generated loop serves one (method, force structure): one signature each.
    loops = [fn for key, fn in codegen._KERNELS.items() if key[0] in ("loop", "array")]
    assert loops
    for fn in loops:
        assert len(fn.signatures) == 1


@pytest.mark.parametrize("same, other", [
    (("chain", {"masses": [2.0, 0.3], "springs": [1.0, 7.0, 3.0]}), MODEL_CASES[4]),
    (("pendulums", {"m": 0.2, "length": 1.0, "g": 1.6, "k": 2.0}), MODEL_CASES[9]),
], ids=["chain", "pendulums"])
def test_one_generated_loop_per_method_and_structure(same, other):
    # The loop's text depends on the definition's structure, not its numbers (except
    # that a factor 1 or a term 0 simplifies away, as length = 1 and k/2 = 1 here):
    # a model of the same structure with other parameters reuses it.
    from rk4h.fast import codegen

    heun = Tableau("heun", np.array([[0.0, 0.0], [1.0, 0.0]]), np.array([0.5, 0.5]), np.array([0.0, 1.0]), 2)
    first = {"chain": MODEL_CASES[0], "pendulums": MODEL_CASES[6]}[same[0]]
    model, y0 = _model(first)
    fast.solve_model(model, (0.0, 0.1), y0, n_steps=3, method=heun)
    before = codegen.compiled_kernels()
    twin = rk4h.make_model(*same)
    assert fast.force_kernel(twin).key() == fast.force_kernel(model).key()
    res = fast.solve_model(twin, (0.0, 0.1), y0, n_steps=3, method=heun)
    assert codegen.compiled_kernels() == before
    np.testing.assert_array_equal(res.y, rk4h.solve(twin.rhs, (0.0, 0.1), y0, n_steps=3, method=heun).y)
    other_model, y0o = _model(other)
    fast.solve_model(other_model, (0.0, 0.1), y0o, n_steps=3, method=heun)
    assert codegen.compiled_kernels() == before + 1


def test_generated_source_skips_zero_coefficients():
    # RK4 has 3 nonzero a_ij and 4 nonzero b_i: one product h * coefficient
    # for each and each half (q, v) of the state, and no other.
    from rk4h.fast import _kernels, codegen
    from rk4h.methods import RK4

    model, _ = _model(MODEL_CASES[0])
    text = codegen.source(RK4, fast.force_kernel(model))
    n_products = sum(1 for line in text.splitlines() if line.strip().startswith(("hq", "hv")) and "= step *" in line)
    assert n_products == 2 * (np.count_nonzero(RK4.A) + np.count_nonzero(RK4.b))
    assert "* 0.0" not in text
    # The force is inline straight-line code: the stages and the Hermite end slope each divide by m1.
    assert text.count("/ m0") == RK4.n_stages + 1


# Sums that extend the stage state's (rk4h.fast.codegen._Held): a splitting
# method's stage is the one before plus one drift, so the loop adds that term
# to the held value -- the same roundings as the whole sum. A row that shares
# only slopes with the held one (Kutta's third-order method: a_10 = 1/2,
# a_20 = -1) must start from the state; one that begins with it starts from
# the held value in a classical method too (``gap`` below). 2 masses run
# the straight-line loop, 9 the array loop.
KUTTA3 = make_tableau("kutta3", A=[[0, 0, 0], ["1/2", 0, 0], [-1, 2, 0]], b=["1/6", "2/3", "1/6"])
# Partitioned tableaux (not methods anyone would use: consistent, low order)
# that reach the branches no built-in method does: position-first stages
# after the first, whose velocity sums extend the held one before and after
# the diagonal term (``pos_first``); a velocity-first stage that is not
# evaluated, one with a diagonal position term, and a velocity row that
# falls back to the state (``mixed``). And a classical tableau with an
# empty row between two that extend each other (``gap``: the held sum
# survives a call at the state). Found by a review of the change.
POS_FIRST = make_tableau(
    "pos_first", A=[[0, 0, 0, 0], ["1/2", 0, 0, 0], ["1/2", 0, 0, 0], ["1/2", "1/4", "1/4", 0]],
    b=["1/2", "1/4", "1/3", 0], A_v=[[0, 0, 0, 0], ["1/3", 0, 0, 0], ["1/3", "1/6", "1/5", 0], ["1/3", "1/6", "1/5", "1/7"]],
    b_v=["1/3", "1/6", "1/5", "2/7"])
MIXED = make_tableau(
    "mixed", A=[[0, 0, 0, 0, 0], ["1/2", "1/3", 0, 0, 0], ["1/2", 0, 0, 0, 0], ["1/2", "1/3", "1/5", 0, 0],
                ["1/2", "1/3", "1/5", "1/9", 0]], b=["1/2", "1/3", "1/5", "1/9", "1/11"],
    A_v=[[0, 0, 0, 0, 0], ["1/4", 0, 0, 0, 0], ["1/4", "1/8", 0, 0, 0], ["1/4", 0, 0, 0, 0], ["1/4", "1/8", 0, "1/6", "1/7"]],
    b_v=["1/4", "1/8", 0, "1/6", "1/3"])
GAP = make_tableau("gap", A=[[0, 0, 0, 0], ["1/2", 0, 0, 0], [0, 0, 0, 0], ["1/2", 0, "1/2", 0]],
                   b=["1/2", 0, "1/4", "1/4"])
HELD_METHODS = ["stormer-verlet", "blanes-moan4", KUTTA3, POS_FIRST, MIXED, GAP]
OTHER_METHODS = [m for m in sorted(METHODS_ALL) if m not in HELD_METHODS + METHODS]


def _held_cases(methods, forms=(0, 1)):
    return [(MODEL_CASES[i], m) for i in forms for m in methods]


def _held_ids(cases):
    return [f"{case[0]}-{m if isinstance(m, str) else m.name}" for case, m in cases]


# The default set: the four tableaux that reach every branch on the array
# loop, two on the straight-line one (whose text the jax step prints too);
# the rest in the slow set (each case compiles a loop: 2-5 s on a cold
# cache; Stormer-Verlet's loops are also checked by tests/test_verlet.py,
# a splitting method's text by the yoshida6 test below).
HELD_DEFAULT = _held_cases([KUTTA3, POS_FIRST, MIXED, GAP], (1,)) + _held_cases([KUTTA3, MIXED], (0,))
HELD_SLOW = [c for c in _held_cases(HELD_METHODS + OTHER_METHODS) if c not in HELD_DEFAULT]


def _equals_generic_with_outputs(case, method):
    model, y0 = _model(case)
    t_eval = np.array([0.0, 0.013, 0.25, 0.7071, 1.5])
    for kw in (dict(h=0.01, method=method), dict(h=0.01, method=method, t_eval=t_eval)):
        _assert_same(fast.solve_model(model, (0.0, 1.5), y0, **kw), rk4h.solve(model.rhs, (0.0, 1.5), y0, **kw),
                     exact=True)


@pytest.mark.parametrize("case, method", HELD_DEFAULT, ids=_held_ids(HELD_DEFAULT))
def test_sums_from_the_held_stage_equal_generic(case, method):
    _equals_generic_with_outputs(case, method)


@pytest.mark.slow
@pytest.mark.parametrize("case, method", HELD_SLOW, ids=_held_ids(HELD_SLOW))
def test_every_other_method_and_loop_form_equals_generic(case, method):
    _equals_generic_with_outputs(case, method)


def test_a_splitting_stage_adds_one_drift_and_kutta3_starts_from_the_state():
    from rk4h.fast import codegen
    from rk4h.methods import get_method

    model, _ = _model(MODEL_CASES[1])
    kern = fast.force_kernel(model)
    yoshida6 = get_method("yoshida6")
    text = codegen.array_source(yoshida6, kern)
    sums = [line.split("=", 1)[1] for line in text.splitlines() if line.strip().startswith(("yi[p] =", "v ="))]
    # Seven Stormer-Verlet sub-steps: each sum adds at most two slopes to the
    # held value (a sub-step's position row has two).
    assert max(s.count("* k[") for s in sums) <= 2
    assert sum(s.count("* k[") for s in sums) < 30  # 134 when every sum starts from the state
    # The new position is the last stage's, as the drift-kick loop has it.
    assert "            v = yi[p]" in text
    # Only the products the loop uses are formed.
    assert text.count("= step *") == len(set(re.findall(r"\bh[qv]b?_[0-9_]+\b", text.split("for i in range(n)")[1])))
    kutta = codegen.array_source(KUTTA3, kern)
    assert "yi[p] = y[p] + hq_2_0 * k[0, p] + hq_2_1 * k[1, p]" in kutta
    gap = codegen.array_source(GAP, kern)  # stage 3 extends stage 1 across stage 2, taken at the state
    assert "yi[p] = yi[p] + hq_3_2 * k[2, p]" in gap


def _kernel_args(model):
    kern = fast.force_kernel(model)
    return kern, (np.ascontiguousarray(kern.fp), np.ascontiguousarray(kern.ip), np.ascontiguousarray(model.mass))


def _array_loop(kern, fp, ip, mass, y0, step, n, tab, *rest):
    from rk4h.fast import codegen

    return codegen.array_kernel(tab, kern)(fp, ip, mass, np.zeros(kern.work_size), y0, 0.0, step, n, *rest)


# The two forms on the models of 3 to 8 degrees of freedom that run the
# straight-line loop: the array loop with one wall, with FPUT tension, and a
# network's, against it (each compiles one array loop on a cold cache).
FORM_CASES = [(0, m) for m in METHODS] + [(i, "rk4") for i in (2, 3, 8, 10)]


@pytest.mark.parametrize("case_i, method", FORM_CASES, ids=[f"{MODEL_CASES[i][0]}-{m}" for i, m in FORM_CASES])
def test_straight_line_loop_is_bit_identical_to_array_loop(case_i, method):
    # The two generated forms of one (method, force) pair -- scalar locals and
    # arrays -- do the same arithmetic in the same order.
    from rk4h.fast import codegen
    from rk4h.fast.solve import _output_points
    from rk4h.methods import get_method

    model, y0 = _model(MODEL_CASES[case_i])
    assert not codegen.array_loop(fast.force_kernel(model), y0.size)
    kern, (fp, ip, mass) = _kernel_args(model)
    tab = get_method(method)
    n, step = 150, 0.01
    idx, theta, _ = _output_points(0.0, step, n, np.array([0.0, 0.013, 0.5, 0.7071, 1.5]), 1)
    ys_arr, ys_sl = np.empty((idx.size, y0.size)), np.empty((idx.size, y0.size))
    bound = np.full(y0.size, np.finfo(float).max)
    fail_arr, fail_sl = np.zeros(y0.size), np.zeros(y0.size)
    ret_arr = _array_loop(kern, fp, ip, mass, y0, step, n, tab, idx, theta, ys_arr, bound.copy(), 0.0, fail_arr)
    ret_sl = codegen.kernel(tab, kern)(fp, ip, mass, y0, 0.0, step, n, idx, theta, ys_sl, bound.copy(), 0.0,
                                       fail_sl)
    assert tuple(ret_sl) == tuple(ret_arr) and ret_arr[2] == 0
    np.testing.assert_array_equal(ys_sl, ys_arr)


# Kernel-level stops: a tight bound (growth), and a bound still to be set
# from the first state (``pending``: as for an all-zero y0), then tight.
KERNEL_STOPS = [("tight-bound", 1e4, 0.0), ("pending-scale", np.finfo(float).max, 3.0)]


@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("stop, bound0, pending", KERNEL_STOPS, ids=[k[0] for k in KERNEL_STOPS])
def test_generated_loop_stops_where_generic_loop_stops(stop, bound0, pending, method):
    from rk4h.fast import codegen
    from rk4h.fast.solve import _output_points
    from rk4h.methods import get_method

    model, y0 = _model(MODEL_CASES[0])  # chain case 1, at omega_max h = 3: unstable for every method here
    kern, (fp, ip, mass) = _kernel_args(model)
    tab = get_method(method)
    n, step = 400, 3.0 / float(model.modes()[0][-1])
    bound = np.full(y0.size, bound0 * (np.max(np.abs(y0)) if stop == "tight-bound" else 1.0))
    idx, theta, _ = _output_points(0.0, step, n, None, 1)
    out = {}
    for which in ("generic", "generated"):
        ys, b, y_fail = np.full((idx.size, y0.size), np.nan), bound.copy(), np.zeros(y0.size)
        if which == "generic":
            ret = _array_loop(kern, fp, ip, mass, y0, step, n, tab, idx, theta, ys, b, pending, y_fail)
        else:
            ret = codegen.kernel(tab, kern)(fp, ip, mass, y0, 0.0, step, n, idx, theta, ys, b, pending, y_fail)
        out[which] = (tuple(ret), ys, b, y_fail)
    (ret_g, ys_g, b_g, f_g), (ret_f, ys_f, b_f, f_f) = out["generic"], out["generated"]
    assert ret_g == ret_f and ret_g[2] == -1 and 0 < ret_g[0] < n
    np.testing.assert_array_equal(ys_f, ys_g)
    np.testing.assert_array_equal(b_f, b_g)
    np.testing.assert_array_equal(f_f, f_g)
    assert np.all(np.isfinite(f_g)) and np.any(np.abs(f_g) > b_g)
    if stop == "pending-scale":  # set from the first state: 3 max|y_1|
        assert b_g[0] == 3.0 * np.max(np.abs(ys_g[1])) and np.all(b_g == b_g[0])


def test_finite_state_whose_sum_overflows_is_not_a_blow_up():
    # The loop tests finiteness on the sum of the state; two finite
    # components of 1.5e308 sum to inf, which must not stop the run.
    model = rk4h.make_model("oscillator2d", {"m": 1.0, "kx": 1e-300, "ky": 1e-300})
    y0 = np.array([1.5e308, 1.5e308, 0.0, 0.0])
    kw = dict(n_steps=10, method="euler")
    res = fast.solve_model(model, (0.0, 1.0), y0, **kw)
    assert res.success
    _assert_same(res, rk4h.solve(model.rhs, (0.0, 1.0), y0, **kw))


def test_second_process_loads_the_loops_from_the_disk_cache():
    # After this process has compiled (or loaded) them, a new process finds
    # every loop it needs in numba's on-disk cache: no compilation.
    import subprocess
    import sys

    model, y0 = _model(MODEL_CASES[0])
    fast.warm_up(model, "rk4")
    code = ("import rk4h, rk4h.fast as fast\n"
            "from rk4h.fast import _kernels, codegen\n"
            f"m = rk4h.make_model('chain', {CASE1!r})\n"
            "fast.warm_up(m, 'rk4')\n"
            "(loop,) = codegen._KERNELS.values()\n"
            "print(sum(loop.stats.cache_misses.values()), sum(loop.stats.cache_hits.values()))\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120, check=True)
    misses, hits = map(int, out.stdout.split())
    assert (misses, hits) == (0, 1)


def test_same_array_text_other_edge_list_gets_its_own_loop():
    # Two one-mass networks: the same array source (dim 2, harmonic springs)
    # but different edge lists, so different straight-line loops; each must
    # equal its own generic-path run (a shared loop would be wrong for one).
    a = rk4h.make_model("planar4", {"m": 0.5, "k": 20.0, "l": 1.0})
    b = rk4h.make_model("network", {"dim": 2, "masses": [0.5], "positions": [0.0, 0.0],
                                       "anchors": [-1.0, 0.0, 0.0, 2.0, 1.5, -1.0],
                                       "springs": [[0, 1, 20.0], [0, 2, 7.0], [0, 3, 3.0]]})
    assert fast.force_kernel(a).key() == fast.force_kernel(b).key()
    assert fast.force_kernel(a).scalar_key() != fast.force_kernel(b).scalar_key()
    for model in (a, b):
        y0 = model.state([0.1, -0.05], [0.0, 0.2])
        np.testing.assert_array_equal(fast.solve_model(model, (0.0, 1.0), y0, h=0.01).y,
                                      rk4h.solve(model.rhs, (0.0, 1.0), y0, h=0.01).y)


def test_a_force_patched_onto_the_class_disables_the_compiled_path(monkeypatch):
    # The compiled kernels are printed from the definition; a force or
    # right-hand side assigned onto the class afterwards is not in them.
    from rk4h.models.chain import Chain

    model, y0 = _model(MODEL_CASES[1])
    assert fast.supports(model)
    monkeypatch.setattr(Chain, "_force", lambda self, q, ops: 0.0 * q)
    patched = rk4h.make_model("chain", dict(MODEL_CASES[1][2]))
    assert not fast.supports(patched)
