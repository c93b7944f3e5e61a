"""Every model has one symbolic definition; everything else is derived from it.

For each model below (every shipped model, chains with each wall variant,
FPUT chains, spring networks in 1-D and 2-D, a potential typed as text) the
derived pieces must agree with each other:

1. the force is minus the gradient of the potential (central differences);
2. the stiffness matrix is the Hessian of V at the reference state q = 0
   (central differences of -F) and is symmetric;
3. the numpy right-hand side ``model.rhs`` and the compiled one
   (``rk4h.fast.compiled_rhs``: ``__call__``, ``checked``, ``permuted``);
4. heyoka's equations (``model.heyoka_system()`` and the scaled system the
   Taylor solver integrates, ``rk4h.references.solvers.taylor.scaled_system``),
   evaluated with heyoka's compiled functions (``heyoka.cfunc``);
5. for linear models, ``model.modes()`` and the generalized eigenproblem
   ``scipy.linalg.eigh(K, M)``;
6. for kernels with straight-line code (up to 8 degrees of freedom), the
   generated RK4 loop (straight-line) and the numpy path (bit for bit, or to
   round-off where sin/cos/exp/log are involved);
7. an FPUT chain with alpha = beta = 0 and the linear chain (bit for bit).
"""
from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from typing import Callable

import numpy as np
import pytest

import rk4h.fast as fast
from rk4h.models import Chain, Network, Oscillator2D, Pendulums, Planar4, PotentialModel, Triangle

EPS = np.finfo(float).eps  # 2.2e-16
CBRT_EPS = EPS ** (1.0 / 3.0)  # 6.1e-6: the central-difference step that balances truncation and round-off
CASE1 = ([0.815, 3.099], [41.5, 138.0, 157.8])
HENON_HEILES = "(x^2 + y^2)/2 + lam*(x^2*y - y^3/3)"


@dataclass(frozen=True)
class Case:
    """A model and the scales of its states.

    ``scale``: standard deviation of the random coordinates (m or rad), small
    enough that the model is well defined there (no spring near zero length).
    ``length``: the length over which the force changes by O(itself) -- the
    geometric length for exact geometry, sqrt(k/beta) or k/alpha for FPUT, 1
    for Henon-Heiles and the pendulum angles, ``scale`` for a linear model --
    always >= ``scale``; it sets the finite-difference step. (Henon-Heiles:
    scale 0.1 keeps the energy of a random state well below the escape energy
    1/6, beyond which y runs off to infinity in finite time.)
    """

    id: str
    build: Callable
    scale: float
    length: float


CASES = [
    Case("chain-case1", lambda: Chain(*CASE1), 0.005, 0.005),
    Case("chain-walls-none", lambda: Chain([1.0, 2.0, 1.5], [3.0, 5.0], walls="none"), 0.01, 0.01),
    Case("chain-walls-left", lambda: Chain([1.0, 2.0, 1.5], [3.0, 5.0, 4.0], walls="left"), 0.01, 0.01),
    Case("chain-walls-right", lambda: Chain([1.0, 2.0, 1.5], [3.0, 5.0, 4.0], walls="right"), 0.01, 0.01),
    Case("fput-alpha", lambda: Chain(1.0, 1.0, n=8, alpha=0.25), 0.3, 4.0),
    Case("fput-beta", lambda: Chain(1.0, 1.0, n=8, beta=1.0), 0.3, 1.0),
    Case("planar4-exact", lambda: Planar4(0.5, 20.0, 0.01), 1e-3, 0.01),
    Case("planar4-linear", lambda: Planar4(0.5, 20.0, 0.01, linear=True), 1e-3, 1e-3),
    Case("pendulums-exact", lambda: Pendulums(1.0, 1.0, 9.81, 2.0), 0.3, 1.0),
    Case("pendulums-linear", lambda: Pendulums(1.0, 1.0, 9.81, 2.0, linear=True), 0.3, 0.3),
    Case("triangle", lambda: Triangle(1.0, 10.0, 1.0), 0.05, 1.0),
    Case("oscillator2d", lambda: Oscillator2D(1.0, 2.0, 4.0), 0.01, 0.01),
    # Three masses, two anchors, five springs; spring 0-2 has rest 0.7 m at a
    # reference distance of sqrt(0.89) = 0.943 m: pre-stressed (tension 4.9 N).
    Case("network-2d", lambda: Network(2, [1.0, 1.5, 0.8], [0.0, 0.0, 1.0, 0.0, 0.5, 0.8],
                                       [[0, 1, 30.0], [1, 2, 25.0], [0, 2, 20.0, 0.7], [3, 0, 15.0], [1, 4, 18.0]],
                                       anchors=[-1.0, 0.3, 2.0, -0.4]), 0.02, 0.5),
    # Two masses and one anchor on a line, all three pairs joined; spring
    # anchor-mass 2 has rest 1.5 m at a reference distance of 2 m (pre-stressed).
    Case("network-1d", lambda: Network(1, [0.7, 1.3], [0.0, 1.0], [[2, 0, 12.0], [0, 1, 20.0], [2, 1, 8.0, 1.5]],
                                       anchors=[-1.0]), 0.02, 0.5),
    Case("henon-heiles", lambda: PotentialModel(["x", "y"], [1.0, 1.0], HENON_HEILES, {"lam": 1}), 0.1, 1.0),
]
IDS = [c.id for c in CASES]
BY_ID = {c.id: c for c in CASES}


