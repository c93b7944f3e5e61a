"""Work and memory a scene will take, estimated before anything runs.

A scene whose estimate exceeds a cap is refused up front (``run_all`` exits 2
with the estimate in the message) instead of running for hours or exhausting
memory. The estimate is a sum over everything the scene will run, and it costs
no eigensolve: the fastest frequency is the Gershgorin bound
:func:`rk4h.references.solvers.tolerances.omega_bound` (O(N) for a chain), an upper
bound of the linearized spectrum.

``steps``
    double-precision integration steps, summed over the scene's plan
    (:func:`rk4h.validation.plan.plan`, one term per spec: :func:`spec_steps`):
    every fixed-step run (``ceil(t_end / h)``), the convergence sweeps, the
    RK4 run behind the state figures, for each adaptive run a lower bound of
    :data:`ADAPTIVE_STEPS_PER_PERIOD` steps per period of the fastest mode,
    and each stability unit (:func:`rk4h.validation.stability.unit_steps`).
    Timing repeats are not counted (runs longer than 0.1 s are timed once).
    Cap: :data:`MAX_STEPS` (``--max-steps``).
``truth_steps``
    quadruple-precision Taylor steps of the reference of a nonlinear model
    (heyoka ``real128``, about 1 ms per step on a 2-DOF model on the
    development machine): :data:`TRUTH_STEPS_PER_PERIOD` per period of the
    fastest mode over each horizon that needs one (the output grid, the
    convergence sweep, the figures when no RK4 run draws them). Linear models
    have closed forms and cost none. Cap: :data:`MAX_TRUTH_STEPS`
    (``--max-truth-steps``).
``dense_dof``
    the size of the dense eigenproblem ``K phi = omega^2 M phi`` the scene
    solves (the exact modal reference of a linear model, the convergence
    horizon, the modes table): ``n_dof``, or 0 when only the stability study
    runs. O(n^3): 4.4 s at 3000 on the development machine, about 20 s at
    5000, several minutes at 10^4. Cap: :data:`MAX_DENSE_DOF`.
``memory_bytes``
    the whole process: :data:`BASE_BYTES` for the interpreter and libraries,
    plus :data:`TRAJECTORIES_HELD` trajectories on the output grid (the
    reference and its low part, the run, its difference and energy, the
    timing repeats), each ``8 x state size x output points`` bytes. Cap:
    :data:`MAX_BYTES`; decimated output (``[run] max_output_points`` or
    ``run_all --max-output-points``) lowers it.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from .scenes import MAX_DENSE_DOF, Scene, SceneError

__all__ = ["Estimate", "estimate", "check", "MAX_STEPS", "MAX_TRUTH_STEPS", "MAX_BYTES", "MAX_DENSE_DOF",
           "ADAPTIVE_STEPS_PER_PERIOD", "TRUTH_STEPS_PER_PERIOD", "TRAJECTORIES_HELD", "BASE_BYTES"]

#: Largest number of double-precision integration steps a scene may ask for.
MAX_STEPS = 1e9
#: Largest number of quadruple-precision Taylor steps of a scene's reference
#: (~1e3 s at ~1 ms per step on a 2-DOF model).
MAX_TRUTH_STEPS = 1e6
#: Largest estimated memory of the whole process (bytes): 4 GiB.
MAX_BYTES = 4 * 2**30
#: Adaptive solvers: at least this many steps per period of the fastest mode
#: (a lower bound; DOP853 at rtol 1e-6 takes about 10).
ADAPTIVE_STEPS_PER_PERIOD = 4
#: heyoka real128 at tol 1e-32 (order 38): 9-25 steps per period of the
#: Gershgorin frequency on the shipped nonlinear models; 30 bounds them.
TRUTH_STEPS_PER_PERIOD = 30
#: Trajectories on the output grid the runner holds at its peak: measured 9.8
#: (maximum resident set 1.15 GB, 0.22 GB without the trajectories) on a
#: one-mass scene with a 95 MiB trajectory, RK4 and DOP853, --repeats 3;
#: 12 leaves a margin.
TRAJECTORIES_HELD = 12
#: The interpreter with numpy, scipy, numba, heyoka and matplotlib loaded.
BASE_BYTES = 400 * 2**20


@dataclass(frozen=True)
class Estimate:
    """What a scene will cost: steps, quadruple-precision steps, output points,
    state size, the fastest frequency bound (rad/s), and the number of runs
    of its plan (``runs``)."""

    steps: float
    truth_steps: float
    output_points: int
    state_size: int
    omega_max: float
    dense_dof: int = 0
    runs: int = 0

    @property
    def trajectory_bytes(self) -> float:
        return 8.0 * self.state_size * self.output_points

    @property
    def memory_bytes(self) -> float:
        return BASE_BYTES + TRAJECTORIES_HELD * self.trajectory_bytes


def _omega_bound(model) -> float:
    import numpy as np

    from rk4h.references.solvers.tolerances import omega_bound

    try:
        with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
            w = float(omega_bound(model))
    except (ValueError, ArithmeticError, TypeError, NotImplementedError):
        return math.nan
    return w


def _rate(scene, model) -> float:
    """The frequency bound (rad/s) the estimate runs on: :func:`_omega_bound`,
    or a first-order ODE's rate at its initial state
    (:func:`rk4h.validation.execute.fastest_rate`, 1/s)."""
    if getattr(model, "first_order", False):
        from .execute import fastest_rate

        return fastest_rate(scene, model)
    return _omega_bound(model)


def _steps(t_end: float, h: float) -> int:
    from rk4h.solver import step_count

    return step_count((0.0, t_end), h)  # the integrator's own rule


def spec_steps(scene, spec, model, w, quick=False) -> tuple[float, float]:
    """``(steps, truth_steps)`` of one spec (see the module docstring); ``w``
    is the model's fastest-frequency bound (rad/s)."""
    periods = lambda T: T * w / (2 * math.pi)  # noqa: E731
    nonlinear = not getattr(model, "linear", True)
    p = spec.purpose
    if p == "truth":
        if spec.grid == "order":
            T = min(scene.convergence.get("t_end", 2.0 * math.pi / w), scene.t_end) if w > 0 else 0.0
            return 0.0, nonlinear * TRUTH_STEPS_PER_PERIOD * periods(T)
        return 0.0, nonlinear * TRUTH_STEPS_PER_PERIOD * periods(scene.t_end)
    if p in ("run", "confirm", "figure", "modal"):
        if scene.method(spec.solver).fixed_step:
            return float(_steps(scene.t_end, spec.setting)), 0.0
        return ADAPTIVE_STEPS_PER_PERIOD * periods(scene.t_end), 0.0
    if p == "order":
        if w <= 0:
            return 0.0, 0.0
        T = min(scene.convergence.get("t_end", 2.0 * math.pi / w), scene.t_end)
        top = spec.param("theta0")
        n0 = max(1, math.ceil(T * w / top))
        return float(n0 * max(1, round(top / spec.setting))), 0.0
    if p == "stability":
        from .stability import unit_steps

        return float(unit_steps(scene, spec.unit, quick)), 0.0
    if p == "linearization":
        return 0.0, 0.0  # its truth is the scene grid's
    if p == "packet":
        return 4e4, 0.0  # wavepacket.measure_group_velocity: 400 sites, about 4e4 steps
    if p == "ensemble":  # every instance of [ensemble] at this step
        n = _steps(scene.t_end, spec.setting)
        if not getattr(model, "linear", True):  # and the batch reference: at h_ref / 2 and its confirmation at h_ref
            from .outputs.ensemble import reference_step

            n += 3 * _steps(scene.t_end, reference_step(scene, model))
        return float(scene.ensemble["size"] * n), 0.0
    if p == "amplitude_ensemble":  # every instance at h, a few at h/2
        return float(scene.ensemble["size"] * _steps(scene.t_end, spec.setting)), 0.0
    if p == "stability_map":  # every (value, h) of the map, map_steps steps each at most
        from .ensemble import map_settings

        _, values, hs, n = map_settings(scene.ensemble, model)
        return float(values.size * hs.size * n), 0.0
    return 0.0, 0.0


