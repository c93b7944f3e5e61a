"""Tests of the seed models: forces, vectorised and heyoka evaluation, energy,
natural frequencies, small-amplitude limits and parameter validation.

Expected values are derived from theory in the test (formula and comment).
"""
import math

import numpy as np
import pytest

import rk4h
from rk4h.models import BUILTIN_CLASSES, MODELS, example_parameters

# (id, model name, params, coordinate scale of a typical non-equilibrium state)
MODEL_CASES = [
    ("chain-both", "chain", {"masses": [0.815, 3.099], "springs": [41.5, 138.0, 157.8], "walls": "both"}, 0.005),
    ("chain-left", "chain", {"masses": [1.0, 2.0, 3.0], "springs": [5.0, 6.0, 7.0], "walls": "left"}, 0.1),
    ("chain-right", "chain", {"masses": [1.0, 2.0, 3.0], "springs": [5.0, 6.0, 7.0], "walls": "right"}, 0.1),
    ("chain-none", "chain", {"masses": [1.0, 2.0, 3.0], "springs": [5.0, 6.0], "walls": "none"}, 0.1),
    ("chain-single", "chain", {"masses": [2.0], "springs": [3.0, 4.0]}, 0.1),
    ("planar4-exact", "planar4", {"m": 0.5, "k": 25.0, "l": 0.01}, 0.004),
    ("planar4-linear", "planar4", {"m": 0.5, "k": 25.0, "l": 0.01, "linear": True}, 0.004),
    ("oscillator2d", "oscillator2d", {"m": 0.5, "kx": 80.0, "ky": 20.0}, 0.01),
    ("pendulums-exact", "pendulums", {"m": 0.2, "length": 0.5, "g": 9.81, "k": 1.0}, 0.4),
    ("pendulums-linear", "pendulums", {"m": 0.2, "length": 0.5, "g": 9.81, "k": 1.0, "linear": True}, 0.4),
    ("pendulums-separated", "pendulums", {"m": 0.2, "length": 0.5, "g": 9.81, "k": 1.0, "separation": 0.3}, 0.4),
    ("triangle", "triangle", {"m": 1.0, "k": 5.0, "side": 1.0}, 0.15),
    ("network", "network", {"dim": 2, "masses": [0.5, 0.8], "positions": [-0.2, 0.0, 0.2, 0.0],
                            "anchors": [-0.6, 0.0, 0.0, 0.5, 0.6, 0.0, 0.0, -0.5],
                            "springs": [[0, 2, 30.0], [0, 3, 20.0], [1, 4, 30.0], [1, 5, 20.0], [0, 1, 50.0]]}, 0.02),
    ("potential", "potential", {"coordinates": ["x", "y"], "masses": 1.0,
                                "potential": "(x^2 + y^2)/2 + x^2*y - y^3/3"}, 0.1),
]
# Every registered built-in model is tested: one without a case above is built
# from its declared examples (so a new model is covered, not skipped by omission).
# First-order models (no potential, no force) are tested in test_ode.py.
MODEL_CASES += [(f"{cls.name}-example", cls.name, example_parameters(cls.name), 0.01) for cls in BUILTIN_CLASSES
                if all(c[1] != cls.name for c in MODEL_CASES) and not cls.first_order]
CASE_IDS = [c[0] for c in MODEL_CASES]


def build(case):
    _, name, params, scale = case
    return rk4h.make_model(name, params), scale


def random_q(model, scale, seed, m=None):
    rng = np.random.default_rng(seed)
    shape = (model.n_dof,) if m is None else (model.n_dof, m)
    return scale * rng.uniform(-1.0, 1.0, shape)


def random_y(model, scale, seed, m=None):
    """State [q, v] with v of the size omega * scale (so both halves matter)."""
    w = np.sqrt(np.max(np.linalg.eigvalsh(model.stiffness_matrix() / model.mass[:, None])))
    rng = np.random.default_rng(seed)
    shape = (model.n_state,) if m is None else (model.n_state, m)
    y = scale * rng.uniform(-1.0, 1.0, shape)
    y[model.n_dof:] *= w
    return y


