"""Energy over time: the energy error's time series of a run, summarised.

A run's relative energy error ``e(t) = (E(t) - E0) / E_motion``
(:func:`rk4h.energy.relative_energy_error`; ``E_motion = E0 - V(q*)``)
is summarised by

- its maximum ``max_t |e(t)|`` (``energy_drift_max``, as every table has it);
- its *growth law*: the slope ``k`` of ``log M(t)`` against ``log t``, where
  ``M(t) = max_{s <= t} |e(s)|`` is the running maximum (the envelope; the
  instantaneous error of a symplectic method dips to zero twice a period),
  fitted by least squares at :data:`FIT_POINTS` log-spaced times over the
  last :data:`FIT_DECADES` decades of the run, ``[t_end / 10^FIT_DECADES,
  t_end]`` (``energy_fit_t0``, ``energy_fit_t1``, s). ``k`` near 0: the
  error is bounded (oscillates, as a symplectic method's does); ``k`` near 1:
  it grows secularly, linearly in time (RK4 loses ``1 - |R(i omega h)|^2``
  of each mode's energy every step);
- on a linear model (periodic motion of each mode), the *phase error* of
  its modes: the unwrapped angle between the computed and the exact modal
  coordinate ``omega_j eta_j - i eta_j'`` of every mode that holds at least
  :data:`PHASE_MIN_SHARE` of the energy (rad), its maximum over the run and
  the modes that stay resolved (``phase_error_max``; a mode the method damps
  into round-off, :data:`PHASE_RESOLUTION`, is left out and counted in
  ``phase_modes_unresolved``) and the growth exponent of its running maximum
  (``phase_growth_exponent``, fitted as the energy's): 1 for a phase that
  drifts linearly, as it does for every method of this harness (RK4 lags
  ``theta^5/120`` per step, Stormer-Verlet ``theta^3/24``).

The long runs (:func:`long_run`) use the compiled fixed-step loops
(:mod:`rk4h.fast`), keeping :data:`LONG_SAMPLES` states.

Functions here integrate only in :func:`long_run` and :func:`work_precision_rows`
(the opt-in energy work-precision study, :mod:`rk4h.validation.energy_study`);
:func:`summary` is a pure function of a trajectory.
"""
from __future__ import annotations

import math
import time

import numpy as np

__all__ = ["FIT_DECADES", "FIT_POINTS", "PHASE_MIN_SHARE", "PHASE_RESOLUTION", "LONG_SAMPLES", "COLUMNS",
           "running_max", "growth_exponent", "energetic_modes", "phase_angles", "phase_errors", "summary",
           "is_symplectic", "equal_cost_step", "slowest_period",
           "long_run", "dense_samples", "SAMPLES_PER_FAST_PERIOD", "MAX_SAMPLES", "MAX_VALUES", "work_precision_rows", "WP_HORIZONS", "WP_SCENES",
           "reference_step_cap", "STEP_CAP_MARGIN", "STEP_CAP_CALIBRATION_PERIODS", "STEP_CAP_CEILING",
           "STEP_CAP_STATUS", "exchange_period", "EXCHANGE_MIN_SHARE"]

#: Decades of time, ending at the run's end, over which a growth exponent is fitted.
FIT_DECADES = 2.0
#: Log-spaced times at which the running maximum enters the fit.
FIT_POINTS = 64
#: A mode enters the phase error when it holds at least this share of the
#: energy of the motion at t = 0 (a mode with almost no energy has no
#: measurable phase).
PHASE_MIN_SHARE = 1e-6
#: A mode's phase error counts while the rounding estimate of its angle
#: (:func:`phase_angles`: ``eps`` times the sum of the absolute values of the
#: terms its modal coordinate adds up, ``omega |phi_j|^T M |q| + |phi_j|^T M
#: |v|``, over the coordinate ``|z_j|``) is at most this (rad). It estimates
#: the rounding of the projection and, since the integration's rounding
#: enters every coordinate in proportion to the same terms, the size of that
#: too; the integration's rounding also builds up over the steps, which the
#: estimate does not count. A method that damps a mode (RK4 near its
#: stability limit) raises it until the round-off of the rest of the motion
#: takes over the mode's angle. On the shipped scenes' RK4 runs of 1000
#: steps (``benchmarks/phase_floor.py``) the measured angles leave RK4's
#: exact lag by 1e-6 rad only where the estimate is 7.6e-7 or more; over
#: millions of steps, angles that pass it can drift from the lag by more
#: than the estimate. A mode that shares no terms with the rest of the motion
#: (uncoupled coordinates) passes it however small it gets.
PHASE_RESOLUTION = 1e-7
#: States kept by :func:`long_run` (evenly spaced in steps).
LONG_SAMPLES = 20000

