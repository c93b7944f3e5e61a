"""Work and memory a scene will take, estimated before anything runs.

A scene whose estimate exceeds a cap is refused up front (``run_all`` exits 2
with the estimate in the message) instead of running for hours or exhausting
memory:

``steps``
    integration steps of the runs the scene asks for: every fixed-step run
    (``ceil(t_end / h)`` per solver and step), the convergence sweeps
    (:func:`validation.experiments.order_sweep`), the RK4 run behind the state
    figures, and for each adaptive run a lower bound of
    :data:`ADAPTIVE_STEPS_PER_PERIOD` steps per period of the fastest
    (linearized) mode. Timing repeats are not counted (runs longer than 1 s
    are timed once). Cap: :data:`MAX_STEPS`.
``trajectory_bytes``
    one trajectory on the output grid, ``8 x state size x output points``
    (float64). The runner holds a few of these at once (reference, run, their
    difference), so peak memory is a small multiple of it. Cap:
    :data:`MAX_BYTES`; decimated output (``[run] max_output_points`` or
    ``run_all --max-output-points``) lowers it.

The stability study (``outputs = ["stability"]``) sizes its own runs from its
``[stability]`` table and is not part of this estimate.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from references.solvers.base import ADAPTIVE, FIXED_STEP

from .scenes import Scene, SceneError

__all__ = ["Estimate", "estimate", "check", "MAX_STEPS", "MAX_BYTES", "ADAPTIVE_STEPS_PER_PERIOD"]

#: Largest number of integration steps a scene may ask for.
MAX_STEPS = 1e9
#: Largest trajectory (bytes) on a scene's output grid: 4 GiB.
MAX_BYTES = 4 * 2**30
#: Adaptive solvers: at least this many steps per period of the fastest mode
#: (a lower bound; DOP853 at rtol 1e-6 takes about 10).
ADAPTIVE_STEPS_PER_PERIOD = 4


@dataclass(frozen=True)
class Estimate:
    """What a scene will cost: steps, output points, state size, bytes."""

    steps: float
    output_points: int
    state_size: int
    omega_max: float

    @property
    def trajectory_bytes(self) -> float:
        return 8.0 * self.state_size * self.output_points


def _omega_max(model) -> float:
    try:
        w = float(max(model.modes()[0]))
    except Exception:  # noqa: BLE001 - no (finite) linearization: no frequency-based estimate
        return math.nan
    return w if math.isfinite(w) and w > 0 else math.nan


def estimate(scene: Scene, model=None) -> Estimate:
    """Estimate the cost of ``scene`` (see the module docstring)."""
    from .experiments import EULER_THETAS, RK4_THETAS, convergence_horizon

    model = model if model is not None else scene.build_model()
    w = _omega_max(model)
    want = set(scene.outputs)
    steps = 0.0
    if {"state", "energy", "work_precision"} & want:
        for s in scene.solvers:
            if s in FIXED_STEP:
                steps += sum(math.ceil(scene.t_end / h * (1 - 1e-12)) for h in scene.h)
            elif s in ADAPTIVE and math.isfinite(w):
                steps += len(scene.tolerances) * ADAPTIVE_STEPS_PER_PERIOD * scene.t_end * w / (2 * math.pi)
    if "figures" in want and scene.h and "rk4" in scene.solvers:
        steps += math.ceil(scene.t_end / min(scene.h) * (1 - 1e-12))
    if "convergence" in want and math.isfinite(w):
        T = convergence_horizon(scene, model)
        for thetas in (scene.convergence.get("theta", RK4_THETAS),
                       scene.convergence.get("theta_euler", EULER_THETAS),
                       scene.convergence.get("theta_euler", EULER_THETAS)):
            top = max(thetas)
            n0 = max(1, math.ceil(T * w / top))
            steps += sum(n0 * max(1, round(top / th)) for th in thetas)
    return Estimate(steps=steps, output_points=scene.n_output_points, state_size=2 * model.n_dof,
                    omega_max=w)


def _gib(b: float) -> str:
    return f"{b / 2**30:.3g} GiB"


def check(scene: Scene, *, max_steps: float = MAX_STEPS, max_bytes: float = MAX_BYTES) -> Estimate:
    """Refuse ``scene`` with a :class:`SceneError` (one line, the estimate in it)
    when it exceeds ``max_steps`` or ``max_bytes``; return the estimate."""
    path = scene.path if scene.path is not None else scene.name
    try:
        est = estimate(scene)
    except (ValueError, ArithmeticError) as e:
        raise SceneError(path, "run", f"its cost cannot be estimated: {type(e).__name__}: {e}") from None
    if est.steps > max_steps:
        raise SceneError(path, "run", f"asks for about {est.steps:.3g} integration steps, above the cap "
                         f"of {max_steps:.3g} (raise it with --max-steps)")
    if est.trajectory_bytes > max_bytes:
        raise SceneError(path, "run", f"needs {_gib(est.trajectory_bytes)} per trajectory (8 B x "
                         f"{est.state_size} states x {est.output_points:.3g} output points), above the cap "
                         f"of {_gib(max_bytes)}; decimate with [run] max_output_points or "
                         f"--max-output-points")
    return est
