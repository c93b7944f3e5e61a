"""A ``command`` method: an external program run through the file protocol of
:mod:`rk4h.command`, behind the solver interface (:class:`SolverRun`).

The harness owns the grid, as for every fixed-step method: ``n =
ceil((t_end - t0) / h)`` equal steps of ``h_used = (t_end - t0) / n``
(``rk4h.solve``'s rule); ``t_eval`` must lie on that grid (the scenes'
output grids do), other times end the run FAILED. The problem the program
reads is built from the model (:func:`build_problem`); the states it returns
at ``t_eval`` are judged like a fixed-step run's: the first output with a
non-finite component, or one beyond :data:`rk4h.references.solvers.fixed.MAX_GROWTH`
times its group scale, ends the run UNSTABLE (``y`` NaN from there).

Status: ``ok``; ``failed`` (non-zero exit, timeout, malformed output: the
message says which); ``unavailable`` (the program is not installed: the
message names it and how to install it). Never raises for the program.

``nfev``: ``stats.json``'s count when the program writes one; else
``nfev_per_step * n_steps`` when the method declares its cost; else 0, and
``extra["nfev_note"]`` says it is unknown; 0 for an ``unavailable`` program
(``extra["nfev_source"]`` is ``"not run"``; the report shows no count). ``wall_s`` is the program's whole
run, its start-up included (GNU Octave: about 0.3 s).
"""
from __future__ import annotations

import numpy as np

from rk4h.command import DEFAULT_TIMEOUT, LAYOUT, PROTOCOL_VERSION, run_command
from rk4h.solver import grid_times, step_count

from .base import SolverRun, Status
from .fixed import MAX_GROWTH
from .tolerances import state_scale

__all__ = ["run_command_method", "build_problem", "DENSE_K_MAX"]

#: Largest n_dof for which the problem carries the dense stiffness matrix.
DENSE_K_MAX = 1000

_STATUS = {"ok": Status.OK, "failed": Status.FAILED, "unavailable": Status.UNAVAILABLE}


def _plain(value):
    """``value`` as plain JSON types (numpy scalars and arrays, tuples)."""
    if isinstance(value, dict):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    if isinstance(value, np.ndarray):
        return _plain(value.tolist())
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        return float(value)
    if value is None or isinstance(value, str):
        return value
    return str(value)


def _first_doc_line(obj) -> str:
    doc = (getattr(obj, "__doc__", None) or "").strip()
    return " ".join(doc.split("\n\n")[0].split())


def build_problem(model, y0, t_eval, h: float, *, t0: float | None = None) -> tuple[dict, np.ndarray, float]:
    """The protocol-1 problem of ``model`` from ``y0`` at ``t0`` over the grid
    of largest step ``h`` to ``t_eval[-1]``.

    Parameters
    ----------
    model : rk4h.models.Model
    y0 : array_like, shape (2 n_dof,)
        Initial state ``[q, v]`` at ``t0`` (SI units).
    t_eval : array_like, shape (m,)
        Output times (s), increasing, on the step grid.
    h : float
        Largest step (s); the step used is ``(t_end - t0) / ceil(...)``.
    t0 : float, optional
        Initial time (s); default ``t_eval[0]``.

    Returns
    -------
    problem : dict
    index : ndarray of int, shape (m,)
        The grid index of each output time.
    h_used : float

    Raises
    ------
    ValueError
        An output time is not on the step grid, or before ``t0``.
    """
    t_eval = np.asarray(t_eval, dtype=float)
    y0 = np.asarray(y0, dtype=float)
    t0 = float(t_eval[0]) if t0 is None else float(t0)
    t1 = float(t_eval[-1])
    n = step_count((t0, t1), float(h))
    step = (t1 - t0) / n
    idx = np.rint((t_eval - t0) / step).astype(np.int64)
    grid = grid_times(t0, t1, step, idx, n)
    tol = 1e-9 * step + 4.0 * float(np.spacing(max(abs(t0), abs(t1))))
    off = np.flatnonzero((np.abs(grid - t_eval) > tol) | (idx < 0))
    if off.size:
        raise ValueError(f"`t_eval`: t = {t_eval[off[0]]!r} is not on the step grid t0 + i h of h = {step!r} "
                         f"(t0 = {t0!r}); a command method returns states only on its grid")
    nd = int(model.n_dof)
    problem = {
        "protocol": PROTOCOL_VERSION,
        "model": model.name,
        "params": _plain(model.params()),
        "n_dof": nd,
        "coordinates": [str(c) for c in getattr(model, "coord_names", [])],
        "layout": LAYOUT,
        "y0": [float(v) for v in y0],
        "t0": t0,
        "t_end": t1,
        "h": step,
        "n_steps": int(n),
        "t_eval": [float(v) for v in grid],
    }
    masses = [float(v) for v in np.asarray(model.mass, dtype=float)]
    if getattr(model, "linear", False) and nd <= DENSE_K_MAX:
        K = model.stiffness_matrix()
        K = np.asarray(K.toarray() if hasattr(K, "toarray") else K, dtype=float)
        problem["stiffness_matrix"] = K.tolist()
        problem["masses"] = masses
        problem["rhs"] = ("q' = v, diag(masses) v' = -stiffness_matrix q (linear; y = [q, v], SI units)")
    else:
        what = _first_doc_line(type(model)) or f"model {model.name}"
        problem["rhs"] = (f"q' = v, m_i v_i' = F_i(q) with F = -grad V(q), V the potential of the harness' "
                          f"model {model.name!r} with these params ({what}); generalized masses m = "
                          f"{masses}; y = [q, v], SI units")
    return problem, idx, step


