"""The tableau methods of the system under test (``rk4``, ``euler``,
``symplectic-euler``, any scene's own tableau). Built-in models run through the compiled fast path
(``rk4h.fast.solve_model``: the same numbers as ``rk4h.solve`` on
``model.rhs``, tested to 1e-14); any other model through ``rk4h.solve`` on
``model.rhs``. Compile/cache-load time of the fast path is ``compile_s``, kept
out of ``wall_s``; ``extra["path"]`` says which path ran.

``setting`` is the largest step ``h`` (s); the step used is
``(t_eval[-1] - t_eval[0]) / ceil(...)`` (``extra["h_used"]``). Output times on
the step grid are returned exactly, others by cubic Hermite interpolation
(``extra["dense"]`` says which). ``nfev`` is the method's own count
(``Tableau.nfev_per_step`` per step, first-same-as-last reuse counted: see
``rk4h.solve``), plus one end-slope evaluation per step that holds
off-grid outputs.

A run is UNSTABLE (with ``t_fail``; ``y`` NaN from the first output time not
reached) at the first step where a component is non-finite or exceeds
:data:`MAX_GROWTH` times its group scale (``s_q`` for positions, ``s_v`` for
velocities: :func:`rk4h.references.solvers.tolerances.state_scale`, the amplitude of
a state with the initial energy). Why that bound: on a linear conservative
model a step inside the method's stability region (``|R(i omega_j h)| <= 1`` on
every mode) never increases the energy, so every component stays below
``sqrt(n_dof m_max / m_min)`` times its scale (energy bound); on the shipped
models that is at most a few thousand. Exceeding 1e6 therefore means the
amplification ``|R|^n`` of some mode passed 1e6: the method left its
stability region (explicit Euler, whose ``|R| = sqrt(1 + theta^2) > 1`` at
every step, included). A run at 1e145 is never labelled ``ok``.
"""
from __future__ import annotations

import math
import time

import numpy as np

import rk4h
import rk4h.fast as fast

from rk4h.fast.solve import solve_checked
from rk4h.solver import _DBL_MAX

from .base import SolverRun, Status
from .tolerances import group_scales, state_scale

__all__ = ["run_fixed", "MAX_GROWTH"]

#: A fixed-step run stops as UNSTABLE when a component exceeds this many times
#: its group scale (see the module docstring).
MAX_GROWTH = 1e6


def run_fixed(method, model, y0: np.ndarray, t_eval: np.ndarray, h: float) -> SolverRun:
    """Integrate ``model`` with the tableau ``method`` (an
    ``rk4h.methods.Tableau`` or a built-in name); never raises.

    The arguments are those :func:`rk4h.references.solvers.integrate` has checked:
    ``y0`` a finite float64 array of length ``2 n_dof`` (a state where the
    model's force is finite), ``t_eval`` a finite, strictly increasing
    float64 array of at least 2 times (s), ``h > 0`` finite (s)."""
    tab = rk4h.get_method(method)
    name = tab.name
    m = t_eval.shape[0]
    use_fast = fast.supports(model)
    compile_s = fast.warm_up(model, tab) if use_fast else 0.0
    s_q, s_v = group_scales(model, y0)
    trusted = use_fast and math.isfinite(s_q) and math.isfinite(s_v)
    if trusted:  # growth_bound(y0, MAX_GROWTH, state_scale(model, y0)), without the array round trip
        n_dof = model.n_dof
        growth = np.empty(2 * n_dof)
        growth[:n_dof] = min(MAX_GROWTH * s_q, _DBL_MAX)
        growth[n_dof:] = min(MAX_GROWTH * s_v, _DBL_MAX)
    else:
        bound = {"max_growth": MAX_GROWTH, "y_scale": state_scale(model, y0)}
    start = time.perf_counter()
    try:
        if trusted:
            # integrate() has checked y0, t_eval and h: the loop without solve_model's second round of checks
            res = solve_checked(model, t_eval, y0, h, tab, growth)
        elif use_fast:
            res = fast.solve_model(model, (t_eval[0], t_eval[-1]), y0, h=h, t_eval=t_eval, method=tab, **bound)
        else:
            res = rk4h.solve(model.rhs, (t_eval[0], t_eval[-1]), y0, h=h, t_eval=t_eval, method=tab,
                                **bound)
    except Exception as exc:  # noqa: BLE001 - a failure inside is a status, not an exception
        return SolverRun(name, h, t_eval, np.full((y0.shape[0], m), np.nan), 0, 0, time.perf_counter() - start, compile_s, status=Status.FAILED,
                         message=f"{name}: {type(exc).__name__}: {exc}", t_fail=float(t_eval[0]))
    wall = time.perf_counter() - start
    reached = res.y.shape[1]
    if reached == m:
        y = np.ascontiguousarray(res.y)
    else:
        y = np.full((y0.shape[0], m), np.nan)
        y[:, :reached] = res.y
    status = Status.OK if res.success else Status.UNSTABLE
    return SolverRun(name, h, t_eval, y, int(res.nfev), int(res.n_steps), wall, compile_s, status=status,
                     message=res.message, t_fail=res.t_fail,
                     extra={"h_used": res.h, "dense": res.dense, "path": "numba" if use_fast else "python",
                            "reason": res.reason})
