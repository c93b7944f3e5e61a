"""Any ODE from Python: a plain ``fun(t, y)`` through the scene pipeline.

:func:`ode_scene` turns ``fun`` (scipy's convention), ``t_span``, ``y0`` and
an optional ``exact(t)`` and ``invariant(y)`` into a validated
:class:`rk4h.validation.scenes.Scene` whose model is an
:class:`rk4h.models.FunctionOde`; every rule of a scene file holds (the
steps divide the output spacing, which divides the horizon, ...). That scene
goes where a scene file goes: :func:`study` runs its plan (truth, runs,
convergence sweeps, the trust table's confirmation runs) in this process and
returns its tables and checks; :func:`rk4h.validation.advise.advise` gives the
advisor's answer for a target error.

The truth is ``exact`` when given, else DOP853 at its tightest tolerance
confirmed by a second reference (:mod:`rk4h.references.ode_truth`). The
invariant's drift is ``max |I(t) - I0| / |I0|`` (the ``energy_drift_max``
column). Times in the tables count from ``t_span[0]`` (the scene runs on
``[0, t_span[1] - t_span[0]]``; ``fun`` and ``exact`` are called at the
true times).

Example (Lotka-Volterra)::

    from rk4h.validation.ode import ode_scene, study

    def lv(t, y):
        u, v = y
        return [1.5*u - u*v, -3.0*v + u*v]

    scene = ode_scene(lv, (0.0, 20.0), [1.0, 1.0], h=[0.1, 0.05, 0.02, 0.01],
                      invariant=lambda y: y[0] - 3*np.log(y[0]) + y[1] - 1.5*np.log(y[1]))
    res = study(scene)
    res.tables["convergence"]     # observed orders; res.tables["work_precision"], ["cheapest"], ...
"""
from __future__ import annotations

import math

from rk4h.models import FunctionOde, MODELS, register_model

from .scenes import Scene, SceneError, scene_from_dict

__all__ = ["ode_scene", "study"]

if MODELS.get(FunctionOde.name) is not FunctionOde:
    register_model(FunctionOde)


def _shifted(f, t0: float, first: bool):
    """``f`` with its time argument counted from ``t0`` (first argument of
    ``fun(t, y)``, the only one of ``exact(t)``)."""
    if f is None or t0 == 0.0:
        return f
    if first:
        return lambda t, y: f(t + t0, y)
    return lambda t: f(t + t0)


def ode_scene(fun, t_span, y0, *, exact=None, invariant=None, h=None, tolerances=(1e-6, 1e-9, 1e-12),
              solvers=("rk4", "dop853"), outputs=None, output_dt=None, convergence=None, name="my-ode",
              names=None) -> Scene:
    """A validated scene of the ODE ``y' = fun(t, y)``, ``y(t_span[0]) = y0``.

    Parameters
    ----------
    fun : callable
        ``fun(t, y)`` -> ``dy/dt``, ``y`` of shape (n,).
    t_span : (float, float)
        Start and end times (s), ``t1 > t0``.
    y0 : array_like, shape (n,)
    exact : callable, optional
        ``exact(t)`` -> ``y`` at ``t`` (shape (n,) for a float, (n, m) for m
        times): the truth.
    invariant : callable, optional
        ``invariant(y)`` -> a float the exact flow conserves.
    h : list of float, optional
        Steps (s) of the fixed-step solvers (required when ``solvers`` lists
        one); each must divide the output spacing ``output_dt`` (default: the
        largest ``h``).
    tolerances : list of float
        rtol of the adaptive solvers.
    solvers, outputs, output_dt, convergence, name
        As the scene keys ``run.solvers``, ``run.outputs``, ``run.output_dt``,
        ``[convergence]``, ``name`` (docs/scene-reference.md).
    names : list of str, optional
        Names of the state components (figures, tables).

    Returns
    -------
    rk4h.validation.scenes.Scene

    Raises
    ------
    rk4h.validation.scenes.SceneError
        One line naming the field and the value.
    """
    try:
        t0, t1 = (float(v) for v in t_span)
    except (TypeError, ValueError):
        raise SceneError("<python>", "t_span", "must be two numbers (t0, t1)", t_span) from None
    if not (math.isfinite(t0) and math.isfinite(t1) and t1 > t0):
        raise SceneError("<python>", "t_span", "must be finite with t1 > t0", t_span)
    try:
        y = [float(v) for v in y0]
    except (TypeError, ValueError):
        raise SceneError("<python>", "y0", "must be a 1-D list of numbers", y0) from None
    params = {"fun": _shifted(fun, t0, True), "n": len(y), "exact": _shifted(exact, t0, False),
              "invariant": invariant}
    if names is not None:
        params["names"] = list(names)
    run = {"t_end": t1 - t0, "solvers": list(solvers)}
    for key, value in (("h", h), ("tolerances", tolerances), ("outputs", outputs), ("output_dt", output_dt)):
        if value is not None:
            run[key] = [float(v) for v in value] if key in ("h", "tolerances") else \
                list(value) if key == "outputs" else float(value)
    doc = {"name": name, "model": FunctionOde.name, "params": params, "initial": {"y": y}, "run": run}
    if convergence is not None:
        doc["convergence"] = dict(convergence)
    scene = scene_from_dict(doc, "<python>")
    model = scene.build_model()
    if exact is not None:
        import numpy as np

        e0 = np.asarray(model.exact_solution(np.array([0.0])), dtype=float)[:, 0]
        if not np.allclose(e0, y, rtol=1e-12, atol=0.0):
            raise SceneError("<python>", "exact", f"exact(t0) = {e0.tolist()} is not y0 = {y}")
    return scene


def study(scene, *, quick: bool = False, figures: bool = False):
    """Run ``scene``'s plan in this process, one run at a time (its truth,
    runs, convergence sweeps and the trust table's confirmation runs), and
    measure it.

    Returns
    -------
    rk4h.validation.measure.SceneTables
        ``tables`` (name -> list of row dicts: ``accuracy``,
        ``work_precision``, ``convergence``, ``energy``, ``cheapest`` (the
        trust table), ...; ``pandas.DataFrame(res.tables[NAME])``), ``checks``
        and ``failures`` (the expectations that did not hold).
    """
    from . import confirm
    from .execute import execute
    from .measure import measure
    from .plan import plan

    specs = plan(scene, quick=quick, figures=figures)
    records = {s.key: execute(scene, s, quick) for s in specs}
    for _ in range(confirm.MAX_ROUNDS):
        extra = [s for s in confirm.next_specs(scene, specs, records) if s.key not in records]
        if not extra:
            break
        specs = specs + extra
        records.update({s.key: execute(scene, s, quick) for s in extra})
    return measure(scene, specs, records, quick=quick, figures=figures)
