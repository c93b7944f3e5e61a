"""Each numba loop of a plan compiled by one worker (issue 29,
:mod:`rk4h.validation.warm`): the loops are told apart by what the compiled code
depends on, never by the numbers of a model."""
from __future__ import annotations

from pathlib import Path

import pytest

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


def _scene(name):
    from rk4h.validation.scenes import load_scenes

    (scene,) = [s for s in load_scenes() if s.name == name]
    return scene


def test_an_energy_work_precision_loop_is_handed_out():
    """energy-planar4 lists only the energy work-precision output: its methods' loops ran
    in no ``run`` spec and were compiled by every worker that met them (the full run's
    two-worker cold ledger: 20 such loops, each compiled twice)."""
    from rk4h.validation.outputs import loops

    scene = _scene("energy-planar4")
    jobs = plan_all([scene], quick=False, figures=False)
    assert {spec.purpose for _, spec in jobs} == {"energy_wp"}
    assert loops("energy_wp") is not None
    keys = {_loop_key(s, v) for s, v in loop_jobs(jobs)}
    wanted = {_loop_key(scene, spec.solver) for _, spec in jobs} - {None}
    assert len(wanted) >= 5 and keys == wanted


def test_an_ensembles_batch_loops_are_handed_out_with_its_references():
    """A nonlinear ensemble runs its solver's batch loop and the batch reference's
    (blanes-moan6); a linear one only its solver's, which its stability map shares."""
    from rk4h.validation.ensemble import REFERENCE_METHOD
    from rk4h.validation.warm import BATCH

    weak = _scene("ensemble-planar4-weak")
    keys = {_loop_key(s, v) for s, v in loop_jobs(plan_all([weak], quick=False, figures=False))}
    batch = {k for k in keys if k[0] == "batch"}
    assert batch == {_loop_key(weak, BATCH + "rk4"), _loop_key(weak, BATCH + REFERENCE_METHOD)}
    assert _loop_key(weak, BATCH + "rk4") != _loop_key(weak, "rk4")  # a module of its own
    linear = _scene("ensemble-2dof-map")
    jobs = plan_all([linear], quick=False, figures=False)
    assert {"ensemble", "stability_map"} <= {spec.purpose for _, spec in jobs}
    batch = [v for s, v in loop_jobs(jobs) if _loop_key(s, v)[0] == "batch"]
    assert batch == [BATCH + "rk4"]


def test_the_warmed_batch_loop_is_the_one_the_ensemble_runs():
    """warm_one's one-instance batch compiles (or loads) the signature the
    ensemble's own batches call: running the ensemble adds none."""
    from rk4h.batch import _numba
    from rk4h.fast import force_kernel
    from rk4h.validation.execute import execute, problem
    from rk4h.validation.warm import BATCH

    scene = _scene("ensemble-2dof-map")
    model, y0 = problem(scene)
    tab = scene.method("rk4").tableau
    assert warm_one(scene, BATCH + "rk4") >= 0.0
    fn, _ = _numba.batch_loop(tab, force_kernel(model), len(y0))
    assert len(fn.signatures) == 1
    (spec,) = [s for _, s in plan_all([scene], quick=True, figures=False) if s.purpose == "ensemble"][:1]
    assert execute(scene, spec).status == "ok"
    assert len(fn.signatures) == 1


def test_the_outputs_declare_the_loops_of_the_specs_that_run_their_own_solver():
    """warm.py knows no purpose by name: the outputs owning ``run``, ``confirm``,
    ``order``, ``figure`` and ``stability`` declare their loops
    (:attr:`Output.loops`), and a spec of those with a solver is handed out.
    On the full shipped plan, every loop a spec runs on its own solver is one job."""
    from types import SimpleNamespace

    from rk4h.validation.outputs import loops, solver_loop
    from rk4h.validation.scenes import load_scenes
    from rk4h.validation.warm import STABILITY

    for purpose in ("run", "order", "figure"):
        assert loops(purpose) is solver_loop, purpose
    confirm = SimpleNamespace(purpose="confirm", solver="dop853")
    assert loops("confirm")(None, confirm) == [("loop", "dop853"), ("compiled", "dop853")]
    assert loops("stability")(None, None) == [("stability", "")]
    jobs = plan_all(load_scenes(), quick=False, figures=True)
    keys = {_loop_key(s, v) for s, v in loop_jobs(jobs)}
    own = {(scene.name, spec.solver) for scene, spec in jobs
           if spec.purpose in ("run", "confirm", "order", "figure") and spec.solver}
    by_name = {scene.name: scene for scene, _ in jobs}
    wanted = {_loop_key(by_name[name], solver) for name, solver in own} - {None}
    assert len(wanted) > 20 and wanted <= keys
    stab = {scene.name for scene, spec in jobs if spec.purpose == "stability"}
    assert stab and {_loop_key(by_name[n], STABILITY) for n in stab} - {None} <= keys


def test_a_new_outputs_declared_loop_is_handed_out(monkeypatch):
    """An output of a user's (a purpose warm.py has never heard of) gets its
    loop compiled ahead by declaring it: nothing to change in warm.py."""
    from types import SimpleNamespace

    from rk4h.validation import outputs

    scene = _scene("thesis-2dof-case1")
    spec = SimpleNamespace(purpose="my_sweep", solver="", key="k1")
    assert loop_jobs([(scene, spec)]) == []
    monkeypatch.setattr(outputs, "loops", lambda p: (lambda sc, sp: [("loop", "symplectic-euler")])
                        if p == "my_sweep" else None)
    assert loop_jobs([(scene, spec)]) == [(scene, "symplectic-euler")]