# -- force = -grad V -----------------------------------------------------------

@pytest.mark.parametrize("seed", [0, 1, 2])
@pytest.mark.parametrize("case", MODEL_CASES, ids=CASE_IDS)
def test_force_is_minus_gradient_of_potential(case, seed):
    # Central differences: error delta^2 / 6 * V''' ~ 1e-10 relative with
    # delta = 1e-5 scale, round-off eps V / delta ~ 1e-11 relative: tolerance 1e-7.
    model, scale = build(case)
    q = random_q(model, scale, seed)
    delta = 1e-5 * scale
    E = np.eye(model.n_dof) * delta
    grad = (model.potential(q[:, None] + E) - model.potential(q[:, None] - E)) / (2 * delta)
    f = model.force(q)
    np.testing.assert_allclose(f, -grad, rtol=0, atol=1e-7 * np.max(np.abs(f)))


@pytest.mark.parametrize("case", MODEL_CASES, ids=CASE_IDS)
def test_stiffness_matrix_is_hessian_at_rest(case):
    # K = Hessian of V at q = 0 = -dF/dq there; F is exactly linear for linear
    # models, and for the others the central difference errs by O(delta^2).
    model, scale = build(case)
    delta = 1e-6 * scale
    E = np.eye(model.n_dof) * delta
    K_fd = -(model.force(E) - model.force(-E)) / (2 * delta)
    K = np.asarray(model.stiffness_matrix(), dtype=float)
    np.testing.assert_allclose(K, K.T, rtol=0, atol=0)
    np.testing.assert_allclose(K_fd, K, rtol=0, atol=1e-7 * np.max(np.abs(K)))


@pytest.mark.parametrize("case", MODEL_CASES, ids=CASE_IDS)
def test_jacobian_matches_complex_step(case):
    # Reference: the complex-step derivative dF/dq_j = Im F(q + i d e_j) / d, exact
    # to round-off for these analytic forces (no subtraction). model.jacobian uses
    # central differences with step eps = 1e-6 (states below 1 m / 1 rad): error
    # ~ (eps / length scale)^2 <= (1e-6 / 4e-3)^2 ~ 1e-7 here; tolerance 1e-6.
    from rk4h.models import NUMPY

    model, scale = build(case)
    n = model.n_dof
    y = random_y(model, scale, seed=8)
    d = 1e-30 * scale
    dF = np.asarray(model._force(y[:n, None] + 1j * d * np.eye(n), NUMPY)).imag / d
    expected = np.zeros((2 * n, 2 * n))
    expected[:n, n:] = np.eye(n)
    expected[n:, :n] = dF / model.mass[:, None]
    J = model.jacobian(0.0, y)
    np.testing.assert_allclose(J, expected, rtol=0, atol=1e-6 * np.max(np.abs(expected)))


@pytest.mark.parametrize("case", MODEL_CASES, ids=CASE_IDS)
def test_force_vanishes_at_rest(case):
    # The rest state is an equilibrium with V = 0. The triangle's rest corner
    # a sqrt(3)/2 is rounded, so its spring lengths err by ~eps a: forces of
    # ~k eps a remain (bound 8 k eps a), V ~ k (eps a)^2.
    model, _ = build(case)
    tol = 8 * np.finfo(float).eps * model.k * model.side if model.name == "triangle" else 0.0
    np.testing.assert_allclose(model.force(np.zeros(model.n_dof)), 0.0, rtol=0, atol=tol)
    assert abs(model.potential(np.zeros(model.n_dof))) <= tol**2


# -- vectorised numpy and heyoka evaluation ------------------------------------

