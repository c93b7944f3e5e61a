"""The energy of the motion: the scale of every relative energy error.

A relative energy error divides ``E(t) - E0`` by the energy of the motion,

    E_motion = E0 - V(q*),

with ``q*`` the equilibrium the model is linearized about (the reference
positions, ``q = 0``: every model's coordinates are displacements from it).
Dividing by ``|E0|`` instead would depend on where the potential's zero is:
adding a constant to ``V`` (or a pre-tensioned network's static spring energy)
changes ``E0`` but not the motion nor ``E(t) - E0``. ``E_motion`` is the
kinetic energy plus the potential energy above the equilibrium, so it is
invariant under ``V -> V + c``. When it is 0 (a model at rest in its
equilibrium) the error is absolute (J): the scale is 1.

A first-order model (``rk4h.models.OdeModel``: ``model.first_order``)
has an invariant ``I(y)`` in place of an energy, and no rest state: its
scale is ``|I0|`` (absolute where ``I0 = 0``).

The differences ``E(t) - E0`` are formed from ``T + (V(q) - V(q*))``: a model
with a method ``potential_above_rest(q)`` (the ``potential`` model: ``V(0)``
subtracted symbolically, so a constant cancels exactly) is evaluated through
it, any other model as ``potential(q) - V(q*)``.
"""
from __future__ import annotations

import numpy as np

__all__ = ["rest_energy", "motion_energy", "energy_scale", "motion_energies", "relative_energy_error"]


def rest_energy(model) -> float:
    """``V(q*)`` (J): the potential energy at the equilibrium ``q* = 0``; 0
    for a first-order model (``model.first_order``: its "energy" is an
    invariant ``I(y)`` with no rest state, so the scale is ``|I0|``)."""
    if getattr(model, "first_order", False):
        return 0.0
    with np.errstate(all="ignore"):
        return float(np.asarray(model.potential(np.zeros(model.n_dof)), float))


def motion_energy(model, E0) -> float:
    """``E_motion = E0 - V(q*)`` (J) for the initial energy ``E0`` (J)."""
    return float(E0) - rest_energy(model)


def _scale(motion) -> float:
    s = abs(float(motion))
    return s if np.isfinite(s) and s > 0.0 else 1.0


def energy_scale(model, E0) -> float:
    """The divisor of relative energy errors: ``|E0 - V(q*)|`` (J), or 1 where
    it is 0 or not finite (the error is then absolute)."""
    return _scale(motion_energy(model, E0))


#: Bytes of states per block when the energies of a long trajectory are
#: evaluated (:func:`motion_energies`): numpy's temporaries of one block stay
#: in the processor's cache instead of streaming the whole trajectory through
#: memory once per operation.
BLOCK_BYTES = 1 << 20


def motion_energies(model, y) -> np.ndarray:
    """``T + V(q) - V(q*)`` (J) of states ``y`` of shape (2n, m) (or (2n,)).

    A long trajectory is evaluated in blocks of consecutive columns
    (:data:`BLOCK_BYTES` of states each). Every energy is a function of its
    own column, and a block is a view of the trajectory (same memory
    layout), so the result equals one call on the whole array to the bit
    (``tests/test_energy_blocks.py`` checks C and F order); only the
    temporaries shrink."""
    y = np.asarray(y, dtype=float)
    above = getattr(model, "potential_above_rest", None)
    rest = 0.0 if above is not None else rest_energy(model)
    width = max(256, BLOCK_BYTES // (8 * max(1, y.shape[0]))) if y.ndim == 2 else 0
    if y.ndim != 2 or y.shape[1] <= width:
        return _motion_energies(model, y, above, rest)
    out = np.empty(y.shape[1])
    for a in range(0, y.shape[1], width):
        part = _motion_energies(model, y[:, a:a + width], above, rest)
        if part.shape != out[a:a + width].shape:
            raise ValueError(f"{type(model).__name__}.energy of {y.shape[0]} x {y[:, a:a + width].shape[1]} "
                             f"states returned shape {part.shape}, not one energy per state")
        out[a:a + width] = part
    return out


def _motion_energies(model, y, above, rest) -> np.ndarray:
    if above is None:
        return np.asarray(model.energy(y), float) - rest
    n = model.n_dof
    m = model.mass if y.ndim == 1 else np.asarray(model.mass)[:, None]
    v = y[n:]
    return 0.5 * np.sum(m * v * v, axis=0) + np.asarray(above(y[:n]), float)


def relative_energy_error(model, y) -> np.ndarray:
    """``(E(t) - E0) / E_motion`` along states ``y`` of shape (2n, m) (signed,
    dimensionless; see the module docstring)."""
    with np.errstate(over="ignore", invalid="ignore"):  # a blown-up run's energy is inf
        E = motion_energies(model, y)
        return (E - E[0]) / _scale(E[0])
