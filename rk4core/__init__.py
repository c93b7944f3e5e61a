"""rk4core: the system under test -- the thesis' fixed-step classical RK4 (with
explicit and semi-implicit Euler as contrasts) and the seed's models."""
from .methods import EULER, METHODS, RK4, SYMPLECTIC_EULER, Tableau, get_method, rk_step
from .models import MODELS, Defined, Drawing, Model, Network, PotentialModel, make_model, register_model
from .solver import FixedStepResult, solve, step_count

__all__ = ["solve", "FixedStepResult", "step_count", "Tableau", "RK4", "EULER", "SYMPLECTIC_EULER",
           "METHODS", "get_method", "rk_step", "MODELS", "Model", "Defined", "Drawing", "Network", "PotentialModel",
           "make_model", "register_model"]
