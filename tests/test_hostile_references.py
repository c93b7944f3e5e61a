"""Never trust blindly, bounded work, honest statuses: the references (truth cache,
adaptive solvers, heyoka's grid output), the models' refusals, the stability
study's parameters and step estimate, and the RK4 theory functions.

Each case is named (``ids``) so that a failure says which one; cases that
could hang (they did before the fixes) run in a subprocess with a timeout.
"""
from __future__ import annotations

import collections
import json
import math
import os
import stat
import subprocess
import sys
import tempfile
import textwrap
import time
import warnings
from pathlib import Path

import mpmath as mp
import numpy as np
import pytest

import rk4h
import rk4h.references.truth as truth_mod
from rk4h.references.registry import BUILTIN, REFERENCES, UNDER_TEST
from rk4h.references.solvers import Status, integrate
from rk4h.references.solvers import taylor
from rk4h.references.truth import TruthCacheWarning, cache_dir, clear_memory_cache, reference_solution
from rk4h.models import Planar4
from rk4h.validation import metrics
from rk4h.validation.stability import PARAMS, estimate_steps, params_table_markdown, validate_params
from rk4h.validation.stability import _common as SC
from rk4h.validation.stability import boundary as B
from rk4h.validation.stability import long_horizon as LHm

REPO = Path(__file__).resolve().parent.parent
PEND = ("pendulums", {"m": 1.0, "length": 1.0, "g": 9.81, "k": 2.0})
PEND_X0, PEND_V0 = [0.3, 0.0], [0.0, 0.5]
T11 = np.linspace(0.0, 1.0, 11)


def run_bounded(code: str, timeout: float = 90.0) -> dict:
    """Run ``code`` in a fresh interpreter (repository as cwd, a private
    RK4H_CACHE); it prints one JSON line. A hang fails the test, naming the
    bound, instead of hanging the suite."""
    with tempfile.TemporaryDirectory() as d:
        os.chmod(d, 0o700)
        env = {**os.environ, "RK4H_CACHE": d, "PYTHONWARNINGS": "ignore"}
        try:
            p = subprocess.run([sys.executable, "-c", textwrap.dedent(code)], cwd=REPO, env=env,
                               capture_output=True, text=True, timeout=timeout)
        except subprocess.TimeoutExpired:
            pytest.fail(f"no answer within {timeout} s: the run hangs")
    lines = [ln for ln in p.stdout.splitlines() if ln.startswith("{")]
    assert p.returncode == 0 and lines, f"rc {p.returncode}\n{p.stdout}\n{p.stderr[-2000:]}"
    return json.loads(lines[-1])


# =============================================================================================
# 1. The truth cache
# =============================================================================================
@pytest.fixture
def cache(tmp_path, monkeypatch):
    """A fresh private cache directory and an empty memory cache; warnings of
    earlier tests about directories forgotten."""
    clear_memory_cache()
    monkeypatch.setattr(truth_mod, "_WARNED", set())
    d = cache_dir(tmp_path / "truth")
    yield d
    clear_memory_cache()


def _pend():
    model = rk4h.make_model(*PEND)
    return model, model.state(PEND_X0, PEND_V0)


def _fresh():
    model, y0 = _pend()
    return reference_solution(model, y0, T11, cache=False)


def _entry(d, model, y0):
    first = reference_solution(model, y0, T11, path=d)
    clear_memory_cache()
    return first, d / f"{first.key}.npz"


def _rewrite_npz(file, change):
    with np.load(file, allow_pickle=False) as z:
        arrays = {k: z[k] for k in z.files}
    change(arrays)
    os.unlink(file)
    with open(file, "wb") as f:
        np.savez(f, **arrays)


def _tamper_keep_checksum(file, other):
    _rewrite_npz(file, lambda a: a.__setitem__("y", a["y"] * 1.001))


