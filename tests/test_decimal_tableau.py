"""Tableaux given as decimals are judged at the precision they were given with
(one tolerance, rk4h.methods.Tableau.coefficient_tol): Ralston's
fourth-order method printed to 8 decimals has order 4 and RK4's stability
boundary, in the tableau and in a scene run; a genuinely wrong coefficient
still lowers the order."""
import math
from fractions import Fraction as F

import pandas as pd
import pytest

from rk4h.methods import EXACT_DECIMALS, METHODS, make_tableau
from rk4h.stability_function import imaginary_axis_boundary, real_axis_boundary

# Ralston (1962), the 4-stage 4th-order method with the least error bound, as
# usually printed (8 decimals).
C8 = [0, 0.4, 0.45573725, 1]
A8 = [[0, 0, 0, 0], [0.4, 0, 0, 0], [0.29697761, 0.15875964, 0, 0], [0.21810040, -3.05096516, 3.83286476, 0]]
B8 = [0.17476028, -0.55148066, 1.20553560, 0.17118478]


def _exact_double():
    """The same method in full double precision from its exact (sqrt 5) formulas."""
    r5 = math.sqrt(5.0)
    a31, a32 = (-2889 + 1428 * r5) / 1024, (3785 - 1620 * r5) / 1024
    a41, a42, a43 = (-3365 + 2094 * r5) / 6040, (-975 - 3046 * r5) / 2552, (467040 + 203968 * r5) / 240845
    b1, b2, b4 = (263 + 24 * r5) / 1812, (125 - 1000 * r5) / 3828, (30 - 4 * r5) / 123
    b3 = 1 - b1 - b2 - b4
    c3 = 7 / 8 - 3 * r5 / 16
    return [0, 0.4, c3, 1], [[0, 0, 0, 0], [0.4, 0, 0, 0], [a31, a32, 0, 0], [a41, a42, a43, 0]], [b1, b2, b3, b4]


CD, AD, BD = _exact_double()


def test_the_printed_coefficients_are_the_exact_ones_to_8_decimals():
    # the printed table carries its row sums exactly; its entries are within 1.2 units of the 8th decimal
    for printed, exact in zip([*C8, *sum(A8, []), *B8], [*CD, *sum(AD, []), *BD]):
        assert abs(printed - exact) <= 1.2e-8, (printed, exact)
    assert sum(B8) == pytest.approx(1, abs=1e-15) and abs(BD[2] - 1.2055356) < 1e-8


@pytest.mark.parametrize("which", ["8 decimals", "8 decimals as strings", "full double"])
def test_ralston4_has_order_4_and_rk4s_boundary(which):
    if which == "full double":
        tab = make_tableau("r4", AD, BD, CD)
        assert tab.precision.startswith(("16 decimals", "17 decimals")), tab.precision
    else:
        conv = (lambda x: repr(x) if x else "0") if "strings" in which else (lambda x: x)
        tab = make_tableau("r4", [[conv(x) for x in row] for row in A8], [conv(x) for x in B8], [conv(x) for x in C8])
        assert tab.precision == "8 decimals, 9 significant digits" and tab.coefficient_tol == F(1, 10**8)
    assert tab.order == 4
    res = tab.order_residuals
    assert [r["order"] for r in res] == [1, 2, 3, 4, 5]
    assert all(r["holds"] for r in res[:4]) and not res[4]["holds"]
    small = 1e-8 if "decimals" in which else 1e-15
    assert 0 < max(r["max_residual"] for r in res[1:4]) < small  # not exact: held within the tolerance
    assert res[4]["max_residual"] > 1e-3  # a real order-5 defect
    # R(z) is RK4's to the coefficients' precision: so are the boundaries
    rel = 1e-6 if "decimals" in which else 1e-12
    assert imaginary_axis_boundary(tab) == pytest.approx(2 * math.sqrt(2), rel=rel)
    assert real_axis_boundary(tab) == pytest.approx(real_axis_boundary(METHODS["rk4"]), rel=rel)


def test_exact_arithmetic_or_a_round_off_tolerance_would_give_order_1_or_less():
    # what the precision fixes: read as exact (or with the former float tolerance, 2**-40 relative),
    # the 8-decimal residuals (~5e-9) fail order 2
    from rk4h import order_conditions as oc
    from rk4h.methods import ORDER_TOL

    tab = make_tableau("r4", A8, B8, C8)
    assert oc.order(tab.A_exact, tab.b_exact) == 0  # the floats' binary sum of b is not exactly 1
    assert oc.order(tab.A_exact, tab.b_exact, tol=ORDER_TOL) == 1
    assert oc.order(tab.A_exact, tab.b_exact, uncertainty=tab.uncertainty) == 4


