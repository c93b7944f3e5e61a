"""Any first-order ODE ``y' = f(t, y)``: typed as text (scene ``model = "ode"``)
or given as a plain Python function.

Scene key ``ode`` (``[params]``):

* ``variables`` -- list of distinct names (at most :data:`MAX_VARIABLES`),
  the state ``y`` in this order; ``t`` is the time and may not be one;
* ``equations`` -- one expression per variable, ``dy_i/dt``, in the grammar
  of :mod:`rk4h.expr` (numbers, the variables, ``t``, the constants,
  ``+ - * / ** ^``, parentheses, ``sin cos tan sinh cosh tanh exp log
  sqrt``), parsed by the harness's own parser, never by ``eval``;
* ``constants`` -- optional table of named numbers used in the texts;
* ``invariant`` -- optional expression ``I(y)`` (of the variables and the
  constants) that the exact flow conserves: its drift is measured as a
  conservative model's energy is;
* ``exact`` -- optional list, one expression of ``t`` (and the constants)
  per variable: the exact solution from the scene's initial state (it is
  checked against ``[initial] y`` at ``t = 0``, to 1e-12 relative).

In a scene the initial state is ``[initial] y`` (one number per variable).

The state is ``y`` itself (:attr:`first_order` is True): there are no
positions and velocities, no masses, no potential and no normal modes.
What the harness does with a mechanical model's energy it does with the
invariant: ``energy(y)`` is ``I(y)``, and a relative drift is
``max_t |I(t) - I0| / |I0|`` (absolute where ``I0 = 0``), since an arbitrary
invariant has no rest state to measure a "motion" from. Without an
invariant ``energy`` is NaN.

:class:`FunctionOde` wraps a plain ``fun(t, y)`` (scipy's convention) with
an optional ``exact(t)`` and ``invariant(y)``; it is what
``rk4h.references.solvers.integrate(solver, fun, ...)`` builds from a callable.
"""
from __future__ import annotations

import math
from functools import partial

import numpy as np

from .. import expr as ex
from ..validate import short
from .base import Model
from .params import Param
from .potential import check_constants, check_names

__all__ = ["OdeModel", "FunctionOde", "MAX_VARIABLES", "EXACT_Y0_RTOL"]

#: Most variables a typed ODE may have.
MAX_VARIABLES = 100
#: Relative agreement (of max |y0|) required between ``exact`` at t = 0 and ``y0``.
EXACT_Y0_RTOL = 1e-12


_short = partial(short, limit=60)


