"""Sweeps: a scene file that stands for one scene per point of a parameter grid.

:func:`expand` turns a scene document holding ``[sweep]`` into one scene per
point; :func:`rk4h.validation.scenes.scene_points_from_dict` and the scene loaders
call it, handing it the validation of one unswept document.

An optional ``[sweep]`` table makes the file stand for one scene per point of
a parameter grid::

    [sweep]
    "params.masses[1]" = [0.0815, 0.815, 3.099, 8.15]
    "run.t_end" = [5.0, 10.0]

Each key is a quoted dotted path into the scene document, each value a
non-empty list of values; the points are the Cartesian product of the lists,
in key order as written (the first key varies slowest, like nested loops).
A path is ``TABLE.NAME`` followed by any number of ``[i]`` (a 0-based index
into a list written in the file) and ``.KEY`` (a key of a table written in the
file, e.g. ``params.constants.w`` of the ``potential`` model). Sweepable:

* ``params.NAME``: any parameter of the scene's model, written in the file or
  not (``params.alpha`` of a chain sets the default 0 to each value);
* ``initial.x``, ``initial.v``, ``initial.mode``, ``initial.amplitude``
  (``initial.x[0]`` sweeps one coordinate; ``initial.amplitude`` goes with
  ``mode``);
* ``run.t_end``. The other ``[run]`` keys are not: ``h``, ``tolerances``,
  ``solvers`` and ``outputs`` are already lists every point runs over, and
  ``output_dt``/``max_output_points`` set the grid, not the physics. Nor are
  ``name``, ``model``, ``quick``, ``[convergence]`` and ``[stability]``.

A value is a number, ``true``/``false`` or a string (a word of ``a-z 0-9 _ . -``,
since it appears in the point's name): one value per point, so a list
parameter is swept element by element through its indices (this keeps every
sweep column a scalar). A list may not hold one value twice; at most
:data:`MAX_SWEEP_POINTS` points. Refused with one line naming the key
(``FILE: field `sweep."params.nope"`: ...``): a key that is not a string
path, an unknown table, an unknown parameter of the model, an index out of
range or into something that is not a list, a path through something the file
does not hold, an empty or non-list value, and two keys of which one contains
the other or which share a column or a name token.

Each point is the document with every swept path set to the point's value and
the ``[sweep]`` table dropped, validated by :func:`rk4h.validation.scenes.scene_from_dict` as an
ordinary scene: every rule above holds for every point, and an error names
the first point that fails, e.g. ``FILE: field `sweep."params.masses[1]"[2]`:
at params.masses[1] = -1.0: field `params.masses[1]`: must be > 0 (got
-1.0)``; an error that every point of a sweep of several shares word for word
(``run.solvers[1]``, a missing ``name``) is the file's and reads as it would
without the sweep.
``quick = true`` marks every point. A point's :class:`rk4h.validation.scenes.Scene` has

* ``base``: the ``name`` written in the file (for an unswept scene, its name);
* ``sweep``: column -> value, in key order (empty for an unswept scene). The
  column is the path without its table: ``masses[1]``, ``x[0]``,
  ``amplitude``, ``k``, ``t_end``, ``constants.w``. Values are as written in
  the file (int, float, bool or str).
* ``name``: ``BASE@TOKEN=VALUE``, once per key in key order, e.g.
  ``sweep-2dof-mass-ratio@masses1=0.815``. ``TOKEN`` is the column lowercased
  with its brackets dropped (``x[0]`` -> ``x0``, ``springs[1][2]`` ->
  ``springs1_2``); ``VALUE`` is ``true``/``false``, the string, or the number
  printed with ``:g``, with ``repr`` instead for values of one key that print
  alike under ``:g`` (``1.0000001`` and ``1.0000002``), a leading minus written
  ``m`` and an exponent's ``+`` dropped (``-0.5`` -> ``m0.5``, ``1e+06`` ->
  ``1e06``, ``1e-06`` stays): figure files are named after
  ``rk4h.validation.figures.slug(name)``, which turns every run of characters other
  than ``a-z0-9`` into ``_``, so ``=-0.5`` and ``=0.5`` would collide. Point
  names are unique within the file, also as figure-file stems (checked), at
  most :data:`_POINT_NAME_MAX` characters, and never match the rule for names
  in files (they hold ``@``), so a point cannot shadow a file's scene.

The points' untimed fixed-step runs that share method, step and grid run as
one batch (:mod:`rk4h.validation.sweep_batch`), each record bit for bit the
one its point makes alone.
"""
from __future__ import annotations

