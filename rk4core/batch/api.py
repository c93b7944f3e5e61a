"""``rk4h.ensemble``: one model, many instances, one batch.

An *instance* is one initial state ``y0[b]`` and, optionally, its own values
of the model's numeric parameters. Every instance runs the fixed-step method
with the same step ``h`` over the same ``t_span``; each obeys the
instability rule of :func:`rk4h.solve` alone (a diverging instance stops
at its own step, with its own ``t_fail``; the others run on).

Backends (both compiled from the model's one symbolic definition, as
:mod:`rk4h.fast`):

* ``"numba"`` -- the loop :func:`rk4h.fast.solve_model` runs, called once
  per instance inside a ``prange`` over instances (all cores). Per instance
  the numbers are those of ``rk4h.solve(model.rhs, ...)`` bit for bit.
* ``"jax"`` -- the same tableau products and the same straight-line force
  expressions, traced with ``jax.numpy`` on arrays of shape (B,) (one lane per
  instance) inside a ``lax.scan``; float64 by default (jax's x64 mode is
  switched on), ``dtype="float32"`` allowed. Equal to the numba path to
  round-off (1e-13 relative on CPU, float64).

``backend="auto"`` takes jax when it is installed and its default device is a
GPU, numba otherwise.

Peak memory besides the result ``y`` (B x rows x n float64) is bounded by
running the instances in chunks of ``chunk`` (default: as many as fit
:data:`CHUNK_BYTES` of per-instance work arrays and stage slopes).
"""
from __future__ import annotations

import importlib.util
from dataclasses import dataclass
from typing import Mapping

import numpy as np

from ..methods import get_method
from ..solver import grid_times, step_count
from ..validate import check_max_growth, check_step_args, check_t_eval, check_t_span

__all__ = ["ensemble", "EnsembleResult", "instance_parameters", "BACKENDS", "CHUNK_BYTES"]

BACKENDS = ("auto", "numba", "jax")
#: Budget (bytes) of the temporaries of one chunk of instances (the jax
#: backend's stage slopes and carried state; the numba backend's per-instance
#: parameter, bound and work rows).
CHUNK_BYTES = 1 << 28
_DBL_MAX = np.finfo(np.float64).max


@dataclass
class EnsembleResult:
    """What :func:`ensemble` returns.

    Attributes
    ----------
    t : ndarray, shape (m,)
        Output times (s), shared by every instance.
    y : ndarray, shape (B, m, n)
        States at ``t`` (units of the model's state ``[q, v]``); rows past an
        instance's failure are NaN.
    status : ndarray of int, shape (B,)
        0: reached ``t_span[1]``; -1: stopped by the instability rule.
    t_fail : ndarray of float, shape (B,)
        Time (s) of the first step past the bound (as ``rk4h.solve``'s
        ``t_fail``); NaN where ``status == 0``.
    n_steps : ndarray of int, shape (B,)
        Steps completed by each instance.
    h : float
        The step used (s): ``(t1 - t0) / N``.
    method, backend, dtype : str
    """

    t: np.ndarray
    y: np.ndarray
    status: np.ndarray
    t_fail: np.ndarray
    n_steps: np.ndarray
    h: float
    method: str
    backend: str
    dtype: str

    @property
    def success(self) -> np.ndarray:
        """``status == 0`` per instance."""
        return self.status == 0


def _jax_has_gpu() -> bool:
    if importlib.util.find_spec("jax") is None:
        return False
    try:
        import jax
        return jax.default_backend() == "gpu"
    except Exception:  # a broken jax install: the CPU path still works
        return False


def _backend(value) -> str:
    if value not in BACKENDS:
        raise ValueError(f"`backend` must be one of {list(BACKENDS)}, got {value!r}")
    if value == "auto":
        return "jax" if _jax_has_gpu() else "numba"
    return value


def _dtype(value, backend: str) -> str:
    name = np.dtype(value).name if isinstance(value, (type, np.dtype)) else value
    if name not in ("float64", "float32"):
        raise ValueError(f"`dtype` must be 'float64' or 'float32', got {value!r}")
    if name == "float32" and backend != "jax":
        raise ValueError(f"`dtype` = 'float32' needs backend='jax' (the numba loops are float64), "
                         f"got backend={backend!r}")
    return name