class _FirstOrder(Model):
    """What every first-order model shares: the state is ``y`` (length
    ``n_dof``, here the number of variables), unit "masses" so that code
    written for mechanical models finds the attribute, no modes."""

    #: The state is y itself, not [q, v].
    first_order = True
    linear = False

    def _setup(self, names):
        self.n_dof = len(names)
        self.coord_names = list(names)
        self.mass = np.ones(self.n_dof)

    @property
    def n_state(self) -> int:
        return self.n_dof

    def _potential(self, q, ops):
        raise NotImplementedError(f"model {self.name!r} is a first-order ODE: it has no potential")

    def _force(self, q, ops):
        raise NotImplementedError(f"model {self.name!r} is a first-order ODE: it has no force")

    def omega_bound(self) -> float:
        raise NotImplementedError(f"model {self.name!r} is a first-order ODE: it has no linearised frequencies")

    def state(self, x, v=None) -> np.ndarray:
        """The state ``y`` (``v`` must be None: there are no velocities)."""
        if v is not None:
            raise ValueError(f"`v`: model {self.name!r} is a first-order ODE; give the state y alone")
        return np.asarray(x, dtype=float).copy()

    def exact_solution(self, t):
        """The exact ``y`` at times ``t``, shape (n, m), or None when not known."""
        return None

    def has_invariant(self) -> bool:
        return False

    def energy(self, y):
        """The invariant ``I(y)`` of states ``y`` (shape (n,) or (n, m)); NaN without one."""
        y = np.asarray(y, dtype=float)
        return np.full(y.shape[1:], np.nan) if y.ndim > 1 else np.float64(np.nan)

    def jacobian(self, t=None, y=None) -> np.ndarray:
        """Jacobian of ``rhs`` at ``(t, y)`` by central differences (relative
        step 1e-6 of the state scale), shape (n, n)."""
        y = np.asarray(y, dtype=float)
        n = y.shape[0]
        eps = 1e-6 * max(1.0, float(np.max(np.abs(y))) if n else 1.0)
        J = np.empty((n, n))
        for j in range(n):
            e = np.zeros(n)
            e[j] = eps
            J[:, j] = (np.asarray(self.rhs(t, y + e), float) - np.asarray(self.rhs(t, y - e), float)) / (2 * eps)
        return J

    def rate(self, y0, t0: float = 0.0) -> float:
        """A characteristic rate (1/s) of the flow at ``(t0, y0)``: the
        spectral radius of the Jacobian there; NaN when it is 0 or not finite.
        It stands for a mechanical model's fastest angular frequency where a
        step must be made dimensionless (``theta = rate * h`` of the
        convergence sweeps)."""
        with np.errstate(all="ignore"):
            try:
                lam = np.linalg.eigvals(self.jacobian(t0, y0))
            except Exception:  # noqa: BLE001 - no rate: the caller falls back
                return math.nan
        r = float(np.max(np.abs(lam))) if lam.size else math.nan
        return r if math.isfinite(r) and r > 0 else math.nan

    def state_problem(self, y, t=None) -> str | None:
        """Why ``y`` is no state to start from (wrong shape, not finite, the
        invariant not finite there and, when the time ``t`` (s) is given,
        the right-hand side not finite or of the wrong shape at ``(t, y)``),
        or None. Without ``t`` the right-hand side is not called: it is
        never evaluated at a time outside the caller's span."""
        y = np.asarray(y, dtype=float)
        n = self.n_dof
        if y.shape != (n,):
            return f"it has shape {y.shape}, not ({n},)"
        if not np.all(np.isfinite(y)):
            return "it is not finite"
        with np.errstate(all="ignore"):
            try:
                f = np.zeros(n) if t is None else np.asarray(self.rhs(float(t), y), dtype=float).reshape(-1)
                inv = float(self.energy(y))
            except Exception as exc:  # noqa: BLE001 - any failure at y0 is a refusal naming y0
                text = " ".join(str(exc).split())[:200]
                return f"evaluating the right-hand side or the invariant raised {type(exc).__name__}: {text}"
        if f.shape != (n,):
            return f"the right-hand side has shape {f.shape} there, not ({n},)"
        bad = np.flatnonzero(~np.isfinite(f))
        if bad.size:
            return f"the right-hand side is not finite there (d{self.coord_names[bad[0]]}/dt = {float(f[bad[0]])!r})"
        if self.has_invariant() and not math.isfinite(inv):
            return f"the invariant is not finite there ({inv!r})"
        return None

    def check_state(self, y, name: str = "y0") -> np.ndarray:
        problem = self.state_problem(y)
        if problem is not None:
            shown = np.array2string(np.asarray(y, dtype=float).ravel(), precision=6, max_line_width=10**6,
                                    threshold=12, separator=", ")
            raise ValueError(f"`{name}` must be a state of {self.name} with a finite right-hand side: "
                             f"{problem}, got {shown}")
        return np.asarray(y, dtype=float)


