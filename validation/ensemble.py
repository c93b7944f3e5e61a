"""Ensembles in scenes: the ``[ensemble]`` table, drawn into a batch, and
what is read off a batch (error statistics, the stability-map figure).

```toml
[ensemble]
size = 10000
seed = 1
"initial.x[0]" = { dist = "uniform", low = -0.01, high = 0.01 }
"params.masses[1]" = { dist = "log-uniform", low = 0.1, high = 10.0 }
```

Keys are ``initial.x[i]``, ``initial.v[i]`` (m, m/s or the model's
coordinate units) or ``params.NAME`` / ``params.NAME[i]`` (a numeric model
parameter, its units). Distributions:

* ``uniform`` (``low``, ``high``), ``normal`` (``mean``, ``std``),
  ``log-uniform`` (``low``, ``high`` > 0: uniform in the logarithm) -- one
  independent draw per instance from ``numpy.random.default_rng(seed)``, in
  the order the keys are written;
* ``grid`` (``low``, ``high``, ``n``; or ``values = [...]``) -- evenly spaced
  points (``scale = "log"`` for geometric spacing); several grid keys form
  their Cartesian product (the first key varies slowest), repeated over the
  random draws: ``size`` must then be a multiple of the product.

Two more keys configure the ``stability_map`` output and are not drawn:
``map_h = { low, high, n, scale }`` (s: the grid of steps, as a ``grid``
entry) and ``map_steps`` (steps per run, default 2000); the map's other axis
is the table's one ``grid`` key over a ``params.*`` value
(:func:`map_settings`). The scene pipeline reads the table through the
``ensemble`` and ``stability_map`` outputs (``validation/outputs/``).
"""
from __future__ import annotations

import numpy as np

__all__ = ["draw_instances", "error_statistics", "instance_errors", "stability_map_figure", "map_settings",
           "batch_reference", "reference_refinement", "EnsembleSums",
           "DISTRIBUTIONS",
           "MAP_KEYS"]

DISTRIBUTIONS = {"uniform": ("low", "high"), "normal": ("mean", "std"), "log-uniform": ("low", "high"),
                 "grid": ("low", "high", "n")}
#: Keys of ``[ensemble]`` that configure the stability map (not drawn per instance).
MAP_KEYS = ("map_h", "map_steps")


def _field(key, name=None):
    """``ensemble."params.masses[1]".low``: the field as the scene writes it."""
    return f'ensemble."{key}"' + (f".{name}" if name else "")


def _number(key, spec, name):
    v = spec.get(name)
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not np.isfinite(v):
        raise ValueError(f"`{_field(key, name)}` must be a finite number, got {v!r}")
    return float(v)


def _grid_points(key, spec):
    if "values" in spec:
        vals = spec["values"]
        if not isinstance(vals, list) or not vals or not all(
                isinstance(v, (int, float)) and not isinstance(v, bool) and np.isfinite(v) for v in vals):
            raise ValueError(f"`{_field(key, 'values')}` must be a non-empty list of finite numbers, got {vals!r}")
        return np.asarray(vals, dtype=float)
    low, high = _number(key, spec, "low"), _number(key, spec, "high")
    n = spec.get("n")
    if isinstance(n, bool) or not isinstance(n, int) or n < 1:
        raise ValueError(f"`{_field(key, 'n')}` must be an integer >= 1, got {n!r}")
    scale = spec.get("scale", "linear")
    if scale == "log":
        if not (low > 0 and high > 0):
            raise ValueError(f"`{_field(key, 'low')}` and `high` must be > 0 with scale = 'log', got {low}, {high}")
        return np.geomspace(low, high, n)
    if scale != "linear":
        raise ValueError(f"`{_field(key, 'scale')}` must be 'linear' or 'log', got {scale!r}")
    return np.linspace(low, high, n)


