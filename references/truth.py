"""The reference ("truth") trajectory of a scene, below double-precision round-off.

``reference_solution(model, y0, t_eval)`` returns a :class:`Truth`:

* linear models (``model.linear``): the modal superposition of
  :func:`references.exact.modal_solution` (``kind = "exact-modal"``), exact up
  to the double-precision evaluation of ``phi``, ``cos`` and ``sin``;
* nonlinear models (planar4 and pendulums with ``linear=False``, triangle):
  heyoka's Taylor integrator in quadruple precision (``heyoka.real128``, 113-bit
  significand, eps = 1.9e-34) at ``tol = 1e-32`` (``kind = "heyoka-real128"``).
  It integrates the same expressions as the double-precision ``heyoka``
  solver (:mod:`references.solvers.taylor`: the model's one ``_force`` code,
  constants the same Python floats, state scaled by the tolerance rule's
  ``s``), so the only differences are precision and tolerance.

``Truth.y`` is the float64 rounding; for real128 runs ``Truth.y_lo`` holds the
remainder (``y + y_lo`` is the real128 result to about 1e-32 relative;
``Truth.y_ext()`` rebuilds it as a real128 array). ``energy_drift`` is
``max_t |E(t) - E(0)| / |E(0)|`` of the reference, evaluated in real128 for
real128 runs (so it measures the integration, not double round-off) and in
float64 for the modal solution (where it is the evaluation's round-off).

Caching
-------
A truth is computed once per scene: results are kept in memory and on disk
(``.npz`` under ``$RK4H_CACHE``, default ``.cache/truth/`` in the repository
root), keyed by a SHA-256 of the model's name and parameters, ``y0`` and
``t_eval`` (exact binary values), the kind and the tolerance. Files are
written atomically, so concurrent runs at worst compute the same truth twice.

A run that fails (non-finite state, heyoka's error outcomes) is reported in
``status``/``message``, with NaN from the first output time not reached.
"""
from __future__ import annotations

import hashlib
import json
import os
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from rk4core.validate import check_model_y0, check_output_times

from .exact import modal_solution
from .solvers.base import Status
from .solvers.taylor import get_integrator, model_key, propagate
from .solvers.tolerances import group_scales

__all__ = ["Truth", "reference_solution", "cache_dir", "clear_memory_cache", "TOL_REAL128", "KINDS"]

#: heyoka's tolerance for the quadruple-precision truth.
TOL_REAL128 = 1e-32
KINDS = ("exact-modal", "heyoka-real128")
_FORMAT = 1  # bump when the cached content or its meaning changes
_MEMORY: dict[str, "Truth"] = {}
_ENERGY_CFUNC: dict[str, object] = {}


@dataclass
class Truth:
    """A reference trajectory.

    Attributes
    ----------
    t : ndarray, shape (m,)
        Output times (s).
    y : ndarray, shape (2 n_dof, m)
        Reference states, rounded to float64.
    y_lo : ndarray or None
        ``real128(y) + y_lo`` is the real128 result (None for exact-modal).
    kind : {"exact-modal", "heyoka-real128"}
    energy_drift : float
        ``max |E(t) - E0| / |E0|`` of the reference (absolute when E0 = 0).
    tol : float or None
        heyoka's tolerance (real128 runs).
    n_steps : int
        Taylor steps (0 for exact-modal).
    wall_s, compile_s : float
        Time the computation took when it was done (not when read from cache).
    status : Status
    message : str
    source : {"computed", "memory", "disk"}
    key : str
        The cache key.
    """

    t: np.ndarray
    y: np.ndarray
    y_lo: np.ndarray | None
    kind: str
    energy_drift: float
    tol: float | None = None
    n_steps: int = 0
    wall_s: float = 0.0
    compile_s: float = 0.0
    status: Status = Status.OK
    message: str = ""
    source: str = "computed"
    key: str = ""
    extra: dict = field(default_factory=dict)

    @property
    def ok(self) -> bool:
        return self.status is Status.OK

    def y_ext(self) -> np.ndarray:
        """The reference in extended precision: a ``heyoka.real128`` array
        (``y + y_lo``); for exact-modal, ``y`` converted."""
        import heyoka as hy

        y = self.y.astype(hy.real128)
        return y if self.y_lo is None else y + self.y_lo.astype(hy.real128)


def cache_dir(path=None) -> Path:
    """``path``, else ``$RK4H_CACHE``, else ``<repo>/.cache/truth``."""
    if path is not None:
        return Path(path)
    env = os.environ.get("RK4H_CACHE")
    return Path(env) if env else Path(__file__).resolve().parents[1] / ".cache" / "truth"


def clear_memory_cache() -> None:
    _MEMORY.clear()


def _key(model, y0, t_eval, kind, tol) -> str:
    h = hashlib.sha256()
    h.update(json.dumps({"format": _FORMAT, "model": model_key(model), "kind": kind,
                         "tol": None if tol is None else float(tol).hex(),
                         "y0": [float(v).hex() for v in y0]}, sort_keys=True).encode())
    h.update(np.ascontiguousarray(t_eval, dtype="<f8").tobytes())
    return h.hexdigest()


