"""The methods table lists the built-in fixed-step methods a scene runs
(issue 30): RK4's principal error coefficient 0.0145 (nodepy's value), its
cost and its imaginary-axis bound 2 sqrt 2; a scene's own Heun3 has sqrt 3."""
import math
from types import SimpleNamespace

import pytest

from rk4h.references.registry import methods_from_tables
from rk4h.methods import METHODS
from rk4h.validation import measure
from rk4h.validation.tables import COLUMNS


def _rows(solvers, own=None):
    rows = []
    res = SimpleNamespace(add=lambda table, r: rows.append(r))
    measure._methods_table(SimpleNamespace(name="s", registry=own or {}, solvers=solvers), res)
    return rows


def _heun3_table():
    tab = METHODS["heun3"]
    return {"heun3": {"A": [[str(x) for x in row] for row in tab.A_exact], "b": [str(x) for x in tab.b_exact]}}


def test_rk4_row_reads_its_error_coefficient_cost_and_axis_bound():
    rows = _rows(["rk4", "dop853", "heyoka"])  # the adaptive references have no tableau: no rows
    assert {r["method"] for r in rows} == {"rk4"}
    assert [r["order_p"] for r in rows] == [1, 2, 3, 4, 5] and {r["order"] for r in rows} == {4}
    for r in rows:
        assert f"{r['error_coefficient']:.4f}" == "0.0145"
        assert (r["stages"], r["nfev_per_step"], r["builtin"], r["partitioned"]) == (4, 4, True, False)
        assert r["imaginary_axis_bound"] == pytest.approx(2 * math.sqrt(2), abs=1e-6)
        assert set(r) == set(COLUMNS["methods"])


def test_builtin_partitioned_and_a_scene_heun3():
    own = methods_from_tables(_heun3_table())
    rows = _rows(["euler", "stormer-verlet", "heun3", "rk4"], own)
    by = {r["method"]: r for r in rows}
    assert set(by) == {"euler", "stormer-verlet", "heun3", "rk4"}
    assert by["heun3"]["imaginary_axis_bound"] == pytest.approx(math.sqrt(3), abs=1e-6)
    assert by["heun3"]["builtin"] is False and by["heun3"]["order"] == 3
    assert by["stormer-verlet"]["imaginary_axis_bound"] == pytest.approx(2.0, abs=1e-12)
    assert by["stormer-verlet"]["partitioned"] and by["stormer-verlet"]["nfev_per_step"] == 1
    assert by["euler"]["imaginary_axis_bound"] == 0.0 and by["euler"]["error_coefficient"] == 0.5
