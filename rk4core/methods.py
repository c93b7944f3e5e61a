"""Explicit one-step methods as data: (partitioned) Butcher tableaux.

A method is a :class:`Tableau`. Classical methods use one tableau for every
component; the semi-implicit (symplectic) Euler method is a *partitioned*
Runge-Kutta method: the first half of the state (positions ``q``) and the
second half (velocities ``v``) use different coefficients. Stepping is one pure
function, :func:`rk_step`, shared by every method.

References
----------
E. Hairer, S. P. Norsett, G. Wanner, *Solving Ordinary Differential Equations I*,
2nd ed., Springer 1993, sec. II.1 (classical RK4, Table 1.2).
E. Hairer, C. Lubich, G. Wanner, *Geometric Numerical Integration*, 2nd ed.,
Springer 2006, sec. II.2 (partitioned RK methods; symplectic Euler, eq. I.1.9).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

__all__ = ["Tableau", "RK4", "EULER", "SYMPLECTIC_EULER", "METHODS", "get_method", "rk_step", "stage_time"]


@dataclass(frozen=True)
class Tableau:
    """Coefficients of an explicit (partitioned) Runge-Kutta method.

    Attributes
    ----------
    name : str
        Registry name (``"rk4"``, ``"euler"``, ``"symplectic-euler"``).
    A, b, c : ndarray
        Butcher coefficients for the position half (or the whole state when
        the method is not partitioned). ``A`` is strictly lower triangular.
    order : int
        Classical order of accuracy.
    A_v, b_v : ndarray or None
        Coefficients for the velocity half of a partitioned method; ``None``
        for a classical method.
    """

    name: str
    A: np.ndarray
    b: np.ndarray
    c: np.ndarray
    order: int
    A_v: np.ndarray | None = None
    b_v: np.ndarray | None = None
    description: str = field(default="", compare=False)

    @property
    def n_stages(self) -> int:
        return len(self.b)

    @property
    def partitioned(self) -> bool:
        return self.A_v is not None


def _tab(name, A, b, c, order, A_v=None, b_v=None, description=""):
    arr = lambda x: None if x is None else np.asarray(x, dtype=float)  # noqa: E731
    return Tableau(name, arr(A), arr(b), arr(c), order, arr(A_v), arr(b_v), description)


#: Classical RK4 as in the thesis, sec. 1.1.4 (eqs. 1.7-1.12): stages at t, t+h/2,
#: t+h/2, t+h; weights 1/6, 1/3, 1/3, 1/6.
RK4 = _tab(
    "rk4",
    A=[[0, 0, 0, 0], [0.5, 0, 0, 0], [0, 0.5, 0, 0], [0, 0, 1, 0]],
    b=[1 / 6, 1 / 3, 1 / 3, 1 / 6],
    c=[0, 0.5, 0.5, 1],
    order=4,
    description="classical Runge-Kutta, 4 stages (thesis sec. 1.1.4)",
)

#: Explicit (forward) Euler, used by the thesis' animation code (Code 01).
EULER = _tab("euler", A=[[0]], b=[1], c=[0], order=1, description="explicit Euler")

#: Semi-implicit (symplectic) Euler of the thesis' N-mass code (Code 02):
#: v_{n+1} = v_n + h a(q_n);  q_{n+1} = q_n + h v_{n+1}.
#: As a partitioned RK method: stage 2 sees (q_n, v_n + h k1_v); q is advanced
#: with stage 2's slope (= v_{n+1}), v with stage 1's (= a(q_n)).
SYMPLECTIC_EULER = _tab(
    "symplectic-euler",
    A=[[0, 0], [0, 0]],
    b=[0, 1],
    c=[0, 0],
    order=1,
    A_v=[[0, 0], [1, 0]],
    b_v=[1, 0],
    description="semi-implicit (symplectic) Euler, velocity first (thesis Code 02)",
)

METHODS: dict[str, Tableau] = {m.name: m for m in (RK4, EULER, SYMPLECTIC_EULER)}


def get_method(method: str | Tableau) -> Tableau:
    """Return the tableau named ``method`` (or ``method`` itself)."""
    if isinstance(method, Tableau):
        return method
    try:
        return METHODS[method]
    except (KeyError, TypeError):
        raise ValueError(
            f"`method` must be one of {sorted(METHODS)}, got {method!r}"
        ) from None


def stage_time(t: float, c: float, h: float, t_max: float | None) -> float:
    """Time ``t + c h`` of a stage, never past ``t_max`` (None: no limit).

    ``t + c h`` can round one ulp past the end of the interval on its last
    step; the right-hand side is never evaluated outside ``t_span`` (as scipy's
    ``solve_ivp`` after gh-17341)."""
    ti = t + c * h
    return ti if t_max is None or ti <= t_max else t_max


def rk_step(fun, t: float, y: np.ndarray, h: float, tab: Tableau, k: np.ndarray, *,
            t_max: float | None = None) -> np.ndarray:
    """Advance ``y`` by one step of size ``h``; pure apart from the scratch ``k``.

    Parameters
    ----------
    fun : callable
        ``fun(t, y) -> dy/dt``.
    t, y, h : float, ndarray, float
        Current time, state (shape (n,), real or complex) and step.
    tab : Tableau
        The method.
    k : ndarray, shape (n_stages, n)
        Scratch space for the stage slopes (overwritten), of the state's dtype.
    t_max : float, optional, keyword-only
        End of the integration interval: stage times are
        ``min(t + c_i h, t_max)`` (:func:`stage_time`), so ``fun`` is never
        called past it. Default: no limit.

    Returns
    -------
    ndarray
        The new state ``y(t + h)`` (a new array).
    """
    A, b, c = tab.A, tab.b, tab.c
    if not tab.partitioned:
        for i in range(tab.n_stages):
            yi = y
            for j in range(i):
                if A[i, j] != 0.0:
                    yi = yi + (h * A[i, j]) * k[j]
            k[i] = fun(stage_time(t, c[i], h, t_max), yi)
        y_new = y.copy()
        for i in range(tab.n_stages):
            if b[i] != 0.0:
                y_new += (h * b[i]) * k[i]
        return y_new
    n = y.shape[0] // 2
    A_v, b_v = tab.A_v, tab.b_v
    for i in range(tab.n_stages):
        yi = y.copy()
        for j in range(i):
            if A[i, j] != 0.0:
                yi[:n] += (h * A[i, j]) * k[j, :n]
            if A_v[i, j] != 0.0:
                yi[n:] += (h * A_v[i, j]) * k[j, n:]
        k[i] = fun(stage_time(t, c[i], h, t_max), yi)
    y_new = y.copy()
    for i in range(tab.n_stages):
        if b[i] != 0.0:
            y_new[:n] += (h * b[i]) * k[i, :n]
        if b_v[i] != 0.0:
            y_new[n:] += (h * b_v[i]) * k[i, n:]
    return y_new
