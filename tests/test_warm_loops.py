"""Each numba loop of a plan compiled by one worker (issue 29,
:mod:`rk4h.validation.warm`): the loops are told apart by what the compiled code
depends on, never by the numbers of a model."""
from __future__ import annotations

from pathlib import Path

from rk4h.validation.plan import plan_all
from rk4h.validation.scenes import load_scene
from rk4h.validation.warm import _loop_key, loop_jobs, warm_one

SCENES = Path(__file__).resolve().parent.parent / "validation" / "scenes"


def test_loop_jobs_one_per_distinct_loop():
    cases = [load_scene(SCENES / f"thesis_2dof_case{i}.toml") for i in (1, 2, 3)]  # one structure, 3 parameter sets
    jobs = plan_all(cases, quick=True, figures=False)
    pairs = loop_jobs(jobs)
    keys = [_loop_key(scene, solver) for scene, solver in pairs]
    assert len(keys) == len(set(keys)) and None not in keys
    solvers = {spec.solver for _, spec in jobs if spec.purpose in ("run", "confirm")}
    # every solver with a compiled loop is covered, once for the three scenes
    expected = {_loop_key(cases[0], s) for s in solvers} - {None}
    assert set(keys) == expected and len(expected) >= 3
    assert len({_loop_key(c, "rk4") for c in cases}) == 1  # the numbers are not part of the loop


def test_loop_key_differs_by_method_and_structure():
    a = load_scene(SCENES / "thesis_2dof_case1.toml")
    b = load_scene(SCENES / "network_web.toml")
    assert _loop_key(a, "rk4") != _loop_key(a, "euler")
    assert _loop_key(a, "rk4") != _loop_key(b, "rk4")
    assert _loop_key(a, "dop853") == _loop_key(a, "cvode-adams")  # one compiled right-hand side
    assert _loop_key(a, "heyoka") is None


def test_warm_one_never_raises():
    scene = load_scene(SCENES / "thesis_2dof_case1.toml")
    assert warm_one(scene, "no-such-solver") >= 0.0
    assert warm_one(scene, "rk4") >= 0.0
