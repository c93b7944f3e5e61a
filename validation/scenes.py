"""Scene files: one physical situation and what to measure on it (docs/scene-reference.md).

Every key a scene file may hold -- type, unit, default, an example -- is in
``docs/scene-reference.md``, generated from :mod:`rk4h.validation.scene_schema`,
where the document's structure is declared once (pydantic, strict: TOML types
kept, unknown keys refused; a union on ``model``). A short scene::

    name = "thesis-2dof-case1"          # [a-z0-9_-], unique; figure names start with it
    model = "chain"                     # a key of rk4h.models.MODELS, or "package.module:Class"
    [params]                            # the model's parameters (rk4h.make_model)
    masses = [0.815, 3.099]
    springs = [41.5, 138.0, 157.8]
    [initial]
    x = [0.005, 0.005]                  # or mode = 2 [and amplitude]: a normal mode (Code 02)
    [run]
    t_end = 100.0                       # s
    h = [0.1, 0.01]                     # fixed steps (s) of the fixed-step methods
    solvers = ["rk4", "euler"]          # built-ins and the scene's own [methods.NAME]
                                        # outputs: default, every output that applies

:func:`scene_from_dict` validates the document with
:data:`rk4h.validation.scene_schema.SCENE`, then checks here what a schema cannot
express: the model (a user's model imported and its parameters checked
against its constructor), the parameters' model (rk4core builds it), ``x``
and ``v`` against the model's degrees of freedom, a mode's shape, the solvers
a scene's own methods add, ``h`` and ``tolerances`` present when a solver
needs them, the output grid below, ``[stability] method``, and sweeps.
``run.outputs`` defaults to :func:`default_outputs`: every output that
applies to the model.

Errors and accuracy are measured on the output grid ``0, output_dt, ...,
t_end``; every ``h`` must divide ``output_dt`` (default: the largest ``h``) and
``output_dt`` must divide ``t_end``, so every output time is a step of every
fixed-step run (no interpolation enters the error). With ``max_output_points``
the grid keeps every ``k``-th of those points (``k`` the smallest stride that
fits) and always ``t_end``: decimated, but still on every step grid.

A malformed scene raises :class:`SceneError`, one line ``FILE: field `F`:
problem (got VALUE)``, before anything runs. A parameter set that passes the
schema but from which rk4core builds no model (a spring network joining a
node to itself, an expression that does not parse, a frequency that
overflows) is refused naming field ``params`` with rk4core's own line.

Sweeps
------
An optional ``[sweep]`` table makes the file stand for one scene per point of
a parameter grid; :mod:`rk4h.validation.sweeps` expands it (its docstring gives the
rules, the point names and the errors). Each point is validated by
:func:`scene_from_dict` as an ordinary scene.

Loading: :func:`load_scene_points` returns one :class:`Scene` per point (or
the one scene of an unswept file); :func:`load_scenes` returns the flattened
list of all files' points, so its duplicate-name check covers points.
:func:`load_scene` returns the one scene of a file and refuses a sweep of more
than one point (field ``sweep``), as does :func:`scene_from_dict` for a
document; :func:`scene_points_from_dict` is the sweep-aware form of the latter.
``load_scenes(["BASE@TOKEN=VALUE"])`` (``run_all --scene``) loads that one
point of a shipped scene.

Code in a scene
---------------
A scene looks like data but can name code: a ``command`` method starts a
program, a ``python`` method and a ``model = "package.module:Class"`` import
a module (which runs whatever that module runs at import time). The loaders
(:func:`load_scene`, :func:`load_scene_points`, :func:`load_scenes`) accept
such keys only in a *shipped* scene -- a regular file directly in
:data:`SCENE_DIR` (resolved path, so a symbolic link elsewhere is not one) and
whose content is the content validated -- or with ``allow_code=True``. Their
default ``allow_code=None`` reads the environment: ``RK4H_ALLOW_CODE=1``
allows, anything else refuses. A refusal is a :class:`SceneError` naming the
file and the key (``model``, ``methods.NAME.python`` or
``methods.NAME.command``), raised after the file is parsed as TOML and before
anything is imported or started. A copy of a shipped scene elsewhere is the
user's file and needs the flag too. :func:`scene_from_dict` and
:func:`scene_points_from_dict` take a document the caller built: code the
caller wrote is the caller's own, so their ``allow_code`` defaults to
``True``; a caller who hands them a document read from somewhere else should
pass ``allow_code=False``.
"""
from __future__ import annotations