#: The energy table's columns :func:`summary` fills (declared, with units, in
#: :mod:`rk4h.validation.columns`).
COLUMNS = ("energy_growth_exponent", "energy_fit_t0", "energy_fit_t1", "phase_error_max", "phase_growth_exponent",
           "phase_modes_unresolved")


def running_max(err) -> np.ndarray:
    """``max_{s <= t} |err(s)|`` along a series (NaN stays NaN from where it appears)."""
    a = np.abs(np.asarray(err, dtype=float))
    return np.maximum.accumulate(a) if a.size else a


def growth_exponent(t, err, decades: float = FIT_DECADES, points: int = FIT_POINTS):
    """Growth exponent of an error series: ``(k, t0, t1)``.

    Parameters
    ----------
    t : array_like
        Times (s), increasing.
    err : array_like
        The error at ``t`` (any unit; its absolute value is used).
    decades : float
        The fit covers ``[t1 / 10**decades, t1]``, ``t1 = t[-1]`` (and starts no
        earlier than the first positive time).
    points : int
        Log-spaced times in that range; at each the running maximum is read at
        the last sample at or before it.

    Returns
    -------
    (float, float, float)
        ``k``, the least-squares slope of ``log M`` against ``log t``, and the
        fit range ``t0, t1`` (s). ``k`` is NaN when the series is not finite,
        is zero somewhere in the range (no error to fit) or has fewer than 3
        distinct samples there.
    """
    t = np.asarray(t, dtype=float)
    m = running_max(err)
    if t.size < 3 or t[-1] <= 0:
        return math.nan, math.nan, math.nan
    t1 = float(t[-1])
    positive = t[t > 0]
    t0 = max(t1 / 10.0 ** decades, float(positive[0]))
    if not t0 < t1:
        return math.nan, t0, t1
    ts = np.geomspace(t0, t1, points)
    idx = np.searchsorted(t, ts * (1 + 1e-12), side="right") - 1
    idx = np.unique(idx[idx >= 0])
    if idx.size < 3:
        return math.nan, t0, t1
    tt, mm = t[idx], m[idx]
    if not (np.all(np.isfinite(mm)) and np.all(mm > 0)):
        return math.nan, t0, t1
    k = float(np.polyfit(np.log(tt), np.log(mm), 1)[0])
    return k, t0, t1


def energetic_modes(ms) -> np.ndarray:
    """Mask of the modes of a modal solution ``ms``
    (:func:`rk4h.references.exact.modal_solution`) that have a phase: nonzero
    frequency and at least :data:`PHASE_MIN_SHARE` of the energy at t = 0."""
    e_mode = 0.5 * (ms.deta0 ** 2 + (ms.omega * ms.eta0) ** 2)
    return (~ms.zero) & (e_mode >= PHASE_MIN_SHARE * max(float(e_mode.sum()), 1e-300))


