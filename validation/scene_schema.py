"""The scene file's schema, declared once (pydantic v2, strict, ``extra="forbid"``).

Every key a scene file may hold, its type, bounds, default, unit, example and
meaning is declared here, and nowhere else -- but a model's ``[params]``,
which are generated from the model's own declaration (its ``parameters``,
:mod:`rk4h.models.params`): :mod:`rk4h.validation.scenes` validates
a document's structure with :data:`SCENE` and keeps only the checks a schema
cannot express (the model's degrees of freedom, ``h`` dividing
``output_dt``, the solvers a scene's own methods add, sweeps). The reference
and the JSON Schema are generated from these models::

    python -m rk4h.validation.scene_schema --markdown > docs/scene-reference.md
    python -m rk4h.validation.scene_schema --json-schema > docs/scene.schema.json

(``python -m rk4h.validation.docs_gen`` writes both, with the other generated documents.)

The top level is a union on ``model``: one variant per built-in model
(``rk4h.models.BUILTIN_CLASSES``), whose ``[params]`` table is generated
from the model's declaration (:func:`params_table`), and one for a user's
model (``"package.module:Class"``), whose ``[params]`` are checked by the
table generated the same way from its class once :mod:`rk4h.validation.scenes`
has resolved it (:func:`params_error`).
A callable discriminator picks the variant (a string naming a built-in model
selects it, anything else the user variant), so only one variant is
validated and its errors name the document's own fields. ``[stability]`` is
declared from :data:`rk4h.validation.stability.params.PARAMS` and validated by its
``validate_params`` (the bounds table stays the rule there).
"""
from __future__ import annotations

import functools
import json
import sys
from collections.abc import Mapping
from typing import Annotated, Any, Literal, Union, get_args, get_origin

from pydantic import (AfterValidator, BaseModel, ConfigDict, Discriminator, Field, Tag, TypeAdapter, ValidationError,
                      WrapValidator, create_model, model_validator)
from pydantic_core import PydanticCustomError, PydanticUndefined, core_schema

from rk4h.references.registry import _METHOD_NAME, BUILTIN
from rk4h.models import BUILTIN_CLASSES, Param, ParamRule, declared
from rk4h.models.base import MASS_MIN
from rk4h.models.params import is_declared
from rk4h.validation import outputs as _outputs
from rk4h.validation.plan import EULER_THETAS, RK4_THETAS
from rk4h.validation.stability.params import MAX_LIST, PARAMS, STUDIES, StabilityParamError, validate_params

__all__ = ["SCENE", "SCENE_MODELS", "BUILTIN_MODELS", "params_table", "params_error", "OUTPUTS", "OUTPUT_HELP",
           "TOP_KEYS", "INITIAL_KEYS", "NAME_PATTERN", "NAME_MAX", "IDENT", "WORD", "first_error", "json_schema", "reference_markdown",
           "validate", "validation_error"]

#: What a scene may ask for in ``run.outputs``: the output registry's names
#: (:mod:`rk4h.validation.outputs`) when this module was imported; the schema
#: itself reads the registry at validation time (:class:`_OutputName`).
OUTPUTS = _outputs.names()
#: output -> (when it applies, so is in the default ``run.outputs``; what it adds to the report),
#: from the registry. The rule is :func:`rk4h.validation.scenes.default_outputs`.
OUTPUT_HELP = _outputs.help_rows()
NAME_PATTERN = "^[a-z0-9][a-z0-9_-]*$"
NAME_MAX = 100
#: A name in a ``[sweep]`` path.
IDENT = r"[A-Za-z_][A-Za-z0-9_]*"
#: A string value of a ``[sweep]`` list (it appears in the point's name).
WORD = r"[a-z0-9][a-z0-9_.-]{0,39}"
_SWEEP_PATH = rf"^{IDENT}(\.{IDENT}|\[(0|[1-9][0-9]*)\])+$"
_TARGET = r"^[A-Za-z_][A-Za-z0-9_]*(\.[A-Za-z_][A-Za-z0-9_]*)*:[A-Za-z_][A-Za-z0-9_]*$"
_STRICT = ConfigDict(strict=True, extra="forbid")


def _f(description: str, unit: str = "-", example: Any = None, **kw):
    """A documented field: ``unit`` and ``example`` go to the reference and the JSON Schema."""
    extra = {"unit": unit, "example": example, **kw.pop("schema", {})}
    if "default_text" in kw:
        extra["default_text"] = kw.pop("default_text")
    return Field(description=description, json_schema_extra=extra, **kw)


def _rule(problem: str, at: str = "", **value) -> PydanticCustomError:
    """A broken rule of a table, raised from its validator: ``problem`` at the
    table's field plus ``at`` (``".amplitude"``); ``value=...`` is shown."""
    return PydanticCustomError("scene_rule", "{problem}", {"problem": problem, "at": at, **value})


def _distinct(items: list) -> list:
    if len(set(items)) != len(items):
        raise _rule("lists a name twice", value=items)
    return items


def _open_unit(x: float) -> float:
    if not 0.0 < x < 1.0:
        raise _rule("must lie in (0, 1)", value=x)
    return x


Finite = Annotated[float, Field(allow_inf_nan=False)]
Positive = Annotated[float, Field(gt=0, allow_inf_nan=False)]
#: A mass, stiffness or length: a normal positive float (rk4h.models.base.MASS_MIN).
Normal = Annotated[float, Field(ge=MASS_MIN, allow_inf_nan=False)]
#: In (0, 1), refused in one message (the bounds are written for the JSON Schema only).
OpenUnit = Annotated[float, Field(allow_inf_nan=False, json_schema_extra={"exclusiveMinimum": 0,
                                                                          "exclusiveMaximum": 1}),
                     AfterValidator(_open_unit)]
