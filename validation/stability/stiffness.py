"""Stiffness: what each solver pays to reach a fixed error as omega_max/omega_min grows.

Two families: (a) a chain of ``N`` unit masses on unit springs whose middle
spring has stiffness ``ratio`` (N/m), so ``omega_max ~ sqrt(2 ratio)``; the
initial state is the lowest mode of the soft chain, symmetric about the stiff
spring, so the stiff mode is (almost) not excited: the accuracy need is set by
the slow motion, and explicit methods are held back by stability alone.
(b) Two masses ``m1 = 1 kg``, ``m2 = mu kg`` on three unit springs, both masses
displaced 0.01 m: both modes are excited, so the fast one must be resolved.

Each run spans one period of the slowest mode. The error is
``max_i |q_i(t_end) - q_i^exact| / max_i |q_i(0)|`` against the modal
solution (:func:`._common.error_rel`, the study's one metric).
:func:`cost_at_target` is the study's one cost-at-target search: RK4's step
starts just below its stability limit ``2 sqrt 2 / omega_max`` and is halved
until the target error is met; for the adaptive solvers the loosest ``rtol``
of a ladder that meets it is searched (:func:`ladder_search`: guided by the
measured error's slope against rtol, so the expensive tight rungs are mostly
jumped over instead of walked). The cost reported is that of the loosest setting
meeting the target (nfev; heyoka: Taylor steps x order).

Skipped for cost (:func:`skip_reason`, status ``skipped`` with the reason):

* DOP853 on the stiff chain beyond omega_max/omega_min = 1e4 (1e3 in quick
  mode): an explicit method is held to ``h ~ 3.3/omega_max`` by stability, so
  it pays ~omega_max/omega_min steps of ~0.1-0.2 ms each (scipy's per-step
  Python overhead) for an accuracy the slow motion alone sets;
* CVODE-BDF on the two-mass chain where both modes are excited and
  omega_max/omega_min > 1e3 (mu <= 1e-6 or >= 1e6 on the shipped grid): BDF
  (order <= 5) must resolve every fast period to reach the target, and first
  meets 1e-6 at rtol 1e-12 with 4.3e5 steps; its rtol search took 51 s CPU at
  mu = 1e-6 (the whole point 66 s; 6 s without it, DOP853's search included).
"""
from __future__ import annotations

import math
import time

import numpy as np

import rk4h
from rk4h.references.exact import modal_solution
from rk4h.references.registry import CostUnit, resolve

from ._common import error_rel, integrate_fixed

__all__ = ["stiff_chain", "mass_ratio_chain", "cost_at_target", "ladder_search", "skip_reason",
           "excited_ratio", "RTOL_LADDER", "RTOL_LADDER_QUICK", "EXCITED"]

RTOL_LADDER = (1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10, 1e-11, 1e-12)
RTOL_LADDER_QUICK = (1e-5, 1e-7, 1e-9, 1e-11)
#: A mode counts as excited when its displacement amplitude is above this
#: fraction of the largest initial displacement.
EXCITED = 1e-3
#: DOP853 is skipped on the stiff chain beyond this omega_max/omega_min (quick, full).
DOP853_MAX_RATIO = {True: 1e3, False: 1e4}
#: CVODE-BDF is skipped where an excited mode is this many times faster than the slowest.
BDF_MAX_EXCITED_RATIO = 1e3


