"""The reference ("truth") of a first-order ODE (``model.first_order``:
:class:`rk4h.models.OdeModel`, :class:`rk4h.models.FunctionOde`).

``ode_reference(model, y0, t_eval)`` returns a :class:`rk4h.references.truth.Truth`:

* the model's exact solution when it has one (``kind = "exact"``);
* else the tightest reference the harness has for an arbitrary right-hand
  side, DOP853 at scipy's floor ``rtol = 100 eps`` (2.2e-14, ``atol = rtol
  s`` with ``s = max |y0|``), **confirmed** by a second, independent
  reference: CVODE's Adams method at the tightest of :data:`CONFIRM_RTOLS`
  at which it finishes (DOP853 at that tolerance when scikit-sundae is not
  installed). The two must agree
  to :data:`AGREE_REL` of the state scale at every output time (max over
  times and components of ``|a - b| / max|a|``); their agreement is reported
  (``extra["agreement_rel"]``, ``extra["confirmed_by"]`` and the message).
  Where they disagree, or either run fails, there is no truth: ``status``
  FAILED and a message saying why, never a number
  (``kind = "dop853-confirmed"``).

heyoka is not used: its equations are built from a mechanical model's force.

``energy_drift`` is the invariant's drift ``max |I(t) - I0| / |I0|`` of the
reference (absolute where ``I0 = 0``; NaN without an invariant).

Results are kept in memory for the process, keyed by the model's identity
(its class and parameters, or the function objects of a :class:`FunctionOde`),
``y0`` and ``t_eval``; nothing is written to disk (a Python function has no
source the key could hold).
"""
from __future__ import annotations

import hashlib
import json
import time

import numpy as np

from .solvers.base import Status
from .solvers.dop853 import RTOL_MIN

__all__ = ["ode_reference", "AGREE_REL", "CONFIRM_RTOLS", "KIND_EXACT", "KIND_CONFIRMED"]

#: Largest disagreement (relative to the state scale max |y|) between the two
#: references for their result to be a truth.
AGREE_REL = 1e-8
#: Tolerances of the confirming reference, tightest first: the first at which
#: it finishes is used (CVODE may give up at 1e-14 where 1e-12 works).
CONFIRM_RTOLS = (1e-14, 1e-12)
KIND_EXACT = "exact"
KIND_CONFIRMED = "dop853-confirmed"
_MEMORY: dict = {}
_MAX_MEMORY = 64


def _key(model, y0, t) -> str:
    from .solvers.taylor import model_key

    h = hashlib.sha256()
    ident = [id(model)] if type(model).__name__ == "FunctionOde" else []  # a function: its object
    h.update(json.dumps({"model": model_key(model), "ident": ident, "y0": [float(v).hex() for v in y0]}).encode())
    h.update(np.ascontiguousarray(t, dtype="<f8").tobytes())
    return h.hexdigest()


def _drift(model, y) -> float:
    from rk4h.energy import relative_energy_error

    if not model.has_invariant():
        return float("nan")
    with np.errstate(all="ignore"):
        r = np.abs(relative_energy_error(model, y))
    return float(np.max(r)) if r.size and not np.isnan(r).any() else float("nan")


def _confirming_run(model, y0, t):
    """``(name, rtol, run)`` of the confirming reference: CVODE-Adams at the
    first of :data:`CONFIRM_RTOLS` at which it finishes (DOP853 without
    scikit-sundae)."""
    from .solvers import integrate

    try:
        import sksundae  # noqa: F401

        name = "cvode-adams"
    except ImportError:
        name = "dop853"
    for rtol in CONFIRM_RTOLS:
        run = integrate(name, model, y0, t, rtol)
        if run.ok:
            break
    return name, rtol, run


def ode_reference(model, y0, t, Truth):
    """The reference trajectory of the first-order ``model`` from ``y0`` (at
    ``t[0]``) on the output times ``t`` (s), as a ``Truth`` (the class
    :class:`rk4h.references.truth.Truth`, passed in by the caller); see the
    module docstring. ``y0`` and ``t`` are checked by the caller
    (:func:`rk4h.references.truth.reference_solution`)."""
    from .solvers import integrate

    key = _key(model, y0, t)
    hit = _MEMORY.get(key)
    if hit is not None and hit[0] is model or (hit is not None and type(model).__name__ != "FunctionOde"):
        return Truth(**{**hit[1].__dict__, "source": "memory"})
    start = time.perf_counter()
    y_exact = model.exact_solution(t)
    if y_exact is not None:
        y = np.asarray(y_exact, dtype=float)
        truth = Truth(t, y, None, KIND_EXACT, _drift(model, y), wall_s=time.perf_counter() - start,
                      message="the model's exact solution (float64 evaluation)", key=key)
        if not np.all(np.isfinite(y)):
            truth.status, truth.message = Status.FAILED, "the exact solution is not finite at every output time"
    else:
        best = integrate("dop853", model, y0, t, RTOL_MIN)
        name, rtol, second = _confirming_run(model, y0, t)
        extra = {"reference": f"dop853 rtol {RTOL_MIN:.3g}", "confirmed_by": f"{name} rtol {rtol:g}",
                 "nfev": int(best.nfev)}
        status, message = Status.OK, ""
        y = np.asarray(best.y, dtype=float)
        if not best.ok:
            status, message = Status.FAILED, f"the reference dop853 did not finish: {best.message}"
        elif not second.ok:
            status, message = Status.FAILED, f"the confirming reference {name} did not finish: {second.message}"
        else:
            scale = float(np.max(np.abs(y))) or 1.0
            agree = float(np.max(np.abs(y - np.asarray(second.y, float)))) / scale
            extra["agreement_rel"] = agree
            if not agree <= AGREE_REL:
                status = Status.FAILED
                message = (f"the references disagree: dop853 (rtol {RTOL_MIN:.3g}) and {name} (rtol "
                           f"{rtol:g}) differ by {agree:.3g} of the state scale (at most {AGREE_REL:g})")
            else:
                message = (f"dop853 at rtol {RTOL_MIN:.3g}, confirmed by {name} at rtol {rtol:g} to "
                           f"{agree:.2g} of the state scale")
        if status is not Status.OK:
            y = np.full_like(y, np.nan)
        truth = Truth(t, y, None, KIND_CONFIRMED, _drift(model, y) if status is Status.OK else float("nan"),
                      tol=RTOL_MIN, n_steps=int(best.n_steps), wall_s=time.perf_counter() - start,
                      status=status, message=message, key=key, extra=extra)
    if len(_MEMORY) >= _MAX_MEMORY:
        _MEMORY.clear()
    _MEMORY[key] = (model, truth)  # the model kept alive: its id is in the key
    return truth
