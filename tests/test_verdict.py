"""A verdict needs a run: the trust table (cheapest.csv), its index.md lines
and the crossover figure name a method only where a measured run at the
recommended setting met the target (rk4h.validation.trust, rk4h.validation.confirm).

The winner logic on synthetic rows (an unconfirmed prediction never wins, an
exact tie of RHS calls is a tie, no run reaching the target is
``unmeasured``), the planning of the confirmation runs, and the invariant
over a fresh ``--quick`` run and over the committed ``reports/cheapest.csv``.
"""
import math
from pathlib import Path
from types import SimpleNamespace

import pandas as pd
import pytest

from rk4h.references.registry import BUILTIN
from rk4h.validation import confirm, trust
from rk4h.validation.report import trust_lines
from rk4h.validation.run_all import _crossover_job

REPO = Path(__file__).resolve().parent.parent
RK4 = BUILTIN["rk4"]
T_END = 100.0


def _row(solver, setting, err, nfev, n_steps=None, wall=1e-3, order=0):
    return dict(solver=solver, setting=setting, error_rel=err, nfev=nfev,
                n_steps=n_steps if n_steps is not None else nfev, wall_s=wall, wall_min=wall, wall_max=wall,
                compile_s=0.0, status="ok", taylor_order=order)


def _rk4(pts):
    """RK4 runs over T_END s at the steps and errors ``pts``."""
    return [_row("rk4", h, e, 4 * round(T_END / h), round(T_END / h)) for h, e in pts]


#: err = 1e3 h^4: an error constant; 1e-9 needs h = 1e-3 s (4e5 calls), no run of the scene reaches it
POWER_LAW = [(h, 1e3 * h**4) for h in (0.1, 0.05, 0.025, 0.0125)]


# -- the winner logic --------------------------------------------------------------------
def test_an_unconfirmed_prediction_never_wins():
    alt = [_row("dop853", 1e-12, 5e-10, 4e6)]   # ten times the predicted calls of rk4
    (row,) = trust.trust_rows("s", _rk4(POWER_LAW) + alt, RK4, T_END, math.inf, [1e-9])
    assert row["h"] == pytest.approx(1e-3) and row["rhs"] < row["alt_rhs"]   # the prediction is cheaper ...
    assert not row["confirmed"] and math.isnan(row["confirmed_error_rel"])
    assert row["verdict_rhs"] == row["verdict_amortized"] == row["verdict_one_run"] == "dop853"  # ... but not run
    assert row["alt_confirmed"] and row["alt_confirmed_error_rel"] == 5e-10


def test_a_confirmation_that_misses_the_target_does_not_win():
    alt = [_row("dop853", 1e-12, 5e-10, 4e6)]
    missed = _rk4([(1e-3, 3e-9)])
    (row,) = trust.trust_rows("s", _rk4(POWER_LAW) + alt, RK4, T_END, math.inf, [1e-9], confirmations=missed)
    assert not row["confirmed"] and row["confirmed_error_rel"] == 3e-9 and row["verdict_rhs"] == "dop853"
    met = _rk4([(1e-3, 8e-10)])
    (row,) = trust.trust_rows("s", _rk4(POWER_LAW) + alt, RK4, T_END, math.inf, [1e-9], confirmations=met)
    assert row["confirmed"] and row["confirmed_error_rel"] == 8e-10 and row["verdict_rhs"] == "rk4"
    assert row["h"] == 1e-3 and row["h_source"] == "error constant" and row["rhs"] == 4e5


def test_no_run_reaching_the_target_is_unmeasured():
    (row,) = trust.trust_rows("s", _rk4(POWER_LAW), RK4, T_END, math.inf, [1e-9])
    assert row["verdict_rhs"] == row["verdict_amortized"] == row["verdict_one_run"] == trust.UNMEASURED
    assert row["alternative"] == "" and not row["confirmed"] and not row["alt_confirmed"]
    assert "not confirmed by a run" in row["note"]
    # the method's own measured run is enough for it to win where nothing else reached the target
    (row,) = trust.trust_rows("s", _rk4(POWER_LAW), RK4, T_END, math.inf, [1e-3])
    assert row["confirmed"] and row["verdict_rhs"] == "rk4" and row["confirmed_error_rel"] <= 1e-3


def test_an_exact_tie_of_calls_is_a_tie():
    met = _rk4([(1e-3, 8e-10)])                     # 4e5 calls
    alt = [_row("dop853", 1e-12, 5e-10, 4e5)]        # the same count
    (row,) = trust.trust_rows("s", _rk4(POWER_LAW) + alt, RK4, T_END, math.inf, [1e-9], confirmations=met)
    assert row["rhs"] == row["alt_rhs"] and row["verdict_rhs"] == trust.TIE
    alt = [_row("dop853", 1e-12, 5e-10, 4e5 + 1)]    # one call more: rk4
    (row,) = trust.trust_rows("s", _rk4(POWER_LAW) + alt, RK4, T_END, math.inf, [1e-9], confirmations=met)
    assert row["verdict_rhs"] == "rk4"