Names = Annotated[list[str], Field(min_length=1), AfterValidator(_distinct)]


def _output_name(name: str) -> str:
    known = _outputs.names()
    if name not in known:
        expected = ", ".join(f"'{o}'" for o in known[:-1]) + f" or '{known[-1]}'"
        raise _rule(f"must be {expected}", value=name)
    return name


class _OutputName(str):
    """A name of :data:`rk4h.validation.outputs.OUTPUTS`, read when a scene is
    validated (an output registered after import is accepted); its JSON
    Schema is the registry's names."""

    @classmethod
    def __get_pydantic_core_schema__(cls, source, handler):
        return core_schema.no_info_after_validator_function(_output_name, core_schema.str_schema(strict=True))

    @classmethod
    def __get_pydantic_json_schema__(cls, schema, handler):
        return {"type": "string", "enum": list(_outputs.names())}


Output = _OutputName


def _shape(v) -> str:
    return "each" if isinstance(v, list) else "one"


#: One number for all, or one per item (``masses = 1.0`` with ``n``, or ``masses = [...]``).
NormalOrList = Annotated[Union[Annotated[Normal, Tag("one")],
                               Annotated[list[Normal], Field(min_length=1), Tag("each")]], Discriminator(_shape)]
#: A tableau coefficient: a number or an exact rational such as ``"1/3"``.
Coefficient = Annotated[Union[Annotated[float, Tag("number")], Annotated[str, Tag("text")]],
                        Discriminator(lambda v: "text" if isinstance(v, str) else "number")]
_TAGS = frozenset({"one", "each", "number", "text"})


class _Table(BaseModel):
    model_config = _STRICT


# -- [params], one table per model, generated from its declaration ---------------------------
def _param_type(p: Param):
    """The pydantic type of declared parameter ``p`` (:data:`rk4h.models.params.KINDS`)."""
    lengths = {k: v for k, v in (("min_length", p.min_length), ("max_length", p.max_length)) if v is not None}
    if p.kind == "int":
        bounds = {k: v for k, v in (("ge", p.ge), ("le", p.le)) if v is not None}
        return Annotated[int, Field(**bounds)] if bounds else int
    if p.kind == "choice":
        return Literal[p.choices]  # type: ignore[valid-type]
    if p.kind == "list[list[float]]":
        lo, hi = p.item_length or (None, None)
        row = Annotated[list[float], Field(**{k: v for k, v in (("min_length", lo), ("max_length", hi))
                                              if v is not None})]
        return Annotated[list[row], Field(**lengths)] if lengths else list[row]
    base = {"normal": Normal, "finite": Finite, "bool": bool, "str": str, "normal|list": NormalOrList,
            "list[normal]": list[Normal], "list[finite]": list[Finite], "list[str]": list[str],
            "dict[str,finite]": dict[str, Finite], "any": Any}[p.kind]
    return Annotated[base, Field(**lengths)] if lengths else base


def _param_field(p: Param):
    """``(type, Field)`` of declared parameter ``p``."""
    kw = {} if p.required else {"default": p.default}
    if p.default_text is not None:
        kw["default_text"] = p.default_text
    return _param_type(p), _f(p.description, p.unit, p.example, **kw)


def _check_rules(model_cls):
    """The table's ``after`` validator: ``model_cls.check_parameters`` (rules
    between parameters), its :class:`ParamRule` reported at the parameter."""
    def check(self):
        if not is_declared(model_cls):  # the rules go with the declaration they are written for
            return self
        try:
            model_cls.check_parameters({name: getattr(self, name) for name in type(self).model_fields})
        except ParamRule as e:
            shown = {} if e.value is None else {"value": e.value}
            raise _rule(e.problem, at=f".{e.at}", **shown) from None
        return self
    return check


def params_table(model_cls) -> type[BaseModel]:
    """The ``[params]`` table of model class ``model_cls``, generated from its
    declared ``parameters`` (:func:`rk4h.models.params.declared`: its
    constructor's arguments, of any type, when it declares none), with its
    ``check_parameters`` rules. Cached on the class."""
    cached = model_cls.__dict__.get("_params_table")
    if cached is not None:
        return cached
    name = model_cls.__name__.removesuffix("Model") or model_cls.__name__
    fields = {p.name: _param_field(p) for p in declared(model_cls)}
    table = create_model(f"{name}Params", __base__=_Table, __doc__=model_cls.summary or model_cls.__doc__,
                         __validators__={"_rules": model_validator(mode="after")(_check_rules(model_cls))}, **fields)
    model_cls._params_table = table
    return table


class _Built(Mapping):
    """A read-only mapping of fixed keys whose values are built on first
    access and kept: a process builds the pydantic models of the scenes it
    validates, not those of every model (each costs milliseconds of schema
    generation). Iterating over ``values()`` or ``items()`` builds them all."""

    def __init__(self, keys, build):
        self._keys = tuple(dict.fromkeys(keys))
        self._build = build
        self._built = {}

    def __getitem__(self, key):
        try:
            return self._built[key]
        except (KeyError, TypeError):
            if not isinstance(key, str) or key not in self._keys:
                raise KeyError(key) from None
        value = self._built[key] = self._build(key)
        return value

    def __iter__(self):
        return iter(self._keys)

    def __len__(self):
        return len(self._keys)

    def __contains__(self, key):
        return isinstance(key, str) and key in self._keys

    def __repr__(self):
        return f"<{len(self._keys)} scene tables, built on first use: {', '.join(self._keys)}>"