def spec_cost_function():
    """``cost(scene, spec) -> float``: a relative cost estimate (steps x DOF,
    quadruple-precision steps weighted 1e3) for ordering the work."""
    cache = {}

    def cost(scene, spec):
        if scene.name not in cache:
            try:
                model = scene.build_model()
                cache[scene.name] = (model, _rate(scene, model))
            except Exception:  # noqa: BLE001 - ordering only
                cache[scene.name] = (None, math.nan)
        model, w = cache[scene.name]
        if model is None or not math.isfinite(w):
            return 0.0
        try:
            steps, truth = spec_steps(scene, spec, model, w)
        except Exception:  # noqa: BLE001
            return 0.0
        return steps * model.n_dof + 1e3 * truth * model.n_dof
    return cost


def estimate(scene: Scene, model=None, *, quick: bool = False) -> Estimate:
    """Estimate the cost of ``scene``: the sum over its plan
    (:func:`rk4h.validation.plan.plan`) of :func:`spec_steps`. Raises
    ``ValueError`` when the model's frequency bound is not a finite number."""
    from .plan import plan

    model = model if model is not None else scene.build_model()
    w = _rate(scene, model)
    if not math.isfinite(w) or w < 0:
        raise ValueError(f"the fastest frequency bound of the model is {w!r} rad/s, not a finite number "
                         f"(are the masses or stiffnesses extreme?)")
    steps = truth = 0.0
    specs = plan(scene, quick=quick)
    for spec in specs:
        a, b = spec_steps(scene, spec, model, w, quick)
        steps += a
        truth += b
    if not (math.isfinite(steps) and math.isfinite(truth)):
        raise ValueError(f"the estimate is not finite (steps {steps!r}, quadruple-precision steps {truth!r})")
    dense = model.n_dof if set(scene.outputs) - {"stability"} else 0
    return Estimate(steps=steps, truth_steps=truth, output_points=scene.n_output_points,
                    state_size=model.n_state, omega_max=w, dense_dof=dense, runs=len(specs))


