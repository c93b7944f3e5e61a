"""Exact references: the 2-DOF closed forms (thesis eqs. 2.28, 2.31, Table 4.3),
the 2-D oscillator closed forms (eqs. 2.86-2.87, Table 4.6) and modal
superposition (rk4h.references.exact)."""
import math
from decimal import Decimal, getcontext

import numpy as np
import pytest
from scipy.linalg import eigh, expm

import rk4h
from rk4h.references import closed_forms as cf
from rk4h.references.exact import modal_solution

EPS = np.finfo(float).eps

# -- Table 4.3 -----------------------------------------------------------------

# Expected values quoted from issue 2 (4 decimals): omega in rad/s, f_max in Hz.
# Case 2 has case 1's parameters (only x2(0) differs), hence case 1's numbers.
TABLE_4_3_EXPECTED = [
    (1, "omega_1", 7.1358), (1, "omega_2", 16.2719), (1, "f_max", 2.5898),
    (2, "omega_1", 7.1358), (2, "omega_2", 16.2719), (2, "f_max", 2.5898),
    (3, "omega_1", 7.1358), (3, "omega_2", 12.3596), (3, "f_max", 1.9671),
]


def _table_row(case):
    return next(r for r in cf.thesis_table_4_3() if r["case"] == case)


@pytest.mark.parametrize("case,key,expected", TABLE_4_3_EXPECTED)
def test_table_4_3_correct_units(case, key, expected):
    # a value that rounds to `expected` at 4 decimals
    assert abs(_table_row(case)[key] - expected) <= 5e-5


@pytest.mark.parametrize("case", [1, 2, 3])
@pytest.mark.parametrize("key", ["omega_1", "omega_2", "f_max"])
def test_table_4_3_closed_form_matches_eigenproblem(case, key):
    row = _table_row(case)
    assert row[key] == pytest.approx(row[key + "_eig"], rel=1e-12, abs=0)


def test_table_4_3_case3_equal_masses_closed_form():
    # eqs. 2.32-2.33: equal masses and springs give omega = sqrt(k/m), sqrt(3k/m)
    row = _table_row(3)
    m, k = row["m1"], row["k1"]
    assert row["omega_1"] == pytest.approx(math.sqrt(k / m), rel=4 * EPS)
    assert row["omega_2"] == pytest.approx(math.sqrt(3 * k / m), rel=4 * EPS)


# -- eq. 2.28 / 2.31 against a 50-digit reference ----------------------------------

def _decimal_roots(m1, m2, k1, k2, k3):
    """sqrt of the roots of eq. 2.24 in 50-digit decimal arithmetic: the textbook
    formula loses at most ~25 digits to cancellation here, leaving ~25 exact."""
    getcontext().prec = 50
    m1, m2, k1, k2, k3 = (Decimal(repr(float(v))) for v in (m1, m2, k1, k2, k3))
    a, b = (k1 + k2) / m1, (k2 + k3) / m2
    D = (a - b) ** 2 + 4 * k2 * k2 / (m1 * m2)
    lo, hi = (a + b - D.sqrt()) / 2, (a + b + D.sqrt()) / 2
    return float(lo.sqrt()), float(hi.sqrt())


MASS_RATIOS = [1e-12, 1e-9, 1e-6, 1e-3, 0.5, 1.0, 3.099 / 0.815, 1e3, 1e6, 1e9, 1e12]


@pytest.mark.parametrize("r", MASS_RATIOS)
@pytest.mark.parametrize("springs", [(41.5, 138.0, 157.8), (1.0, 1e-3, 1e3), (7.0, 7.0, 7.0)])
def test_two_dof_frequencies_accurate_at_extreme_mass_ratio(r, springs):
    m1 = 0.815
    got = cf.two_dof_frequencies(m1, m1 * r, *springs)
    ref = _decimal_roots(m1, m1 * r, *springs)
    # a few ulp: no cancellation in the stable form
    assert got[0] == pytest.approx(ref[0], rel=4 * EPS, abs=0)
    assert got[1] == pytest.approx(ref[1], rel=4 * EPS, abs=0)


MUS = list(np.logspace(-12, 12, 25))


