"""heyoka's adaptive Taylor integrator (``heyoka.taylor_adaptive``), in double
precision for the ``heyoka`` solver and in quadruple precision
(``heyoka.real128``) for :mod:`rk4h.references.truth`.

Equations: ``model.heyoka_system()``, i.e. the model's one ``_force`` evaluated
on heyoka expressions, rewritten for the scaled state ``z = y / s`` with the
two scales ``s = (s_q, s_v)`` as runtime parameters ``par[0], par[1]``:
``zq' = (s_v / s_q) zv``, ``zv' = a(s_q zq) / s_v``. heyoka's single
tolerance is absolute while ``max |z_i| < 1`` and relative above it; with
``tol = rtol`` and ``s`` from :mod:`rk4h.references.solvers.tolerances` this is the
rule ``atol_i = rtol * s_i`` of the other adaptive solvers. The model constants
are Python floats in the expressions, so the real128 integration uses exactly
the doubles the double-precision solvers use.

Compilation happens once per (model, parameters, tolerance, precision): the
integrator is cached and reused across initial states and runs (time, state
and the scale parameters are reset each run; a Taylor step depends only on
the current state, so a reused integrator gives the same result as a fresh
one). ``compile_s`` is the JIT time of the integrator a run used, measured
when it was compiled, for this run or an earlier one in the process
(``extra["cached"]`` says which), so that a run's one-run cost does not depend
on the scenes a worker process happened to run before it; for the same reason
heyoka's one-time start-up in a process (``python
benchmarks/bench_heyoka_startup.py``: a first compile of the 2-DOF model
15.1 ms, the same system again 2.5 ms) is paid by an untimed compile of a
one-line system before the first timed one, and is in no ``compile_s``,
like the imports. Output times
come from ``propagate_grid`` (Taylor dense output), with heyoka's own
``max_steps`` cap (outcome ``step_limit``, status FAILED). When heyoka stops
early (a non-finite state, e.g. a spring of zero length reached mid-run; the
step cap) it returns fewer rows than the grid: :func:`propagate` pads them
with NaN to the full grid, and the run is UNSTABLE (``err_nf_state``) or
FAILED with ``t_fail``, never an exception. heyoka evaluates no
right-hand side: ``nfev = 0``, ``n_steps`` = Taylor steps, ``taylor_order`` =
the order heyoka chose for the tolerance.

References
----------
F. Biscani, D. Izzo, "Revisiting high-order Taylor methods for astrodynamics and
celestial mechanics", MNRAS 504 (2021) 2614-2628.
"""
from __future__ import annotations

import functools
import json
import math
import time

import numpy as np

from .base import SolverRun, Status

__all__ = ["scaled_system", "get_integrator", "propagate", "outcome_status", "stop_time", "run_heyoka", "model_key",
           "clear_cache", "start_up", "DEFAULT_MAX_STEPS"]

#: Default cap on Taylor steps in one run (as CVODE's and DOP853's).
DEFAULT_MAX_STEPS = 5_000_000

#: (model key, tol, fp_type) -> (taylor_adaptive, compile seconds)
_CACHE: dict = {}
#: Systems with more state components than this are compiled in compact mode.
COMPACT_ABOVE = 40


def model_key(model) -> str:
    """A string identifying the model's equations (name and parameters)."""
    cls = f"{type(model).__module__}.{type(model).__qualname__}"
    return json.dumps({"name": model.name, "class": cls, "params": model.params()}, sort_keys=True,
                      default=repr)


def clear_cache() -> None:
    _CACHE.clear()


