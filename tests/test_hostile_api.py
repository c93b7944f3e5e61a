"""Hostile inputs to ``rk4h.solve`` and the compiled fast path
(``rk4h.fast.solve_model``): each is refused with a one-line
``ValueError`` naming the argument, or handled correctly; statuses say what
happened; the generated-loop cache trusts nothing it has not verified.

1. ``fun`` is never evaluated outside ``t_span`` (scipy gh-17341).
2. Coercions: complex ``y0`` (kept on the generic path, refused on the model
   paths), string/bool ``y0``, bad ``fun`` return values, step counts and
   output sizes past the caps, a ``t_span`` whose width overflows.
3. Unbounded growth stops the run (``max_growth``, ``y_scale``, ``reason``).
4. Division by zero in a compiled kernel is a non-finite state (status -1),
   as on the generic path, not a ``ZeroDivisionError``.
5. The generated-loop cache directory and files are verified before use.
"""
import json
import math
import os
import stat
import subprocess
import sys
import time
import warnings

import numpy as np
import pytest

import rk4h
import rk4h.fast as fast
from rk4h.validate import MAX_OUTPUT_BYTES, MAX_STEPS, check_model_y0

CASE1 = {"masses": [0.815, 3.099], "springs": [41.5, 138.0, 157.8]}
DBL_MAX = np.finfo(float).max


def case1():
    model = rk4h.make_model("chain", CASE1)
    return model, model.state([0.005, 0.005])


def rotation(t, y):
    """y' = [y1, -y0]: a harmonic oscillator with omega = 1."""
    return np.array([y[1], -y[0]])


def raises_one_line(name, call):
    """``call()`` raises ValueError whose one-line message names `name`."""
    with pytest.raises(ValueError, match=f"`{name}") as info:
        call()
    assert "\n" not in str(info.value)
    return str(info.value)


# -- 1. fun is never evaluated outside t_span ---------------------------------

# (id, t_span, h): scipy's test_tbound_respected_small_interval (gh-17341)
# adapted to a fixed step, on tiny and ordinary spans where t_i + c h of the
# last step rounded one ulp past t1 before the fix.
TBOUND_CASES = [
    ("scipy-0.05-h-0.05/11", (0.0, 0.05), 0.05 / 11),
    ("tiny-1e-13-h-1e-13/7", (0.0, 1e-13), 1e-13 / 7),
    ("tiny-1e-13-h-1e-13/30", (0.0, 1e-13), 1e-13 / 30),
    ("tiny-7e-13-h-7e-13/13", (0.0, 7e-13), 7e-13 / 13),
    ("0.3-h-0.03", (0.0, 0.3), 0.03),
    ("offset-1-to-1+1e-13", (1.0, 1.0 + 1e-13), 1e-13 / 7),
]


@pytest.mark.parametrize("method", ["rk4", "euler", "symplectic-euler"])
@pytest.mark.parametrize("t_span, h", [c[1:] for c in TBOUND_CASES], ids=[c[0] for c in TBOUND_CASES])
def test_tbound_respected_small_interval(t_span, h, method):
    t0, t1 = t_span
    calls = []

    def fun(t, y):
        assert t0 <= t <= t1, f"fun evaluated at t = {t!r}, outside t_span = [{t0!r}, {t1!r}]"
        calls.append(t)
        return 2 * y

    # A point inside the last step needs the end slope, evaluated at t1.
    t_eval = [t0, t1 - 0.3 * h, t1]
    for kw in ({}, {"t_eval": t_eval}):
        res = rk4h.solve(fun, t_span, [1.0, 0.5], h=h, method=method, **kw)
        assert res.success, res.message
        assert res.t[-1] == t1 and res.t.max() <= t1
    if method == "rk4":  # its last stage and the end slope are at t1 itself
        assert max(calls) == t1


def test_tbound_respected_random_spans():
    # 2000 seeded (t1, n) pairs over 18 decades of t1 (before the fix, about
    # one in eight evaluated fun one ulp past t1 on the last RK4 step).
    rng = np.random.default_rng(17341)
    t1s = 10.0 ** rng.uniform(-13, 5, 2000) * rng.uniform(1.0, 10.0, 2000)
    ns = rng.integers(1, 40, 2000)
    bad = []
    for t1, n in zip(t1s, ns):
        t1 = float(t1)
        seen = []

        def fun(t, y, t1=t1, seen=seen):
            if not 0.0 <= t <= t1:
                seen.append(t)
            return np.zeros(1)  # stable at every step size: only the times matter

        step = t1 / n
        res = rk4h.solve(fun, (0.0, t1), [1.0], n_steps=int(n), t_eval=[0.0, t1 - 0.5 * step, t1])
        if seen or not res.success or res.t[-1] != t1:
            bad.append((t1, int(n), seen[:1]))
    assert bad == [], f"{len(bad)} of 2000 (t1, n) pairs evaluated fun outside t_span, e.g. {bad[:3]}"