import functools
import math
import os
import re
import stat
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from rk4h.references.registry import MethodError, methods_from_tables, names, resolve
from rk4h.solver import _SLACK as _STEP_SLACK

from . import sweeps
from .scene_checks import SceneError
from .scene_checks import check_model as _check_model
from .scene_checks import figure_stem as _figure_stem
from .scene_checks import show as _show
from .scene_checks import unknown_keys as _unknown_keys
from .sweeps import MAX_SWEEP_POINTS, SWEEP_RUN_KEYS

__all__ = ["Scene", "SceneError", "load_scene", "load_scene_points", "load_scenes", "resolve_scene",
           "scene_from_dict", "scene_points_from_dict", "output_stride", "OUTPUTS", "SCENE_DIR",
           "MAX_SCENE_BYTES", "MAX_SWEEP_POINTS", "SWEEP_RUN_KEYS", "default_outputs", "ALLOW_CODE_ENV",
           "code_allowed", "is_shipped", "code_keys"]

#: Degrees of freedom above which no dense eigenproblem is solved (modes,
#: the exact modal reference): minutes of O(n^3) work; the budget
#: (:mod:`rk4h.validation.budget`) refuses such scenes, and the defaults skip
#: what would need one.
MAX_DENSE_DOF = 5000
SCENE_DIR = Path(__file__).resolve().parent / "scenes"
#: Environment variable that allows code from a scene the project does not ship
#: (value ``1``; the command-line flag is ``--allow-code``).
ALLOW_CODE_ENV = "RK4H_ALLOW_CODE"

# The schema (rk4h.validation.scene_schema, with pydantic) is imported when a
# scene is validated, not with this module: a process that only receives
# scenes (a worker unpickling its jobs) never builds it.
#: Relative slack when checking that one step divides another: the slack of
#: rk4core's step count (``ceil((t1 - t0) / h)``), so a step that passes here
#: is the step used, and every output time is a grid point of every run.
_DIVIDES = _STEP_SLACK
#: Largest scene file read (bytes); a scene is a few hundred bytes.
MAX_SCENE_BYTES = 1 << 20


@dataclass
class Scene:
    """A validated scene. Lists are plain Python floats/strings."""

    name: str
    description: str
    model: str
    params: dict
    initial_x: list
    initial_v: list
    t_end: float
    h: list
    tolerances: list
    solvers: list
    outputs: list
    quick: bool = False
    stability: dict | None = None
    path: Path | None = None
    output_dt: float = 0.0
    convergence: dict = field(default_factory=dict)
    #: the ``[energy_work_precision]`` keys as written (the output applies the defaults)
    energy_work_precision: dict = field(default_factory=dict)
    max_output_points: int | None = None
    #: sweep column -> value of this point (empty unless the file has ``[sweep]``)
    sweep: dict = field(default_factory=dict)
    #: the scene's name in its file (``name`` is ``BASE@...`` for a sweep point)
    base: str = ""
    #: the scene's own methods: ``[methods.NAME]`` tables as written
    methods: dict = field(default_factory=dict)
    #: the thesis figures the scene reproduces (``thesis_figures``; "" for none)
    thesis_figures: str = ""
    #: the ``[ensemble]`` table as written (rk4h.validation.ensemble), or None
    ensemble: dict | None = None

    def __post_init__(self):
        if not self.base:
            self.base = self.name

    @property
    def n_intervals(self) -> int:
        """Number of ``output_dt`` intervals in ``[0, t_end]``."""
        return int(round(self.t_end / self.output_dt))

    @property
    def output_stride(self) -> int:
        """Keep every ``output_stride``-th point of the ``output_dt`` grid
        (1 unless ``max_output_points`` asks for fewer points)."""
        return output_stride(self.n_intervals, self.max_output_points)

    def build_model(self):
        """The rk4core model the scene names."""
        from rk4h import make_model

        return make_model(self.model, dict(self.params))

    def y0(self) -> np.ndarray:
        """Flat initial state ``[x, v]`` (a first-order ODE's ``[initial] y``
        is kept in ``initial_x``, with ``initial_v`` empty)."""
        return np.concatenate([np.asarray(self.initial_x, float), np.asarray(self.initial_v, float)])

    def t_eval(self) -> np.ndarray:
        """The output grid ``0, output_dt, ..., t_end`` (s); decimated to every
        :attr:`output_stride`-th point, ``t_end`` always included."""
        n, k = self.n_intervals, self.output_stride
        idx = np.arange(0, n + 1, k, dtype=float)
        if idx[-1] != n:
            idx = np.append(idx, float(n))
        # as np.linspace(0, t_end, n + 1)[::k] (bit for bit), without the full grid
        t = idx * (self.t_end / n)
        t[-1] = self.t_end
        return t

    @property
    def n_output_points(self) -> int:
        """Length of :meth:`t_eval` (without building it)."""
        n, k = self.n_intervals, self.output_stride
        return n // k + 1 + (n % k != 0)

    @property
    def registry(self) -> dict:
        """The scene's own methods by name (:class:`rk4h.references.registry.Method`),
        built once per scene object."""
        cached = self.__dict__.get("_registry")
        if cached is None:
            cached = self.__dict__["_registry"] = methods_from_tables(self.methods)
        return cached

    def method(self, name):
        """The :class:`rk4h.references.registry.Method` ``name`` names in this scene."""
        return resolve(name, self.registry)

    @property
    def fixed_solvers(self) -> list:
        return [s for s in self.solvers if self.method(s).fixed_step]

    @property
    def adaptive_solvers(self) -> list:
        return [s for s in self.solvers if not self.method(s).fixed_step]