@functools.lru_cache(maxsize=None)
def _model(case_id):
    return BY_ID[case_id].build()


LINEAR_CASES = [c for c in CASES if _model(c.id).linear]


def _has_straight_line_code(case):
    kern = fast.force_kernel(_model(case.id))
    return kern is not None and kern.has_scalar()


STRAIGHT_LINE_CASES = [c for c in CASES if _has_straight_line_code(c)]


def test_every_definition_of_up_to_8_degrees_of_freedom_has_a_straight_line_form():
    # so that section 6 below runs on each (a kernel that lost its
    # straight-line form would otherwise leave it without a word)
    small = {c.id for c in CASES if _model(c.id).n_dof <= fast.force_kernel(_model(c.id)).MAX_SCALAR_DOF}
    assert len(small) >= 10 and small == {c.id for c in STRAIGHT_LINE_CASES}


def _velocity_scale(case):
    """m/s (rad/s): the coordinate scale times the fastest frequency, so that
    both halves of dy/dt are of comparable size."""
    return case.scale * _model(case.id).omega_bound()


def _coordinates(case, m=5, seed=0):
    """``m`` random coordinate vectors, shape (n_dof, m)."""
    return np.random.default_rng(seed).normal(scale=case.scale, size=(_model(case.id).n_dof, m))


def _states(case, m=5, seed=1):
    """``m`` random states ``[q, v]``, shape (2 n_dof, m)."""
    rng = np.random.default_rng(seed)
    n = _model(case.id).n_dof
    return np.concatenate([rng.normal(scale=case.scale, size=(n, m)),
                           rng.normal(scale=_velocity_scale(case), size=(n, m))])


def _assert_rhs_close(got, want, n, rtol=1e-14):
    """Each half of dy/dt -- ``q' = v`` and ``v' = F/m`` -- within ``rtol`` of
    the largest entry of that half (stricter than one scale for the whole
    vector: the accelerations are not hidden behind large velocities)."""
    got, want = np.asarray(got, dtype=float), np.asarray(want, dtype=float)
    assert got.shape == want.shape
    for half in (slice(0, n), slice(n, 2 * n)):
        scale = np.max(np.abs(want[half]))
        err = np.max(np.abs(got[half] - want[half]))
        assert err <= rtol * scale, f"max error {err:.3g} > {rtol:g} * {scale:.3g} in {half}"


# -- 1. F = -grad V -----------------------------------------------------------------
# Central differences with step h = eps^(1/3) * length (length >= scale: see Case).
# Error relative to the state's max|F|, with |V'''| ~ |F| / (|q| length):
#   truncation  h^2 |V'''| / 6 / |F|          ~ eps^(2/3) * (length / |q|) / 6,
#   round-off   eps (|V| + k L |r|) / (h |F|) <= eps^(2/3) * few
# (|V| ~ |F| |q|, or |F| r0 for a pre-stressed spring, r0 <= length; the extension
# r = L - rest of a spring of length L carries an absolute error eps L, L <= 2
# length here). eps^(2/3) = 3.7e-11 and length / |q| <= ~100 (length / scale <=
# 25, and the |q| of a draw can be a fraction of the scale), so the error is
# below ~1e-9 (observed: <= 4e-10, Henon-Heiles and triangle). 1e-8 leaves a
# factor >= 10; a wrong force (a factor, a missing term) is off by O(1).
FD_RTOL = 1e-8


