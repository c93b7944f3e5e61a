"""What scene loading (:mod:`rk4h.validation.scenes`) and sweep expansion
(:mod:`rk4h.validation.sweeps`) share: the error they raise and the small checks
both make. Kept apart so that neither of the two imports the other's caller.
"""
from __future__ import annotations

import re
from numbers import Real

__all__ = ["SceneError", "show", "Raw", "is_num", "unknown_keys", "check_model", "model_keys", "figure_stem"]


class SceneError(ValueError):
    """A malformed scene: one line naming the file, the field and the value."""

    def __init__(self, path, fld: str, problem: str, value=None):
        problem = " ".join(str(problem).split("\n"))  # one line, whatever the source said
        self.path, self.field, self.problem, self.value = str(path), fld, problem, value
        got = "" if value is None else f" (got {show(value)})"
        super().__init__(f"{self.path}: field `{fld}`: {problem}{got}")


def show(value) -> str:
    """``repr(value)``, cut to 80 characters (a value quoted in an error line)."""
    try:
        text = repr(value)
    except Exception:  # noqa: BLE001 - e.g. an int too long to print
        text = f"<{type(value).__name__}>"
    return text if len(text) <= 80 else text[:77] + "..."


class Raw(str):
    """A string that is its own ``repr`` (an already shown value in an error)."""

    def __repr__(self):
        return str(self)


def is_num(x) -> bool:
    """A real number that is not a bool."""
    return isinstance(x, Real) and not isinstance(x, bool)


def unknown_keys(path, fld, table: dict, known) -> None:
    """Refuse the first key of ``table`` outside ``known`` (a user model's
    parameters; the top level of a swept document)."""
    unknown = sorted((k for k in table if k not in known), key=str)
    if unknown:
        where = f"{fld}.{unknown[0]}" if fld else str(unknown[0])
        raise SceneError(path, where, f"unknown key (known: {', '.join(sorted(known))})")


def check_model(path, model_name) -> None:
    """Refuse a ``model`` that is neither a built-in nor ``package.module:Class``."""
    from rk4h import MODELS
    from rk4h.models import resolve_model

    try:
        resolve_model(model_name)
    except ValueError:
        raise SceneError(path, "model", f"must be one of {', '.join(sorted(MODELS))} or "
                         f"'package.module:ClassName'", model_name) from None


def model_keys(model_name) -> set:
    """The parameter names (required and optional) of model ``model_name``."""
    from rk4h.models import model_parameters

    required, optional = model_parameters(model_name)
    return set(required) | set(optional)


def figure_stem(name: str) -> str:
    """The stem ``rk4h.validation.figures.slug`` makes of a scene name (figure files
    start with it); repeated here to keep matplotlib out of scene loading."""
    return re.sub(r"[^a-z0-9]+", "_", name.lower()).strip("_")