@pytest.mark.parametrize("path", ["generic", "fast"])
def test_grid_ends_exactly_at_t1_and_never_passes_it(path):
    model, y0 = case1()
    for t1, n in [(0.3, 10), (0.1, 3), (1e-13, 7), (0.05, 11)]:
        if path == "generic":
            res = rk4h.solve(model.rhs, (0.0, t1), y0, n_steps=n)
        else:
            res = fast.solve_model(model, (0.0, t1), y0, n_steps=n)
        assert res.t[-1] == t1 and np.all(res.t <= t1) and np.all(np.diff(res.t) >= 0)


# -- 2. coercions ---------------------------------------------------------------

COMPLEX_Y0 = [
    ("complex-list", lambda: [1.0 + 0.5j, -0.25j]),
    ("complex-tuple", lambda: (1.0 + 0.5j, -0.25j)),
    ("complex128-ndarray", lambda: np.array([1.0 + 0.5j, -0.25j])),
    ("complex64-ndarray", lambda: np.array([1.0 + 0.5j, -0.25j], dtype=np.complex64)),
    ("mixed-real-complex-list", lambda: [1.0, -0.25j]),
]


@pytest.mark.parametrize("make_y0", [c[1] for c in COMPLEX_Y0], ids=[c[0] for c in COMPLEX_Y0])
@pytest.mark.parametrize("with_t_eval", [False, True], ids=["grid", "t_eval"])
def test_complex_y0_is_integrated_with_its_imaginary_part(make_y0, with_t_eval):
    # y' = -i w y: y(t) = y0 exp(-i w t). RK4's error after one period at
    # w h = 0.05 is ~ w t (w h)^4 / 120 ~ 3e-7 of |y0|; dropping the
    # imaginary part would be off by O(1).
    w = 2.0
    y0 = make_y0()
    y0_exact = np.asarray(y0, dtype=complex)
    kw = {"t_eval": np.linspace(0.0, math.pi, 7) + 0.01} if with_t_eval else {}
    if with_t_eval:
        kw["t_eval"][-1] = math.pi
    res = rk4h.solve(lambda t, y: -1j * w * y, (0.0, math.pi), y0, h=0.025, **kw)
    assert res.success and res.y.dtype == np.complex128
    exact = y0_exact[:, None] * np.exp(-1j * w * res.t)[None, :]
    assert np.max(np.abs(res.y - exact)) < 1e-5 * np.max(np.abs(y0_exact))
    assert np.max(np.abs(res.y[:, -1].imag)) > 0.1  # the imaginary part is there


@pytest.mark.parametrize("make_y0", [c[1] for c in COMPLEX_Y0], ids=[c[0] for c in COMPLEX_Y0])
def test_complex_y0_refused_on_model_paths(make_y0):
    model, _ = case1()
    y0 = make_y0()  # doubled to the model's length, 4, in the same container
    y0 = np.concatenate([y0, y0]) if isinstance(y0, np.ndarray) else type(y0)(list(y0) * 2)
    msg = raises_one_line("y0", lambda: fast.solve_model(model, (0.0, 1.0), y0, h=0.1))
    assert "complex" in msg
    raises_one_line("y0", lambda: check_model_y0(model, y0))


BAD_Y0 = [
    ("string", "abc"),
    ("bytes", b"ab"),
    ("list-of-strings", ["1", "2"]),
    ("ndarray-of-strings", np.array(["1.0", "2.0"])),
    ("list-of-bools", [True, False]),
    ("bool-ndarray", np.array([True])),
    ("number-and-bool", [1.0, True]),
    ("number-and-string", [1.0, "2"]),
    ("object-with-dict", np.array([1.0, {"a": 1}], dtype=object)),
    ("ragged", [[1.0], [1.0, 2.0]]),
    ("int-too-large", [10**400, 1]),
]


@pytest.mark.parametrize("y0", [c[1] for c in BAD_Y0], ids=[c[0] for c in BAD_Y0])
@pytest.mark.parametrize("path", ["generic", "fast"])
def test_string_and_bool_y0_refused(y0, path):
    if path == "generic":
        raises_one_line("y0", lambda: rk4h.solve(lambda t, y: -y, (0.0, 1.0), y0, h=0.1))
    else:
        model = rk4h.make_model("oscillator2d", {"m": 1.0, "kx": 1.0, "ky": 1.0})
        raises_one_line("y0", lambda: fast.solve_model(model, (0.0, 1.0), y0, h=0.1))


def _calls_then(value, good_calls=0):
    """A right-hand side for a 2-state system that returns ``-y`` for its
    first ``good_calls`` calls, then ``value(y)``."""
    count = [0]

    def fun(t, y):
        count[0] += 1
        return -y if count[0] <= good_calls else value(y)

    return fun


