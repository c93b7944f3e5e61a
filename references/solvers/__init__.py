"""Every solver behind one call: ``integrate(solver, model, y0, t_eval, setting)``.

Solvers (``SOLVER_NAMES``)
--------------------------
Fixed-step methods (``rk4``, ``euler``, ``symplectic-euler``, ``stormer-verlet``, ``rk38``...; a scene's own tableaux)
    ``rk4h.solve`` on ``model.rhs`` with the method's tableau (the compiled
    loop of ``rk4h.fast`` when the model has one); ``setting`` is the step ``h`` (s).
A scene's ``python`` and ``command`` methods
    :mod:`rk4h.references.solvers.stepper` and :mod:`rk4h.references.solvers.command`;
    ``setting`` is the step ``h`` (s).
``dop853``
    scipy's explicit RK 8(5,3) on the model's right-hand side compiled from its definition
    (``rk4h.fast.CompiledRHS``; ``model.rhs`` when it has none); ``setting`` is ``rtol``.
    :func:`integrate_compiled` runs the same method as one compiled loop
    (:mod:`rk4h.fast.dop853`), equal to scipy's step for step to round-off, for
    untimed work (the trust table's confirmation runs); timed rows keep scipy's.
    Where steps are rejected near the tolerance a run can part from scipy's, as
    scipy's own does when rtol moves one ulp (``benchmarks/dop853_parting.py``).
``cvode-adams``, ``cvode-bdf``
    SUNDIALS CVODE (scikit-sundae) on the compiled right-hand side (as
    DOP853), analytic Jacobian, banded for chains; ``setting`` is ``rtol``.
    :func:`integrate_compiled` drives the same CVODE library through
    ``ctypes`` with compiled callbacks (:mod:`rk4h.references.solvers.cvode_compiled`),
    equal to scikit-sundae's run, for untimed work; timed rows keep scikit-sundae's.
``heyoka``
    heyoka's Taylor integrator, double precision, on ``model.heyoka_system()``
    (the same ``_force`` code as ``model.rhs``); ``setting`` is ``rtol``.

Absolute tolerance rule (adaptive solvers, ``atol=None``)
---------------------------------------------------------
``atol_i = rtol * s_i`` with one scale for the positions and one for the
velocities, from the initial state and the model's fastest linearised
frequency ``w`` (Gershgorin bound ``sqrt(max_i sum_j |K_ij| / m_i)``):
``s_q = max(max|q0|, max|v0| / w)``, ``s_v = max(max|v0|, w max|q0|)`` (a zero
scale becomes 1). Millimetre states are so judged relative to millimetres.
heyoka, which has one tolerance (absolute below 1, relative above), integrates
the scaled state ``y / s`` with ``tol = rtol``: the same rule. A caller's
``atol`` (scalar or per component) replaces the rule; heyoka then uses the
scales ``atol / rtol`` (smallest per group). ``run.atol`` is the position
component's atol, ``run.extra["atol_state"]`` the whole vector.

Arguments
---------
``model`` must be an :class:`rk4h.models.Model` (a name such as
``"chain"`` is refused with a ``ValueError`` naming ``model``), and ``y0`` a
state where the model's force and energy are finite
(:meth:`rk4h.models.Model.check_state`): planar4 on an anchor or two
triangle masses on top of each other (a spring of zero length) and states so
large that the energy overflows raise ``ValueError`` naming ``y0`` before
anything is integrated.

Outcome
-------
A run never raises once its arguments are valid: a solver's error flag, step
cap, non-finite state or any exception inside becomes ``status`` FAILED or
UNSTABLE with ``message`` and ``t_fail``; ``y`` is NaN where not reached.
Every adaptive run is bounded: ``max_steps`` caps DOP853's and CVODE's
accepted steps (DOP853 also its right-hand-side evaluations) and heyoka's
Taylor steps; a run that reaches a state where the force is not finite ends
UNSTABLE at about that time instead of shrinking its step forever.
"""
from __future__ import annotations

import math

import numpy as np

from rk4h.models.base import Model
from rk4h.validate import check_model_y0, check_output_times, positive

from ..registry import BUILTIN, Kind, Method, resolve
from .base import ADAPTIVE, FIXED_STEP, SOLVER_NAMES, SolverRun, Status
from .cvode import DEFAULT_MAX_STEPS, run_cvode
from .cvode_compiled import run_cvode_compiled
from .dop853 import run_dop853, run_dop853_compiled
from .fixed import run_fixed, run_fixed_short
from .stepper import run_python
from .taylor import run_heyoka
from .tolerances import absolute_tolerance

__all__ = ["integrate", "integrate_compiled", "COMPILED_RUNNERS", "COMPILED_LOOPS", "check_setting", "check_model",
           "as_model", "MECHANICAL_ONLY", "mechanical_only", "SOLVER_NAMES", "FIXED_STEP", "ADAPTIVE", "Status",
           "SolverRun", "absolute_tolerance"]


