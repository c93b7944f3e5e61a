"""Per-model constants computed once (issue 29): cached results are the
results computed afresh, bit for bit, and each model's own."""
from __future__ import annotations

import gc
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import rk4h
import rk4h.fast.solve as fast_solve
from rk4h.references import truth
from rk4h.references.solvers import integrate
from rk4h.references.solvers.cvode import _linear_jacobian_once, interleave, linear_jacobian
from rk4h.models import base

T = np.array([0.0, 0.05, 0.1])


def _chain(masses, springs=None, **extra):
    springs = [1.0] * (len(masses) + 1) if springs is None else springs
    return rk4h.make_model("chain", {"masses": list(masses), "springs": list(springs), **extra})


@pytest.fixture(autouse=True)
def _fresh():
    base.clear_constants()
    yield
    base.clear_constants()


@pytest.mark.parametrize("solver, setting, extra", [("rk4", 0.01, {"alpha": 0.25}), ("rk4", 0.01, {}),
                                                    ("cvode-adams", 1e-8, {}), ("cvode-bdf", 1e-8, {}),
                                                    ("dop853", 1e-8, {})])
def test_cold_and_warm_runs_identical(solver, setting, extra):
    model = _chain([1.0, 2.0, 0.5, 1.5], **extra)
    y0 = model.state([0.01, -0.02, 0.03, 0.0])
    fast_solve._WARMED.clear()
    cold = integrate(solver, model, y0, T, setting)
    warm = integrate(solver, model, y0, T, setting)
    other = integrate(solver, _chain([1.0, 2.0, 0.5, 1.5], **extra), y0, T, setting)  # shares the constants
    assert cold.ok and warm.ok
    for run in (warm, other):
        np.testing.assert_array_equal(run.y, cold.y)
        assert (run.nfev, run.n_steps, run.atol) == (cold.nfev, cold.n_steps, cold.atol)


def test_models_of_one_class_with_other_parameters_have_their_own_constants():
    # A cache keyed on the class would give b the modes and bound of a.
    a, b = _chain([1.0, 2.0]), _chain([1.0, 2.0], [1.0, 3.0, 1.0])
    wa, wb = a.modes()[0], b.modes()[0]
    assert not np.array_equal(wa, wb)
    np.testing.assert_array_equal(wb, b._compute_modes()[0])
    assert a.omega_bound() != b.omega_bound()
    assert b._gershgorin_w2() == b._compute_gershgorin_w2()


@pytest.mark.slow
def test_a_new_model_at_a_freed_address_gets_its_own_constants():
    # A cache keyed on id() would hand a model built where a dead one lived
    # that one's modes: CPython reuses freed addresses at once.
    for i in range(40):
        model = _chain([1.0, 1.0 + 0.1 * i], [1.0 + 0.1 * i, 1.0, 1.0])
        w, phi = model.modes()
        fresh_w, fresh_phi = model._compute_modes()
        np.testing.assert_array_equal(w, fresh_w)
        np.testing.assert_array_equal(phi, fresh_phi)
        assert model._gershgorin_w2() == model._compute_gershgorin_w2()
        del model
        gc.collect()


def test_kept_modes_have_eighs_layout_and_give_the_same_truth():
    # A C-ordered copy of eigh's Fortran-ordered phi changes BLAS's path in
    # phi.T @ x and so the last bits of the exact-modal truth.
    from rk4h.references.exact import modal_solution

    model = _chain([0.5, 1.0, 2.0, 1.5, 0.7], [3.0, 1.0, 2.0, 5.0, 1.0, 4.0])
    fresh_w, fresh_phi = model._compute_modes()
    y0 = model.state(fresh_phi[:, 1], 0.3 * fresh_phi[:, 3])
    t = np.linspace(0.0, 10.0, 101)
    for _ in range(2):  # cold, then kept
        w, phi = model.modes()
        assert phi.strides == fresh_phi.strides and w.strides == fresh_w.strides
        eta0 = fresh_phi.T @ (model.mass * y0[:5])
        ms = modal_solution(model, y0)
        np.testing.assert_array_equal(ms.eta0, eta0)
        y = ms(t)
        np.testing.assert_array_equal(y, ms(t))
        assert np.array_equal(y[:, 50], modal_solution(model, y0)(t)[:, 50])


def test_equal_parameters_share_and_results_are_copies():
    a, b = _chain([1.0, 2.0]), _chain([1.0, 2.0])
    assert base.model_constants(a) is base.model_constants(b)
    w, phi = a.modes()
    w[:] = -1.0
    phi[:] = 0.0
    w2, phi2 = b.modes()
    np.testing.assert_array_equal(w2, b._compute_modes()[0])
    np.testing.assert_array_equal(phi2, b._compute_modes()[1])


