"""Ensembles: one model integrated from many initial states (and parameter
sets) as one batch -- :func:`ensemble`, on every core (numba) or through jax
(CPU or GPU). Neither numba nor jax is imported until a batch runs."""
from .api import EnsembleResult, ensemble, instance_parameters

__all__ = ["ensemble", "EnsembleResult", "instance_parameters"]