@pytest.mark.parametrize("case", MODEL_CASES, ids=CASE_IDS)
def test_vectorised_evaluation_equals_columns(case):
    model, scale = build(case)
    Y = random_y(model, scale, seed=3, m=5)
    Q = Y[: model.n_dof]
    F, V, E, R = model.force(Q), model.potential(Q), model.energy(Y), model.rhs(0.0, Y)
    assert F.shape == Q.shape and V.shape == (5,) and E.shape == (5,) and R.shape == Y.shape
    for j in range(5):  # the columns of one array, not test cases
        np.testing.assert_allclose(F[:, j], model.force(Q[:, j]), rtol=1e-14, atol=0)
        np.testing.assert_allclose(V[j], model.potential(Q[:, j]), rtol=1e-14, atol=0)
        np.testing.assert_allclose(E[j], model.energy(Y[:, j]), rtol=1e-14, atol=0)
        np.testing.assert_allclose(R[:, j], model.rhs(0.0, Y[:, j]), rtol=1e-14, atol=0)


@pytest.fixture(scope="module")
def hy():
    return pytest.importorskip("heyoka")


@pytest.mark.parametrize("case", MODEL_CASES, ids=CASE_IDS)
def test_heyoka_system_matches_rhs(case, hy):
    model, scale = build(case)
    vs, exprs = model.heyoka_system()
    assert len(vs) == len(exprs) == model.n_state
    cf = hy.cfunc(exprs + [model.heyoka_energy(vs)], vs)
    Y = random_y(model, scale, seed=4, m=6)
    out = cf(Y)  # batch mode: inputs (n_vars, m) -> outputs (n_out, m)
    ref = np.vstack([model.rhs(0.0, Y), model.energy(Y)])
    # One rounding per operation in either evaluation (heyoka multiplies by 1/m
    # where numpy divides by m): agree to 1e-13 of each output's scale.
    scale_out = np.max(np.abs(ref), axis=1, keepdims=True)
    assert np.all(np.abs(out - ref) <= 1e-13 * scale_out), np.max(np.abs(out - ref) / scale_out)


# -- energy along RK4 runs --------------------------------------------------------

LINEAR_IDS = ["chain-both", "chain-left", "chain-right", "chain-none", "chain-single",
              "planar4-linear", "oscillator2d", "pendulums-linear"]


@pytest.mark.parametrize("theta", [0.1, 1.0])
@pytest.mark.parametrize("case", [c for c in MODEL_CASES if c[0] in LINEAR_IDS],
                         ids=[c for c in CASE_IDS if c in LINEAR_IDS])
def test_linear_energy_follows_modal_amplification(case, theta):
    # M q'' = -K q decouples into modes eta_j'' = -omega_j^2 eta_j with energy
    # E = sum_j (deta_j^2 + omega_j^2 eta_j^2) / 2. RK4 commutes with the modal
    # change of variables, and multiplies each mode's energy by
    # d_j = 1 - theta_j^6/72 + theta_j^8/576 per step (theta_j = omega_j h; a zero
    # mode has d = 1): E_n = sum_j E_j(0) d_j^n exactly, to round-off.
    model, scale = build(case)
    omega, phi = model.modes()
    h = theta / omega.max()
    n = 100
    y0 = random_y(model, scale, seed=5)
    res = rk4h.solve(model.rhs, (0.0, n * h), y0, n_steps=n)
    q0, v0 = y0[: model.n_dof], y0[model.n_dof:]
    eta, deta = phi.T @ (model.mass * q0), phi.T @ (model.mass * v0)
    e_modes = 0.5 * (deta**2 + omega**2 * eta**2)
    tj = omega * res.h
    d = 1 - tj**6 / 72 + tj**8 / 576
    expected = (e_modes[:, None] * d[:, None] ** np.arange(n + 1)).sum(axis=0)
    np.testing.assert_allclose(model.energy(res.y), expected, rtol=1e-9, atol=0)


NONLINEAR_IDS = ["planar4-exact", "pendulums-exact", "pendulums-separated", "triangle"]


@pytest.mark.parametrize("case", [c for c in MODEL_CASES if c[0] in NONLINEAR_IDS],
                         ids=[c for c in CASE_IDS if c in NONLINEAR_IDS])