def output_stride(n_intervals: int, max_points: int | None) -> int:
    """Smallest stride ``k`` for which the points ``0, k, 2k, ... (<= n)`` plus
    the end point ``n`` number at most ``max_points`` (>= 2)."""
    if max_points is None or n_intervals + 1 <= max_points:
        return 1
    k = max(1, -(-n_intervals // (max_points - 1)))
    while n_intervals // k + 1 + (n_intervals % k != 0) > max_points:
        k += 1
    return k


# -- checks --------------------------------------------------------------------
def _divides(small: float, big: float) -> bool:
    r = big / small
    if not math.isfinite(r):
        return False
    return abs(r - round(r)) <= _DIVIDES * max(1.0, r)


def _schema():
    """:mod:`rk4h.validation.scene_schema`, imported on first use (it loads pydantic)."""
    from . import scene_schema

    return scene_schema


def __getattr__(name):
    # OUTPUTS (the output names when the schema was imported), read from the schema on first use
    if name == "OUTPUTS":
        return _schema().OUTPUTS
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def _validated(path, doc: dict):
    """``doc`` validated by :data:`rk4h.validation.scene_schema.SCENE` (the variant of
    its model), or the :class:`SceneError` of its first error."""
    from pydantic import ValidationError

    scene_schema = _schema()
    try:
        return scene_schema.validate(doc)  # as SCENE.validate_python(doc), building only doc's variant
    except ValidationError as e:
        fld, problem, value = scene_schema.validation_error(e, doc)
        raise SceneError(path, fld, problem, value) from None


# -- loading -------------------------------------------------------------------
def _read_text(path: Path) -> str:
    """The UTF-8 text of a regular file of at most :data:`MAX_SCENE_BYTES`.

    A FIFO, a device (``/dev/zero``), a directory or a larger file is refused
    before it is read, so a wrong path can neither block nor exhaust memory."""
    try:
        st = os.stat(path)
    except OSError as e:
        raise SceneError(path, "file", f"cannot be read: {e.strerror}") from None
    if not stat.S_ISREG(st.st_mode):
        what = ("a directory" if stat.S_ISDIR(st.st_mode) else "a FIFO" if stat.S_ISFIFO(st.st_mode)
                else "a device" if stat.S_ISCHR(st.st_mode) or stat.S_ISBLK(st.st_mode) else "not a regular file")
        raise SceneError(path, "file", f"must be a regular file, but it is {what}")
    if st.st_size > MAX_SCENE_BYTES:
        raise SceneError(path, "file", f"is {st.st_size} bytes, above the {MAX_SCENE_BYTES}-byte cap for a scene")
    try:
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0))
        with os.fdopen(fd, "rb") as f:
            if not stat.S_ISREG(os.fstat(f.fileno()).st_mode):  # swapped since the stat
                raise SceneError(path, "file", "must be a regular file")
            data = f.read(MAX_SCENE_BYTES + 1)
    except OSError as e:
        raise SceneError(path, "file", f"cannot be read: {e.strerror}") from None
    if len(data) > MAX_SCENE_BYTES:
        raise SceneError(path, "file", f"is above the {MAX_SCENE_BYTES}-byte cap for a scene")
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as e:
        raise SceneError(path, "file", f"is not UTF-8 text ({e.reason} at byte {e.start})") from None


def _read_doc(path: Path) -> dict:
    return _parse(path, _read_text(path))