def reference_solution(model, y0, t_eval, *, kind: str = "auto", tol: float = TOL_REAL128,
                       cache: bool = True, path=None) -> Truth:
    """The reference trajectory of ``model`` from ``y0`` at ``t_eval``.

    Parameters
    ----------
    model : rk4core.models.Model
    y0 : array_like, shape (2 n_dof,)
    t_eval : array_like, shape (m,)
        Output times (s), strictly increasing; ``y0`` is the state at ``t_eval[0]``.
    kind : {"auto", "exact-modal", "heyoka-real128"}
        ``"auto"``: exact-modal for linear models, heyoka-real128 otherwise.
        ``"heyoka-real128"`` on a linear model is allowed (to check it against
        the exact solution).
    tol : float
        heyoka's tolerance for the real128 run.
    cache : bool
        Use (and fill) the memory and disk caches.
    path : path-like, optional
        Cache directory (default: :func:`cache_dir`).

    Returns
    -------
    Truth
    """
    y0 = check_model_y0(model, y0)
    t = check_output_times(t_eval)
    if kind == "auto":
        kind = "exact-modal" if model.linear else "heyoka-real128"
    if kind not in KINDS:
        raise ValueError(f"`kind` must be one of {['auto', *KINDS]}, got {kind!r}")
    if kind == "exact-modal" and not model.linear:
        raise ValueError(f"`kind` 'exact-modal' needs a linear model, got nonlinear {model.name!r}")
    tol_key = tol if kind == "heyoka-real128" else None
    key = _key(model, y0, t, kind, tol_key)
    if cache:
        hit = _MEMORY.get(key)
        if hit is not None:
            return _relabel(hit, "memory")
        hit = _load(cache_dir(path) / f"{key}.npz", key)
        if hit is not None:
            _MEMORY[key] = hit
            return _relabel(hit, "disk")
    if kind == "exact-modal":
        truth = _exact_modal(model, y0, t)
    else:
        truth = _real128(model, y0, t, tol)
    truth.key = key
    if cache:
        _MEMORY[key] = truth
        _save(cache_dir(path) / f"{key}.npz", truth)
    return truth


def _relabel(truth: Truth, source: str) -> Truth:
    return Truth(**{**truth.__dict__, "source": source})


def _drift(E: np.ndarray) -> float:
    dE = np.abs(E - E[0])
    scale = abs(E[0]) if E[0] != 0 else 1
    return float(np.max(dE) / scale) if dE.size else 0.0


def _exact_modal(model, y0, t) -> Truth:
    start = time.perf_counter()
    y = modal_solution(model, y0)(t)
    drift = _drift(np.asarray(model.energy(y), dtype=float))
    return Truth(t, y, None, "exact-modal", drift, wall_s=time.perf_counter() - start,
                 message="modal superposition (float64 evaluation)")


def _energy_cfunc(model):
    import heyoka as hy

    key = model_key(model)
    cf = _ENERGY_CFUNC.get(key)
    if cf is None:
        vs, _ = model.heyoka_system()
        cf = hy.cfunc([model.heyoka_energy(vs)], vs, fp_type=hy.real128)
        _ENERGY_CFUNC[key] = cf
    return cf


def _real128(model, y0, t, tol) -> Truth:
    import heyoka as hy

    R = hy.real128
    ta, compile_s = get_integrator(model, tol, "real128")
    scales = group_scales(model, y0)
    start = time.perf_counter()
    with np.errstate(over="ignore", invalid="ignore"):
        outcome, n_steps, y128 = propagate(ta, model, y0, scales, t, dtype=R)
    wall = time.perf_counter() - start
    status, message = Status.OK, f"heyoka real128, tol {tol:g}, order {ta.order}"
    y_hi = y128.astype(float)
    y_lo = (y128 - y_hi.astype(R)).astype(float)
    if outcome != hy.taylor_outcome.time_limit:
        t_fail = float(ta.time)
        status = Status.UNSTABLE if outcome == hy.taylor_outcome.err_nf_state else Status.FAILED
        message = f"heyoka real128 stopped with {outcome} at t = {t_fail:.6g}"
        y_hi[:, t > t_fail] = np.nan
        y_lo[:, t > t_fail] = np.nan
    reached = np.all(np.isfinite(y_hi), axis=0)
    E = np.asarray(_energy_cfunc(model)(np.ascontiguousarray(y128[:, reached])))[0]
    drift = _drift(E) if E.size else float("nan")
    return Truth(t, y_hi, y_lo, "heyoka-real128", drift, tol=float(tol), n_steps=n_steps, wall_s=wall,
                 compile_s=compile_s, status=status, message=message, extra={"order": int(ta.order)})


def _save(file: Path, truth: Truth) -> None:
    try:
        file.parent.mkdir(parents=True, exist_ok=True)
        meta = {k: getattr(truth, k) for k in ("kind", "energy_drift", "tol", "n_steps", "wall_s",
                                                "compile_s", "message", "key", "extra")}
        meta["status"] = truth.status.value
        tmp = file.with_name(f".{file.stem}.{os.getpid()}.tmp.npz")
        arrays = {"t": truth.t, "y": truth.y, "meta": np.array(json.dumps(meta))}
        if truth.y_lo is not None:
            arrays["y_lo"] = truth.y_lo
        np.savez(tmp, **arrays)
        os.replace(tmp, file)
    except OSError:  # a read-only or full disk costs a recomputation, not the run
        pass


def _load(file: Path, key: str) -> Truth | None:
    if not file.exists():
        return None
    try:
        with np.load(file, allow_pickle=False) as z:
            meta = json.loads(str(z["meta"]))
            if meta.get("key") != key:
                return None
            return Truth(z["t"], z["y"], z["y_lo"] if "y_lo" in z.files else None, meta["kind"],
                         meta["energy_drift"], tol=meta["tol"], n_steps=meta["n_steps"],
                         wall_s=meta["wall_s"], compile_s=meta["compile_s"], status=Status(meta["status"]),
                         message=meta["message"], key=key, extra=meta.get("extra", {}))
    except (OSError, ValueError, KeyError):
        return None