def test_a_reference_run_at_a_tighter_tolerance_counts_as_the_alternative():
    tight = [_row("heyoka", 1e-14, 4e-13, 0, n_steps=500, order=20)]
    (row,) = trust.trust_rows("s", _rk4(POWER_LAW), RK4, T_END, math.inf, [1e-12], confirmations=tight)
    assert row["alternative"] == "heyoka" and row["alt_rhs"] == 1e4 and row["verdict_rhs"] == "heyoka"


def test_on_grid_divides_the_output_spacing():
    assert trust.on_grid(0.03, 0.1) == pytest.approx(0.1 / 4)
    assert trust.on_grid(0.1, 0.1) == 0.1 and trust.on_grid(0.35, 0.1) == 0.1
    assert math.isnan(trust.on_grid(math.nan, 0.1)) and trust.on_grid(0.03, None) == 0.03


# -- index.md and the crossover figure ----------------------------------------------------
def _table(confirmations=(), alt=()):
    return trust.trust_rows("s", _rk4(POWER_LAW) + list(alt), RK4, T_END, math.inf, [1e-3, 1e-9],
                            confirmations=list(confirmations))


def test_trust_lines_bold_only_a_measured_winner():
    text = "\n".join(trust_lines(_table()))   # 1e-3: rk4 measured; 1e-9: nothing measured
    assert "calls: **rk4**" in text and "predicted, unconfirmed; unmeasured" in text
    assert "**unmeasured**" not in text and "**tie**" not in text
    text = "\n".join(trust_lines(_table(_rk4([(1e-3, 8e-10)]), [_row("dop853", 1e-12, 5e-10, 4e5)])))
    assert "calls: tie" in text and "measured 8e-10" in text


def test_crossover_names_only_confirmed_winners():
    rows = _table(alt=[_row("dop853", 1e-12, 5e-10, 4e6)]) + _table(_rk4([(1e-3, 8e-10)]),
                                                                     [_row("dop853", 1e-12, 5e-10, 4e5)])
    cells = _crossover_job(rows).figures[0].data["rows"]
    got = [(c["target_error"], c["solver"], c["cell"]) for c in cells]
    assert got == [(1e-3, "rk4", ""), (1e-9, "dop853", ""), (1e-3, "rk4", ""), (1e-9, "", "tie")]
    cells = _crossover_job(_table()).figures[0].data["rows"]
    assert cells[1]["solver"] == "" and cells[1]["cell"] == "unmeasured"
    # read back from the CSV (booleans as text): the same cells
    cells = _crossover_job(pd.DataFrame(_table()).astype({"confirmed": str}).to_dict("records")).figures[0].data
    assert [c["solver"] for c in cells["rows"]] == ["rk4", ""]


def test_crossover_figure_says_tie_and_unmeasured(tmp_path):
    import matplotlib

    matplotlib.use("Agg")
    from rk4h.validation import figures

    rows = _crossover_job(_table() + _table(_rk4([(1e-3, 8e-10)]), [_row("dop853", 1e-12, 5e-10, 4e5)])
                          ).figures[0].data["rows"]
    for i, r in enumerate(rows):
        r["scene"] = f"s{i // 2}"
    path, caption = figures.crossover(tmp_path, pd.DataFrame(rows))
    assert path.exists()
    assert "rk4 2" in str(caption) and "tie 1" in str(caption) and "unmeasured 1" in str(caption)


# -- planning the confirmation runs ------------------------------------------------------
def _scene(output_dt=0.1, adaptive=("dop853", "heyoka")):
    return SimpleNamespace(t_end=T_END, output_dt=output_dt, adaptive_solvers=list(adaptive))


def test_confirmation_steps_are_the_predicted_ones_on_the_output_grid():
    steps = confirm._method_steps(_rk4(POWER_LAW), [], RK4, _scene(), math.inf)
    pred = [h for h, _, _ in trust.predicted_steps(_rk4(POWER_LAW), RK4, T_END, math.inf,
                                                   confirm.TARGETS)["steps"]]
    # 1e-3 is met by the scene's run at 0.025 s (1e3 h^4 = 3.9e-4): no run needed for it
    assert steps == [trust.on_grid(h, 0.1) for h in pred[1:]]
    assert all(0.1 / s == pytest.approx(round(0.1 / s)) for s in steps)


def test_a_missed_confirmation_is_retried_at_a_smaller_step_at_most_confirm_tries_times():
    def steps(tried):
        return confirm._method_steps(_rk4(POWER_LAW), tried, RK4, _scene(), math.inf)

    h6, h1, h12 = steps([])   # the steps for 1e-6, 1e-9, 1e-12
    tried = _rk4([(h1, 1e-8)])          # 1e-9 missed: ten times the target
    (h2,) = [s for s in steps(tried) if s not in (h6, h12)]
    assert h2 == trust.on_grid(h1 * 0.9 * 0.1 ** 0.25, 0.1)
    tried += _rk4([(h2, 1e-8)])
    (h3,) = [s for s in steps(tried) if s not in (h6, h12)]
    assert h3 < h2
    tried += _rk4([(h3, 1e-8)])
    assert confirm.CONFIRM_TRIES == 3 and steps(tried) == [h6, h12]   # three tries: no fourth
    # a try that met the target ends the tries
    assert steps(_rk4([(h1, 1e-8), (h2, 9e-10)])) == [h6, h12]


