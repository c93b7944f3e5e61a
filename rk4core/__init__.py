"""rk4core: the system under test -- the thesis' fixed-step classical RK4 (with
explicit and semi-implicit Euler as contrasts), further explicit Runge-Kutta
methods as data (``methods``: tableaux with computed order, cost and
stability, ``order_conditions``, ``stability_function``; splitting and
composition methods converted to tableaux, ``geometric``) and the seed's
models."""
from . import order_conditions, stability_function
from .methods import (EULER, HEUN3, METHODS, RALSTON, RK4, RK38, STORMER_VERLET, SYMPLECTIC_EULER, Tableau,
                      get_method, make_tableau, rk_step)
from .geometric import GEOMETRIC as _GEOMETRIC
from .models import MODELS, Defined, Drawing, Model, Network, PotentialModel, make_model, register_model
from .solver import FixedStepResult, nfev_count, solve, step_count

METHODS.update(_GEOMETRIC)  # splitting and composition methods, as tableaux (rk4h.geometric)

__all__ = ["solve", "FixedStepResult", "step_count", "nfev_count", "Tableau", "make_tableau", "RK4", "RK38",
           "HEUN3", "RALSTON", "EULER", "SYMPLECTIC_EULER", "STORMER_VERLET", "METHODS", "get_method", "rk_step",
           "order_conditions", "stability_function", "MODELS", "Model", "Defined", "Drawing", "Network",
           "PotentialModel", "make_model", "register_model"]


def __getattr__(name):
    # rk4h.ivp (scipy's OdeSolver classes) is imported on first use: it loads scipy.integrate
    if name == "ivp":
        import importlib
        return importlib.import_module(".ivp", __name__)
    # rk4h.ensemble (rk4h.batch) is imported on first use; numba and jax only when a batch runs
    if name in ("ensemble", "EnsembleResult"):
        from . import batch
        return getattr(batch, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
