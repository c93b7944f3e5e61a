"""The ``[stability]`` table of a scene: keys, documented bounds, defaults and validation.

Every key has a row in :data:`PARAMS` -- ``(name, type, min, max, default,
unit, meaning)`` -- and :func:`validate_params` checks values against it, so
the table *is* the rule (``params_table_markdown()`` prints it for the
README). Bounds keep every study's work finite and sensible: the boundary
bisection cannot ask for more precision than double round-off allows, the long
run at most ``1e7`` periods, the large-N chains at most ``1e6`` masses, every
list at most :data:`MAX_LIST` entries. A value outside raises one line naming
the field ``stability.<key>`` (see :func:`validate_params`). ``docs/stability-params.md``
is :func:`params_document` (``python -m rk4h.validation.docs_gen`` writes it).
"""
from __future__ import annotations

import math
from collections import namedtuple
from numbers import Real

__all__ = ["STUDIES", "DEFAULTS", "PARAMS", "Param", "MAX_LIST", "validate_params", "pick",
           "params_table_markdown", "StabilityParamError"]

STUDIES = ("boundary", "stiffness", "mass_ratio", "long_horizon", "roundoff", "large_n",
           "amplitude", "singular")

#: Longest list accepted for a list-valued key.
MAX_LIST = 64

Param = namedtuple("Param", "name type min max default unit meaning")

#: Every key: (name, type, min, max, default, unit, meaning). ``*_quick`` values
#: replace the plain ones in --quick runs. ``min``/``max`` bound each number
#: (each entry of a list), both inclusive.
PARAMS = (
    Param("studies", "list[str]", None, None, None, "-",
          f"required: the studies to run, out of {', '.join(STUDIES)}"),
    Param("method", "str", None, None, None, "-",
          "the classical tableau method the studies other than boundary integrate (a built-in such as "
          "rk4 or rk38, or one of the scene's [methods]); default: the first classical tableau of "
          "run.solvers, else rk4"),
    Param("bisection_rtol", "float", 1e-12, 1e-3, 1e-4, "1",
          "relative precision of the bisection for the largest stable step (at most 100 probes)"),
    Param("growth_theta", "list[float]", 1e-4, 4.0,
          [0.25, 0.5, 1.0, 1.5, 1.9, 2.2, 2.6, 2.9, 3.2], "rad",
          "omega_max h of the growth-factor figure (each at most 1000 steps)"),
    Param("target_error", "float", 1e-12, 0.1, 1e-6, "1",
          "stiffness and mass-ratio sweeps: relative error every solver must reach"),
    Param("stiffness_ratios", "list[float]", 1e-8, 1e8, [1.0, 1e2, 1e4, 1e6, 1e8], "1",
          "stiffness of the middle spring / the others (N/m over N/m)"),
    Param("stiffness_ratios_quick", "list[float]", 1e-8, 1e8, [1.0, 1e4, 1e8], "1",
          "the same, --quick"),
    Param("mu", "list[float]", 1e-6, 1e6, [1e-6, 1e-4, 1e-2, 1.0, 1e2, 1e4, 1e6], "1",
          "mass ratio m2/m1 of the two-mass chain"),
    Param("mu_quick", "list[float]", 1e-6, 1e6, [1e-2, 1.0, 1e2], "1", "the same, --quick"),
    Param("long_theta", "float", 1e-3, 2.5, 0.2, "rad", "omega_max h of the long RK4 run"),
    Param("long_periods", "float", 1.0, 1e7, 1e6, "periods",
          "length of the long RK4 run and of the heyoka run, in periods of the slowest mode"),
    Param("long_periods_quick", "float", 1.0, 1e7, 1e3, "periods", "the same, --quick"),
    Param("reference_periods", "float", 1.0, 1e5, 200.0, "periods",
          "length of the CVODE-BDF run on the long horizon (at most long_periods; heyoka covers "
          "long_periods): about 8 ms of CPU per period of the 2-DOF case at rtol 1e-10, under 2 s by default"),
    Param("reference_periods_quick", "float", 1.0, 1e5, 20.0, "periods", "the same, --quick"),
    Param("drift_theta", "list[float]", 1e-3, 2.5, [0.05, 0.1, 0.2, 0.3, 0.4, 0.5], "rad",
          "omega_max h of the 2000-step drift and phase measurements"),
    Param("roundoff_theta", "list[float]", 1e-5, 1.0,
          [0.5, 0.2, 0.1, 0.05, 0.02, 1e-2, 5e-3, 2e-3, 1e-3, 5e-4, 2e-4], "rad",
          "omega_max h of the round-off sweep (one slow period each)"),
    Param("roundoff_theta_quick", "list[float]", 1e-5, 1.0,
          [0.5, 0.2, 0.1, 0.05, 0.02, 1e-2, 5e-3, 2e-3, 1e-3], "rad", "the same, --quick"),
    Param("n_values", "list[int]", 2, 1_000_000, [3e3, 1e4, 3e4, 1e5], "masses",
          "chain sizes of the large-N study (fits start above the cache-resident sizes)"),
    Param("n_values_quick", "list[int]", 2, 1_000_000, [3e3, 1e4, 3e4], "masses", "the same, --quick"),
    Param("amplitudes", "list[float]", 1e-8, 10.0,
          [1e-6, 1e-5, 1e-4, 1e-3, 1e-2, 3e-2, 0.1, 0.3, 1.0, 2.0, 3.0], "l",
          "planar4 initial displacements, in units of the natural length l"),
    Param("singular_offset", "float", 1e-15, 1.0, 1e-9, "m",
          "y offset of the planar4 mass aimed at the anchor (l, 0)"),
)
_BY_NAME = {p.name: p for p in PARAMS}