@pytest.mark.parametrize("mu", MUS)
def test_two_dof_equal_k_matches_high_precision_eq_2_31(mu):
    k, m2 = 41.5, 0.815
    got = cf.two_dof_equal_k(k, m2=m2, mu=mu)
    ref = _decimal_roots(m2 / mu, m2, k, k, k)
    assert got[0] == pytest.approx(ref[0], rel=4 * EPS, abs=0)
    assert got[1] == pytest.approx(ref[1], rel=4 * EPS, abs=0)


@pytest.mark.parametrize("mu", MUS)
def test_two_dof_equal_k_matches_scipy_eigh(mu):
    # the 2x2 generalized eigenproblem K phi = omega^2 M phi, K = k [[2, -1], [-1, 2]]
    m1, k = 0.815, 41.5
    lam = eigh(k * np.array([[2.0, -1.0], [-1.0, 2.0]]), np.diag([m1, mu * m1]), eigvals_only=True)
    got = cf.two_dof_equal_k(k, m1=m1, mu=mu)
    assert got == pytest.approx(np.sqrt(lam), rel=8 * EPS, abs=0)


@pytest.mark.parametrize("mu", [1e-12, 1e-3, 1.0, 3.8, 1e4, 1e12])
def test_two_dof_equal_k_is_eq_2_28_with_equal_springs(mu):
    m1, k = 0.815, 41.5
    a = cf.two_dof_equal_k(k, m1=m1, mu=mu)
    b = cf.two_dof_frequencies(m1, m1 * mu, k, k, k)
    assert a == pytest.approx(b, rel=4 * EPS, abs=0)


@pytest.mark.parametrize("mu", [1e-12, 1e-10, 1e-8])
def test_two_dof_equal_k_light_second_mass_limit(mu):
    # m1 fixed, m2 = mu m1 -> 0. From eq. 2.31 with s = sqrt(1 - mu + mu^2)
    # = 1 - mu/2 + 3 mu^2/8 + O(mu^3):
    #   omega_low^2  = (3k / (2 m1)) (1 - mu/4 + O(mu^2))   (m1 on k || (k in series k): 3k/2)
    #   omega_high^2 = (2k / m2) (1 + mu/4 + O(mu^2))
    # so the two-term series is exact to O(mu^2) <= 1e-16 here.
    m1, k = 0.815, 41.5
    m2 = mu * m1
    lo, hi = cf.two_dof_equal_k(k, m1=m1, mu=mu)
    assert lo**2 == pytest.approx(1.5 * k / m1 * (1 - mu / 4), rel=4 * EPS, abs=0)
    assert hi**2 == pytest.approx(2 * k / m2 * (1 + mu / 4), rel=4 * EPS, abs=0)


@pytest.mark.parametrize("mu", [1e8, 1e10, 1e12])
def test_two_dof_equal_k_heavy_second_mass_limit(mu):
    # m1 fixed, m2 = mu m1 -> inf; with eps = 1/mu, s = mu (1 - eps/2 + 3 eps^2/8 + ...):
    #   omega_low^2  = (3k / (2 m2)) (1 - eps/4 + O(eps^2))
    #   omega_high^2 = (2k / m1) (1 + eps/4 + O(eps^2))
    m1, k = 0.815, 41.5
    m2, e = mu * m1, 1.0 / mu
    lo, hi = cf.two_dof_equal_k(k, m1=m1, mu=mu)
    assert lo**2 == pytest.approx(1.5 * k / m2 * (1 - e / 4), rel=4 * EPS, abs=0)
    assert hi**2 == pytest.approx(2 * k / m1 * (1 + e / 4), rel=4 * EPS, abs=0)


def test_textbook_eq_2_31_would_fail_the_limit_test():
    # The tolerance above has teeth: (mu + 1 - sqrt((mu-1)^2 + mu)) cancels ~12
    # digits at mu = 1e-12, so the naive omega_low is off by far more than 4 eps.
    mu, k, m1 = 1e-12, 41.5, 0.815
    m2 = mu * m1
    naive = k / m2 * (mu + 1 - math.sqrt((mu - 1) ** 2 + mu))
    exact = 1.5 * k / m1 * (1 - mu / 4)
    assert abs(naive / exact - 1) > 1e-6


def test_two_dof_equal_k_mirror_symmetry():
    # equal springs: swapping the masses mirrors the system, frequencies unchanged
    a = cf.two_dof_equal_k(10.0, m1=0.3, m2=7.0)
    b = cf.two_dof_equal_k(10.0, m1=7.0, m2=0.3)
    assert a == pytest.approx(b, rel=4 * EPS, abs=0)


