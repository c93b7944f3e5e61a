"""scipy's DOP853 (explicit Runge-Kutta 8(5,3), Hairer-Norsett-Wanner) on ``model.rhs``.

The stepping loop is the one ``scipy.integrate.solve_ivp(method="DOP853",
t_eval=...)`` runs, written out so that accepted steps can be counted: one
``DOP853.step()`` per accepted step, output times inside a step from the
method's 7th-order dense output, and the exact step end when it is an output
time. ``nfev`` is scipy's count (rejected steps included) plus the one
evaluation of the first-step selection (below); the guard evaluation of
``f(t0, y0)`` is not counted (scipy evaluates it again), so ``nfev`` is the
number scipy's own ``solve_ivp`` reports.

scipy raises ``rtol`` below ``100 * eps`` (2.2e-14) to that value with a
warning; here the clip is recorded in ``message`` and ``extra["rtol_used"]``.

Bounded work
------------
Every run ends, and quickly when the problem is ill-posed:

* ``f(t0, y0)`` is evaluated first; a non-finite value ends the run at once
  (status UNSTABLE, no step taken).
* The first step is computed here, by scipy's own rule (Hairer-Norsett-Wanner
  II.4, :func:`first_step`), and handed to scipy; a step that comes out
  non-finite or not positive ends the run (FAILED). scipy would otherwise
  start with ``h = nan``, which its minimum-step test (``h < min_step``) never
  catches: the step would be rejected forever.
* The right-hand side is called through a wrapper that counts the calls and
  raises a private exception, caught into status FAILED ("step cap ... reached"),
  past ``max_steps`` accepted steps or ``EVALS_PER_STEP * max_steps``
  evaluations (rejections included), and at once when scipy asks for it at a
  non-finite time (a NaN step).
* A run in which the right-hand side returned a non-finite value at a finite
  state (e.g. a spring of zero length reached mid-run) and which then fails
  is reported UNSTABLE, with the time it had reached.

References
----------
E. Hairer, S. P. Norsett, G. Wanner, *Solving Ordinary Differential Equations I*,
2nd ed., Springer 1993, sec. II.4 and II.10.
"""
from __future__ import annotations

import math
import time
import warnings

import numpy as np

from rk4h.fast.solve import compiled_entry, plain_vector

from .base import SolverRun, Status, compiled_rhs

__all__ = ["run_dop853", "run_dop853_compiled", "first_step", "RTOL_MIN", "EVALS_PER_STEP", "DEFAULT_MAX_STEPS"]

#: scipy's floor on rtol (``scipy.integrate._ivp.rk``: ``100 * EPS``).
RTOL_MIN = 100 * np.finfo(float).eps
#: Right-hand-side evaluations allowed per allowed step (12 stages, 3 more for
#: dense output, and room for rejected steps).
EVALS_PER_STEP = 30
#: Default cap on accepted DOP853 steps in one run (as CVODE's).
DEFAULT_MAX_STEPS = 5_000_000
#: DOP853's error estimator order (scipy: ``DOP853.error_estimator_order``).
_ORDER = 7


class _Stop(Exception):
    """Raised by the right-hand-side wrapper to end a run; ``status`` and
    ``message`` say why."""

    def __init__(self, status: Status, message: str):
        super().__init__(message)
        self.status, self.message = status, message


def _rms(x) -> float:
    return float(np.linalg.norm(x) / math.sqrt(x.size))


def first_step(fun, t0: float, y0: np.ndarray, t1: float, f0: np.ndarray, rtol: float,
               atol: np.ndarray, order: int = _ORDER) -> float:
    """The initial step (s) scipy would choose (``scipy.integrate._ivp.common.
    select_initial_step``, Hairer-Norsett-Wanner sec. II.4), computed here so
    that its value can be checked before the solver starts.

    Parameters
    ----------
    fun : callable
        ``fun(t, y)``; called once (at ``t0 + h0``).
    t0, t1 : float
        Start and end of the interval (s), ``t1 > t0``.
    y0, f0 : ndarray
        Initial state and ``fun(t0, y0)``.
    rtol : float
        Relative tolerance as scipy uses it (already clipped to ``RTOL_MIN``).
    atol : ndarray
        Absolute tolerance per component.
    order : int
        Error estimator order (7 for DOP853).

    Returns
    -------
    float
        The step; may be NaN, inf or 0 when ``f0`` or ``fun(t0 + h0, ...)`` is
        not finite (the caller checks).
    """
    interval = abs(t1 - t0)
    scale = atol + np.abs(y0) * rtol
    d0, d1 = _rms(y0 / scale), _rms(f0 / scale)
    h0 = 1e-6 if d0 < 1e-5 or d1 < 1e-5 else 0.01 * d0 / d1
    h0 = min(h0, interval)
    f1 = fun(t0 + h0, y0 + h0 * 1.0 * f0)
    d2 = _rms((f1 - f0) / scale) / h0
    if d1 <= 1e-15 and d2 <= 1e-15:
        h1 = max(1e-6, h0 * 1e-3)
    else:
        h1 = (0.01 / max(d1, d2)) ** (1 / (order + 1))
    return min(100 * h0, h1, interval)


