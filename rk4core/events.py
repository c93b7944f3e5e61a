"""Event functions of :func:`rk4h.solve`, with ``scipy.integrate.solve_ivp``'s
conventions (scipy/integrate/_ivp/ivp.py: ``prepare_events``,
``find_active_events``, ``handle_events``, ``solve_event_equation``).

An event is a function ``event(t, y, *args) -> float`` whose zeros are
wanted. After each step the event is evaluated at the new grid point; a sign
change over the step (``up``: from <= 0 to >= 0, ``down``: from >= 0 to <= 0,
filtered by the event's ``direction``) is located by ``scipy.optimize.brentq``
on the step's dense-output polynomial (:mod:`rk4h.dense`) with
``xtol = rtol = 4 eps``, as scipy. The located time is then exact for the
interpolant; its distance from the true event time is the dense output's
error divided by ``|dg/dt|`` there (fourth order in ``h`` for RK4; see
:mod:`rk4h.dense`). Two sign changes inside one step are not seen (as
scipy).

Attributes read from each event function (as scipy >= 1.12):

* ``terminal``: ``False``/``None``/``0`` (never stop), ``True`` (stop at the
  first occurrence) or a positive integer ``k`` (stop at the ``k``-th).
  Anything else is refused: ``ValueError`` ("The `terminal` attribute of each
  event must be a boolean or positive integer; ...").
* ``direction``: > 0 only increasing crossings, < 0 only decreasing ones, 0
  (default) both.

One difference from scipy, on purpose: a zero that falls exactly on a grid
point is one event, recorded in the step that ends there. scipy records it a
second time at the start of the next step when the function then moves away
from zero (a fixed grid lands on such zeros often: ``event = t - 5`` with
``h = 0.5``).
"""
from __future__ import annotations

import math
from functools import partial
from numbers import Real

import numpy as np

from .validate import short

__all__ = ["Events", "TERMINAL_MESSAGE"]

EPS = float(np.finfo(float).eps)
TERMINAL_MESSAGE = "The `terminal` attribute of each event must be a boolean or positive integer"


_short = partial(short, limit=60)


class Events:
    """The events of one run: their functions, limits, and what was found.

    Parameters
    ----------
    events : callable or sequence of callables
        As ``solve_ivp``'s ``events``.
    args : tuple
        Extra arguments passed to every event function after ``(t, y)``.

    Attributes
    ----------
    max_events : ndarray, shape (n_events,)
        Occurrences after which the run stops (``inf``: never).
    direction : ndarray, shape (n_events,)
    t_events, y_events : list of list
        Times and states found so far, per event.
    """

    def __init__(self, events, args=()):
        if callable(events):
            events = (events,)
        try:
            funcs = list(events)
        except TypeError:
            raise ValueError(f"`events` must be a callable or a list of callables, got {_short(events)}") from None
        m = len(funcs)
        self.funcs = funcs
        self.args = tuple(args)
        self.max_events = np.empty(m)
        self.direction = np.empty(m)
        for i, ev in enumerate(funcs):
            if not callable(ev):
                raise ValueError(f"`events[{i}]` must be callable, got {_short(ev)}")
            terminal = getattr(ev, "terminal", None)
            try:
                if terminal is None or terminal == 0:
                    self.max_events[i] = np.inf
                elif isinstance(terminal, (Real, np.bool_)) and int(terminal) == terminal and terminal > 0:
                    self.max_events[i] = int(terminal)
                else:
                    raise ValueError
            except (TypeError, ValueError):
                raise ValueError(f"{TERMINAL_MESSAGE}; events[{i}].terminal = {_short(terminal)}") from None
            direction = getattr(ev, "direction", 0)
            if not isinstance(direction, (Real, np.bool_)) or not math.isfinite(float(direction)):
                raise ValueError(f"`events[{i}].direction` must be a finite number (> 0 rising, < 0 falling, "
                                 f"0 both), got {_short(direction)}")
            self.direction[i] = float(direction)
        self.count = np.zeros(m)
        self.last = np.full(m, np.nan)  # time of the last event recorded, per function
        self.t_events = [[] for _ in range(m)]
        self.y_events = [[] for _ in range(m)]

    def __len__(self) -> int:
        return len(self.funcs)

    def value(self, i: int, t: float, y: np.ndarray) -> float:
        """``events[i](t, y, *args)`` as a float; ``ValueError`` naming
        ``events[i]`` for anything else."""
        g = self.funcs[i](t, y, *self.args)
        if type(g) is float or type(g) is np.float64:
            return float(g)
        try:
            if np.iscomplexobj(g):
                raise TypeError
            return float(np.asarray(g, dtype=float).reshape(()))
        except (TypeError, ValueError):
            raise ValueError(f"`events[{i}]` returned {_short(g)} at t = {float(t)!r}; expected a real "
                             f"number") from None

    def values(self, t: float, y: np.ndarray) -> list:
        return [self.value(i, t, y) for i in range(len(self.funcs))]

    def active(self, g, g_new, t_old: float) -> np.ndarray:
        """Indices of the events whose sign changed over a step (scipy's
        ``find_active_events``: ``up`` from <= 0 to >= 0, ``down`` from >= 0
        to <= 0, kept by ``direction``), less those whose zero at ``t_old``
        was already recorded (the step before ended on it)."""
        found = []
        for i, (a, b) in enumerate(zip(g, g_new)):
            up = a <= 0 and b >= 0
            down = a >= 0 and b <= 0
            if not (up or down):
                continue
            d = self.direction[i]
            if (up and d > 0) or (down and d < 0) or d == 0:
                if not (a == 0 and self.last[i] == t_old):
                    found.append(i)
        return np.array(found, dtype=np.int64)

    def locate(self, i: int, interp, t_old: float, t_new: float) -> float:
        """Zero of ``events[i](t, interp(t))`` between ``t_old`` and ``t_new``
        (brentq, ``xtol = rtol = 4 eps``, as scipy)."""
        from scipy.optimize import brentq

        return brentq(lambda t: self.value(i, t, interp(t)), t_old, t_new, xtol=4 * EPS, rtol=4 * EPS)

    def handle(self, active: np.ndarray, interp, t_old: float, t_new: float):
        """Locate and record the events ``active`` in the step ``[t_old,
        t_new]`` (scipy's ``handle_events``): returns ``(t, y)`` of the
        terminal event that stops the run, or None."""
        roots = np.asarray([self.locate(i, interp, t_old, t_new) for i in active])
        self.count[active] += 1
        terminate = False
        if np.any(self.count[active] >= self.max_events[active]):
            order = np.argsort(roots) if t_new > t_old else np.argsort(-roots)
            active, roots = active[order], roots[order]
            stop = np.nonzero(self.count[active] >= self.max_events[active])[0][0]
            active, roots = active[: stop + 1], roots[: stop + 1]
            terminate = True
        for i, te in zip(active, roots):
            self.t_events[i].append(float(te))
            self.y_events[i].append(interp(te))
            self.last[i] = te
        if terminate:
            return float(roots[-1]), interp(roots[-1])
        return None

    def results(self):
        """``(t_events, y_events)`` as ``solve_ivp`` returns them: a list of
        arrays per event (shape (k,) and (k, n); ``(0,)`` when none)."""
        return ([np.asarray(te, dtype=float) for te in self.t_events],
                [np.asarray(ye) for ye in self.y_events])
