"""Example ``python`` methods: step functions ``step(fun, t, y, h) -> y_next``.

A scene names one with ``[methods.NAME] python = "rk4h.steppers:rk4_step"``
and its declared ``order``; the harness runs it on the generic loop of
``rk4h.references.solvers.stepper`` and measures it like any other method. Write
your own in any importable module with the same signature.

References
----------
Thesis sec. 1.1.4, eqs. 1.7-1.12 (classical RK4, written out as in its Code 03).
"""
from __future__ import annotations

__all__ = ["rk4_step"]


def rk4_step(fun, t, y, h):
    """One classical RK4 step written out by hand, as the thesis' Code 03 does:
    ``k1 = f(t, y)``, ``k2 = f(t + h/2, y + h k1/2)``, ``k3 = f(t + h/2, y + h k2/2)``,
    ``k4 = f(t + h, y + h k3)``, ``y + h (k1 + 2 k2 + 2 k3 + k4) / 6``.

    Parameters
    ----------
    fun : callable
        ``fun(t, y) -> dy/dt``.
    t : float
        Time (s).
    y : ndarray, shape (n,)
        State.
    h : float
        Step (s).
    """
    k1 = fun(t, y)
    k2 = fun(t + h / 2, y + h / 2 * k1)
    k3 = fun(t + h / 2, y + h / 2 * k2)
    k4 = fun(t + h, y + h * k3)
    return y + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
