"""The reference ("truth") trajectory of a scene, below double-precision round-off.

``reference_solution(model, y0, t_eval)`` returns a :class:`Truth`:

* linear models (``model.linear``): the modal superposition of
  :func:`rk4h.references.exact.modal_solution` (``kind = "exact-modal"``), exact up
  to the double-precision evaluation of ``phi``, ``cos`` and ``sin``;
* first-order models (any ODE, ``model.first_order``): the exact solution
  when the model has one, else DOP853 at its tightest tolerance confirmed by
  a second reference (:mod:`rk4h.references.ode_truth`);
* nonlinear models (planar4 and pendulums with ``linear=False``, triangle):
  heyoka's Taylor integrator in quadruple precision (``heyoka.real128``, 113-bit
  significand, eps = 1.9e-34) at ``tol = 1e-32`` (``kind = "heyoka-real128"``).
  It integrates the same expressions as the double-precision ``heyoka``
  solver (:mod:`rk4h.references.solvers.taylor`: the model's one ``_force`` code,
  constants the same Python floats, state scaled by the tolerance rule's
  ``s``), so the only differences are precision and tolerance.

``Truth.y`` is the float64 rounding; for real128 runs ``Truth.y_lo`` holds the
remainder (``y + y_lo`` is the real128 result to about 1e-32 relative;
``Truth.y_ext()`` rebuilds it as a real128 array). ``energy_drift`` is
``max_t |E(t) - E(0)| / E_motion`` of the reference (``E_motion = E(0) -
V(q*)``, :mod:`rk4h.energy`), evaluated in real128 for
real128 runs (so it measures the integration, not double round-off) and in
float64 for the modal solution (where it is the evaluation's round-off).

Caching
-------
A truth is computed once per scene: results are kept in memory and on disk,
in ``rk4h.cachedir.private_dir("truth")`` (``$RK4H_CACHE/truth``, else
``$XDG_CACHE_HOME/rk4h/truth``, else ``~/.cache/rk4h/truth``: created 0700,
verified to be a real directory owned by the user and closed to others). An
explicit ``path`` is used as given, created 0700 when missing, and must pass
the same check. When the directory is not trusted the truth is computed
without the disk cache and one line (a :class:`TruthCacheWarning`) names the
directory and the reason; the run goes on.

The key is a SHA-256 of: the cache format :data:`_FORMAT`; the model's name,
parameters and *definition* (:func:`definition_hash`: the source code of every
class in the model's MRO and of their modules, and of the code that builds
heyoka's equations), so an edited force never reuses a stale truth; the code
that computes the truth (:func:`method_hash`), so neither does an edited
integration or modal solution; the heyoka,
numpy and scipy versions; ``y0`` and ``t_eval`` (exact binary values), the kind,
the tolerance and the step cap.

Each entry (``<key>.npz``, written without pickles) holds ``t``, ``y``,
``y_lo``, a JSON ``meta`` record and ``sums``: SHA-256 checksums of the arrays
(dtype, shape and bytes of ``t``, ``y``, ``y_lo``) and of ``meta``. Reading
never trusts it: a file that is a symbolic link, not a regular file, not owned
by the user or writable by group/others, unreadable, truncated (BadZipFile,
EOFError, ...), with a wrong checksum, key, format, shape or times is a MISS:
the truth is recomputed, the entry overwritten, and one line says so
(``truth cache: <file> was corrupt (<reason>); recomputed``). Files are
written to a temporary file in the same directory, fsync'ed, renamed over
the entry (``os.replace``) and the directory fsync'ed, so concurrent runs at
worst compute the same truth twice and a crash leaves the old entry or the new
one, never half of one.

Shipped truths
--------------
The quadruple-precision truths of the shipped scenes also ship with the
package, in ``shipped_truths/`` next to this module: one entry per truth,
the same ``<key>.npz`` format as the disk cache, and ``MANIFEST.json`` naming
each entry's key, file and SHA-256 (and the cache format, the library
versions and the scenes that made them). A real128 truth is read from there
only when its key -- computed here exactly as for the disk cache, so the
model's parameters and definition, ``y0``, ``t_eval``, the tolerance and the
heyoka, numpy and scipy versions all match -- is in the manifest, the file's
SHA-256 equals the manifest's, and the entry passes every check of a disk
entry (its own checksums, key, format, kind, shapes, times); anything else is
computed as without it, with one line when an entry was there but failed.
mpmath is not in the key: no truth uses it (it gives the exact coefficients of
:mod:`rk4h.geometric`). An edited model, another heyoka, numpy or scipy, or
other output times change the key: the shipped entry is then simply not
used. ``python -m rk4h.validation.ship_truths`` regenerates the folder.

A run that fails (non-finite state, heyoka's error outcomes, the step cap
:data:`MAX_STEPS`) is reported in ``status``/``message``, with NaN from the
first output time not reached (heyoka's shortened output is padded to the
full grid), never an exception.
"""
from __future__ import annotations

