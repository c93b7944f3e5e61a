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
"""
from __future__ import annotations

from . import captions, measurement, scene, style
from .captions import *  # noqa: F403
from .measurement import *  # noqa: F403
from .scene import *  # noqa: F403
from .style import *  # noqa: F403

__all__ = [*captions.__all__, *style.__all__, *scene.__all__, *measurement.__all__]