_BUILTIN_CLASS = {cls.name: cls for cls in BUILTIN_CLASSES}
#: Built-in model name -> its ``[params]`` table, generated from rk4core's model registry
#: (each table is generated when first asked for).
BUILTIN_MODELS: Mapping[str, type[BaseModel]] = _Built(_BUILTIN_CLASS, lambda name: params_table(_BUILTIN_CLASS[name]))


# -- the other tables ----------------------------------------------------------------
class Initial(_Table):
    """The state at t = 0: `x` (and `v`), or a normal mode."""

    x: list[Finite] = _f("generalized coordinates at t = 0, one per degree of freedom, flat; give `x` or `mode`",
                         "m or rad", [0.005, 0.005], default=None, min_length=1)
    v: list[Finite] = _f("their time derivatives at t = 0", "m/s or rad/s", [0.0, 0.0], default=None,
                         min_length=1, default_text="zeros")
    mode: int = _f("start in this normal mode instead (1-based, ascending frequency): x = amplitude phi[:, mode-1], "
                   "the mass-normalised mode shape with its first non-zero entry > 0 (thesis Code 02)", "-", 2,
                   default=None, ge=1)
    amplitude: Finite = _f("scale of the mode shape (only with `mode`)", "m kg^(1/2)", 0.001, default=1.0)
    y: list[Finite] = _f("the state at t = 0 of a first-order ODE (model `ode`), one number per variable; "
                         "instead of `x` and `v`", "state units", [1.0, 0.0], default=None, min_length=1)

    @model_validator(mode="after")
    def _one_start(self):
        if self.y is not None:
            if self.x is not None or self.mode is not None or self.v is not None:
                raise _rule("give `y` alone (the state of a first-order ODE), not with `x`, `v` or `mode`")
            return self
        if (self.x is None) == (self.mode is None):
            raise _rule("give exactly one of `x` and `mode` (or `y` for model `ode`)")
        if self.x is not None and "amplitude" in self.model_fields_set:
            raise _rule("only goes with `mode`", at=".amplitude")
        return self


class Run(_Table):
    """What to integrate, with which methods and settings, and what to measure."""

    t_end: Positive = _f("end of the integration, from t = 0; output_dt must divide it", "s", 10.0)
    h: list[Positive] = _f("steps of the fixed-step methods; each at most t_end and dividing output_dt; required "
                           "when run.solvers lists a fixed-step method", "s", [0.1, 0.05], default=None,
                           min_length=1)
    tolerances: list[OpenUnit] = _f("relative tolerances (rtol) of the adaptive solvers, in (0, 1); required when "
                                    "run.solvers lists one", "1", [1e-6, 1e-9], default=None, min_length=1)
    solvers: Names = _f(f"methods to run: the built-ins ({', '.join(BUILTIN)}) and the scene's own "
                        f"[methods.NAME]", "-", ["rk4", "dop853"])
    outputs: Annotated[list[Output], Field(min_length=1), AfterValidator(_distinct)] = _f(
        "what to measure and report (the table of outputs below)", "-", ["state", "energy"], default=None,
        default_text="every output that applies to the model")
    output_dt: Positive = _f("spacing of the output grid the errors are measured on; must divide t_end", "s", 0.1,
                             default=None, default_text="the largest h; t_end/1000 without h")
    max_output_points: int = _f("keep at most this many output points (every k-th point, t_end kept)", "points",
                                1000, default=None, ge=2, default_text="all")


class Convergence(_Table):
    """The convergence sweep: the observed order of every fixed-step method."""

    t_end: Positive = _f("length of each sweep run (at most run.t_end)", "s", 0.5, default=None,
                         default_text="one period of the fastest mode")
    theta: list[Positive] = _f("omega_max h of the sweep of methods of order >= 3, halving for nested grids", "rad",
                               [0.4, 0.2, 0.1, 0.05], default=list(RK4_THETAS), min_length=3)
    theta_euler: list[Positive] = _f("the same for methods of order 1-2", "rad", [0.02, 0.01, 0.005],
                                     default=list(EULER_THETAS), min_length=3)


class MethodTable(_Table):
    """A scene's own method: a Butcher tableau, a Python stepper or an external command."""

    A: list[list[Coefficient]] = _f("Butcher matrix of an explicit tableau (zero on and above the diagonal, "
                                    "except in a partitioned pair)", "-", [["0", "0"], ["2/3", "0"]], default=None)
    kind: Literal["tableau", "splitting", "composition"] = _f(
        "how the method is written: a Butcher tableau (A, b), a drift-kick splitting (a, b) or a composition "
        "of a base method (base, gamma); the last two become a partitioned tableau (docs/geometric.md)", "-",
        "splitting", default=None, default_text="tableau (or python / command)")
    b: list[Coefficient] = _f("weights of the tableau; with kind = splitting, the kick fractions b_i (end with 0 "
                              "after a last drift)", "-", ["1/4", "3/4"], default=None)
    a: list[Coefficient] = _f("drift fractions of a splitting (kind = splitting): drift a_i h, then kick b_i h, "
                              "for i = 1..s; numbers, decimals or expressions such as '1/(2 - 2^(1/3))'", "-",
                              ["1/2", "1/2"], default=None)
    base: str = _f("base method of a composition (kind = composition): a tableau of rk4core's library", "-",
                   "stormer-verlet", default=None)
    gamma: list[Coefficient] = _f("step fractions of a composition, in the order the sub-steps are taken; they "
                                  "sum to 1", "-", ["1/(2 - 2^(1/3))", "-2^(1/3)/(2 - 2^(1/3))",
                                                     "1/(2 - 2^(1/3))"], default=None)
    c: list[Coefficient] = _f("nodes of the tableau", "-", ["0", "2/3"], default=None,
                              default_text="the row sums of A")
    A_v: list[list[Coefficient]] = _f("velocity-half matrix of a partitioned tableau (A, b act on the positions); "
                                      "with b_v", "-", [["0", "0"], ["1", "0"]], default=None)
    b_v: list[Coefficient] = _f("velocity-half weights of a partitioned tableau; with A_v", "-", ["1", "0"],
                                default=None)
    description: str = _f("label in tables and figures", "-", "Ralston's second-order method", default="")
    python: str = _f("a step function f(fun, t, y, h) -> y_next, as 'package.module:function'", "-",
                     "rk4h.steppers:rk4_step", default=None, pattern=_TARGET)
    command: list[str] = _f("an external program speaking the file protocol (rk4h.command), as argv", "-",
                            ["octave-cli", "step.m"], default=None, min_length=1, max_length=100)
    order: int = _f("the declared order of a python or command method (a tableau's is computed)", "-", 4,
                    default=None, ge=1, le=20)
    nfev_per_step: int = _f("right-hand-side calls per step of a python or command method", "calls", 4,
                            default=None, ge=0, default_text="counted")