import functools
import hashlib
import inspect
import io
import json
import os
import stat
import sys
import time
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from rk4h import cachedir
from rk4h.cachedir import UntrustedCacheError
from rk4h.energy import rest_energy
from rk4h.validate import check_model_y0, check_output_times

from .exact import modal_solution
from .solvers import check_model
from .solvers.base import Status
from .solvers.taylor import _pars, get_integrator, model_key, outcome_status, propagate, scaled_system, stop_time
from .solvers.tolerances import group_scales

__all__ = ["Truth", "reference_solution", "cache_dir", "clear_memory_cache", "definition_hash",
           "TruthCacheWarning", "TOL_REAL128", "KINDS", "MAX_STEPS"]

#: heyoka's tolerance for the quadruple-precision truth.
TOL_REAL128 = 1e-32
KINDS = ("exact-modal", "heyoka-real128")
#: Cap on Taylor steps of one real128 run (status FAILED beyond).
MAX_STEPS = 1_000_000
_FORMAT = 3  # bump when the cached content or its meaning changes (2: checksums, definition in the key;
#             3: energy_drift relative to the energy of the motion)
_ARRAYS = ("t", "y", "y_lo")
#: Truths shipped with the package for the shipped scenes (see "Shipped truths"
#: in the module docstring); written by ``python -m rk4h.validation.ship_truths``.
SHIPPED_DIR = Path(__file__).resolve().parent / "shipped_truths"
SHIPPED_MANIFEST = "MANIFEST.json"
_SHIPPED: dict = {}
_MEMORY: dict[str, "Truth"] = {}
_ENERGY_CFUNC: dict[str, object] = {}
_DEFINITION: dict[type, str | None] = {}
_WARNED: set = set()


class TruthCacheWarning(UserWarning):
    """One line about the disk cache of the truth: a directory not used, or an
    entry that was corrupt and has been recomputed."""


def _say(message: str) -> None:
    warnings.warn(" ".join(message.split()), TruthCacheWarning, stacklevel=3)


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
        ``max |E(t) - E0| / E_motion`` of the reference, ``E_motion = E0 - V(q*)``
        (absolute when it is 0).
    tol : float or None
        heyoka's tolerance (real128 runs).
    n_steps : int
        Taylor steps (0 for exact-modal).
    wall_s, compile_s : float
        Time the computation took when it was done (not when read from cache).
    status : Status
    message : str
    source : {"computed", "memory", "disk", "shipped"}
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
        from rk4h._heyoka import heyoka as _heyoka
        hy = _heyoka()

        y = self.y.astype(hy.real128)
        return y if self.y_lo is None else y + self.y_lo.astype(hy.real128)


def cache_dir(path=None) -> Path:
    """The verified truth cache directory.

    Parameters
    ----------
    path : path-like, optional
        Used as given; created with mode 0700 when missing. Default:
        ``rk4h.cachedir.private_dir("truth")`` (``$RK4H_CACHE/truth``, else
        ``$XDG_CACHE_HOME/rk4h/truth``, else ``~/.cache/rk4h/truth``).

    Returns
    -------
    Path

    Raises
    ------
    rk4h.cachedir.UntrustedCacheError
        The directory (or, by default, the cache root) is a symbolic link, not
        owned by the user, open to group or others, or cannot be created.
    """
    if path is None:
        return cachedir.private_dir("truth")
    p = Path(path)
    if not os.path.lexists(p):
        try:
            p.parent.mkdir(parents=True, exist_ok=True)
            os.mkdir(p, 0o700)
        except FileExistsError:
            pass
        except OSError as e:
            raise UntrustedCacheError(e.errno, f"cache directory {p}: cannot create it ({e.strerror})") from None
    return cachedir.verify(p)


