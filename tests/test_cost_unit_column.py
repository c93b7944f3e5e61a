"""The cost unit each method declares (``Method.cost_unit``) is shown beside
every cost column: ``cost_unit`` in ``accuracy`` and ``work_precision`` (what
``nfev`` counts), ``cost_unit`` and ``alt_cost_unit`` in ``cheapest`` (what
``rhs`` and ``alt_rhs`` count), declared in rk4h.validation.columns."""
import pytest

from rk4h.references.registry import CostUnit
from rk4h.validation import columns, execute, measure, plan
from rk4h.validation.scenes import scene_from_dict

pytest.importorskip("sksundae")

DOC = {"name": "cost-units", "model": "chain",
       "params": {"masses": [1.0, 1.0], "springs": [1.0, 1.0, 1.0]},
       "initial": {"x": [0.5, 0.0]},
       "run": {"t_end": 10.0, "h": [0.2, 0.1, 0.05], "tolerances": [1e-4, 1e-8],
               "solvers": ["rk4", "dop853", "cvode-bdf"], "outputs": ["state", "work_precision"]}}


@pytest.fixture(scope="module")
def tables():
    scene = scene_from_dict(DOC, "cost-units.toml")
    specs = plan.plan(scene, figures=False)
    records = {s.key: execute.execute(scene, s) for s in specs}
    return scene, measure.measure(scene, specs, records, figures=False).tables


def test_run_tables_name_each_methods_cost_unit(tables):
    scene, t = tables
    for name in ("accuracy", "work_precision"):
        rows = t[name]
        assert {r["solver"] for r in rows} == set(DOC["run"]["solvers"])
        for r in rows:
            assert r["cost_unit"] == scene.method(r["solver"]).cost_unit.value
    units = {r["solver"]: r["cost_unit"] for r in t["work_precision"]}
    assert units == {"rk4": "rhs", "dop853": "rhs", "cvode-bdf": "rhs+jacobian-dq"}


def test_the_trust_table_names_both_sides_units(tables):
    scene, t = tables
    rows = t["cheapest"]
    assert rows
    for r in rows:
        assert r["cost_unit"] == scene.method(r["method"]).cost_unit.value
        assert r["alt_cost_unit"] == (scene.method(r["alternative"]).cost_unit.value if r["alternative"] else "")
    assert any(r["alternative"] for r in rows)


@pytest.mark.parametrize("table, column", [("accuracy", "cost_unit"), ("work_precision", "cost_unit"),
                                           ("cheapest", "cost_unit"), ("cheapest", "alt_cost_unit")])
def test_the_column_is_declared_with_every_unit(table, column):
    (col,) = [c for c in columns.table_columns(table) if c.name == column]
    assert col.dtype == "category"
    assert all(f"`{u.value}`: {u.text}" in col.description for u in CostUnit)
    assert column in columns.markdown() and any(
        c["name"] == column for c in columns.columns_json([table])["tables"][table]["columns"])


#: The columns that hold a cost in calls, by table: each needs a unit column beside it.
COST_COLUMNS = ("nfev", "rhs", "alt_rhs", "rhs_calls")


def test_every_registered_table_with_a_cost_column_declares_its_unit():
    """Read from the outputs registry, so a new output's cost column cannot
    come without its unit: ``cost_unit`` (``alt_cost_unit`` beside ``alt_rhs``)."""
    seen = 0
    for table, cols in columns.declared().items():
        names = [c.name for c in cols]
        for cost in COST_COLUMNS:
            if cost in names:
                seen += 1
                assert ("alt_cost_unit" if cost.startswith("alt_") else "cost_unit") in names, (table, cost)
    assert seen >= 6  # accuracy, work_precision, cheapest (rhs, alt_rhs), energy_work_precision, ensemble


def test_energy_rows_name_the_unit_of_their_calls():
    from rk4h.validation import energy_time

    assert energy_time._RHS_UNIT == CostUnit.RHS.value
    assert energy_time._reference_cost_unit("heyoka") == CostUnit.TAYLOR_STEPS.value
    assert energy_time._reference_cost_unit("cvode-adams") == CostUnit.RHS_WITH_JACOBIAN_DQ.value