def _parse(path, text: str) -> dict:
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as e:
        raise SceneError(path, "file", f"is not valid TOML: {e}") from None


def code_allowed(allow_code=None) -> bool:
    """Whether code named by a non-shipped scene may run: ``allow_code`` when it
    is a bool, else the environment (``RK4H_ALLOW_CODE=1`` allows; unset, empty
    or ``0`` refuses). Any other value of the variable raises :class:`SceneError`
    (field ``RK4H_ALLOW_CODE``), rather than guessing what it meant."""
    if allow_code is not None:
        return bool(allow_code)
    value = os.environ.get(ALLOW_CODE_ENV, "")
    if value not in ("", "0", "1"):
        raise SceneError("environment", ALLOW_CODE_ENV, "must be 1 (allow code from scenes) or 0/unset", value)
    return value == "1"


def is_shipped(path, text: str | None = None) -> bool:
    """Whether ``path`` is a scene the project ships: a regular file directly
    in :data:`SCENE_DIR` (paths compared resolved, so a link to a file
    elsewhere is not one) and, when ``text`` is given, whose content is
    ``text`` (the text that was validated)."""
    try:
        resolved = Path(path).resolve(strict=True)
        if resolved.parent != SCENE_DIR.resolve() or resolved.suffix != ".toml" or not resolved.is_file():
            return False
        return text is None or _read_text(resolved) == text
    except (OSError, RuntimeError, SceneError):
        return False


def code_keys(doc) -> list[tuple[str, object]]:
    """``(field, value)`` of every key of a scene document that names code: a
    ``model`` of the form ``package.module:Class`` and the ``python`` and
    ``command`` keys of ``[methods.NAME]`` tables. Reads the document only."""
    found = []
    if not isinstance(doc, dict):
        return found
    model = doc.get("model")
    if isinstance(model, str) and ":" in model:
        found.append(("model", model))
    methods = doc.get("methods")
    if isinstance(methods, dict):
        for name, table in methods.items():
            if isinstance(table, dict):
                for key in ("python", "command"):
                    if key in table:
                        found.append((f"methods.{name}.{key}", table[key]))
    return found


def _refuse_code(path, doc) -> None:
    keys = code_keys(doc)
    if keys:
        fld, value = keys[0]
        what = "starts a program" if fld.endswith(".command") else "imports a Python module"
        raise SceneError(path, fld, f"{what}, and this scene is not one the project ships: read the scene, then "
                         f"pass --allow-code (or set {ALLOW_CODE_ENV}=1; allow_code=True in Python) to run it",
                         value)


def _load_file(path, allow_code) -> list[Scene]:
    path = Path(path)
    text = _read_text(path)
    doc = _parse(path, text)
    allowed = code_allowed(allow_code) or not code_keys(doc) or is_shipped(path, text)
    return scene_points_from_dict(doc, path, allow_code=allowed)


def load_scene(path, *, allow_code=None) -> Scene:
    """Read and validate one scene file. Raises :class:`SceneError`, also for a
    file whose ``[sweep]`` gives more than one scene (use :func:`load_scene_points`),
    and for code in a scene the project does not ship unless ``allow_code``
    (module docstring, "Code in a scene"; ``None``: ``RK4H_ALLOW_CODE``)."""
    path = Path(path)
    return _only(_load_file(path, allow_code), path)


def load_scene_points(path, *, allow_code=None) -> list[Scene]:
    """Read and validate one scene file: one :class:`Scene` per point of its
    ``[sweep]`` (:mod:`rk4h.validation.sweeps`), or the one scene of an unswept
    file. ``allow_code`` as for :func:`load_scene`."""
    return _load_file(path, allow_code)


def _only(scenes: list, path) -> Scene:
    if len(scenes) != 1:
        raise SceneError(path, "sweep", f"gives {len(scenes)} scenes, one per point: load them with "
                         f"load_scene_points() or load_scenes()")
    return scenes[0]


def scene_from_dict(doc: dict, path="<scene>", *, allow_code: bool = True) -> Scene:
    """Validate a parsed scene document (see the module docstring). A document
    whose ``[sweep]`` gives more than one point is validated, then refused
    (field ``sweep``): use :func:`scene_points_from_dict`. With
    ``allow_code=False`` a document naming code is refused before anything is
    imported (module docstring, "Code in a scene"); the default allows it: a
    document built in the caller's own code is the caller's code."""
    if isinstance(doc, dict) and "sweep" in doc:
        return _only(scene_points_from_dict(doc, path, allow_code=allow_code), path)
    if not allow_code:
        _refuse_code(path, doc)
    return _scene_from_dict(doc, path)