import copy
import functools
import itertools
import math
import re
from dataclasses import dataclass

from .scene_checks import Raw as _Raw
from .scene_checks import SceneError
from .scene_checks import check_model as _check_model
from .scene_checks import figure_stem as _figure_stem
from .scene_checks import is_num as _is_num
from .scene_checks import model_keys as _model_keys
from .scene_checks import show as _show

__all__ = ["expand", "MAX_SWEEP_POINTS", "SWEEP_RUN_KEYS"]

#: Most points one ``[sweep]`` may give (each is validated, then run, as a scene).
MAX_SWEEP_POINTS = 1000
#: The ``[run]`` keys a sweep may set.
SWEEP_RUN_KEYS = ("t_end",)
#: Longest point name ``BASE@TOKEN=VALUE...`` (file-name stems stay well below 255 bytes).
_POINT_NAME_MAX = 200
_POINT_NAME = re.compile(r"[a-z0-9][a-z0-9_-]*(?:@[a-z0-9_.]+=[a-z0-9_.-]+)+")


@functools.cache
def _patterns():
    """``(IDENT, path pattern, step pattern, word pattern, initial keys)`` of a
    ``[sweep]`` key, from the scene schema, imported on first use: it loads
    pydantic, which a process that only receives scenes never needs."""
    from . import scene_schema

    ident = scene_schema.IDENT
    return (ident, re.compile(rf"({ident})((?:\.{ident}|\[(?:0|[1-9][0-9]*)\])+)"),
            re.compile(rf"\.({ident})|\[(0|[1-9][0-9]*)\]"), re.compile(scene_schema.WORD),
            set(scene_schema.INITIAL_KEYS))


# -- expansion --------------------------------------------------------------------
@dataclass(frozen=True)
class _Axis:
    """One ``[sweep]`` key: where it points, its values and how a point names it."""

    key: str
    field: str        # sweep."KEY", as error messages name it
    table: str        # params / initial / run
    steps: tuple      # ((is_index, name_or_index), ...) below the table
    column: str       # the key without its table: masses[1]
    token: str        # the column in a point name: masses1
    values: tuple


def expand(doc: dict, path, validate) -> list:
    """The scenes of a document with a ``[sweep]`` table, one per point (module
    docstring).

    Parameters
    ----------
    doc : dict
        The parsed scene document, holding ``sweep`` (its other top-level keys
        already checked by the caller).
    path : str or Path
        The file (or ``"<scene>"``) that error lines name.
    validate : callable
        ``validate(point_doc) -> Scene``: an unswept document validated as a
        scene (:func:`rk4h.validation.scenes.scene_from_dict`); raises
        :class:`~rk4h.validation.scene_checks.SceneError`.

    Returns
    -------
    list of Scene
        In grid order (the first key varies slowest), each with ``base``,
        ``name`` and ``sweep`` set for its point.
    """
    axes = _sweep_axes(path, doc)
    n_points = math.prod(len(a.values) for a in axes)
    if n_points > MAX_SWEEP_POINTS:
        raise SceneError(path, "sweep", f"gives {n_points} points, above the cap of {MAX_SWEEP_POINTS}")
    base_doc = {k: v for k, v in doc.items() if k != "sweep"}

    def point(idx):
        point_doc = copy.deepcopy(base_doc)
        for a, i in zip(axes, idx):
            _set_path(point_doc[a.table], a.steps, a.values[i])
        return validate(point_doc)

    grid = list(itertools.product(*(range(len(a.values)) for a in axes)))
    scenes = []
    for idx in grid:
        try:
            scenes.append(point(idx))
        except SceneError as e:
            raise _point_error(path, axes, grid, idx, e, point) from None
    labels = [_labels(path, a) for a in axes]
    names, stems = {}, {}
    for scene, idx in zip(scenes, grid):
        name = scene.name + "".join(f"@{a.token}={lab[i]}" for a, lab, i in zip(axes, labels, idx))
        where = ", ".join(f"{a.field}[{i}]" for a, i in zip(axes, idx))
        if len(name) > _POINT_NAME_MAX or not _POINT_NAME.fullmatch(name):
            raise SceneError(path, where, f"gives the point name {name!r}, which is not 1 to {_POINT_NAME_MAX} "
                             f"characters of the form BASE@TOKEN=VALUE")
        stem = _figure_stem(name)
        for seen, key in ((names, name), (stems, stem)):
            if key in seen:
                raise SceneError(path, where, f"gives the point name {name!r}, which {seen[key]} gives too"
                                 + ("" if seen is names else " as a figure-file stem"))
            seen[key] = where
        scenes_sweep = {a.column: a.values[i] for a, i in zip(axes, idx)}
        scene.base, scene.name, scene.sweep = scene.name, name, scenes_sweep
    return scenes