def test_nonlinear_energy_drift_between_fourth_and_fifth_order(case):
    # The exact flow conserves E, so |E(y_n) - E0| <= |grad E| |y_n - y(t_n)| =
    # O(h^4) over a fixed time: the exponent is at least 4. On the linear part
    # RK4 loses E theta^6/72 per step (test above), O(h^5) over a fixed time,
    # which the nonlinear terms do not cancel: the exponent is at most 5.
    # (Measured: 4.7 to 5.0 at these amplitudes.)
    model, scale = build(case)
    w = np.sqrt(np.max(np.linalg.eigvalsh(model.stiffness_matrix() / model.mass[:, None])))
    y0 = random_y(model, scale, seed=6)
    e0 = model.energy(y0)
    t_end = 4 * np.pi / w
    hs = 0.1 / w / 2.0 ** np.arange(4)
    used, drift = [], []
    for h in hs:
        res = rk4h.solve(model.rhs, (0.0, t_end), y0, h=h)
        assert res.success
        used.append(res.h)
        drift.append(np.max(np.abs(model.energy(res.y) - e0)) / abs(e0))
    p = np.polyfit(np.log(used), np.log(drift), 1)[0]
    assert 3.9 < p < 5.1, (p, drift)


# -- natural frequencies ---------------------------------------------------------

@pytest.mark.parametrize("N", [1, 2, 5, 12])
def test_equal_chain_between_walls_frequencies(N):
    # omega_n = 2 sqrt(k/m) sin(n pi / (2 (N + 1))), n = 1..N (thesis sec. 2.2).
    m, k = 0.3, 7.0
    model = rk4h.make_model("chain", {"masses": [m] * N, "springs": [k] * (N + 1)})
    n = np.arange(1, N + 1)
    expected = 2 * np.sqrt(k / m) * np.sin(n * np.pi / (2 * (N + 1)))
    np.testing.assert_allclose(model.modes()[0], expected, rtol=1e-12)


def test_equal_chain_mode_shapes_are_sines():
    # Mode n of the chain between walls: phi_j ∝ sin(j n pi / (N + 1)).
    N, m, k = 6, 0.3, 7.0
    model = rk4h.make_model("chain", {"masses": [m] * N, "springs": [k] * (N + 1)})
    _, phi = model.modes()
    j = np.arange(1, N + 1)[:, None]
    n = np.arange(1, N + 1)[None, :]
    expected = np.sin(j * n * np.pi / (N + 1)) * np.sqrt(2 / ((N + 1) * m))  # mass-normalised
    np.testing.assert_allclose(np.abs(phi), np.abs(expected), rtol=0, atol=1e-12)
    np.testing.assert_allclose(phi.T @ (model.mass[:, None] * phi), np.eye(N), atol=1e-12)


def test_triangle_linearized_frequencies():
    # Three rigid motions (two translations, a rotation), a degenerate pair at
    # sqrt(3k / (2m)) and the breathing mode at sqrt(3k / m).
    m, k = 1.3, 5.0
    model = rk4h.make_model("triangle", {"m": m, "k": k, "side": 0.7})
    w = np.sqrt(k / m)
    np.testing.assert_allclose(model.modes()[0], [0, 0, 0, math.sqrt(1.5) * w, math.sqrt(1.5) * w,
                                                  math.sqrt(3) * w], rtol=1e-12, atol=1e-12 * w)


def test_co2_frequencies():
    # Free chain M - m - M with two springs k: 0 (translation), sqrt(k/M)
    # (symmetric stretch, carbon at rest) and sqrt(k/M (1 + 2M/m)) (asymmetric).
    M, m, k = 16.0, 12.0, 5.0
    model = rk4h.make_model("chain", {"masses": [M, m, M], "springs": [k, k], "walls": "none"})
    expected = [0.0, math.sqrt(k / M), math.sqrt(k / M * (1 + 2 * M / m))]
    np.testing.assert_allclose(model.modes()[0], expected, rtol=1e-12, atol=1e-12)


def test_three_blocks_four_springs_frequencies():
    # Equal m and k: K/k = tridiag(-1, 2, -1), eigenvalues 2 - sqrt2, 2, 2 + sqrt2.
    m, k = 0.4, 9.0
    model = rk4h.make_model("chain", {"masses": [m] * 3, "springs": [k] * 4})
    w = math.sqrt(k / m)
    expected = [w * math.sqrt(2 - math.sqrt(2)), w * math.sqrt(2), w * math.sqrt(2 + math.sqrt(2))]
    np.testing.assert_allclose(model.modes()[0], expected, rtol=1e-12)