def clear_memory_cache() -> None:
    _MEMORY.clear()


def _source(obj) -> str:
    return inspect.getsource(obj)


def definition_hash(model) -> str | None:
    """SHA-256 (hex) of the code that defines ``model``'s equations: the source
    of every class in ``type(model).__mro__`` (``object`` excepted) and of the
    module each is defined in, of the definitions they are built on
    (:mod:`rk4h.models.network`, :mod:`rk4h.models.potential`, the
    expression code :mod:`rk4h.expr`), and of the code turning ``_force``
    into heyoka's equations (:func:`rk4h.references.solvers.taylor.scaled_system`,
    ``_pars``).

    Returns None when a source cannot be read (a class defined interactively):
    such a model's truth is then not cached on disk.
    """
    cls = type(model)
    if cls in _DEFINITION:
        return _DEFINITION[cls]
    h = hashlib.sha256()
    try:
        for c in cls.__mro__:
            if c is object:
                continue
            mod = sys.modules.get(c.__module__)
            h.update(f"{c.__module__}.{c.__qualname__}\n".encode())
            h.update(_source(c).encode())
            if mod is not None:
                h.update(_source(mod).encode())
        for fn in (scaled_system, _pars):
            h.update(_source(fn).encode())
        # The definitions the shipped models are built on (a Defined model's
        # Network or PotentialModel, the spring-energy template) and the
        # expression code that turns them into heyoka's equations.
        for name in ("rk4h.expr", "rk4h.models.network", "rk4h.models.potential"):
            h.update(_source(sys.modules[name]).encode())
        out = h.hexdigest()
    except (OSError, TypeError):
        out = None
    _DEFINITION[cls] = out
    return out


@functools.lru_cache(maxsize=1)
def method_hash() -> str:
    """SHA-256 (hex) of the code that computes a truth from a model (part of
    its key): :func:`_real128`, :func:`_exact_modal`, :func:`_energy_cfunc`,
    :func:`_drift` and the modules they run (the Taylor driver
    :mod:`rk4h.references.solvers.taylor`, its tolerances and scales
    :mod:`rk4h.references.solvers.tolerances`, the modal solution
    :mod:`rk4h.references.exact`, the rest energy :mod:`rk4h.energy`). An
    edit to any of them keys every truth anew: a cached or shipped entry
    computed by other code is never read as this code's result."""
    from rk4h import energy

    from . import exact
    from .solvers import taylor, tolerances

    h = hashlib.sha256()
    for obj in (_real128, _exact_modal, _energy_cfunc, _drift, taylor, tolerances, exact, energy):
        h.update(_source(obj).encode())
    return h.hexdigest()


def _versions() -> dict:
    """The versions of the libraries a truth depends on (part of its key),
    read once per process (``importlib.metadata`` scans the installed
    distributions: milliseconds a call)."""
    return dict(_versions_once())


def _versions_once() -> tuple:
    from rk4h.distributions import version

    return tuple((dist, version(dist)) for dist in ("heyoka", "numpy", "scipy"))


def _key(model, y0, t_eval, kind, tol, max_steps=MAX_STEPS) -> str:
    h = hashlib.sha256()
    h.update(json.dumps({"format": _FORMAT, "model": model_key(model), "definition": definition_hash(model),
                         "method": method_hash(), "versions": _versions(), "kind": kind,
                         "tol": None if tol is None else float(tol).hex(),
                         "max_steps": None if tol is None else int(max_steps),
                         "y0": [float(v).hex() for v in y0]}, sort_keys=True).encode())
    h.update(np.ascontiguousarray(t_eval, dtype="<f8").tobytes())
    return h.hexdigest()


