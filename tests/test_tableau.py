"""Methods as data: exact tableaux, computed order, cost and stability.

Expected values come from the literature, stated beside each test: orders of
the classical methods (HNW I, sec. II.1), the counts of rooted and bi-coloured
trees (Butcher 2008, sec. 30; OEIS A000081, A000151), stability polynomials and
boundaries (RK4: |R(iy)|^2 = 1 - y^6/72 + y^8/576, so 2 sqrt 2; Heun3:
1 - y^4/12 + y^6/36, so sqrt 3), Stormer-Verlet and symplectic Euler stable
for h w < 2 (HLW sec. I.5).
"""
import math
from fractions import Fraction as F

import numpy as np
import pytest

import rk4h
from rk4h import order_conditions as oc
from rk4h import stability_function as sf
from rk4h.methods import METHODS, Tableau, make_tableau

# The two-parameter family of 3-stage third-order methods (HNW I, sec. II.1;
# Butcher 2008, sec. 32) built from free nodes c2, c3: it satisfies every
# condition of order <= 3 and, having 3 stages, cannot reach 4.
_C2, _C3 = F(1, 3), F(3, 4)
_B2 = (2 - 3 * _C3) / (6 * _C2 * (_C2 - _C3))
_B3 = (2 - 3 * _C2) / (6 * _C3 * (_C3 - _C2))
_A32 = _C3 * (_C3 - _C2) / (_C2 * (2 - 3 * _C2))
THIRD = make_tableau("third", [[0, 0, 0], [_C2, 0, 0], [_C3 - _A32, _A32, 0]], [1 - _B2 - _B3, _B2, _B3])

# Bogacki-Shampine 3(2): third order, first same as last (its last row is b).
BS3 = make_tableau("bs3", [[0, 0, 0, 0], ["1/2", 0, 0, 0], [0, "3/4", 0, 0], ["2/9", "1/3", "4/9", 0]],
                   ["2/9", "1/3", "4/9", 0])

ORDERS = [("rk4", 4), ("rk38", 4), ("heun3", 3), ("ralston", 2), ("euler", 1), ("symplectic-euler", 1),
          ("stormer-verlet", 2)]


@pytest.mark.parametrize("name, expected", ORDERS)
def test_builtin_order_is_computed_from_the_conditions(name, expected):
    tab = METHODS[name]
    assert tab.order == expected
    # Directly from the conditions, too.
    assert oc.order(tab.A_exact, tab.b_exact, tab.A_v_exact, tab.b_v_exact) == expected


def test_constructed_third_order_tableau_has_order_3():
    A, b = THIRD.A_exact, THIRD.b_exact
    for p in (1, 2, 3):
        for tree, gamma in oc.tree_conditions(p):
            assert oc.elementary_weight(tree, A, b) == F(1, gamma)
    assert any(oc.elementary_weight(t, A, b) != F(1, g) for t, g in oc.tree_conditions(4))
    assert THIRD.order == 3
    assert BS3.order == 3


def test_tree_counts():
    assert [len(oc.rooted_trees(p)) for p in range(1, 9)] == [1, 1, 2, 4, 9, 20, 48, 115]
    assert [len(oc.bicoloured_trees(p)) for p in range(1, 6)] == [2, 4, 14, 52, 214]
    # gamma of the tall and the bushy tree of order 4
    assert sorted(g for _, g in oc.tree_conditions(4)) == [4, 8, 12, 24]


def _gauss(s):
    """The s-stage Gauss method in float64 (order 2s): nodes, then A and b by
    integrating the Lagrange basis."""
    x = np.sort((np.polynomial.legendre.legroots([0] * s + [1]) + 1) / 2)
    A, b = np.zeros((s, s)), np.zeros(s)
    for j in range(s):
        others = np.delete(x, j)
        integ = np.polyint(np.poly(others) / np.prod(x[j] - others))
        b[j] = np.polyval(integ, 1) - np.polyval(integ, 0)
        A[:, j] = np.polyval(integ, x) - np.polyval(integ, 0)
    return A, b