def _scene_from_dict(doc: dict, path) -> Scene:
    if not isinstance(doc, dict):
        raise SceneError(path, "file", "must hold a table of scene fields", doc)
    s = _validated(path, doc)
    _check_model(path, s.model)
    model = _build_model(path, s.model, doc["params"])
    n = model.n_dof
    ini = s.initial
    first_order = getattr(model, "first_order", False)
    if first_order or ini.y is not None:
        x, v = _first_order_start(path, s.model, model, ini, doc)
    elif ini.x is not None:
        if len(ini.x) != n:
            raise SceneError(path, "initial.x", f"must have {n} entries for this {s.model}", doc["initial"]["x"])
        x = list(ini.x)
    else:
        x = _mode_shape(path, model, ini)
    if not first_order:
        v = list(ini.v) if ini.v is not None else [0.0] * n
        if len(v) != n:
            raise SceneError(path, "initial.v", f"must have {n} entries for this {s.model}", doc["initial"]["v"])

    run = s.run
    t_end = run.t_end
    methods = _methods(path, doc.get("methods", {}))
    known = names(methods)
    for i, solver in enumerate(run.solvers):
        if solver not in known:
            raise SceneError(path, f"run.solvers[{i}]", f"must be one of {', '.join(known)}", solver)
        if first_order:
            _first_order_solver(path, i, solver, methods)
    fixed = [resolve(sv, methods).fixed_step for sv in run.solvers]
    h = []
    if any(fixed) or run.h is not None:
        if run.h is None:
            raise SceneError(path, "run.h", "is missing (needed by the fixed-step solvers)")
        h = list(run.h)
        for i, hi in enumerate(h):
            if hi > t_end:
                raise SceneError(path, f"run.h[{i}]", f"must be <= t_end = {t_end}", hi)
    tolerances = []
    if not all(fixed) or run.tolerances is not None:
        if run.tolerances is None:
            raise SceneError(path, "run.tolerances", "is missing (needed by the adaptive solvers)")
        tolerances = list(run.tolerances)
    output_dt = run.output_dt if run.output_dt is not None else max(h) if h else t_end / 1000.0
    if output_dt > t_end or not _divides(output_dt, t_end):
        raise SceneError(path, "run.output_dt", f"must divide t_end = {t_end}", output_dt)
    for i, hi in enumerate(h):
        if not _divides(hi, output_dt):
            raise SceneError(path, f"run.h[{i}]", f"must divide the output spacing {output_dt}", hi)

    stability = s.stability
    if run.outputs is not None:
        outputs = list(run.outputs)
    else:
        outputs = default_outputs(model, stability=stability is not None)
        if not outputs:

            raise SceneError(path, "run.outputs", f"is missing, and only `stability` applies to a model of {n} "
                             f"degrees of freedom (every other output needs a dense eigensolve, above "
                             f"{MAX_DENSE_DOF}): give a [stability] table or outputs")
    if first_order and run.outputs is not None:
        fits = default_outputs(model) + ["trajectory"]  # trajectory: any model's runs, never a default
        for i, o in enumerate(outputs):
            if o not in fits:
                raise SceneError(path, f"run.outputs[{i}]", f"does not apply to model {s.model!r} (a first-order "
                                 f"ODE{'' if model.has_invariant() else ' without an invariant'}): "
                                 f"it takes {', '.join(fits)}", o)
    if "stability" in outputs and stability is None:  # its defaults, or the error of a missing `studies`
        stability = _validated(path, {**doc, "stability": {}}).stability
    if stability is not None:
        stability["method"] = _stability_method(path, stability.get("method"), run.solvers, methods)

    ensemble = _ensemble(path, doc.get("ensemble"), outputs, model, x, v)
    scene = Scene(name=s.name, description=s.description, model=s.model, params=dict(doc["params"]),
                  initial_x=[float(a) for a in x], initial_v=[float(a) for a in v], t_end=t_end,
                  h=h, tolerances=tolerances, solvers=list(run.solvers), outputs=outputs, quick=s.quick,
                  stability=stability, path=Path(path), output_dt=output_dt,
                  convergence=s.convergence.model_dump(exclude_unset=True),
                  energy_work_precision=s.energy_work_precision.model_dump(exclude_unset=True),
                  max_output_points=run.max_output_points,
                  methods={k: dict(v) for k, v in doc.get("methods", {}).items()},
                  thesis_figures=s.thesis_figures, ensemble=ensemble)
    scene.__dict__["_registry"] = methods
    return scene