def scaled_system(model):
    """``(zvars, [(z_i, dz_i/dt)])`` for the scaled state ``z = y / s``.

    Runtime parameters: ``par[0] = s_q``, ``par[1] = s_v``, ``par[2 + i]`` = the
    generalized mass ``m_i``. The force is the model's ``_force`` on heyoka
    expressions (as in ``model.heyoka_system()``), but the mass enters as a
    parameter: heyoka folds ``f / m`` with a numeric ``m`` into ``f * fl(1/m)``
    with the reciprocal rounded to double, which in real128 is a different
    mass (relative 1e-17) and breaks energy conservation at that level.
    """
    from rk4h._heyoka import heyoka as _heyoka
    hy = _heyoka()

    from rk4h.models import HEYOKA

    n = model.n_dof
    names = [f"z{i}" for i in range(2 * n)]
    zs = hy.make_vars(*names)
    zs = list(zs) if isinstance(zs, (list, tuple)) else [zs]
    sq, sv = hy.par[0], hy.par[1]
    q = np.array([sq * zs[i] for i in range(n)], dtype=object)
    f = np.asarray(model._force(q, HEYOKA), dtype=object).reshape(-1)
    dq = [(sv * zs[n + i]) / sq for i in range(n)]
    dv = [f[i] / (sv * hy.par[2 + i]) for i in range(n)]
    return zs, list(zip(zs, dq + dv))


def _pars(model, scales, dtype=float):
    return np.concatenate([np.asarray(scales, dtype=float), np.asarray(model.mass, dtype=float)]).astype(dtype)


@functools.cache
def start_up() -> None:
    """heyoka's one-time start-up in this process, untimed (module docstring):
    a compile of a one-line system, done once."""
    from rk4h._heyoka import heyoka as _heyoka
    hy = _heyoka()

    x, v = hy.make_vars("x", "v")
    hy.taylor_adaptive([(x, v), (v, -x)], [0.0, 1.0], tol=1e-6)


def get_integrator(model, tol: float, fp_type: str = "double"):
    """``(ta, compile_s, cached)``: the ``taylor_adaptive`` for ``(model, tol,
    fp_type)``, the seconds its compilation took (now, or when it was cached)
    and whether it came from the cache."""
    from rk4h._heyoka import heyoka as _heyoka
    hy = _heyoka()

    key = (model_key(model), float(tol), fp_type)
    hit = _CACHE.get(key)
    if hit is not None:
        return hit[0], hit[1], True
    start_up()
    _, sys = scaled_system(model)
    n2 = 2 * model.n_dof
    start = time.perf_counter()
    if fp_type == "real128":
        R = hy.real128
        ta = hy.taylor_adaptive(sys, np.zeros(n2, dtype=R), tol=R(tol), fp_type=R,
                                pars=_pars(model, (1.0, 1.0), R), compact_mode=True)
    else:
        ta = hy.taylor_adaptive(sys, np.zeros(n2), tol=float(tol), pars=_pars(model, (1.0, 1.0)),
                                compact_mode=n2 > COMPACT_ABOVE)
    compile_s = time.perf_counter() - start
    _CACHE[key] = (ta, compile_s)
    return ta, compile_s, False


def _propagate_grid(ta, grid, max_steps: int):
    """``ta.propagate_grid(grid, max_steps=max_steps)`` (one place, so that
    tests can stand in for heyoka's result)."""
    return ta.propagate_grid(grid, max_steps=int(max_steps))


def propagate(ta, model, y0, scales, t_eval, dtype=float, max_steps: int = DEFAULT_MAX_STEPS):
    """Reset ``ta`` to ``y0`` at ``t_eval[0]`` and propagate over ``t_eval``.

    Parameters
    ----------
    ta : heyoka.taylor_adaptive
    model : rk4h.models.Model
    y0 : ndarray, shape (2n,)
    scales : (float, float)
        ``(s_q, s_v)`` of the tolerance rule.
    t_eval : ndarray, shape (m,)
        Output times (s).
    dtype : type
        ``float`` or ``heyoka.real128``.
    max_steps : int
        heyoka's cap on Taylor steps (outcome ``step_limit`` when reached).

    Returns
    -------
    outcome : heyoka.taylor_outcome
    n_steps : int
        Taylor steps taken.
    y : ndarray, shape (2n, m)
        Unscaled states in ``dtype``; NaN where heyoka did not get (heyoka
        returns only the rows it reached when it stops early; they are padded
        here to the full grid).
    n_rows : int
        Output times heyoka returned.
    """
    n2 = y0.shape[0]
    n = n2 // 2
    m = np.asarray(t_eval).shape[0]
    s = np.concatenate([np.full(n, scales[0]), np.full(n, scales[1])]).astype(dtype)
    ta.time = dtype(t_eval[0]) if dtype is not float else float(t_eval[0])
    ta.state[:] = np.asarray(y0).astype(dtype) / s
    ta.pars[:] = _pars(model, scales, dtype)
    grid = np.asarray(t_eval).astype(dtype)
    res = _propagate_grid(ta, grid, max_steps)
    outcome, n_steps = res[0], int(res[3])
    zs = np.asarray(res[5])
    y = np.full((n2, m), np.nan, dtype=dtype)
    rows = 0
    if zs.ndim == 2 and zs.shape[1] == n2:
        rows = min(int(zs.shape[0]), m)
        if rows:
            y[:, :rows] = (zs[:rows] * s).T
    return outcome, n_steps, y, rows


