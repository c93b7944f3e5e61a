"""The seed's mass-spring models, one class each, a spring network
(``network``), a model whose potential is typed in the scene
(``potential``), and a registry by scene key.

A model of your own is one Python file: subclass :class:`Defined` and build
its definition -- a :class:`PotentialModel` (the potential as text or
:mod:`rk4h.expr` expressions) or a :class:`Network` -- in the constructor
(``self._adopt(lambda: PotentialModel(...), "param")``), so that the force,
the Hessian, the compiled kernels and heyoka's equations are derived from it;
or subclass :class:`Model` and write ``_potential``/``_force`` by hand (the
numpy path, no compiled kernel). Give it a unique ``name``, and either call
:func:`register_model` on the class or name it in a scene as ``model =
"package.module:ClassName"`` (the module must be importable, e.g. on
``PYTHONPATH``; it is imported, so it must be your own code). Its
constructor's keyword arguments are the scene's ``[params]``: declare them
once as ``parameters`` (:class:`~rk4h.models.params.Param` rows: kind,
unit, default, description) and the scene schema, its checks and the scene
reference are generated from them; without a declaration they are read from
the constructor's signature.

A new built-in model is one file (the class, with its ``parameters``) plus
its class in :data:`BUILTIN_CLASSES`.
"""
from __future__ import annotations

import importlib
import re
from collections.abc import Mapping

from .base import HEYOKA, NUMPY, Defined, Drawing, Model
from .chain import Chain
from .oscillator2d import Oscillator2D
from .pendulums import Pendulums
from .network import Network
from .ode import FunctionOde, OdeModel
from .planar4 import Planar4
from .params import REQUIRED, Param, ParamRule, declared, is_declared
from .potential import PotentialModel
from .triangle import Triangle

#: The built-in models, in the order the scene reference lists them: the
#: registry's one line per model.
BUILTIN_CLASSES: tuple[type[Model], ...] = (Chain, Planar4, Oscillator2D, Pendulums, Triangle, Network,
                                             PotentialModel, OdeModel)
MODELS: dict[str, type[Model]] = {c.name: c for c in BUILTIN_CLASSES}

__all__ = ["Model", "Defined", "Drawing", "Chain", "Planar4", "Oscillator2D", "Pendulums", "Triangle", "Network",
           "PotentialModel", "OdeModel", "FunctionOde", "MODELS", "BUILTIN_CLASSES", "Param", "ParamRule", "REQUIRED", "declared", "make_model",
           "example_parameters", "model_parameters", "register_model", "resolve_model", "NUMPY", "HEYOKA"]

_NAME = re.compile(r"[a-z][a-z0-9_-]*")
_IMPORT = re.compile(r"[A-Za-z_][A-Za-z0-9_]*(\.[A-Za-z_][A-Za-z0-9_]*)*:[A-Za-z_][A-Za-z0-9_]*")


def register_model(cls: type[Model], *, replace: bool = False) -> type[Model]:
    """Add the :class:`Model` subclass ``cls`` to :data:`MODELS` under
    ``cls.name`` (lowercase letters, digits, ``-``, ``_``); returns ``cls``,
    so it can decorate the class. A name already taken by another class is
    refused unless ``replace``. Raises ``ValueError`` naming the problem."""
    if not (isinstance(cls, type) and issubclass(cls, Model)) or cls is Model:
        raise ValueError(f"`cls` must be a subclass of rk4h.models.Model, got {cls!r}")
    name = getattr(cls, "name", None)
    if not isinstance(name, str) or not _NAME.fullmatch(name) or name == Model.name:
        raise ValueError(f"`{getattr(cls, '__name__', cls)}.name` must be a lowercase name of its own "
                         f"([a-z][a-z0-9_-]*), got {name!r}")
    if MODELS.get(name, cls) is not cls and not replace:
        raise ValueError(f"model name {name!r} is taken by {MODELS[name].__module__}.{MODELS[name].__qualname__}")
    MODELS[name] = cls
    return cls


def resolve_model(name: str) -> str:
    """The registry key of ``name``: a key of :data:`MODELS` as it is, or
    ``"package.module:ClassName"``, imported and registered (see the module
    docstring). Raises ``ValueError`` naming ``model``."""
    if not isinstance(name, str):
        raise ValueError(f"`model` must be a model name or 'package.module:ClassName', got {name!r}")
    if name in MODELS:
        return name
    if not _IMPORT.fullmatch(name):
        raise ValueError(f"`model` must be one of {sorted(MODELS)} or 'package.module:ClassName', got {name!r}")
    module_name, cls_name = name.split(":")
    try:
        module = importlib.import_module(module_name)
    except ImportError as e:
        raise ValueError(f"`model` {name!r}: cannot import {module_name!r} ({e})") from None
    cls = getattr(module, cls_name, None)
    if cls is None:
        raise ValueError(f"`model` {name!r}: module {module_name!r} has no {cls_name!r}")
    return register_model(cls).name


def model_parameters(name: str) -> tuple[list[str], list[str]]:
    """(required, optional) parameter names of model ``name``: its declared
    ``parameters``, else its constructor's arguments
    (:func:`rk4h.models.params.declared`)."""
    ps = declared(MODELS[resolve_model(name)])
    return [p.name for p in ps if p.required], [p.name for p in ps if not p.required]


def example_parameters(name: str) -> dict:
    """``{parameter: example}`` of model ``name``'s declared ``parameters``:
    a valid ``[params]`` table (tests build every registered model from it).
    Raises ``ValueError`` naming ``model`` for a model without a declaration."""
    cls = MODELS[resolve_model(name)]
    if not is_declared(cls):
        raise ValueError(f"`model` {name!r} declares no parameters, so has no examples")
    return {p.name: p.example for p in declared(cls)}


def make_model(name: str, params: dict) -> Model:
    """Build model ``name`` from a parameter dict; unknown or missing keys and
    bad values raise ``ValueError`` naming the parameter."""
    name = resolve_model(name)
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