def stiff_chain(ratio: float, N: int = 8):
    """Chain with one stiff middle spring: (model, y0)."""
    springs = [1.0] * (N + 1)
    springs[N // 2] = float(ratio)
    model = rk4h.make_model("chain", {"masses": [1.0] * N, "springs": springs})
    x = 0.01 * np.sin(np.pi * np.arange(1, N + 1) / (N + 1))
    return model, model.state(x)


def mass_ratio_chain(mu: float):
    """Two masses 1 and ``mu`` kg on three 1 N/m springs: (model, y0)."""
    model = rk4h.make_model("chain", {"masses": [1.0, float(mu)], "springs": [1.0, 1.0, 1.0]})
    return model, model.state([0.01, 0.01])


def excited_ratio(model, y0) -> tuple[float, float]:
    """``(omega_max / omega_min, omega_exc / omega_min)``: the stiffness ratio and
    that of the fastest mode whose displacement amplitude exceeds :data:`EXCITED`
    of ``max |q(0)|`` (both from the model's modes, no integration)."""
    omega, phi = model.modes()
    n = model.n_dof
    M = model.mass
    eta, deta = phi.T @ (M * y0[:n]), phi.T @ (M * y0[n:])
    pos = omega > 0
    with np.errstate(divide="ignore", invalid="ignore"):
        amp = np.where(pos, np.hypot(omega * eta, deta) / np.where(pos, omega, 1.0), np.abs(eta))
    scale = float(np.max(np.abs(y0[:n]))) or 1.0
    exc = pos & (amp * np.max(np.abs(phi), axis=0) >= EXCITED * scale)
    w_lo = float(omega[pos][0])
    w_exc = float(omega[exc][-1]) if exc.any() else w_lo
    return float(omega[-1]) / w_lo, w_exc / w_lo


def skip_reason(solver: str, what: str, ratio: float, exc_ratio: float, quick: bool):
    """Why ``solver`` is skipped at a sweep point (``what``: "ratio" for the
    stiff chain, "mu" for the two-mass chain), or None; see the module
    docstring. ``ratio``/``exc_ratio`` from :func:`excited_ratio`."""
    from rk4h.references.registry import BUILTIN

    m = BUILTIN.get(solver)
    if m is None or not m.adaptive:  # the fixed-step method under study is never skipped
        return None
    explicit_rk = not (m.implicit or m.taylor)  # an explicit adaptive Runge-Kutta method (DOP853)
    if explicit_rk and what == "ratio" and ratio > DOP853_MAX_RATIO[bool(quick)]:
        return (f"skipped for cost: omega_max/omega_min = {ratio:.3g} > {DOP853_MAX_RATIO[bool(quick)]:g}; "
                f"explicit {solver.upper()} is held to h ~ 3.3/omega_max by stability (~{ratio:.2g} steps of "
                f"~0.1-0.2 ms from Python per rtol tried) for an error the slow mode alone sets")
    if m.stiff and what == "mu" and exc_ratio > BDF_MAX_EXCITED_RATIO:
        return (f"skipped for cost: both modes excited, omega_max/omega_min = {exc_ratio:.3g} > "
                f"{BDF_MAX_EXCITED_RATIO:g}; BDF must resolve every fast period (measured at mu = 1e-6: first "
                f"meets 1e-6 at rtol 1e-12 with 4.3e5 steps, 51 s CPU for the rtol search)")
    return None


def ladder_search(ladder, target: float, run):
    """Loosest rung of ``ladder`` (rtols, loosest first) whose run meets
    ``target``, found with fewer (and cheaper) runs than a walk down every rung.

    ``run(rtol)`` returns a dict with ``status`` ("ok" or a failure status)
    and ``error``. The two loosest rungs are run first (as in a walk); then,
    from the last two misses, the straight line of log(error) against
    log(rtol) -- its slope held in [1, 3], so that the jump errs towards
    looser, cheaper rungs -- predicts the first rung meeting the target, which
    is run; a miss there repeats the prediction from the new pair, a hit is
    confirmed by walking back to looser rungs until one misses. The answer
    is thus always a hit whose looser neighbour missed; the rungs jumped over
    (all looser than a measured miss) are not run, which equals the walk
    whenever the error falls with rtol. A run that fails (step cap,
    instability) ends the jumps: the rungs between the last miss and it are
    walked, and if none meets, the failure is the answer.

    Returns ``(index, runs)``: the index of the rung found (None if none
    meets) and ``{index: run result}`` of every rung probed, in probing order.
    """
    runs: dict = {}
    n = len(ladder)

    def probe(i):
        if i not in runs:
            runs[i] = run(ladder[i])
        r = runs[i]
        return "fail" if r["status"] != "ok" else ("hit" if r["error"] <= target else "miss")

    misses = []
    i = 0
    while i < n:
        out = probe(i)
        if out == "hit":
            j = i  # walk back to the first miss (or the loosest rung)
            while j > 0 and (j - 1) not in misses:
                if probe(j - 1) != "hit":
                    break
                j -= 1
            return j, runs
        if out == "fail":
            for k in range((misses[-1] + 1) if misses else 0, i):
                out_k = probe(k)
                if out_k == "hit":
                    return k, runs
                if out_k == "fail":
                    break
            return None, runs
        misses.append(i)
        i = i + 1 if len(misses) < 2 else max(i + 1, _predict(ladder, target, runs, misses[-2], misses[-1]))
    return None, runs


def _predict(ladder, target, runs, a, b):
    """First rung whose rtol is at or below where the line through misses
    ``a`` and ``b`` (slope held in [1, 3]) reaches ``target``."""
    xa, xb = math.log(ladder[a]), math.log(ladder[b])
    ea, eb = runs[a]["error"], runs[b]["error"]
    slope = 1.0
    if ea > 0 and eb > 0 and math.isfinite(ea) and math.isfinite(eb) and xa != xb:
        slope = (math.log(ea) - math.log(eb)) / (xa - xb)
    slope = min(max(slope if math.isfinite(slope) else 1.0, 1.0), 3.0)
    x = xb + (math.log(target) - math.log(eb)) / slope if eb > 0 and math.isfinite(eb) else xb
    return next((k for k in range(len(ladder)) if math.log(ladder[k]) <= x + 1e-9), len(ladder) - 1)


def cost_at_target(model, y0, target: float, solvers, *, fixed=None, max_rk4_steps: float = 5e7,
                   skip=lambda solver: None, rtol_ladder=RTOL_LADDER):
    """Cheapest setting of each solver meeting ``target`` (the study's one
    cost-at-target search; see the module docstring).

    ``fixed`` maps the fixed-step solvers among ``solvers`` to their tableaux
    (default: the registry's ``UNDER_TEST``, RK4): their step starts at 0.99 of the method's
    imaginary-axis boundary (or ``0.5 / omega_max`` for a method without one)
    and halves until the error meets ``target`` or ``max_rk4_steps`` steps
    would be needed; every other solver climbs the rtol ladder.

    ``skip(solver)`` returns the reason a solver is skipped (a string), or
    None/False to run it.

    Returns a list of dicts: solver, setting, error, nfev, n_steps, wall_s
    (a timing: the wall time of the reported run), status ("ok",
    "not-reached", "skipped", or the run's failure status), note (deterministic),
    and ``omega_max``, ``omega_min``, ``stiffness_ratio``.
    """
    from rk4h.references import registry
    from rk4h.stability_function import imaginary_axis_boundary

    if fixed is None:  # the registry's method under test
        fixed = {registry.UNDER_TEST: registry.resolve(registry.UNDER_TEST).tableau}
    omega = model.modes()[0]
    w_lo, w_hi = float(omega[omega > 0][0]), float(omega[-1])
    t_end = 2 * math.pi / w_lo
    ref = modal_solution(model, y0)(np.array([t_end]))[:, :1]
    scale = float(np.max(np.abs(y0[: model.n_dof])))
    common = {"omega_max": w_hi, "omega_min": w_lo, "stiffness_ratio": w_hi / w_lo, "t_end": t_end}
    out = []
    for solver in solvers:
        rec = {"solver": solver, "setting": math.nan, "error": math.nan, "nfev": math.nan,
               "n_steps": math.nan, "wall_s": math.nan, "status": "not-reached", "note": "", **common}
        why = skip(solver)
        if why:
            rec.update(status="skipped", note=why if isinstance(why, str) else "skipped (see params)")
            out.append(rec)
            continue
        if solver in fixed:
            tab = fixed[solver]
            h_stab = imaginary_axis_boundary(tab) / w_hi
            h = 0.99 * h_stab if h_stab > 0 else 0.5 / w_hi
            while t_end / h <= max_rk4_steps:
                t0 = time.perf_counter()
                res, path = integrate_fixed(model, (0.0, t_end), y0, h=h, t_eval=[t_end], method=tab)
                wall = time.perf_counter() - t0
                err = error_rel(model, res.y[:, -1:], ref, scale) if res.success else math.nan
                rec.update(setting=res.h, error=err, nfev=res.nfev, n_steps=res.n_steps,
                           wall_s=wall,
                           note=f"path={path}; h_stab={h_stab:.3g}")
                if not res.success:
                    rec.update(status="unstable", note=res.message)
                    break
                if err <= target:
                    rec["status"] = "ok"
                    break
                h /= 2
        else:
            from rk4h.references.solvers import integrate

            def one(rtol, solver=solver):
                with np.errstate(all="ignore"):
                    run = integrate(solver, model, y0, np.array([0.0, t_end]), rtol)
                err = error_rel(model, run.y[:, -1:], ref, scale) if run.ok else math.nan
                nfev = int(resolve(solver).cost(run.nfev, run.n_steps, run.taylor_order or 0))
                return {"status": "ok" if run.ok else run.status.value, "error": err, "setting": rtol,
                        "nfev": nfev, "n_steps": run.n_steps, "wall_s": run.wall_s, "message": run.message}

            found, runs = ladder_search(rtol_ladder, target, one)
            tried = ", ".join(f"{rtol_ladder[j]:.0e}" for j in runs)
            pick_ = found if found is not None else max(runs)
            r = runs[pick_]
            rec.update({k: r[k] for k in ("setting", "error", "nfev", "n_steps", "wall_s")})
            rec["status"] = "ok" if found is not None else ("not-reached" if r["status"] == "ok" else r["status"])
            unit = resolve(solver).cost_unit
            rec["note"] = (f"{solver}: nfev = {unit.text}; " if unit is CostUnit.TAYLOR_STEPS else "") + \
                f"rtol tried: {tried}" + ("" if r["status"] == "ok" else f"; {r['message']}")
        out.append(rec)
    return out