BAD_FUN = [
    ("none", lambda y: None, "None"),
    ("scalar", lambda y: 1.0, "shape ()"),
    ("numpy-scalar", lambda y: np.float64(1.0), "shape ()"),
    ("length-1-for-2-states", lambda y: np.array([1.0]), "shape (1,)"),
    ("wrong-shape-3", lambda y: np.zeros(3), "shape (3,)"),
    ("column-2x1", lambda y: np.zeros((2, 1)), "shape (2, 1)"),
    ("complex-for-real-y0", lambda y: 1j * y, "complex"),
    ("strings", lambda y: ["a", "b"], "<U1"),
    ("bools", lambda y: np.array([True, False]), "bool"),
    ("dict", lambda y: {"a": 1}, "shape ()"),
]


@pytest.mark.parametrize("good_calls", [0, 7], ids=["first-call", "later-call"])
@pytest.mark.parametrize("value, what", [c[1:] for c in BAD_FUN], ids=[c[0] for c in BAD_FUN])
@pytest.mark.parametrize("with_t_eval", [False, True], ids=["grid", "t_eval"])
def test_bad_fun_return_refused_naming_fun(value, what, good_calls, with_t_eval):
    kw = {"t_eval": [0.0, 0.33, 1.0]} if with_t_eval else {}
    msg = raises_one_line("fun", lambda: rk4h.solve(_calls_then(value, good_calls), (0.0, 1.0), [1.0, 2.0],
                                                       h=0.1, **kw))
    assert what in msg and "expected an array of shape (2,) and dtype float64" in msg
    assert "non-finite" not in msg


@pytest.mark.parametrize("value", [lambda y: [y[1], -y[0]], lambda y: np.array([1, 2]),
                                   lambda y: np.array([1.0, 2.0], dtype=np.float32), lambda y: (y[1], -y[0])],
                         ids=["list", "int-array", "float32-array", "tuple"])
def test_array_like_fun_returns_still_work(value):
    res = rk4h.solve(lambda t, y: value(y), (0.0, 1.0), [1.0, 0.0], n_steps=10)
    assert res.success and res.y.dtype == np.float64


def test_real_fun_for_complex_state_is_fine():
    res = rk4h.solve(lambda t, y: np.zeros(2), (0.0, 1.0), [1.0 + 1.0j, 2.0], n_steps=10)
    assert res.success and np.all(res.y == np.array([[1.0 + 1.0j], [2.0]]))


# Sizes past the caps, refused before anything is allocated. Each runs in a
# subprocess with a wall-clock timeout and a 4 GiB address-space limit, so a
# regression can neither hang the suite nor eat the machine's memory.
SIZE_CASES = [
    # (id, path, t_span, kwargs, argument named, text in the message)
    ("h-5e-324", "generic", (0.0, 100.0), {"h": 5e-324}, "h", "inf steps"),
    ("h-1e-12", "generic", (0.0, 100.0), {"h": 1e-12}, "h", "1e+14 steps"),
    ("h-1e-300", "generic", (0.0, 100.0), {"h": 1e-300}, "h", "1e+302 steps"),
    ("h-1e-12-t_eval", "generic", (0.0, 100.0), {"h": 1e-12, "t_eval": [100.0]}, "h", "MAX_STEPS"),
    ("n_steps-1e11", "generic", (0.0, 1.0), {"n_steps": 10**11, "t_eval": [1.0]}, "n_steps", "MAX_STEPS"),
    ("h-output-32GiB", "generic", (0.0, 1.0), {"h": 1e-9}, "h", "2**33"),
    ("n_steps-output-32GiB", "generic", (0.0, 1.0), {"n_steps": 10**9}, "n_steps", "2**33"),
    ("t_span-overflow", "generic", (-1e308, 1e308), {"h": 1.0}, "t_span", "overflows"),
    ("fast-h-5e-324", "fast", (0.0, 100.0), {"h": 5e-324}, "h", "inf steps"),
    ("fast-h-1e-12", "fast", (0.0, 100.0), {"h": 1e-12}, "h", "1e+14 steps"),
    ("fast-h-1e-300", "fast", (0.0, 100.0), {"h": 1e-300}, "h", "1e+302 steps"),
    ("fast-n_steps-1e11", "fast", (0.0, 1.0), {"n_steps": 10**11, "t_eval": [1.0]}, "n_steps", "MAX_STEPS"),
    ("fast-h-output-32GiB", "fast", (0.0, 1.0), {"h": 1e-9}, "h", "2**33"),
    ("fast-record_every-output", "fast", (0.0, 1.0), {"n_steps": 10**9, "record_every": 2}, "record_every",
     "2**33"),
    ("fast-t_span-overflow", "fast", (-1e308, 1e308), {"h": 1.0}, "t_span", "overflows"),
]