def stop_time(ta, t_eval, n_rows: int) -> float:
    """Where a run that stopped early got to (s): heyoka's time when it is
    finite (after a non-finite state it can be NaN), else the last output time
    reached (``t_eval[0]`` if none)."""
    t = float(ta.time)
    if math.isfinite(t):
        return t
    return float(t_eval[n_rows - 1]) if n_rows > 0 else float(t_eval[0])


def outcome_status(outcome, n_rows: int, m: int, max_steps: int, t_fail: float, who: str):
    """``(status, message)`` of a heyoka ``propagate_grid`` outcome.

    ``time_limit`` with every row is OK; ``err_nf_state`` (a non-finite
    state) is UNSTABLE; ``step_limit`` (the ``max_steps`` cap) and anything
    else, or fewer rows than the grid, are FAILED. ``t_fail`` (s) is heyoka's
    time when it stopped."""
    from rk4h._heyoka import heyoka as _heyoka
    hy = _heyoka()

    if outcome == hy.taylor_outcome.time_limit and n_rows == m:
        return Status.OK, ""
    got = f"; {n_rows} of {m} output times reached"
    if outcome == hy.taylor_outcome.err_nf_state:
        return Status.UNSTABLE, f"{who}: the state became non-finite at t = {t_fail:.6g}{got}"
    if outcome == hy.taylor_outcome.step_limit:
        return Status.FAILED, f"{who}: step cap max_steps = {max_steps} reached at t = {t_fail:.6g}{got}"
    return Status.FAILED, f"{who}: propagate_grid stopped with {outcome} at t = {t_fail:.6g}{got}"


def run_heyoka(model, y0: np.ndarray, t_eval: np.ndarray, rtol: float, atol: np.ndarray,
               max_steps: int = DEFAULT_MAX_STEPS) -> SolverRun:
    """Integrate ``model`` with double-precision heyoka at ``tol = rtol``; the
    scales are ``atol / rtol`` (per group: the smallest); at most ``max_steps``
    Taylor steps. Never raises."""
    n = model.n_dof
    scales = (float(np.min(atol[:n])) / rtol, float(np.min(atol[n:])) / rtol)
    m = t_eval.shape[0]
    y = np.full((2 * n, m), np.nan)
    extra = {"atol_state": atol, "scales": scales}
    compile_s, order, n_steps, t_fail = 0.0, None, 0, None
    try:
        ta, compile_s, extra["cached"] = get_integrator(model, rtol)
        order = int(ta.order)
        start = time.perf_counter()
        with np.errstate(over="ignore", invalid="ignore"):
            outcome, n_steps, y, rows = propagate(ta, model, y0, scales, t_eval, max_steps=max_steps)
        wall = time.perf_counter() - start
        extra["rows_returned"] = rows
        t_stop = stop_time(ta, t_eval, rows)
        status, message = outcome_status(outcome, rows, m, max_steps, t_stop, "heyoka")
        if status is Status.OK:
            message = "heyoka: reached the end of the interval"
        else:
            t_fail = t_stop
            y[:, t_eval > t_fail] = np.nan
    except Exception as exc:  # noqa: BLE001 - a failure inside is a status, not an exception
        wall = 0.0
        status, message, t_fail = Status.FAILED, f"heyoka: {type(exc).__name__}: {exc}", float(t_eval[0])
        y = np.full((2 * n, m), np.nan)
    return SolverRun("heyoka", rtol, t_eval, y, 0, n_steps, wall, compile_s=compile_s, status=status,
                     message=message, atol=float(atol[0]), taylor_order=order, t_fail=t_fail, extra=extra)