def reference_solution(model, y0, t_eval, *, kind: str = "auto", tol: float = TOL_REAL128,
                       cache: bool = True, path=None) -> Truth:
    """The reference trajectory of ``model`` from ``y0`` at ``t_eval``.

    Parameters
    ----------
    model : rk4h.models.Model
    y0 : array_like, shape (2 n_dof,)
        Initial state ``[q, v]``; must have finite force and energy
        (:meth:`rk4h.models.Model.check_state`).
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

    Raises
    ------
    ValueError
        Naming ``model``, ``y0``, ``t_eval`` or ``kind``. Cache problems never
        raise (see the module docstring).
    """
    check_model(model)
    y0 = model.check_state(check_model_y0(model, y0), "y0")
    t = check_output_times(t_eval)
    if getattr(model, "first_order", False):  # any ODE: exact, or two references that agree
        from .ode_truth import ode_reference

        if kind not in ("auto", "ode"):
            raise ValueError(f"`kind` must be 'auto' for a first-order model, got {kind!r}")
        return ode_reference(model, y0, t, Truth)
    if kind == "auto":
        kind = "exact-modal" if model.linear else "heyoka-real128"
    if kind not in KINDS:
        raise ValueError(f"`kind` must be one of {['auto', *KINDS]}, got {kind!r}")
    if kind == "exact-modal" and not model.linear:
        raise ValueError(f"`kind` 'exact-modal' needs a linear model, got nonlinear {model.name!r}")
    tol_key = tol if kind == "heyoka-real128" else None
    key = _key(model, y0, t, kind, tol_key)
    file, corrupt = None, None
    if cache:
        hit = _MEMORY.get(key)
        if hit is not None:
            return _relabel(hit, "memory")
        hit = _shipped_hit(key, t, 2 * model.n_dof, kind) if kind == "heyoka-real128" else None
        if hit is not None:
            _MEMORY[key] = hit
            return _relabel(hit, "shipped")
        directory = _usable_dir(path) if definition_hash(model) is not None else None
        if directory is not None:
            file = directory / f"{key}.npz"
            hit, corrupt = _load(file, key, t, 2 * model.n_dof, kind)
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
        if file is not None:
            written = _save(file, truth)
            if corrupt is not None:
                _say(f"truth cache: {file} was corrupt ({corrupt}); recomputed"
                     + ("" if written else " (could not rewrite it)"))
    return truth


def shipped_manifest(directory=None) -> dict:
    """The verified-looking entries of the shipped truths' manifest:
    ``{key: (file name, sha256 hex)}``, read once per process and directory
    (default :data:`SHIPPED_DIR`). A manifest that is missing, unreadable, of
    another cache format or malformed gives ``{}`` (every truth computed)."""
    directory = Path(SHIPPED_DIR if directory is None else directory)
    got = _SHIPPED.get(str(directory))
    if got is None:
        fmt, entries = manifest_entries(directory / SHIPPED_MANIFEST)
        got = _SHIPPED[str(directory)] = entries if fmt == _FORMAT else {}
    return got


def manifest_entries(file: Path) -> tuple:
    """``(format, {key: (file name, sha256 hex)})`` of a shipped truths'
    manifest, whatever its format (read as :func:`_read_regular` reads package
    data); entries whose file name is not a plain name in the folder or whose
    digest is not 64 characters are left out. ``(None, {})`` when the manifest
    is missing, unreadable or malformed."""
    try:
        text = _read_regular(file, _SHIPPED_MANIFEST_CAP)
        manifest = json.loads(text.decode("utf-8")) if text is not None else {}
        entries = {}
        for key, entry in manifest.get("entries", {}).items():
            name, digest = str(entry["file"]), str(entry["sha256"])
            if name == Path(name).name and not name.startswith(".") and len(digest) == 64:
                entries[str(key)] = (name, digest)
        return manifest.get("format"), entries
    except (OSError, ValueError, KeyError, TypeError, AttributeError, RecursionError, _Corrupt):
        return None, {}