_SIZE_CHILD = """
import json, resource, sys, time
resource.setrlimit(resource.RLIMIT_AS, (4 << 30, 4 << 30))
import numpy as np, rk4h, rk4h.fast as fast
model = rk4h.make_model("chain", {"masses": [1.0, 2.0], "springs": [1.0, 2.0, 3.0]})
y0 = [0.01, 0.0, 0.0, 0.0]
for case, path, t_span, kw in json.loads(sys.argv[1]):
    start = time.perf_counter()
    try:
        if path == "generic":
            rk4h.solve(model.rhs, tuple(t_span), y0, **kw)
        else:
            fast.solve_model(model, tuple(t_span), y0, **kw)
        out = {"type": None, "message": ""}
    except BaseException as e:
        out = {"type": type(e).__name__, "message": str(e)}
    out["elapsed"] = time.perf_counter() - start
    print(json.dumps({"case": case, **out}), flush=True)
"""


@pytest.fixture(scope="module")
def size_results():
    """Every SIZE_CASES call in one child process (one interpreter start-up, not
    fifteen); a case that hangs or eats memory still fails the suite (timeout,
    4 GiB address-space limit)."""
    cases = [[c[0], c[1], c[2], c[3]] for c in SIZE_CASES]
    proc = subprocess.run([sys.executable, "-c", _SIZE_CHILD, json.dumps(cases)],
                          capture_output=True, text=True, timeout=120)
    results = {}
    for line in proc.stdout.splitlines():
        if line.startswith("{"):
            r = json.loads(line)
            results[r.pop("case")] = r
    return proc, results


@pytest.mark.parametrize("case, path, t_span, kw, name, text", SIZE_CASES, ids=[c[0] for c in SIZE_CASES])
def test_step_count_and_output_size_caps(size_results, case, path, t_span, kw, name, text):
    proc, results = size_results
    assert case in results, f"the child died before this case: rc {proc.returncode}, {proc.stderr[-2000:]}"
    out = results[case]
    assert out["type"] == "ValueError", out
    assert f"`{name}`" in out["message"] and text in out["message"] and "\n" not in out["message"]
    assert out["elapsed"] < 5.0


def test_caps_are_documented_values():
    assert MAX_STEPS == 10**10 and MAX_OUTPUT_BYTES == 2**33
    # Just under the output cap is allowed (not run: n_steps decides).
    model, y0 = case1()
    res = fast.solve_model(model, (0.0, 1.0), y0, n_steps=10**6, record_every=10**6)
    assert res.success and res.t.shape == (2,)


BAD_TIMES = [
    ("t_eval-nan", {"h": 0.1, "t_eval": [0.0, np.nan]}, "t_eval"),
    ("t_eval-text", {"h": 0.1, "t_eval": ["a", "b"]}, "t_eval"),
    ("t_span-nan", {"h": 0.1, "t_span": (0.0, np.nan)}, "t_span"),
    ("t_span-text", {"h": 0.1, "t_span": ("0", "1")}, "t_span"),
    ("t_span-overflow", {"h": 1.0, "t_span": (-1e308, 1e308)}, "t_span"),
    ("t_span-overflow-n_steps", {"n_steps": 10, "t_span": (-1.5e308, 1.5e308)}, "t_span"),
]


@pytest.mark.parametrize("kw, name", [c[1:] for c in BAD_TIMES], ids=[c[0] for c in BAD_TIMES])
@pytest.mark.parametrize("path", ["generic", "fast"])
def test_bad_times_refused_naming_them(kw, name, path):
    kw = dict(kw)
    t_span = kw.pop("t_span", (0.0, 1.0))
    model, y0 = case1()
    if path == "generic":
        raises_one_line(name, lambda: rk4h.solve(model.rhs, t_span, y0, **kw))
    else:
        raises_one_line(name, lambda: fast.solve_model(model, t_span, y0, **kw))


# -- 3. statuses that hide trouble: unbounded growth ------------------------------

def exp_growth(t, y):
    return y


GROWTH = [
    # (id, fun, y0, kwargs, reason, expected t_fail (one step of slack), |y| bound)
    ("exp-default-1e8", exp_growth, [1.0, -0.5], {}, "growth", math.log(1e8), 1e8),
    ("exp-max_growth-1e3", exp_growth, [1.0, -0.5], {"max_growth": 1e3}, "growth", math.log(1e3), 1e3),
    ("exp-y_scale", exp_growth, [1.0, 1e-3], {"y_scale": [1.0, 1e-6]}, "growth", math.log(1e8 * 1e-6 / 1e-3),
     None),
    # y = e^t - 1 from y0 = 0: the first non-zero state y_1 = e^h - 1 sets the
    # scale, so the run stops where e^t - 1 > 1e8 (e^h - 1).
    ("zero-y0-scale-from-first-state", lambda t, y: y + 1.0, [0.0], {}, "growth",
     math.log(1.0 + 1e8 * math.expm1(0.01)), None),
    ("nan-from-fun", lambda t, y: np.full_like(y, np.nan), [1.0, 2.0], {}, "non-finite", 0.01, None),
    ("inf-from-fun", lambda t, y: np.full_like(y, np.inf), [1.0, 2.0], {"max_growth": None}, "non-finite",
     0.01, None),
    ("nan-with-growth-off", lambda t, y: y * np.nan, [1.0], {"max_growth": None}, "non-finite", 0.01, None),
]


