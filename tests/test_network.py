"""The `network` model: masses, anchors and springs with exact geometry.

`triangle`, `planar4` and a walled `chain` are special cases: the network
must equal them on states and trajectories (docs/user-guide.md; 1e-13). Force, Hessian
and the heyoka system are derived from one spring-energy expression.
"""
import math

import numpy as np
import pytest

import rk4h
from rk4h.models import Chain, Network, Planar4, Triangle

A = 0.3  # triangle side (m)
L = 0.5  # planar4 anchor distance (m)


def triangle_pair():
    net = Network(2, [1.2] * 3, [0, 0, A, 0, A / 2, A * math.sqrt(3) / 2],
                  [[0, 1, 40.0], [1, 2, 40.0], [0, 2, 40.0]])
    return Triangle(1.2, 40.0, A), net, 0.02


def planar4_pair():
    net = Network(2, [0.815], [0.0, 0.0], [[0, 1, 41.5], [0, 2, 41.5], [0, 3, 41.5], [0, 4, 41.5]],
                  anchors=[-L, 0.0, L, 0.0, 0.0, -L, 0.0, L])
    return Planar4(0.815, 41.5, L), net, 0.1


def chain_pair():
    net = Network(1, [0.815, 3.099], [0.0, 1.0], [[2, 0, 41.5], [0, 1, 138.0], [1, 3, 157.8]],
                  anchors=[-1.0, 2.0])
    return Chain([0.815, 3.099], [41.5, 138.0, 157.8]), net, 0.01


PAIRS = {"triangle": triangle_pair, "planar4": planar4_pair, "walled-chain": chain_pair}


def _states(n, scale, m=5, seed=0):
    return np.random.default_rng(seed).normal(scale=scale, size=(n, m))


@pytest.mark.parametrize("case", PAIRS)
def test_network_equals_the_special_case_on_states(case):
    model, net, scale = PAIRS[case]()
    Q = _states(model.n_dof, scale)
    F, Fn = model.force(Q), net.force(Q)
    np.testing.assert_allclose(Fn, F, rtol=0, atol=1e-13 * np.max(np.abs(F)))
    V, Vn = model.potential(Q), net.potential(Q)
    np.testing.assert_allclose(Vn, V, rtol=0, atol=1e-13 * np.max(np.abs(V)))
    K = np.asarray(model.stiffness_matrix(), float)
    np.testing.assert_allclose(net.stiffness_matrix(), K, rtol=0, atol=1e-13 * np.max(np.abs(K)))


@pytest.mark.parametrize("case", PAIRS)
def test_network_equals_the_special_case_on_trajectories(case):
    model, net, scale = PAIRS[case]()
    y0 = np.concatenate([_states(model.n_dof, scale, m=1, seed=3)[:, 0], np.zeros(model.n_dof)])
    t = np.linspace(0.0, 2.0, 201)
    a = rk4h.solve(model.rhs, (0.0, 2.0), y0, h=0.001, t_eval=t)
    b = rk4h.solve(net.rhs, (0.0, 2.0), y0, h=0.001, t_eval=t)
    assert a.success and b.success
    np.testing.assert_allclose(b.y, a.y, rtol=0, atol=1e-13 * np.max(np.abs(a.y)) * 10)


@pytest.mark.parametrize("case", PAIRS)
def test_force_is_minus_the_gradient_and_hessian_the_force_derivative(case):
    _, net, scale = PAIRS[case]()
    q = _states(net.n_dof, scale, m=1, seed=7)[:, 0]
    d = 1e-6 * max(scale, 1e-3)
    E = np.eye(net.n_dof) * d
    grad = np.array([(net.potential(q + e) - net.potential(q - e)) / (2 * d) for e in E])
    np.testing.assert_allclose(net.force(q), -grad, rtol=1e-6, atol=1e-8 * np.max(np.abs(grad)))
    z = np.zeros(net.n_dof)
    H = -np.array([(net.force(z + e) - net.force(z - e)) / (2 * d) for e in E]).T
    np.testing.assert_allclose(net.stiffness_matrix(), H, rtol=1e-6, atol=1e-6 * np.max(np.abs(H)))


@pytest.mark.parametrize("case", PAIRS)
def test_heyoka_and_numpy_right_hand_sides_agree(case):
    import heyoka as hy

    _, net, scale = PAIRS[case]()
    vs, rhs = net.heyoka_system()
    cf = hy.cfunc(rhs, vs)
    Y = np.concatenate([_states(net.n_dof, scale, m=6, seed=11), _states(net.n_dof, 1.0, m=6, seed=12)])
    got = cf(Y)
    want = np.stack([net.rhs(0.0, Y[:, j]) for j in range(Y.shape[1])], axis=1)
    np.testing.assert_allclose(got, want, rtol=1e-14, atol=1e-14 * np.max(np.abs(want)))


def test_a_prestressed_spring_adds_the_geometric_stiffness():
    # one mass between two anchors 1 m away each side, springs of rest 0.5 m: tension
    # k (1 - 0.5) along x; transverse stiffness 2 T / L = 2 * 10 * 0.5 / 1 = 10 N/m
    net = Network(2, [1.0], [0.0, 0.0], [[0, 1, 10.0, 0.5], [0, 2, 10.0, 0.5]], anchors=[-1.0, 0.0, 1.0, 0.0])
    np.testing.assert_allclose(net.stiffness_matrix(), [[20.0, 0.0], [0.0, 10.0]], rtol=1e-15)


BAD = [
    ("missing-node", dict(springs=[[0, 5, 1.0]]), "`springs[0][1]` must be a node index in 0..2"),
    ("self-loop", dict(springs=[[1, 1, 1.0]]), "`springs[0]` joins node 1 to itself"),
    ("two-anchors", dict(springs=[[0, 2, 1.0], [2, 2, 1.0]]), "joins node 2 to itself"),
    ("duplicate", dict(springs=[[0, 2, 1.0], [2, 0, 1.0]]), "a second time"),
    ("negative-k", dict(springs=[[0, 2, -1.0]]), "`springs[0][2]` (k) must be a finite number > 0"),
    ("coincident-nodes", dict(positions=[0.0, 0.0, 0.0, 0.0], springs=[[0, 1, 1.0], [0, 2, 1.0]]),
     "coincide at the reference positions"),
    ("bad-dim", dict(dim=3), "`dim` must be 1 or 2"),
    ("positions-length", dict(positions=[0.0, 0.0, 1.0]), "`positions` must hold 2 numbers per point"),
    ("mass-count", dict(masses=[1.0, 1.0, 1.0]), "`positions` must hold 6 numbers"),
    ("string-spring", dict(springs=["a"]), "`springs[0]` must be [a, b, k]"),
    ("tiny-mass", dict(masses=[5e-324, 1.0]), "`masses[0]`"),
]


@pytest.mark.parametrize("case, change, says", BAD, ids=[b[0] for b in BAD])
def test_bad_network_is_refused_naming_the_field(case, change, says):
    params = dict(dim=2, masses=[1.0, 1.0], positions=[0.0, 0.0, 1.0, 0.0], springs=[[0, 1, 1.0], [1, 2, 1.0]],
                  anchors=[2.0, 0.0])
    params.update(change)
    with pytest.raises(ValueError) as info:
        rk4h.make_model("network", params)
    assert says in str(info.value) and "\n" not in str(info.value), str(info.value)