#: Horizons (periods of the slowest mode) and steps per fastest period of the
#: ``energy_work_precision`` output (rk4h.validation.energy_time.WP_HORIZONS; the CLI's steps).
EWP_PERIODS = (1e2, 1e4)
EWP_STEPS = (8, 16, 32, 64)


class EnergyWorkPrecision(_Table):
    """The energy work-precision output (`energy_work_precision` in run.outputs; docs/energy-over-time.md)."""

    periods: list[Annotated[float, Field(ge=1, le=1e6, allow_inf_nan=False)]] = _f(
        "horizons in periods of the slowest (linearized) mode, each from 1 to 1e6 (a repeat runs once); every "
        "solver runs over each; the bounded-energy check reads those of at least 100",
        "periods", [1e2, 1e4], default=list(EWP_PERIODS), min_length=1, max_length=4)
    steps: list[Annotated[int, Field(ge=2, le=4096)]] = _f(
        "steps per period of the fastest mode at which each fixed-step method runs (h = T_fast / n); the "
        "adaptive references run at run.tolerances", "1", [16, 32], default=list(EWP_STEPS), min_length=1,
        max_length=8)


def _stability_field(p):
    """``(type, Field)`` of the ``[stability]`` key of row ``p`` of PARAMS."""
    number = Annotated[float, Field(ge=p.min, le=p.max)] if p.min is not None else float
    whole = {"multiple_of": 1} if p.type == "list[int]" else {}
    types = {"list[str]": list[Literal[STUDIES]], "str": str, "float": number,  # type: ignore[valid-type]
             "list[float]": list[number], "list[int]": list[Annotated[number, Field(**whole)]]}
    lists = {"min_length": 1, "max_length": MAX_LIST} if p.type.startswith("list") else {}
    example = p.default if p.default is not None else (["boundary", "roundoff"] if p.name == "studies" else "rk4")
    default = PydanticUndefined if p.name == "studies" else p.default
    text = {"method": "the first classical tableau of run.solvers, else rk4"}.get(p.name)
    return types[p.type], _f(p.meaning.removeprefix("required: "), p.unit, example, default=default, **lists,
                             **({"default_text": text} if text else {}))


#: The ``[stability]`` table, declared from rk4h.validation.stability.params.PARAMS.
Stability = create_model("Stability", __config__=_STRICT, __doc__="The stability study (docs/stability-params.md).",
                         **{p.name: _stability_field(p) for p in PARAMS})


def _by_params(value, handler):
    """``[stability]`` is validated by validate_params (its bounds table is the rule); the model
    above gives it a schema."""
    if not isinstance(value, dict):
        raise _rule("must be a table", value=value)
    try:
        return validate_params(dict(value), "stability")
    except StabilityParamError as e:
        shown = {} if e.value is None else {"value": e.value}
        raise _rule(e.problem, at=e.field[len("stability"):], **shown) from None


#: A key of ``[ensemble]`` (rk4h.validation.ensemble).
_ENSEMBLE_KEY = r"^(size|seed|map_h|map_steps|initial\.[xv]\[(0|[1-9][0-9]*)\]|params\.[A-Za-z_][A-Za-z0-9_]*(\[(0|[1-9][0-9]*)\])?)$"

SweepValue = Union[bool, int, float, Annotated[str, Field(pattern=f"^{WORD}$")]]