#: Every key and its default (``studies`` has none: it is required).
DEFAULTS = {p.name: p.default for p in PARAMS}


class StabilityParamError(ValueError):
    """A bad ``[stability]`` value, in one line.

    Attributes
    ----------
    key : str
        The key inside the table (``bisection_rtol``).
    field : str
        ``stability.<key>``.
    problem : str
        What is wrong (``must lie in [1e-12, 0.001]``).
    value : object
        The value given (None when there is none).
    """

    def __init__(self, where: str, key: str, problem: str, value=None, has_value=True):
        self.key, self.field, self.problem, self.value = key, f"stability.{key}", problem, value
        got = f", got {value!r}" if has_value else ""
        # Called by rk4h.validation.scenes with the file as ``where``: it prefixes the
        # field with "stability." itself ("FILE: field `stability.KEY`: problem
        # (got VALUE)"), so the message names the key alone. Otherwise ``where``
        # is the prefix of the field ("stability" by default).
        name = f"{where}.{key}" if _is_prefix(where) else key
        super().__init__(f"`{name}` {problem}{got}")


def _is_prefix(where: str) -> bool:
    return str(where).rstrip().endswith("stability")


def _is_num(x) -> bool:
    return isinstance(x, Real) and not isinstance(x, bool)


def _fmt(x) -> str:
    if not isinstance(x, float):
        return str(x)
    return f"{x:g}".replace("e+0", "e").replace("e+", "e").replace("e-0", "e-")


def _check_number(where, key, value, p: Param, shown=None):
    shown = value if shown is None else shown
    if not _is_num(value):
        raise StabilityParamError(where, key, "must be a number", shown)
    try:
        v = float(value)
    except OverflowError:
        raise StabilityParamError(where, key, "must be finite (it exceeds the double range)", shown) from None
    if not math.isfinite(v):
        raise StabilityParamError(where, key, "must be finite", shown)
    if p.type == "list[int]" and v != math.floor(v):
        raise StabilityParamError(where, key, "must hold whole numbers", shown)
    if not p.min <= v <= p.max:
        unit = "" if p.unit in ("1", "-") else f" {p.unit}"
        raise StabilityParamError(where, key, f"must lie in [{_fmt(p.min)}, {_fmt(p.max)}]{unit}", shown)
    return v


