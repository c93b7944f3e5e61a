"""Pack a built-in model into the integer kind and parameter arrays the
compiled kernels read (:mod:`rk4core.fast._kernels`).

The arrays are read from the model's own attributes (``model.mass``,
``model.k``, ``model.walls``, ...): the model stays the one source of truth.
Derived constants are formed with the same expressions as the model's
``_force`` so that both evaluate bit for bit alike.
"""
from __future__ import annotations

import numpy as np

from ..models import Chain, Oscillator2D, Pendulums, Planar4, Triangle
from . import _kernels as K

__all__ = ["pack", "supports"]


def _chain(m: Chain):
    ip = np.array([m.walls in ("both", "left"), m.walls in ("both", "right")], dtype=np.int64)
    return K.CHAIN, ip, np.ascontiguousarray(m.k, dtype=float)


def _planar4(m: Planar4):
    if m.linear:
        return K.PLANAR4_LINEAR, None, np.array([m.k])
    return K.PLANAR4, None, np.array([m.k, m.l] + [a for xy in m.anchors for a in xy])


def _oscillator2d(m: Oscillator2D):
    return K.OSCILLATOR2D, None, np.array([m.kx, m.ky])


def _pendulums(m: Pendulums):
    mgl, kl2 = m.m * m.g * m.length, m.k * m.length ** 2  # as Pendulums._force
    kind = K.PENDULUMS_LINEAR if m.linear else K.PENDULUMS
    return kind, None, np.array([mgl, kl2, m.length, m.separation, m.k])


def _triangle(m: Triangle):
    from ..models.triangle import _PAIRS

    if tuple(_PAIRS) != ((0, 1), (1, 2), (0, 2)):  # the kernel hard-codes this order
        raise ValueError(f"triangle bond order changed to {_PAIRS!r}; update rk4core.fast")
    rel = []
    for i, j in _PAIRS:
        (xi, yi), (xj, yj) = m.rest[i], m.rest[j]
        rel += [xj - xi, yj - yi]
    return K.TRIANGLE, None, np.array([m.k, m.side] + rel)


_PACKERS = {Chain: _chain, Planar4: _planar4, Oscillator2D: _oscillator2d,
            Pendulums: _pendulums, Triangle: _triangle}


def supports(model) -> bool:
    """True when ``model`` is one of the built-in model classes (not a subclass,
    which could redefine the force) and so has a compiled right-hand side.
    An anharmonic (FPUT) chain has none yet: it runs on the generic path."""
    if type(model) is Chain and not model.linear:
        return False
    return type(model) in _PACKERS


def pack(model):
    """``(kind, ip, fp, mass)`` for the compiled kernels.

    Raises
    ------
    ValueError
        If ``model`` is not supported (see :func:`supports`).
    """
    if not supports(model):
        raise ValueError(f"`model` must be a built-in model ({', '.join(c.name for c in _PACKERS)}) "
                         f"for the fast path, got {type(model).__name__}")
    kind, ip, fp = _PACKERS[type(model)](model)
    ip = np.zeros(2, dtype=np.int64) if ip is None else ip
    return kind, ip, np.asarray(fp, dtype=float), np.ascontiguousarray(model.mass, dtype=float)