def test_conditions_are_checked_through_order_8():
    # order() is algebra on (A, b): the implicit 4-stage Gauss method, order 8,
    # needs every condition up to 115 trees of order 8 (and fails at 9).
    A, b = _gauss(4)
    assert oc.order(A, b, tol=1e-10) == 8
    assert oc.order(A, b) == 0  # floats, compared exactly: not even consistent


def test_partitioned_conditions_over_bicoloured_trees():
    # A classical method written as a partitioned one keeps its order.
    rk4 = METHODS["rk4"]
    assert oc.order(rk4.A_exact, rk4.b_exact, rk4.A_exact, rk4.b_exact) == 4
    # The 3-stage Lobatto IIIA-IIIB pair has order 2s - 2 = 4 (HLW sec. II.2.2;
    # implicit, but order() does not care).
    A = [[0, 0, 0], [F(5, 24), F(1, 3), F(-1, 24)], [F(1, 6), F(2, 3), F(1, 6)]]
    A_v = [[F(1, 6), F(-1, 6), 0], [F(1, 6), F(1, 3), 0], [F(1, 6), F(5, 6), 0]]
    b = [F(1, 6), F(2, 3), F(1, 6)]
    assert oc.order(A, b, A_v, b) == 4
    # Swapping the roles of A and A_v in the weights breaks it.
    assert oc.order(A, b, A_v, [F(1, 2), 0, F(1, 2)]) < 4


# -- exact entries ----------------------------------------------------------------------------------
def test_entries_are_kept_exact():
    rk4 = METHODS["rk4"]
    assert rk4.b_exact == (F(1, 6), F(1, 3), F(1, 3), F(1, 6))
    assert rk4.c_exact == (0, F(1, 2), F(1, 2), 1)
    np.testing.assert_array_equal(rk4.b, [1 / 6, 1 / 3, 1 / 3, 1 / 6])  # correctly rounded, as before
    tab = make_tableau("t", [[0, 0], ["0.1", 0]], ["0.9", 0.1])
    assert tab.A_exact[1][0] == F(1, 10)  # the string: exactly one tenth
    assert tab.b_exact[1] == F(0.1) != F(1, 10)  # the float: its binary value, noted
    assert tab.inexact == ("b[1]",)
    assert make_tableau("h", [[0, 0], [0.5, 0]], [0, 1.0]).inexact == ()  # 0.5 is exact


def test_float_tableau_gets_its_order_within_round_off():
    tab = make_tableau("rk4f", [[0, 0, 0, 0], [0.5, 0, 0, 0], [0, 0.5, 0, 0], [0, 0, 1, 0]],
                       [1 / 6, 1 / 3, 1 / 3, 1 / 6])
    assert tab.inexact and tab.order == 4


def test_positional_constructor_checks_a_declared_order():
    heun = Tableau("heun", np.array([[0.0, 0.0], [1.0, 0.0]]), np.array([0.5, 0.5]), np.array([0.0, 1.0]), 2)
    assert heun.order == 2
    with pytest.raises(ValueError, match="`order` is declared 3 but the order conditions give 2"):
        Tableau("heun", [[0, 0], [1, 0]], [0.5, 0.5], [0, 1], 3)


def test_c_defaults_to_row_sums_and_row_sum_false_allows_others():
    tab = make_tableau("r", [[0, 0], ["2/3", 0]], ["1/4", "3/4"])
    assert tab.c_exact == (0, F(2, 3))
    odd = make_tableau("odd", [[0, 0], [1, 0]], ["1/2", "1/2"], [0, "1/2"], row_sum=False)
    assert odd.c_exact == (0, F(1, 2))