def _truncate(file, other):
    data = file.read_bytes()
    file.write_bytes(data[: len(data) // 2])


def _flip_byte(file, other):
    # a byte inside y's data (not a zip field that nothing checks)
    data = bytearray(file.read_bytes())
    with np.load(file, allow_pickle=False) as z:
        y = z["y"].tobytes()
    i = bytes(data).find(y)
    assert i >= 0
    data[i + len(y) // 2] ^= 0x40
    file.write_bytes(bytes(data))


def _empty(file, other):
    file.write_bytes(b"")


def _symlink(file, other):
    # a symbolic link to a valid entry (here: a copy of the file itself, elsewhere)
    target = Path(tempfile.mkdtemp()) / "planted.npz"
    target.write_bytes(file.read_bytes())
    os.unlink(file)
    os.symlink(target, file)


def _group_writable(file, other):
    os.chmod(file, 0o664)


def _foreign_owner(file, other):
    os.chown(file, 4242, -1)


def _wrong_key(file, other):
    # another scene's valid entry, renamed to this key
    file.write_bytes(other.read_bytes())


def _pickled(file, other):
    with open(file, "wb") as f:
        np.savez(f, t=np.array([object()], dtype=object), y=np.zeros(1), meta=np.array("{}"), sums=np.array("{}"))


def _wrong_times(file, other):
    # consistent entry (checksums recomputed) whose output times are not the ones asked for
    def change(a):
        a["t"] = a["t"] * 2.0
        sums = json.loads(str(a["sums"][()]))
        sums["arrays"] = truth_mod._array_sum(a)
        a["sums"] = np.array(json.dumps(sums, sort_keys=True))
    _rewrite_npz(file, change)


CORRUPTIONS = [
    ("tamper-y-keep-old-checksum", _tamper_keep_checksum, "checksum"),
    ("truncated", _truncate, "BadZipFile"),
    ("flipped-byte", _flip_byte, ""),
    ("empty-file", _empty, ""),
    ("symlink", _symlink, "symbolic link"),
    ("group-writable", _group_writable, "writable by group"),
    ("foreign-owner", _foreign_owner, "owned by uid 4242"),
    ("other-scene-entry", _wrong_key, ""),
    ("pickled-object-array", _pickled, ""),
    ("wrong-output-times", _wrong_times, "output times"),
]


@pytest.mark.parametrize("corrupt, reason", [c[1:] for c in CORRUPTIONS], ids=[c[0] for c in CORRUPTIONS])
def test_corrupt_entry_is_a_miss_recomputed_and_reported_once(cache, corrupt, reason):
    if corrupt is _foreign_owner and os.getuid() != 0:
        pytest.skip("chown to another uid needs root")
    model, y0 = _pend()
    good, file = _entry(cache, model, y0)
    _, other = _entry(cache, model, y0 * 0.5)
    corrupt(file, other)
    with warnings.catch_warnings(record=True) as got:
        warnings.simplefilter("always")
        again = reference_solution(model, y0, T11, path=cache)
    lines = [str(w.message) for w in got if issubclass(w.category, TruthCacheWarning)]
    assert len(lines) == 1, lines
    assert lines[0].startswith(f"truth cache: {file} was corrupt (") and lines[0].endswith("); recomputed")
    assert reason in lines[0]
    assert "\n" not in lines[0]
    assert again.source == "computed"
    fresh = _fresh()
    np.testing.assert_array_equal(again.y, fresh.y)
    np.testing.assert_array_equal(again.y_lo, fresh.y_lo)
    # overwritten atomically: a regular private file that the next process reads back
    st = os.lstat(file)
    assert stat.S_ISREG(st.st_mode) and not st.st_mode & 0o077
    clear_memory_cache()
    with warnings.catch_warnings():
        warnings.simplefilter("error", TruthCacheWarning)
        back = reference_solution(model, y0, T11, path=cache)
    assert back.source == "disk"
    np.testing.assert_array_equal(back.y, fresh.y)


def test_tampered_values_would_be_used_without_the_checksum(cache, monkeypatch):
    # the negative control: with verification switched off, the tampered truth
    # (1.001 x) comes back from disk -- the situation the checksum prevents
    model, y0 = _pend()
    good, file = _entry(cache, model, y0)
    _tamper_keep_checksum(file, None)
    monkeypatch.setattr(truth_mod, "_array_sum", lambda arrays: json.loads(
        str(np.load(file)["sums"][()]))["arrays"])
    bad = reference_solution(model, y0, T11, path=cache)
    assert bad.source == "disk"
    np.testing.assert_allclose(bad.y, good.y * 1.001, rtol=0, atol=0)


def test_key_includes_the_model_definition(monkeypatch):
    model, y0 = _pend()
    k0 = truth_mod._key(model, y0, T11, "heyoka-real128", 1e-32)
    assert truth_mod.definition_hash(model) is not None
    monkeypatch.setattr(truth_mod, "definition_hash", lambda m: "edited force")
    k1 = truth_mod._key(model, y0, T11, "heyoka-real128", 1e-32)
    assert k1 != k0
    # and the definition hash itself follows the source text of the model's code
    monkeypatch.undo()
    monkeypatch.setattr(truth_mod, "_DEFINITION", {})
    h0 = truth_mod.definition_hash(model)
    real = truth_mod._source
    monkeypatch.setattr(truth_mod, "_DEFINITION", {})
    monkeypatch.setattr(truth_mod, "_source", lambda obj: real(obj) + ("# edited\n" if obj is type(model) else ""))
    assert truth_mod.definition_hash(model) != h0


def test_key_includes_the_heyoka_version(monkeypatch):
    from importlib import metadata

    model, y0 = _pend()
    assert truth_mod._versions()["heyoka"] == metadata.version("heyoka")
    k0 = truth_mod._key(model, y0, T11, "heyoka-real128", 1e-32)
    real = truth_mod._versions
    monkeypatch.setattr(truth_mod, "_versions", lambda: {**real(), "heyoka": "0.0.1"})
    assert truth_mod._key(model, y0, T11, "heyoka-real128", 1e-32) != k0


def test_format_is_bumped_and_in_the_key(monkeypatch):
    model, y0 = _pend()
    assert truth_mod._FORMAT >= 2
    k0 = truth_mod._key(model, y0, T11, "heyoka-real128", 1e-32)
    monkeypatch.setattr(truth_mod, "_FORMAT", truth_mod._FORMAT + 1)
    assert truth_mod._key(model, y0, T11, "heyoka-real128", 1e-32) != k0


@pytest.mark.parametrize("how", ["root-0777", "explicit-path-0777", "explicit-path-symlink"])
def test_untrusted_directory_computes_without_cache_and_says_so_once(tmp_path, monkeypatch, how):
    clear_memory_cache()
    monkeypatch.setattr(truth_mod, "_WARNED", set())
    bad = tmp_path / "bad"
    bad.mkdir()
    os.chmod(bad, 0o777)
    path = None
    if how == "root-0777":
        monkeypatch.setenv("RK4H_CACHE", str(bad))
        named = bad
    elif how == "explicit-path-0777":
        path = named = bad
    else:
        real = tmp_path / "real"
        real.mkdir(mode=0o700)
        path = named = tmp_path / "link"
        os.symlink(real, path)
    model, y0 = _pend()
    with warnings.catch_warnings(record=True) as got:
        warnings.simplefilter("always")
        first = reference_solution(model, y0, T11, path=path)
        clear_memory_cache()
        second = reference_solution(model, y0, T11, path=path)
    lines = [str(w.message) for w in got if issubclass(w.category, TruthCacheWarning)]
    assert len(lines) == 1, lines
    assert str(named) in lines[0] and "without the disk cache" in lines[0] and "\n" not in lines[0]
    assert first.ok and first.source == "computed" and second.source == "computed"
    assert not list(tmp_path.rglob("*.npz"))
    clear_memory_cache()


def test_entry_is_written_with_fsync_of_file_and_directory_then_renamed(cache, monkeypatch):
    synced = []
    real_fsync, real_replace = os.fsync, os.replace
    replaced = []

    def fsync(fd):
        synced.append(stat.S_ISDIR(os.fstat(fd).st_mode))
        return real_fsync(fd)

    def replace(a, b):
        replaced.append((Path(a).parent, Path(b)))
        return real_replace(a, b)

    monkeypatch.setattr(os, "fsync", fsync)
    monkeypatch.setattr(os, "replace", replace)
    model, y0 = _pend()
    t = reference_solution(model, y0, T11, path=cache)
    assert synced == [False, True]  # the temporary file, then the directory
    assert replaced == [(cache, cache / f"{t.key}.npz")]
    assert not [p for p in cache.iterdir() if p.suffix != ".npz"]  # no temporary file left


# =============================================================================================
# 2. Hangs: models refuse nonsense, every adaptive run is bounded
# =============================================================================================
BAD_MODELS = [
    ("subnormal-mass", "chain", {"masses": [5e-324, 1.0], "springs": [1.0, 1.0, 1.0]}, "`masses[0]`"),
    ("mass-1e-310", "chain", {"masses": [1.0, 1e-310], "springs": [1.0, 1.0, 1.0]}, "`masses[1]`"),
    ("mass-ratio-inf", "chain", {"masses": [1e-300, 1e300], "springs": [1.0, 1.0, 1.0]}, "`masses`"),
    ("frequency-inf", "chain", {"masses": [1e-300, 1.0], "springs": [1e300, 1.0, 1.0]}, "`springs`"),
    ("subnormal-spring", "chain", {"masses": [1.0, 1.0], "springs": [5e-324, 1.0, 1.0]}, "`springs[0]`"),
    ("planar4-tiny-m", "planar4", {"m": 1e-320, "k": 1.0, "l": 1.0}, "`m`"),
    ("oscillator-frequency-inf", "oscillator2d", {"m": 1e-300, "kx": 1e300, "ky": 1.0}, "`kx`"),
    ("pendulums-generalized-mass", "pendulums", {"m": 1e-290, "length": 1e-10, "g": 9.8, "k": 1.0}, "`length`"),
    ("triangle-tiny-m", "triangle", {"m": 5e-324, "k": 1.0, "side": 1.0}, "`m`"),
]


@pytest.mark.parametrize("name, params, field", [c[1:] for c in BAD_MODELS], ids=[c[0] for c in BAD_MODELS])
def test_model_refuses_unphysical_parameters(name, params, field):
    with pytest.raises(ValueError) as info:
        rk4h.make_model(name, params)
    assert field in str(info.value) and "\n" not in str(info.value)


HANGING_STARTS = {  # each of these never returned from DOP853 before
    "planar4-on-anchor": ("planar4", {"m": 0.815, "k": 41.5, "l": 0.01}, [0.01, 0.0]),
    "triangle-two-masses-coincide": ("triangle", {"m": 1.0, "k": 10.0, "side": 1.0}, [1.0, 0.0, 0, 0, 0, 0]),
    "chain-x-1e308": ("chain", {"masses": [0.815, 3.099], "springs": [41.5, 138.0, 157.8]}, [1e308, 0.005]),
}


@pytest.mark.parametrize("case", sorted(HANGING_STARTS))
def test_singular_or_overflowing_y0_is_refused_naming_y0_by_every_solver(case):
    name, params, x0 = HANGING_STARTS[case]
    out = run_bounded(f"""
        import json, numpy as np, rk4h
        from rk4h.references.solvers import FIXED_STEP, SOLVER_NAMES, integrate
        from rk4h.references.truth import reference_solution
        m = rk4h.make_model({name!r}, {params!r}); y0 = m.state({x0!r})
        out = {{}}
        for s in SOLVER_NAMES:
            try:
                integrate(s, m, y0, np.linspace(0, 1, 5), 0.01 if s in FIXED_STEP else 1e-6)
                out[s] = "returned"
            except ValueError as e:
                out[s] = str(e)
        try:
            reference_solution(m, y0, np.linspace(0, 1, 5), cache=False); out["truth"] = "returned"
        except ValueError as e:
            out["truth"] = str(e)
        print(json.dumps(out))
    """)
    for solver, msg in out.items():
        assert msg.startswith("`y0` must be a state of"), (solver, msg)
        assert "finite" in msg and "\n" not in msg


@pytest.mark.parametrize("solver", ["dop853", "cvode-bdf", "heyoka"])
def test_subnormal_mass_model_built_around_the_check_still_ends(solver):
    # the constructor check bypassed (object built by hand): the solvers' own guards end the run
    out = run_bounded(f"""
        import json, numpy as np, rk4h
        from rk4h.references.solvers import integrate
        from rk4h.references.solvers.dop853 import run_dop853
        from rk4h.references.solvers.cvode import run_cvode
        from rk4h.references.solvers.taylor import run_heyoka
        m = rk4h.make_model("chain", {{"masses": [1.0, 1.0], "springs": [1.0, 1.0, 1.0]}})
        m.mass = np.array([5e-324, 1.0])
        from rk4h.references.solvers.tolerances import absolute_tolerance
        y0 = m.state([0.01, 0.0]); t = np.linspace(0, 1, 5)
        atol = absolute_tolerance(m, y0, 1e-6)  # as integrate() would: inf for the velocities here
        run = {{"dop853": lambda: run_dop853(m, y0, t, 1e-6, atol),
               "cvode-bdf": lambda: run_cvode("cvode-bdf", m, y0, t, 1e-6, atol),
               "heyoka": lambda: run_heyoka(m, y0, t, 1e-6, atol)}}[{solver!r}]()
        print(json.dumps({{"status": run.status.value, "message": run.message,
                          "last_finite": bool(np.isfinite(run.y[:, -1]).all())}}))
    """)
    assert out["status"] in ("unstable", "failed"), out
    assert not out["last_finite"]


DOP853_GUARDS = {
    # (rhs override, expected status, words in the message): each never returned before
    "nan-rhs-at-y0": ("return np.full_like(y, np.nan)", "unstable", "not finite at the initial state"),
    "first-step-not-finite": ("return super().rhs(t, y) if t == 0.0 else np.full_like(y, np.inf)",
                              "unstable", "no usable first step"),
    "nan-after-start-eval-cap": ("return super().rhs(t, y) if t < 1e-3 else np.full_like(y, np.nan)",
                                 "", ""),
}


@pytest.mark.parametrize("case", sorted(DOP853_GUARDS))
def test_dop853_guards_end_at_once(case):
    # a model with finite force and energy at y0 whose right-hand side breaks
    # (stands in for any model whose equations fail at or right after the start)
    body, status, words = DOP853_GUARDS[case]
    out = run_bounded(f"""
        import json, time, numpy as np, rk4h
        from rk4h.references.solvers.dop853 import EVALS_PER_STEP, run_dop853

        class Broken(rk4h.models.Chain):
            def rhs(self, t, y):
                {body}

        m = Broken(masses=[1.0, 2.0], springs=[10.0, 20.0, 30.0])
        t0 = time.perf_counter()
        run = run_dop853(m, m.state([0.01, 0.0]), np.linspace(0.0, 1.0, 5), 1e-6, np.full(4, 1e-8), max_steps=3)
        print(json.dumps({{"status": run.status.value, "message": run.message, "n_steps": run.n_steps,
                          "t_fail": run.t_fail, "wall": time.perf_counter() - t0,
                          "calls": run.extra["nfev_calls"], "cap": EVALS_PER_STEP * 3 + 100,
                          "rest_nan": bool(np.isnan(run.y[:, 1:]).all())}}))
    """)
    assert out["wall"] < 5.0 and out["calls"] <= out["cap"], out
    assert out["rest_nan"]
    if status:
        assert out["status"] == status and words in out["message"], out
        assert out["n_steps"] == 0 and out["t_fail"] == 0.0
    else:
        assert out["status"] in ("failed", "unstable"), out


@pytest.mark.parametrize("solver", ["dop853", "cvode-adams", "heyoka"])
def test_step_cap_is_a_failed_status(solver):
    model = rk4h.make_model("chain", {"masses": [0.815, 3.099], "springs": [41.5, 138.0, 157.8]})
    y0 = model.state([0.005, 0.005])
    run = integrate(solver, model, y0, np.linspace(0.0, 10.0, 11), 1e-10, max_steps=20)
    assert run.status is Status.FAILED and "step cap" in run.message and "max_steps = 20" in run.message
    assert run.n_steps <= 20 and 0.0 < run.t_fail < 10.0
    assert np.all(np.isnan(run.y[:, -1])) and np.all(np.isfinite(run.y[:, 0]))


class Cliff(Planar4):
    """planar4 plus a term ``1e-20 sqrt(x - 0.015)``: its force is NaN (numpy)
    and non-finite (heyoka) for x < 0.015 m. Started at x = 0.02 m it reaches
    such a state near t = 0.07 s: a singular state met mid-run."""

    name = "planar4"

    def _force(self, q, ops):
        f = super()._force(q, ops)
        c = 1e-20 * ops.sqrt(q[0] - 0.015)
        return np.array([f[0] + c, f[1]], dtype=object) if q.dtype == object else np.stack([f[0] + c, f[1]])


def _cliff():
    m = Cliff(0.815, 41.5, 0.01)
    return m, m.state([0.02, 0.001])


T_CLIFF = np.linspace(0.0, 0.5, 51)


@pytest.mark.parametrize("solver", [*REFERENCES, UNDER_TEST])
def test_singular_state_reached_mid_run_is_unstable_with_its_time_quickly(solver):
    m, y0 = _cliff()
    t0 = time.perf_counter()
    with np.errstate(all="ignore"):
        run = integrate(solver, m, y0, T_CLIFF, 1e-8 if BUILTIN[solver].adaptive else 1e-4)
    assert time.perf_counter() - t0 < 30.0  # heyoka's JIT included
    assert run.status is Status.UNSTABLE, run.message
    assert 0.05 < run.t_fail < 0.1, run.t_fail
    assert run.y.shape == (4, 51)
    assert np.all(np.isfinite(run.y[:, T_CLIFF <= 0.05])) and np.all(np.isnan(run.y[:, T_CLIFF > 0.1]))
    if BUILTIN[solver].adaptive:
        assert f"{run.t_fail:.6g}" in run.message or "non-finite" in run.message


@pytest.mark.parametrize("call", ["integrate", "reference_solution"])
def test_model_name_instead_of_model_is_refused_naming_model(call):
    with pytest.raises(ValueError, match="`model`"):
        if call == "integrate":
            integrate("dop853", "chain", [0.0, 0.0], [0.0, 1.0], 1e-6)
        else:
            reference_solution("chain", [0.0, 0.0], [0.0, 1.0])


# =============================================================================================
# 3. heyoka's shortened grid output: padded, a status, never an exception
# =============================================================================================
def _short(outcome_name, rows):
    import heyoka as hy

    real = taylor._propagate_grid

    def fake(ta, grid, max_steps):
        res = list(real(ta, grid, max_steps))
        res[0] = getattr(hy.taylor_outcome, outcome_name)
        res[5] = np.asarray(res[5])[:rows]
        return tuple(res)

    return fake


SHORT = [
    ("nf-state-3-rows", "err_nf_state", 3, Status.UNSTABLE),
    ("nf-state-0-rows", "err_nf_state", 0, Status.UNSTABLE),
    ("step-limit-5-rows", "step_limit", 5, Status.FAILED),
    ("time-limit-but-short", "time_limit", 7, Status.FAILED),
]


@pytest.mark.parametrize("where", ["heyoka", "truth"])
@pytest.mark.parametrize("outcome, rows, status", [c[1:] for c in SHORT], ids=[c[0] for c in SHORT])
def test_short_heyoka_output_is_padded_not_an_index_error(monkeypatch, where, outcome, rows, status):
    model, y0 = _pend()
    monkeypatch.setattr(taylor, "_propagate_grid", _short(outcome, rows))
    if where == "heyoka":
        run = integrate("heyoka", model, y0, T11, 1e-10)
        y, msg = run.y, run.message
    else:
        run = reference_solution(model, y0, T11, cache=False)
        y, msg = run.y, run.message
        assert run.y_lo.shape == y.shape and np.all(np.isnan(run.y_lo[:, rows:]))
    assert run.status is status, msg
    assert y.shape == (4, 11)
    assert np.all(np.isnan(y[:, rows:]))
    assert f"{rows} of 11 output times" in msg


@pytest.mark.parametrize("where", ["heyoka", "truth"])
def test_real_collision_mid_run_loses_no_rows(where):
    m, y0 = _cliff()
    if where == "heyoka":
        run = integrate("heyoka", m, y0, T_CLIFF, 1e-10)
    else:
        run = reference_solution(m, y0, T_CLIFF, cache=False)
    t_fail = run.t_fail if where == "heyoka" else run.extra["t_fail"]
    assert run.status is Status.UNSTABLE and 0.05 < t_fail < 0.1, run.message
    assert run.y.shape == (4, 51)
    reached = run.extra["rows_returned"]
    assert 0 < reached < 51
    assert np.all(np.isfinite(run.y[:, :reached])) and np.all(np.isnan(run.y[:, reached:]))


# =============================================================================================
# 4. The stability study: bounded parameters, bounded loops, a step estimate
# =============================================================================================

BAD_STABILITY = [
    ("bisection-rtol-1e-300", "bisection_rtol", 1e-300),
    ("bisection-rtol-0.5", "bisection_rtol", 0.5),
    ("long-periods-1e13", "long_periods", 1e13),
    ("long-periods-quick-1e13", "long_periods_quick", 1e13),
    ("n-values-1e12", "n_values", [1e12]),
    ("n-values-fraction", "n_values", [3000, 2.5]),
    ("drift-theta-10", "drift_theta", [0.1, 10.0]),
    ("growth-theta-65-entries", "growth_theta", [0.5] * 65),
    ("target-error-0", "target_error", 0.0),
    ("mu-0", "mu", [0.0]),
    ("amplitudes-text", "amplitudes", ["a"]),
    ("singular-offset-inf", "singular_offset", math.inf),
    ("long-theta-bool", "long_theta", True),
    ("roundoff-theta-tiny", "roundoff_theta", [1e-9]),
]


@pytest.mark.parametrize("key, value", [c[1:] for c in BAD_STABILITY], ids=[c[0] for c in BAD_STABILITY])
def test_stability_value_out_of_bounds_names_the_field(key, value):
    with pytest.raises(ValueError) as info:
        validate_params({"studies": ["boundary"], key: value})
    msg = str(info.value)
    assert msg.startswith(f"`stability.{key}") and "\n" not in msg
    assert info.value.field.startswith(f"stability.{key}")


@pytest.mark.parametrize("key, value, problem", [
    ("bisection_rtol", "1e-300", "must lie in [1e-12, 0.001] (got 1e-300)"),
    ("long_periods", "1e13", "must lie in [1, 1e7] periods (got 10000000000000.0)"),
    ("n_values", "[1e12]", "must lie in [2, 1000000] masses (got 1000000000000.0)"),
], ids=["bisection_rtol", "long_periods", "n_values"])
def test_scene_file_error_is_one_line_with_the_stability_field(tmp_path, key, value, problem):
    from rk4h.validation.scenes import SCENE_DIR, SceneError, load_scene

    text = (SCENE_DIR / "stability_2dof.toml").read_text() + f"{key} = {value}\n"
    path = tmp_path / "bad.toml"
    path.write_text(text)
    with pytest.raises(SceneError) as info:
        load_scene(path)
    field = f"stability.{key}" + ("[0]" if key == "n_values" else "")
    assert str(info.value) == f"{path}: field `{field}`: {problem}"
    assert str(path) not in info.value.field


def test_bounds_table_covers_every_key_and_its_defaults():
    names = [p.name for p in PARAMS]
    assert len(names) == len(set(names))
    every = {p.name: p.default for p in PARAMS if p.default is not None}
    out = validate_params({"studies": ["boundary"], **every})  # every default within its bounds
    assert set(out) == set(names)
    table = params_table_markdown()
    assert all(f"`{n}`" in table for n in names)
    for p in PARAMS:
        assert len(p) == 7 and p.unit and p.meaning


def test_bisection_ends_for_any_rtol():
    out = run_bounded("""
        import json, math, rk4h
        from rk4h.validation.stability import boundary as B
        m = rk4h.make_model("chain", {"masses": [0.815, 3.099], "springs": [41.5, 138.0, 157.8]})
        h, probes = B.largest_stable_step(m, "rk4", rtol=1e-300)
        w = float(m.modes()[0][-1])
        print(json.dumps({"ratio": h * w / (2 * math.sqrt(2)), "probes": probes}))
    """, timeout=60)
    assert out["ratio"] == pytest.approx(1.0, rel=1e-6)
    assert out["probes"] <= B.MAX_BISECTIONS + 40


def test_study_run_beyond_the_work_cap_is_refused_before_it_starts():
    model = rk4h.make_model("chain", {"masses": [1.0, 1.0], "springs": [1.0, 1.0, 1.0]})
    t0 = time.perf_counter()
    with pytest.raises(SC.StudyCapError, match="cap"):
        SC.integrate_fixed(model, (0.0, 1e13), model.state([0.01, 0.0]), h=1e-3)
    assert time.perf_counter() - t0 < 1.0


STABILITY_SCENES = ["stability_2dof", "stability_stiff_chain", "stability_large_n", "stability_planar4"]


@pytest.fixture
def step_counter(monkeypatch):
    """Count every integration step the stability study takes: fixed-step runs
    (``res.n_steps``), ``rk4h.references.solvers.integrate`` runs, the large-N
    CVODE and tracemalloc runs, and the bisection's one-step-map probes."""
    import rk4h.references.solvers as RS
    from rk4h.validation.stability import geometry as G
    from rk4h.validation.stability import large_n as LN
    from rk4h.validation.stability import long_horizon as LH
    from rk4h.validation.stability import stiffness as ST
    from rk4h.validation.stability import studies as S

    tally = collections.Counter()
    fixed, integ = SC.integrate_fixed, RS.integrate

    def counted_fixed(*a, **k):
        res, path = fixed(*a, **k)
        tally["fixed"] += int(res.n_steps)
        return res, path

    def counted_integrate(solver, *a, **k):
        run = integ(solver, *a, **k)
        tally["adaptive"] += int(run.n_steps)
        return run

    for mod in (B, LH, ST, G, LN, S):
        monkeypatch.setattr(mod, "integrate_fixed", counted_fixed)
    monkeypatch.setattr(RS, "integrate", counted_integrate)
    cv, pb, sr = LN.cvode_band_cost, LN.peak_bytes, B.spectral_radius

    def counted_cv(N, *a, **k):
        out = cv(N, *a, **k)
        tally["adaptive"] += out["n_steps"]
        return out

    def counted_pb(N, n_steps=3):
        tally["fixed"] += n_steps
        return pb(N, n_steps)

    def counted_sr(*a, **k):
        tally["probe"] += 1
        return sr(*a, **k)

    monkeypatch.setattr(LN, "cvode_band_cost", counted_cv)
    monkeypatch.setattr(LN, "peak_bytes", counted_pb)
    monkeypatch.setattr(B, "spectral_radius", counted_sr)
    return tally


# the two scenes with the longest quick studies (~9 s together) run with -m slow
@pytest.mark.parametrize("name", [pytest.param(n, marks=pytest.mark.slow)
                                  if n in ("stability_2dof", "stability_large_n") else n
                                  for n in STABILITY_SCENES])
def test_estimate_steps_matches_the_steps_taken(name, step_counter, tmp_path):
    # Factor 2 on the total: fixed-step counts are the studies' own step rules on exact
    # frequencies (measured 0-5 % apart), adaptive counts a per-period model calibrated
    # on these scenes (0.5x-4x per solver); totals measured 0.7x-1.0x.
    from rk4h.validation.scenes import SCENE_DIR, load_scene
    from rk4h.validation.stability import run

    scene = load_scene(SCENE_DIR / f"{name}.toml")
    t0 = time.perf_counter()
    detail = estimate_steps(scene, quick=True, detail=True)
    est = estimate_steps(scene, quick=True)
    assert time.perf_counter() - t0 < 2.0
    result = run(scene, tmp_path, quick=True)
    assert not [r for r in result.rows if r["status"] == "failed"]
    taken = sum(step_counter.values())
    assert 0.5 <= est / taken <= 2.0, (est, dict(step_counter), detail)
    fixed_est = sum(v for d in detail.values() for k, v in d.items()
                    if k in ("rk4", "euler", "symplectic-euler"))
    assert 0.95 <= fixed_est / step_counter["fixed"] <= 1.25, (fixed_est, dict(step_counter))


def test_estimate_steps_needs_no_dense_eigensolve_of_the_scene(monkeypatch):
    from rk4h.validation.scenes import scene_from_dict

    N = 20000
    doc = {"name": "big_chain", "model": "chain",
           "params": {"masses": [1.0] * N, "springs": [1.0] * (N + 1)},
           "initial": {"x": [0.001] + [0.0] * (N - 1)},
           "run": {"t_end": 1.0, "h": [0.01], "solvers": ["rk4"], "outputs": ["stability"]},
           "stability": {"studies": ["long_horizon", "roundoff"]}}
    scene = scene_from_dict(doc)

    def refuse(self):
        raise AssertionError("dense eigensolve")

    monkeypatch.setattr(rk4h.models.Model, "modes", refuse)
    t0 = time.perf_counter()
    d = estimate_steps(scene, quick=True, detail=True)
    assert time.perf_counter() - t0 < 5.0
    # omega_max/omega_min = sin(N pi / 2(N+1)) / sin(pi / 2(N+1)) for the uniform chain
    ratio = math.sin(N * math.pi / (2 * (N + 1))) / math.sin(math.pi / (2 * (N + 1)))
    n_long = 1e3 * 2 * math.pi * ratio / 0.2
    assert d["long_horizon"]["rk4"] == pytest.approx(6 * 2000 + n_long, rel=1e-6)


# =============================================================================================
# 5. Theory functions against mpmath
# =============================================================================================

THETAS = [0.05, 0.5, 2.6, 2.8]


def _mp_R(s):
    z = mp.mpc(0, s)
    return 1 + z + z**2 / 2 + z**3 / 6 + z**4 / 24


def _mp_lag(theta):
    """theta - arg R(i theta) with the argument continued from 0: the integral of
    d arg R(i s)/ds = Re(R'(i s) / R(i s)) (no branch choice involved)."""
    def darg(s):
        z = mp.mpc(0, s)
        return mp.re((1 + z + z**2 / 2 + z**3 / 6) / _mp_R(s))
    th = mp.mpf(theta)
    return th - mp.quad(darg, [0, th])


@pytest.mark.parametrize("theta", THETAS)
def test_phase_lag_per_step_against_mpmath(theta):
    with mp.workdps(40):
        ref = _mp_lag(theta)
        got = LHm.rk4_phase_lag_per_step(theta)
        assert abs((mp.mpf(float(got)) - ref) / ref) < 1e-13
        assert abs((mp.mpf(float(LHm.rk4_phase_lag_per_step(-theta))) + ref) / ref) < 1e-13  # odd


@pytest.mark.parametrize("theta", THETAS)
def test_energy_theory_against_mpmath(theta):
    with mp.workdps(40):
        t = mp.mpf(theta)
        g = abs(_mp_R(t)) ** 2
        assert abs((mp.mpf(float(metrics.rk4_energy_log_factor(theta))) - mp.log(g)) / mp.log(g)) < 1e-13
        loss = 1 - g
        assert abs((mp.mpf(float(LHm.rk4_energy_loss_per_step(theta))) - loss) / loss) < 1e-13
        # the drift theory of one mode over n steps: g^n - 1 per unit time
        n, h = 1000, 0.01
        ref = (g**n - 1) / (n * h)
        got = metrics.rk4_drift_theory(np.array([theta / h]), np.array([1.0]), np.array([0.0]), h, n, n * h)
        assert abs((mp.mpf(got) - ref) / ref) < 1e-12


def test_the_old_formulas_fail_these_checks():
    # negative controls: np.angle wraps by 2 pi past sqrt 6, log(1 - ...) cancels at 0.05
    with mp.workdps(40):
        z = 1j * 2.6
        wrapped = 2.6 - np.angle(1 + z + z**2 / 2 + z**3 / 6 + z**4 / 24)
        assert abs(wrapped - float(_mp_lag(2.6))) == pytest.approx(2 * math.pi, rel=1e-9)
        th = 0.05
        naive = math.log(1 - th**6 / 72 + th**8 / 576)
        ref = mp.log(abs(_mp_R(mp.mpf(th))) ** 2)
        assert abs((mp.mpf(naive) - ref) / ref) > 1e-9


def test_phase_argument_is_continuous_through_sqrt6():
    s6 = math.sqrt(6.0)
    a = LHm.rk4_phase_arg(np.array([s6 - 1e-9, s6, s6 + 1e-9]))
    assert np.all(np.abs(np.diff(a)) < 1e-8) and a[1] == pytest.approx(math.pi, rel=1e-12)


def test_the_stability_parameter_document_is_current():
    from pathlib import Path

    from rk4h.validation.stability.params import params_document

    doc = Path(__file__).resolve().parents[1] / "docs" / "stability-params.md"
    assert doc.read_text() == params_document(), "run: python -m rk4h.validation.stability.params > docs/stability-params.md"
