"""Exact solutions of linear models by modal superposition.

For ``M q'' + K q = 0`` with ``K phi_j = omega_j^2 M phi_j`` (mass-normalised
``phi``), the modal coordinates ``eta = phi^T M q`` evolve independently:
``eta_j(t) = eta_j(0) cos(omega_j t) + eta_j'(0) sin(omega_j t) / omega_j``, and a
zero-frequency mode (a free chain's translation, the triangle's rigid motions)
moves uniformly: ``eta_j(t) = eta_j(0) + eta_j'(0) t``.
"""
from __future__ import annotations

import numpy as np

__all__ = ["ModalSolution", "modal_solution"]


class ModalSolution:
    """Exact trajectory of a linear(ized) model from ``y0 = [q0, v0]``.

    Call it with times ``t`` (shape (m,)) to get ``y`` of shape (2n, m).
    """

    def __init__(self, model, y0):
        y0 = np.asarray(y0, dtype=float)
        n = model.n_dof
        if y0.shape != (2 * n,):
            raise ValueError(f"`y0` must have length {2 * n} for {model.name}, got shape {y0.shape}")
        self.model = model
        self.omega, self.phi = model.modes()
        M = model.mass
        self.eta0 = self.phi.T @ (M * y0[:n])
        self.deta0 = self.phi.T @ (M * y0[n:])
        self.zero = self.omega == 0.0

    def modal(self, t):
        """Modal coordinates and velocities, shape (n, m) each."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        w = np.where(self.zero, 1.0, self.omega)[:, None]
        wt = w * t[None, :]
        c, s = np.cos(wt), np.sin(wt)
        e0, de0 = self.eta0[:, None], self.deta0[:, None]
        eta = np.where(self.zero[:, None], e0 + de0 * t, e0 * c + de0 * s / w)
        deta = np.where(self.zero[:, None], de0 + 0.0 * t, -e0 * w * s + de0 * c)
        return eta, deta

    def __call__(self, t) -> np.ndarray:
        eta, deta = self.modal(t)
        return np.vstack([self.phi @ eta, self.phi @ deta])


def modal_solution(model, y0) -> ModalSolution:
    """Exact solution of the linear model (or of a model's linearization)."""
    return ModalSolution(model, y0)