def _scene(tag: str, model_type, params_type) -> type[BaseModel]:
    """One variant of the top level: every field but `model` and `params` is shared."""
    builtin = ", ".join(BUILTIN_MODELS)
    fields = dict(
        name=(str, _f(f"the scene's name: 1 to {NAME_MAX} of a-z 0-9 - _, starting with a letter or digit; unique; "
                      "figure files start with it; `--scene NAME` runs it", "-", "thesis-2dof-case1",
                      pattern=NAME_PATTERN, max_length=NAME_MAX)),
        description=(str, _f("what the scene shows, one line", "-", "Thesis Table 4.1: unequal masses", default="")),
        model=(model_type, _f(f"the model: {builtin} (its [params] below), or 'package.module:Class', a subclass of "
                              f"rk4h.Model", "-", "chain")),
        quick=(bool, _f("part of the --quick subset", "-", True, default=False)),
        thesis_figures=(str, _f("the thesis figures this scene reproduces, quoted in its state figures' captions "
                                "as '(thesis ...)'; empty: the scene reproduces none", "-", "Figs 4.1-4.2",
                                default="", max_length=80)),
        params=(params_type, _f("the model's parameters (the [params] tables below)", "-",
                                {"masses": [0.815, 3.099], "springs": [41.5, 138.0, 157.8]})),
        initial=(Initial, _f("the initial state", "-", {"x": [0.005, 0.005]})),
        run=(Run, _f("the runs and the outputs", "-", {"t_end": 1.0, "h": [0.1], "solvers": ["rk4"]})),
        convergence=(Convergence, _f("the convergence sweep", "-", {"t_end": 0.5}, default_factory=Convergence,
                                     default_text="the defaults below")),
        energy_work_precision=(EnergyWorkPrecision, _f("the energy work-precision output's horizons and steps", "-",
                                                       {"periods": [1e2, 1e4]}, default_factory=EnergyWorkPrecision,
                                                       default_text="the defaults below")),
        methods=(dict[str, MethodTable], _f("the scene's own methods, [methods.NAME] (NAME: 1 to 40 of a-z 0-9 . - "
                                            "_, not a built-in's)", "-",
                                            {"ralston2": {"A": [["0", "0"], ["2/3", "0"]], "b": ["1/4", "3/4"]}},
                                            default_factory=dict, default_text="none",
                                            schema={"propertyNames": {"pattern": f"^{_METHOD_NAME.pattern}$"}})),
        stability=(Annotated[Stability, WrapValidator(_by_params)],
                   _f("the stability study", "-", {"studies": ["boundary"]}, default=None, default_text="none")),
        ensemble=(dict[str, Any], _f("an ensemble of instances run as one batch: size, seed, one distribution per "
                                     "`initial.x[i]`, `initial.v[i]` or numeric `params.NAME[i]`, and the stability "
                                     "map's `map_h`, `map_steps` ([ensemble] below)", "-",
                                     {"size": 100, "seed": 1,
                                      "params.masses[1]": {"dist": "log-uniform", "low": 0.1, "high": 10.0}},
                                     default=None, default_text="none",
                                     schema={"propertyNames": {"pattern": _ENSEMBLE_KEY}})),
        sweep=(dict[str, Annotated[list[SweepValue], Field(min_length=1)]],
               _f("one scene per point of the product of these lists: \"PATH\" = [values] ([sweep] below)", "-",
                  {"params.masses[1]": [0.5, 1.0]}, default=None, default_text="none",
                  schema={"propertyNames": {"pattern": _SWEEP_PATH}})),
    )
    return create_model(f"Scene_{tag}", __config__=_STRICT, __doc__=f"A scene file, model {tag}.", **fields)


#: A user's model: any string at run time (a registered name, or an import path the registry
#: resolves); the JSON Schema asks for 'package.module:Class', so its variants never overlap.
_USER_MODEL = Annotated[str, Field(json_schema_extra={"pattern": _TARGET})]


def _variant(tag: str) -> type[BaseModel]:
    if tag == "user":
        return _scene("user", _USER_MODEL, dict[str, Any])
    return _scene(tag, Literal[tag], BUILTIN_MODELS[tag])


#: tag -> the scene variant (the user's model under "user"); each is generated when first asked for.
SCENE_MODELS: Mapping[str, type[BaseModel]] = _Built([*BUILTIN_MODELS, "user"], _variant)


def _which(doc) -> str:
    model = doc.get("model") if isinstance(doc, dict) else None
    return model if isinstance(model, str) and model in BUILTIN_MODELS else "user"


@functools.cache
def _scene_adapter() -> TypeAdapter:
    return TypeAdapter(Annotated[Union[tuple(Annotated[cls, Tag(tag)] for tag, cls in SCENE_MODELS.items())],
                                 Discriminator(_which)])


#: The scene document: ``SCENE.validate_python(doc)`` (every variant is built
#: with it, on first use); :func:`validate` validates the same way, building
#: only the variant ``doc`` selects.
SCENE: TypeAdapter
#: The top-level keys of a scene file (built with the user's variant on first use).
TOP_KEYS: tuple
INITIAL_KEYS = tuple(Initial.model_fields)
_LAZY = {"SCENE": _scene_adapter, "TOP_KEYS": lambda: tuple(SCENE_MODELS["user"].model_fields)}


def __getattr__(name):
    if name in _LAZY:
        return _LAZY[name]()
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def validate(doc):
    """``doc`` validated as ``SCENE.validate_python(doc)`` validates it: by the
    variant of its model (:data:`SCENE_MODELS`, the one ``SCENE``'s
    discriminator picks), building only that variant.

    Raises
    ------
    pydantic.ValidationError
        Give it to :func:`first_error` with ``variant=SCENE_MODELS[_which(doc)]``
        (its locations lack the union's tag); :func:`validation_error` does.
    """
    return SCENE_MODELS[_which(doc)].model_validate(doc)


def validation_error(exc, doc) -> tuple[str, str, object]:
    """:func:`first_error` of a :func:`validate` failure of ``doc``."""
    return first_error(exc, doc, variant=SCENE_MODELS[_which(doc)])


