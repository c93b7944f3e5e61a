"""The one interface every solver is called through.

``integrate(solver, model, y0, t_eval, setting)`` returns a :class:`SolverRun`:
the trajectory at ``t_eval`` plus cost counters and an outcome. A solver that
fails never raises: it returns ``status`` FAILED or UNSTABLE with its message,
and ``y`` is NaN from the first output time it did not reach.

``setting`` is the step ``h`` (s) for fixed-step solvers and the relative
tolerance for adaptive ones (see ``rk4h.references.solvers`` for the absolute
tolerance rule).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from enum import Enum

import numpy as np

from ..registry import BUILTIN, REFERENCES

__all__ = ["Status", "SolverRun", "FIXED_STEP", "ADAPTIVE", "SOLVER_NAMES", "compiled_rhs"]


class Status(str, Enum):
    """Outcome of one run."""

    OK = "ok"
    FAILED = "failed"      # the solver gave up (error flag, step cap, exception inside)
    UNSTABLE = "unstable"  # the state became non-finite (a blow-up)
    UNAVAILABLE = "unavailable"  # an external program (a command method) is not installed


#: Built-in fixed-step methods and adaptive references, from the registry
#: (a scene's own methods are resolved with ``rk4h.references.registry.resolve``).
FIXED_STEP = tuple(n for n, m in BUILTIN.items() if m.fixed_step)
ADAPTIVE = REFERENCES
SOLVER_NAMES = FIXED_STEP + ADAPTIVE


@dataclass
class SolverRun:
    """One integration of one model by one solver at one setting.

    Attributes
    ----------
    solver : str
    setting : float
        ``h`` (s) for fixed-step solvers, ``rtol`` for adaptive ones.
    t : ndarray, shape (m,)
        The requested output times.
    y : ndarray, shape (2 n_dof, m)
        States at ``t``; NaN where the run did not get.
    nfev : int
        Right-hand-side evaluations (heyoka: 0, see ``taylor_order``).
    n_steps : int
        Steps taken.
    wall_s : float
        Integration wall time (s), compilation excluded.
    compile_s : float
        One-off compilation/setup time (s) (heyoka JIT, numba), 0 if none.
    status : Status
    message : str
    atol : float or None
        Absolute tolerance of the position components (adaptive solvers; the
        whole per-component vector is ``extra["atol_state"]``).
    taylor_order : int or None
        heyoka's Taylor order.
    t_fail : float or None
        Time of failure or blow-up.
    """

    solver: str
    setting: float
    t: np.ndarray
    y: np.ndarray
    nfev: int
    n_steps: int
    wall_s: float
    compile_s: float = 0.0
    status: Status = Status.OK
    message: str = ""
    atol: float | None = None
    taylor_order: int | None = None
    t_fail: float | None = None
    extra: dict = field(default_factory=dict)

    @property
    def ok(self) -> bool:
        return self.status is Status.OK


def compiled_rhs(model):
    """The model's right-hand side compiled from its definition
    (:class:`rk4h.fast.CompiledRHS`), built once per model object and
    kept on it, or None for a model without a compiled form (a subclass with
    a hand-written force: the solvers then call ``model.rhs``). Built before
    a solver's clock starts: compilation is never timed."""
    cached = model.__dict__.get("_references_rhs", False)
    if cached is False:
        from rk4h import fast

        cached = fast.compiled_rhs(model)
        model.__dict__["_references_rhs"] = cached
    return cached
