"""Typed tables: one declaration of every column (rk4h.validation.columns), Parquet
beside CSV, columns.json in every report, docs/columns.md generated from it."""
import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from rk4h.validation import columns as C
from rk4h.validation import compare_reports, report
from rk4h.validation.stability import row as stability_row

from _scenes import one_mass

REPO = Path(__file__).resolve().parent.parent
TINY = one_mass("tiny-columns", tolerances="[1e-5, 1e-9]",
                outputs='["state", "energy", "convergence", "work_precision", "modes"]')
#: pandas dtype kind of each declared dtype as read back from Parquet.
KIND = {"float": "f", "int": "i", "bool": "b"}


@pytest.fixture(scope="module")
def fresh(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("columns")
    scene = tmp / "tiny.toml"
    scene.write_text(TINY)
    out = tmp / "out"
    # in process: these tests read the tables, not the process (its start-up alone was ~10 s of ~20)
    import contextlib
    import io

    from rk4h.validation import run_all

    log = io.StringIO()
    with contextlib.redirect_stdout(log), contextlib.redirect_stderr(log):
        rc = run_all.main(["--scene", str(scene), "--out", str(out), "--repeats", "1", "--no-figures",
                           "--workers", "1"])
    assert rc == 0, log.getvalue()
    return out


def test_accuracy_parquet_has_float_h_and_rtol_apart(fresh):
    acc = pd.read_parquet(fresh / "accuracy.parquet")
    assert acc["h"].dtype == np.float64 and acc["rtol"].dtype == np.float64
    rk4, dop = acc[acc.solver == "rk4"], acc[acc.solver == "dop853"]
    assert sorted(rk4["h"]) == [0.05, 0.1] and rk4["rtol"].isna().all()
    assert sorted(dop["rtol"]) == [1e-9, 1e-5] and dop["h"].isna().all()
    assert (acc["setting"] == acc["h"].fillna(acc["rtol"])).all()
    # the CSV holds the same values
    csv = pd.read_csv(fresh / "accuracy.csv")
    np.testing.assert_array_equal(csv["h"].to_numpy(float), acc["h"].to_numpy(float))


def test_every_parquet_matches_its_declaration_and_columns_json(fresh):
    described = json.loads((fresh / "columns.json").read_text())["tables"]
    parquets = sorted(fresh.glob("*.parquet"))
    assert {p.stem for p in parquets} == {p.stem for p in fresh.glob("*.csv")} == set(described)
    for path in parquets:
        df = pd.read_parquet(path)
        decl = {c["name"]: c for c in described[path.stem]["columns"]}
        assert [c for c in df.columns if c in decl] == list(decl), path.name
        for name, c in decl.items():
            kind = df[name].dtype.kind
            if c["dtype"] in KIND:
                assert kind == KIND[c["dtype"]], (path.name, name, df[name].dtype)
            elif c["dtype"] == "category":
                assert isinstance(df[name].dtype, pd.CategoricalDtype), (path.name, name, df[name].dtype)
            else:
                assert kind == "O", (path.name, name, df[name].dtype)


def test_energy_passed_is_bool_and_checked_says_which_rows_were_judged(fresh):
    e = pd.read_parquet(fresh / "energy.parquet")
    assert e["passed"].dtype == bool and e["checked"].dtype == bool
    assert not (e["passed"] & ~e["checked"]).any()
    assert len(e[e.passed]) == int(e["passed"].sum())  # boolean indexing works
    # dop853 has no energy theory: not judged; rk4 on a linear model is
    assert not e[e.solver == "dop853"]["checked"].any() and e[e.solver == "rk4"]["checked"].all()


def test_cheapest_h_source_holds_categories_only(fresh):
    ch = pd.read_parquet(fresh / "cheapest.parquet")
    assert set(ch["h_source"]) <= set(C.H_SOURCES) | {""}
    assert ch["alt_h"].dtype == np.float64 and ch["alt_rtol"].dtype == np.float64
    from rk4h.references.registry import REFERENCES

    ref = ch["alternative"].astype(str).isin(REFERENCES)
    assert ch.loc[ref, "alt_rtol"].notna().all() and ch.loc[ref, "alt_h"].isna().all()


def test_stability_passed_is_bool_in_csv_and_parquet(tmp_path):
    rows = [stability_row("s", "boundary", "rk4", "largest_stable_h_s", 0.17, 0.17, passed=True, theta=2.8),
            stability_row("s", "growth", "rk4", "growth_per_step", 1.01, passed=None, theta=3.0),
            stability_row("s", "growth", "euler", "growth_per_step", 2.0, 1.0, passed=False, mode=2)]
    report.write_tables(tmp_path, {"stability": rows})
    for df in (pd.read_parquet(tmp_path / "stability.parquet"), pd.read_csv(tmp_path / "stability.csv")):
        assert df["passed"].dtype == bool and df["checked"].dtype == bool
        assert df["passed"].tolist() == [True, False, False]
        assert df["checked"].tolist() == [True, False, True]
        assert df[df.passed]["quantity"].tolist() == ["largest_stable_h_s"]
    pq = pd.read_parquet(tmp_path / "stability.parquet")
    assert str(pq["mode"].dtype) == "Int64" and pq["mode"].tolist()[2] == 2 and pq["mode"].isna().sum() == 2
    assert rows[1]["passed"] is None  # the rows themselves are not changed


def test_h_source_detail_moves_to_note():
    cols = report.COLUMNS["cheapest"]
    base = {c: "" for c in cols}
    rows = [{**base, "h_source": "no asymptotic fit: fewer than two runs", "note": "n1"},
            {**base, "h_source": "error constant (2 runs)", "note": ""},
            {**base, "h_source": "stability", "note": "n3"},
            {**base, "h_source": "something new", "note": ""}]
    df = C.typed_frame("cheapest", pd.DataFrame(rows)[cols])
    assert df["h_source"].tolist() == ["no asymptotic fit", "error constant", "stability", "other"]
    assert df["note"].tolist() == ["n1; h_source detail: fewer than two runs", "h_source detail: (2 runs)", "n3",
                                   "h_source detail: something new"]


def test_every_column_of_every_table_is_declared_once():
    tables = C.declared()
    assert set(tables) == set(report.COLUMNS) and set(tables) <= set(report.DESCRIPTIONS)
    for name, cols in tables.items():
        assert [c.name for c in cols] == list(report.COLUMNS[name])
        for c in cols:
            assert c.dtype in C.DTYPES and c.description, (name, c)
    assert {c.dtype for c in tables["accuracy"] if c.name in ("h", "rtol", "setting")} == {"float"}


def test_docs_columns_md_is_current():
    committed = (REPO / "docs" / "columns.md").read_text(encoding="utf-8")
    assert committed == C.markdown(), "docs/columns.md is stale: python -m rk4h.validation.columns --markdown > docs/columns.md"


def test_cli_prints_markdown_and_json():
    md = subprocess.run([sys.executable, "-m", "rk4h.validation.columns", "--markdown"], cwd=REPO, capture_output=True,
                        text=True, timeout=120)
    assert md.returncode == 0 and md.stdout == C.markdown()
    js = subprocess.run([sys.executable, "-m", "rk4h.validation.columns", "--json"], cwd=REPO, capture_output=True,
                        text=True, timeout=120)
    assert js.returncode == 0 and "stability" in json.loads(js.stdout)["tables"]


def test_compare_table_names_added_columns_and_compares_the_common_ones():
    old = pd.DataFrame({"scene": ["a", "b"], "setting": [0.1, 0.2], "error_max": [1.0, 2.0]})
    new = old.assign(h=[0.1, 0.2], error_max=[1.0, 2.5])
    lines = compare_reports.compare_table(old, new)
    assert any("new columns: h" in line for line in lines)
    assert any(line.strip().startswith("error_max: 1 rows differ") for line in lines)
    assert compare_reports.compare_table(new, old.assign(error_max=[1.0, 2.5]))[0].strip() == "dropped columns: h"


def test_text_in_a_numeric_column_is_refused_not_turned_into_nan():
    cols = report.COLUMNS["accuracy"]
    rows = pd.DataFrame([{**{c: "" for c in cols}, "solver": "rk4", "setting": 0.1, "error_max": "1e-3"},
                         {**{c: "" for c in cols}, "solver": "rk4", "setting": 0.1, "error_max": "n/a"}])[cols]
    with pytest.raises(ValueError, match="'accuracy' column 'error_max' is declared numeric, got 'n/a'"):
        C.typed_frame("accuracy", rows)


def test_undeclared_columns_are_kept_and_mixed_text_is_written_as_text(tmp_path):
    rows = [{"scene": "a", "masses[1]": 2.0, "kind": "x", "solver": "rk4", "setting": 0.1},
            {"scene": "b", "kind": 3, "solver": "dop853", "setting": 1e-6}]
    report.write_tables(tmp_path, {"accuracy": rows}, front=["masses[1]"])
    df = pd.read_parquet(tmp_path / "accuracy.parquet")
    assert list(df.columns[:2]) == ["scene", "masses[1]"] and df["masses[1]"].dtype == np.float64
    assert df["kind"].tolist() == ["x", "3"]
    assert df["h"].tolist()[0] == 0.1 and math.isnan(df["h"].tolist()[1]) and df["rtol"].tolist()[1] == 1e-6
    meta = json.loads((tmp_path / "columns.json").read_text())
    assert [p["name"] for p in meta["sweep_parameters"]] == ["masses[1]"]


def test_committed_tables_pass_through_the_typed_writer(tmp_path):
    # every table of the full committed report (stability, methods, thesis_code, ... included)
    tables = {n: pd.read_csv(REPO / "reports" / f"{n}.csv").to_dict("records") for n in report.COLUMNS
              if (REPO / "reports" / f"{n}.csv").exists()}
    assert "stability" in tables and "thesis_code" in tables
    paths = report.write_tables(tmp_path, tables, front=["masses[1]", "x[0]"])
    st = pd.read_parquet(tmp_path / "stability.parquet")
    assert st["passed"].dtype == bool and 0 < st["checked"].sum() < len(st)
    assert not (st["passed"] & ~st["checked"]).any()
    for name in paths:
        pq = pd.read_parquet(tmp_path / f"{name}.parquet")
        assert len(pq) == len(tables[name]), name


def test_fresh_stability_run_writes_boolean_passed(tmp_path):
    from rk4h.validation import run_all
    from rk4h.validation.scenes import scene_from_dict

    doc = {"name": "columns-boundary", "model": "chain",
           "params": {"masses": [1.0, 2.0], "springs": [40.0, 140.0, 160.0], "walls": "both"},
           "initial": {"x": [0.005, 0.005]},
           "run": {"t_end": 2.0, "h": [0.02, 0.01], "tolerances": [1e-8], "solvers": ["rk4"],
                   "outputs": ["stability"]},
           "stability": {"studies": ["boundary"]}}
    run_all.run([scene_from_dict(doc)], tmp_path, quick=True, figures=False)
    st = pd.read_parquet(tmp_path / "stability.parquet")
    assert st["passed"].dtype == bool and st["checked"].dtype == bool and len(st)
    (row,) = st[(st.solver == "rk4") & (st.quantity == "largest_stable_h_s")].to_dict("records")
    assert row["passed"] is True and row["checked"] is True
    described = json.loads((tmp_path / "columns.json").read_text())["tables"]["stability"]["columns"]
    assert {c["name"]: c["dtype"] for c in described}["passed"] == "bool"


def test_categorical_columns_of_the_committed_tables_hold_labels_not_numbers():
    """A ``category`` column holds a few fixed labels; text that carries a measured number
    (``computed to within 2.5e-14 per entry``) is free text (dtype ``str``)."""
    import re

    number = re.compile(r"\d[eE][-+]?\d|\d\.\d+\s")  # 2.5e-14, "1.5 per": a value, not a label
    seen = 0
    for name, cols in C.declared().items():
        path = REPO / "reports" / f"{name}.csv"
        if not path.exists():
            continue
        df = pd.read_csv(path, keep_default_na=False, dtype=str)
        for col in cols:
            if col.dtype == "category" and col.name in df:
                seen += 1
                bad = sorted({v for v in df[col.name] if number.search(v)})
                assert not bad, f"{name}.{col.name} is declared category but holds free text: {bad[:3]}"
    assert seen >= 20