def _shipped_hit(key: str, t: np.ndarray, n_state: int, kind: str) -> Truth | None:
    """The shipped truth for ``key``, or None: no entry for this exact key, or
    an entry whose file fails its manifest SHA-256 or any check of
    :func:`_parse` (then one line says so and the truth is computed)."""
    entry = shipped_manifest().get(key)
    if entry is None:
        return None
    file = Path(SHIPPED_DIR) / entry[0]
    # every array is float64 of at most (n_state + 1) x m values (t, y, y_lo);
    # the rest (metadata, zip headers) is far below the 1 MiB margin
    cap = 8 * t.shape[0] * (1 + 2 * n_state) + 2**20
    try:
        data = _read_regular(file, cap)
        if data is None:
            raise _Corrupt("it is missing")
    except _Corrupt as e:
        reason = str(e)
    except OSError as e:
        reason = e.strerror or type(e).__name__
    else:
        if hashlib.sha256(data).hexdigest() != entry[1]:
            reason = "its SHA-256 differs from the manifest's"
        else:
            truth, reason = _parse(data, key, t, n_state, kind)
            if truth is not None:
                return truth
    if (str(file), reason) not in _WARNED:
        _WARNED.add((str(file), reason))
        _say(f"shipped truth {file} not used ({reason}); computed instead")
    return None


_SHIPPED_MANIFEST_CAP = 16 * 2**20  # bytes; the manifest of the shipped scenes is ~13 kB


def _read_regular(file: Path, cap: int | None = None, *, private: bool = False) -> bytes | None:
    """The bytes of ``file`` if it is a regular file (checked on the opened
    descriptor: a symbolic link is not followed, a FIFO does not block) of at
    most ``cap`` bytes (None: any size); None if it does not exist. Raises
    _Corrupt (or OSError) otherwise.

    ``private`` (the disk cache's entries): the file must also be owned by the
    user and not writable by group or others. Shipped package data is read
    without it: it belongs to whoever installed the package, and its content
    is verified by SHA-256."""
    try:
        fd = os.open(file, os.O_RDONLY | getattr(os, "O_NOFOLLOW", 0) | getattr(os, "O_NONBLOCK", 0))
    except FileNotFoundError:
        return None
    except OSError:
        if os.path.islink(file):
            raise _Corrupt("it is a symbolic link") from None
        raise
    with os.fdopen(fd, "rb") as f:
        st = os.fstat(f.fileno())
        if not stat.S_ISREG(st.st_mode):
            raise _Corrupt("it is not a regular file")
        if private:
            uid = os.getuid() if hasattr(os, "getuid") else st.st_uid
            if st.st_uid != uid:
                raise _Corrupt(f"it is owned by uid {st.st_uid}, not by you (uid {uid})")
            if st.st_mode & 0o022:
                raise _Corrupt(f"it has mode {stat.S_IMODE(st.st_mode):04o}: writable by group or others")
        if cap is None:
            return f.read()
        if st.st_size > cap:
            raise _Corrupt(f"it has {st.st_size} bytes, more than the {cap} it can need")
        data = f.read(cap + 1)
    if len(data) > cap:
        raise _Corrupt(f"it grew past {cap} bytes while read")
    return data


def _usable_dir(path) -> Path | None:
    """:func:`cache_dir`, or None (after one line naming the directory and the
    reason, once per directory and reason) when it is not trusted."""
    try:
        return cache_dir(path)
    except (UntrustedCacheError, ValueError) as e:
        where = path if path is not None else cachedir.cache_root() / "truth"
        reason = " ".join(str(e).split())
        if (str(where), reason) not in _WARNED:
            _WARNED.add((str(where), reason))
            _say(f"truth cache: not using directory {where} ({reason}); computing without the disk cache")
        return None


def _relabel(truth: Truth, source: str) -> Truth:
    return Truth(**{**truth.__dict__, "source": source})


def _drift(E: np.ndarray, E_rest) -> float:
    """``max |E - E0| / E_motion`` with ``E_motion = E0 - E_rest`` (absolute when it is 0)."""
    dE = np.abs(E - E[0])
    motion = abs(E[0] - E_rest)
    scale = motion if motion != 0 else 1
    return float(np.max(dE) / scale) if dE.size else 0.0


def _exact_modal(model, y0, t) -> Truth:
    start = time.perf_counter()
    y = modal_solution(model, y0)(t)
    drift = _drift(np.asarray(model.energy(y), dtype=float), rest_energy(model))
    return Truth(t, y, None, "exact-modal", drift, wall_s=time.perf_counter() - start,
                 message="modal superposition (float64 evaluation)")