@pytest.mark.parametrize("case", CASES, ids=IDS)
def test_force_is_minus_the_gradient_of_the_potential(case):
    model = _model(case.id)
    n = model.n_dof
    Q = _coordinates(case)
    m = Q.shape[1]
    h = CBRT_EPS * case.length
    steps = h * np.eye(n)                                         # (n, n): column j is h e_j
    Qp = (Q[:, :, None] + steps[:, None, :]).reshape(n, m * n)    # state j shifted along e_i at column j*n + i
    Qm = (Q[:, :, None] - steps[:, None, :]).reshape(n, m * n)
    grad = ((model.potential(Qp) - model.potential(Qm)) / (2.0 * h)).reshape(m, n).T
    F = model.force(Q)
    assert F.shape == (n, m) and np.all(np.isfinite(F))
    for j in range(m):  # each state against its own largest force component
        scale = np.max(np.abs(F[:, j]))
        assert scale > 0.0
        np.testing.assert_allclose(F[:, j], -grad[:, j], rtol=0, atol=FD_RTOL * scale)
    # the vectorised evaluation is the one-state evaluation
    np.testing.assert_array_equal(np.stack([model.force(Q[:, j]) for j in range(m)], axis=1), F)


# -- 2. K = Hessian of V at q = 0 ------------------------------------------------------
# Central differences of -F with h = eps^(1/3) * length. Relative to max|K|:
#   truncation  h^2 |F'''| / 6 / |K| ~ (h / length)^2 / 6 = eps^(2/3) / 6,
#   round-off   eps (|F(0)| + k L) / (h |K|) <= eps^(2/3) * few
# (F(0) != 0 only for a pre-stressed spring, |F(0)| ~ k r0 with r0 <= length; the
# extension carries eps L, L <= 2 length). Below ~1e-10 (observed: <= 4e-11):
# 1e-8 as above.
@pytest.mark.parametrize("case", CASES, ids=IDS)
def test_stiffness_matrix_is_the_hessian_at_the_reference_state(case):
    model = _model(case.id)
    n = model.n_dof
    K = np.asarray(model.stiffness_matrix(), dtype=float)
    assert K.shape == (n, n) and np.all(np.isfinite(K))
    np.testing.assert_array_equal(K, K.T)  # symmetric, exactly
    h = CBRT_EPS * case.length
    E = h * np.eye(n)
    H = -(model.force(E) - model.force(-E)) / (2.0 * h)  # H[i, j] = -dF_i/dq_j
    np.testing.assert_allclose(K, H, rtol=0, atol=FD_RTOL * np.max(np.abs(K)))


# -- 3. numpy and compiled right-hand sides ----------------------------------------------
@functools.lru_cache(maxsize=None)
def _compiled(case_id):
    return fast.compiled_rhs(_model(case_id))


@pytest.mark.parametrize("case", CASES, ids=IDS)
def test_compiled_rhs_equals_numpy_rhs(case):
    # The kernels are printed from the same expressions, in the numpy path's
    # order of operations: equal bit for bit where the elementary functions
    # agree; asserted to 1e-14 of the largest entry of each half.
    model = _model(case.id)
    n = model.n_dof
    rhs = _compiled(case.id)
    assert rhs is not None
    Y = _states(case)
    perm = np.random.default_rng(2).permutation(2 * n)
    # CVODE's permuted form is one more compiled entry point per structure:
    # checked on a chain, a network and a potential (its text is the same wrapper).
    permuted = rhs.permuted(perm) if case.id in ("chain-case1", "network-2d", "henon-heiles") else None
    for j in range(Y.shape[1]):
        y = np.ascontiguousarray(Y[:, j])
        want = model.rhs(0.0, y)
        _assert_rhs_close(rhs(0.0, y), want, n)
        got, bad = rhs.checked(y)
        assert not bad
        _assert_rhs_close(got, want, n)
        if permuted is None:
            continue
        zp = np.full(2 * n, np.nan)
        assert not permuted(np.ascontiguousarray(y[perm]), zp)
        back = np.empty(2 * n)
        back[perm] = zp
        _assert_rhs_close(back, want, n)
    # and the vectorised numpy rhs is the one-state rhs
    np.testing.assert_array_equal(model.rhs(0.0, Y), np.stack([model.rhs(0.0, Y[:, j]) for j in range(Y.shape[1])],
                                                               axis=1))


# -- 4. heyoka's equations ----------------------------------------------------------------
def _power_of_two(x):
    return 2.0 ** round(math.log2(x))


