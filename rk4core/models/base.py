"""The model base class: one definition of the mechanics feeds every solver.

A model is a set of generalized coordinates ``q`` (length ``n_dof``) with a
*diagonal* generalized mass ``mass`` (kg, or kg m^2 for angles) and a potential
``V(q)`` (J). Its equations of motion are ``mass * q'' = F(q)`` with
``F = -grad V``. The first-order state is ``y = [q, v]`` (length ``2 n_dof``).

Each concrete model writes ``_potential(q, ops)`` and ``_force(q, ops)`` once,
in terms of array operations and ``ops.sqrt / ops.sin / ops.cos``. The same
code is evaluated

* with ``ops = NUMPY`` on float arrays ``q`` of shape ``(n_dof,)`` or
  ``(n_dof, m)`` (vectorised over ``m`` states) -- the right-hand side that
  RK4, DOP853 and CVODE see;
* with ``ops = HEYOKA`` on an object array of heyoka expressions -- the
  equations heyoka's Taylor integrator compiles.

So every solver integrates the same equations; ``tests`` check that the force
is minus the gradient of the potential and that both evaluations agree.
"""
from __future__ import annotations

from typing import ClassVar

import numpy as np

__all__ = ["Model", "NUMPY", "HEYOKA", "Ops"]


class Ops:
    """Elementary functions for one evaluation backend."""

    def __init__(self, name, sqrt, sin, cos):
        self.name, self.sqrt, self.sin, self.cos = name, sqrt, sin, cos

    def __repr__(self):
        return f"Ops({self.name})"


NUMPY = Ops("numpy", np.sqrt, np.sin, np.cos)


def _heyoka_ops():
    import heyoka as hy

    vec = lambda f: np.frompyfunc(f, 1, 1)  # noqa: E731 - elementwise over object arrays
    return Ops("heyoka", vec(hy.sqrt), vec(hy.sin), vec(hy.cos))


class _LazyOps:
    _ops = None

    def __getattr__(self, item):
        if _LazyOps._ops is None:
            _LazyOps._ops = _heyoka_ops()
        return getattr(_LazyOps._ops, item)


HEYOKA = _LazyOps()