# -- errors -----------------------------------------------------------------------------
_PROBLEMS = {
    "missing": "is missing", "float_type": "must be a number", "int_type": "must be an integer",
    "bool_type": "must be true or false", "string_type": "must be a string", "list_type": "must be a list",
    "dict_type": "must be a table", "model_type": "must be a table", "model_attributes_type": "must be a table",
    "finite_number": "must be finite", "greater_than": "must be > {gt:g}", "greater_than_equal": "must be >= {ge:g}",
    "less_than": "must be < {lt:g}", "less_than_equal": "must be <= {le:g}",
    "multiple_of": "must be a whole number", "literal_error": "must be {expected}",
    "string_pattern_mismatch": "must match {pattern}", "string_too_long": "must be at most {max_length} characters",
    "too_long": "must have at most {max_length} entries",
}
#: Field -> the problem of any error there but a missing key.
_FIELD_PROBLEMS = {
    "name": f"must be 1 to {NAME_MAX} lowercase letters, digits, '-' or '_', starting with a letter or digit",
    "run.max_output_points": "must be an integer >= 2",
}

def params_error(model_cls, params) -> tuple[str, str, object] | None:
    """The first error of ``params`` as the ``[params]`` of model class
    ``model_cls`` (a user's model: its :func:`params_table`), as
    :func:`first_error` words it (field ``params.KEY``); None when valid."""
    wrapper = model_cls.__dict__.get("_params_doc")
    if wrapper is None:
        wrapper = create_model(f"{params_table(model_cls).__name__}Doc", __config__=_STRICT,
                               params=(params_table(model_cls), ...))
        model_cls._params_doc = wrapper
    doc = {"params": params}
    try:
        wrapper.model_validate(doc)
    except ValidationError as e:
        return first_error(e, doc, variant=wrapper)
    return None


def first_error(exc, doc, variant=None) -> tuple[str, str, object]:
    """The one error a scene reports of a failed :data:`SCENE` validation.

    Parameters
    ----------
    exc : pydantic.ValidationError
        From ``SCENE.validate_python(doc)``.
    doc : dict
        The document validated (its keys give the error's path).
    variant : type of BaseModel, optional
        The model ``doc`` was validated with, when not :data:`SCENE`.

    Returns
    -------
    field : str
        Dotted path into the document, ``run.h[1]`` (union tags dropped).
    problem : str
        What is wrong, as :class:`rk4h.validation.scenes.SceneError` words it.
    value : object
        The offending value; None when none is shown (a missing or unknown key).

    Notes
    -----
    An unknown key is reported first (as the hand-written checks did), else
    the first error pydantic lists (fields in declaration order).
    """
    errors = exc.errors(include_url=False)
    if variant is not None:  # validated by one model, not the union: no variant tag in front
        errors = [{**e, "loc": (variant.__name__, *e["loc"])} for e in errors]
    err = min(errors, key=lambda e: e["type"] != "extra_forbidden")
    parts = _doc_path(err["loc"], doc)
    field = _dotted(parts)
    kind, ctx = err["type"], err.get("ctx") or {}
    if kind == "scene_rule":
        return field + ctx["at"], ctx["problem"], ctx.get("value")
    if kind == "missing":
        return field, "is missing", None
    if kind == "extra_forbidden":
        known = _known_keys(variant or SCENE_MODELS[_which(doc)], parts[:-1])
        return field, f"unknown key (known: {', '.join(sorted(known))})", None
    value = err.get("input")
    if field in _FIELD_PROBLEMS:
        return field, _FIELD_PROBLEMS[field], value
    if kind == "float_type" and isinstance(value, int) and not isinstance(value, bool):
        return field, "must be finite (it exceeds the double range)", value
    if kind == "float_type" and err["loc"][-1] == "one":  # neither a number nor a list
        return field, "must be a number or a list of numbers", value
    if kind == "too_short":
        n = ctx.get("min_length", 1)
        return field, "must not be empty" if n <= 1 else f"needs at least {n} entries", value
    template = _PROBLEMS.get(kind)
    if template is None:
        msg = err["msg"]
        return field, msg.replace("Input should be", "must be", 1) if msg.startswith("Input should") else msg, value
    try:
        return field, template.format(**ctx), value
    except (KeyError, ValueError, TypeError):
        return field, err["msg"], value


def _doc_path(loc, doc) -> list:
    """The document path of an error's ``loc``: the variant's tag (``loc[0]``) and the
    tags of the number-or-list unions dropped."""
    parts, node = [], doc
    for el in loc[1:]:
        if isinstance(node, dict) and isinstance(el, str) and el in node:
            node = node[el]
        elif isinstance(node, list) and isinstance(el, int) and 0 <= el < len(node):
            node = node[el]
        elif el in _TAGS or el == "[key]":
            continue
        else:
            node = None
        parts.append(el)
    return parts


def _dotted(parts) -> str:
    out = ""
    for p in parts:
        out += f"[{p}]" if isinstance(p, int) else (f".{p}" if out else str(p))
    return out or "file"


def _table_type(annotation):
    """The BaseModel (or ``dict`` value type) an annotation holds, else None."""
    while get_origin(annotation) is Annotated:
        annotation = get_args(annotation)[0]
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return annotation
    if get_origin(annotation) is dict:
        return ("dict", get_args(annotation)[1])
    return None


def _known_keys(cls, parts) -> list:
    t = cls
    for p in parts:
        if isinstance(t, tuple):  # a dict's key: its value type next
            t = _table_type(t[1])
        elif isinstance(t, type) and issubclass(t, BaseModel) and p in t.model_fields:
            t = _table_type(t.model_fields[p].annotation)
        else:
            return []
    return list(t.model_fields) if isinstance(t, type) else []