@pytest.mark.parametrize("case", CASES, ids=IDS)
def test_heyoka_rhs_equals_numpy_rhs(case):
    import heyoka as hy

    from rk4h.references.solvers.taylor import scaled_system

    model = _model(case.id)
    n = model.n_dof
    Y = _states(case)
    want = model.rhs(0.0, Y)
    vs, exprs = model.heyoka_system()
    got = hy.cfunc(exprs, vs)(Y)
    _assert_rhs_close(got, want, n)
    # What the Taylor solver integrates: z = y / s, par = [s_q, s_v, masses...]
    # per state (batch column). Scales that are powers of two make z = y / s and
    # y = s z exact, so the comparison sees the equations, not the rescaling.
    zs, system = scaled_system(model)
    assert [v for v, _ in system] == list(zs)
    s_q, s_v = _power_of_two(case.scale), _power_of_two(_velocity_scale(case))
    s = np.concatenate([np.full(n, s_q), np.full(n, s_v)])
    pars = np.concatenate([[s_q, s_v], model.mass])
    cf = hy.cfunc([e for _, e in system], zs)
    assert cf.nparams == 2 + n
    got_scaled = cf(Y / s[:, None], pars=np.repeat(pars[:, None], Y.shape[1], axis=1)) * s[:, None]
    _assert_rhs_close(got_scaled, want, n)


# -- 5. modes of the linear models --------------------------------------------------------
@pytest.mark.parametrize("case", LINEAR_CASES, ids=[c.id for c in LINEAR_CASES])
def test_modes_are_the_generalized_eigenproblem(case):
    from scipy.linalg import eigh

    model = _model(case.id)
    K = np.asarray(model.stiffness_matrix(), dtype=float)
    M = np.diag(model.mass)
    w, phi = model.modes()
    lam, vec = eigh(K, M)
    lam_max = np.max(np.abs(lam))
    # frequencies: omega^2 to 1e-12 of the largest (zero modes are zeroed by modes()),
    # non-zero omega to 1e-12 relative
    np.testing.assert_allclose(w ** 2, lam, rtol=0, atol=1e-12 * lam_max)
    nz = lam > 1e-10 * lam_max
    np.testing.assert_allclose(w[nz], np.sqrt(lam[nz]), rtol=1e-12, atol=0)
    assert np.all(np.diff(w) >= 0.0)
    # mass-normalised eigenvectors of K phi = omega^2 M phi
    np.testing.assert_allclose(phi.T @ M @ phi, np.eye(model.n_dof), rtol=0, atol=1e-12)
    scale = np.max(np.abs(K @ phi))
    np.testing.assert_allclose(K @ phi, M @ phi * w ** 2, rtol=0, atol=1e-12 * scale)
    # shapes up to sign: phi phi^T over each group of equal frequencies (one mode:
    # the sign drops out; a degenerate pair: any basis of its plane)
    groups = np.split(np.arange(lam.size), np.flatnonzero(np.diff(lam) > 1e-8 * lam_max) + 1)
    for g in groups:
        P, P_ref = phi[:, g] @ phi[:, g].T, vec[:, g] @ vec[:, g].T
        np.testing.assert_allclose(P, P_ref, rtol=0, atol=1e-12 * np.max(np.abs(P_ref)))


# -- 6. generated straight-line loop and the generic numpy path ----------------------------
_TRANSCENDENTAL = ("math.sin", "math.cos", "math.tan", "math.exp", "math.log")


@pytest.mark.parametrize("case", STRAIGHT_LINE_CASES, ids=[c.id for c in STRAIGHT_LINE_CASES])
def test_generated_loop_equals_the_numpy_path(case):
    # The straight-line loop does RK4's arithmetic in rk_step's order on force
    # code printed in the numpy path's order: the same numbers, bit for bit,
    # where only + - * / sqrt (correctly rounded everywhere) are involved; with
    # sin/cos/exp/log, numpy's and libm's may differ in the last bit.
    import rk4h
    from rk4h.fast import codegen
    from rk4h.fast.solve import _loop_of
    from rk4h.methods import RK4

    model = _model(case.id)
    kern = fast.force_kernel(model)
    # solve_model runs the straight-line loop (up to 8 degrees of freedom and
    # a force of at most codegen.MAX_UNROLLED_FORCE_LINES lines: every case here)
    assert _loop_of(model, "rk4") is codegen.kernel(RK4, kern)
    y0 = np.ascontiguousarray(_states(case, m=1, seed=3)[:, 0])
    n, step = 200, 0.1 / model.omega_bound()  # h omega <= 0.1: a stable, accurate run
    t_eval = np.array([0.0, 0.37, 0.5, 0.999, 1.0]) * n * step  # on and off the grid (Hermite)
    kw = dict(n_steps=n, t_eval=t_eval)
    res = fast.solve_model(model, (0.0, n * step), y0, **kw)
    gen = rk4h.solve(model.rhs, (0.0, n * step), y0, **kw)
    assert res.success and gen.success and res.nfev == gen.nfev
    assert np.all(np.isfinite(gen.y)) and not np.array_equal(gen.y[:, -1], y0)
    hoisted, body = kern.scalar_lines([f"q{i}" for i in range(kern.n_dof)], [f"f{i}" for i in range(kern.n_dof)])
    if any(f in line for line in hoisted + body for f in _TRANSCENDENTAL):
        np.testing.assert_allclose(res.y, gen.y, rtol=0, atol=1e-14 * np.max(np.abs(gen.y)))
    else:
        np.testing.assert_array_equal(res.y, gen.y)