def _gib(b: float) -> str:
    return f"{b / 2**30:.3g} GiB"


def check(scene: Scene, *, max_steps: float = MAX_STEPS, max_truth_steps: float = MAX_TRUTH_STEPS,
          max_bytes: float = MAX_BYTES) -> Estimate:
    """Refuse ``scene`` with a :class:`SceneError` (one line, the estimate in it)
    when it exceeds a cap; return the estimate."""
    path = scene.path if scene.path is not None else scene.name
    try:
        est = estimate(scene)
    except (ValueError, ArithmeticError) as e:
        raise SceneError(path, "run", f"its cost cannot be estimated: {e}") from None
    if est.steps > max_steps:
        raise SceneError(path, "run", f"asks for about {est.steps:.3g} integration steps, above the cap "
                         f"of {max_steps:.3g} (raise it with --max-steps)")
    if est.truth_steps > max_truth_steps:
        raise SceneError(path, "run", f"needs about {est.truth_steps:.3g} quadruple-precision steps for its "
                         f"reference (roughly {est.truth_steps * 1e-3 * est.state_size / 4 / 60:.3g} min), "
                         f"above the cap of {max_truth_steps:.3g} (shorten t_end, or raise it with "
                         f"--max-truth-steps)")
    if est.dense_dof > MAX_DENSE_DOF:
        raise SceneError(path, "run", f"needs a dense eigensolve of {est.dense_dof} degrees of freedom (its "
                         f"modes and exact reference), above the cap of {MAX_DENSE_DOF} (minutes of O(n^3) "
                         f"work); keep outputs = [\"stability\"] for chains this long")
    if est.memory_bytes > max_bytes:
        raise SceneError(path, "run", f"needs about {_gib(est.memory_bytes)} of memory ({TRAJECTORIES_HELD} "
                         f"trajectories of 8 B x {est.state_size} states x {est.output_points:.3g} output "
                         f"points), above the cap of {_gib(max_bytes)}; decimate with [run] "
                         f"max_output_points or --max-output-points")
    return est
