"""CVODE's per-call glue (issue 29): the compiled right-hand side called from
one Python frame through its numba entry point, and the constant Jacobian of
a linear model written once. Same steps, same counts, the same numbers bit
for bit as the glue before (a closure over the numba dispatcher, the
Jacobian written at every call), and counts equal to CVODE's own."""
import numpy as np
import pytest
import sksundae.cvode as skc

from rk4h.references.solvers import Status, absolute_tolerance
from rk4h.references.solvers import cvode
from rk4h.fast.solve import compiled_entry
from rk4h.references.solvers.base import compiled_rhs

from _cvode_cases import CASES, T, case


def run(solver, model, y0, rtol, max_steps=cvode.DEFAULT_MAX_STEPS):
    return cvode.run_cvode(solver, model, y0, T, rtol, absolute_tolerance(model, y0, rtol), max_steps)


class _ClosureGlue:
    """The glue before issue 29's round 3: only ``permuted`` (a closure over
    the numba dispatcher), so ``run_cvode`` takes that path."""

    def __init__(self, fast):
        self.permuted = fast.permuted


@pytest.mark.parametrize("name", sorted(CASES))
@pytest.mark.parametrize("solver", ["cvode-adams", "cvode-bdf"])
def test_one_frame_glue_gives_the_closure_glue_bit_for_bit(monkeypatch, name, solver):
    model, y0 = case(name)
    rtol = 1e-9
    new = run(solver, model, y0, rtol)
    fast = compiled_rhs(model)
    monkeypatch.setattr(cvode, "compiled_rhs", lambda m: _ClosureGlue(fast))
    old = run(solver, model, y0, rtol)
    assert new.status is Status.OK and old.status is Status.OK
    assert (new.n_steps, new.nfev) == (old.n_steps, old.nfev) and new.n_steps > 0
    for key in ("nfev_cvode", "nfev_jac_dq", "njev"):
        assert new.extra[key] == old.extra[key], key
    np.testing.assert_array_equal(new.y, old.y)


@pytest.mark.parametrize("name", ["chain-2dof", "pendulums"])
def test_compiled_glue_against_the_numpy_right_hand_side(monkeypatch, name):
    # model.rhs through numpy: the same steps and counts; states equal to the
    # round-off of the compiled force (bit for bit for the linear chain)
    model, y0 = case(name)
    rtol = 1e-9
    new = run("cvode-adams", model, y0, rtol)
    monkeypatch.setattr(cvode, "compiled_rhs", lambda m: None)
    ref = run("cvode-adams", model, y0, rtol)
    assert new.extra["rhs"] == "compiled" and ref.extra["rhs"] == "numpy"
    assert (new.n_steps, new.nfev) == (ref.n_steps, ref.nfev)
    if name == "chain-2dof":
        np.testing.assert_array_equal(new.y, ref.y)
    else:
        np.testing.assert_allclose(new.y, ref.y, rtol=0, atol=1e-12 * np.max(np.abs(ref.y)))


@pytest.mark.parametrize("name", sorted(CASES))
@pytest.mark.parametrize("solver", ["cvode-adams", "cvode-bdf"])
def test_nfev_equals_an_independent_count_and_cvodes_counters(monkeypatch, name, solver):
    real = skc.CVODE
    counted = [0]

    def counting(rhsfn, **opts):  # counts every call CVODE makes of the glue it was given
        def f(t, z, zp):
            counted[0] += 1
            return rhsfn(t, z, zp)

        return real(f, **opts)

    model, y0 = case(name)
    plain = run(solver, model, y0, 1e-8)
    monkeypatch.setattr(skc, "CVODE", counting)
    r = run(solver, model, y0, 1e-8)
    assert r.status is Status.OK
    # the counting wrapper hides the solver's layout: the statistics path is not
    # used then, and the one-step loop takes the same steps
    assert (r.n_steps, r.nfev) == (plain.n_steps, plain.nfev)
    assert plain.extra["counters"] == "cvode-stats"
    assert plain.nfev == counted[0] == plain.extra["nfev_cvode"] + plain.extra["nfev_jac_dq"]
    np.testing.assert_array_equal(r.y, plain.y)


