"""Argument validators, kept together. Each raises ``ValueError`` naming the
argument and the offending value, in one line.

Size caps of the fixed-step integrators (:func:`rk4h.solve`,
:func:`rk4h.fast.solve_model`), checked before anything is allocated:

* :data:`MAX_STEPS` -- at most ``10**10`` steps per run;
* :data:`MAX_OUTPUT_BYTES` -- the output array (rows x components x 8 bytes
  per real component, 16 per complex one) at most ``2**33`` bytes (8 GiB).
"""
from __future__ import annotations

import math
from numbers import Complex, Number, Real

import numpy as np

__all__ = [
    "check_t_span", "check_y0", "check_model_y0", "check_step_args", "check_step_sign", "check_t_eval",
    "check_output_times",
    "check_output_size", "check_max_growth", "check_y_scale", "MAX_STEPS", "MAX_OUTPUT_BYTES",
    "positive", "finite", "nonnegative", "float_list", "choice", "boolean",
]

#: Largest number of fixed steps one run may take (a run of 1e10 RK4 steps
#: already takes minutes compiled and hours in Python).
MAX_STEPS = 10**10
#: Largest output array one run may allocate, in bytes (8 GiB): rows (output
#: times) x state components x 8 bytes (16 for a complex state).
MAX_OUTPUT_BYTES = 2**33


def _is_number(x) -> bool:
    return isinstance(x, Real) and not isinstance(x, bool)


def _finite_number(x) -> bool:
    """A real number (no bool) whose float is finite (an int beyond float's range is not)."""
    try:
        return _is_number(x) and math.isfinite(float(x))
    except OverflowError:
        return False


def finite(name: str, value) -> float:
    """A finite real number."""
    if not _finite_number(value):
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
    arr = _plain_numbers(value)
    if arr is not None and (length is None or arr.shape[0] == length) and arr.shape[0] >= min_length \
            and np.isfinite(arr).all() and (not positive_items or (arr > 0.0).all()):
        return arr  # what the loop below returns, checked in bulk (a long chain's list)
    items = list(value)
    if length is not None and len(items) != length:
        raise ValueError(f"`{name}` must have {length} entries, got {len(items)}: {value!r}")
    if len(items) < min_length:
        raise ValueError(f"`{name}` must have at least {min_length} entries, got {len(items)}")
    for i, v in enumerate(items):
        if not _finite_number(v):
            raise ValueError(f"`{name}[{i}]` must be a finite number, got {v!r}")
        if positive_items and float(v) <= 0.0:
            raise ValueError(f"`{name}[{i}]` must be > 0, got {v!r}")
    return np.asarray(items, dtype=float)


def _plain_numbers(value):
    """``value`` as a float array when it is a list of Python ints and floats
    (no bool) or a 1-D integer or float64 (or narrower) numpy array (not a
    subclass), else None (the items are checked one by one)."""
    if type(value) is list:
        if not set(map(type, value)) <= {float, int}:
            return None
    elif not (type(value) is np.ndarray and value.ndim == 1  # no subclass: a masked array's data is not its values
              and (value.dtype.kind in "iu" or (value.dtype.kind == "f" and value.dtype.itemsize <= 8))):
        return None
    try:
        return np.array(value, dtype=float)
    except OverflowError:  # an int beyond float's range: the loop below says which
        return None


def check_t_span(t_span, *, allow_backward: bool = False):
    """``(t0, t1)`` as two finite floats whose difference is finite.

    ``t1 > t0`` is required unless ``allow_backward`` (:func:`rk4h.solve`:
    ``t1 < t0`` integrates backward, ``t1 == t0`` integrates nothing, as in
    ``scipy.integrate.solve_ivp``)."""
    try:
        t0, t1 = t_span
    except (TypeError, ValueError):
        raise ValueError(f"`t_span` must be a pair (t0, t1), got {t_span!r}") from None
    t0 = finite("t_span[0]", t0)
    t1 = finite("t_span[1]", t1)
    if not allow_backward and not t1 > t0:
        raise ValueError(f"`t_span` must have t1 > t0, got {t_span!r}")
    if not math.isfinite(t1 - t0):
        raise ValueError(f"`t_span` = ({t0!r}, {t1!r}) is too wide: t1 - t0 overflows float64")
    return t0, t1


def short(value, limit=80) -> str:
    """``repr(value)`` on one line, cut to ``limit`` characters (``...``):
    how a refusal quotes the value it refuses."""
    text = repr(value).replace("\n", " ")
    return text if len(text) <= limit else text[: limit - 3] + "..."