INVALID = [
    ("implicit midpoint", dict(A=[["1/2"]], b=[1]), "`A` must be strictly lower triangular",
     "A[0][0] = 1/2"),
    ("one weight for two stages", dict(A=[[0, 0], [1, 0]], b=[1]), "`b` must have 2 entries", "got 1"),
    ("bad rational string", dict(A=[[0, 0], ["1/x", 0]], b=[0, 1]), "`A` entry A[1][0] = '1/x'",
     "not a number or a rational string"),
    ("bad string in b", dict(A=[[0, 0], [1, 0]], b=["half", "1/2"]), "`b` entry b[0] = 'half'", "rational"),
    ("c disagrees with row sums", dict(A=[[0, 0], [1, 0]], b=["1/2", "1/2"], c=[0, "1/2"]),
     "`c` must equal the row sums", "row 1: c[1] = 1/2 but sum_j A[1][j] = 1"),
    ("empty", dict(A=[], b=[]), "`A` must be a non-empty square matrix", ""),
    ("not square", dict(A=[[0, 0], [1]], b=[0, 1]), "`A` must be square", "row 1 has 1 entries"),
    ("non-finite", dict(A=[[0, 0], [float("inf"), 0]], b=[0, 1]), "`A` entry A[1][0] = inf", "not finite"),
    ("nan weight", dict(A=[[0]], b=[float("nan")]), "`b` entry b[0] = nan", "not finite"),
    ("boolean", dict(A=[[0]], b=[True]), "`b` entry b[0] = True", "not a number"),
    ("c too short", dict(A=[[0, 0], [1, 0]], b=[0, 1], c=[0]), "`c` must have 2 entries", "got 1"),
    ("A_v without b_v", dict(A=[[0]], b=[1], A_v=[[0]]), "`b_v` must be given with `A_v`", ""),
    ("partitioned upper entry", dict(A=[[0, 1], [0, 0]], b=[0, 1], A_v=[[0, 0], [1, 0]], b_v=[1, 0]),
     "`A` must be lower triangular for a partitioned method", "A[0][1] = 1"),
    ("partitioned implicit stage", dict(A=[[0, 0], ["1/2", "1/2"]], b=["1/2", "1/2"],
                                        A_v=[["1/2", 0], ["1/2", "1/2"]], b_v=["1/2", "1/2"]),
     "must not both have a diagonal entry", "A[1][1] = 1/2, A_v[1][1] = 1/2"),
    ("A_v shape", dict(A=[[0, 0], [1, 0]], b=[0, 1], A_v=[[0]], b_v=[1, 0]), "`A_v` must be 2 x 2", ""),
]


@pytest.mark.parametrize("kwargs, field, detail", [c[1:] for c in INVALID], ids=[c[0] for c in INVALID])
def test_invalid_tableaux_are_refused_in_one_line(kwargs, field, detail):
    with pytest.raises(ValueError) as info:
        make_tableau("mid", **kwargs)
    text = str(info.value)
    assert "\n" not in text
    assert text.startswith("method 'mid': ")
    assert field in text and detail in text


# -- cost -------------------------------------------------------------------------------------------
COSTS = [("rk4", 4, 4, False), ("rk38", 4, 4, False), ("heun3", 3, 3, False), ("ralston", 2, 2, False),
         ("euler", 1, 1, False), ("symplectic-euler", 1, 1, False), ("stormer-verlet", 2, 1, True)]


@pytest.mark.parametrize("name, first, per_step, fsal", COSTS)
def test_cost_per_step(name, first, per_step, fsal):
    tab = METHODS[name]
    assert (tab.nfev_first_step, tab.nfev_per_step, tab.fsal) == (first, per_step, fsal)


def _counting(fun):
    calls = []

    def counted(t, y):
        calls.append(t)
        return fun(t, y)

    return counted, calls


def _oscillator(t, y):
    return np.array([y[1], -y[0]])


@pytest.mark.parametrize("name", sorted(METHODS) + ["bs3"])
@pytest.mark.parametrize("t_eval", [None, [0.0, 0.02, 0.07, 0.31, 1.0]], ids=["grid", "hermite"])
def test_generic_path_makes_the_calls_it_reports(name, t_eval):
    tab = BS3 if name == "bs3" else METHODS[name]
    fun, calls = _counting(_oscillator)
    n = 20
    res = rk4h.solve(fun, (0.0, 1.0), [1.0, 0.0], n_steps=n, method=tab, t_eval=t_eval)
    expected = tab.nfev_first_step + (n - 1) * tab.nfev_per_step
    assert rk4h.nfev_count(tab, n) == expected
    if t_eval is not None:  # for each of the 3 steps holding off-grid points: the slopes no stage gave
        expected += 3 * ((not tab.fsal) + (tab.start_stage is None))  # (a drift-first splitting: both ends)
    assert res.nfev == len(calls) == expected