def test_references_run_tighter_only_where_no_other_run_reaches_a_target_and_stop_at_their_floor():
    rows = _rk4(POWER_LAW) + [_row("dop853", 1e-10, 3e-9, 1e4), _row("heyoka", 1e-10, 2e-9, 0, 100, 20)]
    got = confirm._reference_rtols(rows, [], _scene(), "rk4")
    assert [s for s, _ in got] == ["dop853", "heyoka"] and [r for _, r in got] == pytest.approx([1e-11, 1e-11])
    reached = rows + [_row("heyoka", 1e-16, 1e-13, 0, 100, 20)]
    assert confirm._reference_rtols(reached, [], _scene(), "rk4") == []
    at_floor = [_row("dop853", confirm.rtol_floor("dop853"), 2e-12, 1e5)]
    got = confirm._reference_rtols(rows, at_floor, _scene(), "rk4")
    assert ("dop853", pytest.approx(confirm.rtol_floor("dop853") / 10)) not in got
    assert [s for s, _ in got] == ["heyoka"]
    assert confirm.rtol_floor("dop853") == pytest.approx(100 * 2.220446049250313e-16)


# -- the invariant over a report -----------------------------------------------------------
def winner_violations(df) -> list[str]:
    """Rows of a cheapest.csv whose verdict names a side without a measured
    run at most the target (or a tie/unmeasured that does not hold)."""
    bad = []
    for r in df.to_dict("records"):
        t = float(r["target_error"])
        mine = str(r["confirmed"]).lower() == "true" and float(r["confirmed_error_rel"]) <= t
        theirs = str(r["alt_confirmed"]).lower() == "true" and float(r["alt_confirmed_error_rel"]) <= t
        what = f"{r['scene']} at {t:g}"
        for col in ("verdict_rhs", "verdict_amortized", "verdict_one_run"):
            v = r[col]
            if v == r["method"] and not mine:
                bad.append(f"{what}: {col} {v} without a measured run at most the target")
            elif isinstance(r["alternative"], str) and v == r["alternative"] and not theirs:
                bad.append(f"{what}: {col} {v} (alternative) without a measured run at most the target")
            elif v == trust.UNMEASURED and (mine or theirs):
                bad.append(f"{what}: {col} unmeasured, but a side was measured")
            elif v == trust.TIE and not (mine and theirs):
                bad.append(f"{what}: {col} tie without both sides measured")
            elif v not in (r["method"], r["alternative"], trust.TIE, trust.UNMEASURED):
                bad.append(f"{what}: {col} names {v!r}")
        if r["verdict_rhs"] == trust.TIE and float(r["rhs"]) != float(r["alt_rhs"]):
            bad.append(f"{what}: verdict_rhs tie with {r['rhs']} against {r['alt_rhs']} calls")
    return bad


def test_the_invariant_check_can_fail():
    df = pd.DataFrame(_table(_rk4([(1e-3, 8e-10)]), [_row("dop853", 1e-12, 5e-10, 4e6)]))
    assert winner_violations(df) == []
    forged = df.copy()
    forged.loc[1, "confirmed_error_rel"] = 2e-9   # above the 1e-9 target, rk4 still named
    assert any("s at 1e-09: verdict_rhs rk4" in b for b in winner_violations(forged))
    forged = df.copy()
    forged.loc[1, "confirmed"] = False
    assert winner_violations(forged)


def _quick_scenes():
    from rk4h.validation.scenes import load_scenes

    return [s.name for s in load_scenes(quick=True) if "work_precision" in s.outputs]


@pytest.fixture(scope="module")
def quick_cheapest(tmp_path_factory):
    # the session's one fresh quick run of these scenes, shared with test_reports_committed (tests/_quick_run.py)
    from _quick_run import shared_quick_run

    run = shared_quick_run(tmp_path_factory)
    names = _quick_scenes()
    assert sorted(run["names"]) == sorted(names)
    out = run["out"]
    assert run["returncode"] in (0, 1) and (out / "cheapest.csv").exists(), run["stdout"][-2000:]
    return pd.read_csv(out / "cheapest.csv"), names


def test_every_winner_of_a_fresh_quick_run_was_measured(quick_cheapest):
    df, names = quick_cheapest
    assert set(df["scene"]) == set(names) and len(df) == 4 * len(names)
    assert winner_violations(df) == []
    assert df["confirmed"].any()   # the confirmation runs were made, not only planned


def test_every_winner_of_the_committed_report_was_measured():
    """Passes once reports/ is regenerated with the confirmation runs."""
    df = pd.read_csv(REPO / "reports" / "cheapest.csv")
    missing = {"confirmed", "confirmed_error_rel", "alt_confirmed", "alt_confirmed_error_rel"} - set(df.columns)
    assert not missing, f"reports/cheapest.csv predates the confirmation runs (no {sorted(missing)}): regenerate"
    assert winner_violations(df) == []
