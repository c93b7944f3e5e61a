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
solution. RK4's step starts just below its stability limit ``2 sqrt 2 /
omega_max`` and is halved until the target error is met; the adaptive solvers'
``rtol`` is lowered along a ladder until it is met. The cost reported is that
of the first setting meeting the target (nfev; heyoka: Taylor steps x order).
"""
from __future__ import annotations

import math
import time

import numpy as np

import rk4core
from references.exact import modal_solution

from ._common import integrate_fixed

__all__ = ["stiff_chain", "mass_ratio_chain", "cost_at_target"]

RTOL_LADDER = (1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10, 1e-11, 1e-12)
RTOL_LADDER_QUICK = (1e-5, 1e-7, 1e-9, 1e-11)


def stiff_chain(ratio: float, N: int = 8):
    """Chain with one stiff middle spring: (model, y0)."""
    springs = [1.0] * (N + 1)
    springs[N // 2] = float(ratio)
    model = rk4core.make_model("chain", {"masses": [1.0] * N, "springs": springs})
    x = 0.01 * np.sin(np.pi * np.arange(1, N + 1) / (N + 1))
    return model, model.state(x)


def mass_ratio_chain(mu: float):
    """Two masses 1 and ``mu`` kg on three 1 N/m springs: (model, y0)."""
    model = rk4core.make_model("chain", {"masses": [1.0, float(mu)], "springs": [1.0, 1.0, 1.0]})
    return model, model.state([0.01, 0.01])


def _error(model, y, ref, scale):
    n = model.n_dof
    return float(np.max(np.abs(y[:n] - ref[:n]))) / scale


def cost_at_target(model, y0, target: float, solvers, *, max_rk4_steps: float = 5e7,
                   skip=lambda solver: False, rtol_ladder=RTOL_LADDER):
    """Cheapest setting of each solver meeting ``target``.

    Returns a list of dicts: solver, setting, error, nfev, n_steps, wall_s,
    status ("ok", "not-reached", "skipped", or the run's failure status),
    note, and ``omega_max``, ``omega_min``, ``stiffness_ratio``.
    """
    omega = model.modes()[0]
    w_lo, w_hi = float(omega[omega > 0][0]), float(omega[-1])
    t_end = 2 * math.pi / w_lo
    ref = modal_solution(model, y0)(np.array([t_end]))[:, 0]
    scale = float(np.max(np.abs(y0[: model.n_dof])))
    common = {"omega_max": w_hi, "omega_min": w_lo, "stiffness_ratio": w_hi / w_lo, "t_end": t_end}
    out = []
    for solver in solvers:
        rec = {"solver": solver, "setting": math.nan, "error": math.nan, "nfev": math.nan,
               "n_steps": math.nan, "wall_s": math.nan, "status": "not-reached", "note": "", **common}
        if skip(solver):
            rec.update(status="skipped", note="too slow for this mode (see params)")
            out.append(rec)
            continue
        if solver == "rk4":
            h = 0.99 * 2 * math.sqrt(2) / w_hi
            while t_end / h <= max_rk4_steps:
                t0 = time.perf_counter()
                res, path = integrate_fixed(model, (0.0, t_end), y0, h=h, t_eval=[t_end])
                wall = time.perf_counter() - t0
                err = _error(model, res.y[:, -1], ref, scale) if res.success else math.nan
                rec.update(setting=res.h, error=err, nfev=res.nfev, n_steps=res.n_steps, wall_s=wall,
                           note=f"path={path}; h_stab={2 * math.sqrt(2) / w_hi:.3g}")
                if not res.success:
                    rec.update(status="unstable", note=res.message)
                    break
                if err <= target:
                    rec["status"] = "ok"
                    break
                h /= 2
        else:
            from references.solvers import integrate

            for rtol in rtol_ladder:
                with np.errstate(all="ignore"):
                    run = integrate(solver, model, y0, np.array([0.0, t_end]), rtol)
                err = _error(model, run.y[:, -1], ref, scale) if run.ok else math.nan
                nfev = run.nfev if solver != "heyoka" else run.n_steps * (run.taylor_order or 0)
                rec.update(setting=rtol, error=err, nfev=nfev, n_steps=run.n_steps, wall_s=run.wall_s,
                           note="heyoka: nfev = Taylor steps x order" if solver == "heyoka" else "")
                if not run.ok:
                    rec.update(status=run.status.value, note=run.message)
                    break
                if err <= target:
                    rec["status"] = "ok"
                    break
        out.append(rec)
    return out
