"""validation/compare_reports.py: what changed between two reports' tables."""
import pandas as pd

from validation.compare_reports import main


def _write(d, rows):
    d.mkdir()
    pd.DataFrame(rows).to_csv(d / "accuracy.csv", index=False)


ROWS = [{"scene": "a", "solver": "rk4", "setting": 0.1, "error_max": 1e-3, "wall_s": 0.5, "status": "ok"},
        {"scene": "a", "solver": "dop853", "setting": 1e-8, "error_max": 2e-9, "wall_s": 0.7, "status": "ok"}]


def test_identical_tables_and_timings_ignored(tmp_path, capsys):
    _write(tmp_path / "old", ROWS)
    _write(tmp_path / "new", [dict(r, wall_s=r["wall_s"] * 3) for r in ROWS])
    assert main([str(tmp_path / "old"), str(tmp_path / "new")]) == 0
    assert capsys.readouterr().out.strip() == "accuracy.csv: identical"


def test_a_changed_value_is_reported_with_its_row(tmp_path, capsys):
    _write(tmp_path / "old", ROWS)
    _write(tmp_path / "new", [ROWS[0], dict(ROWS[1], error_max=2.5e-9, status="failed")])
    assert main([str(tmp_path / "old"), str(tmp_path / "new")]) == 0
    out = capsys.readouterr().out
    assert "error_max: 1 rows differ, largest relative 0.25 (scene=a, solver=dop853, setting=1e-08)" in out
    assert "status: 1 rows differ (text)" in out
    assert main([str(tmp_path / "old"), str(tmp_path / "new"), "--where", "solver=rk4"]) == 0
    assert "accuracy.csv: identical" in capsys.readouterr().out


def test_bad_directory_exits_2_naming_it(tmp_path, capsys):
    _write(tmp_path / "old", ROWS)
    assert main([str(tmp_path / "old"), str(tmp_path / "missing")]) == 2
    err = capsys.readouterr().err
    assert "`new`" in err and "missing" in err and err.count("\n") == 1