# -- the JSON Schema -------------------------------------------------------------------
def json_schema() -> dict:
    """The JSON Schema of a scene file.

    Returns
    -------
    dict
        pydantic's schema of :data:`SCENE` (draft 2020-12), with ``const``
        written as a one-value ``enum`` (draft 4 validators such as Taplo's
        read it too) and ``null`` defaults dropped (TOML has no null: an
        absent key takes the default the reference gives).
    """
    schema = _scene_adapter().json_schema()

    def clean(node):
        if isinstance(node, dict):
            if "const" in node:
                node["enum"] = [node.pop("const")]
            if "default" in node and node["default"] is None:
                del node["default"]
            for v in node.values():
                clean(v)
        elif isinstance(node, list):
            for v in node:
                clean(v)
    clean(schema)
    return {"$schema": "https://json-schema.org/draft/2020-12/schema", "title": "RK4 harness scene file",
            "description": "A scene of the RK4 validation harness (docs/scene-reference.md).", **schema}


# -- the reference --------------------------------------------------------------------
def _toml(v) -> str:
    """``v`` as a TOML value (inline; a float always reads back as a float)."""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, float):
        short = f"{v:g}"
        return short if float(short) == v and any(c in short for c in ".en") else repr(v)
    if isinstance(v, int):
        return repr(v)
    if isinstance(v, str):
        return json.dumps(v)
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_toml(x) for x in v) + "]"
    if isinstance(v, dict):
        keys = (k if all(c.isalnum() or c in "_-" for c in k) else json.dumps(k) for k in v)
        return "{ " + ", ".join(f"{k} = {_toml(x)}" for k, x in zip(keys, v.values())) + " }"
    raise TypeError(f"no TOML form for {v!r}")


def _type_text(s: dict) -> str:
    """A field's type, read from its JSON Schema."""
    if "$ref" in s:
        return "table"
    for key in ("anyOf", "oneOf"):
        if key in s:
            return " or ".join(_type_text(x) for x in s[key])
    if "enum" in s or "const" in s:
        values = s.get("enum", [s.get("const")])
        return "one of " + ", ".join(f"`{v}`" for v in values) if len(values) > 1 else f"`{values[0]}`"
    t = s.get("type")
    if t == "array":
        lo, hi = s.get("minItems"), s.get("maxItems")
        count = (f"list of {lo} to {hi}" if lo and hi else "non-empty list of" if lo == 1
                 else f"list of {lo} or more" if lo else f"list of at most {hi}" if hi else "list of")
        return f"{count} ({_type_text(s.get('items', {}))})"
    if t == "object":
        values = s.get("additionalProperties")
        return f"table of ({_type_text(values)})" if isinstance(values, dict) else "table"
    bounds = [f"{op} {s[k]:g}" for k, op in (("exclusiveMinimum", ">"), ("minimum", ">="), ("exclusiveMaximum", "<"),
                                              ("maximum", "<=")) if k in s]
    word = {"number": "number", "integer": "integer", "string": "string", "boolean": "true/false"}.get(t, "any")
    if s.get("multipleOf") == 1:
        word = "whole number"
    return " ".join([word, ", ".join(bounds)]).strip()


def _default_text(name, info) -> str:
    extra = info.json_schema_extra or {}
    if "default_text" in extra:
        return extra["default_text"]
    if info.is_required():
        return "required"
    if info.default is None:
        return "-"
    return f"`{_toml(info.default)}`"


def _table(cls: type[BaseModel]) -> str:
    props = cls.model_json_schema()
    rows = ["| key | type | unit | default | example | description |", "|---|---|---|---|---|---|"]
    for name, info in cls.model_fields.items():
        extra = info.json_schema_extra or {}
        t = _type_text(props["properties"][name])
        cells = [f"`{name}`", t, extra.get("unit", "-"), _default_text(name, info), f"`{_toml(extra['example'])}`",
                 info.description or ""]
        rows.append("| " + " | ".join(c.replace("|", "\\|") for c in cells) + " |")
    return "\n".join(rows)


_INTRO = """\
# Scene files: every key

Generated from `validation/scene_schema.py` (pydantic models, strict, unknown keys refused) by
`python -m rk4h.validation.scene_schema --markdown > docs/scene-reference.md`;
`tests/test_scene_schema.py` checks that this file is current and that every key below is accepted.
A scene is a TOML file in `validation/scenes/` (or anywhere, given by path): `--scene NAME` runs a
shipped scene by its `name` or file stem. A malformed scene is refused before anything runs, with one
line naming the file, the field and the value: ``FILE: field `run.h[1]`: must be > 0 (got -0.1)``.
TOML types are kept honest: `1.0` is a number, `"1.0"` a string, `true` a boolean (an integer is
accepted where a number is asked for, not the other way round).

Editors: `docs/scene.schema.json` is the JSON Schema of the same models. With Taplo or the VS Code
extension Even Better TOML, put a schema directive on the first line of a scene file,

```toml
#:schema ../../docs/scene.schema.json
```

(the path is relative to the scene file), and keys, types and descriptions complete as you type.

## Security: a scene can run code

A scene looks like data, but three keys name code that runs with your user's rights:
`[methods.NAME] command = [...]` starts that program, `[methods.NAME] python = "module:function"`
imports that module and `model = "module:Class"` imports that module (importing a module runs its
top-level code; the module is looked up on Python's path, which may include the current directory).
Every other key is data: a `potential` (and an `ode`'s `equations`, `invariant` and `exact`) is parsed
by the harness's own parser, never evaluated.
For a scene the project does not ship (any file outside `validation/scenes/` of the installed
package, a copy of a shipped one included), these keys are refused before anything is imported or
started, exit 2, one line naming the file and the key, unless you pass `--allow-code` (to
`run_all.py`/`rk4h run` and `advise.py`/`rk4h advise`), set `RK4H_ALLOW_CODE=1`, or call the loaders
with `allow_code=True`. Before you allow a scene from someone else, read it: search it for
`command`, `python` and a `model` with a `:`, and read every program and module those name (and what
they import).
"""

