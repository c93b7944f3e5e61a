"""The trust table (validation.trust, cheapest.csv) and the advisor
(validation/advise.py): the step for a target from the error constant, the
verdict rules, verdicts identical on a rerun, the advisor's step confirmed
and within 2x of the largest step that meets the target."""
import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from validation import trust
from validation.advise import _Problem, advise

REPO = Path(__file__).resolve().parent.parent


@pytest.mark.parametrize("order, C", [(4, 1.5e4), (2, 3.0), (1, 0.5)])
def test_error_constant_and_step_invert_a_power_law(order, C):
    h = np.array([0.1, 0.05, 0.02, 0.01, 0.005])
    err = C * h**order
    assert trust.error_constant(h, err, order) == pytest.approx(C, rel=1e-12)
    h_t, source, n = trust.step_for(1e-6, C, order, 10.0)
    assert source == "error constant" and C * h_t**order <= 1e-6
    assert C * (10.0 / (n - 1)) ** order > 1e-6  # one step fewer would miss


def test_step_is_capped_by_stability_and_refused_below_round_off():
    h, source, _ = trust.step_for(1e-3, 1e-9, 4, 10.0, h_stab=0.1)
    assert source == "stability" and h <= trust.STABILITY_MARGIN * 0.1
    h, source, n = trust.step_for(1e-17, 1.0, 4, 10.0)
    assert source == "round-off" and math.isnan(h) and trust.roundoff_level(n) > 1e-17


@pytest.mark.parametrize("ta, tb, want", [
    ((1.0, 0.9, 1.1), (4.0, 3.8, 4.2), "a"),       # 4x apart, repeats disjoint
    ((1.0, 0.9, 1.1), (2.5, 2.4, 2.6), "tie"),     # disjoint but under the margin
    ((1.0, 0.5, 3.5), (4.0, 3.0, 5.0), "tie"),     # 4x but the repeats overlap
    ((5.0, 4.9, 5.1), (1.0, 1.0, 1.0), "b"),
    ((math.nan,) * 3, (1.0, 1.0, 1.0), "b"),
])
def test_time_verdict_needs_margin_and_disjoint_repeats(ta, tb, want):
    assert trust.time_verdict("a", ta, "b", tb) == want


def _run(out):
    r = subprocess.run([sys.executable, "validation/run_all.py", "--scene", "thesis-2dof-case1", "--out", str(out)],
                       cwd=REPO, capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr
    return pd.read_csv(Path(out) / "cheapest.csv")


def test_verdicts_survive_a_rerun(tmp_path):
    a, b = _run(tmp_path / "a"), _run(tmp_path / "b")
    cols = ["scene", "target_error", "method", "h", "rhs", "alternative", "alt_rhs",
            "verdict_rhs", "verdict_one_run", "verdict_amortized"]
    pd.testing.assert_frame_equal(a[cols], b[cols], check_exact=True)


# -- the advisor ------------------------------------------------------------------------
def _largest_step_meeting(p, method, target, h0, h_cap):
    """Bisection (on log h) for the largest step whose error meets ``target``,
    among steps that divide the output spacing (as the advisor's do: off the
    step grid the outputs would be interpolated, a third-order error)."""
    def meets(h):
        return p.run(method, p.on_grid(h))[0] <= target

    lo, hi = h0 / 8, min(8 * h0, h_cap)
    if meets(hi):
        return p.on_grid(hi)
    assert meets(lo)
    for _ in range(14):
        mid = math.sqrt(lo * hi)
        lo, hi = (mid, hi) if meets(mid) else (lo, mid)
    return p.on_grid(lo)


FAST = ["thesis-2dof-case1", "three-blocks", "pendulums-beats"]
ALL = sorted({tomlname for tomlname in
              (f.stem.replace("_", "-") for f in (REPO / "validation" / "scenes").glob("*.toml"))
              if not tomlname.startswith(("thesis-code", "stability-"))})


def _scene(name):
    from validation.scenes import load_scenes

    return load_scenes([name])[0]


def _check_advice(name, target):
    scene = _scene(name)
    adv = advise(scene, target)
    assert adv.status == "ok", adv
    assert adv.confirmed_error <= target
    p = _Problem(scene)
    under = next(s for s in scene.solvers if scene.method(s).fixed_step and scene.method(s).tableau is not None)
    method = scene.method(under)
    cand = next(c for c in adv.candidates if c["method"] == under)
    if cand["source"] == "round-off":
        pytest.skip(f"{under} cannot reach {target:g} above round-off on {name}")
    h_best = _largest_step_meeting(p, method, target, cand["setting"], 0.95 * p.h_stab(method))
    assert h_best / 2 <= cand["setting"] <= 2 * h_best, (cand, h_best)


@pytest.mark.parametrize("target", [1e-3, 1e-6, 1e-9])
@pytest.mark.parametrize("name", FAST)
def test_advisor_confirms_the_target_and_predicts_the_step_within_2x(name, target):
    _check_advice(name, target)


@pytest.mark.slow
@pytest.mark.parametrize("target", [1e-3, 1e-6, 1e-9])
@pytest.mark.parametrize("name", [n for n in ALL if n not in FAST])
def test_advisor_on_every_shipped_scene(name, target):
    _check_advice(name, target)


def test_advisor_json_has_the_promised_keys():
    r = subprocess.run([sys.executable, "validation/advise.py", "thesis-2dof-case1", "--target", "1e-6", "--json"],
                       cwd=REPO, capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    d = json.loads(r.stdout)
    for key in ("method", "setting", "model", "predicted_error", "confirmed_error", "cost_rhs", "cost_s"):
        assert key in d
    assert d["confirmed_error"] <= 1e-6 and d["model"] == "closed form"


@pytest.mark.parametrize("args, words", [
    (["thesis-2dof-case1", "--target", "x"], "--target: must be a number"),
    (["thesis-2dof-case1", "--target", "2"], "--target: must lie in (0, 1)"),
    (["no-such-scene", "--target", "1e-3"], "is neither a file nor a shipped scene"),
])
def test_advisor_bad_input_is_one_line_exit_2(args, words):
    r = subprocess.run([sys.executable, "validation/advise.py", *args], cwd=REPO, capture_output=True, text=True,
                       timeout=120)
    assert r.returncode == 2 and words in r.stderr and "Traceback" not in r.stderr
    assert r.stderr.count("\n") == 1


def test_advisor_warns_of_aliasing_and_steps_past_the_limit():
    from validation.scenes import scene_from_dict

    scene = scene_from_dict({"name": "warn", "model": "chain",
                             "params": {"masses": [1.0, 1.0], "springs": [100.0, 1.0, 100.0], "walls": "both"},
                             "initial": {"x": [0.01, 0.0]},
                             "run": {"t_end": 10.0, "h": [0.5, 0.01], "output_dt": 0.5, "tolerances": [1e-8],
                                     "solvers": ["rk4", "dop853"], "outputs": ["state"]}})
    adv = advise(scene, 1e-4)
    text = " ".join(adv.warnings)
    assert "aliases" in text and "exceed its stability limit" in text


def test_the_rk4h_command_dispatches_and_refuses_unknown_commands(capsys):
    from validation.cli import main

    assert main(["bogus"]) == 2 and "unknown command 'bogus'" in capsys.readouterr().err
    assert main(["advise", "three-blocks", "--target", "1e-3", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["confirmed_error"] <= 1e-3