@pytest.mark.parametrize("fun, y0, kw, reason, t_fail, bound", [c[1:] for c in GROWTH], ids=[c[0] for c in GROWTH])
@pytest.mark.parametrize("with_t_eval", [False, True], ids=["grid", "t_eval"])
def test_unbounded_growth_stops_the_run(fun, y0, kw, reason, t_fail, bound, with_t_eval):
    h = 0.01
    if with_t_eval:
        kw = dict(kw, t_eval=np.linspace(0.0, 40.0, 13))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        res = rk4h.solve(fun, (0.0, 40.0), y0, h=h, **kw)
    assert not res.success and res.status == -1 and res.reason == reason
    assert res.t_fail == pytest.approx(t_fail, abs=1.01 * h)
    assert f"t = {res.t_fail:.6g}" in res.message and f"step {res.n_steps + 1} of 4000" in res.message
    assert ("state became non-finite" if reason == "non-finite" else "grew past max_growth") in res.message
    assert np.all(np.isfinite(res.y)) and res.t[-1] < res.t_fail
    if bound is not None:
        assert np.max(np.abs(res.y)) <= bound * np.max(np.abs(y0))
    if not with_t_eval:
        assert res.y.shape[1] == res.n_steps + 1


def test_growth_message_names_component_value_and_bound():
    res = rk4h.solve(exp_growth, (0.0, 40.0), [1.0, 1e-3], h=0.01, y_scale=[1.0, 1e-6])
    assert res.reason == "growth" and "its given scale (|y[1]| = " in res.message
    y_fail = res.message.split("|y[1]| = ")[1].split(" > ")
    assert float(y_fail[0]) > float(y_fail[1].split(")")[0]) == pytest.approx(1e8 * 1e-6)


def test_growth_test_off_keeps_old_behaviour():
    res = rk4h.solve(exp_growth, (0.0, 40.0), [1.0], h=0.01, max_growth=None)
    assert res.success and res.reason == "ok" and res.y[0, -1] == pytest.approx(math.exp(40.0), rel=1e-6)


def test_success_reason_is_ok():
    model, y0 = case1()
    for res in (rk4h.solve(model.rhs, (0.0, 1.0), y0, h=0.01), fast.solve_model(model, (0.0, 1.0), y0, h=0.01)):
        assert res.success and res.status == 0 and res.reason == "ok"


def _thesis_fast_growth_cases():
    model, y0 = case1()
    w = float(model.modes()[0][-1])
    return {
        # Explicit Euler amplifies every mode by sqrt(1 + (w h)^2) a step: at
        # 1e5 steps of 0.01 s the state used to reach 1e180 with success=True.
        "euler-case1-1e5-steps": (model, y0, (0.0, 1000.0), dict(n_steps=100_000, method="euler")),
        # RK4 at w h = 3 > 2 sqrt(2): |R(3i)| = 1.505 a step.
        "rk4-case1-omega-h-3": (model, y0, (0.0, 2000 * 3.0 / w), dict(n_steps=2000, method="rk4")),
    }


FAST_GROWTH = [
    ("default", {}, "growth"),
    ("per-group-y_scale", {"y_scale": [0.005, 0.005, 0.1, 0.1]}, "growth"),
    ("max_growth-1e3", {"max_growth": 1e3}, "growth"),
    ("growth-off", {"max_growth": None}, "non-finite"),
]


# Euler without a growth bound runs every one of its 1e5 steps on the generic
# path to overflow (about 3 s each): in the slow set.
GROWTH_CASES = [pytest.param(case, extra, reason, id=f"{case}-{cid}",
                             marks=pytest.mark.slow if case.startswith("euler") and reason == "non-finite" else ())
                for cid, extra, reason in FAST_GROWTH
                for case in ("euler-case1-1e5-steps", "rk4-case1-omega-h-3")]


