"""The advisor's sampled runs side by side (validation/advise.py, ``_first_miss``):
the first step of a round runs alone, the rest may run in threads, and the
steps recorded (the cache of a round, the problem's runs) are those the runs
one after the other record: the same steps, in the same order, up to the
first miss. Runs started beside one that missed are waited for and thrown
away. The advice itself is the same for any number of threads."""
import json
import threading
import time
from types import SimpleNamespace

import pytest

from rk4h.validation import advise as advise_mod
from rk4h.validation.advise import _first_miss

_M = SimpleNamespace(name="rk4")
_TARGET = 1e-3


class _Stub:
    """A problem whose run at step ``s`` has error ``errors[s]``; each run
    takes ``pause`` seconds. With more than one thread the first two runs in
    threads wait for each other (a barrier), so they certainly overlap."""

    def __init__(self, errors, threads, pause=0.02, side_by_side=True):
        self.errors, self.threads, self.pause, self._sbs = errors, threads, pause, side_by_side
        self.runs, self.executed, self.committed = {}, [], []
        self.active, self.most_active = 0, 0
        self._lock = threading.Lock()
        self._meet = threading.Barrier(2, timeout=30)

    def side_by_side(self, method):
        return self._sbs

    def execute(self, method, s):
        with self._lock:
            self.executed.append(s)
            self.active += 1
            self.most_active = max(self.most_active, self.active)
            first_two = threading.current_thread().name.startswith("rk4h-advise") and len(self.executed) <= 3
        if first_two and self.threads > 1:
            self._meet.wait()  # the main thread ran the first step; the next two run together
        time.sleep(self.pause)
        with self._lock:
            self.active -= 1
        return SimpleNamespace(step=s, thread=threading.current_thread().name)

    def commit(self, method, s, run, alone=True):
        assert run.step == s
        self.committed.append((s, alone))
        out = (self.errors[s], 4.0 / s, self.pause, "ok")
        self.runs.setdefault(s, out)
        return out

    def known(self, method, s):
        return s in self.runs

    def measured(self, method, s):
        return self.runs[s] if s in self.runs else self.commit(method, s, self.execute(method, s))


_STEPS = [8e-4, 7e-4, 6e-4, 5e-4, 4.5e-4, 4e-4]


def _errors(miss_at=None):
    return {s: (2 * _TARGET if i == miss_at else _TARGET / 2) for i, s in enumerate(_STEPS)}


@pytest.mark.parametrize("threads", [1, 2, 3])
def test_every_step_is_recorded_in_order_when_none_misses(threads):
    p, cache = _Stub(_errors(), threads), {}
    assert _first_miss(p, _M, _STEPS, _TARGET, cache) is None
    assert [s for s, _ in p.committed] == _STEPS and list(cache) == _STEPS
    # the first step ran alone; the others were side by side only with more than one thread
    assert [alone for _, alone in p.committed] == [True] + [threads == 1] * (len(_STEPS) - 1)
    assert sorted(p.executed) == sorted(_STEPS) and p.active == 0
    assert (p.most_active > 1) == (threads > 1)


@pytest.mark.parametrize("threads", [1, 2, 3])
@pytest.mark.parametrize("miss_at", [0, 1, 3, 5])
def test_a_miss_records_the_steps_up_to_it_and_no_more(threads, miss_at):
    p, cache = _Stub(_errors(miss_at), threads), {}
    miss = _first_miss(p, _M, _STEPS, _TARGET, cache)
    assert miss == (_STEPS[miss_at], 2 * _TARGET, "ok")
    assert [s for s, _ in p.committed] == _STEPS[:miss_at + 1] and list(cache) == _STEPS[:miss_at + 1]
    assert set(p.runs) == set(_STEPS[:miss_at + 1])     # a run thrown away is not reused later either
    assert p.active == 0                                 # nothing is left running beside the next round
    if threads == 1 or miss_at == 0:
        assert p.executed == _STEPS[:miss_at + 1]        # nothing ran past the miss


def test_a_step_already_run_is_not_run_again():
    p, cache = _Stub(_errors(), 2), {}
    p.measured(_M, _STEPS[2])                            # e.g. a calibration run at that step
    p.executed.clear()
    p.committed.clear()
    assert _first_miss(p, _M, _STEPS, _TARGET, cache) is None
    assert sorted(p.executed) == sorted(set(_STEPS) - {_STEPS[2]}) and list(cache) == _STEPS


def test_without_side_by_side_runs_go_one_after_the_other():
    p, cache = _Stub(_errors(4), 4, side_by_side=False), {}
    assert _first_miss(p, _M, _STEPS, _TARGET, cache)[0] == _STEPS[4]
    assert p.executed == _STEPS[:5] and p.most_active == 1