def _energy_cfunc(model):
    from rk4h._heyoka import heyoka as _heyoka
    hy = _heyoka()

    key = model_key(model)
    cf = _ENERGY_CFUNC.get(key)
    if cf is None:
        vs, _ = model.heyoka_system()
        cf = hy.cfunc([model.heyoka_energy(vs)], vs, fp_type=hy.real128)
        _ENERGY_CFUNC[key] = cf
    return cf


def _real128(model, y0, t, tol) -> Truth:
    from rk4h._heyoka import heyoka as _heyoka
    hy = _heyoka()

    R = hy.real128
    ta, compile_s, _ = get_integrator(model, tol, "real128")
    scales = group_scales(model, y0)
    start = time.perf_counter()
    with np.errstate(over="ignore", invalid="ignore"):
        outcome, n_steps, y128, rows = propagate(ta, model, y0, scales, t, dtype=R, max_steps=MAX_STEPS)
    wall = time.perf_counter() - start
    status, message = Status.OK, f"heyoka real128, tol {tol:g}, order {ta.order}"
    with np.errstate(invalid="ignore"):
        y_hi = y128.astype(float)
        y_lo = (y128 - y_hi.astype(R)).astype(float)
    t_fail = None
    st, msg = outcome_status(outcome, rows, t.shape[0], MAX_STEPS, stop_time(ta, t, rows), "heyoka real128")
    if st is not Status.OK:
        t_fail = stop_time(ta, t, rows)
        status, message = st, msg
        y_hi[:, t > t_fail] = np.nan
        y_lo[:, t > t_fail] = np.nan
    reached = np.all(np.isfinite(y_hi), axis=0)
    cf = _energy_cfunc(model)
    E = np.asarray(cf(np.ascontiguousarray(y128[:, reached])))[0] if reached.any() else np.array([])
    E_rest = np.asarray(cf(np.zeros((y128.shape[0], 1), dtype=R)))[0, 0]  # V(q*) in real128
    drift = _drift(E, E_rest) if E.size else float("nan")
    return Truth(t, y_hi, y_lo, "heyoka-real128", drift, tol=float(tol), n_steps=n_steps, wall_s=wall,
                 compile_s=compile_s, status=status, message=message,
                 extra={"order": int(ta.order), "rows_returned": int(rows),
                        **({"t_fail": t_fail} if t_fail is not None else {})})


# -- disk entries -----------------------------------------------------------------------------
def _array_sum(arrays: dict) -> str:
    h = hashlib.sha256()
    for name in _ARRAYS:
        a = arrays.get(name)
        if a is None:
            h.update(f"{name}:none;".encode())
            continue
        a = np.ascontiguousarray(a)
        h.update(f"{name}:{a.dtype.str}:{a.shape};".encode())
        h.update(a.tobytes())
    return h.hexdigest()


def _meta_sum(meta_text: str) -> str:
    return hashlib.sha256(meta_text.encode()).hexdigest()


def _save(file: Path, truth: Truth) -> bool:
    """Write ``truth`` to ``file`` atomically (temporary file in the same
    directory, fsync, ``os.replace``, fsync of the directory). Returns False
    (and leaves no temporary file) when the disk refuses; never raises."""
    meta = {k: getattr(truth, k) for k in ("kind", "energy_drift", "tol", "n_steps", "wall_s",
                                            "compile_s", "message", "key", "extra")}
    meta["status"] = truth.status.value
    meta["format"] = _FORMAT
    arrays = {"t": np.ascontiguousarray(truth.t, dtype="<f8"), "y": np.ascontiguousarray(truth.y, dtype="<f8")}
    if truth.y_lo is not None:
        arrays["y_lo"] = np.ascontiguousarray(truth.y_lo, dtype="<f8")
    try:
        meta_text = json.dumps(meta, sort_keys=True, allow_nan=True)
    except (TypeError, ValueError):
        return False
    sums = {"arrays": _array_sum(arrays), "meta": _meta_sum(meta_text)}
    tmp = file.with_name(f".{file.stem}.{os.getpid()}.{os.urandom(4).hex()}.tmp")
    try:
        fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_NOFOLLOW", 0), 0o600)
        try:
            with os.fdopen(fd, "wb") as f:
                np.savez(f, **arrays, meta=np.array(meta_text), sums=np.array(json.dumps(sums, sort_keys=True)))
                f.flush()
                os.fsync(f.fileno())
        except BaseException:
            try:
                os.unlink(tmp)
            except OSError:
                pass
            raise
        os.replace(tmp, file)
        try:
            dfd = os.open(file.parent, os.O_RDONLY)
            try:
                os.fsync(dfd)
            finally:
                os.close(dfd)
        except OSError:  # some file systems cannot fsync a directory; the rename is done
            pass
        return True
    except OSError:  # a read-only or full disk costs a recomputation, not the run
        try:
            os.unlink(tmp)
        except OSError:
            pass
        return False