def validate_params(params, where: str = "stability") -> dict:
    """Check a scene's ``[stability]`` table against :data:`PARAMS` and fill in
    defaults.

    Parameters
    ----------
    params : dict
        The table as read from TOML.
    where : str
        Prefix of the field names in messages (default ``"stability"``: a bad
        value raises "`stability.bisection_rtol` must lie in [1e-12, 0.001],
        got 1e-300"). :mod:`rk4h.validation.scenes` passes the scene file here and
        prefixes ``stability.`` itself, so its one-line error reads ``FILE:
        field `stability.bisection_rtol`: must lie in ... (got 1e-300)``.

    Returns
    -------
    dict
        Every key of :data:`DEFAULTS`, numbers as floats.

    Raises
    ------
    StabilityParamError
        (a ``ValueError``) naming the key and the value: unknown keys, unknown
        study names, wrong types, values outside the bounds of :data:`PARAMS`,
        lists longer than :data:`MAX_LIST`.
    """
    if not isinstance(params, dict):
        raise ValueError(f"`{where}` must be a table, got {params!r}")
    unknown = sorted(set(params) - set(DEFAULTS))
    if unknown:
        raise StabilityParamError(where, unknown[0], f"is not a known key (known: {', '.join(DEFAULTS)})",
                                  has_value=False)
    if "studies" not in params:
        raise StabilityParamError(where, "studies", f"is required (a list out of {list(STUDIES)})",
                                  has_value=False)
    out = dict(DEFAULTS)
    studies = params["studies"]
    if isinstance(studies, str) or not isinstance(studies, list) or not studies:
        raise StabilityParamError(where, "studies", "must be a non-empty list", studies)
    for s in studies:
        if s not in STUDIES:
            raise StabilityParamError(where, "studies", f"entries must be among {list(STUDIES)}", s)
    if len(set(studies)) != len(studies):
        raise StabilityParamError(where, "studies", "lists a study twice", studies)
    out["studies"] = list(studies)
    for key, value in params.items():
        if key == "studies":
            continue
        p = _BY_NAME[key]
        if p.type == "str":
            if not isinstance(value, str) or not value:
                raise StabilityParamError(where, key, "must be a non-empty string", value)
            out[key] = value
            continue
        if p.type.startswith("list"):
            if isinstance(value, (str, bytes)) or not isinstance(value, (list, tuple)):
                raise StabilityParamError(where, key, "must be a list of numbers", value)
            if not 1 <= len(value) <= MAX_LIST:
                raise StabilityParamError(where, key, f"must have 1 to {MAX_LIST} entries", len(value))
            out[key] = [_check_number(where, f"{key}[{i}]", v, p) for i, v in enumerate(value)]
        else:
            out[key] = _check_number(where, key, value, p)
    return out


def pick(params: dict, key: str, quick: bool):
    """The ``key_quick`` value in quick mode when there is one, else ``key``."""
    return params.get(f"{key}_quick", params[key]) if quick else params[key]


def params_table_markdown() -> str:
    """:data:`PARAMS` as a Markdown table (key, type, range, default, unit, meaning)."""
    lines = ["| key | type | range | default | unit | meaning |", "|---|---|---|---|---|---|"]
    for p in PARAMS:
        rng = "-" if p.min is None else f"{_fmt(p.min)} ... {_fmt(p.max)}"
        default = ("(required)" if p.name == "studies" else "(see meaning)") if p.default is None else (
            ", ".join(_fmt(v) for v in p.default) if isinstance(p.default, list) else _fmt(p.default))
        lines.append(f"| `{p.name}` | {p.type} | {rng} | {default} | {p.unit} | {p.meaning} |")
    return "\n".join(lines)


def params_document() -> str:
    """The text of ``docs/stability-params.md`` (generated; a test keeps it current)."""
    return ("# `[stability]` keys of a scene\n\n"
            "Generated from `rk4h.validation.stability.params.PARAMS` by "
            "`python -m rk4h.validation.stability.params > docs/stability-params.md`; "
            "`tests/test_hostile_references.py` checks it is current. A value outside its range "
            "is refused with one line naming `stability.<key>` (exit 2).\n\n"
            + params_table_markdown() + "\n")


if __name__ == "__main__":
    import sys

    sys.stdout.write(params_document())
