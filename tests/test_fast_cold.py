"""Fewer numba compiles on a cold cache (issue 29, "Cold start, round 3").

* The references' compiled right-hand side (``rhs_permuted``) is compiled
  for one signature: CVODE's read-only state and DOP853's writable one run
  the same machine code, and the numbers equal ``model.rhs`` bit for bit.
* A generated loop's text carries no method name: two methods with equal
  coefficients share one file (one compile), and still run the same numbers.
"""
from __future__ import annotations

import numpy as np
import pytest

from rk4h import fast
from rk4h.fast import codegen
from rk4h.fast.solve import compiled_rhs, force_kernel, model_module
from rk4h.methods import get_method, make_tableau
from rk4h.models import Chain


def _chain():
    # five masses with both walls: a structure of its own (its module is not
    # compiled by another test first for another signature)
    return Chain([1.0, 2.0, 3.0, 1.5, 0.7], [1.0, 2.0, 3.0, 4.0, 5.0, 6.0])


def _readonly(a):
    a = np.array(a, dtype=float)
    a.flags.writeable = False
    return a


def test_one_signature_serves_read_only_and_writable_states():
    model = _chain()
    rhs = compiled_rhs(model)
    y = np.linspace(-0.1, 0.2, 2 * model.n_dof)
    expected = model.rhs(0.0, y)
    assert np.array_equal(rhs(0.0, y), expected)  # DOP853's writable state
    out, bad = rhs.checked(_readonly(y))  # a read-only one
    assert np.array_equal(out, expected) and not bad
    perm = np.arange(y.shape[0])[::-1].copy()
    fun = rhs.permuted(perm)  # CVODE's form: read-only z, writable zp
    zp = np.empty(y.shape[0])
    assert not fun(_readonly(y[perm]), zp)
    assert np.array_equal(zp, expected[perm])
    zp2 = np.empty(y.shape[0])
    fun(y[perm].copy(), zp2)
    assert np.array_equal(zp2, zp)
    sigs = model_module(force_kernel(model)).rhs_permuted.signatures
    assert len(sigs) == 1, sigs
    assert sigs[0][3].mutable is False  # the state's type is the read-only one


def test_states_of_other_types_still_give_the_numbers():
    """A strided, Fortran-ordered or list state and a strided output go
    through copies (the compiled signature is C-contiguous float64)."""
    model = _chain()
    rhs = compiled_rhs(model)
    y = np.linspace(0.3, -0.2, 2 * model.n_dof)
    expected = model.rhs(0.0, y)
    wide = np.zeros(2 * y.shape[0])
    wide[::2] = y
    assert np.array_equal(rhs(0.0, wide[::2]), expected)
    assert np.array_equal(rhs(0.0, list(y)), expected)
    out, bad = rhs.checked(y.astype(np.float32).astype(np.float64))
    assert out.shape == expected.shape and not bad
    perm = np.arange(y.shape[0], dtype=np.int64)
    fun = rhs.permuted(perm)
    zp = np.zeros(2 * y.shape[0])
    fun(y, zp[::2])
    assert np.array_equal(zp[::2], expected) and not zp[1::2].any()
    assert len(model_module(force_kernel(model)).rhs_permuted.signatures) == 1


def test_nonfinite_rhs_is_still_flagged():
    """``bad`` (a non-finite dy/dt at a finite state) through the one
    signature, from a read-only and a writable state alike."""
    model = _chain()
    rhs = compiled_rhs(model)
    y = np.full(2 * model.n_dof, 1e308)  # finite; the wall springs' forces overflow
    with np.errstate(over="ignore", invalid="ignore"):
        assert not np.isfinite(model.rhs(0.0, y)).all()
    assert rhs.checked(_readonly(y))[1] and rhs.checked(y)[1]
    assert not rhs.checked(np.zeros_like(y))[1]


def _renamed(name, tab):
    kw = {}
    if tab.partitioned:
        kw = dict(A_v=[list(r) for r in tab.A_v_exact], b_v=list(tab.b_v_exact))
    return make_tableau(name, [list(r) for r in tab.A_exact], list(tab.b_exact), list(tab.c_exact), **kw)