class Model:
    """Base class of the mass-spring models.

    Subclasses set ``name``, ``linear``, ``n_dof``, ``mass`` (ndarray, shape
    (n_dof,)), ``coord_names`` and implement ``_potential`` and ``_force``.
    Linear models (and nonlinear ones, for their small-oscillation limit)
    implement ``stiffness_matrix`` (the Hessian of V at q = 0).
    """

    name: ClassVar[str] = "model"
    #: True when the equations of motion are linear (``F = -K q``).
    linear: bool = False
    n_dof: int
    mass: np.ndarray
    coord_names: list[str]

    # -- to implement -----------------------------------------------------
    def _potential(self, q, ops):  # pragma: no cover - abstract
        raise NotImplementedError

    def _force(self, q, ops):  # pragma: no cover - abstract
        raise NotImplementedError

    def stiffness_matrix(self) -> np.ndarray:
        """Hessian of ``V`` at the equilibrium ``q = 0`` (N/m, or N m/rad)."""
        raise NotImplementedError(f"{self.name} has no stiffness matrix")

    def params(self) -> dict:
        """The parameters the model was built with (plain Python values)."""
        raise NotImplementedError

    # -- numpy evaluation ---------------------------------------------------
    @property
    def n_state(self) -> int:
        return 2 * self.n_dof

    def potential(self, q) -> np.ndarray | float:
        """Potential energy (J) of ``q`` with shape (n_dof,) or (n_dof, m)."""
        return self._potential(np.asarray(q, dtype=float), NUMPY)

    def force(self, q) -> np.ndarray:
        """Generalized force ``-grad V`` (N or N m) at ``q``, same shape as ``q``."""
        q = np.asarray(q, dtype=float)
        return np.asarray(self._force(q, NUMPY), dtype=float).reshape(q.shape)

    def acceleration(self, q) -> np.ndarray:
        q = np.asarray(q, dtype=float)
        f = self.force(q)
        return f / (self.mass if q.ndim == 1 else self.mass[:, None])

    def rhs(self, t, y) -> np.ndarray:
        """``dy/dt`` for ``y = [q, v]``; the ``fun(t, y)`` every solver integrates."""
        n = self.n_dof
        out = np.empty_like(y, dtype=float)
        out[:n] = y[n:]
        out[n:] = self.acceleration(y[:n])
        return out

    def energy(self, y) -> np.ndarray | float:
        """Total energy ``T + V`` (J) of ``y`` with shape (2 n_dof,) or (2 n_dof, m)."""
        y = np.asarray(y, dtype=float)
        n = self.n_dof
        q, v = y[:n], y[n:]
        m = self.mass if y.ndim == 1 else self.mass[:, None]
        return 0.5 * np.sum(m * v * v, axis=0) + self.potential(q)

    def jacobian(self, t=None, y=None) -> np.ndarray:
        """Jacobian of ``rhs`` (dense, shape (2n, 2n)).

        Linear models: exact and constant. Nonlinear models: central
        differences of the force (relative step 1e-6 of the state scale).
        """
        n = self.n_dof
        J = np.zeros((2 * n, 2 * n))
        J[:n, n:] = np.eye(n)
        if self.linear:
            J[n:, :n] = -self.stiffness_matrix() / self.mass[:, None]
        else:
            q = np.asarray(y[:n], dtype=float)
            eps = 1e-6 * max(1.0, float(np.max(np.abs(q))) if q.size else 1.0)
            E = np.eye(n) * eps
            dF = (self.force(q[:, None] + E) - self.force(q[:, None] - E)) / (2 * eps)
            J[n:, :n] = dF / self.mass[:, None]
        return J

    # -- heyoka evaluation --------------------------------------------------
    def heyoka_system(self):
        """``(vars, rhs_exprs)`` for ``heyoka.taylor_adaptive``: state ``[q, v]``.

        The masses are numeric constants here, and heyoka folds ``f / m`` into
        ``f * fl(1/m)`` with the reciprocal rounded to double: exact to an ulp in
        double precision, but a different mass (relative ~1e-17) in ``real128``.
        The solvers therefore integrate
        :func:`references.solvers.taylor.scaled_system`, which builds on the
        same ``_force`` and passes the masses as runtime parameters."""
        import heyoka as hy

        names = [f"q{i}" for i in range(self.n_dof)] + [f"v{i}" for i in range(self.n_dof)]
        vs = hy.make_vars(*names)
        vs = list(vs) if isinstance(vs, (list, tuple)) else [vs]
        q = np.array(vs[: self.n_dof], dtype=object)
        f = np.asarray(self._force(q, HEYOKA), dtype=object).reshape(-1)
        acc = [f[i] / float(self.mass[i]) for i in range(self.n_dof)]
        return vs, list(vs[self.n_dof:]) + acc

    def heyoka_energy(self, vs):
        """heyoka expression of the total energy, for the variables ``vs``."""
        q = np.array(vs[: self.n_dof], dtype=object)
        v = vs[self.n_dof:]
        T = sum(0.5 * float(self.mass[i]) * v[i] * v[i] for i in range(self.n_dof))
        return T + self._potential(q, HEYOKA)

    # -- linear analysis ----------------------------------------------------
    def modes(self):
        """Natural angular frequencies (rad/s, ascending) and mass-normalised
        mode shapes (columns) of the linearization: ``K phi = omega^2 M phi``."""
        from scipy.linalg import eigh

        K = np.asarray(self.stiffness_matrix(), dtype=float)
        lam, phi = eigh(K, np.diag(self.mass))
        scale = np.max(np.abs(lam)) if lam.size else 1.0
        lam = np.where(np.abs(lam) < 1e-12 * scale, 0.0, lam)  # zero modes stay zero
        return np.sqrt(np.clip(lam, 0.0, None)), phi

    def state(self, x, v=None) -> np.ndarray:
        """Flat state ``[q, v]`` from coordinates and velocities."""
        x = np.asarray(x, dtype=float)
        v = np.zeros_like(x) if v is None else np.asarray(v, dtype=float)
        return np.concatenate([x, v])

    def __repr__(self):
        args = ", ".join(f"{k}={v!r}" for k, v in self.params().items())
        return f"{type(self).__name__}({args})"
