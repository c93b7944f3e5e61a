"""Behaviour comes from registry data, never from a method's name: the
workers' cost estimate reads ``Method.native_steps`` (heyoka's compiled Taylor
steps), not the name ``"heyoka"``; the large-N study's reference is the
method with role ``"banded"``; compiled loops are chosen by ``adapter``; the
stiffness cost search's default method is the registry's ``UNDER_TEST``."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from rk4h.references import registry
from rk4h.validation import plan, workers
from rk4h.validation.scenes import scene_from_dict

DOC = {"name": "dispatch", "model": "chain",
       "params": {"masses": [1.0, 1.0], "springs": [1.0, 1.0, 1.0]},
       "initial": {"x": [0.5, 0.0]},
       "run": {"t_end": 20.0, "h": [0.1], "tolerances": [1e-6], "solvers": ["rk4", "dop853", "heyoka"],
               "outputs": ["state"]}}


def _run_seconds(scene, solver):
    seconds = workers.spec_seconds_function()
    specs = [s for s in plan.plan(scene, figures=False) if s.purpose == "run" and s.solver == solver]
    assert specs
    return [seconds(scene, s) for s in specs]


def test_the_registry_says_which_reference_steps_natively():
    assert [n for n, m in registry.BUILTIN.items() if m.native_steps] == ["heyoka"]
    assert all(m.kind is registry.Kind.REFERENCE for m in registry.BUILTIN.values() if m.native_steps)


@pytest.mark.parametrize("solver", ["dop853", "heyoka"])
def test_step_cost_follows_native_steps_not_the_name(solver, monkeypatch):
    scene = scene_from_dict(DOC, "dispatch.toml")
    before = _run_seconds(scene, solver)
    method = registry.BUILTIN[solver]
    monkeypatch.setitem(registry.BUILTIN, solver, dataclasses.replace(method, native_steps=not method.native_steps))
    after = _run_seconds(scene, solver)
    # a Python-stepped reference costs about 1e-4 s a step, a compiled one about 1e-6 s
    if method.native_steps:
        assert all(a > b for a, b in zip(after, before))
    else:
        assert all(a < b for a, b in zip(after, before))


def test_the_large_n_reference_is_the_method_with_role_banded(monkeypatch):
    """The large-N study's estimate names its banded reference from the
    registry's role ``"banded"`` (CVODE-BDF), not a written name."""
    from rk4h.validation.stability import estimate, studies

    assert registry.with_role("banded") == ("cvode-bdf",)
    p = {"method": "rk4", "n_values": [10, 20]}
    assert set(estimate._large_n(None, p, False, None)) == {"rk4", "cvode-bdf"}
    for name in ("cvode-bdf", "cvode-adams"):  # move the role: the estimate follows it
        m = registry.BUILTIN[name]
        monkeypatch.setitem(registry.BUILTIN, name, dataclasses.replace(m, roles=m.roles ^ {"banded"}))
    assert studies.banded_reference() == "cvode-adams"
    assert set(estimate._large_n(None, p, False, None)) == {"rk4", "cvode-adams"}


def _renamed(monkeypatch, name, new):
    """A built-in reference under another name, its adapter kept (what a
    registry entry renamed keeps)."""
    m = dataclasses.replace(registry.BUILTIN[name], name=new)
    monkeypatch.setitem(registry.BUILTIN, new, m)
    return m


def test_warm_loops_follow_the_adapter_not_the_name(monkeypatch):
    from pathlib import Path

    from rk4h.validation.scenes import load_scene
    from rk4h.validation.warm import _loop_key

    scene = load_scene(Path(__file__).resolve().parent.parent / "validation" / "scenes" / "thesis_2dof_case1.toml")
    _renamed(monkeypatch, "cvode-bdf", "bdf-renamed")
    assert _loop_key(scene, "cvode-bdf") is not None
    assert _loop_key(scene, "bdf-renamed") == _loop_key(scene, "cvode-bdf")


def test_the_advisor_runs_a_compiled_loop_by_adapter(monkeypatch):
    from rk4h.validation import advise

    scene = scene_from_dict(DOC, "dispatch.toml")
    method = _renamed(monkeypatch, "dop853", "dop-renamed")
    prob = advise._Problem(scene)
    prob.run(method, 1e-6)
    assert prob.implementation.get("dop-renamed") == "compiled"


@pytest.mark.parametrize("under_test", ["rk4", "euler"])
def test_the_cost_search_steps_the_registrys_method_under_test(under_test, monkeypatch):
    """``cost_at_target`` without ``fixed`` steps the registry's method under
    test with a fixed step, whatever its name."""
    from rk4h.validation.stability import stiffness

    monkeypatch.setattr(registry, "UNDER_TEST", under_test)
    model = scene_from_dict(DOC, "dispatch.toml").build_model()
    (row,) = stiffness.cost_at_target(model, np.array([0.5, 0.0, 0.0, 0.0]), 1e-2, (under_test,))
    assert row["solver"] == under_test and row["status"] == "ok", row
    assert row["n_steps"] > 0 and "h_stab=" in row["note"]  # the fixed-step search, not the rtol ladder


def test_batch_outputs_pick_the_registry_method_under_test(monkeypatch):
    from types import SimpleNamespace

    from rk4h.references import registry
    from rk4h.validation.outputs import _batch

    scene = SimpleNamespace(fixed_solvers=["heun3", "rk4"],
                            method=lambda s: SimpleNamespace(tableau=object()))
    assert _batch.one_solver(scene) == "rk4"
    monkeypatch.setattr(registry, "UNDER_TEST", "heun3")
    assert _batch.one_solver(scene) == "heun3"