def check_setting(solver, setting) -> float:
    """Validate ``setting`` for ``solver`` (a built-in name or a
    :class:`rk4h.references.registry.Method`): a finite step ``h > 0`` for the
    fixed-step methods, a relative tolerance in (0, 1) for adaptive ones.

    Raises ``ValueError`` naming the solver or the setting."""
    method = resolve(solver)
    name = method.name
    if method.fixed_step:
        return positive(f"h ({name})", setting)
    rtol = positive(f"rtol ({name})", setting)
    if rtol >= 1.0:
        raise ValueError(f"`rtol ({name})` must be < 1, got {setting!r}")
    return rtol


def check_model(model):
    """``model`` if it is an :class:`rk4h.models.Model`; else raise
    ``ValueError`` naming ``model`` (a model name is not a model: build it
    with ``rk4h.make_model``)."""
    if not isinstance(model, Model):
        hint = " (build it with rk4h.make_model(name, params))" if isinstance(model, str) else ""
        raise ValueError(f"`model` must be an rk4h.models.Model instance{hint}, got {model!r:.80}")
    return model


def as_model(model, y0):
    """``model`` itself when it is an :class:`rk4h.models.Model`; a plain
    callable ``fun(t, y)`` (scipy's convention) as an
    :class:`rk4h.models.FunctionOde` with ``len(y0)`` components; else
    ``ValueError`` naming ``model``."""
    if callable(model) and not isinstance(model, (Model, type)):
        from rk4h.models.ode import FunctionOde

        try:
            n = int(np.asarray(y0, dtype=float).reshape(-1).shape[0])
        except (TypeError, ValueError):
            raise ValueError(f"`y0` must be a 1-D array of real numbers, got {y0!r:.80}") from None
        return FunctionOde(model, n)
    return check_model(model)


#: Reference adapters that need a mechanical model (a potential: heyoka's
#: equations), not a first-order ODE; read from a method's ``adapter``, so a
#: reference renamed in the registry keeps the rule.
MECHANICAL_ONLY = ("heyoka",)


def mechanical_only(method) -> bool:
    """Whether ``method`` (a :class:`rk4h.references.registry.Method`) needs a
    mechanical model: heyoka (equations from the force), a command method
    (the problem file holds masses and springs), a partitioned tableau (it
    integrates ``q' = v`` and uses only the acceleration half of ``fun``)."""
    return method.runner_key in MECHANICAL_ONLY or method.kind in (Kind.COMMAND, Kind.PARTITIONED)


def _check_inputs(model, y0, t_eval, atol, max_steps):
    check_model(model)
    y0 = model.check_state(check_model_y0(model, y0), "y0")
    t = check_output_times(t_eval)
    if atol is not None:
        a = np.broadcast_to(np.asarray(atol, dtype=float), y0.shape).copy()
        if not np.all(np.isfinite(a)) or not np.all(a > 0):
            raise ValueError(f"`atol` must be finite and > 0, got {atol!r}")
        atol = a
    if isinstance(max_steps, bool) or not isinstance(max_steps, (int, np.integer)) or max_steps < 1:
        raise ValueError(f"`max_steps` must be an integer >= 1, got {max_steps!r}")
    return y0, t, atol


#: The runner of each reference adapter (``Method.adapter`` in the registry):
#: ``runner(model, y0, t, rtol, atol, max_steps) -> SolverRun``. A reference
#: whose adapter has no entry is an error, never another solver's run.
REFERENCE_RUNNERS = {
    "dop853": run_dop853,
    "cvode-adams": lambda *a: run_cvode("cvode-adams", *a),
    "cvode-bdf": lambda *a: run_cvode("cvode-bdf", *a),
    "heyoka": run_heyoka,
}


def integrate(solver, model, y0, t_eval, setting: float, *, atol=None,
              max_steps: int = DEFAULT_MAX_STEPS) -> SolverRun:
    """Integrate ``model`` from ``y0`` at ``t_eval[0]`` to ``t_eval[-1]`` with ``solver``.

    Parameters
    ----------
    solver : str or rk4h.references.registry.Method
        A built-in method's name (``SOLVER_NAMES``) or a method (a scene's
        own: ``Scene.method(name)``).
    model : rk4h.models.Model or callable
        A model, or a plain ``fun(t, y)`` (any first-order ODE; wrapped in
        :class:`rk4h.models.FunctionOde`; not for ``heyoka`` or command
        methods).
    y0 : array_like, shape (2 n_dof,) or (n,)
        Initial state ``[q, v]`` (SI units of the model's coordinates), or
        ``y`` of a first-order model.
    t_eval : array_like, shape (m,)
        Output times (s), strictly increasing, ``m >= 2``.
    setting : float
        Step ``h`` (s) for ``FIXED_STEP`` solvers, ``rtol`` for ``ADAPTIVE`` ones.
    atol : float or array_like, optional
        Absolute tolerance (adaptive solvers); default: the rule in the module
        docstring.
    max_steps : int, optional
        Cap on the total steps of an adaptive run: CVODE's internal steps,
        DOP853's accepted steps (and ``30 max_steps`` RHS evaluations),
        heyoka's Taylor steps; ignored by the fixed-step solvers, whose step
        count is ``ceil((t_eval[-1] - t_eval[0]) / h)``.

    Returns
    -------
    SolverRun
        ``y`` of shape (2 n_dof, m) at ``t_eval``.
    """
    return _integrate(solver, model, y0, t_eval, setting, atol, max_steps, REFERENCE_RUNNERS)


