"""Timings carry their context: the load average and CPU count around the
timed runs are recorded in the report, and under a load above the CPUs every
time verdict between two measured sides is a tie, with the reason; one
measured side keeps its verdict (rk4h.validation.timing_context)."""
import math

import pandas as pd
import pytest

from rk4h.validation import timing_context as tc

ROWS = [{"scene": "a", "target_error": 1e-3, "verdict_rhs": "rk4", "verdict_amortized": "rk4",
         "verdict_one_run": "dop853", "note": "rk4 at h = 0.01 s", "confirmed": True, "alt_confirmed": True},
        {"scene": "a", "target_error": 1e-6, "verdict_rhs": "dop853", "verdict_amortized": "tie",
         "verdict_one_run": "tie", "note": "", "confirmed": True, "alt_confirmed": True}]
# one measured side (the method had no run at the target), then neither
ONE_SIDE = [{"scene": "b", "target_error": 1e-3, "verdict_rhs": "cvode-adams", "verdict_amortized": "cvode-adams",
             "verdict_one_run": "cvode-adams", "note": "", "confirmed": False, "alt_confirmed": True},
            {"scene": "b", "target_error": 1e-12, "verdict_rhs": "unmeasured", "verdict_amortized": "unmeasured",
             "verdict_one_run": "unmeasured", "note": "", "confirmed": "False", "alt_confirmed": "False"}]


def _snap(load, cpus=2):
    return {"load": (load, load, load), "cpus": cpus, "t": 0.0}


def test_snapshot_reads_the_machine():
    s = tc.snapshot()
    assert s["cpus"] >= 1 and len(s["load"]) == 3 and all(x >= 0 for x in s["load"])


def test_a_load_above_the_cpus_makes_every_time_verdict_a_tie():
    ctx = tc.load_context(_snap(1.5), _snap(6.3), executed_timed=10)
    assert ctx["loaded"] and ctx["peak"] == 6.3 and ctx["known"]
    out = tc.gate_time_verdicts(ROWS, ctx)
    assert [r["verdict_amortized"] for r in out] == ["tie", "tie"]
    assert [r["verdict_one_run"] for r in out] == ["tie", "tie"]
    assert [r["verdict_rhs"] for r in out] == ["rk4", "dop853"]  # calls are deterministic: kept
    assert [r["note"] for r in out] == [r["note"] for r in ROWS]  # a deterministic column: kept
    assert out[0]["time_context"] == ("load 1.50 -> 6.30 (1 min, before -> after the timed runs) on 2 CPUs; time "
                                      "verdicts between two measured sides are ties: load average 6.30 exceeded "
                                      "the 2 CPUs during the timed runs (timings include waiting for a CPU)")
    assert ROWS[0]["verdict_amortized"] == "rk4"  # the input is not modified


def test_under_load_a_verdict_with_one_measured_side_keeps_it():
    # No tie without both sides measured: the one side with a run at the target keeps the verdict
    # (no speed is compared), and an unmeasured verdict stays unmeasured.
    ctx = tc.load_context(_snap(1.5), _snap(6.3), executed_timed=10)
    out = tc.gate_time_verdicts(ONE_SIDE, ctx)
    for r, was in zip(out, ONE_SIDE):
        assert [r[c] for c in tc.TIME_VERDICT_COLUMNS] == [was[c] for c in tc.TIME_VERDICT_COLUMNS]
        assert "exceeded the 2 CPUs" in r["time_context"]


def test_the_context_column_is_a_timing_column():
    from rk4h.validation.compare_reports import TIMING
    from rk4h.validation.report import COLUMNS, TIMING as REPORT_TIMING
    from rk4h.validation.trust import TIMING_COLUMNS

    assert "time_context" in TIMING_COLUMNS and "time_context" in TIMING and "time_context" in COLUMNS["cheapest"]
    assert "time_context" in REPORT_TIMING["cheapest"] and "note" not in TIMING_COLUMNS


@pytest.mark.parametrize("before, after", [(1.5, 2.0), (0.1, 0.2)])
def test_a_load_within_the_cpus_keeps_the_verdicts(before, after):
    ctx = tc.load_context(_snap(before), _snap(after), executed_timed=3)
    assert not ctx["loaded"]
    out = tc.gate_time_verdicts(ROWS, ctx)
    assert [{k: v for k, v in r.items() if k != "time_context"} for r in out] == ROWS
    assert out[0]["time_context"] == f"load {before:.2f} -> {after:.2f} (1 min, before -> after the timed runs) on 2 CPUs"
    assert tc.gate_time_verdicts(ROWS, None) == ROWS


def test_unknown_or_absent_context():
    assert tc.load_context(None, None) is None  # no timed run: nothing to qualify
    ctx = tc.load_context(None, None, resumed_timed=4)
    assert not ctx["loaded"] and not ctx["known"] and math.isnan(ctx["peak"])
    assert "not known" in tc.sentence(ctx) and "4 timed record(s) were resumed" in tc.sentence(ctx)
    ctx = tc.load_context(_snap(1.0), _snap(1.0), executed_timed=2, resumed_timed=1)
    assert not ctx["known"]


def _scene():
    from rk4h.validation.scenes import scene_from_dict

    return scene_from_dict({
        "name": "timing-ctx", "model": "chain",
        "params": {"masses": [0.815, 3.099], "springs": [41.5, 138.0, 157.8], "walls": "both"},
        "initial": {"x": [0.005, 0.005]},
        "run": {"t_end": 1.0, "h": [0.02, 0.01], "tolerances": [1e-6, 1e-8], "solvers": ["rk4", "dop853"],
                "outputs": ["work_precision"]}})


@pytest.mark.parametrize("load", [9.0, 0.5])
def test_the_report_records_the_load_and_ties_under_it(tmp_path, monkeypatch, load):
    from rk4h.validation import run_all

    monkeypatch.setattr(tc, "snapshot", lambda: _snap(load, cpus=2))
    run_all.run([_scene()], tmp_path, quick=True, figures=False)
    cheapest = pd.read_csv(tmp_path / "cheapest.csv")
    index = (tmp_path / "index.md").read_text()
    env = index[index.index("## Environment"):]
    assert f"- load average (1, 5, 15 min) before the timed runs: {load:.2f}, {load:.2f}, {load:.2f}; after:" in env
    assert "- CPUs: 2 (os.cpu_count)" in env
    assert "shares the machine with other timed runs only" not in index
    header = index.splitlines()[2]
    assert f"Load average (1 min) {load:.2f} before the timed runs and {load:.2f} after them, on 2 CPUs" in header
    assert cheapest.time_context.str.startswith(f"load {load:.2f} -> {load:.2f} (1 min").all()
    if load > 2:
        both = cheapest.confirmed.astype(bool) & cheapest.alt_confirmed.astype(bool)
        assert both.any()
        for col in ("verdict_amortized", "verdict_one_run"):
            assert set(cheapest.loc[both, col]) == {"tie"}
            one = cheapest[~both & cheapest.confirmed.astype(bool)]   # only the method measured: it keeps the verdict
            assert (one[col] == one["method"]).all()
        assert cheapest.time_context.str.contains("load average 9.00 exceeded the 2 CPUs").all()
        assert "every time verdict between two measured sides is `tie`" in header
        assert "ties (load above the CPUs)" in env
        assert "and every one between two measured sides is `tie` here" in index
        assert "- Timed under load: load average 9.00 exceeded the 2 CPUs" in index
    else:
        assert not cheapest.time_context.str.contains("ties").any()
        assert "every time verdict between two measured sides is `tie`" not in header and "as measured (load within the CPUs)" in env
        assert "Timed under load" not in index
