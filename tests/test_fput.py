"""Fermi-Pasta-Ulam-Tsingou chains (`chain` with `alpha`/`beta`) and scalar
broadcast of uniform chains."""
import numpy as np
import pytest

import rk4h
from rk4h.references.solvers import integrate
from rk4h.models import Chain
from rk4h.validation.execute import modal_energies
from rk4h.validation.metrics import fit_order

N = 8


def fput(alpha=0.0, beta=0.0):
    return Chain(1.0, 1.0, n=N, alpha=alpha, beta=beta)


def _state(seed=0, scale=0.3):
    rng = np.random.default_rng(seed)
    return np.concatenate([rng.normal(scale=scale, size=N), rng.normal(scale=scale, size=N)])


def test_zero_anharmonicity_is_the_linear_chain_bit_for_bit():
    lin = Chain([1.0] * N, [1.0] * (N + 1))
    zero = fput()
    assert zero.linear and zero.params() == lin.params()
    y0 = _state()
    a = rk4h.solve(lin.rhs, (0.0, 20.0), y0, h=0.05)
    b = rk4h.solve(zero.rhs, (0.0, 20.0), y0, h=0.05)
    assert np.array_equal(a.y, b.y)


@pytest.mark.parametrize("alpha, beta", [(0.25, 0.0), (0.0, 1.0), (0.25, 1.0)], ids=["alpha", "beta", "both"])
def test_force_is_minus_the_gradient_and_heyoka_agrees(alpha, beta):
    import heyoka as hy

    m = fput(alpha, beta)
    assert not m.linear
    y = _state(seed=1)
    q = y[:N]
    d = 1e-6
    grad = np.array([(m.potential(q + d * e) - m.potential(q - d * e)) / (2 * d) for e in np.eye(N)])
    np.testing.assert_allclose(m.force(q), -grad, rtol=0, atol=1e-8)
    # by hand: tension k r + alpha r^2 + beta r^3 of every spring, walls at both ends
    u = np.concatenate([[0.0], q, [0.0]])
    r = np.diff(u)
    T = r + alpha * r ** 2 + beta * r ** 3
    np.testing.assert_allclose(m.force(q), T[1:] - T[:-1], rtol=1e-14, atol=1e-15)
    vs, rhs = m.heyoka_system()
    np.testing.assert_allclose(hy.cfunc(rhs, vs)(y), m.rhs(0.0, y), rtol=1e-14, atol=1e-15)


@pytest.mark.parametrize("alpha, beta", [(0.25, 0.0), (0.0, 1.0)], ids=["alpha", "beta"])
def test_rk4_is_fourth_order_on_fput(alpha, beta):
    m = fput(alpha, beta)
    y0 = _state(seed=2)
    T = 4.0
    t = np.linspace(0.0, T, 9)
    ref = integrate("heyoka", m, y0, t, 1e-15).y
    hs = [T / n for n in (64, 128, 256, 512)]
    errs = [np.max(np.abs(rk4h.solve(m.rhs, (0.0, T), y0, h=h, t_eval=t).y - ref)) for h in hs]
    fit = fit_order(hs, errs, float(np.max(np.abs(ref))))
    assert abs(fit.order - 4.0) <= 0.1, (fit.order, errs)


def test_modal_energies_sum_to_the_energy_of_a_linear_chain():
    m = fput()
    omega, phi = m.modes()
    y = _state(seed=3)[:, None]
    np.testing.assert_allclose(modal_energies(m, y, omega, phi).sum(), m.energy(y[:, 0]), rtol=1e-13)


@pytest.mark.parametrize("params, says", [
    ({"masses": 1.0, "springs": 1.0}, "`n` must be given when `masses` is one number"),
    ({"masses": [1.0, 2.0], "springs": 1.0, "n": 3}, "`n` = 3 disagrees with the 2 entries"),
    ({"masses": 1.0, "springs": 1.0, "n": 0}, "`n` must be an integer from 1 to 10^7"),
    ({"masses": 1.0, "springs": 1.0, "n": 2.5}, "`n` must be an integer"),
    ({"masses": 1.0, "springs": 1.0, "n": 3, "alpha": float("nan")}, "`alpha` must be a finite number"),
], ids=["no-n", "n-disagrees", "n-zero", "n-float", "alpha-nan"])
def test_bad_broadcast_or_coefficients_are_refused(params, says):
    with pytest.raises(ValueError) as info:
        rk4h.make_model("chain", params)
    assert says in str(info.value)


def test_scalar_broadcast_equals_the_spelled_out_chain():
    a = Chain(0.815, 41.5, n=100)
    b = Chain([0.815] * 100, [41.5] * 101)
    assert a.params() == b.params()