@pytest.mark.parametrize("case, extra, reason", GROWTH_CASES)
@pytest.mark.parametrize("with_t_eval", [False, True], ids=["grid", "t_eval"])
def test_growth_stop_same_on_both_paths(case, extra, reason, with_t_eval):
    model, y0, t_span, kw = _thesis_fast_growth_cases()[case]
    kw = dict(kw, **extra)
    if with_t_eval:
        kw["t_eval"] = np.linspace(*t_span, 777)
    gen = rk4h.solve(model.rhs, t_span, y0, **kw)
    res = fast.solve_model(model, t_span, y0, **kw)
    assert not gen.success and gen.status == res.status == -1 and gen.reason == res.reason == reason
    assert res.t_fail == gen.t_fail and res.message == gen.message
    assert (res.n_steps, res.nfev, res.h, res.dense) == (gen.n_steps, gen.nfev, gen.h, gen.dense)
    np.testing.assert_array_equal(res.t, gen.t)
    np.testing.assert_array_equal(res.y, gen.y)
    if reason == "growth":  # long before overflow
        assert np.max(np.abs(res.y)) < 1e12


BAD_GROWTH_ARGS = [
    ("max_growth-zero", {"max_growth": 0.0}, "max_growth"),
    ("max_growth-below-1", {"max_growth": 0.5}, "max_growth"),
    ("max_growth-negative", {"max_growth": -1e8}, "max_growth"),
    ("max_growth-nan", {"max_growth": float("nan")}, "max_growth"),
    ("max_growth-inf", {"max_growth": float("inf")}, "max_growth"),
    ("max_growth-text", {"max_growth": "1e8"}, "max_growth"),
    ("max_growth-bool", {"max_growth": True}, "max_growth"),
    ("y_scale-short", {"y_scale": [1.0, 1.0]}, "y_scale"),
    ("y_scale-zero", {"y_scale": [1.0, 0.0, 1.0, 1.0]}, "y_scale"),
    ("y_scale-negative", {"y_scale": [1.0, -1.0, 1.0, 1.0]}, "y_scale"),
    ("y_scale-nan", {"y_scale": [1.0, np.nan, 1.0, 1.0]}, "y_scale"),
    ("y_scale-text", {"y_scale": "abcd"}, "y_scale"),
    ("y_scale-scalar", {"y_scale": 1.0}, "y_scale"),
]


@pytest.mark.parametrize("kw, name", [c[1:] for c in BAD_GROWTH_ARGS], ids=[c[0] for c in BAD_GROWTH_ARGS])
@pytest.mark.parametrize("path", ["generic", "fast"])
def test_bad_growth_arguments_refused(kw, name, path):
    model, y0 = case1()
    if path == "generic":
        raises_one_line(name, lambda: rk4h.solve(model.rhs, (0.0, 1.0), y0, h=0.1, **kw))
    else:
        raises_one_line(name, lambda: fast.solve_model(model, (0.0, 1.0), y0, h=0.1, **kw))


def test_all_zero_state_on_both_paths_is_fine():
    # An equilibrium stays exactly zero: the scale is never set, the run succeeds.
    model, _ = case1()
    y0 = np.zeros(4)
    gen = rk4h.solve(model.rhs, (0.0, 10.0), y0, h=0.01)
    res = fast.solve_model(model, (0.0, 10.0), y0, h=0.01)
    assert gen.success and res.success and np.all(gen.y == 0) and np.all(res.y == 0)


# -- 4. division by zero in the compiled kernels ---------------------------------

def _on_anchor():
    model = rk4h.make_model("planar4", {"m": 1.0, "k": 1.0, "l": 1.0})
    return model, model.state(list(model.anchors[1]))  # spring 1 has length 0


def _on_anchor_below():
    model = rk4h.make_model("planar4", {"m": 1.0, "k": 1.0, "l": 1.0})
    return model, model.state(list(model.anchors[2]), [0.0, 0.0])


def _triangle_coincident():
    # Mass 1 displaced onto mass 0: bond (0, 1) has length 0.
    model = rk4h.make_model("triangle", {"m": 1.0, "k": 10.0, "side": 1.0})
    return model, model.state([0.0, 0.0, -1.0, 0.0, 0.0, 0.0])


ZERO_LENGTH = {"planar4-on-anchor": _on_anchor, "planar4-on-lower-anchor": _on_anchor_below,
               "triangle-coincident-masses": _triangle_coincident}


@pytest.mark.parametrize("method", ["rk4", "euler", "symplectic-euler"])
@pytest.mark.parametrize("case", sorted(ZERO_LENGTH))
@pytest.mark.parametrize("with_t_eval", [False, True], ids=["grid", "t_eval"])
def test_zero_spring_length_is_status_minus_one_on_both_paths(case, method, with_t_eval):
    model, y0 = ZERO_LENGTH[case]()
    kw = dict(n_steps=4, method=method)
    if with_t_eval:
        kw["t_eval"] = [0.0, 0.1, 1.0]
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        gen = rk4h.solve(model.rhs, (0.0, 1.0), y0, **kw)
        res = fast.solve_model(model, (0.0, 1.0), y0, **kw)  # no ZeroDivisionError
    assert gen.status == res.status == -1 and gen.reason == res.reason == "non-finite"
    assert res.t_fail == gen.t_fail == 0.25 and res.message == gen.message
    np.testing.assert_array_equal(res.y, gen.y)