def test_constant_jacobian_written_once_equals_written_every_call(monkeypatch):
    model, y0 = case("chain-2dof")
    once = run("cvode-bdf", model, y0, 1e-10)
    assert once.extra["linsolver"] == "dense" and once.extra["njev"] > 1
    real_options = cvode._options
    writes = [0]

    def every_call(model, perm, *args):
        opts = real_options(model, perm, *args)
        rows, cols, vals, _, _ = cvode._linear_jacobian_once(model, perm)

        def jacfn(t, z, zp, JJ):
            writes[0] += 1
            JJ[:, :] = 0.0
            JJ[rows, cols] = vals

        opts["jacfn"] = jacfn
        return opts

    monkeypatch.setattr(cvode, "_options", every_call)
    every = run("cvode-bdf", model, y0, 1e-10)
    assert writes[0] == every.extra["njev"] == once.extra["njev"]
    assert (every.n_steps, every.nfev) == (once.n_steps, once.nfev)
    np.testing.assert_array_equal(every.y, once.y)


def test_linear_jacobian_callback_writes_its_array_once():
    model, y0 = case("chain-2dof")
    perm = cvode.interleave(model.n_dof)
    opts = cvode._options(model, perm, "BDF", 1e-8, absolute_tolerance(model, y0, 1e-8), 100)
    rows, cols, vals, _, _ = cvode._linear_jacobian_once(model, perm)
    JJ = np.zeros((4, 4))
    z = y0[perm]
    opts["jacfn"](0.0, z, z, JJ)
    expected = np.zeros((4, 4))
    expected[rows, cols] = vals
    np.testing.assert_array_equal(JJ, expected)
    JJ[0, 1] = -7.0  # not written again: the same array keeps what it holds
    opts["jacfn"](0.0, z, z, JJ)
    assert JJ[0, 1] == -7.0
    other = np.zeros((4, 4))  # a new array is filled
    opts["jacfn"](0.0, z, z, other)
    np.testing.assert_array_equal(other, expected)


def test_compiled_entry_only_for_the_types_it_was_compiled_for():
    model, y0 = case("chain-2dof")
    perm = cvode.interleave(model.n_dof)
    fn, fp, ip, mass, p64, buf, w = compiled_rhs(model).permuted_parts(perm)
    z = y0[perm].copy()
    z.setflags(write=False)  # as scikit-sundae passes the state
    zp_entry, zp_disp = np.empty(4), np.empty(4)
    entry = compiled_entry(fn, (fp, ip, mass, z, zp_entry, p64, buf, w))
    assert entry is not fn and callable(entry)
    assert entry(fp, ip, mass, z, zp_entry, p64, buf, w) == fn(fp, ip, mass, z, zp_disp, p64, buf, w)
    np.testing.assert_array_equal(zp_entry, zp_disp)
    assert np.any(zp_entry != 0.0)
    # types never compiled: the dispatcher itself, also after the entry above
    # was kept (the kept answers are per argument types)
    z32 = z.astype(np.float32)
    assert compiled_entry(fn, (fp, ip, mass, z32, zp_entry, p64, buf, w)) is fn
    swapped = z.astype(">f8")
    assert compiled_entry(fn, (fp, ip, mass, swapped, zp_entry, p64, buf, w)) is fn
    # a writable state: no version of its own (one compiled signature,
    # rk4h.fast.solve._one_signature): the dispatcher, which converts it
    assert compiled_entry(fn, (fp, ip, mass, z.copy(), zp_entry, p64, buf, w)) is fn
    assert compiled_entry(fn, (fp, ip, mass, z, zp_entry, p64, buf, w)) is entry


