"""The absolute-tolerance rule shared by the adaptive solvers.

An adaptive solver is given a relative tolerance ``rtol``. Unless the caller
passes ``atol``, the absolute tolerance of state component ``i`` is

    atol_i = rtol * s_i,

with one scale for all positions and one for all velocities, taken from the
initial state ``y0 = [q0, v0]`` and the model's fastest linearised frequency:

    s_q = max(max_i |q0_i|, max_i |v0_i| / w),
    s_v = max(max_i |v0_i|, w * max_i |q0_i|),

where ``w`` is the Gershgorin upper bound ``sqrt(max_i sum_j |K_ij| / m_i)``
on the largest natural angular frequency (rad/s) of the linearization
(``K = model.stiffness_matrix()``, the Hessian of V at 0). ``s_q`` is thus the
largest displacement the initial state can produce in the linear limit (up to
the bound on ``w``) and ``s_v`` the largest velocity, so a state measured in
millimetres is judged relative to millimetres, not absolutely against 1 m.
A scale that comes out 0 (``y0 = 0``) falls back to 1.

heyoka has a single tolerance, absolute where ``max_i |x_i| < 1`` and relative
above. It integrates the scaled state ``z = y / s`` (``s = [s_q]*n + [s_v]*n``)
with ``tol = rtol``, which is the same rule: ``|z| <= 1`` at the start, so its
absolute error per step is ``rtol * s_i`` in the original units.
"""
from __future__ import annotations

import numpy as np

__all__ = ["omega_bound", "group_scales", "scales_from", "state_scale", "absolute_tolerance"]


def omega_bound(model) -> float:
    """Gershgorin upper bound (rad/s) on the model's largest linearised natural
    angular frequency: ``sqrt(max_i sum_j |K_ij| / m_i)``. O(nnz(K)) for a chain
    (:meth:`rk4h.models.Model.omega_bound`)."""
    return model.omega_bound()


def group_scales(model, y0) -> tuple[float, float]:
    """``(s_q, s_v)``: the position and velocity scales of the rule above.
    A first-order model (``model.first_order``: no positions, velocities or
    frequencies) has one scale for its whole state, ``s = max_i |y0_i|``
    (1 when it is 0), returned twice."""
    y0 = np.asarray(y0, dtype=float)
    if getattr(model, "first_order", False):
        s = float(np.abs(y0).max()) if y0.size else 0.0
        s = s if s > 0.0 else 1.0
        return s, s
    n = model.n_dof
    aq = float(np.abs(y0[:n]).max())
    av = float(np.abs(y0[n:]).max())
    return scales_from(aq, av, omega_bound(model))


def scales_from(aq: float, av: float, w: float) -> tuple[float, float]:
    """``(s_q, s_v)`` of :func:`group_scales` from ``aq = max_i |q0_i|`` (m),
    ``av = max_i |v0_i|`` (m/s) and the frequency bound ``w`` (rad/s,
    :func:`omega_bound`): for a caller that keeps ``w`` (the fixed-step short
    path), the same operations, so the same numbers bit for bit."""
    if w > 0.0:
        s_q, s_v = max(aq, av / w), max(av, w * aq)
    else:
        s_q, s_v = aq, av
    return (s_q if s_q > 0.0 else 1.0), (s_v if s_v > 0.0 else 1.0)


def state_scale(model, y0) -> np.ndarray:
    """Per-component scale ``s`` (shape (2 n_dof,)): ``s_q`` then ``s_v``."""
    s_q, s_v = group_scales(model, y0)
    if getattr(model, "first_order", False):
        return np.full(np.asarray(y0).shape[0], s_q)
    n = model.n_dof
    s = np.empty(2 * n)
    s[:n] = s_q
    s[n:] = s_v
    return s


def absolute_tolerance(model, y0, rtol: float) -> np.ndarray:
    """``atol_i = rtol * s_i`` (state units), shape (2 n_dof,)."""
    return rtol * state_scale(model, y0)