def test_every_kernel_divides_as_numpy():
    from rk4h.fast import _kernels, codegen
    from rk4h.methods import RK4

    dispatchers = [v for v in vars(_kernels).values() if hasattr(v, "targetoptions")]
    assert len(dispatchers) >= 2
    for d in dispatchers:
        assert d.targetoptions.get("error_model") == "numpy", d
    kern = fast.force_kernel(case1()[0])
    for text in (codegen.source(RK4, kern), codegen.model_source(kern)):
        n_jit = text.count("@njit(")
        assert n_jit >= 1 and text.count('error_model="numpy"') == n_jit


# -- 5. the generated-loop cache ----------------------------------------------------

SENTINEL_CODE = ("import pathlib\n"
                 "pathlib.Path({sentinel!r}).write_text('planted module was executed')\n"
                 "def integrate(*args):\n"
                 "    raise SystemExit('planted')\n")


@pytest.fixture
def fresh_codegen(monkeypatch):
    """No generated loop loaded in this process (restored afterwards)."""
    from rk4h.fast import codegen

    before = {k for k in sys.modules if k.startswith("_rk4core_fast_gen_")}
    monkeypatch.setattr(codegen, "_KERNELS", {})
    for k in before:
        monkeypatch.delitem(sys.modules, k)
    yield codegen
    for k in [k for k in sys.modules if k.startswith("_rk4core_fast_gen_")]:
        sys.modules.pop(k, None)


def _euler_name(codegen):
    from rk4h.methods import EULER

    text = codegen.source(EULER, fast.force_kernel(case1()[0]))
    return codegen.module_name(text), text


def _run_euler():
    model, y0 = case1()
    res = fast.solve_model(model, (0.0, 0.5), y0, h=0.01, method="euler")
    gen = rk4h.solve(model.rhs, (0.0, 0.5), y0, h=0.01, method="euler")
    assert res.success
    np.testing.assert_array_equal(res.y, gen.y)


def _root_0777(root):
    root.mkdir()
    os.chmod(root, 0o777)
    return root, root / "fast"


def _root_symlink(root):
    real = root.parent / "real-cache"
    real.mkdir(mode=0o700)
    root.symlink_to(real)
    return real, real / "fast"


def _root_other_owner(root):
    root.mkdir(mode=0o700)
    os.chown(root, os.getuid() + 4242, -1)
    return root, root / "fast"


def _fast_0777(root):
    root.mkdir(mode=0o700)
    (root / "fast").mkdir()
    os.chmod(root / "fast", 0o777)
    return root, root / "fast"


UNTRUSTED_DIRS = {"root-mode-0777": _root_0777, "root-is-symlink": _root_symlink,
                  "root-owned-by-another-uid": _root_other_owner, "fast-dir-mode-0777": _fast_0777}


@pytest.mark.parametrize("setup", sorted(UNTRUSTED_DIRS))
def test_untrusted_cache_dir_is_not_used(setup, fresh_codegen, tmp_path, monkeypatch):
    if setup == "root-owned-by-another-uid" and os.getuid() != 0:
        pytest.skip("needs root to chown")
    codegen = fresh_codegen
    root = tmp_path / "cache"
    real_root, fast_dir = UNTRUSTED_DIRS[setup](root)
    fast_dir.mkdir(mode=0o700, exist_ok=True)
    name, _ = _euler_name(codegen)
    sentinel = tmp_path / "sentinel"
    planted = fast_dir / f"{name}.py"
    planted.write_text(SENTINEL_CODE.format(sentinel=str(sentinel)))
    before = sorted(p.name for p in fast_dir.iterdir())
    monkeypatch.setenv("RK4H_CACHE", str(root))
    with pytest.warns(codegen.CacheWarning, match="not using cache directory") as rec:
        _run_euler()  # compiled in memory: the run still works
    assert len(rec) == 1 and "\n" not in str(rec[0].message) and str(root) in str(rec[0].message)
    assert not sentinel.exists(), "the planted module was executed"
    assert sorted(p.name for p in fast_dir.iterdir()) == before  # nothing written or changed there
    assert "planted" in planted.read_text()


def _plant_other_content(path, sentinel):
    path.write_text(SENTINEL_CODE.format(sentinel=str(sentinel)))
    os.chmod(path, 0o600)


def _plant_symlink(path, sentinel):
    target = path.parent.parent.parent / "attacker.py"
    target.write_text(SENTINEL_CODE.format(sentinel=str(sentinel)))
    path.symlink_to(target)


def _plant_group_writable(path, sentinel):
    path.write_text(SENTINEL_CODE.format(sentinel=str(sentinel)))
    os.chmod(path, 0o666)


def _plant_right_text_group_writable(path, sentinel):
    from rk4h.fast import codegen

    path.write_text(_euler_name(codegen)[1])
    os.chmod(path, 0o664)


