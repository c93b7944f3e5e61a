"""Argument validators, kept together. Each raises ``ValueError`` naming the
argument and the offending value, in one line."""
from __future__ import annotations

import math
from numbers import Real

import numpy as np

__all__ = [
    "check_t_span", "check_y0", "check_model_y0", "check_step_args", "check_t_eval", "check_output_times",
    "positive", "finite", "nonnegative", "float_list", "choice", "boolean",
]


def _is_number(x) -> bool:
    return isinstance(x, Real) and not isinstance(x, bool)


def finite(name: str, value) -> float:
    """A finite real number."""
    if not _is_number(value) or not math.isfinite(float(value)):
        raise ValueError(f"`{name}` must be a finite number, got {value!r}")
    return float(value)


def positive(name: str, value) -> float:
    """A finite number > 0."""
    v = finite(name, value)
    if v <= 0.0:
        raise ValueError(f"`{name}` must be > 0, got {value!r}")
    return v


def nonnegative(name: str, value) -> float:
    """A finite number >= 0."""
    v = finite(name, value)
    if v < 0.0:
        raise ValueError(f"`{name}` must be >= 0, got {value!r}")
    return v


def boolean(name: str, value) -> bool:
    if not isinstance(value, (bool, np.bool_)):
        raise ValueError(f"`{name}` must be true or false, got {value!r}")
    return bool(value)


def choice(name: str, value, options) -> str:
    if value not in options:
        raise ValueError(f"`{name}` must be one of {list(options)}, got {value!r}")
    return value


def float_list(name: str, value, *, length: int | None = None, min_length: int = 1,
               positive_items: bool = False) -> np.ndarray:
    """A list of finite numbers (optionally all > 0) of a given length."""
    if isinstance(value, (str, bytes)) or not hasattr(value, "__len__"):
        raise ValueError(f"`{name}` must be a list of numbers, got {value!r}")
    items = list(value)
    if length is not None and len(items) != length:
        raise ValueError(f"`{name}` must have {length} entries, got {len(items)}: {value!r}")
    if len(items) < min_length:
        raise ValueError(f"`{name}` must have at least {min_length} entries, got {len(items)}")
    for i, v in enumerate(items):
        if not _is_number(v) or not math.isfinite(float(v)):
            raise ValueError(f"`{name}[{i}]` must be a finite number, got {v!r}")
        if positive_items and float(v) <= 0.0:
            raise ValueError(f"`{name}[{i}]` must be > 0, got {v!r}")
    return np.asarray(items, dtype=float)


def check_t_span(t_span):
    try:
        t0, t1 = t_span
    except (TypeError, ValueError):
        raise ValueError(f"`t_span` must be a pair (t0, t1), got {t_span!r}") from None
    t0 = finite("t_span[0]", t0)
    t1 = finite("t_span[1]", t1)
    if not t1 > t0:
        raise ValueError(f"`t_span` must have t1 > t0, got {t_span!r}")
    return t0, t1


def check_y0(y0) -> np.ndarray:
    try:
        y = np.array(y0, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"`y0` must be a 1-D array of real numbers, got {y0!r}") from None
    if y.ndim != 1:
        raise ValueError(f"`y0` must be 1-dimensional, got shape {y.shape}")
    if y.size == 0:
        raise ValueError("`y0` must not be empty")
    if not np.all(np.isfinite(y)):
        raise ValueError(f"`y0` must be finite, got {y0!r}")
    return y


def check_model_y0(model, y0) -> np.ndarray:
    """``y0`` as :func:`check_y0`, of the model's length ``2 n_dof`` (``y = [q, v]``)."""
    y = check_y0(y0)
    if y.shape[0] != 2 * model.n_dof:
        raise ValueError(f"`y0` must have length {2 * model.n_dof} (y = [q, v]) for "
                         f"{model.name}, got {y.shape[0]}")
    return y


def check_step_args(t0, t1, h, n_steps, step_count) -> int:
    if (h is None) == (n_steps is None):
        raise ValueError(f"give exactly one of `h` and `n_steps`, got h={h!r}, n_steps={n_steps!r}")
    if h is not None:
        h = positive("h", h)
        return step_count((t0, t1), h)
    if isinstance(n_steps, bool) or not isinstance(n_steps, (int, np.integer)) or n_steps < 1:
        raise ValueError(f"`n_steps` must be an integer >= 1, got {n_steps!r}")
    return int(n_steps)


def check_t_eval(t_eval, t0, t1):
    if t_eval is None:
        return None
    try:
        t = np.asarray(t_eval, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"`t_eval` must be an array of real numbers, got {t_eval!r}") from None
    if t.ndim != 1 or t.size == 0:
        raise ValueError(f"`t_eval` must be a non-empty 1-D array, got shape {t.shape}")
    if not np.all(np.isfinite(t)):
        raise ValueError("`t_eval` must be finite")
    span = t1 - t0
    if t.min() < t0 - 1e-12 * span or t.max() > t1 + 1e-12 * span:
        raise ValueError(f"`t_eval` must lie within `t_span` = ({t0}, {t1})")
    if np.any(np.diff(t) < 0):
        raise ValueError("`t_eval` must be increasing")
    return np.clip(t, t0, t1)


def check_output_times(t_eval) -> np.ndarray:
    """Output times of a solver run: a finite, strictly increasing 1-D array of
    at least 2 times (the first is the initial time)."""
    try:
        t = np.array(t_eval, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"`t_eval` must be an array of real numbers, got {t_eval!r}") from None
    if t.ndim != 1 or t.size < 2:
        raise ValueError(f"`t_eval` must be a 1-D array of at least 2 times, got shape {t.shape}")
    if not np.all(np.isfinite(t)) or not np.all(np.diff(t) > 0):
        raise ValueError("`t_eval` must be finite and strictly increasing")
    return t
