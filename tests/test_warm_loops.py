"""Each numba loop of a plan compiled by one worker (issue 29,
:mod:`rk4h.validation.warm`): the loops are told apart by what the compiled code
depends on, never by the numbers of a model."""
from __future__ import annotations

from pathlib import Path

from rk4h.validation.plan import plan_all
from rk4h.validation.scenes import load_scene
from rk4h.validation.warm import _loop_key, loop_jobs, warm_one, _READONLY_STATE

SCENES = Path(__file__).resolve().parent.parent / "validation" / "scenes"


def test_loop_jobs_one_per_distinct_loop():
    cases = [load_scene(SCENES / f"thesis_2dof_case{i}.toml") for i in (1, 2, 3)]  # one structure, 3 parameter sets
    jobs = plan_all(cases, quick=True, figures=False)
    pairs = loop_jobs(jobs)
    keys = [_loop_key(scene, solver) for scene, solver in pairs]
    assert len(keys) == len(set(keys)) and None not in keys
    solvers = {spec.solver for _, spec in jobs if spec.purpose in ("run", "confirm", "order", "figure")}
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


def test_a_loop_only_a_convergence_sweep_calls_is_warmed():
    """oscillator-iso-delta-pi4 runs euler and symplectic-euler only in its
    convergence sweep (``order`` specs): their loops are handed out too."""
    scene = load_scene(SCENES / "oscillator_iso_delta-pi4.toml")
    jobs = plan_all([scene], quick=True, figures=True)
    only_order = {spec.solver for _, spec in jobs if spec.purpose == "order"} - \
        {spec.solver for _, spec in jobs if spec.purpose == "run"}
    keys = {_loop_key(s, v) for s, v in loop_jobs(jobs)}
    assert only_order and all(_loop_key(scene, v) in keys for v in only_order)


def test_the_right_hand_side_job_is_cvodes_when_cvode_runs():
    """One job per compiled right-hand side; CVODE's when CVODE runs (it
    compiles the read-only-state signature CVODE's callback calls as well)."""
    scene = load_scene(SCENES / "thesis_2dof_case1.toml")
    jobs = plan_all([scene], quick=True, figures=False)
    rhs = [(s, v) for s, v in loop_jobs(jobs) if _loop_key(s, v)[0] == "rhs"]
    assert len(rhs) == 1 and rhs[0][1] in _READONLY_STATE
    dop_only = [(sc, sp) for sc, sp in jobs if getattr(sp, "solver", "") not in _READONLY_STATE]
    rhs = [(s, v) for s, v in loop_jobs(dop_only) if _loop_key(s, v)[0] == "rhs"]
    assert [v for _, v in rhs] == ["dop853"]


def test_warm_one_compiles_cvodes_read_only_signature():
    from rk4h.fast.solve import force_kernel, model_module
    from rk4h.validation.execute import problem

    scene = load_scene(SCENES / "thesis_2dof_case1.toml")
    warm_one(scene, "cvode-adams")
    model, _ = problem(scene)
    sigs = model_module(force_kernel(model)).rhs_permuted.signatures
    assert any(getattr(sig[3], "mutable", True) is False for sig in sigs), sigs


def test_a_sweeps_batched_runs_are_left_to_their_batch(monkeypatch):
    """The sweep points' untimed runs that the engine batches
    (rk4h.validation.sweep_batch.group) run the batch's loop: not handed out.
    (The shipped sweeps are below the batch threshold: lowered here.)"""
    from rk4h.validation import sweep_batch
    from rk4h.validation.scenes import load_scene_points
    from rk4h.validation.sweep_batch import group
    from rk4h.validation.warm import _batched_keys

    monkeypatch.setattr(sweep_batch, "BATCH_MIN_STEPS", 0)

    points = load_scene_points(SCENES / "sweep_planar4_amplitude.toml")
    jobs = plan_all(points, quick=False, figures=True)
    batched = _batched_keys(jobs)
    grouped = {s.key for sc, g in group([j for j in jobs if j[1].purpose in ("order", "figure", "modal")])
               if sc is None for _, s in g.jobs}
    assert batched and batched == grouped
    keys = {s.key for _, s in jobs}
    assert batched < keys
