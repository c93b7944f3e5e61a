"""Confirmation runs of the trust table: a verdict needs a run.

The trust table (``cheapest.csv``, :func:`rk4h.validation.trust.trust_rows`)
predicts the step the method under test needs for each target error from the
scene's runs. A prediction is not a measurement: before the method may win a
target, it runs at that step (on the output grid,
:func:`rk4h.validation.trust.on_grid`) and its measured ``error_rel`` must be at
most the target. Where no run of any other method reaches a target, the
scene's adaptive references run at tighter tolerances, ten times tighter per
round, down to each one's floor (:data:`RTOL_FLOOR`). A reference with a
compiled loop runs it there (DOP853: :mod:`rk4h.fast.dop853`, scipy's
method step for step to round-off (where steps are rejected near the
tolerance a run can part from scipy's, as scipy's own does when rtol
moves one ulp), about 100x faster than scipy's Python stepping; CVODE:
:mod:`rk4h.references.solvers.cvode_compiled`, scikit-sundae's CVODE with
compiled callbacks, equal to its run); its
row says so (``implementation``) and the trust table's note names it.

These runs are specs of the plan (purpose ``confirm``: a timed run over the
scene's output grid, executed like a ``run`` spec, kept out of the accuracy
and work-precision tables). They depend on the records of the scene's runs,
so they are planned in rounds after the plan has run
(``rk4h.validation.run_all``): :func:`next_specs` is a pure function of the
specs and records so far, and returns nothing once every target is settled,
so resumed records give the same rounds. At most :data:`MAX_ROUNDS` rounds.

Per target, the method under test runs at the predicted step; if that run
misses the target the step shrinks by the error ratio,
``h (target / err)^(1/p)`` times 0.9 (within 1/8 to 0.9 of ``h``), at most
:data:`CONFIRM_TRIES` steps in all. No run is made where a run of the scene
at that step or a larger one already met the target, where the step would
exceed :data:`MAX_CONFIRM_STEPS` steps, or where the round-off level
``sqrt(n) eps`` of its ``n`` steps exceeds the target.
"""
from __future__ import annotations

import math

import numpy as np

from rk4h.references.registry import BUILTIN

from . import trust
from .plan import TARGETS, RunSpec, scene_digest, under_test

__all__ = ["PURPOSE", "MAX_ROUNDS", "CONFIRM_TRIES", "MAX_CONFIRM_STEPS", "RTOL_FLOOR", "rows_of", "next_specs",
           "rtol_floor"]

PURPOSE = "confirm"
#: Rounds of confirmation runs after the plan (each round's runs depend on the records of the rounds before).
MAX_ROUNDS = 4
#: Steps tried per target for the method under test (the predicted one, then shrunk ones).
CONFIRM_TRIES = 3
#: A confirmation run of the method under test above this many steps is not made (the target stays
#: unconfirmed for it). The predicted steps of the committed report stay below 4.1e6.
MAX_CONFIRM_STEPS = 1e7
_EPS = float(np.finfo(float).eps)
#: The tightest rtol each reference is run at where the registry gives one (``Method.rtol_floor``:
#: heyoka's Taylor method in double precision, 10 eps); else 100 eps: scipy raises DOP853's rtol below
#: 100 eps to 100 eps (``rk4h.references.solvers.dop853.RTOL_MIN``), and CVODE's is taken the same.
RTOL_FLOOR = {n: m.rtol_floor for n, m in BUILTIN.items() if m.rtol_floor is not None}
_RTOL_FLOOR_DEFAULT = 100 * _EPS


def rtol_floor(solver: str) -> float:
    """The tightest rtol :func:`next_specs` runs ``solver`` at."""
    return RTOL_FLOOR.get(solver, _RTOL_FLOOR_DEFAULT)


def rows_of(specs, records) -> list[dict]:
    """Rows shaped like ``work_precision`` rows (``solver``, ``setting``,
    ``error_rel``, ``nfev``, ``n_steps``, ``taylor_order``, ``status``,
    ``wall_s``, ``wall_min``, ``wall_max``, ``compile_s``, and ``implementation``:
    ``"compiled"`` for a reference's confirmation run on its compiled loop,
    :func:`rk4h.references.solvers.integrate_compiled`) of the ``run`` or
    ``confirm`` specs among ``specs`` that have a record; a record without
    values (the execution raised) is a row with status ``failed``."""
    out = []
    for s in specs:
        rec = records.get(s.key)
        if rec is None:
            continue
        v, tm = rec.values, rec.timing or {}
        row = {"solver": s.solver, "setting": float(s.setting)}
        if not v:
            out.append({**row, "error_rel": math.nan, "error_max": math.nan, "nfev": 0, "n_steps": 0,
                        "taylor_order": 0, "status": "failed", "wall_s": math.nan, "wall_min": math.nan,
                        "wall_max": math.nan, "compile_s": math.nan})
            continue
        wall = tm.get("wall_s", math.nan)
        out.append({**row, "error_rel": v["error_rel"], "error_max": v["error_max"], "nfev": v["nfev"],
                    "n_steps": v["n_steps"], "taylor_order": v.get("taylor_order", 0), "status": rec.status,
                    "wall_s": wall, "wall_min": tm.get("wall_min", wall), "wall_max": tm.get("wall_max", wall),
                    "compile_s": tm.get("compile_s", 0.0), "implementation": v.get("implementation", "")})
    return out