def _ensemble(path, table, outputs, model, x, v):
    """The ``[ensemble]`` table, checked against the model (every draw and the
    stability map's keys), or the :class:`SceneError` naming its field."""
    import re

    wants = [o for o in ("ensemble", "stability_map", "amplitude_ensemble") if o in outputs]
    if table is None:
        if wants:
            raise SceneError(path, "run.outputs", f"`{wants[0]}` needs an [ensemble] table", wants[0])
        return None
    from .ensemble import draw_instances, map_settings  # only for a scene with an [ensemble] table

    try:
        draw_instances(table, model, x, v, probe=True)  # the run draws all `size` instances
        if "stability_map" in outputs:
            map_settings(table, model)
    except ValueError as e:
        m = re.match(r"`([^`]+)` (.*)", str(e))
        raise SceneError(path, m.group(1) if m else "ensemble", m.group(2) if m else str(e)) from None
    linear_only = [o for o in wants if o == "stability_map"]  # omega_max; `ensemble` has a batch reference
    if linear_only and not getattr(model, "linear", False):
        raise SceneError(path, "run.outputs", f"`{linear_only[0]}` needs a linear model (each instance's exact modal "
                         f"solution, omega_max); {model.name} is nonlinear", linear_only[0])
    return dict(table)


def _first_order_start(path, model_name, model, ini, doc):
    """``(y, [])`` of a first-order model's ``[initial] y`` (kept as the
    scene's ``initial_x``, with no ``initial_v``: :meth:`Scene.y0` is ``y``)."""
    if not getattr(model, "first_order", False):
        raise SceneError(path, "initial.y", f"is the state of a first-order ODE (model `ode`); a {model_name} "
                         f"starts from `x` and `v` or `mode`", doc["initial"]["y"])
    if ini.y is None:
        raise SceneError(path, "initial", f"needs `y` (one number per variable) for model {model_name!r}; "
                         f"`x`, `v` and `mode` are for mechanical models")
    if len(ini.y) != model.n_state:
        raise SceneError(path, "initial.y", f"must have {model.n_state} entries (one per variable)",
                         doc["initial"]["y"])
    problem = model.state_problem(ini.y, t=0.0)  # a scene starts at t = 0
    if problem is not None:
        raise SceneError(path, "initial.y", f"is no state to start from: {problem}", doc["initial"]["y"])
    check = getattr(model, "check_exact", None)
    if check is not None:
        try:
            check(ini.y)
        except ValueError as e:
            raise SceneError(path, "params.exact", str(e)) from None
    return list(ini.y), []


def _first_order_solver(path, i, solver, methods) -> None:
    """Refuse a solver that needs a mechanical model on a first-order ODE."""
    from rk4h.references.solvers import mechanical_only

    if mechanical_only(resolve(solver, methods)):
        raise SceneError(path, f"run.solvers[{i}]", "needs a mechanical model (y = [q, v], masses, a potential); "
                         "model `ode` is a first-order ODE", solver)


def default_outputs(model, *, stability: bool = False) -> list[str]:
    """What ``run.outputs`` is when a scene omits it: every output of
    :data:`rk4h.validation.outputs.OUTPUTS` whose ``applies`` holds for ``model``
    (an rk4core model), in the registry's order. Each output module states its
    rule; the built-ins:

    * ``state``, ``energy``, ``work_precision``, ``figures``: every model;
    * ``convergence``, ``modes``, ``modal_energy``: a model with a linearization
      (a stiffness matrix: its frequencies set the convergence grid);
    * ``linearization``: a nonlinear model with a linearization;
    * ``dispersion``: a uniform chain between walls (the rule the dispersion
      output itself applies, :meth:`rk4h.models.Model.uniform_chain`);
    * ``stability``: when the scene has a ``[stability]`` table;
    * ``thesis_code``, ``trajectory``: never (the thesis' own programs; every
      run's states);
    * a first-order ODE (model ``ode``): ``state``, ``convergence``,
      ``work_precision``, ``figures``, and ``energy`` when it has an
      invariant (``trajectory`` too when the scene lists it).

    Above :data:`MAX_DENSE_DOF` degrees of freedom only outputs that need no
    dense eigensolve apply (``stability``: the budget refuses the others), so
    the list may be empty.
    """
    from . import outputs

    return outputs.default_outputs(outputs.ModelFacts(model, stability=stability,
                                                      dense=model.first_order or model.n_dof <= MAX_DENSE_DOF))