def _draw(key, spec, rng, size):
    dist = spec.get("dist")
    if dist == "uniform":
        low, high = _number(key, spec, "low"), _number(key, spec, "high")
        if not high >= low:
            raise ValueError(f"`{_field(key, 'high')}` must be >= low = {low}, got {high}")
        return rng.uniform(low, high, size)
    if dist == "normal":
        mean, std = _number(key, spec, "mean"), _number(key, spec, "std")
        if not std >= 0:
            raise ValueError(f"`{_field(key, 'std')}` must be >= 0, got {std}")
        return rng.normal(mean, std, size)
    if dist == "log-uniform":
        low, high = _number(key, spec, "low"), _number(key, spec, "high")
        if not (0 < low <= high):
            raise ValueError(f"`{_field(key, 'low')}` and `high` must satisfy 0 < low <= high, got {low}, {high}")
        return np.exp(rng.uniform(np.log(low), np.log(high), size))
    raise ValueError(f"`{_field(key, 'dist')}` must be one of {sorted(DISTRIBUTIONS)}, got {dist!r}")


def _index(key):
    """``"initial.x[2]"`` -> ``("initial", "x", 2)``; ``"params.alpha"`` -> ``("params", "alpha", None)``."""
    head, dot, rest = key.partition(".")
    if not dot or head not in ("initial", "params") or not rest:
        raise ValueError(f"`ensemble` key {key!r} must be 'initial.x[i]', 'initial.v[i]', 'params.NAME' or "
                         f"'params.NAME[i]'")
    name, i = rest, None
    if rest.endswith("]") and "[" in rest:
        name, _, idx = rest[:-1].partition("[")
        if not idx.isdigit():
            raise ValueError(f"`ensemble` key {key!r}: the index must be a non-negative integer")
        i = int(idx)
    if head == "initial" and (name not in ("x", "v") or i is None):
        raise ValueError(f"`ensemble` key {key!r}: an initial value is 'initial.x[i]' or 'initial.v[i]'")
    return head, name, i