def _point_error(path, axes, grid, idx, err: SceneError, point) -> SceneError:
    """The error of the first failing point ``idx``, naming the point; an error
    every point of a sweep of several shares (the same line) is the file's own
    and is returned as it is."""
    if len(grid) > 1 and all(_fails_alike(point, other, str(err)) for other in grid if other != idx):
        return err
    where = ", ".join(f"{a.field}[{i}]" for a, i in zip(axes, idx))
    at = ", ".join(f"{a.key} = {_show(a.values[i])}" for a, i in zip(axes, idx))
    return SceneError(path, where, f"at {at}: field `{err.field}`: {err.problem}",
                      None if err.value is None else _Raw(_show(err.value)))


def _fails_alike(point, idx, message) -> bool:
    try:
        point(idx)
    except SceneError as e:
        return str(e) == message
    return False


def _key_field(key) -> str:
    if isinstance(key, str) and key.isprintable() and '"' not in key and '`' not in key and len(key) <= 80:
        return f'sweep."{key}"'
    return f"sweep.{_show(key)}"


def _sweep_axes(path, doc) -> list[_Axis]:
    _IDENT, _SWEEP_PATH, _SWEEP_STEP, _WORD, _ = _patterns()
    sweep = doc["sweep"]
    if not isinstance(sweep, dict):
        raise SceneError(path, "sweep", 'must be a table of "PATH" = [values]', sweep)
    if not sweep:
        raise SceneError(path, "sweep", 'is empty: give at least one "PATH" = [values], '
                         'e.g. "params.k" = [1.0, 2.0]')
    if "model" not in doc:
        raise SceneError(path, "model", "is missing")
    _check_model(path, doc["model"])
    axes = []
    for key, values in sweep.items():
        fld = _key_field(key)
        if not isinstance(key, str):
            raise SceneError(path, fld, 'must be a string path such as "params.k"')
        if isinstance(values, dict) and re.fullmatch(_IDENT, key):
            raise SceneError(path, fld, f'is a table of its own: quote the dotted path, "{key}.NAME" = [values] '
                             f"(unquoted, TOML reads {key}.NAME as nested tables)")
        m = _SWEEP_PATH.fullmatch(key)
        if not m:
            raise SceneError(path, fld, 'must be a dotted path such as "params.k", "initial.x[0]" or "run.t_end"')
        table = m.group(1)
        steps = tuple((g[1] != "", int(g[1]) if g[1] else g[0]) for g in _SWEEP_STEP.findall(m.group(2)))
        _check_target(path, fld, doc, key, table, steps)
        if not isinstance(values, list):
            raise SceneError(path, fld, "must be a list of values, one per point", values)
        if not values:
            raise SceneError(path, fld, "must not be empty", values)
        seen = {}
        for i, v in enumerate(values):
            if isinstance(v, bool):
                kind = "bool"
            elif isinstance(v, str):
                kind = "str"
                if not _WORD.fullmatch(v):
                    raise SceneError(path, f"{fld}[{i}]", "must be a word of a-z, 0-9, '_', '.', '-' (at most 40 "
                                     "characters): it appears in the point's name", v)
            elif _is_num(v):
                kind = "num"
            else:
                raise SceneError(path, f"{fld}[{i}]", "must be a number, true/false or a string: one value per "
                                 "point (sweep a list element by element through its index)", v)
            if (kind, v) in seen:
                raise SceneError(path, f"{fld}[{i}]", f"repeats {fld}[{seen[(kind, v)]}]", v)
            seen[(kind, v)] = i
        column = key[len(table) + 1:]
        token = re.sub(r"[\[\]]", "", column.replace("][", "_")).lower()
        axis = _Axis(key, fld, table, steps, column, token, tuple(values))
        for other in axes:
            short, long_ = sorted((other.steps, steps), key=len)
            if other.table == table and long_[:len(short)] == short:
                raise SceneError(path, fld, f"overlaps {other.field}: one sets a part of the other")
            for what in ("column", "token"):
                if getattr(other, what) == getattr(axis, what):
                    raise SceneError(path, fld, f"gives the {what} `{getattr(axis, what)}` of {other.field} too")
        axes.append(axis)
    return axes