class OdeModel(_FirstOrder):
    """A first-order ODE typed as text (see the module docstring).

    Parameters
    ----------
    variables : list of str
        Names of the state components (not ``t``).
    equations : list of str
        ``dy_i/dt`` for each variable, in the variables, ``t`` and ``constants``.
    constants : mapping of str to float, optional
        Named finite numbers.
    invariant : str, optional
        A conserved quantity ``I(y)`` of the variables and constants.
    exact : list of str, optional
        The exact solution, one expression of ``t`` per variable.

    Example (Lotka-Volterra)::

        OdeModel(["u", "v"], ["a*u - b*u*v", "-c*v + d*u*v"],
                 {"a": 1.5, "b": 1.0, "c": 3.0, "d": 1.0},
                 invariant="d*u - c*log(u) + b*v - a*log(v)")
    """

    name = "ode"
    summary = ("Any first-order ODE typed as text: dy/dt = f(t, y) over named variables (parsed by rk4h.expr, "
               "never eval'd); the initial state is `[initial] y`.")
    parameters = (
        Param("variables", "list[str]", "-", "names of the state components, in order (not `t`: the time)",
              ["u", "v"], min_length=1, max_length=MAX_VARIABLES),
        Param("equations", "list[str]", "state units/s", "dy/dt of each variable, in the variables, `t` and "
              "`constants`: numbers, names, + - * / ^, sin cos tan sinh cosh tanh exp log sqrt", ["v", "-u"],
              min_length=1, max_length=MAX_VARIABLES),
        Param("constants", "dict[str,finite]", "-", "named numbers used in the expressions", {"w": 1.0},
              default=None),
        Param("invariant", "str", "-", "a quantity I(y) the exact flow conserves; its drift is measured like "
              "energy, max |I(t) - I0| / |I0|", "u^2 + v^2", default=None,
              default_text="none (no energy column)"),
        Param("exact", "list[str]", "state units", "the exact solution from `[initial] y`, one expression of t "
              "per variable; the truth when given", ["cos(t)", "-sin(t)"], default=None, min_length=1,
              max_length=MAX_VARIABLES, default_text="none (two references that agree)"),
    )

    def __init__(self, variables, equations, constants=None, invariant=None, exact=None):
        names = check_names("variables", variables, MAX_VARIABLES,
                            reserved={"t": "`variables` may not hold `t`: it is the time"})
        self._setup(names)
        n = len(names)
        self.constants = check_constants(constants, set(names) | {"t"},
                                         "`constants.{k}`: `{k}` is also a variable or the time")
        if isinstance(equations, (str, bytes)) or not isinstance(equations, (list, tuple)):
            raise ValueError(f"`equations` must be a list of {n} expressions (one per variable), "
                             f"got {_short(equations)}")
        if len(equations) != n:
            raise ValueError(f"`equations` must have {n} entries (one per variable), got {len(equations)}")
        args = ["t", *names]
        self.equations_text = list(equations)
        self.equations = [self._parse(f"equations[{i}]", text, args) for i, text in enumerate(equations)]
        self.invariant_text = invariant
        self.invariant = None if invariant is None else self._parse("invariant", invariant, names)
        self.exact_text = None if exact is None else list(exact) if isinstance(exact, (list, tuple)) else exact
        if exact is not None:
            if isinstance(exact, (str, bytes)) or not isinstance(exact, (list, tuple)) or len(exact) != n:
                raise ValueError(f"`exact` must be a list of {n} expressions of t (one per variable), "
                                 f"got {_short(exact)}")
            self.exact = [self._parse(f"exact[{i}]", text, ["t"]) for i, text in enumerate(exact)]
        else:
            self.exact = None
        try:
            self._rhs_fn = ex.lambdify(self.equations, args)
            self._inv_fn = None if self.invariant is None else ex.lambdify(self.invariant, names)
            self._exact_fn = None if self.exact is None else ex.lambdify(self.exact, ["t"])
        except ex.ExprError as e:
            raise ValueError(f"`equations`: {e}") from None

    # -- validation -----------------------------------------------------------
    def _parse(self, field, text, names):
        if not isinstance(text, str):
            raise ValueError(f"`{field}` must be a string (an expression), got {_short(text)}")
        try:
            return ex.parse(text, names, self.constants)
        except ex.ExprError as e:
            raise ValueError(f"`{field}`: {e}") from None

    # -- the model interface ----------------------------------------------------
    def params(self):
        out = {"variables": list(self.coord_names), "equations": list(self.equations_text),
               "constants": dict(self.constants)}
        if self.invariant_text is not None:
            out["invariant"] = self.invariant_text
        if self.exact_text is not None:
            out["exact"] = list(self.exact_text)
        return out

    def rhs(self, t, y) -> np.ndarray:
        """``dy/dt`` at ``(t, y)``; ``y`` of shape (n,) or (n, m)."""
        y = np.asarray(y, dtype=float)
        out = self._rhs_fn(t, *y)
        return np.asarray(np.broadcast_arrays(*out), dtype=float).reshape(y.shape)

    def has_invariant(self) -> bool:
        return self._inv_fn is not None

    def energy(self, y):
        if self._inv_fn is None:
            return super().energy(y)
        y = np.asarray(y, dtype=float)
        out = np.asarray(self._inv_fn(*y), dtype=float)
        return np.float64(out) if y.ndim == 1 else np.broadcast_to(out, y.shape[1:]).copy()

    def exact_solution(self, t):
        if self._exact_fn is None:
            return None
        t = np.asarray(t, dtype=float)
        return np.asarray(np.broadcast_arrays(*self._exact_fn(t)), dtype=float).reshape(self.n_dof, *t.shape)

    def check_exact(self, y0, t0: float = 0.0) -> None:
        """Refuse an ``exact`` solution that does not start at ``y0``
        (``ValueError`` naming ``exact``)."""
        if self._exact_fn is None:
            return
        with np.errstate(all="ignore"):
            e0 = self.exact_solution(np.array([t0]))[:, 0]
        y0 = np.asarray(y0, dtype=float)
        scale = max(float(np.max(np.abs(y0))), 1e-300)
        if not np.all(np.isfinite(e0)) or float(np.max(np.abs(e0 - y0))) > EXACT_Y0_RTOL * scale:
            raise ValueError(f"`exact` at t = {t0:g} is {e0.tolist()}, not the initial state {y0.tolist()}")