@pytest.mark.parametrize("linear", [True, False])
def test_pendulums_frequencies(linear):
    # In phase: sqrt(g/L) (spring unstretched); anti-phase: sqrt(g/L + 2k/m).
    m, L, g, k = 0.2, 0.5, 9.81, 1.0
    model = rk4h.make_model("pendulums", {"m": m, "length": L, "g": g, "k": k, "linear": linear})
    np.testing.assert_allclose(model.modes()[0], [math.sqrt(g / L), math.sqrt(g / L + 2 * k / m)], rtol=1e-12)


@pytest.mark.parametrize("linear", [True, False])
def test_planar4_frequencies(linear):
    # m x'' = -2 k x in each direction: a degenerate pair at sqrt(2k/m).
    model = rk4h.make_model("planar4", {"m": 0.5, "k": 25.0, "l": 0.01, "linear": linear})
    np.testing.assert_allclose(model.modes()[0], [10.0, 10.0], rtol=1e-12)


def test_chain_sparse_stiffness_equals_dense():
    model = rk4h.make_model("chain", {"masses": [1.0, 2.0, 3.0, 4.0], "springs": [1.0, 2.0, 3.0], "walls": "none"})
    K = model.stiffness_matrix(sparse=True)
    assert K.shape == (4, 4) and K.nnz == 10
    np.testing.assert_array_equal(K.toarray(), model.stiffness_matrix())
    # A free chain's stiffness annihilates a rigid translation.
    np.testing.assert_array_equal(model.stiffness_matrix() @ np.ones(4), 0.0)


# -- small-amplitude limits --------------------------------------------------------

SMALL_AMPLITUDE = [
    ("planar4", {"m": 0.5, "k": 25.0, "l": 0.01}, 0.01, [0.6, -0.3]),
    ("pendulums", {"m": 0.2, "length": 0.5, "g": 9.81, "k": 1.0}, 1.0, [0.6, -0.3]),
    ("pendulums", {"m": 0.2, "length": 0.5, "g": 9.81, "k": 1.0}, 1.0, [0.5, 0.2]),
]


@pytest.mark.parametrize("name, params, scale, direction", SMALL_AMPLITUDE)
def test_linearized_force_agrees_to_second_order(name, params, scale, direction):
    # Both potentials are even about the rest state up to O(q^4) (planar4: V(-q)
    # = V(q) by the anchors' symmetry; pendulums: cos is even and the spring's
    # extension is L (th2 - th1) + O(th^3)), so F_exact - F_linear = O(A^3):
    # relative agreement to second order in the amplitude A.
    exact = rk4h.make_model(name, {**params, "linear": False})
    lin = rk4h.make_model(name, {**params, "linear": True})
    amps = scale * np.array([0.04, 0.02, 0.01, 0.005])
    u = np.array(direction)
    diff = [np.max(np.abs(exact.force(a * u) - lin.force(a * u))) for a in amps]
    p = np.polyfit(np.log(amps), np.log(diff), 1)[0]
    assert abs(p - 3) < 0.1, (p, diff)


@pytest.mark.parametrize("name, params, scale, direction", SMALL_AMPLITUDE)
def test_linearized_trajectory_agrees_to_second_order(name, params, scale, direction):
    # Over a fixed time the trajectories differ by O(A^3) (relative O(A^2)).
    # RK4's error (400 steps, theta = 0.03: n theta^5 / 120 ~ 1e-7 relative) is
    # far below the smallest difference (~1e-4 relative at A = 0.02 scale).
    exact = rk4h.make_model(name, {**params, "linear": False})
    lin = rk4h.make_model(name, {**params, "linear": True})
    w = lin.modes()[0].max()
    t_end = 4 * np.pi / w
    amps = scale * np.array([0.08, 0.04, 0.02])
    u = np.array(direction)
    diff = []
    for a in amps:
        y0 = exact.state(a * u)
        ye = rk4h.solve(exact.rhs, (0.0, t_end), y0, n_steps=400).y
        yl = rk4h.solve(lin.rhs, (0.0, t_end), y0, n_steps=400).y
        diff.append(np.max(np.abs(ye[:2] - yl[:2])))
    p = np.polyfit(np.log(amps), np.log(diff), 1)[0]
    assert abs(p - 3) < 0.15, (p, diff)