class _Corrupt(Exception):
    pass


def _load(file: Path, key: str, t: np.ndarray, n_state: int, kind: str):
    """``(truth, None)`` on a verified hit, ``(None, None)`` when there is no
    entry, ``(None, reason)`` when the entry is corrupt (see the module
    docstring). Never raises, never unpickles."""
    try:
        data = _read_regular(file, private=True)
        if data is None:
            return None, None
    except _Corrupt as e:
        return None, str(e)
    except Exception as e:  # noqa: BLE001 - any unreadable entry is a miss
        text = " ".join(str(e).split())[:200]
        return None, f"{type(e).__name__}: {text}" if text else type(e).__name__
    return _parse(data, key, t, n_state, kind)


def _parse(data: bytes, key: str, t: np.ndarray, n_state: int, kind: str):
    """``(truth, None)`` when the entry bytes ``data`` hold a verified truth for
    ``key`` (checksums, format, key, kind, shapes, times), else ``(None,
    reason)``. Never raises, never unpickles."""
    try:
        with np.load(io.BytesIO(data), allow_pickle=False) as z:
            names = set(z.files)
            need = {"t", "y", "meta", "sums"} | ({"y_lo"} if kind == "heyoka-real128" else set())
            if not need <= names or not names <= need | {"y_lo"}:
                raise _Corrupt(f"it holds {sorted(names)}, not {sorted(need)}")
            meta_text, sums_text = str(z["meta"][()]), str(z["sums"][()])
            arrays = {name: z[name] for name in _ARRAYS if name in names}
        sums = json.loads(sums_text)
        if _array_sum(arrays) != sums.get("arrays"):
            raise _Corrupt("checksum mismatch of its arrays")
        if _meta_sum(meta_text) != sums.get("meta"):
            raise _Corrupt("checksum mismatch of its metadata")
        meta = json.loads(meta_text)
        if meta.get("format") != _FORMAT:
            raise _Corrupt(f"format {meta.get('format')!r}, not {_FORMAT}")
        if meta.get("key") != key:
            raise _Corrupt("it holds another key")
        if meta.get("kind") != kind:
            raise _Corrupt(f"kind {meta.get('kind')!r}, not {kind!r}")
        m = t.shape[0]
        for name, a in arrays.items():
            want = (m,) if name == "t" else (n_state, m)
            if a.shape != want or a.dtype != np.dtype("<f8"):
                raise _Corrupt(f"`{name}` has shape {a.shape} and dtype {a.dtype}, not {want} float64")
        if not np.array_equal(arrays["t"], t):
            raise _Corrupt("its output times differ from the ones asked for")
        truth = Truth(arrays["t"], arrays["y"], arrays.get("y_lo"), meta["kind"], float(meta["energy_drift"]),
                      tol=None if meta["tol"] is None else float(meta["tol"]), n_steps=int(meta["n_steps"]),
                      wall_s=float(meta["wall_s"]), compile_s=float(meta["compile_s"]),
                      status=Status(meta["status"]), message=str(meta["message"]), key=key,
                      extra=dict(meta.get("extra", {})))
        return truth, None
    except _Corrupt as e:
        return None, str(e)
    except Exception as e:  # noqa: BLE001 - any unreadable entry is a miss (BadZipFile, EOFError, ...)
        text = " ".join(str(e).split())[:200]
        return None, f"{type(e).__name__}: {text}" if text else type(e).__name__