def test_bs3_fsal_reuse_on_both_paths():
    import rk4h.fast as fast

    model = rk4h.make_model("chain", {"masses": [0.815, 3.099], "springs": [41.5, 138.0, 157.8]})
    y0 = model.state([0.005, 0.005], [0.0, 0.0])
    fun, calls = _counting(model.rhs)
    kw = dict(n_steps=150, method=BS3, t_eval=np.array([0.0, 0.013, 0.7, 1.5]))
    gen = rk4h.solve(fun, (0.0, 1.5), y0, **kw)
    res = fast.solve_model(model, (0.0, 1.5), y0, **kw)
    assert gen.nfev == res.nfev == len(calls) == 4 + 149 * 3
    np.testing.assert_array_equal(res.y, gen.y)
    # The reuse changes nothing but the count: the same step with every stage evaluated.
    y, k = np.array(y0), np.empty((4, 4))
    y1 = rk4h.rk_step(model.rhs, 0.0, y, 0.01, BS3, k)
    y2a = rk4h.rk_step(model.rhs, 0.01, y1, 0.01, BS3, k, reuse=True)
    y2b = rk4h.rk_step(model.rhs, 0.01, y1, 0.01, BS3, np.empty((4, 4)))
    np.testing.assert_array_equal(y2a, y2b)


# -- stability --------------------------------------------------------------------------------------
def test_rk4_stability_polynomial_is_exact():
    assert sf.stability_polynomial(METHODS["rk4"]) == [F(1), F(1), F(1, 2), F(1, 6), F(1, 24)]
    assert sf.stability_polynomial(METHODS["rk38"]) == [F(1), F(1), F(1, 2), F(1, 6), F(1, 24)]
    assert sf.stability_polynomial(METHODS["heun3"]) == [F(1), F(1), F(1, 2), F(1, 6)]
    assert sf.stability_polynomial(METHODS["euler"]) == [F(1), F(1)]


def test_R_is_vectorised_and_complex():
    z = np.array([0.3j, -1.0, 2.0 + 1.0j])
    np.testing.assert_allclose(sf.R(METHODS["rk4"], z), 1 + z + z**2 / 2 + z**3 / 6 + z**4 / 24, rtol=1e-15)
    assert sf.R(METHODS["euler"], -2.0) == -1.0


BOUNDARIES = [
    ("rk4", 2 * math.sqrt(2), 2.785293563405282),
    ("rk38", 2 * math.sqrt(2), 2.785293563405282),
    ("heun3", math.sqrt(3), None),
    ("ralston", 0.0, 2.0),
    ("euler", 0.0, 2.0),
    ("stormer-verlet", 2.0, None),
    ("symplectic-euler", 2.0, None),
]


@pytest.mark.parametrize("name, imag, real", BOUNDARIES)
def test_stability_boundaries(name, imag, real):
    tab = METHODS[name]
    assert sf.imaginary_axis_boundary(tab) == pytest.approx(imag, rel=1e-12, abs=0)
    if real is not None:
        assert sf.real_axis_boundary(tab) == pytest.approx(real, rel=1e-12)
    if tab.partitioned:
        with pytest.raises(ValueError, match="partitioned"):
            sf.real_axis_boundary(tab)


def test_heun3_real_boundary_is_where_R_is_minus_one():
    x = sf.real_axis_boundary(METHODS["heun3"])
    assert abs(sf.R(METHODS["heun3"], -x) + 1) < 1e-14