class FunctionOde(_FirstOrder):
    """A plain ``fun(t, y)`` (scipy's convention: ``y`` of shape (n,), returns
    ``dy/dt``) as a model, with an optional ``exact(t)`` (returns ``y`` at
    ``t``: shape (n,) for a float, (n, m) for an array of m times) and an
    optional ``invariant(y)``.

    Parameters
    ----------
    fun : callable
    n : int
        Number of state components.
    exact, invariant : callable, optional
    names : list of str, optional
        Names of the components (default ``y0, y1, ...``).
    """

    name = "ode-function"

    def __init__(self, fun, n, exact=None, invariant=None, names=None):
        for what, f in (("fun", fun), ("exact", exact), ("invariant", invariant)):
            if f is not None and not callable(f):
                raise ValueError(f"`{what}` must be callable, got {_short(f)}")
        if fun is None:
            raise ValueError("`fun` must be callable, got None")
        if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1:
            raise ValueError(f"the state must have at least one component, got n = {n!r}")
        names = [f"y{i}" for i in range(n)] if names is None else list(names)
        if len(names) != n:
            raise ValueError(f"`names` must have {n} entries, got {len(names)}")
        self._setup(names)
        self.fun, self._exact, self._invariant = fun, exact, invariant

    def params(self):
        # the functions themselves (by identity): no two functions share cached constants
        return {"fun": repr(self.fun), "exact": repr(self._exact), "invariant": repr(self._invariant),
                "n": self.n_dof}

    def rhs(self, t, y) -> np.ndarray:
        y = np.asarray(y, dtype=float)
        if y.ndim == 1:
            return np.asarray(self.fun(t, y), dtype=float).reshape(y.shape)
        return np.stack([np.asarray(self.fun(t, y[:, j]), dtype=float).reshape(-1) for j in range(y.shape[1])],
                        axis=1)

    def has_invariant(self) -> bool:
        return self._invariant is not None

    def energy(self, y):
        if self._invariant is None:
            return super().energy(y)
        y = np.asarray(y, dtype=float)
        if y.ndim == 1:
            return np.float64(self._invariant(y))
        return np.array([float(self._invariant(y[:, j])) for j in range(y.shape[1])])

    def exact_solution(self, t):
        if self._exact is None:
            return None
        t = np.asarray(t, dtype=float)
        out = np.asarray(self._exact(t), dtype=float)
        if out.shape != (self.n_dof, *t.shape):  # a scalar-only exact(t): one time at a time
            out = np.stack([np.asarray(self._exact(float(s)), dtype=float).reshape(-1) for s in t.ravel()], axis=1)
        return out.reshape(self.n_dof, *t.shape)