@pytest.mark.parametrize("solver", ["cvode-adams", "cvode-bdf"])
@pytest.mark.parametrize("cap", [1, 2])
def test_tiny_step_caps_on_the_compiled_glue(solver, cap):
    # the first call picks the entry point; a cap that binds at once still holds
    model, y0 = case("chain-2dof")
    rtol = 1e-9
    atol = absolute_tolerance(model, y0, rtol)
    new = cvode.run_cvode(solver, model, y0, T, rtol, atol, cap)
    loop = cvode._run_cvode(solver, model, y0, T, rtol, atol, cap, one_step_loop=True)
    for r in (new, loop):
        assert r.status is Status.FAILED and f"step cap max_steps = {cap} reached" in r.message
        assert r.n_steps == cap
    assert new.t_fail == loop.t_fail
    np.testing.assert_array_equal(new.y, loop.y)


# -- scipy's DOP853 (the timed rows): the same one-frame glue -------------------------------------

class _CheckedGlue:
    """The DOP853 glue before: ``checked`` only (a method over the dispatcher)."""

    def __init__(self, fast):
        self.checked = fast.checked


@pytest.mark.parametrize("name", ["chain-2dof", "chain-12", "pendulums"])
def test_dop853_one_frame_glue_gives_the_checked_glue_bit_for_bit(monkeypatch, name):
    from rk4h.references.solvers.dop853 import run_dop853

    model, y0 = case(name)
    atol = absolute_tolerance(model, y0, 1e-9)
    new = run_dop853(model, y0, T, 1e-9, atol)
    fast = compiled_rhs(model)
    monkeypatch.setattr("rk4h.references.solvers.dop853.compiled_rhs", lambda m: _CheckedGlue(fast))
    old = run_dop853(model, y0, T, 1e-9, atol)
    assert new.status is Status.OK and old.status is Status.OK and new.extra["rhs"] == "compiled"
    assert (new.n_steps, new.nfev) == (old.n_steps, old.nfev) and new.n_steps > 0
    np.testing.assert_array_equal(new.y, old.y)


def test_dop853_strided_initial_state_goes_through_the_dispatcher():
    # scipy evaluates f(t0, y0) on the y0 it was given (a strided view here):
    # the entry point, made for contiguous vectors, must not read it
    from rk4h.references.solvers.dop853 import run_dop853

    model, y0 = case("pendulums")
    wide = np.zeros((y0.size, 2))
    wide[:, 0] = y0
    strided = wide[:, 0]
    assert not strided.flags.c_contiguous
    atol = absolute_tolerance(model, y0, 1e-8)
    a = run_dop853(model, y0.copy(), T, 1e-8, atol)
    b = run_dop853(model, strided, T, 1e-8, atol)
    assert a.status is Status.OK and (a.n_steps, a.nfev) == (b.n_steps, b.nfev)
    np.testing.assert_array_equal(a.y, b.y)


def test_per_call_benchmark_runs_and_prints_each_split():
    # its own checks: the runs it times give the same steps, nfev and y, and
    # the replay run reproduces the recorded one exactly
    import pathlib
    import re
    import subprocess
    import sys

    root = pathlib.Path(__file__).resolve().parents[1]
    proc = subprocess.run([sys.executable, str(root / "benchmarks" / "bench_cvode.py"), "--per-call", "--tiny"],
                          cwd=root, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    num = r"-?[0-9]+\.[0-9]+"
    for solver in ("cvode-adams", "cvode-bdf"):
        assert re.search(rf"^{solver}: n_steps \d+, nfev \d+, njev \d+ \(dense\); replay: {num} us per call$",
                         proc.stdout, flags=re.M), proc.stdout
    assert len(re.findall(rf"^  new: run {num} = glue {num} \+ jac {num} x {num} \+ sundae\+cvode {num}; "
                          rf"our frames {num}$", proc.stdout, flags=re.M)) == 2, proc.stdout
    assert re.search(rf"^  new: run {num} = RHS wrapper {num} \({num}%\) \+ scipy's stepping {num}$",
                     proc.stdout, flags=re.M), proc.stdout