def _warm_jobs_script():
    import importlib.util
    from pathlib import Path

    path = Path(__file__).resolve().parent.parent / "benchmarks" / "warm_jobs.py"
    spec = importlib.util.spec_from_file_location("warm_jobs_script", path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_the_warm_jobs_script_prints_the_plans_jobs(capsys):
    script = _warm_jobs_script()
    assert script.main(["thesis-2dof-case1"]) == 0
    lines = capsys.readouterr().out.splitlines()
    scene = _scene("thesis-2dof-case1")
    pairs = loop_jobs(plan_all([scene], quick=False, figures=True, repeats=3))
    assert lines[0] == f"{len(pairs)} jobs" and len(pairs) >= 3
    assert lines[1:] == [f"{s.name} {v} {_loop_key(s, v)[0]}" for s, v in pairs]


@pytest.mark.parametrize("argv, words", [(["--bogus"], "unknown option '--bogus'"),
                                         (["no-such-scene"], "no-such-scene")])
def test_the_warm_jobs_script_refuses_bad_arguments_in_one_line(argv, words, capsys):
    assert _warm_jobs_script().main(argv) == 2
    err = capsys.readouterr().err
    assert words in err and len(err.strip().splitlines()) == 1


@pytest.mark.parametrize("solver, where", [("dop853", "dop853"), ("cvode-adams", "cvode"), ("cvode-bdf", "cvode")])
def test_a_confirmation_runs_compiled_loop_is_handed_out_and_is_the_one_it_runs(solver, where):
    """Confirmation runs are planned from the records, after the plan, and step a
    reference's compiled loop (DOP853's right-hand side, CVODE's callbacks): the
    engine's warm-up before them hands that loop out once (it was compiled by every
    worker that ran a confirmation), and what it builds is what the run calls."""
    from types import SimpleNamespace

    from rk4h import fast
    from rk4h.fast import dop853 as fast_dop853
    from rk4h.references.solvers import cvode_compiled, integrate_compiled
    from rk4h.validation.execute import problem
    from rk4h.validation.warm import COMPILED

    scene = _scene("thesis-2dof-case1")
    other = _scene("thesis-2dof-case2")  # same structure, other numbers: one job
    specs = [(sc, SimpleNamespace(purpose="confirm", solver=solver, key=f"c{i}")) for i, sc in enumerate((scene, other))]
    jobs = loop_jobs(specs)
    compiled = [(s, v) for s, v in jobs if v.startswith(COMPILED)]
    assert compiled == [(scene, COMPILED + solver)]
    assert _loop_key(scene, COMPILED + solver) == ("compiled", where, fast.force_kernel(problem(scene)[0]).key())
    assert _loop_key(scene, COMPILED + "rk4") is None  # a tableau's confirmation runs its own loop

    model, y0 = problem(scene)
    key = fast.force_kernel(model).key()
    fast_dop853._LOOPS.pop(key, None)
    for k in [k for k in cvode_compiled._CALLBACK_CACHE if k[0] == key]:
        del cvode_compiled._CALLBACK_CACHE[k]
    warm_one(scene, COMPILED + solver)
    built = key in fast_dop853._LOOPS if where == "dop853" else (key, "rhs") in cvode_compiled._CALLBACK_CACHE
    assert built
    before = (dict(fast_dop853._LOOPS), dict(cvode_compiled._CALLBACK_CACHE))
    import numpy as np

    run = integrate_compiled(scene.method(solver), model, y0, np.linspace(0.0, 1.0, 5), 1e-8)
    assert run.extra["implementation"] == "compiled"
    assert (dict(fast_dop853._LOOPS), dict(cvode_compiled._CALLBACK_CACHE)) == before  # nothing more built


def test_the_references_compiled_loops_are_warmed_in_one_process(monkeypatch):
    """DOP853's compiled loop is one function for every model, compiled inside
    the package: two of its jobs in two workers compiled it twice on a fresh
    install (the --quick cold ledger: 4.8 + 4.6 s). Every COMPILED job goes to the
    lane, a pool of one process; the others alternate as before."""
    from concurrent.futures import Future

    from rk4h.validation import warm

    class Pool:
        def __init__(self, name, log):
            self.name, self.log = name, log

        def submit(self, fn, scene, solver):
            self.log.append((self.name, solver))
            f = Future()
            f.set_result(0.0)
            return f

    class Pools:
        workers = 2

        def __init__(self):
            self.log = []
            self.lane, self.general = Pool("lane", self.log), Pool("general", self.log)

        def start(self):
            return self

    pairs = [(None, "rk4"), (None, warm.COMPILED + "dop853"), (None, "euler"), (None, warm.COMPILED + "cvode-bdf"),
             (None, warm.COMPILED + "dop853")]
    monkeypatch.setattr(warm, "loop_jobs", lambda jobs: pairs)
    pools = Pools()
    assert warm.warm_pools(pools, []) == 5
    assert pools.log == [("lane", "rk4"), ("lane", warm.COMPILED + "dop853"), ("lane", "euler"),
                         ("lane", warm.COMPILED + "cvode-bdf"), ("lane", warm.COMPILED + "dop853")]
    pairs[:] = [(None, "rk4"), (None, "euler"), (None, "heun3")]
    pools = Pools()
    warm.warm_pools(pools, [])
    assert [n for n, _ in pools.log] == ["lane", "general", "lane"]