def check_y0(y0, *, allow_complex: bool = False) -> np.ndarray:
    """The initial state: a non-empty, finite 1-D array of numbers.

    Returns a new float64 array, or complex128 when ``allow_complex`` and
    any entry is complex (the imaginary part is kept, as in
    ``scipy.integrate.solve_ivp``). Strings, booleans and other non-numbers
    are refused whatever the container (list, tuple, ndarray); complex values
    are refused unless ``allow_complex``.
    """
    if type(y0) is np.ndarray and y0.dtype == np.float64 and y0.ndim == 1 and y0.size:
        y = y0.copy()  # the common case, checked whole; a bad entry: the general path's message
        if np.isfinite(y).all():
            return y
    kind = "real or complex numbers" if allow_complex else "real numbers"
    if isinstance(y0, (str, bytes)):
        raise ValueError(f"`y0` must be a 1-D array of {kind}, got the string {short(y0)}")
    if isinstance(y0, (list, tuple)):
        for i, v in enumerate(y0):
            if isinstance(v, (bool, np.bool_)):
                raise ValueError(f"`y0` must be a 1-D array of {kind}, got the boolean y0[{i}] = {v!r}")
    try:
        raw = np.asarray(y0)
    except (TypeError, ValueError, OverflowError):
        raise ValueError(f"`y0` must be a 1-D array of {kind}, got {short(y0)}") from None
    if raw.dtype.kind == "O":  # mixed or exotic entries: each must be a number
        flat = raw.ravel()
        for v in flat:
            if not isinstance(v, Number) or isinstance(v, (bool, np.bool_)):
                raise ValueError(f"`y0` must be a 1-D array of {kind}, got an entry {short(v)}")
        cplx = any(isinstance(v, Complex) and not isinstance(v, Real) for v in flat)
    elif raw.dtype.kind in "iuf":
        cplx = False
    elif raw.dtype.kind == "c":
        cplx = True
    else:  # b (bool), U/S (text), V, M/m (dates)...
        raise ValueError(f"`y0` must be a 1-D array of {kind}, got dtype {raw.dtype} ({short(y0)})")
    if cplx and not allow_complex:
        raise ValueError(f"`y0` must be real here, got complex values ({short(y0)}); only "
                         f"rk4h.solve integrates a complex state")
    try:
        y = np.array(raw, dtype=np.complex128 if cplx else np.float64)
    except (TypeError, ValueError, OverflowError):
        raise ValueError(f"`y0` must be a 1-D array of {kind}, got {short(y0)}") from None
    if y.ndim != 1:
        raise ValueError(f"`y0` must be 1-dimensional, got shape {y.shape}")
    if y.size == 0:
        raise ValueError("`y0` must not be empty")
    if not np.all(np.isfinite(y)):
        raise ValueError(f"`y0` must be finite, got {short(y0)}")
    return y


def check_model_y0(model, y0) -> np.ndarray:
    """``y0`` as :func:`check_y0` (real only: a complex ``y0`` is refused
    whatever its container), of the model's length ``2 n_dof`` (``y = [q, v]``),
    or ``n_state`` for a first-order model (``model.first_order``: the state is ``y``)."""
    y = check_y0(y0, allow_complex=False)
    if getattr(model, "first_order", False):
        if y.shape[0] != model.n_state:
            raise ValueError(f"`y0` must have length {model.n_state} (one entry per variable) for "
                             f"{model.name}, got {y.shape[0]}")
        return y
    if y.shape[0] != 2 * model.n_dof:
        raise ValueError(f"`y0` must have length {2 * model.n_dof} (y = [q, v]) for "
                         f"{model.name}, got {y.shape[0]}")
    return y


def check_step_args(t0, t1, h, n_steps, step_count) -> int:
    """The number of steps from exactly one of ``h`` (``step_count((t0, t1), h)``)
    and ``n_steps``, at most :data:`MAX_STEPS`.

    ``h`` is the step's magnitude (> 0); for a backward span (``t1 < t0``)
    the count is ``step_count((t0, t1), -h)``. A signed ``h`` is first
    resolved by :func:`check_step_sign`."""
    if (h is None) == (n_steps is None):
        raise ValueError(f"give exactly one of `h` and `n_steps`, got h={h!r}, n_steps={n_steps!r}")
    if h is not None:
        h = positive("h", h)
        ratio = abs(t1 - t0) / h  # may overflow to inf for a subnormal h
        if not ratio <= MAX_STEPS:
            raise ValueError(f"`h` = {h!r} implies {ratio:.3g} steps over t_span = ({t0!r}, {t1!r}), "
                             f"more than MAX_STEPS = {MAX_STEPS:.0e}; use a larger h")
        return step_count((t0, t1), h if t1 >= t0 else -h)
    if isinstance(n_steps, bool) or not isinstance(n_steps, (int, np.integer)) or n_steps < 1:
        raise ValueError(f"`n_steps` must be an integer >= 1, got {n_steps!r}")
    if n_steps > MAX_STEPS:
        raise ValueError(f"`n_steps` = {n_steps!r} is more than MAX_STEPS = {MAX_STEPS:.0e}")
    return int(n_steps)