def test_partitioned_step_matrix():
    hw = np.array([0.3, 1.0, 1.9])
    M = sf.partitioned_step_matrix(METHODS["stormer-verlet"], hw)
    x = hw**2
    np.testing.assert_allclose(M[:, 0, 0], 1 - x / 2)
    np.testing.assert_allclose(M[:, 1, 0], -x * (1 - x / 4))
    np.testing.assert_allclose(np.linalg.det(M), 1.0, rtol=1e-14)  # symplectic: area preserving
    lam = np.linalg.eigvals(M)
    np.testing.assert_allclose(np.abs(lam), 1.0, rtol=1e-12)
    # Beyond h w = 2 one eigenvalue leaves the unit circle.
    assert np.max(np.abs(np.linalg.eigvals(sf.partitioned_step_matrix(METHODS["stormer-verlet"], 2.01)))) > 1
    # A classical method's step matrix has the eigenvalues R(+-i h w).
    lam = np.linalg.eigvals(sf.partitioned_step_matrix(METHODS["rk4"], 1.3))
    np.testing.assert_allclose(np.sort(np.abs(lam)), abs(sf.R(METHODS["rk4"], 1.3j)), rtol=1e-13)


def _amplitude_growth(tab, hw, n_steps=3000):
    """max |y| / |y0| of ``solve`` on q'' = -q at step h = hw (None when the run stopped as unstable)."""
    res = rk4h.solve(_oscillator, (0.0, n_steps * hw), [1.0, 0.0], n_steps=n_steps, method=tab)
    return float(np.max(np.abs(res.y))) if res.success else None


@pytest.mark.parametrize("name", ["rk4", "rk38", "heun3", "stormer-verlet", "symplectic-euler"])
def test_imaginary_boundary_matches_a_run(name):
    tab = METHODS[name]
    edge = sf.imaginary_axis_boundary(tab)
    below = _amplitude_growth(tab, 0.99 * edge)
    above = _amplitude_growth(tab, 1.01 * edge)
    assert below is not None and below < 20.0  # bounded (the symplectic ellipse is elongated near h w = 2)
    assert above is None or above > 1e6  # grows until the run is stopped


@pytest.mark.parametrize("name", ["ralston", "euler"])
def test_no_imaginary_interval_grows_at_any_step(name):
    tab = METHODS[name]
    assert sf.imaginary_axis_boundary(tab) == 0.0
    growth = _amplitude_growth(tab, 0.5)  # |R(0.5 i)|^2 = 1 + 1/64 (ralston), 1.25 (euler) per step
    assert growth is None or growth > 1e6


@pytest.mark.parametrize("name", ["rk4", "rk38", "heun3", "ralston", "euler"])
def test_real_boundary_matches_a_run(name):
    tab = METHODS[name]
    edge = sf.real_axis_boundary(tab)

    def decay(t, y):
        return -y

    def final(x):
        res = rk4h.solve(decay, (0.0, 3000 * x), [1.0], n_steps=3000, method=tab)
        return abs(res.y[0, -1]) if res.success else math.inf

    assert final(0.99 * edge) < 1.0
    assert final(1.01 * edge) > 1e6


def test_imaginary_boundary_kept_per_coefficients_not_per_name():
    # The boundary is kept per process for each set of coefficients: a tableau with the same name and
    # other coefficients gets its own, and a repeated call answers from the memory without recomputing.
    third = F(1, 3)
    heun3 = make_tableau("same-name", [[0, 0, 0], [third, 0, 0], [0, 2 * third, 0]], [F(1, 4), 0, F(3, 4)])
    rk4 = make_tableau("same-name", [[0, 0, 0, 0], [F(1, 2), 0, 0, 0], [0, F(1, 2), 0, 0], [0, 0, 1, 0]],
                       [F(1, 6), F(1, 3), F(1, 3), F(1, 6)])
    assert sf.imaginary_axis_boundary(heun3) == pytest.approx(math.sqrt(3), rel=1e-12)
    assert sf.imaginary_axis_boundary(rk4) == pytest.approx(2 * math.sqrt(2), rel=1e-12)
    calls = []
    real = sf._imaginary_axis_boundary
    try:
        sf._imaginary_axis_boundary = lambda tab: calls.append(tab) or real(tab)
        assert sf.imaginary_axis_boundary(heun3) == pytest.approx(math.sqrt(3), rel=1e-12)
    finally:
        sf._imaginary_axis_boundary = real
    assert calls == []
