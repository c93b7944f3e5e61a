"""Dense output of :func:`rk4h.solve`: the method's cubic Hermite interpolant
between steps, as an object that behaves as scipy's ``OdeSolution``.

Between grid points ``t_i`` and ``t_{i+1} = t_i + d_i`` the solution is the
cubic Hermite polynomial through the step's end states and slopes::

    u(t_i + theta d_i) = h00(theta) y_i + d_i h10(theta) f_i
                       + h01(theta) y_{i+1} + d_i h11(theta) f_{i+1},
    h00 = (1 + 2 theta)(1 - theta)^2,   h10 = theta (1 - theta)^2,
    h01 = theta^2 (3 - 2 theta),        h11 = theta^2 (theta - 1),

with ``f_i = f(t_i, y_i)`` taken from the stages the method already computed
(:func:`~rk4h.methods.start_slope`, :func:`~rk4h.methods.end_slope`;
one extra right-hand-side call where no stage gives it, counted in
``nfev``). ``theta`` is dimensionless; ``d_i`` has the units of ``t`` (negative
for a backward run: the formula is the same).

Accuracy. The interpolant reproduces ``y_i`` and ``y_{i+1}`` exactly
(``theta = 0`` and ``1`` give the node values bit for bit) and is C^1 across
grid points. As a continuous extension it has order 3 (Hairer, Norsett,
Wanner, *Solving ODEs I*, 2nd ed., sec. II.6): started from the exact
solution, its error inside a step is ``d^4 |y''''| / 384`` at most -- one
order less than RK4's local error ``O(d^5)``. Its global error is therefore
``O(h^min(p, 4))`` for a method of order ``p``: fourth order for RK4, the
same order as the grid values but with its own constant (the node errors
plus at most ``h^4 max|y''''| / 384``; the node errors enter with weight at
most ``1 + |h| L / 4`` for a Lipschitz constant ``L``). For a method of order
``p < 4`` the nodes dominate (``O(h^p)``).

References
----------
E. Hairer, S. P. Norsett, G. Wanner, *Solving Ordinary Differential Equations I*,
2nd ed., Springer 1993, sec. II.6 (dense output, Hermite interpolation).
scipy.integrate.OdeSolution and scipy.integrate.DenseOutput (the interface
reproduced here; scipy/integrate/_ivp/common.py and base.py).
"""
from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from scipy.integrate import DenseOutput, OdeSolution

__all__ = ["hermite", "HermiteSolution", "HermiteStep", "DENSE_ORDER"]

#: Order of the dense output as a continuous extension (local error O(h^4)).
DENSE_ORDER = 3


def hermite(theta, d, y0, y1, f0, f1):
    """Cubic Hermite interpolant at ``theta`` (shape (m,)) of steps of length
    ``d`` (scalar or shape (m,)) with end states ``y0, y1`` and slopes
    ``f0, f1`` (shape (m, n), or (n,) for one step shared by every point).

    Returns shape (m, n). The arithmetic is that of ``rk4h.solver._emit``
    term for term, so a point is bit for bit what the solver's ``t_eval``
    output gives for the same ``theta`` and ``d``."""
    h00 = (1 + 2 * theta) * (1 - theta) ** 2
    h10 = theta * (1 - theta) ** 2
    h01 = theta * theta * (3 - 2 * theta)
    h11 = theta * theta * (theta - 1)
    return h00[:, None] * y0 + (h10 * d)[:, None] * f0 + h01[:, None] * y1 + (h11 * d)[:, None] * f1