def _plant_directory(path, sentinel):
    path.mkdir()


PLANTED_FILES = {"other-content": _plant_other_content, "symlink-to-attacker-file": _plant_symlink,
                 "group-writable": _plant_group_writable, "right-text-but-group-writable": _plant_right_text_group_writable,
                 "a-directory": _plant_directory}


@pytest.mark.parametrize("plant", sorted(PLANTED_FILES))
def test_untrusted_generated_file_is_replaced_not_executed(plant, fresh_codegen, tmp_path, monkeypatch):
    from rk4h.cachedir import private_dir
    from rk4h.methods import EULER

    codegen = fresh_codegen
    root = tmp_path / "cache"
    monkeypatch.setenv("RK4H_CACHE", str(root))
    fast_dir = private_dir("fast")  # ours, 0700
    name, text = _euler_name(codegen)
    sentinel = tmp_path / "sentinel"
    path = fast_dir / f"{name}.py"
    PLANTED_FILES[plant](path, sentinel)
    if plant == "a-directory":  # cannot be replaced by a rename: compiled in memory instead
        with pytest.warns(codegen.CacheWarning, match="cannot be rewritten") as rec:
            _run_euler()
        assert len(rec) == 1 and path.is_dir()
        assert codegen._KERNELS[next(iter(codegen._KERNELS))].py_func.__code__.co_filename.startswith("<")
        return
    with pytest.warns(codegen.CacheWarning, match="not trusted and was rewritten") as rec:
        loop = codegen.kernel(EULER, fast.force_kernel(case1()[0]))
    assert len(rec) == 1 and str(path) in str(rec[0].message) and "\n" not in str(rec[0].message)
    assert not sentinel.exists(), "the planted module was executed"
    st = os.lstat(path)
    assert stat.S_ISREG(st.st_mode) and st.st_uid == os.getuid() and stat.S_IMODE(st.st_mode) == 0o600
    assert path.read_bytes() == text.encode()
    assert loop.py_func.__code__.co_filename == str(path)
    if plant == "symlink-to-attacker-file":  # the link is replaced, its target untouched
        assert "planted" in (tmp_path / "attacker.py").read_text()
    # A second load in a fresh process state accepts the file without warning.
    codegen._KERNELS.clear()
    sys.modules.pop(name, None)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        codegen.kernel(EULER, fast.force_kernel(case1()[0]))


@pytest.mark.parametrize("numba_cache_dir", [False, True], ids=["default", "NUMBA_CACHE_DIR-elsewhere"])
def test_trusted_cache_layout_is_private(numba_cache_dir, fresh_codegen, tmp_path, monkeypatch):
    import numba

    codegen = fresh_codegen
    root = tmp_path / "cache"
    other = tmp_path / "numba-elsewhere"
    monkeypatch.setenv("RK4H_CACHE", str(root))
    if numba_cache_dir:
        monkeypatch.setenv("NUMBA_CACHE_DIR", str(other))
        monkeypatch.setattr(numba.config, "CACHE_DIR", str(other))
    name, text = _euler_name(codegen)
    with warnings.catch_warnings():
        warnings.simplefilter("error", codegen.CacheWarning)
        _run_euler()
    for d in (root, root / "fast", root / "fast" / "__pycache__"):
        st = os.lstat(d)
        assert stat.S_ISDIR(st.st_mode) and stat.S_IMODE(st.st_mode) == 0o700 and st.st_uid == os.getuid(), d
    path = root / "fast" / f"{name}.py"
    assert path.read_bytes() == text.encode()
    assert stat.S_IMODE(os.lstat(path).st_mode) & 0o022 == 0
    loop = codegen._KERNELS[next(iter(codegen._KERNELS))]
    assert os.path.realpath(loop._cache.cache_path) == os.path.realpath(root / "fast" / "__pycache__")
    index = [p.name for p in (root / "fast" / "__pycache__").iterdir() if p.name.startswith(name)]
    assert any(n.endswith(".nbi") for n in index) and any(n.endswith(".nbc") for n in index), index
    assert not other.exists()


def test_generated_files_no_longer_in_package_or_tmp(fresh_codegen, tmp_path, monkeypatch):
    import tempfile
    from rk4h.methods import EULER

    codegen = fresh_codegen
    monkeypatch.setenv("RK4H_CACHE", str(tmp_path / "cache"))
    name, _ = _euler_name(codegen)
    pkg = codegen._HERE / "__pycache__" / "generated" / f"{name}.py"
    tmp = os.path.join(tempfile.gettempdir(), f"rk4core-fast-{os.getuid()}", f"{name}.py")
    had = (pkg.exists(), os.path.exists(tmp))
    codegen.kernel(EULER, fast.force_kernel(case1()[0]))
    assert (pkg.exists(), os.path.exists(tmp)) == had
    assert (tmp_path / "cache" / "fast" / f"{name}.py").exists()
