"""rk4core's fixed-step methods as ``scipy.integrate.OdeSolver`` classes.

``scipy.integrate.solve_ivp(fun, t_span, y0, method=rk4h.ivp.RK4, h=0.01)``
runs scipy's own driver (``t_eval``, ``dense_output``, events, ``args``,
``vectorized``) on rk4core's stepping function: every step is one call of
:func:`rk4h.methods.rk_step` with the method's tableau, so the states are
those of :func:`rk4h.solve` at the same grid points (bit for bit when
``h`` divides ``t_span``).

Conventions
-----------
* The grid: ``t_i = t0 + i h`` (computed from ``i``, not accumulated), in
  the direction of ``t_span`` (``h`` is a magnitude; a negative ``h`` is
  accepted for a backward span only). With a finite ``t_bound`` the number
  of steps is ``N = ceil(|t_bound - t0| / h)`` (relative slack 1e-12, as
  :func:`rk4h.solver.step_count`). When ``N h`` equals the span to that
  slack, the grid is :func:`rk4h.solve`'s (steps of ``(t_bound - t0) /
  N``: states and ``nfev`` equal bit for bit); otherwise the last step is
  shortened to ``t_bound - t_{N-1}`` so that it ends on ``t_bound``
  exactly, as scipy's own solvers end on ``t_bound`` (``rk4h.solve``
  would take ``N`` equal steps instead). Times are in the units of
  ``t_span``.
* An infinite ``t_bound`` (``t_span = (0, inf)``) needs a terminal event to
  end the run; after ``max_steps`` steps (default :data:`MAX_STEPS_INFINITE`)
  the step fails with a message, so ``solve_ivp`` returns ``status = -1``
  instead of running forever.
* Dense output (``dense_output=True`` and event location) is the cubic
  Hermite interpolant of the step's end states and slopes, as
  :mod:`rk4h.dense`. The slopes come from the stages where the method has
  them (``start_slope``/``end_slope``); else ``f(t_{i+1}, y_{i+1})`` costs
  one call, which the next step's first stage then reuses.
* Options for adaptive or implicit methods (``rtol``, ``atol``,
  ``first_step``, ``max_step``, ``min_step``, ``jac``, ...) are refused,
  naming the option; so is any other unknown keyword.
* Partitioned (symplectic) tableaux are supported: ``y = [q, v]`` (even
  length), ``fun`` returns ``[v, a(q)]`` and only its acceleration half is
  used, as in :func:`rk4h.solve`.
"""
from __future__ import annotations

import math

import numpy as np
from scipy.integrate import DenseOutput, OdeSolver

from .dense import hermite
from .methods import METHODS, Tableau, end_slope, get_method, rk_step, start_slope
from .solver import _SLACK, _Once, grid_time, refuse_options, step_count
from .validate import check_step_args, check_step_sign, positive

__all__ = ["FixedStepSolver", "FixedStepDenseOutput", "solver_class", "MAX_STEPS_INFINITE", "RK4", "RK38",
           "HEUN3", "RALSTON", "EULER", "SYMPLECTIC_EULER", "STORMER_VERLET"]

#: Default step cap of a run with an infinite ``t_bound``.
MAX_STEPS_INFINITE = 10**6


class FixedStepDenseOutput(DenseOutput):
    """Cubic Hermite interpolant of one step (``y`` and ``f = dy/dt`` at both
    ends), the arithmetic of :func:`rk4h.dense.hermite`."""

    def __init__(self, t_old, t, y_old, y, f_old, f):  # noqa: D107
        super().__init__(t_old, t)
        self.d = t - t_old
        self.y_old, self.y, self.f_old, self.f = y_old, y, f_old, f

    def _call_impl(self, t):
        t = np.asarray(t, dtype=float)
        theta = np.atleast_1d((t - self.t_old) / self.d)
        out = hermite(theta, self.d, self.y_old, self.y, self.f_old, self.f)  # (m, n)
        return out[0] if t.ndim == 0 else out.T