def test_triangle_force_linearization_error_is_second_order():
    # The triangle has cubic terms in V, so F + K q = O(A^2).
    model = rk4h.make_model("triangle", {"m": 1.0, "k": 5.0, "side": 1.0})
    K = model.stiffness_matrix()
    u = np.array([0.3, -0.2, 0.1, 0.5, -0.4, 0.2])
    amps = np.array([0.04, 0.02, 0.01, 0.005])
    diff = [np.max(np.abs(model.force(a * u) + K @ (a * u))) for a in amps]
    p = np.polyfit(np.log(amps), np.log(diff), 1)[0]
    assert abs(p - 2) < 0.1, (p, diff)


@pytest.mark.parametrize("which", ["translation", "rotation"])
def test_triangle_rigid_motions_cost_no_energy(which):
    # Exact geometry: a rigid translation or rotation, of any size, leaves
    # every spring at its natural length: V = 0 and F = 0.
    model = rk4h.make_model("triangle", {"m": 1.0, "k": 5.0, "side": 1.0})
    rest = np.array(model.rest)
    if which == "translation":
        q = np.tile([0.7, -1.3], 3)
    else:
        c, s = math.cos(0.9), math.sin(0.9)
        q = (rest @ np.array([[c, s], [-s, c]]) - rest).ravel()
    assert model.potential(q) == pytest.approx(0.0, abs=1e-28)
    np.testing.assert_allclose(model.force(q), 0.0, atol=1e-14)


# -- parameter validation -------------------------------------------------------------