_ENSEMBLE = """\
## `[ensemble]`

`size` instances (1 to 10^8) of the scene's model, one batch (`rk4h.ensemble`, numba backend), for the
`ensemble` and `stability_map` outputs. `seed` (default 0) seeds `numpy.random.default_rng`. Every other key
is `"initial.x[i]"`, `"initial.v[i]"`, `"params.NAME"` or `"params.NAME[i]"` (a numeric parameter) = a
distribution: `{ dist = "uniform", low, high }`, `{ dist = "normal", mean, std }`,
`{ dist = "log-uniform", low, high }` (low > 0) or `{ dist = "grid", low, high, n }` (`scale = "log"`
optional; or `values = [...]`; grid keys form a product repeated over the draws, `size` a multiple of it).
What is not drawn keeps the scene's `[initial]` and `[params]`. The stability map reads `map_h = { low,
high, n }` (its steps, s; `scale = "log"` optional), `map_steps` (steps per run, default 2000) and the one
grid key over a parameter. Details: [ensembles.md](ensembles.md).

"""

_SWEEP = """\
## `[sweep]`

`"PATH" = [values]`: the file stands for one scene per point of the product of the lists (the first
key varies slowest). A PATH is a table and a key, then any number of `[i]` (0-based index into a
list written in the file) or `.KEY`. Sweepable: `params.NAME` (any parameter of the model, written
or not), `initial.x`, `initial.v`, `initial.mode`, `initial.amplitude` (`initial.x[0]` sweeps one
coordinate) and `run.t_end`. A value is a number, `true`/`false` or a word of `a-z 0-9 _ . -`; a
point is named `NAME@TOKEN=VALUE`, e.g. `sweep-2dof-mass-ratio@masses1=0.815`. The rules are in
the docstring of `validation/sweeps.py`.
"""

_USER = """\
### `[params]` of a user's model

With `model = "package.module:Class"` (a subclass of `rk4h.Model`, importable), the keys are the
class's declared `parameters` (`rk4h.models.Param` rows: kind, unit, default, description; checked
as the built-ins' tables above are), or, when it declares none, the arguments of its `__init__`: those
without a default are required, unknown keys are refused.
"""


def _outputs_table() -> str:
    rows = ["| output | in the default when | adds |", "|---|---|---|"]
    rows += [f"| `{o}` | {when} | {what} |" for o, (when, what) in _outputs.help_rows().items()]
    return "\n".join(rows)


def reference_markdown() -> str:
    """The text of ``docs/scene-reference.md``.

    Returns
    -------
    str
        One Markdown table per section (key, type, unit, default, example,
        description), each read from the models' fields: types from their
        JSON Schema, the rest from ``Field(description=...,
        json_schema_extra={"unit": ..., "example": ...})``.
    """
    parts = [_INTRO, "## Top level\n", _table(SCENE_MODELS["user"]), ""]
    for name, cls in BUILTIN_MODELS.items():
        parts += [f"### `[params]` of `model = \"{name}\"`\n", (cls.__doc__ or "").strip() + "\n", _table(cls), ""]
    parts += [_USER, "## `[initial]`\n", _table(Initial), "", "## `[run]`\n", _table(Run), "",
              "### Outputs\n", "`run.outputs` defaults to every output that applies to the model "
              "(`rk4h.validation.scenes.default_outputs`); a chain above 5000 degrees of freedom gets only "
              "`stability` (every other output needs a dense eigensolve).\n", _outputs_table(), "",
              "## `[convergence]`\n", _table(Convergence), "",
              "## `[energy_work_precision]`\n", "Read only when run.outputs lists `energy_work_precision`.\n",
              _table(EnergyWorkPrecision), "", "## `[methods.NAME]`\n",
              "Exactly one of a tableau (`A`, `b`, optional `c`; `A_v`, `b_v` make it partitioned), `python` or "
              "`command`; the last two need `order`.\n", _table(MethodTable), "",
              "## `[stability]`\n", "Declared from `rk4h.validation.stability.params.PARAMS`; the same keys with their "
              "ranges: [stability-params.md](stability-params.md).\n", _table(Stability), "", _ENSEMBLE, _SWEEP]
    return "\n".join(parts)


def json_schema_text() -> str:
    """:func:`json_schema` as the text of ``docs/scene.schema.json`` (indent 2, a final newline)."""
    return json.dumps(json_schema(), indent=2) + "\n"


def main(argv=None, *, prog="python -m rk4h.validation.scene_schema") -> int:
    """Print the scene reference (``--markdown``) or the JSON Schema
    (``--json-schema``); returns the exit status."""
    import argparse

    p = argparse.ArgumentParser(prog=prog, description="Every key a scene file may hold, generated from the "
                                "schema the harness validates scenes with.",
                                epilog="examples:\n  %(prog)s --markdown > scene-reference.md\n"
                                       "  %(prog)s --json-schema > scene.schema.json   # for editors (Taplo)",
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    what = p.add_mutually_exclusive_group(required=True)
    what.add_argument("--markdown", action="store_true", help="the reference as Markdown")
    what.add_argument("--json-schema", action="store_true", help="the JSON Schema")
    from .commandline import parse

    args = parse(p, argv)
    if isinstance(args, int):
        return args
    sys.stdout.write(reference_markdown() if args.markdown else json_schema_text())
    return 0


if __name__ == "__main__":
    sys.exit(main())