def _closing_message(status, message: str, t_fail, note: str) -> str:
    """A DOP853 run's message (scipy's loop and the compiled one alike): the
    end reached, or what stopped it with the time of the last step."""
    if status is Status.OK:
        return "dop853: reached the end of the interval" + note
    if t_fail is not None and f"{t_fail:.6g}" not in message:
        message += f" (last step ended at t = {t_fail:.6g})"
    return message + note


def run_dop853(model, y0: np.ndarray, t_eval: np.ndarray, rtol: float, atol: np.ndarray,
               max_steps: int = DEFAULT_MAX_STEPS) -> SolverRun:
    """Integrate ``model`` with DOP853 at ``rtol``/``atol``; never raises, and
    ends after at most ``max_steps`` accepted steps (see the module docstring)."""
    # imported here, before the clock starts: scipy.integrate loads scipy.optimize and
    # scipy.special, which a process running only the compiled loop never uses
    from scipy.integrate import DOP853

    m = t_eval.shape[0]
    y = np.full((y0.shape[0], m), np.nan)
    y[:, 0] = y0
    rtol_used = max(rtol, RTOL_MIN)
    extra = {"rtol_used": rtol_used, "max_steps": int(max_steps)}
    note = f" (rtol {rtol:.3g} clipped to scipy's floor {RTOL_MIN:.3g})" if rtol < RTOL_MIN else ""
    max_evals = EVALS_PER_STEP * int(max_steps) + 100
    calls = [0]
    bad = []  # (t, which) of the first non-finite right-hand side at a finite state
    fast_rhs = compiled_rhs(model)
    extra["rhs"] = "compiled" if fast_rhs is not None else "numpy"
    if fast_rhs is not None:
        with np.errstate(all="ignore"):
            fast_rhs.checked(np.ascontiguousarray(y0, dtype=float))  # compiled (or loaded) before the clock starts
    n_state = y0.shape[0]
    if fast_rhs is not None and hasattr(fast_rhs, "permuted_parts"):
        # the compiled right-hand side called from this one frame through its
        # numba entry point (CVODE's glue; rk4h.references.solvers.cvode)
        with np.errstate(all="ignore"):
            disp, fp, ip, mass, ident, buf, w = fast_rhs.permuted_parts(np.arange(n_state), readonly=False)
        # looked up for a read-only state: the one signature the references'
        # right-hand side is compiled for (rk4h.fast.solve._one_signature);
        # the entry point reads a writable state of that layout alike
        yc = np.array(y0, dtype=float)
        yc.setflags(write=False)
        entry = compiled_entry(disp, (fp, ip, mass, yc, np.empty(n_state), ident, buf, w))
        entry = None if entry is disp else entry
    else:
        entry = None

    def fun(t, yy):
        calls[0] += 1
        if calls[0] > max_evals:
            raise _Stop(Status.FAILED, f"dop853: step cap reached ({max_evals} right-hand-side evaluations, "
                                       f"max_steps = {max_steps})")
        if not math.isfinite(t):
            raise _Stop(Status.FAILED, f"dop853: the step size became non-finite (right-hand side asked "
                                       f"for at t = {t!r})")
        # the entry point takes C-contiguous float64 vectors of the state's
        # length only, unchecked (scipy's stages are; anything else goes
        # through CompiledRHS.checked)
        if entry is not None and plain_vector(yy, n_state):
            f = np.empty(n_state)
            if entry(fp, ip, mass, yy, f, ident, buf, w) and not bad:
                bad.append(float(t))
            return f
        if fast_rhs is not None:
            f, nonfinite = fast_rhs.checked(yy)
            if nonfinite and not bad:
                bad.append(float(t))
            return f
        f = model.rhs(t, yy)
        if not bad and np.all(np.isfinite(yy)) and not np.all(np.isfinite(f)):
            bad.append(float(t))
        return f

    n_steps, k, extra_evals = 0, 1, 0
    status, message, t_fail = Status.OK, "", None
    solver = None
    start = time.perf_counter()
    t0, t1 = float(t_eval[0]), float(t_eval[-1])
    try:
        with warnings.catch_warnings(), np.errstate(over="ignore", invalid="ignore", divide="ignore"):
            warnings.simplefilter("ignore")
            f0 = np.asarray(model.rhs(t0, y0), dtype=float)
            if not np.all(np.isfinite(f0)):
                raise _Stop(Status.UNSTABLE, f"dop853: the right-hand side is not finite at the initial "
                                             f"state (t = {t0:.6g}); no step taken")
            h = first_step(fun, t0, y0, t1, f0, rtol_used, atol)
            extra_evals = calls[0]
            if not (math.isfinite(h) and h > 0.0):
                raise _Stop(Status.UNSTABLE if bad else Status.FAILED,
                            f"dop853: no usable first step (computed h = {h!r} s at t = {t0:.6g})")
            extra["first_step"] = h
            solver = DOP853(fun, t0, y0, t1, rtol=rtol, atol=atol, first_step=h)
            while solver.status == "running":
                if n_steps >= max_steps:
                    raise _Stop(Status.FAILED, f"dop853: step cap max_steps = {max_steps} reached at "
                                               f"t = {float(solver.t):.6g}")
                msg = solver.step()
                if solver.status == "failed":
                    if bad:
                        status = Status.UNSTABLE
                        message = (f"dop853: the right-hand side became non-finite at t = {bad[0]:.6g} "
                                   f"(a state where the force is undefined?); scipy: {msg}")
                    else:
                        status, message = Status.FAILED, f"dop853: {msg}"
                    t_fail = float(solver.t)
                    break
                n_steps += 1
                if not np.all(np.isfinite(solver.y)):
                    status, t_fail = Status.UNSTABLE, float(solver.t)
                    message = f"dop853: state became non-finite at t = {t_fail:.6g}"
                    break
                j = int(np.searchsorted(t_eval, solver.t, side="right"))
                if j > k:
                    sol = solver.dense_output()
                    y[:, k:j] = sol(t_eval[k:j])
                    if t_eval[j - 1] == solver.t:
                        y[:, j - 1] = solver.y
                    k = j
    except _Stop as stop:
        status, message = stop.status, stop.message
        t_fail = float(solver.t) if solver is not None else t0
        if status is Status.FAILED and bad and "step cap" not in message:
            status = Status.UNSTABLE
    except Exception as exc:  # noqa: BLE001 - a failure inside is a status, not an exception
        status, message = Status.FAILED, f"dop853: {type(exc).__name__}: {exc}"
        t_fail = float(solver.t) if solver is not None else t0
    wall = time.perf_counter() - start
    message = _closing_message(status, message, t_fail, note)
    if status is not Status.OK:
        y[:, k:] = np.nan
    nfev = (int(solver.nfev) + extra_evals) if solver is not None else calls[0]
    extra["nfev_calls"] = calls[0]
    return SolverRun("dop853", rtol, t_eval, y, nfev, n_steps, wall, status=status, message=message,
                     atol=float(atol[0]), t_fail=t_fail, extra={**extra, "atol_state": atol})