class FixedStepSolver(OdeSolver):
    """Base class: a fixed-step explicit Runge-Kutta method as an
    ``OdeSolver``; subclasses set :attr:`tableau` (see :func:`solver_class`).

    Parameters
    ----------
    fun, t0, y0, t_bound, vectorized
        As ``scipy.integrate.OdeSolver`` (``solve_ivp`` passes them).
    h : float
        The step (units of ``t``), required: its magnitude, or a negative
        value for a backward span (``t_bound < t0``).
    max_steps : int, optional
        Step cap when ``t_bound`` is infinite (default
        :data:`MAX_STEPS_INFINITE`); ignored for a finite ``t_bound``.
    **options
        Refused: each tolerance or Jacobian option of the adaptive and
        implicit solvers raises ``ValueError`` naming it, and so does any
        other keyword.

    Attributes
    ----------
    h : float
        Signed step (negative backward).
    n_grid : int or None
        Steps to ``t_bound`` (None when ``t_bound`` is infinite).
    step_index : int
        Steps taken.
    """

    tableau: Tableau = None
    _uneven = False  # h does not divide the span: the last step is shorter

    def __init__(self, fun, t0, y0, t_bound, vectorized=False, *, h=None, max_steps=MAX_STEPS_INFINITE,
                 **options):  # noqa: D107
        name = type(self).__name__
        refuse_options(options, f"rk4h.ivp.{name}", "h", "it takes h and max_steps")
        if self.tableau is None:
            raise TypeError("FixedStepSolver has no tableau; use rk4h.ivp.solver_class(method)")
        tab = self.tableau
        super().__init__(fun, t0, y0, t_bound, vectorized, support_complex=True)
        if tab.partitioned and self.n % 2:
            raise ValueError(f"`y0` must have even length for {tab.name!r} (y = [q, v]), got {self.n}")
        if h is None:
            raise ValueError(f"`h` is required by rk4h.ivp.{name} (the fixed step), got h=None")
        t0, t_bound = float(t0), float(t_bound)
        if t_bound == t0 or math.isinf(t_bound):
            # no grid to fit: h is a magnitude (a negative one only for a backward span)
            if isinstance(h, (int, float, np.integer, np.floating)) and h < 0 and t_bound <= t0:
                h = -h
            h = positive("h", h)
            if isinstance(max_steps, bool) or not isinstance(max_steps, (int, np.integer)) or max_steps < 1:
                raise ValueError(f"`max_steps` must be an integer >= 1, got {max_steps!r}")
            self.n_grid = None if t_bound != t0 else 0
            self.max_steps = int(max_steps)
        else:
            self.n_grid = check_step_args(t0, t_bound, check_step_sign(h, t0, t_bound), None, step_count)
            h = abs(float(h))
            self.max_steps = self.n_grid
            span = abs(t_bound - t0)
            if abs(self.n_grid * h - span) <= _SLACK * span:
                h = span / self.n_grid  # h divides the span: rk4h.solve's grid, bit for bit
            else:
                self._uneven = True
        self.h = self.direction * h
        self._t0 = t0
        self.step_index = 0
        self._k = np.empty((tab.n_stages, self.n), dtype=self.y.dtype)
        self._reuse = False
        self._kept = None  # (t, y, f) of f(t_i, y_i) computed for a dense output
        self._y_old = self.y

    def _grid(self, i):
        if self.n_grid is None:
            return self._t0 + i * self.h
        return grid_time(self._t0, self.t_bound, self.h, i, self.n_grid)

    def _step_size(self, i, t):
        if self._uneven and i + 1 == self.n_grid:
            return self.t_bound - t
        return self.h

    def _step_impl(self):
        i = self.step_index
        if self.n_grid is None and i >= self.max_steps:
            return False, (f"no terminal event ended the run within max_steps = {self.max_steps} steps "
                           f"(t = {self.t:.6g}, h = {self.h:.6g}); t_span's end is infinite")
        tab = self.tableau
        t = self.t
        t_new = self._grid(i + 1)
        fun = self.fun
        if self._kept is not None:
            fun = _Once(self.fun, *self._kept)
            self._kept = None
        t_max = None
        if self.n_grid is not None and i + 1 == self.n_grid:  # the last step: no stage time past t_bound
            if self.direction > 0:
                t_max = self.t_bound
            else:
                inner, t_floor = fun, self.t_bound

                def fun(t_, y_):
                    return inner(t_ if t_ >= t_floor else t_floor, y_)
        y_old = self.y
        y_new = rk_step(fun, t, y_old, self._step_size(i, t), tab, self._k, t_max=t_max, reuse=self._reuse)
        self._reuse = tab.fsal
        self._y_old = y_old
        self.t, self.y = t_new, y_new
        self.step_index = i + 1
        return True, None

    def _slope(self, t, y):
        f = np.asarray(self.fun(t, y))
        if self.tableau.partitioned:
            half = self.n // 2
            f = np.concatenate((y[half:], f[half:]))
        return f

    def _dense_output_impl(self):
        # scipy asks for the step's interpolant right after the step, while
        # the scratch k still holds its stages
        tab = self.tableau
        f_old = start_slope(tab, self._y_old, self._k)
        f_old = self._slope(self.t_old, self._y_old) if f_old is None else f_old.copy()
        f_new = end_slope(tab, self.y, self._k)
        if f_new is None:
            f_new = self._slope(self.t, self.y)
            if not tab.partitioned:  # the next step's first stage reuses it
                self._kept = (self.t, self.y, f_new)
        else:
            f_new = f_new.copy()
        return FixedStepDenseOutput(self.t_old, self.t, self._y_old, self.y, f_old, f_new)


def solver_class(method) -> type:
    """A :class:`FixedStepSolver` subclass for ``method`` (a name of
    ``rk4h.METHODS`` or a :class:`~rk4h.methods.Tableau`), to pass as
    ``solve_ivp(..., method=solver_class(tab), h=...)``."""
    tab = get_method(method)
    cls_name = "".join(ch if ch.isalnum() else "_" for ch in tab.name.upper()) or "METHOD"
    if not cls_name[0].isalpha():
        cls_name = "M_" + cls_name
    return type(cls_name, (FixedStepSolver,), {"tableau": tab, "__doc__": (
        f"{tab.name}: fixed-step ``OdeSolver`` for ``scipy.integrate.solve_ivp`` "
        f"(``solve_ivp(..., method=<this class>, h=...)``); see :class:`FixedStepSolver`.")})


RK4 = solver_class(METHODS["rk4"])
RK38 = solver_class(METHODS["rk38"])
HEUN3 = solver_class(METHODS["heun3"])
RALSTON = solver_class(METHODS["ralston"])
EULER = solver_class(METHODS["euler"])
SYMPLECTIC_EULER = solver_class(METHODS["symplectic-euler"])
STORMER_VERLET = solver_class(METHODS["stormer-verlet"])