def phase_angles(model, y0, t, y):
    """Angle of each energetic mode against the exact one, and how well it is resolved.

    Parameters
    ----------
    model : rk4h.models.Model
        A linear model (``model.linear``).
    y0 : array_like
        The initial state ``[q, v]`` (SI).
    t : array_like, shape (m,)
        Times (s) of the states.
    y : array_like, shape (2n, m)
        The computed states.

    Returns
    -------
    (numpy.ndarray, numpy.ndarray), each shape (modes, m)
        The unwrapped ``arg(z_num) - arg(z_exact)`` (rad) of ``z = omega eta
        - i eta'`` per energetic mode (:func:`energetic_modes`; a positive
        value: the computed mode leads), and an
        estimate of its rounding, ``eps (omega |phi|^T M |q| + |phi|^T M |v|)
        / |z_num|`` (rad; ``inf`` where ``z_num`` is 0; see
        :data:`PHASE_RESOLUTION`). Both empty (0, m) for a model that
        is not linear or has no such mode. The unwrapping assumes the error
        changes by less than pi between samples; it runs forward, so a sample
        does not depend on later ones.
    """
    from rk4h.references.exact import modal_solution

    t = np.asarray(t, dtype=float)
    y = np.asarray(y, dtype=float)
    empty = np.zeros((0, t.size))
    if not getattr(model, "linear", False):
        return empty, empty
    ms = modal_solution(model, np.asarray(y0, float))
    w = np.where(ms.zero, 1.0, ms.omega)
    keep = energetic_modes(ms)
    if not keep.any():
        return empty, empty
    n = model.n_dof
    M = np.asarray(model.mass, float)[:, None]
    eta = ms.phi.T @ (M * y[:n])
    deta = ms.phi.T @ (M * y[n:])
    eta_x, deta_x = ms.modal(t)
    z_num = (w[:, None] * eta - 1j * deta)[keep]
    z_ex = (w[:, None] * eta_x - 1j * deta_x)[keep]
    angle = np.unwrap(np.angle(z_num * np.conj(z_ex)), axis=1)
    a = np.abs(ms.phi[:, keep]).T
    terms = w[keep][:, None] * (a @ (M * np.abs(y[:n]))) + a @ (M * np.abs(y[n:]))
    with np.errstate(divide="ignore", invalid="ignore"):
        rounding = np.where(np.abs(z_num) > 0, np.finfo(float).eps * terms / np.abs(z_num), np.inf)
    return angle, rounding


def phase_errors(model, y0, t, y):
    """Phase error (rad) of each energetic mode of a linear model along a trajectory.

    Parameters are those of :func:`phase_angles`.

    Returns
    -------
    numpy.ndarray, shape (modes, m)
        :func:`phase_angles`' angle, NaN from the first sample at which its
        rounding estimate exceeds :data:`PHASE_RESOLUTION`. A method that
        damps a mode (RK4 near its stability limit loses ``1 - |R(i omega
        h)|^2`` of its energy per step: 9% at ``omega h = 1.43``) leaves that
        mode's angle to the round-off of the rest of the motion, and the
        unwrapped angle of round-off is no phase error. Empty (0, m) for a model that is not
        linear or has no energetic mode.
    """
    angle, rounding = phase_angles(model, y0, t, y)
    return np.where(np.logical_and.accumulate(rounding <= PHASE_RESOLUTION, axis=1), angle, np.nan)


def summary(model, y0, t, y) -> dict:
    """The energy-over-time columns of one run (:data:`COLUMNS`), from its trajectory.

    ``t`` (s, shape (m,)) and ``y`` (shape (2n, m)) as a solver returns them;
    NaN entries where the run has none (a blown-up run, a nonlinear model's phase;
    ``phase_modes_unresolved`` is then NaN too, else a count).
    """
    from rk4h.energy import relative_energy_error

    t = np.asarray(t, dtype=float)
    with np.errstate(all="ignore"):
        e = relative_energy_error(model, y)
    k, t0, t1 = growth_exponent(t, e)
    out = {"energy_growth_exponent": k, "energy_fit_t0": t0, "energy_fit_t1": t1,
           "phase_error_max": math.nan, "phase_growth_exponent": math.nan, "phase_modes_unresolved": math.nan}
    if getattr(model, "linear", False) and np.all(np.isfinite(y)):
        ph = phase_errors(model, y0, t, y)
        if not ph.size:
            return out
        # the modes resolved to the run's end; a damped one's error would stop
        # wherever the bar cuts it, so it is counted, not measured
        resolved = ~np.isnan(ph[:, -1])
        out["phase_modes_unresolved"] = int((~resolved).sum())
        if resolved.any():
            env = np.max(np.abs(ph[resolved]), axis=0)
            out["phase_error_max"] = float(env.max())
            out["phase_growth_exponent"] = growth_exponent(t, env)[0]
    return out