def _at(rows, setting):
    return next((r for r in rows if math.isclose(float(r["setting"]), setting, rel_tol=1e-9)), None)


def _method_steps(rows, crows, method, scene, h_stab):
    """The confirmation steps of the method under test still to run."""
    order = int(method.order)
    pred = trust.predicted_steps(rows, method, scene.t_end, h_stab, TARGETS)
    mine = [r for r in rows + crows if r["solver"] == method.name]
    want = []
    for target, (h, _, _) in zip(TARGETS, pred["steps"]):
        if not math.isfinite(h):
            continue
        h = trust.on_grid(h, scene.output_dt)
        for _ in range(CONFIRM_TRIES):
            if trust.pick_measured([r for r in mine if r["setting"] >= h * (1 - 1e-9)], target) is not None:
                break  # a run at this step or a larger one met the target
            n = round(scene.t_end / h)
            if n > MAX_CONFIRM_STEPS or trust.roundoff_level(n) > target:
                break
            done = _at(mine, h)
            if done is None:
                want.append(h)
                break
            err = done["error_rel"]
            if done["status"] != "ok" or not (math.isfinite(err) and err > 0):
                break
            shrink = min(0.9, max(0.125, 0.9 * (target / err) ** (1.0 / order)))
            h_next = trust.on_grid(h * shrink, scene.output_dt)
            if not h_next < h:
                break
            h = h_next
    return want


def _reference_rtols(rows, crows, scene, under):
    """The next tighter rtol of each adaptive reference, where no run of any
    method but ``under`` reaches some target."""
    runs = rows + crows
    others = [r for r in runs if r["solver"] != under]
    if all(trust.pick_measured(others, t) is not None for t in TARGETS):
        return []
    want = []
    for solver in scene.adaptive_solvers:
        theirs = sorted((r for r in runs if r["solver"] == solver), key=lambda r: r["setting"])
        if not theirs:
            continue
        tight = theirs[0]
        if tight["status"] != "ok" or not math.isfinite(tight["error_rel"]):
            continue  # failed at its tightest tolerance: tighter would not help
        if len(theirs) >= 2 and _at(crows, tight["setting"]) is not None and \
                tight["error_rel"] >= 0.5 * theirs[1]["error_rel"]:
            continue  # tightening stopped lowering its error: at its floor
        floor = rtol_floor(solver)
        rtol = float(tight["setting"]) / 10
        if rtol < floor:
            if tight["setting"] <= floor * (1 + 1e-9):
                continue
            rtol = floor
        want.append((solver, rtol))
    return want


def next_specs(scene, specs, records) -> list[RunSpec]:
    """The confirmation specs of ``scene`` still to run, given its ``specs``
    so far (the plan and earlier rounds) and their ``records``; empty when
    the scene needs none (no ``work_precision`` output, no method under test,
    a run without a record yet) or every target is settled."""
    if "work_precision" not in scene.outputs:
        return []
    under = under_test(scene)
    runs = [s for s in specs if s.purpose == "run"]
    conf = [s for s in specs if s.purpose == PURPOSE]
    if under is None or not runs or any(s.key not in records for s in runs + conf):
        return []
    from .execute import problem

    rows, crows = rows_of(runs, records), rows_of(conf, records)
    method = scene.method(under)
    h_stab = trust.stable_step(method, trust.fastest_omega(problem(scene)[0]))
    dig = scene_digest(scene)
    repeats = int(runs[0].repeats)
    have = {s.key for s in specs}
    out = [RunSpec(scene.name, dig, PURPOSE, solver=under, setting=float(h), grid="scene", repeats=repeats)
           for h in _method_steps(rows, crows, method, scene, h_stab)]
    out += [RunSpec(scene.name, dig, PURPOSE, solver=solver, setting=float(rtol), grid="scene", repeats=repeats)
            for solver, rtol in _reference_rtols(rows, crows, scene, under)]
    seen = set(have)
    return [s for s in out if not (s.key in seen or seen.add(s.key))]
