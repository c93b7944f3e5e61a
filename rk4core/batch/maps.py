"""Maps over an ensemble: where a fixed-step method stays stable, and how
far float32 round-off carries.

* :func:`stability_map` -- over a grid of one numeric model parameter and the
  step ``h``, which instances reach the end of the run without tripping the
  instability rule; per parameter value the largest stable ``h`` on the grid
  and ``omega_max h`` there (``omega_max``: the model's fastest linearised
  angular frequency). For RK4 on a linear oscillator the boundary is
  ``omega_max h = 2 sqrt(2) = 2.8284`` (the imaginary-axis limit of
  ``R(z) = 1 + z + z^2/2 + z^3/6 + z^4/24``).
* :func:`float32_floor` -- the round-off floor of a method in float32 against
  the same run in float64 (jax backend), over step counts; expected to grow
  like ``sqrt(n) eps32`` (a random walk of one rounding per step).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .api import ensemble

__all__ = ["stability_map", "StabilityMap", "float32_floor", "RK4_IMAGINARY_LIMIT"]

#: ``2 sqrt(2)``: RK4's stability interval on the imaginary axis (``|R(iy)| <= 1`` for ``|y| <= 2 sqrt(2)``).
RK4_IMAGINARY_LIMIT = 2.0 * np.sqrt(2.0)


@dataclass
class StabilityMap:
    """Result of :func:`stability_map`.

    Attributes
    ----------
    param : str
        The swept model parameter (``"masses[1]"``, ``"alpha"``, ...).
    values : ndarray, shape (V,)
        Its values (the parameter's units).
    h : ndarray, shape (H,)
        Steps (s), increasing.
    stable : ndarray of bool, shape (V, H)
        Instance ``(v, j)`` reached ``n_steps`` steps within the growth bound.
    omega_max : ndarray, shape (V,)
        Fastest linearised angular frequency (rad/s) per value.
    h_max : ndarray, shape (V,)
        Largest grid step below which every grid step is stable (s); NaN
        when the smallest is not.
    """

    param: str
    values: np.ndarray
    h: np.ndarray
    stable: np.ndarray
    omega_max: np.ndarray
    h_max: np.ndarray

    @property
    def z_max(self) -> np.ndarray:
        """``omega_max h_max`` per value (dimensionless)."""
        return self.omega_max * self.h_max


def _instance_models(model, param, values):
    from .api import _split_key

    name, i = _split_key(param)
    out = []
    for v in values:
        p = {k: (list(x) if isinstance(x, list) else x) for k, x in model.params().items()}
        if i is None:
            p[name] = float(v)
        else:
            p[name][i] = float(v)
        out.append(type(model)(**p))
    return out


def stability_map(model, param: str, values, h, *, y0, n_steps: int = 2000, method="rk4", max_growth=1e4,
                  backend="numba") -> StabilityMap:
    """Stable or not over the grid ``values x h``: one ensemble per step ``h``
    (all parameter values in one batch).

    Parameters
    ----------
    model : rk4h.models.Model
        Base model (compiled force); its other parameters are kept.
    param : str
        A numeric parameter of ``model.params()``, or ``"name[i]"``.
    values : array_like, shape (V,)
    h : array_like, shape (H,)
        Steps (s), positive, increasing.
    y0 : array_like, shape (n,)
        Initial state of every instance (it should excite the fastest mode).
    n_steps : int
        Steps per run: a growth factor ``g`` per step trips ``max_growth``
        after ``log(max_growth) / log(g)`` steps, so just past the boundary
        ``n_steps`` must be large.
    method, max_growth, backend
        As :func:`rk4h.ensemble`.
    """
    values = np.asarray(values, dtype=float).reshape(-1)
    hs = np.asarray(h, dtype=float).reshape(-1)
    if hs.size == 0 or not (np.isfinite(hs).all() and (hs > 0).all() and (np.diff(hs) > 0).all()):
        raise ValueError("`h` must be positive, finite and increasing")
    if isinstance(n_steps, bool) or not isinstance(n_steps, (int, np.integer)) or n_steps < 1:
        raise ValueError(f"`n_steps` must be an integer >= 1, got {n_steps!r}")
    y = np.tile(np.asarray(y0, dtype=float), (values.size, 1))
    stable = np.zeros((values.size, hs.size), dtype=bool)
    from .api import instance_parameters

    groups = instance_parameters(model, {param: values}, values.size)  # the models, built once for every h
    for j, step in enumerate(hs):
        t1 = n_steps * step
        r = ensemble(model, y, (0.0, t1), h=step, method=method, params={param: values}, t_eval=[0.0, t1],
                     max_growth=max_growth, backend=backend, groups=groups)
        stable[:, j] = r.status == 0
    omega = np.array([m.frequency_range()[1] for m in _instance_models(model, param, values)])
    first_bad = np.where(stable.all(axis=1), hs.size, np.argmin(stable, axis=1))
    h_max = np.where(first_bad > 0, hs[np.maximum(first_bad - 1, 0)], np.nan)
    return StabilityMap(param=param, values=values, h=hs, stable=stable, omega_max=omega, h_max=h_max)


def float32_floor(model, y0, t_end: float, n_steps, *, method="rk4"):
    """Round-off of ``method`` in float32 against float64 (jax backend), at
    ``t_end`` for each step count.

    Parameters
    ----------
    model : rk4h.models.Model
    y0 : array_like, shape (B, n)
        Instances (their spread averages the random walk).
    t_end : float
        End time (s); the runs take ``n`` steps of ``t_end / n``.
    n_steps : sequence of int

    Returns
    -------
    ndarray, shape (len(n_steps),)
        Median over instances of ``max_p |y32_p - y64_p| / max_p |y64_p|`` at
        ``t_end`` (dimensionless; compare with ``sqrt(n) eps32``,
        ``eps32 = 2^-23``).
    """
    y0 = np.asarray(y0, dtype=float)
    out = []
    for n in n_steps:
        h = t_end / n
        r64 = ensemble(model, y0, (0.0, t_end), h=h, method=method, t_eval=[t_end], backend="jax")
        r32 = ensemble(model, y0, (0.0, t_end), h=h, method=method, t_eval=[t_end], backend="jax",
                       dtype="float32")
        a, b = r32.y[:, -1], r64.y[:, -1]
        out.append(float(np.median(np.max(np.abs(a - b), axis=1) / np.max(np.abs(b), axis=1))))
    return np.array(out)