def run_command_method(name: str, argv, model, y0, t_eval, h: float, *, nfev_per_step=None,
                       t0: float | None = None, timeout: float = DEFAULT_TIMEOUT) -> SolverRun:
    """Integrate ``model`` with the external program ``argv``; never raises
    for the program (see the module docstring).

    Parameters
    ----------
    name : str
        The method's name (``SolverRun.solver``).
    argv : list of str
        Its command line, with the placeholders of :mod:`rk4h.command`.
    model : rk4h.models.Model
    y0 : array_like, shape (2 n_dof,)
    t_eval : array_like, shape (m,)
        Output times (s) on the step grid; the run starts at ``t0``.
    h : float
        Largest step (s).
    nfev_per_step : int, optional
        The method's declared right-hand-side evaluations per step.
    t0 : float, optional
        Initial time (s); default ``t_eval[0]``.
    timeout : float
        Seconds before the program is killed.

    Returns
    -------
    SolverRun
        ``extra``: ``h_used``, ``path`` ("command"), ``argv``, ``nfev_source``
        ("stats.json", "nfev_per_step" or "unknown"), ``nfev_note``,
        ``leftovers``, ``stderr_tail``.
    """
    t_eval = np.asarray(t_eval, dtype=float)
    y0 = np.asarray(y0, dtype=float)
    y_out = np.full((y0.shape[0], t_eval.shape[0]), np.nan)
    t_start = float(t_eval[0]) if t0 is None else float(t0)
    try:
        problem, idx, step = build_problem(model, y0, t_eval, h, t0=t0)
    except ValueError as e:
        return SolverRun(name, h, t_eval, y_out, 0, 0, 0.0, status=Status.FAILED, t_fail=t_start,
                         message=f"{name}: {e}", extra={"path": "command"})
    n = problem["n_steps"]
    res = run_command(argv, problem, timeout=timeout)
    extra = {"h_used": step, "path": "command", "argv": list(res.argv), "leftovers": list(res.leftovers),
             "stderr_tail": res.stderr[-500:]}
    if res.nfev is not None:
        nfev, extra["nfev_source"] = int(res.nfev), "stats.json"
    elif nfev_per_step is not None:
        nfev, extra["nfev_source"] = int(nfev_per_step) * n, "nfev_per_step"
    else:
        nfev, extra["nfev_source"] = 0, "unknown"
        extra["nfev_note"] = ("the program wrote no stats.json and the method declares no nfev_per_step: "
                              "nfev is unknown, reported as 0")
    status = _STATUS[res.status]
    if status is Status.UNAVAILABLE:  # the program never ran: no evaluations to count
        nfev, extra["nfev_source"] = 0, "not run"
        extra.pop("nfev_note", None)
    message = f"{name}: {res.message}" if res.message else f"{name}: reached t_end"
    if status is not Status.OK:
        return SolverRun(name, h, t_eval, y_out, nfev, 0, res.wall_s, status=status, message=message,
                         t_fail=t_start, extra=extra)
    y = res.y
    bound = MAX_GROWTH * state_scale(model, y0)
    with np.errstate(invalid="ignore"):
        bad = np.flatnonzero(~np.all(np.abs(y) <= bound[:, None], axis=0))
    t_fail = None
    if bad.size:
        k = int(bad[0])
        y = y.copy()
        y[:, k:] = np.nan
        t_fail = float(t_eval[k])
        status = Status.UNSTABLE
        message = (f"{name}: state not finite or beyond {MAX_GROWTH:g} x its scale at t = {t_fail:g} s "
                   f"(the program's output)")
    y_out[:, :] = y
    steps = n if status is Status.OK else int(idx[int(bad[0])])
    return SolverRun(name, h, t_eval, y_out, nfev, steps, res.wall_s, status=status, message=message,
                     t_fail=t_fail, extra=extra)
