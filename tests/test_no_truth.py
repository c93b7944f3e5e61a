"""No truth is a failure, never blank errors beside "all expectations held".

An FPUT-beta chain started in its sine mode is symmetric: the middle spring's
extension is exactly 0 for all time. heyoka's Taylor recurrence of
``pow(r, 3.0)`` divides by ``r`` and was NaN there, so the reference (and the
``heyoka`` solver) were NaN and the accuracy table had empty error cells.
"""
import math

import numpy as np
import pandas as pd
import pytest

from rk4h.references.solvers import integrate
from rk4h.references.truth import reference_solution
from rk4h.models import Chain
from rk4h.validation import execute as X
from rk4h.validation import run_all

# x_n = sin(n pi / 5), n = 1..4: sin(3 pi/5) = sin(2 pi/5) and sin(4 pi/5) = sin(pi/5),
# written as the same doubles so that the middle spring's extension is exactly 0.
S1, S2 = 0.5877852522924731, 0.9510565162951535
SINE = [S1, S2, S2, S1]

SCENE = f"""
name = "fput-beta-sine"
model = "chain"
[params]
masses = 1.0
springs = 1.0
n = 4
walls = "both"
beta = 1.0
[initial]
x = {SINE}
v = [0.0, 0.0, 0.0, 0.0]
[run]
t_end = 5.0
h = [0.1, 0.05]
tolerances = [1e-8, 1e-10]
solvers = ["rk4", "dop853", "heyoka"]
outputs = ["state", "energy"]
"""


@pytest.fixture
def tmp_cache(tmp_path, monkeypatch):
    """An empty truth cache (``tmp_path/cache/truth``): the truths here are
    computed, not read from one an older heyoka wrote. Only the truth's: the
    compiled loops keep the user's cache (a fresh ``RK4H_CACHE`` made the
    scene's run compile its numba loop cold, 22 of its 30 s)."""
    from rk4h.references import truth as T

    real = T.cache_dir
    fresh = tmp_path / "cache" / "truth"
    monkeypatch.setattr(T, "cache_dir", lambda path=None: real(path if path is not None else fresh))
    return tmp_path / "cache"


def _model_y0():
    return Chain(1.0, 1.0, n=4, beta=1.0), np.array(SINE + [0.0] * 4)


def test_sine_mode_starts_at_a_zero_extension():
    m, y0 = _model_y0()
    r = np.diff(np.concatenate([[0.0], y0[:4], [0.0]]))
    assert r[2] == 0.0


def test_fput_beta_sine_mode_on_heyoka_double_and_quadruple(tmp_cache):
    m, y0 = _model_y0()
    t = np.linspace(0.0, 5.0, 51)
    truth = reference_solution(m, y0, t, kind="heyoka-real128", path=tmp_cache)
    assert truth.ok, truth.message
    assert np.all(np.isfinite(truth.y))
    run = integrate("heyoka", m, y0, t, 1e-14)
    assert run.ok, run.message
    assert np.all(np.isfinite(run.y))
    # the middle spring stays at zero extension (symmetry), and the two precisions agree
    assert np.max(np.abs(truth.y[2] - truth.y[1])) == 0.0
    assert np.max(np.abs(run.y - truth.y)) < 1e-11
    # and the double-precision reference agrees with an independent one (DOP853)
    ref = integrate("dop853", m, y0, t, 1e-12)
    assert np.max(np.abs(ref.y - truth.y)) < 1e-9


def _run(tmp_path, capsys):
    scene = tmp_path / "fput_beta_sine.toml"
    scene.write_text(SCENE)
    out = tmp_path / "out"
    rc = run_all.main(["--scene", str(scene), "--out", str(out), "--repeats", "1", "--no-figures",
                       "--workers", "1"])
    return rc, out, capsys.readouterr()


def test_fput_beta_sine_scene_has_finite_errors(tmp_path, tmp_cache, capsys):
    rc, out, cap = _run(tmp_path, capsys)
    assert rc == 0, cap.out + cap.err
    acc = pd.read_csv(out / "accuracy.csv")
    assert set(acc["solver"]) == {"rk4", "dop853", "heyoka"}
    assert np.all(np.isfinite(acc["error_max"])), acc[["solver", "setting", "error_max"]]
    assert acc["note"].isna().all()
    assert (acc["status"] == "ok").all()


@pytest.mark.parametrize("how", ["nan", "raise"])
def test_a_scene_without_truth_fails_and_exits_1(tmp_path, tmp_cache, capsys, monkeypatch, how):
    real = X._truth

    def broken(model, y0, t):
        if how == "raise":
            raise RuntimeError("the reference integrator broke")
        truth = real(model, y0, t)
        truth.y = np.full_like(truth.y, math.nan)
        return truth

    monkeypatch.setattr(X, "_truth", broken)
    X.clear_problems()
    rc, out, cap = _run(tmp_path, capsys)
    assert rc == 1, cap.out + cap.err
    assert "all expectations held" not in cap.out
    index = (out / "index.md").read_text()
    failures = index[index.index("## Failures"):index.index("## Main findings")]
    assert "every expectation held" not in failures
    assert "no truth" in failures
    if how == "raise":
        assert "the reference integrator broke" in failures
    acc = pd.read_csv(out / "accuracy.csv")
    # typed: the error columns stay float (NaN), the reason is in the text column `note`
    assert acc["error_max"].dtype == float and acc["error_max"].isna().all()
    assert acc["note"].str.startswith("no truth").all()
    # the runs themselves are still measured
    assert np.all(np.isfinite(acc["energy_drift_max"]))
