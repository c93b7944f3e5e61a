"""The report's figures: plots of data the runner has already computed.

Every public figure function draws one kind of figure from arrays or
DataFrames, writes a PNG into ``out_dir`` and returns ``(path, sentence)``,
where ``sentence`` is a :class:`Caption`: one line (a ``str``) of what is
specific to the data drawn, whose ``kind`` keys the figure kind's generic
reading guide in :data:`GENERIC_CAPTIONS` (``index.md`` prints that once per
kind). Nothing here integrates, fits, solves an eigenproblem or measures: the
runner computes and records, these modules draw.

One job per module:

* :mod:`~rk4h.validation.figures.style`: the style kit (sizes, fonts, solver
  colours, canvas, titles, legends, log axes, the final draw, the PNG writer,
  number formats), used by every figure of the report;
* :mod:`~rk4h.validation.figures.captions`: :class:`Caption` and the reading guides;
* :mod:`~rk4h.validation.figures.scene`: the physics drawings of a scene's
  trajectory (:func:`scene_figures`);
* :mod:`~rk4h.validation.figures.measurement`: work-precision, convergence,
  energy error, modal energy, dispersion, crossover.

This package re-exports the public names of all four, so
``from rk4h.validation import figures as F; F.work_precision(...)``,
``F.new_figure()`` and ``F.slug(...)`` work. Module-level settings that code
changes at run time (:data:`style.SAVE_HOOK`, :data:`style.MINOR_SUBS`) are
read where they live: set them on :mod:`rk4h.validation.figures.style`.
The drawing modules (and matplotlib) are imported on the first use of one
of their names; :data:`GENERIC_CAPTIONS` alone imports neither.
"""
from __future__ import annotations

import importlib

from . import captions
from .captions import *  # noqa: F403

#: The drawing modules, imported on first use of one of their names: the
#: reading guides (:mod:`captions`) need no matplotlib, so a run without
#: figures (``--no-figures``) does not load the drawing stack.
_DRAWING = ("style", "scene", "measurement")


def _load_all():
    names = list(captions.__all__)
    for mod in _DRAWING:
        m = importlib.import_module(f"{__name__}.{mod}")
        for name in m.__all__:
            globals()[name] = getattr(m, name)
        names += m.__all__
    globals()["__all__"] = names
    return names


def __getattr__(name):
    if name in _DRAWING:
        return importlib.import_module(f"{__name__}.{name}")
    _load_all()
    if name in globals():
        return globals()[name]
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__():
    return sorted(set(globals()) | set(_load_all()) | set(_DRAWING))