class HermiteSolution(OdeSolution):
    """Continuous solution of one :func:`rk4h.solve` run (``result.sol``).

    Behaves as ``scipy.integrate.OdeSolution`` (and is one, for
    ``isinstance``): ``sol(t)`` for a scalar ``t`` returns shape (n,), for a
    1-D array shape (n, m), in one vectorised evaluation (no Python loop over
    segments); outside ``[t_min, t_max]`` the first or last step's polynomial
    is extrapolated (no accuracy promised, as scipy). At a breakpoint the
    segment with the lower index is used, as scipy's default; both give the
    grid state there bit for bit.

    Parameters
    ----------
    ts : array_like, shape (n_segments + 1,)
        Breakpoints, in the direction of integration (decreasing for a
        backward run). The last one is the end of the run: ``t1``, or the
        time of a terminal event (the last polynomial then ends past it).
    nodes : array_like, shape (n_segments + 1,)
        Grid times of the polynomials' ends (equal to ``ts`` except perhaps
        the last).
    ys, fs : ndarray, shape (n_segments + 1, n)
        States and slopes ``f(t_i, y_i)`` at ``nodes`` (rows).

    Attributes
    ----------
    ts, t_min, t_max, n_segments, ascending, side, ts_sorted
        As ``OdeSolution``. With no step at all (``t0 == t1``, or a run
        stopped at ``t0``), ``ts = [t0, t0]``, one constant segment, as
        scipy's ``ConstantDenseOutput``.
    interpolants : sequence of :class:`HermiteStep`
        One per step, built on access (``len``, indexing, iteration).
    order : int
        3 (:data:`DENSE_ORDER`): the order of the continuous extension; see
        the module docstring for what that means for the global error.
    """

    order = DENSE_ORDER

    def __init__(self, ts, nodes, ys, fs):  # noqa: D107 - scipy's __init__ is replaced, not extended
        ts = np.asarray(ts, dtype=float)
        self._nodes = np.asarray(nodes, dtype=float)
        self._ys = ys
        self._fs = fs
        self._const = self._nodes.shape[0] == 1
        if self._const:
            ts = np.array([ts[0], ts[0]])
        self.ts = ts
        self.n_segments = ts.shape[0] - 1
        if ts[-1] >= ts[0]:
            self.t_min, self.t_max = ts[0], ts[-1]
            self.ascending, self.side, self.ts_sorted = True, "left", ts
        else:
            self.t_min, self.t_max = ts[-1], ts[0]
            self.ascending, self.side, self.ts_sorted = False, "right", ts[::-1]
        self.interpolants = _Interpolants(self)

    def _segments(self, t: np.ndarray) -> np.ndarray:
        ind = np.searchsorted(self.ts_sorted, t, side=self.side)
        seg = np.clip(ind - 1, 0, self.n_segments - 1)
        return seg if self.ascending else self.n_segments - 1 - seg

    def _eval(self, t: np.ndarray, seg: np.ndarray) -> np.ndarray:
        """States at times ``t`` (shape (m,)) on segments ``seg``: shape (n, m)."""
        if self._const:
            return np.repeat(self._ys[0][:, None], t.shape[0], axis=1)
        a = self._nodes[seg]
        d = self._nodes[seg + 1] - a
        theta = (t - a) / d
        out = hermite(theta, d, self._ys[seg], self._ys[seg + 1], self._fs[seg], self._fs[seg + 1])
        return np.ascontiguousarray(out.T)

    def __call__(self, t):
        """Evaluate the solution at ``t`` (float, or 1-D array of floats):
        shape (n,) or (n, m)."""
        t = np.asarray(t, dtype=float)
        if t.ndim == 0:
            tt = t.reshape(1)
            return self._eval(tt, self._segments(tt))[:, 0]
        if t.ndim != 1:
            raise ValueError(f"`t` must be a float or a 1-D array, got shape {t.shape}")
        return self._eval(t, self._segments(t))

    def __repr__(self) -> str:
        return (f"HermiteSolution(t_min={self.t_min!r}, t_max={self.t_max!r}, n_segments={self.n_segments}, "
                f"n={self._ys.shape[1]}, order={self.order})")


class HermiteStep(DenseOutput):
    """The interpolant of one step of a :class:`HermiteSolution` (a
    ``scipy.integrate.DenseOutput``): ``t_old``, ``t``, ``t_min``, ``t_max``;
    calling it evaluates that step's cubic at a float or a 1-D array of times
    (outside its step: extrapolated)."""

    def __init__(self, sol: HermiteSolution, i: int):
        super().__init__(float(sol.ts[i]), float(sol.ts[i + 1]))
        self._sol = sol
        self._i = i

    def _call_impl(self, t):
        tt = np.atleast_1d(np.asarray(t, dtype=float))
        out = self._sol._eval(tt, np.full(tt.shape[0], self._i, dtype=np.int64))
        return out[:, 0] if np.ndim(t) == 0 else out


class _Interpolants(Sequence):
    """``HermiteSolution.interpolants``: one :class:`HermiteStep` per step,
    made when indexed (a run of 10^6 steps does not hold 10^6 objects)."""

    def __init__(self, sol: HermiteSolution):
        self._sol = sol

    def __len__(self) -> int:
        return self._sol.n_segments

    def __getitem__(self, i):
        if isinstance(i, slice):
            return [self[j] for j in range(*i.indices(len(self)))]
        i = int(i)
        if i < 0:
            i += len(self)
        if not 0 <= i < len(self):
            raise IndexError(f"interpolant index out of range (there are {len(self)})")
        return HermiteStep(self._sol, i)

    def __repr__(self) -> str:
        return f"<{len(self)} HermiteStep interpolants>"