def test_constants_cache_is_bounded():
    for i in range(base.CONSTANTS_MAXSIZE + 10):
        _chain([1.0, 1.0 + i]).omega_bound()
    assert len(base._CONSTANTS) == base.CONSTANTS_MAXSIZE


def test_constants_bytes_are_bounded(monkeypatch):
    # modes of a 20-mass chain: 20 * 8 + 20 * 20 * 8 = 3360 bytes; room for two
    monkeypatch.setattr(base, "CONSTANTS_MAX_BYTES", 7000)
    models = [_chain([1.0 + i] * 20) for i in range(5)]
    for model in models:
        model.modes()
    held = [r.get("_nbytes", 0) for r in base._CONSTANTS.values()]
    assert sum(held) <= 7000 and held.count(3360) == 2
    assert base.model_constants(models[-1]).get("_nbytes") == 3360  # the newest is kept
    for model in models:  # dropped ones are recomputed, the same numbers
        np.testing.assert_array_equal(model.modes()[1], model._compute_modes()[1])


def test_refused_state_is_refused_again_with_the_same_message():
    model = _chain([1.0, 2.0])
    y = model.state([1e200, 0.0])  # k x^2 overflows
    messages = []
    for _ in range(2):
        with pytest.raises(ValueError) as err:
            model.check_state(y)
        messages.append(str(err.value))
    assert messages[0] == messages[1] and "`y0`" in messages[0]
    assert _chain([1.0, 2.0]).state_problem(model.state([0.1, 0.0])) is None


def test_cvode_jacobian_kept_read_only_and_equal_to_a_fresh_one():
    model = _chain([1.0, 2.0, 3.0])
    perm = interleave(model.n_dof)
    kept = _linear_jacobian_once(model, perm)
    assert _linear_jacobian_once(_chain([1.0, 2.0, 3.0]), perm) is kept
    fresh = linear_jacobian(model, perm)
    for k, f in zip(kept[:3], fresh[:3]):
        np.testing.assert_array_equal(k, f)
        assert not k.flags.writeable
    assert kept[3:] == fresh[3:]
    other = _linear_jacobian_once(_chain([1.0, 2.0, 4.0]), perm)
    assert not np.array_equal(other[2], kept[2])


def test_truth_versions_read_once_and_not_shared():
    from rk4h import distributions

    v = truth._versions()
    misses = distributions.version.cache_info().misses
    v["numpy"] = "edited"
    assert truth._versions()["numpy"] == np.__version__
    assert distributions.version.cache_info().misses == misses  # read once: the second call hit the cache


def test_warm_up_runs_a_loop_once_and_gives_the_same_numbers():
    model = _chain([1.0] * 5, alpha=0.5)
    y0 = model.state([0.01 * i for i in range(5)])
    fast_solve._WARMED.clear()
    rk4h.fast.warm_up(model, "rk4")
    loop = fast_solve._loop_of(model, "rk4")
    assert fast_solve._WARMED == {id(loop): loop}
    rk4h.fast.warm_up(model, "rk4")
    assert len(fast_solve._WARMED) == 1
    a = rk4h.fast.solve_model(model, (0.0, 0.1), y0, h=0.01)
    b = rk4h.solve(model.rhs, (0.0, 0.1), y0, h=0.01)
    np.testing.assert_allclose(a.y, b.y, rtol=0, atol=1e-14)


def test_benchmark_checks_bit_identity():
    root = Path(__file__).resolve().parent.parent
    proc = subprocess.run([sys.executable, str(root / "benchmarks" / "bench_fixed_cost.py"), "--calls", "3"],
                          capture_output=True, text=True, timeout=600, cwd=root)
    assert proc.returncode == 0, proc.stderr
    checks = [line for line in proc.stdout.splitlines() if line.startswith("check")]
    assert len(checks) == 2 and all(line.endswith("True") for line in checks), proc.stdout


def test_benchmark_refuses_too_few_calls():
    root = Path(__file__).resolve().parent.parent
    proc = subprocess.run([sys.executable, str(root / "benchmarks" / "bench_fixed_cost.py"), "--calls", "1"],
                          capture_output=True, text=True, timeout=600, cwd=root)
    assert proc.returncode == 2
    assert proc.stderr.strip().splitlines() == ["bench_fixed_cost: `--calls` must be >= 3, got 1"]