def _check_y0(model, y0) -> np.ndarray:
    try:
        y = np.array(y0, dtype=np.float64, ndmin=2)
    except (TypeError, ValueError):
        raise ValueError(f"`y0` must be a (B, {2 * model.n_dof}) array of real numbers") from None
    if np.iscomplexobj(np.asarray(y0)):
        raise ValueError("`y0` must be real, got complex values")
    if y.ndim != 2 or y.shape[1] != 2 * model.n_dof or y.shape[0] < 1:
        raise ValueError(f"`y0` must have shape (B, {2 * model.n_dof}) (rows y = [q, v]) for "
                         f"{model.name}, got {np.shape(y0)}")
    if not np.isfinite(y).all():  # whole-array test first: a row-wise one costs 8x as much
        bad = np.flatnonzero(~np.isfinite(y).all(axis=1))
        raise ValueError(f"`y0` must be finite, got a non-finite value in instance {int(bad[0])}")
    return np.ascontiguousarray(y)


def _parameter_column(name: str, value, B: int) -> np.ndarray:
    try:
        a = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"`params[{name!r}]` must be an array of numbers, got {value!r}") from None
    if a.ndim == 0 or a.shape[0] != B:
        raise ValueError(f"`params[{name!r}]` must have length B = {B} (one value per instance), "
                         f"got shape {a.shape}")
    if not np.isfinite(a).all():
        raise ValueError(f"`params[{name!r}]` must be finite")
    return a.reshape(B, -1)


def _split_key(key: str):
    """``"masses[1]"`` -> ``("masses", 1)``; ``"alpha"`` -> ``("alpha", None)``."""
    if isinstance(key, str) and key.endswith("]") and "[" in key:
        base, _, i = key[:-1].partition("[")
        if i.isdigit():
            return base, int(i)
    return key, None


def parameter_row(base: Mapping, values) -> dict:
    """One instance's parameters: a copy of ``base`` (``model.params()``)
    with each ``(key, value)`` of ``values`` set, ``value`` a number or a
    vector. ``"name[i]"`` sets element ``i`` of a list parameter; a list
    parameter takes a vector whole, or one value for every element; any other
    parameter takes the (first) value as a float."""
    p = {k: (list(v) if isinstance(v, list) else v) for k, v in base.items()}
    for key, value in values:
        name, i = _split_key(key)
        vals = np.asarray(value, dtype=float).reshape(-1)
        if i is not None:
            p[name][i] = float(vals[0])
        elif isinstance(p[name], list):
            p[name] = [float(v) for v in vals] if vals.size > 1 else [float(vals[0])] * len(p[name])
        else:
            p[name] = float(vals[0])
    return p


