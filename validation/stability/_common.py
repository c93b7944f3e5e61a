"""Shared pieces of the stability study: the result type, tidy rows, the one
fixed-step entry point, the one error metric, fits."""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

import rk4h

from ..metrics import error_max

__all__ = ["stiffest_index", "cost_at_point", "FREQUENCY_RATIO", "SWEEP_NAMES",
           "StudyResult", "row", "COLUMNS", "PARAM_COLUMNS", "TIMING_COLUMNS", "integrate_fixed", "error_rel",
           "loglog_slope", "mode_amplitudes", "MAX_STEP_WORK", "StudyCapError", "frequency_range", "heyoka_steps"]

#: Cap on one fixed-step run of a study: steps x degrees of freedom (about
#: 2.5e9 steps of a 2-DOF chain, a minute or two on the compiled path). A run
#: beyond it is refused before it starts (:class:`StudyCapError`), so no
#: parameter combination starts a run of days.
MAX_STEP_WORK = 5e9

#: Parameter columns of ``stability.csv``: NaN where a row has no such parameter.
#: theta = omega h (rad; of the fastest mode, or of ``mode``), mode (1 = slowest),
#: mu = m2/m1, ratio = stiff spring / the others, stiffness_ratio = the cost
#: point's omega_max / omega_min (derived from mu or ratio), n = masses of a chain,
#: a_over_l = initial amplitude / natural length, offset (m) = aim past an anchor,
#: periods = run length in periods of the slowest mode, target_error = the
#: relative error a cost row is measured at.
PARAM_COLUMNS = ("theta", "mode", "mu", "ratio", "stiffness_ratio", "n", "a_over_l", "offset", "periods", "target_error")

#: Columns read from a clock (not reproducible): ``wall_s`` is the wall time (s)
#: of the run a row measures; ``measured_timed`` holds a row's measured value
#: when that value is itself derived from wall times (``measured`` is then NaN).
TIMING_COLUMNS = ("wall_s", "measured_timed")

#: Every column of ``stability.csv``, in order. All but :data:`TIMING_COLUMNS`
#: are deterministic: a rerun gives them bit for bit.
COLUMNS = ("scene", "study", "solver", "quantity", *PARAM_COLUMNS, "measured", "theory", "passed", "checked", "status",
           "note",
           *TIMING_COLUMNS)


class StudyCapError(ValueError):
    """A study run would exceed :data:`MAX_STEP_WORK`; the message says how big."""


@dataclass
class StudyResult:
    """What :func:`rk4h.validation.stability.run_unit` / :func:`~rk4h.validation.stability.assemble`
    return (plain data: picklable, and storable in a run record).

    Attributes
    ----------
    rows : list of dict
        ``stability.csv`` rows with the keys :data:`COLUMNS` (see :func:`row`).
    findings : list of str
        One-line conclusions for index.md.
    plots : list of dict
        Plot descriptions ``{"kind", "scene", "name", "data"}``: ``data`` a dict
        of numpy arrays, floats, strings (and dicts of those); drawn by
        :func:`rk4h.validation.stability.draw`.
    figures : list of (Path, str)
        Only filled by :func:`rk4h.validation.stability.run` (the old entry point),
        which draws the plots.
    """

    rows: list = field(default_factory=list)
    findings: list = field(default_factory=list)
    plots: list = field(default_factory=list)
    figures: list = field(default_factory=list)

    def extend(self, other: "StudyResult") -> None:
        self.rows += other.rows
        self.findings += other.findings
        self.plots += other.plots
        self.figures += other.figures


def row(scene, study, solver, quantity, measured, theory=math.nan, passed=None, status="ok", note="", *,
        wall_s=math.nan, measured_timed=math.nan, **params):
    """One ``stability.csv`` row (keys :data:`COLUMNS`). ``passed`` is None
    when the quantity is informative only (``checked`` False; the written
    table then says ``passed`` False, rk4h.validation.columns); ``params`` are
    :data:`PARAM_COLUMNS` (others raise ``TypeError``); the quantity is a bare
    name, its parameters go into those columns."""
    bad = set(params) - set(PARAM_COLUMNS)
    if bad:
        raise TypeError(f"unknown parameter column(s) {sorted(bad)}; known: {PARAM_COLUMNS}")
    if "(" in quantity or "=" in quantity:
        raise ValueError(f"`quantity` must be a bare name, got {quantity!r}")
    out = {"scene": scene, "study": study, "solver": solver, "quantity": quantity}
    for p in PARAM_COLUMNS:
        v = params.get(p)
        out[p] = math.nan if v is None else (int(v) if p in ("mode", "n") else float(v))
    out.update({"measured": float(measured), "theory": float(theory),
                "passed": None if passed is None else bool(passed), "checked": passed is not None,
                "status": status, "note": note,
                "wall_s": float(wall_s), "measured_timed": float(measured_timed)})
    return out


