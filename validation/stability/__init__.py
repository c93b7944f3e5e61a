"""Numerical-stability study (issue 6): where fixed-step RK4 breaks, what it
costs to stay accurate, and what the references do there.

The study is data for the pipeline (plan -> RunSpec -> execute -> records ->
report):

``units(scene, quick) -> list[str]``
    the independent work units of the studies the scene's ``[stability]``
    table names (:mod:`.params`), in a deterministic order;
``run_unit(scene, unit, quick) -> StudyResult``
    one unit's ``rows``, ``findings`` and ``plots`` (plot descriptions: plain
    data), safe in any process or on any machine; no file written, no
    plotting library imported; exceptions propagate (:func:`failed_unit`
    makes the ``failed`` row of a unit that raised);
``assemble(scene, quick, {unit: StudyResult}) -> StudyResult``
    the merge (one cost plot and one finding per sweep ...); integrates nothing;
``draw(plot, out_dir) -> (Path, sentence)``
    one plot description drawn in the style of :mod:`rk4h.validation.figures`
    (the only place the study imports matplotlib);
``unit_steps(scene, unit, quick) -> float``
    the integration steps of one unit, estimated without integrating;
    :func:`estimate_steps` is their sum over :func:`units`.

Rows have the columns :data:`COLUMNS` (tidy: parameters such as ``theta``,
``mode``, ``mu`` in their own columns, ``quantity`` a bare name); only
:data:`TIMING_COLUMNS` are read from a clock. :func:`run` is the former
single entry point, kept as a thin wrapper (units, assemble, draw).
"""
from __future__ import annotations

from pathlib import Path

from ._common import COLUMNS, PARAM_COLUMNS, TIMING_COLUMNS, StudyResult, row
from .estimate import estimate_steps, unit_steps
from .params import DEFAULTS, PARAMS, STUDIES, params_table_markdown, validate_params
from .studies import assemble, failed_unit, parse_unit, run_unit, units

__all__ = ["units", "run_unit", "assemble", "draw", "unit_steps", "failed_unit", "parse_unit", "run",
           "COLUMNS", "PARAM_COLUMNS", "TIMING_COLUMNS", "validate_params", "estimate_steps", "StudyResult",
           "STUDIES", "DEFAULTS", "PARAMS", "params_table_markdown"]


def draw(plot: dict, out_dir) -> tuple[Path, str]:
    """Draw one plot description (from :func:`run_unit` / :func:`assemble`)
    into ``out_dir``; returns ``(path, sentence)``."""
    from .plots import draw as _draw

    return _draw(plot, out_dir)


def run(scene, out_dir, quick: bool, progress=None) -> StudyResult:
    """Every unit of ``scene``'s study in this process, merged and drawn into
    ``out_dir`` (figures in ``.figures``). A unit or figure that raises becomes
    a ``failed`` row; nothing raises into the caller but a bad ``[stability]``
    table (``ValueError``)."""
    out_dir = Path(out_dir)
    results = {}
    for unit in units(scene, quick):
        if progress is not None:
            progress(f"stability {scene.name}: {unit}")
        try:
            results[unit] = run_unit(scene, unit, quick)
        except Exception as exc:  # noqa: BLE001 - a unit failure is a row, not a crash
            results[unit] = failed_unit(scene.name, unit, exc)
    result = assemble(scene, quick, results)
    for plot in result.plots:
        try:
            result.figures.append(draw(plot, out_dir))
        except Exception as exc:  # noqa: BLE001
            result.rows.append(row(scene.name, plot.get("study", "-"), "-", "figure", float("nan"), passed=False,
                                   status="failed", note=f"figure {plot.get('kind')}: {type(exc).__name__}: {exc}"))
    return result