def instance_parameters(model, params: Mapping | None, B: int):
    """Per-instance kernel numbers of ``model`` under ``params``, grouped by
    the structure of the compiled force.

    Parameters
    ----------
    model : rk4h.models.Model
        A model with a compiled force (:func:`rk4h.fast.supports`).
    params : mapping or None
        Numeric parameters of the model (names of ``model.params()``; an
        element of a list parameter as ``"name[i]"``) to arrays of length B
        (a list parameter may also take shape (B, len)).
    B : int
        Number of instances.

    Returns
    -------
    list of (index, fp, mass, kern)
        One entry per force structure: ``index`` (ndarray of int) the
        instances, ``fp`` (len(index), n_fp) the kernel's float parameters,
        ``mass`` (len(index), n_dof) the masses (kg, or the model's inertia
        units), ``kern`` a kernel of that structure. One entry unless the
        numbers change the printed force (a potential model's constants
        share one slot when two are equal, so equal values give another
        text); each structure compiles its own loop.

    Each distinct parameter row builds the model once (``type(model)(**p)``,
    so the model's own checks apply, refusals naming the instance).
    """
    from ..fast import force_kernel

    kern = force_kernel(model)
    if kern is None:
        raise ValueError(f"`model` must have a compiled force (see rk4h.fast.supports) for an ensemble, "
                         f"got {type(model).__name__}")
    fp0 = np.ascontiguousarray(kern.fp, dtype=np.float64)
    mass0 = np.ascontiguousarray(model.mass, dtype=np.float64)
    if not params:
        return [(np.arange(B), np.tile(fp0, (B, 1)), np.tile(mass0, (B, 1)), kern)]
    if not isinstance(params, Mapping):
        raise ValueError(f"`params` must be a mapping of parameter names to arrays, got {type(params).__name__}")
    base = model.params()
    cols = []
    for key, value in params.items():
        name, i = _split_key(key)
        if name not in base:
            raise ValueError(f"`params` key {key!r} is not a parameter of {model.name} "
                             f"(known: {', '.join(base)})")
        current = base[name]
        if i is not None and (not isinstance(current, list) or i >= len(current)):
            raise ValueError(f"`params` key {key!r}: {name} has no element {i}")
        if i is None and (isinstance(current, (bool, str)) or current is None):
            raise ValueError(f"`params` key {key!r} is not a numeric parameter of {model.name}")
        col = _parameter_column(key, value, B)
        if i is None and isinstance(current, list):
            if col.shape[1] not in (1, len(current)):
                raise ValueError(f"`params[{key!r}]` must have shape (B,) or (B, {len(current)}), "
                                 f"got {np.shape(value)}")
        elif col.shape[1] != 1:
            raise ValueError(f"`params[{key!r}]` must have shape (B,), got {np.shape(value)}")
        cols.append((key, col))
    table = np.concatenate([col for _, col in cols], axis=1)
    rows, inverse = np.unique(table, axis=0, return_inverse=True)
    inverse = inverse.reshape(-1)
    structures: dict = {}  # structure -> (kern, row numbers, fp rows, mass rows)
    row_group = np.empty(rows.shape[0], dtype=np.int64)
    ends = np.cumsum([col.shape[1] for _, col in cols])
    for r, row in enumerate(rows):
        p = parameter_row(base, ((key, row[end - col.shape[1]:end]) for (key, col), end in zip(cols, ends)))
        try:
            m = type(model)(**p)
        except ValueError as e:
            raise ValueError(f"`params` of instance {int(np.flatnonzero(inverse == r)[0])}: {e}") from None
        k = force_kernel(m)
        if k is None or m.mass.shape != mass0.shape:
            raise ValueError(f"`params` of instance {int(np.flatnonzero(inverse == r)[0])} give {model.name} "
                             f"no compiled force of its size")
        key = (k.key(), k.scalar_key() if k.has_scalar() else None, k.ip.tobytes(), k.fp.shape)
        g = structures.setdefault(key, (k, [], [], []))
        row_group[r] = list(structures).index(key)
        g[1].append(r)
        g[2].append(np.asarray(k.fp, dtype=np.float64))
        g[3].append(np.asarray(m.mass, dtype=np.float64))
    groups = []
    for gi, (k, rnums, fps, masses) in enumerate(structures.values()):
        local = np.full(rows.shape[0], -1, dtype=np.int64)
        local[np.asarray(rnums)] = np.arange(len(rnums))
        index = np.flatnonzero(row_group[inverse] == gi)
        at = local[inverse[index]]
        groups.append((index, np.ascontiguousarray(np.stack(fps)[at]), np.ascontiguousarray(np.stack(masses)[at]), k))
    return groups


def _growth_bounds(y0: np.ndarray, max_growth, y_scale):
    """Per-instance :func:`rk4h.solver.growth_bound`: ``(bound (B, n), pending (B,))``;
    ``bound`` may be a read-only broadcast view."""
    B, n = y0.shape
    pending = np.zeros(B)
    if max_growth is None:
        return np.broadcast_to(_DBL_MAX, (B, n)), pending
    if y_scale is not None:
        return np.minimum(max_growth * y_scale, _DBL_MAX), pending
    scale = np.abs(y0[:, 0])  # max |y| of each row, a column at a time (6x faster than max(axis=1) for 4 columns)
    for j in range(1, n):
        np.maximum(scale, np.abs(y0[:, j]), out=scale)
    pos = scale > 0.0
    pending[~pos] = float(max_growth)
    column = np.where(pos, np.minimum(max_growth * scale, _DBL_MAX), _DBL_MAX)
    return np.broadcast_to(column[:, None], (B, n)), pending


def _check_y_scale(value, B: int, n: int):
    if value is None:
        return None
    try:
        a = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"`y_scale` must be {n} positive numbers (or a (B, {n}) array), got {value!r}") from None
    if a.shape not in ((n,), (B, n)) or not (np.isfinite(a) & (a > 0)).all():
        raise ValueError(f"`y_scale` must be {n} positive finite numbers (or a (B, {n}) array), got shape {a.shape}")
    return np.broadcast_to(a, (B, n))


def _check_chunk(value):
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
        raise ValueError(f"`chunk` must be an integer >= 1, got {value!r}")
    return int(value)