def test_two_dof_equal_k_vectorised_over_mu():
    mu = np.array([1e-6, 1.0, 1e6])
    lo, hi = cf.two_dof_equal_k(41.5, m1=0.815, mu=mu)
    for i, x in enumerate(mu):
        assert (lo[i], hi[i]) == cf.two_dof_equal_k(41.5, m1=0.815, mu=float(x))


@pytest.mark.parametrize("mu", [0.0, -1.0, float("nan"), float("inf"), [1.0, 0.0], [2.0, -3.0]])
def test_two_dof_equal_k_rejects_bad_mu(mu):
    with pytest.raises(ValueError, match="`mu`"):
        cf.two_dof_equal_k(41.5, m1=0.815, mu=mu)


@pytest.mark.parametrize("kwargs", [{"m1": 1.0}, {"mu": 1.0}, {"m1": 1.0, "m2": 2.0, "mu": 2.0}, {}])
def test_two_dof_equal_k_needs_exactly_two_of_m1_m2_mu(kwargs):
    with pytest.raises(ValueError, match="exactly two"):
        cf.two_dof_equal_k(41.5, **kwargs)


@pytest.mark.parametrize("name", ["m1", "m2", "k1", "k2", "k3"])
@pytest.mark.parametrize("bad", [0.0, -2.0, float("nan")])
def test_two_dof_frequencies_rejects_bad_parameter(name, bad):
    args = {"m1": 0.815, "m2": 3.099, "k1": 41.5, "k2": 138.0, "k3": 157.8}
    args[name] = bad
    with pytest.raises(ValueError, match=f"`{name}`"):
        cf.two_dof_frequencies(**args)


# -- the 2-D oscillator (eqs. 2.83-2.87, Table 4.6) -------------------------------

def test_table_4_6_recomputed():
    t46 = cf.thesis_table_4_6()
    # omega = sqrt(2k/m) for m x'' = -2kx (eqs. 2.81-2.82); T = 2 pi / omega
    assert t46["omega"] == pytest.approx(math.sqrt(2 * 41.5 / 0.815), rel=2 * EPS)
    assert round(t46["omega"], 2) == 10.09
    assert round(t46["T"], 3) == 0.623


def test_planar4_small_oscillation_is_the_linear_model_frequency():
    model = rk4h.make_model("planar4", {"m": 0.815, "k": 41.5, "l": 0.01, "linear": True})
    omega, _ = model.modes()
    w, _ = cf.planar4_small_oscillation(0.815, 41.5)
    assert omega == pytest.approx([w, w], rel=1e-14)


@pytest.mark.parametrize("Delta", cf.TABLE_4_6["Delta"])
@pytest.mark.parametrize("kx_over_ky", [1.0, 2.0, 4.0])
def test_oscillator2d_closed_form_matches_modal_solution(Delta, kx_over_ky):
    # kx/ky = 4: omega_x = 2 omega_y (Fig. 4.19); kx/ky = 2: omega_x = sqrt(2) omega_y (Fig. 4.20)
    m, ky = 0.815, 83.0
    A, B = 0.02, 0.01
    model = rk4h.make_model("oscillator2d", {"m": m, "kx": kx_over_ky * ky, "ky": ky})
    wx, wy = cf.oscillator2d_frequencies(m, kx_over_ky * ky, ky)
    y0 = cf.oscillator2d_initial_state(A, B, wy, Delta)
    t = np.linspace(0.0, 5.0, 101)
    closed = cf.oscillator2d_trajectory(t, A, B, wx, wy, Delta)
    modal = modal_solution(model, y0)(t)
    scale = np.array([A, B, A * wx, B * wy])[:, None]
    assert np.max(np.abs(closed - modal) / scale) < 1e-12


def test_isotropic_in_phase_is_a_line():
    # Delta = 0: y / x = B / A at all times (thesis Fig. 4.15)
    t = np.linspace(0.0, 2.0, 257)
    x, y, _, _ = cf.oscillator2d_trajectory(t, 2.0, 1.0, 10.0, 10.0, 0.0)
    assert np.max(np.abs(y - 0.5 * x)) < 1e-15


