"""Eq. 2.31 at extreme mass ratios: the closed form against the eigenproblem,
an independent 50-digit evaluation, and the mu -> 0 / mu -> infinity limits.

Two masses ``m1``, ``m2 = mu m1`` between walls on three springs ``k``. In units
``k/m2``, eq. 2.31 reads ``lam = mu + 1 -+ sqrt(mu^2 - mu + 1)``. Expanding the
root (``m1`` fixed):

* ``mu -> 0``: ``omega_low^2 = (3k / 2m1) (1 - mu/4 + O(mu^2))`` (the light mass
  follows quasi-statically: springs k2, k3 in series with k1),
  ``omega_high^2 = (2k / m2) (1 + mu/4 + O(mu^2))``;
* ``mu -> inf``: ``omega_low^2 = (3k / 2m2) (1 - 1/(4mu) + O(mu^-2))``,
  ``omega_high^2 = (2k / m1) (1 + 1/(4mu) + O(mu^-2))``.

Written as printed, the minus root loses ``log10(1/mu)`` (or ``log10 mu``)
digits to cancellation: about 1e-10 relative at ``mu = 1e-6`` or ``1e6``,
which the ``O(mu^2)`` remainder (1e-12) exposes.
"""
from __future__ import annotations

import decimal
import math

import numpy as np

__all__ = ["omega_sq_decimal", "omega_sq_eig", "omega_sq_limits", "omega_sq_naive", "closed_form_sq"]


def omega_sq_decimal(k: float, m1: float, mu: float, digits: int = 50):
    """``(omega_low^2, omega_high^2)`` from eq. 2.31 as printed, evaluated in
    ``digits``-digit decimal arithmetic (cancellation is harmless there)."""
    ctx = decimal.Context(prec=digits)
    D = lambda x: decimal.Decimal(repr(float(x)))  # noqa: E731 - exact binary value
    k_, m1_, mu_ = D(k), D(m1), D(mu)
    m2 = ctx.multiply(m1_, mu_)
    unit = ctx.divide(k_, m2)
    s = ctx.sqrt(ctx.add(ctx.power(ctx.subtract(mu_, 1), 2), mu_))
    lo = ctx.multiply(unit, ctx.subtract(ctx.add(mu_, 1), s))
    hi = ctx.multiply(unit, ctx.add(ctx.add(mu_, 1), s))
    return float(lo), float(hi)


def omega_sq_naive(k: float, m1: float, mu: float):
    """Eq. 2.31 exactly as printed, in double precision (cancels for the minus root)."""
    m2 = m1 * mu
    s = math.sqrt((mu - 1) ** 2 + mu)
    return k / m2 * (mu + 1 - s), k / m2 * (mu + 1 + s)


def omega_sq_eig(k: float, m1: float, mu: float):
    """Squared frequencies from ``K phi = omega^2 M phi`` of the chain model."""
    from rk4h.models import Chain

    omega, _ = Chain([m1, m1 * mu], [k, k, k]).modes()
    return float(omega[0] ** 2), float(omega[1] ** 2)


def omega_sq_limits(k: float, m1: float, mu: float):
    """The two-term expansions above; valid for ``mu << 1`` or ``mu >> 1``."""
    m2 = m1 * mu
    if mu < 1:
        return 1.5 * k / m1 * (1 - mu / 4), 2 * k / m2 * (1 + mu / 4)
    return 1.5 * k / m2 * (1 - 1 / (4 * mu)), 2 * k / m1 * (1 + 1 / (4 * mu))


def closed_form_sq(k: float, m1: float, mu: float):
    """``rk4h.references.closed_forms.two_dof_equal_k`` squared: (low, high)."""
    from rk4h.references.closed_forms import two_dof_equal_k

    lo, hi = two_dof_equal_k(k, m1=m1, mu=mu)
    return float(lo) ** 2, float(hi) ** 2