def _build_model(path, model_name, params):
    """The rk4core model of the scene's ``[params]``. A user's model's
    ``[params]`` are checked here by the table generated from its declared
    parameters (its constructor's, when it declares none), as the schema
    checks a built-in's; what rk4core still refuses is one line naming
    ``params``."""
    from rk4h import MODELS, make_model
    from rk4h.models import resolve_model

    scene_schema = _schema()
    if model_name not in scene_schema.BUILTIN_MODELS:
        err = scene_schema.params_error(MODELS[resolve_model(model_name)], params)
        if err is not None:
            raise SceneError(path, *err)
    try:
        return make_model(model_name, dict(params))
    except ValueError as e:
        raise SceneError(path, "params", str(e).strip() or type(e).__name__) from None
    except TypeError as e:
        raise SceneError(path, "params", f"has a value of the wrong type: {e}") from None
    except ArithmeticError as e:  # overflow in a derived quantity of extreme parameters
        raise SceneError(path, "params", f"gives no usable model: {type(e).__name__}: {e}") from None


def _methods(path, tables) -> dict:
    """The scene's ``[methods.NAME]`` tables as registry methods; a bad one is
    one line naming ``methods.NAME.KEY``."""
    try:
        return methods_from_tables(tables)
    except MethodError as e:
        raise SceneError(path, f"methods.{e.name}.{e.field}" if e.field != "name" else f"methods.{e.name}",
                         e.problem) from None


def _mode_shape(path, model, ini) -> list:
    """``amplitude * phi[:, mode - 1]`` with a fixed sign (first nonzero entry > 0)."""
    mode = ini.mode
    if mode > model.n_dof:
        raise SceneError(path, "initial.mode", f"must be an integer in 1..{model.n_dof}", mode)

    if model.n_dof > MAX_DENSE_DOF:
        raise SceneError(path, "initial.mode", f"needs a dense eigensolve of {model.n_dof} degrees of freedom, "
                         f"above the cap of {MAX_DENSE_DOF}; give `x` instead", mode)
    try:
        _, phi = model.modes()
    except NotImplementedError:
        raise SceneError(path, "initial.mode", f"model {model.name!r} has no modes") from None
    shape = phi[:, mode - 1]
    first = np.flatnonzero(np.abs(shape) > 1e-12 * np.max(np.abs(shape)))[0]
    return list(ini.amplitude * np.sign(shape[first]) * shape)


def _stability_method(path, name, solvers, methods) -> str:
    """``stability.method``: the classical tableau the studies integrate
    (given, or the first classical tableau of ``run.solvers``, else
    :data:`rk4h.references.registry.UNDER_TEST`)."""
    from rk4h.references.registry import UNDER_TEST, Kind

    if name is None:
        return next((sv for sv in solvers if resolve(sv, methods).kind is Kind.TABLEAU), UNDER_TEST)
    if name not in names(methods):
        raise SceneError(path, "stability.method", f"must be one of {', '.join(names(methods))}", name)
    kind = resolve(name, methods).kind
    if kind is not Kind.TABLEAU:
        raise SceneError(path, "stability.method", f"must be a classical tableau method (the studies use its "
                         f"stability function R(z)); {name!r} is a {kind.value} method", name)
    return name


def scene_points_from_dict(doc: dict, path="<scene>", *, allow_code: bool = True) -> list[Scene]:
    """Validate a parsed scene document: one :class:`Scene` per point of its
    ``[sweep]`` (:mod:`rk4h.validation.sweeps`), or ``[scene]`` without one.
    ``allow_code`` as for :func:`scene_from_dict`."""
    if not allow_code:
        _refuse_code(path, doc)
    if not isinstance(doc, dict) or "sweep" not in doc:
        return [_scene_from_dict(doc, path)]
    _unknown_keys(path, "", doc, set(_schema().TOP_KEYS))
    return sweeps.expand(doc, path, lambda point_doc: _scene_from_dict(point_doc, path))


@functools.cache
def _name_pattern():
    """The scene-name pattern, for ``fullmatch`` (no trailing newline slips through)."""
    return re.compile(_schema().NAME_PATTERN.strip("^$"))


