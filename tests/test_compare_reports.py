"""validation/compare_reports.py: what changed between two reports' tables."""
import pandas as pd

from rk4h.validation.compare_reports import main


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


def _two(tmp_path):
    _write(tmp_path / "old", ROWS)
    _write(tmp_path / "new", ROWS)
    return [str(tmp_path / "old"), str(tmp_path / "new")]


def test_a_misspelt_column_fails_with_one_line(tmp_path, capsys):
    args = _two(tmp_path)
    assert main(args + ["--columns", "error_maxx"]) == 1
    captured = capsys.readouterr()
    assert captured.out == ""
    assert "`--columns`" in captured.err and "'error_maxx'" in captured.err and captured.err.count("\n") == 1
    assert main(args + ["--columns", "error_max"]) == 0  # the same with a real column compares it
    assert capsys.readouterr().out.strip() == "accuracy.csv: identical"


def test_a_where_that_matches_nothing_fails(tmp_path, capsys):
    args = _two(tmp_path)
    assert main(args + ["--where", "solver=rk5"]) == 1
    err = capsys.readouterr().err
    assert "solver=rk5" in err and "matches no row" in err and err.count("\n") == 1
    assert main(args + ["--where", "solverr=rk4"]) == 1
    err = capsys.readouterr().err
    assert "'solverr'" in err and err.count("\n") == 1
    assert main(args + ["--where", "solver=rk4"]) == 0


def test_no_common_table_fails(tmp_path, capsys):
    (tmp_path / "old").mkdir()
    (tmp_path / "new").mkdir()
    assert main([str(tmp_path / "old"), str(tmp_path / "new")]) == 1
    err = capsys.readouterr().err
    assert "no table to compare" in err and err.count("\n") == 1
    _write(tmp_path / "only", ROWS)
    assert main([str(tmp_path / "only"), str(tmp_path / "new")]) == 1
    assert "1 CSV file(s)" in capsys.readouterr().err


def test_a_table_without_the_named_columns_says_so(tmp_path, capsys):
    args = _two(tmp_path)
    pd.DataFrame([{"scene": "a", "mode": 1, "omega_rad_s": 7.1}]).to_csv(tmp_path / "old" / "modes.csv", index=False)
    pd.DataFrame([{"scene": "a", "mode": 1, "omega_rad_s": 7.1}]).to_csv(tmp_path / "new" / "modes.csv", index=False)
    assert main(args + ["--columns", "error_max"]) == 0
    out = capsys.readouterr().out
    assert "accuracy.csv: identical" in out and "modes.csv: not compared (none of the `--columns`)" in out
    assert main(args + ["--where", "solver=rk4"]) == 0
    assert "modes.csv: identical" in capsys.readouterr().out  # no `solver` column: compared whole
