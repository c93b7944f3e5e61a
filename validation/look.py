"""What the state figures read of a model, recorded with the trajectory.

The state figures (:func:`rk4h.validation.figures.scene.scene_figures`)
need a few facts of the scene's model: its name, its coordinates (count and
names), its masses, whether it is linear or a first-order ODE, and its
:class:`~rk4h.models.base.Drawing`. The run that keeps a trajectory records
them (:func:`record_look`, called by :mod:`rk4h.validation.execute`) and the
drawing reads them back (:class:`ModelLook`), so that drawing a figure builds
no model: the figures read records only.

Record layout: value ``look`` (JSON text: ``name``, ``n_dof``, ``n_state``,
``first_order``, ``linear`` and ``drawing``, the drawing's fields, ``null``
for a first-order ODE), arrays ``look_mass`` (kg or the model's mass unit,
one per coordinate; absent when the model has none) and
``look_coord_names``. Imports numpy only: a worker that records a run does
not load the drawing stack.
"""
from __future__ import annotations

import dataclasses
import json

import numpy as np

__all__ = ["ModelLook", "record_look", "recorded_look"]

#: Drawing fields that are tuples of pairs or triples (JSON gives lists).
_NESTED = ("points", "reference", "anchors", "springs")
_FLAT = ("rest", "point_labels")


def record_look(model, values: dict, arrays: dict) -> None:
    """Put what the state figures read of ``model`` into a record's
    ``values`` and ``arrays`` (see the module docstring)."""
    first = bool(getattr(model, "first_order", False))
    drawing = None if first else dataclasses.asdict(model.drawing())
    look = {"name": str(model.name), "n_dof": int(model.n_dof), "n_state": int(model.n_state),
            "first_order": first, "linear": bool(getattr(model, "linear", False)), "drawing": drawing}
    values["look"] = json.dumps(look, sort_keys=True, allow_nan=True)
    mass = getattr(model, "mass", None)
    if mass is not None:
        arrays["look_mass"] = np.asarray(mass, dtype=float)
    names = getattr(model, "coord_names", None)
    if names:
        arrays["look_coord_names"] = np.array([str(n) for n in names], dtype=str)


def recorded_look(record) -> dict:
    """The look a record holds, as a plain dict (pickles to a worker):
    ``{}`` when it holds none."""
    if "look" not in record.values:
        return {}
    out = {"look": record.values["look"]}
    out.update({key: record.arrays[key] for key in ("look_mass", "look_coord_names") if key in record.arrays})
    return out


class ModelLook:
    """A recorded model's look: the attributes the state figures read
    (``name``, ``n_dof``, ``n_state``, ``first_order``, ``linear``,
    ``mass``, ``coord_names``) and :meth:`drawing`. Built from
    :func:`recorded_look`'s dict; raises ``ValueError`` for an empty one (a
    record that holds no look)."""

    def __init__(self, recorded: dict):
        if not recorded or "look" not in recorded:
            raise ValueError("the record holds no model look (rk4h.validation.look): rerun its scene")
        look = json.loads(recorded["look"])
        self.name = look["name"]
        self.n_dof = int(look["n_dof"])
        self.n_state = int(look["n_state"])
        self.first_order = bool(look["first_order"])
        self.linear = bool(look["linear"])
        self.mass = np.asarray(recorded["look_mass"], float) if "look_mass" in recorded else None
        self.coord_names = [str(n) for n in recorded.get("look_coord_names", [])]
        self._drawing = look["drawing"]

    def drawing(self):
        """The model's :class:`~rk4h.models.base.Drawing`, as recorded."""
        from rk4h.models import Drawing

        if self._drawing is None:
            raise ValueError(f"{self.name} is a first-order ODE: it has no drawing")
        d = dict(self._drawing)
        for key in _NESTED:
            d[key] = tuple(tuple(x) for x in d.get(key, ()))
        for key in _FLAT:
            d[key] = tuple(d.get(key, ()))
        return Drawing(**d)

    def __repr__(self):
        return f"ModelLook({self.name!r}, n_dof={self.n_dof})"