def run_dop853_compiled(model, y0: np.ndarray, t_eval: np.ndarray, rtol: float, atol: np.ndarray,
                        max_steps: int = DEFAULT_MAX_STEPS, *, name: str = "dop853") -> SolverRun:
    """:func:`run_dop853` with scipy's DOP853 loop compiled
    (:mod:`rk4h.fast.dop853`): the same method, step size control, first
    step, dense output, caps, statuses and messages, with the stage sums
    taken left to right instead of by BLAS, so each step equals scipy's to
    round-off (``tests/test_dop853_compiled.py``). Over a run, where a step
    is rejected near the tolerance, that round-off can send the decision
    the other way and the runs part, as scipy's own does when rtol moves
    one ulp (``benchmarks/dop853_parting.py``).
    For untimed work (confirmation runs): a user runs scipy's, which
    :func:`run_dop853` times. A model without a compiled right-hand side
    runs :func:`run_dop853`, as does one whose loop fails to compile
    (``extra["compiled_error"]`` says why). ``extra["implementation"]`` says which ran;
    ``compile_s`` is the first call's (compile or cache load) time, kept out
    of ``wall_s``; ``name`` is the run's ``solver``."""
    fast_rhs = compiled_rhs(model)
    if fast_rhs is None:
        run = run_dop853(model, y0, t_eval, rtol, atol, max_steps)
        run.solver = name
        run.extra["implementation"] = "scipy"
        return run
    from rk4h.fast import force_kernel
    from rk4h.fast.dop853 import STATUS_TEXT, coefficients, dop853_loop

    kern = force_kernel(model)
    m, n2 = t_eval.shape[0], y0.shape[0]
    rtol_used = max(rtol, RTOL_MIN)
    extra = {"rtol_used": rtol_used, "max_steps": int(max_steps), "rhs": "compiled", "implementation": "compiled"}
    note = f" (rtol {rtol:.3g} clipped to scipy's floor {RTOL_MIN:.3g})" if rtol < RTOL_MIN else ""
    max_evals = EVALS_PER_STEP * int(max_steps) + 100
    y0 = np.ascontiguousarray(y0, dtype=float)
    atol_c = np.array(np.broadcast_to(np.asarray(atol, dtype=float), y0.shape))  # a writable C-ordered copy
    t_c = np.ascontiguousarray(t_eval, dtype=float)
    coef = coefficients()
    args = (fast_rhs.fp, fast_rhs.ip, fast_rhs.mass, np.zeros(kern.work_size))
    ys = np.full((m, n2), np.nan)
    ys[0] = y0
    counts = np.zeros(4, dtype=np.int64)
    info = np.full(4, np.nan)
    t0, t1 = float(t_c[0]), float(t_c[-1])
    start = time.perf_counter()
    try:
        loop = dop853_loop(kern)
        with np.errstate(all="ignore"):  # compile (or load) now: max_steps = 0 ends after one evaluation
            loop(*args, np.full(4, np.nan), y0, t_c, 1.0, rtol_used, atol_c, *coef, 0, 100, ys.copy(),
                 np.zeros(4, dtype=np.int64))
    except Exception as exc:  # noqa: BLE001 - no compiled loop: scipy's, said in extra
        run = run_dop853(model, y0, t_eval, rtol, atol, max_steps)
        run.solver = name
        run.extra["implementation"] = "scipy"
        run.extra["compiled_error"] = f"{type(exc).__name__}: {exc}"
        return run
    compile_s = time.perf_counter() - start
    status, message, t_fail, n_steps, nfev = Status.OK, "", None, 0, 0
    start = time.perf_counter()
    try:
        with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
            f0 = np.asarray(model.rhs(t0, y0), dtype=float)
            if not np.all(np.isfinite(f0)):
                raise _Stop(Status.UNSTABLE, f"dop853: the right-hand side is not finite at the initial "
                                             f"state (t = {t0:.6g}); no step taken")
            bad = []
            calls = [0]

            def fun(t, yy):
                calls[0] += 1
                f, nonfinite = fast_rhs.checked(yy)
                if nonfinite and not bad:
                    bad.append(float(t))
                return f

            h = first_step(fun, t0, y0, t1, f0, rtol_used, atol_c)
            nfev = calls[0]
            if not (math.isfinite(h) and h > 0.0):
                raise _Stop(Status.UNSTABLE if bad else Status.FAILED,
                            f"dop853: no usable first step (computed h = {h!r} s at t = {t0:.6g})")
            extra["first_step"] = h
            counts[1], counts[3] = nfev, int(bool(bad))
            if bad:
                info[1] = bad[0]
            code = int(loop(*args, info, y0, t_c, h, rtol_used, atol_c, *coef, int(max_steps), int(max_evals), ys,
                            counts))
            n_steps, nfev, k, is_bad = int(counts[0]), int(counts[1]), int(counts[2]), bool(counts[3])
            t_end = float(info[0])
            if code == 0:
                pass
            elif code == 1:
                t_fail = t_end
                if is_bad:
                    status = Status.UNSTABLE
                    message = (f"dop853: the right-hand side became non-finite at t = {float(info[1]):.6g} "
                               f"(a state where the force is undefined?); scipy: {STATUS_TEXT[1]}")
                else:
                    status, message = Status.FAILED, f"dop853: {STATUS_TEXT[1]}"
            elif code == 5:
                status, t_fail = Status.UNSTABLE, t_end
                message = f"dop853: state became non-finite at t = {t_fail:.6g}"
            else:
                t_fail = t_end
                if code == 2:
                    message = f"dop853: step cap max_steps = {max_steps} reached at t = {t_end:.6g}"
                elif code == 3:
                    message = (f"dop853: step cap reached ({max_evals} right-hand-side evaluations, "
                               f"max_steps = {max_steps})")
                else:
                    message = (f"dop853: the step size became non-finite (right-hand side asked "
                               f"for at t = {float(info[2])!r})")
                status = Status.UNSTABLE if is_bad and "step cap" not in message else Status.FAILED
    except _Stop as stop:
        status, message, t_fail, k = stop.status, stop.message, t0, 1
    except Exception as exc:  # noqa: BLE001 - a failure inside is a status, not an exception
        status, message, t_fail, k = Status.FAILED, f"dop853: {type(exc).__name__}: {exc}", t0, 1
    wall = time.perf_counter() - start
    y = ys.T.copy()
    message = _closing_message(status, message, t_fail, note)
    if status is not Status.OK:
        y[:, k:] = np.nan
    extra["nfev_calls"] = nfev
    return SolverRun(name, rtol, t_eval, y, nfev, n_steps, wall, compile_s=compile_s, status=status,
                     message=message, atol=float(atol_c[0]), t_fail=t_fail, extra={**extra, "atol_state": atol})