def resolve_scene(arg) -> Path:
    """``--scene`` argument -> file: an existing path as given, else a shipped
    scene named by its ``name`` (``three-blocks``) or file stem (``three_blocks``)."""
    p = Path(arg)
    if _exists(p) or os.sep in str(arg) or str(arg).endswith(".toml"):
        return p
    stem = str(arg).replace("-", "_")
    candidate = SCENE_DIR / f"{stem}.toml"
    if _name_pattern().fullmatch(stem) and len(stem) <= _schema().NAME_MAX and candidate.is_file():
        return candidate
    for f in sorted(SCENE_DIR.glob("*.toml")):
        try:
            if tomllib.loads(f.read_text(encoding="utf-8")).get("name") == arg:
                return f
        except (OSError, tomllib.TOMLDecodeError, UnicodeDecodeError):
            continue
    shipped = ", ".join(sorted(f.stem.replace("_", "-") for f in SCENE_DIR.glob("*.toml")))
    raise SceneError(_show(str(arg)) if len(str(arg)) > 80 else arg, "file",
                     f"is neither a file nor a shipped scene (shipped: {shipped})")


def load_scenes(paths=None, *, quick=False, allow_code=None) -> list[Scene]:
    """Load ``paths`` (default: every ``*.toml`` in :data:`SCENE_DIR`, sorted).

    Returns one :class:`Scene` per sweep point (:mod:`rk4h.validation.sweeps`),
    file by file. A path may also name one point of a shipped scene,
    ``BASE@TOKEN=VALUE...``. With ``quick`` (and no ``paths``), only the files
    marked ``quick = true`` are loaded: the mark is read from each file's TOML
    parse alone, and the other files are not validated, so a broken scene
    outside the subset does not stop a quick run (a file whose mark cannot be
    read is loaded, and refused). Every file loaded is validated before any is
    run; the first bad one raises :class:`SceneError`; two loaded scenes with
    one name (or one figure-file stem) are refused too. ``allow_code`` as for
    :func:`load_scene`.
    """
    if isinstance(paths, (str, Path)):
        paths = [paths]
    allow = code_allowed(allow_code)
    if not paths and quick:
        scenes = [s for f in sorted(SCENE_DIR.glob("*.toml")) if _marked_quick(f)
                  for s in load_scene_points(f, allow_code=allow)]
    elif not paths:
        scenes = [s for f in sorted(SCENE_DIR.glob("*.toml")) for s in load_scene_points(f, allow_code=allow)]
    else:
        scenes = [s for p in paths for s in _load_arg(p, allow)]
    seen = {}
    for s in scenes:
        # figure files are named after the scene's stem (rk4h.validation.figures.slug: '-', '_', '@', '='
        # and '.' alike): those stems must differ too
        key = _figure_stem(s.name)
        if key in seen:
            other, other_name = seen[key]
            also = "" if other_name == s.name else f" as {other_name!r} (figure files would collide)"
            raise SceneError(s.path, "name", f"is also used by {other}{also}", s.name)
        seen[key] = (s.path, s.name)
    if quick and not paths:
        scenes = [s for s in scenes if s.quick]
    return scenes


def _marked_quick(path) -> bool:
    """Whether a scene file is in the ``--quick`` subset, read from its TOML
    parse alone (``quick = true`` at the top). A file that cannot be read or
    parsed, or whose ``quick`` is not a boolean, counts as marked, so that
    loading it raises its own error: what it meant cannot be told."""
    try:
        doc = _read_doc(Path(path))
    except SceneError:
        return True
    flag = doc.get("quick", False)
    return flag is True or not isinstance(flag, bool)


def _exists(p) -> bool:
    """``Path(p).exists()``, False for a name the system refuses (too long...)."""
    try:
        return Path(p).exists()
    except (OSError, ValueError):
        return False


def _load_arg(arg, allow_code=None) -> list[Scene]:
    """The scenes one ``paths`` entry of :func:`load_scenes` stands for."""
    text = str(arg)
    base, at, _ = text.partition("@")
    if at and not _exists(arg) and os.sep not in text and not text.endswith(".toml"):
        try:
            f = resolve_scene(base)
        except SceneError as e:
            raise SceneError(text, "file", f"names no point of a shipped scene: {base!r} {e.problem}") from None
        points = load_scene_points(f, allow_code=allow_code)
        chosen = [s for s in points if s.name == text]
        if not chosen:
            names = ", ".join(s.name for s in points[:3])
            names += f", ... ({len(points)} in all)" if len(points) > 3 else ""
            raise SceneError(f, "name", f"has no point {text!r} (points: {names})")
        return chosen
    return load_scene_points(resolve_scene(arg), allow_code=allow_code)