def is_symplectic(tab) -> bool:
    """Whether a tableau is a symplectic method: its ``symplectic`` flag where it
    has one, else whether it is partitioned (every partitioned method shipped
    is symplectic: symplectic Euler, Stormer-Verlet and the splittings)."""
    flag = getattr(tab, "symplectic", None)
    return bool(tab.partitioned if flag is None else flag)


def equal_cost_step(tab, h_ref: float, ref_calls_per_step: int = 4) -> float:
    """The step (s) at which ``tab`` makes as many RHS calls per unit time as a
    method of ``ref_calls_per_step`` calls at ``h_ref`` (RK4: 4)."""
    return float(h_ref) * int(tab.nfev_per_step) / int(ref_calls_per_step)


def slowest_period(model) -> float:
    """``2 pi / omega_min`` (s) of the model's (linearized) slowest nonzero mode."""
    try:
        omega = np.asarray(model.modes()[0], float)
    except Exception as e:  # noqa: BLE001 - a model without (linearized) modes
        raise ValueError(f"the model has no modes ({type(e).__name__}): a horizon in periods is undefined") from None
    omega = omega[omega > 0]
    if not omega.size:
        raise ValueError("the model has no oscillating mode: a horizon in periods is undefined")
    return float(2.0 * math.pi / omega.min())


#: Samples per period of the fastest mode kept by :func:`dense_samples`: the
#: energy error of a symplectic method oscillates at up to twice the fastest
#: frequency, so its largest value between samples is at most ``1 - cos(pi /
#: 8)``, 8 %, above the largest sampled one (for one harmonic).
SAMPLES_PER_FAST_PERIOD = 16
#: Cap on :func:`dense_samples`: kept state values (rows x state size; 128 MB
#: of float64), 4e6 rows of a 2-DOF model.
MAX_VALUES = 16_000_000
MAX_SAMPLES = 4_000_000