def integrate_fixed(model, t_span, y0, *, h=None, n_steps=None, t_eval=None, method="rk4", record_every=1):
    """Fixed-step run of ``model``: the compiled loop (``rk4h.fast.solve_model``)
    exactly when ``rk4h.fast.supports(model)``, else :func:`rk4h.solve` on
    ``model.rhs``. An exception on either path propagates (the caller's unit
    becomes a ``failed`` row); there is no silent fallback. ``record_every``
    keeps every k-th step (and the last).

    Returns the solver result (``.t``, ``.y``, ``.status``, ``.t_fail``, ...)
    and the name of the path used (``"fast"`` or ``"solve"``). Floating-point
    warnings are silenced here because a blow-up is reported by the result's
    status, not by a warning. A run of more than :data:`MAX_STEP_WORK` steps x
    DOF raises :class:`StudyCapError` before it starts. rk4core's growth stop
    (``max_growth``) is switched off: a blow-up here ends on a non-finite
    state, as the study's theory (``log(DBL_MAX) / log g`` steps) assumes.
    """
    from rk4h import fast

    kw = {"h": h} if n_steps is None else {"n_steps": int(n_steps)}
    steps = float(n_steps) if n_steps is not None else (
        math.ceil((t_span[1] - t_span[0]) / h) if h and math.isfinite(h) and h > 0 else math.inf)
    if steps * model.n_dof > MAX_STEP_WORK:
        raise StudyCapError(f"a {method} run of {steps:.3g} steps on {model.n_dof} degrees of freedom exceeds the "
                            f"study cap of {MAX_STEP_WORK:.3g} step x DOF (rk4h.validation.stability._common.MAX_STEP_WORK)")
    with np.errstate(all="ignore"):
        if fast.supports(model):
            return fast.solve_model(model, t_span, y0, t_eval=t_eval, method=method, record_every=record_every,
                                    max_growth=None, **kw), "fast"
        res = rk4h.solve(model.rhs, t_span, y0, t_eval=t_eval, method=method, max_growth=None, **kw)
        if record_every > 1 and t_eval is None:
            keep = np.unique(np.r_[np.arange(0, res.t.shape[0], record_every), res.t.shape[0] - 1])
            res.t, res.y = res.t[keep], res.y[:, keep]
        return res, "solve"


def error_rel(model, y, y_ref, scale) -> float:
    """The study's one error metric: ``max_i |q_i - q_i^ref| / scale`` over the
    position components (and output times) of ``y`` (rk4h.validation.metrics.error_max
    of the positions, divided by ``scale``, e.g. ``max |q(0)|``); NaN when ``y``
    is not finite."""
    n = model.n_dof
    y, y_ref = np.asarray(y, float), np.asarray(y_ref, float)
    return error_max(y[:n], y_ref[:n]) / scale


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


def frequency_range(model) -> tuple[float, float]:
    """``(omega_min, omega_max)`` (rad/s): the slowest non-zero and the fastest
    natural angular frequency of ``model``'s linearization, from
    ``model.frequency_range()`` (see :mod:`rk4h.validation.stability.estimate`)."""
    lo, hi = model.frequency_range()
    return float(lo), float(hi)


def heyoka_steps(p_fast, p_exc):
    """heyoka's Taylor steps over ``p_fast`` periods of the fastest mode
    (``p_exc`` of the fastest excited one); calibrated on the shipped scenes."""
    return max(1.2 * p_fast, 3.5 * p_exc) + 15


#: The name of ``stiffness_ratio`` (omega_max/omega_min of the linearization) in
#: every caption, finding and table line; the swept parameters have their own.
FREQUENCY_RATIO = "omega_max/omega_min"
#: Cost sweeps: swept column -> its name in text (never "stiffness ratio": that
#: would read as omega_max/omega_min).
SWEEP_NAMES = {"ratio": "spring ratio k_mid/k", "mu": "mass ratio mu"}


def stiffest_index(x, stiffness_ratio, rtol: float = 1e-9) -> int:
    """Index of a cost sweep's stiffest point, the one its caption, finding and
    limits line all quote: the largest ``stiffness_ratio`` (omega_max/omega_min;
    equal to ``rtol``, as mu and 1/mu are), among those the largest ``x``."""
    x, r = np.asarray(x, float), np.asarray(stiffness_ratio, float)
    fin = np.isfinite(r)
    if not fin.any():
        raise ValueError("no finite stiffness ratio in the sweep")
    top = fin & (r >= np.nanmax(r) * (1.0 - rtol))
    cand = np.flatnonzero(top)
    return int(cand[np.argmax(x[cand])])


def cost_at_point(solver: str, nfev: float, status: str) -> str:
    """``"rk4 2.65e+06"``, or the solver's status where it has no cost there
    (``"cvode-bdf skipped"``)."""
    return f"{solver} {nfev:.3g}" if status == "ok" and math.isfinite(nfev) else f"{solver} {status or 'not run'}"