def _integrate(solver, model, y0, t_eval, setting, atol, max_steps, runners) -> SolverRun:
    """:func:`integrate` with ``runners`` (adapter -> runner) for the references."""
    if atol is None:
        run = _fixed_short(solver, model, y0, t_eval, setting, max_steps)
        if run is not None:
            return run
    method = resolve(solver)
    setting = check_setting(method, setting)
    model = as_model(model, y0)
    if getattr(model, "first_order", False) and mechanical_only(method):
        raise ValueError(f"solver {method.name!r} needs a mechanical model (y = [q, v], masses, a potential); "
                         f"{model.name!r} is a first-order ODE")
    y0, t, atol = _check_inputs(model, y0, t_eval, atol, max_steps)
    if method.kind in (Kind.TABLEAU, Kind.PARTITIONED):
        return run_fixed(method.tableau, model, y0, t, setting)
    if method.kind is Kind.PYTHON:
        return run_python(method, model, y0, t, setting)
    if method.kind is Kind.COMMAND:
        from .command import run_command_method

        return run_command_method(method.name, list(method.argv), model, y0, t, setting,
                                  nfev_per_step=method.nfev_per_step)
    if atol is None:
        atol = absolute_tolerance(model, y0, setting)
    runner = runners.get(method.adapter)
    if runner is None:
        raise ValueError(f"solver: no adapter runs the reference {method.name!r} (adapter {method.adapter!r}; "
                         f"adapters: {', '.join(sorted(runners))})")
    return runner(model, y0, t, setting, atol, int(max_steps))


_SHORT_KINDS = (Kind.TABLEAU, Kind.PARTITIONED)


def _fixed_short(solver, model, y0, t_eval, setting, max_steps):
    """A repeated fixed-step call on the short path
    (:func:`rk4h.references.solvers.fixed.run_fixed_short`), or None: the
    general path then checks everything and says what is wrong. Here only
    the arguments that need no message are tested, each with one cheap test."""
    if type(solver) is str:
        method = BUILTIN.get(solver)
    else:
        method = solver if type(solver) is Method else None
    if method is None or method.kind not in _SHORT_KINDS:
        return None
    if type(setting) not in (float, np.float64) or not 0.0 < setting < math.inf:
        return None
    if type(max_steps) is not int or max_steps < 1:
        return None
    return run_fixed_short(method.tableau, model, y0, t_eval, float(setting))


#: Reference adapters with a compiled loop for untimed work (:func:`integrate_compiled`).
COMPILED_RUNNERS = {"dop853": run_dop853_compiled,
                    "cvode-adams": lambda *a: run_cvode_compiled("cvode-adams", *a),
                    "cvode-bdf": lambda *a: run_cvode_compiled("cvode-bdf", *a)}
#: The compiled code each of :data:`COMPILED_RUNNERS` steps, by adapter
#: (:mod:`rk4h.validation.warm` prepares each once per machine): DOP853's
#: loop on the model's right-hand side; CVODE's two share their C callbacks.
COMPILED_LOOPS = {"dop853": "dop853", "cvode-adams": "cvode", "cvode-bdf": "cvode"}


def integrate_compiled(solver, model, y0, t_eval, setting: float, *, atol=None,
                       max_steps: int = DEFAULT_MAX_STEPS) -> SolverRun:
    """:func:`integrate` for untimed work (confirmation runs): a reference
    with a compiled loop (:data:`COMPILED_RUNNERS`: DOP853 stepped by
    :func:`rk4h.references.solvers.dop853.run_dop853_compiled`, equal to scipy's
    step for step to round-off; CVODE driven through ``ctypes`` with compiled callbacks by
    :func:`rk4h.references.solvers.cvode_compiled.run_cvode_compiled`, equal to
    scikit-sundae's) runs it; every other solver, and a model without a
    compiled right-hand side, runs as :func:`integrate` runs it.
    ``run.extra["implementation"]`` is ``"compiled"`` where the compiled
    loop ran. Same arguments, checks and result."""
    return _integrate(solver, model, y0, t_eval, setting, atol, max_steps, {**REFERENCE_RUNNERS, **COMPILED_RUNNERS})
