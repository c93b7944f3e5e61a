"""Numerical-stability study (issue 6): where fixed-step RK4 breaks, what it
costs to stay accurate, and what the references do there.

``run(scene, out_dir, quick, progress=None) -> StudyResult`` runs the studies a
scene's ``[stability]`` table names (see :mod:`.params`) and returns
``stability.csv`` rows (scene, solver, quantity, measured, theory, passed,
status, note), figures ``(Path, sentence)`` and one-line findings. Computation
lives in :mod:`.boundary`, :mod:`.long_horizon`, :mod:`.stiffness`,
:mod:`.mass_ratio`, :mod:`.large_n`, :mod:`.geometry`; drawing in :mod:`.plots`.

A study that fails (a bug, a missing solver, a run beyond the work cap
``_common.MAX_STEP_WORK``) becomes a row with status ``failed`` and the error
in its note; it never raises into the runner. :func:`estimate_steps` says
beforehand how many integration steps a scene's study will take, without
integrating (:mod:`.estimate`); :data:`PARAMS` holds every key's bounds.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from ._common import StudyResult, row
from .estimate import estimate_steps
from .params import DEFAULTS, PARAMS, STUDIES, params_table_markdown, validate_params

__all__ = ["run", "validate_params", "estimate_steps", "StudyResult", "STUDIES", "DEFAULTS", "PARAMS",
           "params_table_markdown"]


def run(scene, out_dir, quick: bool, progress=None) -> StudyResult:
    """Run the stability studies of ``scene`` (a :class:`validation.scenes.Scene`
    whose ``stability`` dict names them) and return a :class:`StudyResult`."""
    from .studies import STUDY_FUNCTIONS, Context

    params = validate_params(scene.stability or {})
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    ctx = Context(scene.name, scene.build_model(), np.asarray(scene.y0(), float), params, bool(quick),
                  out_dir, progress)
    result = StudyResult()
    for name in params["studies"]:
        ctx.say(name)
        try:
            with np.errstate(all="ignore"):  # blow-ups are reported by status, not warnings
                result.extend(STUDY_FUNCTIONS[name](ctx))
        except Exception as exc:  # noqa: BLE001 - a study failure is a row, not a crash
            result.rows.append(row(scene.name, "-", name, math.nan, passed=False, status="failed",
                                   note=f"{type(exc).__name__}: {exc}"))
    return result
