"""Shared helpers of the stability study: rows, the RK4 entry point, fits."""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

import rk4core

__all__ = ["StudyResult", "row", "integrate_fixed", "loglog_slope", "mode_amplitudes"]


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
    status, not by a warning.
    """
    kw = {"h": h} if n_steps is None else {"n_steps": int(n_steps)}
    solver = _fast_solver() if fast else None
    with np.errstate(all="ignore"):
        if solver is not None:
            try:
                return solver(model, t_span, y0, t_eval=t_eval, method=method,
                              record_every=record_every, **kw), "fast"
            except Exception:  # noqa: BLE001 - compiled path unavailable: use the generic loop
                pass
        res = rk4core.solve(model.rhs, t_span, y0, t_eval=t_eval, method=method, **kw)
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