def draw_instances(table, model, x, v=None, *, probe: bool = False):
    """The instances of an ``[ensemble]`` table.

    Parameters
    ----------
    table : mapping
        The ``[ensemble]`` table (``size``, ``seed``, one entry per drawn
        quantity; see the module docstring).
    model : rk4h.models.Model
        The scene's model (its parameters are the defaults of the others).
    x, v : array_like, shape (n_dof,)
        The scene's initial positions and velocities (defaults of the others).
    probe : bool
        Check every field as for the full draw, but draw only one copy of
        the grid (one instance when there is no grid): what a scene's
        validation needs, without allocating ``size`` instances.

    Returns
    -------
    y0 : ndarray, shape (size, 2 n_dof)
    params : dict
        ``"NAME"`` or ``"NAME[i]"`` -> ndarray of shape (size,), for
        :func:`rk4h.ensemble`.

    Raises
    ------
    ValueError
        One line naming the field (``ensemble.size``, ``ensemble."params.masses[1]".low``, ...) and the value.
    """
    if not isinstance(table, dict):
        raise ValueError(f"`ensemble` must be a table, got {table!r}")
    size, seed = table.get("size"), table.get("seed", 0)
    if isinstance(size, bool) or not isinstance(size, int) or not 1 <= size <= 10 ** 8:
        raise ValueError(f"`ensemble.size` must be an integer from 1 to 10^8, got {size!r}")
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise ValueError(f"`ensemble.seed` must be a non-negative integer, got {seed!r}")
    entries = [(k, s) for k, s in table.items() if k not in ("size", "seed", *MAP_KEYS)]
    if not entries:
        raise ValueError("`ensemble` must draw at least one quantity ('initial.x[0]', 'params.NAME', ...)")
    n = model.n_dof
    base = model.params()
    x = np.asarray(x, dtype=float).reshape(-1)
    v = np.zeros(n) if v is None else np.asarray(v, dtype=float).reshape(-1)
    for key, spec in entries:
        if not isinstance(spec, dict):
            raise ValueError(f"`{_field(key)}` must be a table like {{ dist = \"uniform\", low = 0, high = 1 }}, "
                             f"got {spec!r}")
        head, name, i = _index(key)
        if head == "initial" and i >= n:
            raise ValueError(f"`ensemble` key {key!r}: {model.name} has {n} coordinates")
        if head == "params":
            if name not in base or isinstance(base[name], (str, bool)) or base[name] is None:
                raise ValueError(f"`ensemble` key {key!r}: not a numeric parameter of {model.name} "
                                 f"(known: {', '.join(base)})")
            if i is not None and (not isinstance(base[name], list) or i >= len(base[name])):
                raise ValueError(f"`ensemble` key {key!r}: {name} has no element {i}")
    grids = [(k, _grid_points(k, s)) for k, s in entries if s.get("dist") == "grid"]
    n_grid = int(np.prod([g.size for _, g in grids])) if grids else 1
    if size % n_grid:
        raise ValueError(f"`ensemble.size` must be a multiple of the grid's {n_grid} points, got {size}")
    if probe:
        size = n_grid
    rng = np.random.default_rng(seed)
    columns = {}
    if grids:
        mesh = np.meshgrid(*[g for _, g in grids], indexing="ij")
        for (k, _), m in zip(grids, mesh):
            columns[k] = np.tile(m.reshape(-1), size // n_grid)
    for k, s in entries:
        if s.get("dist") != "grid":
            columns[k] = _draw(k, s, rng, size)
    y0 = np.tile(np.concatenate([x, v]), (size, 1))
    params = {}
    for k, col in columns.items():
        head, name, i = _index(k)
        if head == "initial":
            y0[:, i if name == "x" else n + i] = col
        else:
            params[name if i is None else f"{name}[{i}]"] = col
    return y0, params


def map_settings(table, model):
    """The stability map an ``[ensemble]`` table asks for.

    Returns
    -------
    param : str
        The model parameter of the table's one ``grid`` key (``"masses[1]"``).
    values : ndarray
        Its grid points (the parameter's units).
    h : ndarray
        ``map_h``'s grid of steps (s), increasing.
    n_steps : int
        ``map_steps`` (default 2000).

    Raises
    ------
    ValueError
        One line naming the field (``ensemble.map_h``, ``ensemble.map_steps``, ...).
    """
    spec = table.get("map_h")
    if not isinstance(spec, dict):
        raise ValueError(f"`ensemble.map_h` must be a table like {{ low = 0.01, high = 0.2, n = 100 }}, got {spec!r}")
    h = _grid_points("map_h", spec)
    if not ((h > 0).all() and (np.diff(h) > 0).all()):
        raise ValueError(f"`ensemble.map_h` must be positive and increasing, got {spec!r}")
    n_steps = table.get("map_steps", 2000)
    if isinstance(n_steps, bool) or not isinstance(n_steps, int) or not 1 <= n_steps <= 10 ** 6:
        raise ValueError(f"`ensemble.map_steps` must be an integer from 1 to 10^6, got {n_steps!r}")
    grids = [k for k, s in table.items() if k not in ("size", "seed", *MAP_KEYS)
             and isinstance(s, dict) and s.get("dist") == "grid"]
    if len(grids) != 1 or not grids[0].startswith("params."):
        raise ValueError(f"`ensemble` must have exactly one grid key over a 'params.NAME' value for the stability "
                         f"map, got {grids!r}")
    head, name, i = _index(grids[0])
    values = _grid_points(grids[0], table[grids[0]])
    return (name if i is None else f"{name}[{i}]"), values, h, n_steps


def statistics(a):
    """``{"median", "p95", "max"}`` of ``a`` (its units)."""
    return _stats(a)


def _stats(a):
    a = np.asarray(a, dtype=float)
    return {"median": float(np.median(a)), "p95": float(np.percentile(a, 95)), "max": float(np.max(a))}


def error_statistics(model, result, y0, params=None):
    """Error and energy-error statistics of a linear model's ensemble against
    the exact modal solution of each instance.

    Parameters
    ----------
    model : rk4h.models.Model
        A linear model (its ``modes()`` give the exact solution).
    result : rk4h.EnsembleResult
    y0 : ndarray, shape (B, n)
    params : mapping, optional
        The per-instance parameters the ensemble ran with.

    Returns
    -------
    dict
        ``{"error": {...}, "energy_error": {...}, "failed": int}``; each
        ``{...}`` holds ``median``, ``p95`` and ``max`` over the instances
        that reached the end: the error is ``max_t |y - y_exact|_inf /
        max_t |y_exact|_inf`` (dimensionless), the energy error ``max_t |E -
        E0| / E0``.
    """
    errs, eerrs, failed = instance_errors(model, result, y0, params)
    if not errs.size:
        return {"error": None, "energy_error": None, "failed": failed}
    return {"error": _stats(errs), "energy_error": _stats(eerrs), "failed": failed}


def instance_errors(model, result, y0, params=None, built=None):
    """Per instance that reached the end, the error and the relative energy
    error of :func:`error_statistics` (before the statistics).

    Parameters
    ----------
    model, result, y0, params
        As :func:`error_statistics`.
    built : dict, optional
        Parameter row -> model, filled as rows are built (pass one dict to
        several calls on chunks of one ensemble: one build per distinct row).

    Returns
    -------
    errors, energy_errors : ndarray
        Dimensionless, one per instance with ``status == 0``, in instance order.
    failed : int
        Instances that did not reach the end.
    """
    if not model.linear:
        raise ValueError(f"`model` {model.name} is nonlinear: error_statistics needs an exact (modal) solution")
    sums = EnsembleSums()
    sums.add(model, result, y0, params, built)
    return np.asarray(sums.errors, float), np.asarray(sums.energy_errors, float), sums.failed


def stability_map_figure(smap, path, *, limit=None, label=None):
    """Draw a :class:`rk4h.batch.maps.StabilityMap`: stable (light) and
    unstable (dark) grid cells over (parameter, h), and the largest stable
    ``omega_max h`` per value on a second panel, with ``limit`` (e.g. RK4's
    2.8284) as a line. Written to ``path`` (PNG); returns ``path``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (a1, a2) = plt.subplots(1, 2, figsize=(9, 3.6), constrained_layout=True)
    a1.pcolormesh(smap.values, smap.h, smap.stable.T.astype(float), cmap="Greys_r", vmin=-0.5, vmax=1.5,
                  shading="nearest")
    a1.set_xscale("log")
    a1.set_xlabel(label or smap.param)
    a1.set_ylabel("h (s)")
    a1.set_title("stable (light) / unstable (dark)")
    a2.semilogx(smap.values, smap.z_max, "o-", ms=3, label="largest stable $\\omega_{max} h$ on the grid")
    if limit is not None:
        a2.axhline(limit, color="C3", lw=1, label=f"{limit:.4f}")
    a2.set_xlabel(label or smap.param)
    a2.set_ylabel("$\\omega_{max} h$")
    a2.legend(fontsize=8)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


# -- weak errors and the batch reference of a nonlinear model -------------------------------------------------
#: The reference method of a nonlinear model's ensemble: Blanes and Moan's sixth-order splitting (the
#: registry's highest order; every model a batch runs is separable, ``dq/dt = v``, ``dv/dt = a(q)``).
REFERENCE_METHOD = "blanes-moan6"
#: What the reference step aims at: the reference's error this fraction of the smallest error it measures.
REFERENCE_TARGET = 1e-3
#: The check: the reference bound must lie at least this factor below every error statistic it measures.
REFERENCE_MARGIN = 10.0


def reference_refinement(h, order, omega_max, ref_order=6, target=REFERENCE_TARGET) -> int:
    """How many reference steps per scene step (an integer ``r >= 2``, so the
    reference's steps land on every grid point the scene's steps do).

    Model: a method of order ``p`` at ``z = omega_max h`` makes a relative
    error of about ``z^p`` (constants of order one and the same growth over
    the run for both methods); the reference of order ``q`` at ``z / r``
    then makes ``(z / r)^q``, and ``(z / r)^q = target z^p`` gives ``r =
    target^(-1/q) z^(1 - p/q)``. This is a rule for the step, not a
    guarantee: the second reference batch measures the bound, and the check
    fails when it is not :data:`REFERENCE_MARGIN` below the errors.

    Parameters
    ----------
    h : float
        The scene's smallest step (s).
    order : int
        The highest order among the scene's methods.
    omega_max : float
        The largest angular frequency of the model's linearization (rad/s);
        ``z = omega_max h`` is taken as at most 1 where it is larger, and as
        1 where it is unknown (0 or not finite).
    ref_order : int
        The reference method's order.
    target : float
        The aimed ratio of the reference's error to the scene method's.
    """
    z = omega_max * h if np.isfinite(omega_max) and omega_max > 0 else 1.0
    z = min(z, 1.0)
    r = target ** (-1.0 / ref_order) * z ** (1.0 - order / ref_order)
    return max(2, int(np.ceil(r)))


_REFERENCE_CACHE: dict = {}
#: Bytes of reference states kept in memory between the specs of one process (solvers and steps of a scene
#: share one reference); larger references are recomputed per spec.
REFERENCE_CACHE_BYTES = 512 * 2 ** 20


def batch_reference(model, y0, params, t_eval, t_end, h_ref, method=REFERENCE_METHOD):
    """A nonlinear model's reference over an ensemble, run as one batch and
    confirmed by a second one.

    The reference is ``method`` at ``h_ref / 2``; the confirmation the same
    method at ``h_ref``. Their disagreement, an estimate of the error of the
    coarser one (``1 - 2^-q`` of it at order ``q``), bounds the reference's
    error from above.

    Parameters
    ----------
    model : rk4h.models.Model
    y0 : ndarray, shape (B, 2 n)
        Initial states ``[q, v]`` (the model's units).
    params : mapping or None
        Per-instance parameters (as :func:`rk4h.ensemble`).
    t_eval : ndarray, shape (m,)
        Output times (s); grid points of both reference steps.
    t_end : float
        End of the run (s), from 0.
    h_ref : float
        The confirmation's step (s); the reference runs at half of it.
    method : str
        A fixed-step method of ``rk4h.METHODS``.

    Returns
    -------
    y_ref : ndarray, shape (B, m, 2 n)
        The reference states (NaN past a failure).
    bound : ndarray, shape (B,)
        Per instance ``max_t |y_ref - y_confirm|_inf / max_t |y_ref|_inf``
        (dimensionless).
    delta : ndarray, shape (m,)
        Per output time the largest ``|y_ref - y_confirm|_inf`` over the
        instances (the model's units), for the weak error's bound.
    status : ndarray of int, shape (B,)
        0 where both reference runs reached ``t_end``.
    """
    import hashlib

    import rk4h

    hsh = hashlib.sha1()
    for a in (y0, t_eval, *(np.asarray(params[k]) for k in sorted(params or {}))):
        hsh.update(np.ascontiguousarray(a, dtype=float).tobytes())
    key = (model.name, repr(sorted(model.params().items())), tuple(sorted(params or {})), hsh.hexdigest(),
           float(t_end), float(h_ref), method)
    if key in _REFERENCE_CACHE:
        return _REFERENCE_CACHE[key]
    kw = dict(params=params or None, t_eval=t_eval, backend="numba", method=method)
    fine = rk4h.ensemble(model, y0, (0.0, t_end), h=h_ref / 2.0, **kw)
    coarse = rk4h.ensemble(model, y0, (0.0, t_end), h=h_ref, **kw)
    diff = np.abs(fine.y - coarse.y)
    bound = np.max(diff, axis=(1, 2)) / np.max(np.abs(fine.y), axis=(1, 2))
    status = np.where((fine.status == 0) & (coarse.status == 0), 0, -1)
    delta = np.max(np.where(status[:, None, None] == 0, diff, 0.0), axis=(0, 2))
    out = (fine.y, bound, delta, status)
    held = sum(v[0].nbytes for v in _REFERENCE_CACHE.values())
    if held + fine.y.nbytes > REFERENCE_CACHE_BYTES:
        _REFERENCE_CACHE.clear()  # the chunks of another scene's reference, or too many to keep
    if fine.y.nbytes <= REFERENCE_CACHE_BYTES:
        _REFERENCE_CACHE[key] = out
    return out


class EnsembleSums:
    """Per-instance (strong) errors and the running sums of the weak errors
    over the chunks of one ensemble.

    Conventions (all dimensionless), over the instances ``b`` that reached
    the end (and whose reference did), ``y_ref`` each instance's exact modal
    solution (a linear model) or its batch reference
    (:func:`batch_reference`), ``E0_b`` its initial energy:

    * strong: per instance ``max_t |y_b - y_ref_b|_inf / max_t |y_ref_b|_inf``
      and ``max_t |E_b - E0_b| / E0_b`` (their median, 95th percentile and
      maximum are the table's statistics);
    * weak: the error of the ensemble mean, ``max_t |mean_b (y_b(t) -
      y_ref_b(t))|_inf / max_t mean_b |y_ref_b(t)|_inf`` -- the scale is the
      mean size of the instances, not the size of their mean (which may be
      near 0 for a symmetric ensemble) -- and ``max_t |mean_b (E_b(t) -
      E0_b)| / mean_b E0_b``. This follows the weak error ``weak_l∞`` of
      SciML's ensemble errors (``calculate_ensemble_errors``, formerly
      ``calculate_monte_errors``, which DiffEqDevTools' ``test_convergence``
      reports for ensembles) [1]_: the largest over the output times of the
      max-norm of the mean over the trajectories of ``u_j - u_true_j``; here
      divided by the scale above. Its strong errors are the mean and median
      over the trajectories; here the median, 95th percentile and maximum.

    References
    ----------
    .. [1] SciML, DiffEqDevTools.jl (https://github.com/SciML/DiffEqDevTools.jl)
       and SciMLBase.jl: ``EnsembleTestSolution``, its ``weak_errors``
       (``weak_final``, ``weak_l2``, ``weak_l∞``) and per-trajectory
       ``errors`` with their means and medians.
    """

    def __init__(self):
        self.errors, self.energy_errors = [], []
        self.failed = 0
        self.reference_failed = 0
        self.count = 0
        self.dy = self.ref_norm = self.de = None
        self.e0 = 0.0
        self.bound = []
        self.delta = None

    def add(self, model, result, y0, params=None, built=None, y_ref=None, bound=None, delta=None,
            ref_status=None):
        """Add one chunk: ``result`` (:class:`rk4h.EnsembleResult`) from
        ``y0`` with ``params``; ``y_ref`` (B, m, n) its batch reference, or
        None for a linear model's exact modal solutions; ``bound``, ``delta``
        and ``ref_status`` as :func:`batch_reference` returns them."""
        from rk4h.references.exact import modal_solution

        if y_ref is None and not model.linear:
            raise ValueError(f"`model` {model.name} is nonlinear: its errors need a batch reference")
        ok = result.status == 0
        self.failed += int((~ok).sum())
        if ref_status is not None:
            self.reference_failed += int((ok & (ref_status != 0)).sum())
            ok &= ref_status == 0
        if bound is not None:
            self.bound.extend(np.asarray(bound)[ok].tolist())
        if delta is not None:
            self.delta = delta if self.delta is None else np.maximum(self.delta, delta)
        m_rows, n = result.y.shape[1], result.y.shape[2]
        if self.dy is None:
            self.dy, self.ref_norm, self.de = np.zeros((m_rows, n)), np.zeros(m_rows), np.zeros(m_rows)
        built = {} if built is None else built  # one build per distinct parameter row of the chunk
        for b in np.flatnonzero(ok):
            m = instance_model(model, params, b, built)
            ref = modal_solution(m, y0[b])(result.t).T if y_ref is None else y_ref[b]
            err = result.y[b] - ref
            size = np.max(np.abs(ref), axis=1)
            self.errors.append(np.max(np.abs(err)) / np.max(size))
            e = m.energy(result.y[b].T)
            self.energy_errors.append(np.max(np.abs(e - e[0])) / abs(e[0]) if e[0] != 0 else np.nan)
            self.dy += err
            self.ref_norm += size
            self.de += e - e[0]
            self.e0 += e[0]
            self.count += 1

    def weak(self):
        """``(weak_error, weak_energy_error, weak_reference_bound)``
        (dimensionless; NaN when no instance counts). The bound is the
        largest disagreement of the two reference batches over instances and
        times on the weak error's scale (0 for exact modal solutions)."""
        if not self.count:
            return float("nan"), float("nan"), float("nan")
        scale = np.max(self.ref_norm / self.count)
        weak = float(np.max(np.abs(self.dy / self.count)) / scale)
        e0 = self.e0 / self.count
        weak_e = float(np.max(np.abs(self.de / self.count)) / abs(e0)) if e0 != 0 else float("nan")
        wbound = 0.0 if self.delta is None else float(np.max(self.delta) / scale)
        return weak, weak_e, wbound


def instance_model(model, params, b, built):
    """The model of instance ``b``: ``model`` itself without ``params``, else
    built from its parameter row (once per distinct row when ``built``, a
    dict, is passed to every call)."""
    from rk4h.batch.api import parameter_row

    if not params:
        return model
    row = tuple(x for col in params.values() for x in np.asarray(np.asarray(col)[b], dtype=float).reshape(-1).tolist())
    built = {} if built is None else built
    if row not in built:  # the parameters rk4h.ensemble gave this instance
        built[row] = type(model)(**parameter_row(model.params(), ((k, np.asarray(col)[b]) for k, col in params.items())))
    return built[row]