def test_a_problem_with_only_run_goes_one_after_the_other():
    """A problem without ``execute`` (tests' stand-ins, older callers) runs each step through ``run``."""
    seen = []
    p = SimpleNamespace(run=lambda m, s: (seen.append(s), (_errors(2)[s], 1.0, 0.0, "ok"))[1], threads=4)
    assert _first_miss(p, _M, _STEPS, _TARGET, {})[0] == _STEPS[2] and seen == _STEPS[:3]


def _scene(name):
    from rk4h.validation.scenes import load_scenes

    return load_scenes([name])[0]


_TIMING = {"cost_s", "cost_s_min", "cost_s_max", "compile_s", "fastest", "fastest_one_run", "timing_runs"}


def _without_timing(d):
    if isinstance(d, dict):
        return {k: _without_timing(v) for k, v in d.items() if k not in _TIMING}
    if isinstance(d, list):
        return [_without_timing(x) for x in d]
    return d


def test_the_advice_is_the_same_with_one_thread_or_several(monkeypatch):
    """thesis-2dof-case1: symplectic-euler's 8 sampled steps run in threads
    with ``threads=3`` (seen from the threads' names); every number of the
    advice but the wall times equals the advice with one thread."""
    names = []
    real = advise_mod._Problem.execute

    def spy(self, method, setting):
        names.append(threading.current_thread().name)
        return real(self, method, setting)

    monkeypatch.setattr(advise_mod._Problem, "execute", spy)
    monkeypatch.setattr(advise_mod, "SKIP_MIN_S", float("inf"))  # no choice by a wall time: the load cannot flip one
    scene = _scene("thesis-2dof-case1")
    one = json.loads(advise_mod.advise(scene, 1e-3, threads=1).to_json())
    assert not any(n.startswith("rk4h-advise") for n in names)
    names.clear()
    several = json.loads(advise_mod.advise(scene, 1e-3, threads=3).to_json())
    assert sum(n.startswith("rk4h-advise") for n in names) >= 4
    assert any(c["sample"] for c in one["candidates"])
    assert _without_timing(one) == _without_timing(several)


@pytest.mark.parametrize("model_name, array", [("thesis-2dof-case1", False), ("chain10-mode2", True)])
def test_the_compiled_loops_release_the_interpreter_lock(model_name, array):
    """The generated loop (straight-line for 2-DOF, array loop for 10 masses)
    is compiled ``nogil``: side by side runs use several cores."""
    from rk4h.fast import codegen
    from rk4h.fast import solve as fast_solve
    from rk4h.validation.execute import problem

    model, _ = problem(_scene(model_name))
    assert codegen.array_loop(fast_solve.force_kernel(model), 2 * model.n_dof) is array
    fast_solve.warm_up(model, "rk4")
    loop = fast_solve._loop_of(model, "rk4")
    assert loop.targetoptions.get("nogil") is True


@pytest.mark.parametrize("value", ["0", "-1", "two", "2000"])
def test_a_bad_threads_value_is_one_line_and_exit_2(value, capsys):
    assert advise_mod.main(["thesis-2dof-case1", "--target", "1e-3", "--threads", value]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--threads" in err[0] and repr(value) in err[0]


def test_threads_with_an_energy_target_is_refused(capsys):
    assert advise_mod.main(["thesis-2dof-case1", "--energy-target", "1e-3", "--periods", "10", "--threads", "2"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--threads" in err[0] and "--target" in err[0]


def test_only_a_tableau_on_rk4hs_own_compiled_model_goes_side_by_side():
    """A scene's own model class (``module:Class``, or any subclass defined
    outside rk4h) may run user code in the general path (its state checks),
    so its runs stay one at a time; so do methods other than tableaux."""
    import rk4h.fast
    from rk4h.models import Chain

    p = advise_mod._Problem(_scene("thesis-2dof-case1"), 2)
    scene = p.scene
    assert p.side_by_side(scene.method("rk4")) and p.side_by_side(scene.method("symplectic-euler"))
    assert not p.side_by_side(scene.method("dop853")) and not p.side_by_side(scene.method("heyoka"))

    class Mine(Chain):  # a user's subclass, defined outside rk4h
        pass

    mine = Mine([1.0, 1.0], [1.0, 1.0, 1.0])
    assert rk4h.fast.supports(mine) and not advise_mod.compiled_own_model(mine)
    assert advise_mod.compiled_own_model(Chain([1.0, 1.0], [1.0, 1.0, 1.0]))
