"""Shared helpers of the stability study: rows, the RK4 entry point, fits."""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

import rk4core

__all__ = ["StudyResult", "row", "integrate_fixed", "loglog_slope", "mode_amplitudes", "MAX_STEP_WORK",
           "StudyCapError"]

#: Cap on one fixed-step run of a study: steps x degrees of freedom (about
#: 2.5e9 steps of a 2-DOF chain, a minute or two on the compiled path). A run
#: beyond it is refused before it starts (:class:`StudyCapError`), so no
#: parameter combination starts a run of days.
MAX_STEP_WORK = 5e9


class StudyCapError(ValueError):
    """A study run would exceed :data:`MAX_STEP_WORK`; the message says how big."""


@dataclass
class StudyResult:
    """What :func:`validation.stability.run` returns.

    Attributes
    ----------
    rows : list of dict
        ``stability.csv`` rows: scene, solver, quantity, measured, theory,
        passed, and optionally status, note.
    figures : list of (Path, str)
        PNGs and the one-sentence reading of each.
    findings : list of str
        One-line conclusions for index.md.
    """

    rows: list = field(default_factory=list)
    figures: list = field(default_factory=list)
    findings: list = field(default_factory=list)

    def extend(self, other: "StudyResult") -> None:
        self.rows += other.rows
        self.figures += other.figures
        self.findings += other.findings


def row(scene, solver, quantity, measured, theory=math.nan, passed=None, status="ok", note=""):
    """One stability.csv row; ``passed`` is None (reported as empty) when the
    quantity is informative only."""
    return {"scene": scene, "solver": solver, "quantity": quantity,
            "measured": float(measured), "theory": float(theory),
            "passed": None if passed is None else bool(passed), "status": status, "note": note}


def _no_growth_stop(fn) -> dict:
    """``{"max_growth": None}`` when ``fn`` has rk4core's growth stop (a run is
    ended as unstable once the state grows ``max_growth`` times): the study
    measures growth factors up to 1e100 and blow-up times to overflow against
    ``log(DBL_MAX) / log g``, so it keeps only the non-finite test."""
    import inspect

    try:
        return {"max_growth": None} if "max_growth" in inspect.signature(fn).parameters else {}
    except (TypeError, ValueError):
        return {}


def _fast_solver():
    try:
        from rk4core import fast  # written in parallel; optional
    except ImportError:
        return None
    return getattr(fast, "solve_model", None)


def integrate_fixed(model, t_span, y0, *, h=None, n_steps=None, t_eval=None, method="rk4",
                    record_every=1, fast=True):
    """Fixed-step run of ``model``: the compiled path (``rk4core.fast.solve_model``)
    when it is installed and ``fast``, :func:`rk4core.solve` otherwise.
    ``record_every`` (compiled path only) keeps every k-th step.

    Returns the solver result (``.t``, ``.y``, ``.status``, ``.t_fail``, ...)
    and the name of the path used (``"fast"`` or ``"solve"``). Floating-point
    warnings are silenced here because a blow-up is reported by the result's
    status, not by a warning. A run of more than :data:`MAX_STEP_WORK` steps x
    DOF raises :class:`StudyCapError` before it starts. rk4core's growth stop
    (``max_growth``) is switched off: a blow-up here ends on a non-finite
    state, as the study's theory (``log(DBL_MAX) / log g`` steps) assumes.
    """
    kw = {"h": h} if n_steps is None else {"n_steps": int(n_steps)}
    steps = float(n_steps) if n_steps is not None else (
        math.ceil((t_span[1] - t_span[0]) / h) if h and math.isfinite(h) and h > 0 else math.inf)
    if steps * model.n_dof > MAX_STEP_WORK:
        raise StudyCapError(f"a {method} run of {steps:.3g} steps on {model.n_dof} degrees of freedom exceeds the "
                            f"study cap of {MAX_STEP_WORK:.3g} step x DOF (validation.stability._common.MAX_STEP_WORK)")
    solver = _fast_solver() if fast else None
    with np.errstate(all="ignore"):
        if solver is not None:
            try:
                return solver(model, t_span, y0, t_eval=t_eval, method=method,
                              record_every=record_every, **kw, **_no_growth_stop(solver)), "fast"
            except Exception:  # noqa: BLE001 - compiled path unavailable: use the generic loop
                pass
        res = rk4core.solve(model.rhs, t_span, y0, t_eval=t_eval, method=method, **kw,
                            **_no_growth_stop(rk4core.solve))
        if record_every > 1 and t_eval is None:
            keep = np.unique(np.r_[np.arange(0, res.t.shape[0], record_every), res.t.shape[0] - 1])
            res.t, res.y = res.t[keep], res.y[:, keep]
        return res, "solve"


def loglog_slope(x, y):
    """Least-squares slope of log(y) against log(x)."""
    lx, ly = np.log(np.asarray(x, float)), np.log(np.asarray(y, float))
    return float(np.polyfit(lx, ly, 1)[0])


def mode_amplitudes(model, y, modes=None):
    """Complex modal amplitudes ``z_j = omega_j eta_j - i eta_j'`` of states ``y``
    (shape (2n, m)); for the exact motion ``z_j(t) = z_j(0) exp(i omega_j t)``
    and the mode's energy is ``|z_j|^2 / 2``.

    Returns (omega, z) with z of shape (n_modes, m).
    """
    omega, phi = modes if modes is not None else model.modes()
    n = model.n_dof
    M = model.mass[:, None]
    eta = phi.T @ (M * y[:n])
    deta = phi.T @ (M * y[n:])
    return omega, omega[:, None] * eta - 1j * deta