def ensemble(model, y0, t_span, *, h, method="rk4", params=None, t_eval=None, backend="auto",
             dtype="float64", max_growth=1e8, y_scale=None, chunk=None, groups=None) -> EnsembleResult:
    """Integrate ``B`` instances of ``model`` with one fixed-step method, as one batch.

    Parameters
    ----------
    model : rk4h.models.Model
        A model with a compiled force (every shipped model; see
        :func:`rk4h.fast.supports`); state ``y = [q, v]`` in its units.
    y0 : array_like, shape (B, n)
        Initial state of each instance, ``n = 2 model.n_dof``.
    t_span : (float, float)
        ``(t0, t1)`` (s), ``t1 > t0``.
    h : float
        Step (s), as :func:`rk4h.solve`: ``N = step_count(t_span, h)``
        steps of ``(t1 - t0) / N``.
    method : str or Tableau
        Any fixed-step method of ``rk4h.METHODS`` (partitioned ones
        included) or a tableau.
    params : mapping, optional
        Numeric model parameters per instance: ``{"alpha": a}`` with ``a``
        of shape (B,), ``{"masses": M}`` with ``M`` of shape (B, n_dof), or
        one element ``{"masses[1]": m1}`` (shape (B,)).
    t_eval : array_like, optional
        Output times (s), shared by every instance; default every step. Off-grid
        times are cubic Hermite (numba backend only; jax needs grid times).
    backend : {"auto", "numba", "jax"}
    dtype : {"float64", "float32"}
        Arithmetic precision; float32 with the jax backend only.
    max_growth, y_scale
        The instability rule of :func:`rk4h.solve`, per instance
        (``y_scale``: (n,) or (B, n)).
    chunk : int, optional
        Instances per chunk (default from :data:`CHUNK_BYTES`).
    groups : list, optional
        ``instance_parameters(model, params, B)`` computed before (a
        stability map reuses it over its steps: each distinct parameter
        row builds a model, milliseconds each); ``params`` is then ignored.

    Returns
    -------
    EnsembleResult
        ``y`` of shape (B, len(t), n) (float64 whatever ``dtype``), per
        instance ``status``, ``t_fail``, ``n_steps``.
    """
    backend = _backend(backend)
    dtype = _dtype(dtype, backend)
    tab = get_method(method)
    t0, t1 = check_t_span(t_span)
    y = _check_y0(model, y0)
    B, n = y.shape
    max_growth = check_max_growth(max_growth)
    y_scale = _check_y_scale(y_scale, B, n)
    N = check_step_args(t0, t1, h, None, step_count)
    step = (t1 - t0) / N
    t_eval = check_t_eval(t_eval, t0, t1)
    chunk = _check_chunk(chunk)
    groups = instance_parameters(model, params, B) if groups is None else groups
    bound, pending = _growth_bounds(y, max_growth, y_scale)
    from ..fast.solve import _output_points

    idx, theta, dense = _output_points(t0, step, N, t_eval, 1)
    t_out = grid_times(t0, t1, step, idx, N) if t_eval is None else t_eval
    rows = idx.shape[0]
    if backend == "numba":
        from . import _numba as impl
    else:
        if dense != "grid":
            raise ValueError("`t_eval` must hold grid times t0 + i h with backend='jax' "
                             "(off-grid output is cubic Hermite on the numba backend only)")
        from . import _jax as impl
    ys = np.full((B, rows, n), np.nan)
    n_done = np.zeros(B, dtype=np.int64)
    status = np.zeros(B, dtype=np.int64)
    for index, fp, mass, kern in groups:
        per_instance = 8 * (fp.shape[1] + mass.shape[1] + 4 * n + (len(tab.b) + 4) * n + kern.work_size)
        size = chunk or max(1, min(index.size, CHUNK_BYTES // max(per_instance, 1)))
        whole = index.size == B  # one structure: write the result in place
        for lo in range(0, index.size, size):
            hi = min(index.size, lo + size)
            sel = slice(lo, hi) if whole else index[lo:hi]  # whole: index is arange(B), so a slice (no copies)
            out = ys[lo:hi] if whole else np.full((hi - lo, rows, n), np.nan)
            d, s = impl.run(tab, kern, fp[lo:hi], mass[lo:hi], y[sel], t0, step, N, idx, theta, out,
                            np.array(bound[sel]), pending[sel].copy(), dtype=dtype)
            if not whole:
                ys[sel] = out
            n_done[sel], status[sel] = d, s
    t_fail = np.full(B, np.nan)
    failed = status != 0
    if failed.any():
        t_fail[failed] = grid_times(t0, t1, step, n_done[failed] + 1, N)
    return EnsembleResult(t=np.asarray(t_out, dtype=float), y=ys, status=status, t_fail=t_fail, n_steps=n_done,
                          h=step, method=tab.name, backend=backend, dtype=dtype)