def check_step_sign(h, t0, t1):
    """``h`` of :func:`rk4h.solve` as the step's magnitude.

    ``h > 0`` is the magnitude whatever the direction of ``t_span``; a
    negative ``h`` is accepted when it matches a backward span (``t1 < t0``)
    or an empty one (``t1 == t0``) and refused, naming ``h``, when it
    contradicts a forward one. Anything that is not a real number is passed
    on unchanged (:func:`check_step_args` refuses it naming ``h``)."""
    if not _finite_number(h) or not float(h) < 0.0:
        return h
    if t1 > t0:
        raise ValueError(f"`h` = {h!r} is negative but t_span = ({t0!r}, {t1!r}) runs forward (t1 > t0); "
                         f"give h > 0 (the step's magnitude) or a negative h only for t1 < t0")
    return -float(h)


def check_output_size(name: str, value, rows: int, n_components: int, itemsize: int = 8) -> None:
    """Refuse an output array of ``rows x n_components x itemsize`` bytes
    above :data:`MAX_OUTPUT_BYTES`, naming the argument ``name`` (= ``value``)
    that sets the number of rows (a ``str`` value is shown as is)."""
    size = int(rows) * int(n_components) * int(itemsize)
    if size > MAX_OUTPUT_BYTES:
        shown = value if isinstance(value, str) else short(value, 40)
        raise ValueError(f"`{name}` = {shown} implies an output of {rows} rows x {n_components} "
                         f"components x {itemsize} bytes = {size / 2**30:.3g} GiB, over the "
                         f"MAX_OUTPUT_BYTES = 2**33 bytes (8 GiB) cap; keep fewer output times "
                         f"(t_eval, or record_every on the fast path)")


def check_max_growth(value) -> float | None:
    """``max_growth``: None (growth test off) or a finite number >= 1."""
    if value is None:
        return None
    v = finite("max_growth", value)
    if not v >= 1.0:
        raise ValueError(f"`max_growth` must be >= 1 (or None to disable the growth test), got {value!r}")
    return v


def check_y_scale(value, n: int) -> np.ndarray | None:
    """``y_scale``: None, or ``n`` positive finite per-component scales."""
    if value is None:
        return None
    if isinstance(value, (str, bytes)) or not hasattr(value, "__len__"):
        raise ValueError(f"`y_scale` must be a list of {n} positive numbers, got {short(value)}")
    if len(value) != n:
        raise ValueError(f"`y_scale` must have {n} entries (one per state component), got {len(value)}")
    if isinstance(value, np.ndarray) and value.dtype == np.float64 and value.ndim == 1:
        # the common case (a solver's own scale) checked whole; any bad entry: the itemwise message
        if np.isfinite(value).all() and (value > 0.0).all():
            return value.copy()
    return float_list("y_scale", value, length=n, positive_items=True)


def check_t_eval(t_eval, t0, t1):
    """Output times inside ``t_span`` (a relative slack of 1e-12 of its
    width, then clipped to it), non-decreasing for ``t1 >= t0`` and
    non-increasing for a backward span ``t1 < t0`` (as in ``solve_ivp``,
    which also wants them sorted in the direction of integration)."""
    if t_eval is None:
        return None
    try:
        t = np.asarray(t_eval, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"`t_eval` must be an array of real numbers, got {t_eval!r}") from None
    if t.ndim != 1 or t.size == 0:
        raise ValueError(f"`t_eval` must be a non-empty 1-D array, got shape {t.shape}")
    if not np.isfinite(t).all():  # array methods: np.all's numbers without its Python wrapper
        raise ValueError("`t_eval` must be finite")
    lo, hi = (t0, t1) if t1 >= t0 else (t1, t0)
    span = hi - lo
    if t.min() < lo - 1e-12 * span or t.max() > hi + 1e-12 * span:
        raise ValueError(f"`t_eval` must lie within `t_span` = ({t0}, {t1})")
    if t1 >= t0:
        if (t[1:] < t[:-1]).any():
            raise ValueError("`t_eval` must be increasing")
    elif (t[1:] > t[:-1]).any():
        raise ValueError(f"`t_eval` must be decreasing, as t_span = ({t0}, {t1}) runs backward (t1 < t0)")
    return np.clip(t, lo, hi)


def check_output_times(t_eval) -> np.ndarray:
    """Output times of a solver run: a finite, strictly increasing 1-D array of
    at least 2 times (the first is the initial time)."""
    if type(t_eval) is np.ndarray and t_eval.dtype == np.float64 and t_eval.ndim == 1 and 2 <= t_eval.size <= 64:
        v = t_eval.tolist()  # a few times: compared as Python floats (the same comparisons), no ufunc calls
        if all(map(math.isfinite, v)) and all(a < b for a, b in zip(v, v[1:])):
            return t_eval.copy()
    try:
        t = np.array(t_eval, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"`t_eval` must be an array of real numbers, got {t_eval!r}") from None
    if t.ndim != 1 or t.size < 2:
        raise ValueError(f"`t_eval` must be a 1-D array of at least 2 times, got shape {t.shape}")
    if not np.isfinite(t).all() or not (t[1:] > t[:-1]).all():
        raise ValueError("`t_eval` must be finite and strictly increasing")
    return t