@pytest.mark.parametrize("method", ["rk4", "forest-ruth"])
@pytest.mark.parametrize("n", [2, 9])  # the straight-line loop; the array loop (above 8 masses)
def test_equal_coefficients_share_one_loop_text(method, n):
    tab = get_method(method)
    twin = _renamed(f"{method}-under-another-name", tab)
    assert twin.name != tab.name
    model = Chain([1.0 + 0.5 * i for i in range(n)], [1.0] * (n + 1))
    kern = force_kernel(model)
    text = codegen.source if 2 * n <= codegen.MAX_UNROLLED_DIM else codegen.array_source
    assert text(tab, kern) == text(twin, kern)
    assert codegen.module_name(text(tab, kern)) == codegen.module_name(text(twin, kern))
    # and a method with other coefficients still gets its own text
    assert text(tab, kern) != text(get_method("euler"), kern)
    y0 = np.linspace(0.01, 0.02, 2 * n)
    a = fast.solve_model(model, (0.0, 1.0), y0, n_steps=50, t_eval=[0.0, 0.33, 1.0], method=tab)
    b = fast.solve_model(model, (0.0, 1.0), y0, n_steps=50, t_eval=[0.0, 0.33, 1.0], method=twin)
    assert np.array_equal(a.y, b.y) and a.nfev == b.nfev
    assert b.method == twin.name


def test_a_stability_studys_loop_is_handed_out():
    """stability_planar4 has no run spec: its studies' RK4 loop on planar4
    was compiled by each worker that met it (round 3's two-worker ledger);
    it is now one job of :func:`rk4h.validation.warm.loop_jobs`."""
    from pathlib import Path

    from rk4h.validation.execute import problem
    from rk4h.validation.plan import plan_all
    from rk4h.validation.scenes import load_scene
    from rk4h.validation.warm import STABILITY, _loop_key, loop_jobs, warm_one

    scene = load_scene(Path(__file__).resolve().parent.parent / "validation" / "scenes" / "stability_planar4.toml")
    jobs = plan_all([scene], quick=True, figures=False)
    assert {spec.purpose for _, spec in jobs} == {"stability"}
    pairs = loop_jobs(jobs)
    assert pairs == [(scene, STABILITY)]
    model, _ = problem(scene)
    assert _loop_key(scene, STABILITY)[0] == "scalar"  # the straight-line loop of RK4 on planar4
    assert warm_one(scene, STABILITY) >= 0.0
    assert fast.solve.warmed(model, get_method("rk4"))


def test_read_only_constants_of_a_model_still_run(monkeypatch):
    """The one signature takes writable constants: a model whose masses or
    force parameters are read-only arrays (frozen, memory-mapped) still runs,
    because :class:`CompiledRHS` keeps its own writable copies of them."""
    from rk4h.fast.solve import CompiledRHS

    model = _chain()
    kern = force_kernel(model)
    ro_kern = type("K", (), {})()
    for name in dir(kern):
        if not name.startswith("__"):
            setattr(ro_kern, name, getattr(kern, name))
    ro_kern.fp, ro_kern.ip = _readonly(kern.fp), np.array(kern.ip, dtype=np.int64)
    ro_kern.ip.flags.writeable = False
    ro_model = type("M", (), {"mass": _readonly(model.mass), "n_dof": model.n_dof})()
    rhs = CompiledRHS(ro_model, ro_kern)
    assert rhs.fp.flags.writeable and rhs.ip.flags.writeable and rhs.mass.flags.writeable
    y = np.linspace(-0.1, 0.2, 2 * model.n_dof)
    assert np.array_equal(rhs(0.0, y), model.rhs(0.0, y))
    perm = _readonly(np.arange(y.shape[0])[::-1]).astype(np.int64)
    perm.flags.writeable = False
    zp = np.empty(y.shape[0])
    assert not rhs.permuted(perm)(_readonly(y[perm]), zp)
    assert np.array_equal(zp, model.rhs(0.0, y)[perm])