@pytest.mark.parametrize("change, expected", [
    ({0: +1e-3}, 0),               # one weight off by 1e-3: the weights no longer sum to 1
    ({0: +1e-3, 3: -1e-3}, 1),     # two off, the sum kept: b^T c = 1/2 fails
])
def test_a_wrong_weight_still_lowers_the_order(change, expected):
    b = list(B8)
    for i, d in change.items():
        b[i] += d
    tab = make_tableau("bad", A8, b, C8)
    assert tab.order == expected
    assert not tab.order_residuals[expected]["holds"]


def test_a_wrong_matrix_entry_still_lowers_the_order():
    A = [list(r) for r in A8]
    A[3][1] -= 1e-3
    A[3][2] += 1e-3  # the row sum kept: the order-3 condition b^T A c fails
    assert make_tableau("bad", A, B8, C8).order == 2


def test_short_decimals_are_exact():
    # the explicit midpoint rule typed as floats: 0.5 and 1.0 are exact, its order stays 2
    mid = make_tableau("mid", [[0.0, 0.0], [0.5, 0.0]], [0.0, 1.0])
    assert mid.precision == "exact" and mid.order == 2 and mid.uncertainty is None
    assert make_tableau("t", [[0, 0], [0.125, 0]], ["0.875", 0.125]).coefficient_tol == 0
    # ... and the threshold is EXACT_DECIMALS places: one more is read as rounded
    assert make_tableau("t", [[0, 0], ["0." + "1" * (EXACT_DECIMALS + 1), 0]], [0, 1]).precision.startswith(
        f"{EXACT_DECIMALS + 1} decimals")


def test_rounded_row_sums_are_accepted_within_the_precision_only():
    make_tableau("r", A8, B8, [0, 0.4, 0.45573726, 1])  # one unit in the last place: within
    with pytest.raises(ValueError, match=r"row 2"):
        make_tableau("r", A8, B8, [0, 0.4, 0.4557, 1])


# -- in a scene --------------------------------------------------------------------------------
def _scene_doc():
    fmt = lambda x: repr(float(x))  # noqa: E731 - full double as strings
    return {"name": "ralston4-decimal", "model": "chain",
            "params": {"masses": [0.815, 3.099], "springs": [41.5, 138.0, 157.8], "walls": "both"},
            "initial": {"x": [0.005, 0.005]},
            "run": {"t_end": 2.0, "h": [0.02, 0.01], "tolerances": [1e-8], "solvers": ["ralston4", "ralston4-double"],
                    "outputs": ["convergence", "stability"]},
            "methods": {"ralston4": {"A": A8, "b": B8, "c": C8},
                        "ralston4-double": {"A": [[fmt(x) for x in r] for r in AD], "b": [fmt(x) for x in BD],
                                            "c": [fmt(x) for x in CD]}},
            "stability": {"studies": ["boundary"]}}


@pytest.fixture(scope="module")
def scene_report(tmp_path_factory):
    from rk4h.validation import run_all
    from rk4h.validation.scenes import scene_from_dict

    out = tmp_path_factory.mktemp("ralston4")
    scene = scene_from_dict(_scene_doc())
    results, failures = run_all.run([scene], out, quick=True, figures=False)
    return scene, out, failures


def test_scene_expectations_hold(scene_report):
    scene, out, failures = scene_report
    assert scene.stability["method"] == "ralston4"
    assert failures == []


@pytest.mark.parametrize("method", ["ralston4", "ralston4-double"])
def test_scene_observed_order_is_4(scene_report, method):
    _, out, _ = scene_report
    conv = pd.read_csv(out / "convergence.csv")
    (row,) = conv[(conv.solver == method) & (conv.quantity == "order in h")].to_dict("records")
    assert row["expected_order"] == 4 and abs(row["observed_order"] - 4) <= 0.1 and row["passed"], row


@pytest.mark.parametrize("method", ["ralston4", "ralston4-double"])
def test_scene_boundary_is_measured_and_predicted(scene_report, method):
    _, out, _ = scene_report
    st = pd.read_csv(out / "stability.csv")
    (row,) = st[(st.solver == method) & (st.quantity == "largest_stable_h_s")].to_dict("records")
    assert row["passed"] and row["theory"] > 0 and row["theta"] == pytest.approx(2 * math.sqrt(2), rel=1e-3), row


def test_scene_methods_table_and_limits(scene_report):
    _, out, _ = scene_report
    m = pd.read_csv(out / "methods.csv")
    mine = m[m.method == "ralston4"].sort_values("order_p")
    assert list(mine.order_p) == [1, 2, 3, 4, 5] and set(mine.order) == {4}
    assert list(mine.holds) == [True, True, True, True, False]
    assert (mine.max_residual[mine.order_p.between(2, 4)] <= mine.tolerance[mine.order_p.between(2, 4)]).all()
    index = (out / "index.md").read_text()
    assert "| ralston4-decimal | ralston4 stable up to | omega_max h = 2.828 |" in index
    assert "rk4 stable up to" not in index