def test_isotropic_quarter_phase_is_an_axis_aligned_ellipse():
    # Delta = pi/2: x = A cos(wt), y = B sin(wt) -> x^2/A^2 + y^2/B^2 = 1
    t = np.linspace(0.0, 2.0, 257)
    A, B = 2.0, 0.5
    x, y, _, _ = cf.oscillator2d_trajectory(t, A, B, 10.0, 10.0, math.pi / 2)
    assert np.max(np.abs((x / A) ** 2 + (y / B) ** 2 - 1)) < 1e-14


# -- modal superposition (rk4h.references.exact) --------------------------------------

LINEAR_MODELS = [
    ("chain", {"masses": [0.815, 3.099], "springs": [41.5, 138.0, 157.8], "walls": "both"}),
    ("chain", {"masses": [1.0, 2.0, 3.0], "springs": [4.0, 5.0, 6.0], "walls": "left"}),
    ("chain", {"masses": [1.0, 2.0, 3.0], "springs": [4.0, 5.0, 6.0], "walls": "right"}),
    ("chain", {"masses": [16.0, 12.0, 16.0], "springs": [1.0, 1.0], "walls": "none"}),  # CO2
    ("oscillator2d", {"m": 0.815, "kx": 166.0, "ky": 83.0}),
    ("planar4", {"m": 0.815, "k": 41.5, "l": 0.01, "linear": True}),
    ("pendulums", {"m": 1.0, "length": 1.0, "g": 9.81, "k": 2.0, "linear": True}),
    ("triangle", {"m": 1.0, "k": 3.0, "side": 1.0}),  # its linearization
]


def _linear_propagator(model, tau):
    """exp(tau J) with J = [[0, I], [-M^-1 K, 0]]: the exact flow of the linearization."""
    n = model.n_dof
    J = np.zeros((2 * n, 2 * n))
    J[:n, n:] = np.eye(n)
    J[n:, :n] = -np.asarray(model.stiffness_matrix(), dtype=float) / model.mass[:, None]
    return expm(tau * J)


@pytest.mark.parametrize("name,params", LINEAR_MODELS, ids=[
    "chain-both", "chain-left", "chain-right", "co2-free", "oscillator2d", "planar4-linear",
    "pendulums-linear", "triangle-linearized"])
def test_modal_solution_is_the_matrix_exponential_flow(name, params):
    model = rk4h.make_model(name, params)
    rng = np.random.default_rng(2)
    y0 = rng.standard_normal(2 * model.n_dof) * 1e-2
    sol = modal_solution(model, y0)
    t = np.array([0.0, 0.37, 1.9])
    y = sol(t)
    assert np.max(np.abs(y[:, 0] - y0)) < 1e-14
    for j in (1, 2):
        ref = _linear_propagator(model, t[j]) @ y0
        assert np.max(np.abs(y[:, j] - ref)) < 1e-11 * np.max(np.abs(ref))


def test_modal_solution_free_chain_translates():
    # walls "none": a uniform velocity is a zero mode, q(t) = q0 + v t exactly
    model = rk4h.make_model("chain", {"masses": [16.0, 12.0, 16.0], "springs": [5.0, 5.0], "walls": "none"})
    y0 = model.state([0.1, 0.1, 0.1], [0.3, 0.3, 0.3])
    t = np.array([0.0, 1.0, 10.0])
    y = modal_solution(model, y0)(t)
    assert np.max(np.abs(y[:3] - (0.1 + 0.3 * t))) < 1e-13
    assert np.max(np.abs(y[3:] - 0.3)) < 1e-13


def test_modal_solution_linearized_triangle_rotates_uniformly():
    # Linearized rigid rotation about the centroid c: v_i = w e_z x (r_i - c), a zero
    # mode of the linearization, so q(t) = v t (no restoring force to first order).
    model = rk4h.make_model("triangle", {"m": 1.0, "k": 3.0, "side": 1.0})
    r = np.array(model.rest)
    c = r.mean(axis=0)
    w = 0.2
    v = np.column_stack([-w * (r[:, 1] - c[1]), w * (r[:, 0] - c[0])]).ravel()
    y0 = model.state(np.zeros(6), v)
    t = np.array([0.0, 2.0, 7.0])
    y = modal_solution(model, y0)(t)
    assert np.max(np.abs(y[:6] - v[:, None] * t)) < 1e-13
    assert np.max(np.abs(y[6:] - v[:, None])) < 1e-13
