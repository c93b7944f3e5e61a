"""The seed's mass-spring models, one class each, and a registry by scene key."""
from __future__ import annotations

import inspect
from collections.abc import Mapping

from .base import HEYOKA, NUMPY, Model
from .chain import Chain
from .oscillator2d import Oscillator2D
from .pendulums import Pendulums
from .planar4 import Planar4
from .triangle import Triangle

MODELS: dict[str, type[Model]] = {c.name: c for c in (Chain, Planar4, Oscillator2D, Pendulums, Triangle)}

__all__ = ["Model", "Chain", "Planar4", "Oscillator2D", "Pendulums", "Triangle",
           "MODELS", "make_model", "model_parameters", "NUMPY", "HEYOKA"]


def model_parameters(name: str) -> tuple[list[str], list[str]]:
    """(required, optional) parameter names of model ``name``."""
    sig = inspect.signature(MODELS[name].__init__)
    ps = [p for p in sig.parameters.values() if p.name != "self"]
    return ([p.name for p in ps if p.default is inspect.Parameter.empty],
            [p.name for p in ps if p.default is not inspect.Parameter.empty])


def make_model(name: str, params: dict) -> Model:
    """Build model ``name`` from a parameter dict; unknown or missing keys and
    bad values raise ``ValueError`` naming the parameter."""
    if not isinstance(name, str) or name not in MODELS:
        raise ValueError(f"`model` must be one of {sorted(MODELS)}, got {name!r}")
    if not isinstance(params, Mapping):
        raise ValueError(f"`params` must be a mapping of parameter names to values, got {params!r}")
    required, optional = model_parameters(name)
    unknown = sorted(set(params) - set(required) - set(optional))
    if unknown:
        raise ValueError(f"unknown parameter `{unknown[0]}` for model {name!r} "
                         f"(known: {', '.join(required + optional)})")
    missing = [p for p in required if p not in params]
    if missing:
        raise ValueError(f"missing parameter `{missing[0]}` for model {name!r}")
    return MODELS[name](**params)
