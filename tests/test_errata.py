"""The errata table (docs/scenes.md, "The thesis' errata"): every corrected
number is computed by the code and agrees with the theory written here."""
import math

import numpy as np

import pytest

from rk4h.references import closed_forms as cf
from rk4h.references import errata

K_TAB, M_TAB = 41.5, 0.815  # thesis' mass (kg) and spring (N/m), Tables 4.4-4.6 and sec. 4.2


@pytest.fixture(scope="module")
def rows():
    return errata.errata_rows()


def _find(rows, item, contains):
    (row,) = [r for r in rows if r["item"] == item and contains in r["quantity"]]
    return row


def test_rows_cover_every_erratum_with_the_agreed_keys(rows):
    assert {r["item"] for r in rows} == set(range(1, 9))
    for r in rows:
        assert set(r) == {"item", "quantity", "thesis", "corrected", "note"}
        assert isinstance(r["corrected"], float) and math.isfinite(r["corrected"])


@pytest.mark.parametrize("case,name,index", [(1, "omega_1", 0), (1, "omega_2", 1), (3, "omega_1", 0), (3, "omega_2", 1)])
def test_item1_printed_value_is_omega_squared(rows, case, name, index):
    row = _find(rows, 1, f"case {case}: {name}")
    p = cf.TABLE_4_3_CASES[case - 1]
    expected = cf.two_dof_frequencies(p["m1"], p["m2"], p["k1"], p["k2"], p["k3"])[index]
    assert row["corrected"] == expected
    # the thesis printed omega^2 rounded to 4 decimals
    assert abs(row["thesis"] - row["corrected"] ** 2) <= 5e-5 + 1e-12


@pytest.mark.parametrize("case", [1, 3])
def test_item1_f_max_was_printed_correctly(rows, case):
    row = _find(rows, 1, f"case {case}: f_max")
    p = cf.TABLE_4_3_CASES[case - 1]
    w_high = cf.two_dof_frequencies(p["m1"], p["m2"], p["k1"], p["k2"], p["k3"])[1]
    assert row["corrected"] == pytest.approx(w_high / (2 * math.pi), rel=1e-15)
    assert abs(row["thesis"] - row["corrected"]) <= 5e-5


def test_item2_potential_with_k3_x2_squared(rows):
    row = _find(rows, 2, "V(x0)")
    p = cf.TABLE_4_3_CASES[0]
    x1, x2 = p["x0"]
    V = 0.5 * p["k1"] * x1**2 + 0.5 * p["k2"] * (x2 - x1) ** 2 + 0.5 * p["k3"] * x2**2  # eq. 2.2 corrected
    assert row["corrected"] == pytest.approx(1e3 * V, rel=1e-14)  # mJ


def test_items3_and_4_planar4_force(rows):
    # At y = 0, |x| < l the x-springs give -2kx exactly; each y-spring has length
    # L = sqrt(x^2 + l^2) and x-force -k (L - l0) x / L with l0 the natural length.
    x, l = 0.005, 0.01
    L = math.hypot(x, l)
    correct = -2 * K_TAB * x - 2 * K_TAB * (L - l) * x / L
    # printed eqs. 2.63-2.78: extension length - l^2. The x-springs then give
    # -k (l + x - l^2) + k (l - x - l^2) = -2kx, the y-springs -2k (L - l^2) x / L.
    printed = -2 * K_TAB * x - 2 * K_TAB * (L - l * l) * x / L
    r3 = _find(rows, 3, "F_x")
    assert r3["corrected"] == pytest.approx(correct, rel=1e-13)
    assert r3["thesis"] == pytest.approx(printed, rel=1e-13)
    # Code 03: anchors and natural length 1 m; then (L - 1) x / L ~ x^3 / 2
    L1 = math.hypot(x, 1.0)
    r4 = _find(rows, 4, "F_x")
    assert r4["thesis"] == pytest.approx(-2 * K_TAB * x - 2 * K_TAB * (L1 - 1.0) * x / L1, rel=1e-13)
    assert r4["corrected"] == r3["corrected"]