# -- 7. FPUT with alpha = beta = 0 is the linear chain -------------------------------------
WALLS = ["both", "left", "right", "none"]
_N_SPRINGS = {"both": 6, "left": 5, "right": 5, "none": 4}


def _chain_pair(walls):
    rng = np.random.default_rng(4)
    masses, springs = list(rng.uniform(0.5, 2.0, 5)), list(rng.uniform(1.0, 3.0, _N_SPRINGS[walls]))
    return Chain(masses, springs, walls=walls), Chain(masses, springs, walls=walls, alpha=0.0, beta=0.0)


@pytest.mark.parametrize("walls", WALLS)
def test_fput_with_zero_anharmonicity_is_the_linear_chain_bit_for_bit(walls):
    linear, zero = _chain_pair(walls)
    assert zero.linear and zero.params() == linear.params()
    Y = np.random.default_rng(5).normal(scale=0.3, size=(2 * linear.n_dof, 5))
    np.testing.assert_array_equal(zero.rhs(0.0, Y), linear.rhs(0.0, Y))
    a, b = fast.compiled_rhs(linear), fast.compiled_rhs(zero)
    assert fast.force_kernel(zero).key() == fast.force_kernel(linear).key()
    for j in range(Y.shape[1]):
        y = np.ascontiguousarray(Y[:, j])
        np.testing.assert_array_equal(b(0.0, y), a(0.0, y))
        np.testing.assert_array_equal(b(0.0, y), linear.rhs(0.0, y))


@pytest.mark.parametrize("walls", WALLS)
def test_fput_template_with_zero_coefficients_is_the_harmonic_tension(walls):
    # The general (anharmonic) form of the one spring-energy template, with
    # alpha = beta = 0 as numbers rather than substituted away: numpy's
    # tension and the compiled FPUT kernel give the linear chain bit for bit.
    from rk4h.fast.solve import CompiledRHS
    from rk4h.models.compiled import ChainKernel
    from rk4h.models.network import spring_tension

    linear, _ = _chain_pair(walls)
    rng = np.random.default_rng(6)
    r = rng.normal(scale=0.3, size=50)
    np.testing.assert_array_equal(spring_tension(r, 2.7, 0.0, 0.0), 2.7 * r)
    kern = ChainKernel(linear.k, 0.0, 0.0, linear._left, linear._right, linear=False)
    assert kern.key() != fast.force_kernel(linear).key()  # the anharmonic text, not the harmonic one
    general = CompiledRHS(linear, kern)
    for _ in range(5):
        y = rng.normal(scale=0.3, size=2 * linear.n_dof)
        np.testing.assert_array_equal(general(0.0, y), linear.rhs(0.0, y))


# -- fast.supports ---------------------------------------------------------------------------
@pytest.mark.parametrize("case", CASES, ids=IDS)
def test_supports_every_case_but_not_a_subclass_overriding_the_force(case):
    model = _model(case.id)
    assert fast.supports(model)

    class Tweaked(type(model)):
        def _force(self, q, ops):  # a change the kernel printed from the definition does not know
            return 2.0 * super()._force(q, ops)

    tweaked = Tweaked(**model.params())
    q = _coordinates(case, m=1)[:, 0]
    np.testing.assert_array_equal(tweaked.force(q), 2.0 * model.force(q))
    assert not fast.supports(tweaked)
    assert fast.force_kernel(tweaked) is None and fast.compiled_rhs(tweaked) is None