def dense_samples(model, t_end: float, per_period: int = SAMPLES_PER_FAST_PERIOD, cap: int = MAX_SAMPLES) -> int:
    """Samples for :func:`long_run` that resolve the fastest mode over ``t_end`` (s):
    ``per_period`` per fastest period, at most ``cap`` rows and
    :data:`MAX_VALUES` values (beyond, the maximum of an oscillating error is
    undersampled: the samples alias its oscillation)."""
    omega = np.asarray(model.modes()[0], float)
    T_fast = 2.0 * math.pi / float(omega.max())
    cap = min(int(cap), MAX_VALUES // (2 * int(model.n_dof)))
    return int(min(cap, max(LONG_SAMPLES, math.ceil(t_end / T_fast * per_period))))


def long_run(model, y0, method, h: float, t_end: float, samples: int = LONG_SAMPLES):
    """A long fixed-step run on the compiled loops, ``samples`` states kept.

    Parameters
    ----------
    model : rk4h.models.Model
        A model with a compiled force (:func:`rk4h.fast.supports`).
    y0 : array_like
        Initial state ``[q, v]`` (SI).
    method : str or rk4h.methods.Tableau
    h : float
        Step (s); the run takes ``ceil(t_end / h)`` equal steps.
    t_end : float
        Horizon (s), from t = 0.
    samples : int
        About this many states are kept, evenly spaced in steps.

    Returns
    -------
    (result, wall_s)
        The :class:`rk4h.solver.FixedStepResult` and the wall time (s) of
        the run (the loop is warmed up first, its compile time apart).
    """
    import rk4h.fast as fast

    n = max(1, int(math.ceil(t_end / h * (1 - 1e-12))))
    every = max(1, n // max(int(samples), 1))
    fast.warm_up(model, method)
    start = time.perf_counter()
    res = fast.solve_model(model, (0.0, float(t_end)), np.asarray(y0, float), n_steps=n, method=method,
                           record_every=every)
    return res, time.perf_counter() - start


#: Horizons (periods of the slowest mode) of the energy work-precision study;
#: 1e6 is added with ``full=True``.
WP_HORIZONS = (1e2, 1e4)
#: Scenes the study is meant for (FPUT, Henon-Heiles, lattice, exact planar4).
WP_SCENES = ("fput-alpha", "henon-heiles", "lattice100", "planar4-case1")


def work_precision_rows(scene_name, model, y0, methods, steps_per_period=(8, 16, 32, 64), horizons=WP_HORIZONS,
                        full: bool = False, references=(), rtols=(1e-6, 1e-8, 1e-10, 1e-12),
                        max_steps=None) -> list:
    """Energy work-precision: max |E(t) - E0| / E_motion against RHS calls and wall time.

    Parameters
    ----------
    scene_name : str
    model, y0
        The scene's model and initial state (SI).
    methods : iterable of rk4h.methods.Tableau
        Fixed-step methods, run on the compiled loops.
    steps_per_period : sequence of int
        Steps per period of the *fastest* mode at which each method runs
        (``h = T_fast / n``); a run past a method's stability limit ends
        ``unstable`` and is listed so.
    horizons : sequence of float
        Horizons in periods of the slowest mode; ``full`` adds 1e6. States
        are kept as :func:`dense_samples` says (16 per fastest period).
    references : sequence of str
        Adaptive references (``"heyoka"``, ...) run at each of ``rtols`` too,
        on the same sampled grid (their ``h`` is NaN, ``rtol`` set), each under
        the step cap :func:`reference_step_cap` sizes from the horizon.
    max_steps : int, optional
        A fixed step cap for the references instead (tests).

    Returns
    -------
    list of dict
        One row per (horizon, method, step or rtol): ``scene, solver, periods,
        t_end`` (s), ``h`` (s), ``rtol``, ``energy_drift_max`` (1), ``energy_growth_exponent``,
        ``nfev``, ``wall_s`` (s, one run, compile time apart), ``status``
        (``ok``, ``unstable``, ``failed`` or :data:`STEP_CAP_STATUS`),
        ``max_steps`` (a reference's step cap; NaN for a fixed-step run) and
        ``message`` (one line: the cap's sizing, or why the run failed).
    """
    from rk4h.energy import relative_energy_error

    T_slow = slowest_period(model)
    omega = np.asarray(model.modes()[0], float)
    T_fast = 2.0 * math.pi / float(omega.max())
    hs = list(horizons) + ([1e6] if full and 1e6 not in horizons else [])
    t_ex = exchange_period(model, y0)
    rows = []
    for periods in hs:
        t_end = periods * T_slow
        for tab in methods:
            for n in steps_per_period:
                h = T_fast / n
                res, wall = long_run(model, y0, tab, h, t_end, dense_samples(model, t_end))
                ok = bool(res.success)
                with np.errstate(all="ignore"):
                    e = relative_energy_error(model, res.y)
                k, note = _fit(res.t, e, t_ex) if ok else (math.nan, "")
                rows.append({"scene": scene_name, "solver": tab.name, "periods": float(periods), "t_end": t_end,
                             "h": float(res.h), "rtol": math.nan,
                             "energy_drift_max": float(np.max(np.abs(e))) if ok else math.nan,
                             "energy_growth_exponent": k,
                             "nfev": int(res.nfev), "cost_unit": _RHS_UNIT, "wall_s": wall,
                             "status": "ok" if ok else res.reason,
                             "max_steps": math.nan, "message": note})
        for name in references:
            for rtol in rtols:
                rows.append(_reference_row(scene_name, model, y0, name, rtol, periods, t_end, max_steps, t_ex))
    return rows


#: A mode drives a 2:1 exchange (:func:`exchange_period`) when it holds at
#: least this share of the energy of the motion at t = 0.
EXCHANGE_MIN_SHARE = 0.01


def exchange_period(model, y0) -> float:
    """Period (s) of the slowest 2:1 energy exchange of an FPUT-alpha chain.

    The cubic spring energy ``alpha r^3 / 3`` gives a force quadratic in the
    displacements, which drives every mode ``j`` at twice the frequency of
    each energetic mode ``i``: near the resonance ``2 omega_i ~ omega_j``
    energy flows from ``i`` to ``j`` and back with the beat period
    ``2 pi / |2 omega_i - omega_j|`` (linear frequencies, rad/s). Returned:
    the longest such period over the modes ``i`` holding at least
    :data:`EXCHANGE_MIN_SHARE` of the initial energy and every ``j != i``.
    The running maximum of a bounded energy error rises until the first
    exchange has gone half way; a growth exponent fitted from before then
    reads that rise as growth (:func:`work_precision_rows` does not fit it).

    NaN for a model without a nonzero ``alpha`` (a linear chain's modes do not
    exchange energy; other nonlinearities get no estimate here).
    """
    alpha = float(getattr(model, "alpha", 0.0) or 0.0)
    if alpha == 0.0:
        return math.nan
    omega, V = model.modes()[:2]
    omega = np.asarray(omega, float)
    n = omega.size
    y0 = np.asarray(y0, float)
    m = np.broadcast_to(np.asarray(model.mass, float), (n,))
    eta, etad = V.T @ (m * y0[:n]), V.T @ (m * y0[n:])
    e = 0.5 * (etad ** 2 + omega ** 2 * eta ** 2)
    if not np.sum(e) > 0:
        return math.nan
    energetic = np.flatnonzero(e >= EXCHANGE_MIN_SHARE * np.sum(e))
    detuning = [abs(2 * omega[i] - omega[j]) for i in energetic for j in range(n) if j != i]
    slow = min((d for d in detuning if d > 0), default=math.nan)
    return 2 * math.pi / slow if math.isfinite(slow) else math.nan


def _fit(t, e, t_exchange) -> tuple[float, str]:
    """``(k, note)``: the growth exponent, or NaN and why it was not fitted
    (the fit window starts before half the exchange period)."""
    k, t0, _ = growth_exponent(t, e)
    if math.isfinite(t_exchange) and t0 < t_exchange / 2:
        return math.nan, (f"not fitted: the fit window starts at {t0:.4g} s, before half the 2:1 exchange period "
                          f"{t_exchange:.4g} s (exchange_period): the running maximum still rises with the exchange")
    return k, ""


#: A reference's step cap over a long horizon is this many times its
#: estimated steps (:func:`reference_step_cap`).
STEP_CAP_MARGIN = 2.0
#: The calibration run that estimates a reference's steps covers at most this
#: many periods of the slowest mode.
STEP_CAP_CALIBRATION_PERIODS = 100.0
#: Hard ceiling of a reference's step cap: a run estimated to need more (with
#: the margin) is not run and its row says so (status ``step_cap``). 5e8
#: heyoka steps take of the order of an hour on a few-DOF model.
STEP_CAP_CEILING = 500_000_000
#: The ``status`` of a work-precision row whose reference reached (or would
#: need more than) its step cap: a failure, never a truncated run read as ok.
STEP_CAP_STATUS = "step_cap"


def reference_step_cap(model, y0, name: str, rtol: float, t_end: float) -> dict:
    """The step cap of reference ``name`` at ``rtol`` over ``[0, t_end]`` (s).

    A horizon no longer than :data:`STEP_CAP_CALIBRATION_PERIODS` slowest
    periods keeps the references' default cap (``DEFAULT_MAX_STEPS``, 5e6).
    A longer one is sized from a calibration run over that many periods at the
    same rtol: ``estimate = n_steps * t_end / t_cal`` (adaptive steps on a
    bounded orbit are about uniform in time), and the cap is
    ``max(DEFAULT_MAX_STEPS, STEP_CAP_MARGIN * estimate)``, at most
    :data:`STEP_CAP_CEILING`.

    Returns
    -------
    dict
        ``cap`` (int steps, or 0: do not run), ``estimate`` (steps; NaN
        without a calibration), ``why`` (one line: how the cap was set, or
        why the run is refused).
    """
    from rk4h.references.solvers import DEFAULT_MAX_STEPS, integrate

    t_cal = STEP_CAP_CALIBRATION_PERIODS * slowest_period(model)
    if t_end <= t_cal:
        return {"cap": int(DEFAULT_MAX_STEPS), "estimate": math.nan,
                "why": f"default cap {DEFAULT_MAX_STEPS:.3g} steps (horizon within {STEP_CAP_CALIBRATION_PERIODS:g} "
                       f"slowest periods)"}
    r = integrate(name, model, y0, np.array([0.0, t_cal]), rtol)
    if getattr(r.status, "value", str(r.status)) != "ok" or r.n_steps <= 0:
        return {"cap": 0, "estimate": math.nan,
                "why": f"its calibration run over {t_cal:.4g} s failed ({(r.message or '').splitlines()[0][:120]})"}
    est = r.n_steps * t_end / t_cal
    need = math.ceil(STEP_CAP_MARGIN * est)
    if need > STEP_CAP_CEILING:
        return {"cap": 0, "estimate": est,
                "why": f"estimated {est:.3g} steps ({r.n_steps} over {t_cal:.4g} s), x {STEP_CAP_MARGIN:g} above the "
                       f"ceiling {STEP_CAP_CEILING:.3g}: not run"}
    cap = int(max(DEFAULT_MAX_STEPS, need))
    return {"cap": cap, "estimate": est,
            "why": f"cap {cap:.3g} steps: {STEP_CAP_MARGIN:g} x the {est:.3g} estimated from {r.n_steps} steps over "
                   f"{t_cal:.4g} s"}


#: What a fixed-step method's ``nfev`` counts: every stage of every step.
_RHS_UNIT = "rhs"


def _reference_cost_unit(name: str) -> str:
    """The cost unit the registry declares for reference ``name``
    (:class:`rk4h.references.registry.CostUnit` value)."""
    from rk4h.references.registry import resolve

    return resolve(name).cost_unit.value


def _reference_row(scene_name, model, y0, name, rtol, periods, t_end, max_steps=None, t_exchange=math.nan) -> dict:
    """One adaptive reference's run for :func:`work_precision_rows` (``nfev``: its
    RHS calls, heyoka's Taylor steps times order; ``wall_s`` as the solver timed it).

    Its step cap is :func:`reference_step_cap`'s (``max_steps`` overrides it).
    A run that reaches its cap, or would need more than the ceiling, is a row
    with status :data:`STEP_CAP_STATUS` and NaN energy (``message`` says
    where it stopped and what the cap was)."""
    from rk4h.references.solvers import integrate
    from rk4h.energy import relative_energy_error

    from .trust import rhs_calls

    sized = (reference_step_cap(model, y0, name, rtol, t_end) if max_steps is None
             else {"cap": int(max_steps), "estimate": math.nan, "why": f"cap {int(max_steps):.3g} steps (given)"})
    row = {"scene": scene_name, "solver": name, "periods": float(periods), "t_end": t_end, "h": math.nan,
           "rtol": float(rtol), "energy_drift_max": math.nan, "energy_growth_exponent": math.nan, "nfev": 0,
           "cost_unit": _reference_cost_unit(name), "wall_s": 0.0, "status": STEP_CAP_STATUS, "max_steps": sized["cap"], "message": sized["why"]}
    if sized["cap"] <= 0:
        if "calibration" in sized["why"]:
            row["status"] = "failed"
        return row
    t = np.linspace(0.0, t_end, dense_samples(model, t_end))
    r = integrate(name, model, y0, t, rtol, max_steps=sized["cap"])
    status = getattr(r.status, "value", str(r.status))
    ok = status == "ok"
    if not ok and (r.n_steps >= sized["cap"] or "step cap" in (r.message or "")):
        status = STEP_CAP_STATUS
    with np.errstate(all="ignore"):
        e = relative_energy_error(model, r.y)
    k, note = _fit(t, e, t_exchange) if ok else (math.nan, "")
    row.update({"energy_drift_max": float(np.max(np.abs(e))) if ok else math.nan,
                "energy_growth_exponent": k,
                "nfev": int(rhs_calls({"nfev": r.nfev, "n_steps": r.n_steps, "taylor_order": r.taylor_order or 0})),
                "wall_s": float(r.wall_s), "status": status,
                "message": ("; ".join(x for x in (note, sized["why"]) if x) if ok
                            else f"{(r.message or status).splitlines()[0][:200]} ({sized['why']})")})
    return row
