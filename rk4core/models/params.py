"""A model's parameters, declared once on the model class.

Each :class:`~rk4h.models.Model` subclass lists its constructor's keyword
arguments as :class:`Param` rows in the class attribute ``parameters`` (with
``summary``, one line on what the model is). That one declaration is what
the scene file's ``[params]`` table is generated from (type, unit, default,
example, description; :mod:`rk4h.validation.scene_schema`), what
:func:`rk4h.models.model_parameters` reports and what the scene reference
prints. A rule that spans several parameters (a chain's spring count follows
its mass count and walls) is the class method ``check_parameters``, raising
:class:`ParamRule`.

A model without a declaration (a user's class that only has a constructor) is
read from its constructor's signature (:func:`declared`): every argument of
kind ``"any"``, required when it has no default.

Kinds (``Param.kind``), all in SI units of the row's ``unit``:

``"normal"``
    a float >= :data:`~rk4h.models.base.MASS_MIN` (1e-300), finite: a mass,
    stiffness or length;
``"finite"``
    any finite float;
``"bool"``, ``"int"`` (bounds ``ge``/``le``), ``"str"``;
``"choice"``
    one of the strings ``choices``;
``"normal|list"``
    one normal number for all, or a non-empty list of them;
``"list[normal]"``, ``"list[finite]"``, ``"list[str]"``
    lists (lengths ``min_length``/``max_length``);
``"list[list[float]]"``
    rows of floats, each of ``item_length = (lo, hi)`` entries;
``"dict[str,finite]"``
    named finite numbers;
``"any"``
    anything (a constructor argument with no declaration).

This module is plain Python (no pydantic): :mod:`rk4core` stays free of the
harness' scene layer, which turns the rows into its schema.
"""
from __future__ import annotations

import inspect
from dataclasses import dataclass
from typing import Any

__all__ = ["Param", "ParamRule", "REQUIRED", "KINDS", "declared", "is_declared"]


class _Required:
    def __repr__(self):
        return "REQUIRED"


#: The ``default`` of a parameter a caller must give.
REQUIRED: Any = _Required()

KINDS = ("normal", "finite", "bool", "int", "str", "choice", "normal|list", "list[normal]", "list[finite]",
         "list[str]", "list[list[float]]", "dict[str,finite]", "any")


@dataclass(frozen=True)
class Param:
    """One constructor argument of a model.

    Attributes
    ----------
    name : str
        The keyword argument, and the key in a scene's ``[params]``.
    kind : str
        One of :data:`KINDS` (the module docstring says what each accepts).
    unit : str
        SI unit of the value (``"kg"``, ``"N/m"``; ``"-"`` for none).
    description : str
        One line: what the value means.
    example : object
        A valid value, shown in the scene reference.
    default : object
        The value when omitted, or :data:`REQUIRED`.
    default_text : str or None
        Words for the reference when the default is computed (``"length"``).
    choices : tuple of str
        The values of a ``"choice"``.
    ge, le : float or None
        Inclusive bounds of an ``"int"``.
    min_length, max_length : int or None
        Lengths of a list kind.
    item_length : (int, int) or None
        Entries of each row of a ``"list[list[float]]"``.
    """

    name: str
    kind: str
    unit: str
    description: str
    example: Any
    default: Any = REQUIRED
    default_text: str | None = None
    choices: tuple = ()
    ge: float | None = None
    le: float | None = None
    min_length: int | None = None
    max_length: int | None = None
    item_length: tuple | None = None

    def __post_init__(self):
        if self.kind not in KINDS:
            raise ValueError(f"`kind` of parameter {self.name!r} must be one of {', '.join(KINDS)}, "
                             f"got {self.kind!r}")
        if (self.kind == "choice") != bool(self.choices):
            raise ValueError(f"`choices` of parameter {self.name!r} go with kind 'choice' (and only it)")

    @property
    def required(self) -> bool:
        """True when a caller must give it."""
        return self.default is REQUIRED


class ParamRule(ValueError):
    """A broken rule between parameters, raised by a model's
    ``check_parameters``: ``at`` is the parameter blamed, ``problem`` the
    words after its name, ``value`` the value shown (None: none shown)."""

    def __init__(self, at: str, problem: str, value: Any = None):
        self.at, self.problem, self.value = at, problem, value
        super().__init__(f"`{at}` {problem}" + ("" if value is None else f", got {value!r}"))


def is_declared(cls) -> bool:
    """True when model class ``cls`` has a declaration of its ``parameters``
    that describes its constructor: written on the class itself, or inherited
    together with the constructor it describes (a subclass that writes its
    own ``__init__`` and no ``parameters`` is read from its signature)."""
    for klass in cls.__mro__:
        if klass.__dict__.get("parameters") is not None:
            return cls.__init__ is klass.__init__ or "parameters" in cls.__dict__
    return False


def declared(cls) -> tuple[Param, ...]:
    """The parameters of model class ``cls``: its declaration, else its
    constructor's keyword arguments (kind ``"any"``, unit ``"-"``, required
    when they have no default), in the constructor's order."""
    if is_declared(cls):
        return tuple(cls.parameters)
    sig = inspect.signature(cls.__init__)
    out = []
    for p in sig.parameters.values():
        if p.name == "self" or p.kind in (p.VAR_POSITIONAL, p.VAR_KEYWORD):
            continue
        default = REQUIRED if p.default is inspect.Parameter.empty else p.default
        out.append(Param(p.name, "any", "-", "an argument of the model's constructor", None, default=default))
    return tuple(out)