def test_item4_is_an_assumption_with_both_readings_computed(rows):
    import numpy as np

    import rk4h
    from rk4h.references.thesis_code import printed_code03_rhs

    item4 = [r for r in rows if r["item"] == 4]
    assert len(item4) == 3
    assert all(r["note"].startswith("ASSUMPTION") and "l = 0.01 m" in r["note"] and "l = 1 m" in r["note"]
               for r in item4)
    # Code 03 as printed on Table 4.5's state under each reading, run here independently
    y0 = np.array([0.005, 0.03, 0.0, 0.0])
    want = []
    for L in (1.0, 0.01):
        res = rk4h.solve(printed_code03_rhs(M_TAB, K_TAB, L), (0.0, 3.0), y0, n_steps=300, method="rk4")
        want.append(res.y[1, -1] / y0[1])
    row = _find(rows, 4, "Code 03 as printed")
    assert (row["thesis"], row["corrected"]) == pytest.approx(want, rel=1e-12)
    # the two readings disagree in sign and size: the reading decides the number
    assert row["thesis"] > 10 and row["corrected"] < 0
    assert f"{row['corrected']:.4g}" in row["note"] and f"{row['thesis']:.4g}" in row["note"]


def test_item4_physics_row_is_the_generic_solvers_number_to_the_bit(rows):
    # the repaired planar4 runs on its compiled loop; rk4h.solve on the model's numpy
    # right-hand side must give the very same y(3 s) / y(0) under both readings
    import rk4h
    from rk4h.models import Planar4

    y0 = np.array([0.005, 0.03, 0.0, 0.0])
    want = [rk4h.solve(Planar4(M_TAB, K_TAB, L).rhs, (0.0, 3.0), y0, n_steps=300, method="rk4").y[1, -1] / y0[1]
            for L in (1.0, 0.01)]
    row = _find(rows, 4, "planar4 (dz4 repaired)")
    assert (row["thesis"], row["corrected"]) == (float(want[0]), float(want[1]))


def test_printed_code03_default_reading_is_the_digit_one():
    from rk4h.references.thesis_code import printed_code03_rhs

    y = [0.004, -0.002, 0.1, 0.2]
    assert np.array_equal(printed_code03_rhs(M_TAB, K_TAB)(0.0, y), printed_code03_rhs(M_TAB, K_TAB, 1.0)(0.0, y))


def test_item5_table_4_6(rows):
    w = math.sqrt(2 * K_TAB / M_TAB)  # m x'' = -2kx
    omega, period = _find(rows, 5, "omega"), _find(rows, 5, "period")
    assert omega["corrected"] == pytest.approx(w, rel=1e-15)
    assert period["corrected"] == pytest.approx(2 * math.pi / w, rel=1e-15)
    assert (round(omega["corrected"], 2), round(period["corrected"], 3)) == (10.09, 0.623)
    assert (omega["thesis"], period["thesis"]) == (10.30, 0.61)


def test_item6_lattice_sign(rows):
    row = _find(rows, 6, "zone edge")
    assert row["corrected"] == pytest.approx(4 * K_TAB / M_TAB, rel=1e-14)  # omega_0^2, eq. 2.50
    assert row["thesis"] == pytest.approx(-2 * K_TAB / M_TAB, rel=1e-14)


def test_item7_group_velocity(rows):
    row = _find(rows, 7, "group velocity")
    kp, d = 0.3 * math.pi / 0.01, 0.01
    assert row["corrected"] == pytest.approx(d * math.sqrt(K_TAB / M_TAB) * math.cos(kp * d / 2), rel=1e-14)


def test_item7_can_quote_the_rk4_wave_packet():
    row = _find(errata.errata_rows(with_wavepacket=True), 7, "group velocity")
    assert "RK4 wave packet" in row["note"]


def test_item8_anisotropic_ratio(rows):
    row = _find(rows, 8, "omega_x")
    w_y = math.sqrt(2 * K_TAB / M_TAB)
    assert row["corrected"] == pytest.approx(math.sqrt(2) * w_y, rel=1e-14)
    assert row["thesis"] == pytest.approx(math.sqrt(2 * w_y), rel=1e-14)


def test_corrected_numbers_are_computed_not_typed(rows, monkeypatch):
    # if the closed forms changed, the table would follow them
    monkeypatch.setattr(cf, "two_dof_frequencies", lambda *a: (1.0, 2.0))
    monkeypatch.setattr(cf, "planar4_small_oscillation", lambda m, k: (3.0, 4.0))
    patched = errata.errata_rows()
    assert _find(patched, 1, "case 1: omega_1")["corrected"] == 1.0
    assert _find(patched, 5, "omega")["corrected"] == 3.0


def test_markdown_has_one_line_per_row(rows):
    text = errata.errata_markdown(rows)
    assert text.count("\n") == len(rows) + 2
    assert "| 7.1358 |" in text