def _check_target(path, fld, doc, key, table, steps):
    """Refuse a path that does not address a sweepable place of ``doc``."""
    _INITIAL = _patterns()[4]
    allowed = {"params": None, "initial": _INITIAL, "run": set(SWEEP_RUN_KEYS)}
    if table not in allowed:
        run_keys = SWEEP_RUN_KEYS[0] if len(SWEEP_RUN_KEYS) == 1 else f"{{{', '.join(SWEEP_RUN_KEYS)}}}"
        raise SceneError(path, fld, f"addresses `{table}`, which cannot be swept (sweepable: params.*, "
                         f"initial.{{{', '.join(sorted(_INITIAL))}}}, run.{run_keys})")
    is_index, name = steps[0]
    if is_index:  # "params[0]"
        raise SceneError(path, fld, f"must name a key of `{table}` before an index")
    if table == "params":
        known, what = _model_keys(doc["model"]), f"a parameter of model {doc['model']!r}"
    else:
        known, what = allowed[table], f"a sweepable key of `{table}`"
    if name not in known:
        raise SceneError(path, fld, f"`{table}.{name}` is not {what} (known: {', '.join(sorted(known))})")
    node = doc.get(table)
    if not isinstance(node, dict):
        raise SceneError(path, fld, f"addresses `{table}`, which the file does not hold as a table", node)
    where = table
    for j, (is_index, step) in enumerate(steps):
        last = j == len(steps) - 1
        if is_index:
            if not isinstance(node, list):
                raise SceneError(path, fld, f"indexes `{where}`, which is not a list", node)
            if step >= len(node):
                raise SceneError(path, fld, f"index {step} is out of range: `{where}` has {len(node)} "
                                 f"entr{'y' if len(node) == 1 else 'ies'}")
            where = f"{where}[{step}]"
        else:
            if not isinstance(node, dict):
                raise SceneError(path, fld, f"reads the key `{step}` of `{where}`, which is not a table", node)
            if step not in node and not (j == 0 and last):
                raise SceneError(path, fld, f"`{where}.{step}` is not in the file (only a top-level key of "
                                 f"`{table}` may be swept without being written)")
            where = f"{where}.{step}"
        if not last:
            node = node[step]


def _set_path(node, steps, value):
    for _, step in steps[:-1]:
        node = node[step]
    node[steps[-1][1]] = value


def _labels(path, axis: _Axis) -> list[str]:
    """How each value of ``axis`` appears in a point name (module docstring)."""
    def text(v, precise):
        if isinstance(v, bool):
            return "true" if v else "false"
        if isinstance(v, str):
            return v
        if not precise:
            try:
                return f"{v:g}"
            except OverflowError:  # an int beyond the double range
                pass
        return repr(v)

    rough = [text(v, False) for v in axis.values]
    nums = [i for i, v in enumerate(axis.values) if _is_num(v)]
    alike = {i for i in nums if sum(rough[j] == rough[i] for j in nums) > 1}
    labels = []
    for i, v in enumerate(axis.values):
        lab = text(v, i in alike)
        if _is_num(v):
            lab = lab.replace("e+", "e")
            if lab.startswith("-"):
                lab = "m" + lab[1:]
        labels.append(lab)
    return labels