BAD_PARAMS = [
    ("chain mass zero", "chain", {"masses": [1.0, 0.0], "springs": [1.0, 1.0, 1.0]}, "masses[1]"),
    ("chain mass negative", "chain", {"masses": [-1.0, 1.0], "springs": [1.0, 1.0, 1.0]}, "masses[0]"),
    ("chain spring zero", "chain", {"masses": [1.0, 1.0], "springs": [1.0, 0.0, 1.0]}, "springs[1]"),
    ("chain spring nan", "chain", {"masses": [1.0, 1.0], "springs": [1.0, float("nan"), 1.0]}, "springs[1]"),
    ("chain mass inf", "chain", {"masses": [float("inf"), 1.0], "springs": [1.0, 1.0, 1.0]}, "masses[0]"),
    ("chain mass bool", "chain", {"masses": [True, 1.0], "springs": [1.0, 1.0, 1.0]}, "masses[0]"),
    ("chain mass text", "chain", {"masses": ["1", 1.0], "springs": [1.0, 1.0, 1.0]}, "masses[0]"),
    ("chain masses empty", "chain", {"masses": [], "springs": [1.0]}, "masses"),
    ("chain masses scalar", "chain", {"masses": 1.0, "springs": [1.0, 1.0]}, "masses"),
    ("chain springs both short", "chain", {"masses": [1.0, 1.0], "springs": [1.0, 1.0]}, "springs"),
    ("chain springs left long", "chain", {"masses": [1.0, 1.0], "springs": [1.0, 1.0, 1.0], "walls": "left"}, "springs"),
    ("chain springs right short", "chain", {"masses": [1.0, 1.0], "springs": [1.0], "walls": "right"}, "springs"),
    ("chain springs none long", "chain", {"masses": [1.0, 1.0], "springs": [1.0, 1.0], "walls": "none"}, "springs"),
    ("chain none one mass", "chain", {"masses": [1.0], "springs": [], "walls": "none"}, "masses"),
    ("chain walls unknown", "chain", {"masses": [1.0], "springs": [1.0, 1.0], "walls": "top"}, "walls"),
    ("chain walls list", "chain", {"masses": [1.0], "springs": [1.0, 1.0], "walls": ["both"]}, "walls"),
    ("planar4 m zero", "planar4", {"m": 0.0, "k": 1.0, "l": 1.0}, "`m`"),
    ("planar4 k negative", "planar4", {"m": 1.0, "k": -1.0, "l": 1.0}, "`k`"),
    ("planar4 l nan", "planar4", {"m": 1.0, "k": 1.0, "l": float("nan")}, "`l`"),
    ("planar4 k bool", "planar4", {"m": 1.0, "k": True, "l": 1.0}, "`k`"),
    ("planar4 linear int", "planar4", {"m": 1.0, "k": 1.0, "l": 1.0, "linear": 1}, "`linear`"),
    ("planar4 linear text", "planar4", {"m": 1.0, "k": 1.0, "l": 1.0, "linear": "yes"}, "`linear`"),
    ("oscillator2d kx zero", "oscillator2d", {"m": 1.0, "kx": 0.0, "ky": 1.0}, "`kx`"),
    ("oscillator2d ky inf", "oscillator2d", {"m": 1.0, "kx": 1.0, "ky": float("inf")}, "`ky`"),
    ("oscillator2d m text", "oscillator2d", {"m": "1", "kx": 1.0, "ky": 1.0}, "`m`"),
    ("pendulums length zero", "pendulums", {"m": 1.0, "length": 0.0, "g": 9.8, "k": 1.0}, "`length`"),
    ("pendulums g negative", "pendulums", {"m": 1.0, "length": 1.0, "g": -9.8, "k": 1.0}, "`g`"),
    ("pendulums k zero", "pendulums", {"m": 1.0, "length": 1.0, "g": 9.8, "k": 0.0}, "`k`"),
    ("pendulums separation zero", "pendulums", {"m": 1.0, "length": 1.0, "g": 9.8, "k": 1.0, "separation": 0.0},
     "`separation`"),
    ("triangle side negative", "triangle", {"m": 1.0, "k": 1.0, "side": -1.0}, "`side`"),
    ("triangle m bool", "triangle", {"m": False, "k": 1.0, "side": 1.0}, "`m`"),
    ("unknown parameter", "planar4", {"m": 1.0, "k": 1.0, "l": 1.0, "mass": 2.0}, "`mass`"),
    ("missing parameter", "oscillator2d", {"m": 1.0, "kx": 1.0}, "`ky`"),
    ("unknown model", "spring", {}, "`model`"),
    ("params not a mapping", "planar4", [("m", 1.0)], "`params`"),
]


@pytest.mark.parametrize("name, params, field", [c[1:] for c in BAD_PARAMS], ids=[c[0] for c in BAD_PARAMS])
def test_bad_parameters_raise_value_error_naming_the_field(name, params, field):
    with pytest.raises(ValueError) as info:
        rk4h.make_model(name, params)
    msg = str(info.value)
    assert field in msg and "\n" not in msg


#: First-order models (no force, no modes): their round trip compares right-hand sides.
FIRST_ORDER_CASES = {"ode": {"variables": ["u", "v"], "equations": ["a*u - u*v", "-c*v + u*v + sin(t)"],
                             "constants": {"a": 1.5, "c": 3.0}, "invariant": "u + v"}}


@pytest.mark.parametrize("name", sorted(c.name for c in BUILTIN_CLASSES))
def test_params_round_trip(name):
    # A model rebuilt from its own params() is the same model.
    if name in FIRST_ORDER_CASES:
        model = rk4h.make_model(name, FIRST_ORDER_CASES[name])
        again = rk4h.make_model(name, model.params())
        assert again.params() == model.params()
        y = np.random.default_rng(7).uniform(0.5, 2.0, (model.n_state, 5))
        np.testing.assert_array_equal(again.rhs(0.3, y), model.rhs(0.3, y))
        np.testing.assert_array_equal(again.energy(y), model.energy(y))
        return
    case = next(c for c in MODEL_CASES if c[1] == name)
    model, scale = build(case)
    again = rk4h.make_model(name, model.params())
    assert again.params() == model.params()
    q = random_q(model, scale, seed=7)
    np.testing.assert_array_equal(again.force(q), model.force(q))
