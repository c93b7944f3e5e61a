"""The model base class: one definition of the mechanics feeds every solver.

A model is a set of generalized coordinates ``q`` (length ``n_dof``) with a
*diagonal* generalized mass ``mass`` (kg, or kg m^2 for angles) and a potential
``V(q)`` (J). Its equations of motion are ``mass * q'' = F(q)`` with
``F = -grad V``. The first-order state is ``y = [q, v]`` (length ``2 n_dof``).

Each concrete model writes ``_potential(q, ops)`` and ``_force(q, ops)`` once,
in terms of array operations and ``ops.sqrt / ops.sin / ops.cos``. The same
code is evaluated

* with ``ops = NUMPY`` on float arrays ``q`` of shape ``(n_dof,)`` or
  ``(n_dof, m)`` (vectorised over ``m`` states) -- the right-hand side that
  RK4, DOP853 and CVODE see;
* with ``ops = HEYOKA`` on an object array of heyoka expressions -- the
  equations heyoka's Taylor integrator compiles.

So every solver integrates the same equations; ``tests`` check that the force
is minus the gradient of the potential and that both evaluations agree.
"""
from __future__ import annotations

import json
import math
import operator
import threading
from collections import OrderedDict
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np

__all__ = ["Model", "Defined", "Drawing", "NUMPY", "HEYOKA", "Ops", "MASS_MIN", "check_masses",
           "check_normal_positive", "check_all_normal_positive", "model_constants", "model_fingerprint",
           "CONSTANTS_MAXSIZE", "clear_constants", "model_current", "OBJECT_CACHES", "register_object_cache"]

#: Smallest mass (kg, or kg m^2) a model accepts. Anything smaller is not a
#: physical mass but an underflow: at 5e-324 (the smallest subnormal) the
#: acceleration ``F/m`` and the fastest frequency ``sqrt(k/m)`` overflow to
#: inf, and an adaptive solver's first step comes out NaN (DOP853 then never
#: terminates). 1e-300 keeps every such quotient of the models' normal
#: parameters finite.
MASS_MIN = 1e-300


def check_normal_positive(name: str, value: float, minimum: float = MASS_MIN) -> float:
    """``value`` if it is a finite float ``>= minimum``.

    Parameters
    ----------
    name : str
        Field named in the error.
    value : float
        A mass (kg), stiffness (N/m) or length (m), in the model's units.
    minimum : float
        Smallest accepted value (default :data:`MASS_MIN`, 1e-300).

    Returns
    -------
    float

    Raises
    ------
    ValueError
        One line naming ``name`` and the value.
    """
    v = float(value)
    if not (math.isfinite(v) and v >= minimum):
        raise ValueError(f"`{name}` must be a finite number >= {minimum:g} (a normal positive float), "
                         f"got {v!r}")
    return v


def check_all_normal_positive(values: np.ndarray, label) -> None:
    """:func:`check_normal_positive` on every entry of the float array
    ``values``, tested in bulk; the first entry that fails is named
    ``label(i)`` (its flat index ``i``) in the error."""
    if not (np.isfinite(values).all() and (values >= MASS_MIN).all()):
        for i, v in enumerate(values.ravel()):
            check_normal_positive(label(i), v)


def check_masses(name: str, masses) -> np.ndarray:
    """Every entry of ``masses`` a finite float ``>= MASS_MIN`` and the ratio
    of the largest to the smallest finite.

    Parameters
    ----------
    name : str
        Field named in the error (``name[i]`` for one entry).
    masses : array_like
        Masses (kg, or kg m^2 for angles).

    Returns
    -------
    ndarray of float

    Raises
    ------
    ValueError
        One line naming the field and the value.
    """
    try:
        m = np.asarray(masses, dtype=float)
    except OverflowError:  # an int beyond float's range: name it
        for i, v in enumerate(np.ravel(np.asarray(masses, dtype=object))):
            try:
                float(v)
            except OverflowError:
                raise ValueError(f"`{name}[{i}]` must be a finite number >= {MASS_MIN:g} (a normal positive "
                                 f"float), got {v!r}") from None
        raise
    check_all_normal_positive(m, lambda i: f"{name}[{i}]" if m.size > 1 else name)
    if m.size and not math.isfinite(float(m.max()) / float(m.min())):
        raise ValueError(f"`{name}` must have a finite ratio largest/smallest, got "
                         f"{float(m.max())!r} / {float(m.min())!r}")
    return m


class Ops:
    """Elementary functions for one evaluation backend."""

    def __init__(self, name, sqrt, sin, cos):
        self.name, self.sqrt, self.sin, self.cos = name, sqrt, sin, cos

    def __repr__(self):
        return f"Ops({self.name})"


NUMPY = Ops("numpy", np.sqrt, np.sin, np.cos)


def _heyoka_ops():
    from rk4h._heyoka import heyoka as _heyoka
    hy = _heyoka()

    vec = lambda f: np.frompyfunc(f, 1, 1)  # noqa: E731 - elementwise over object arrays
    return Ops("heyoka", vec(hy.sqrt), vec(hy.sin), vec(hy.cos))


class _LazyOps:
    _ops = None

    def __getattr__(self, item):
        if _LazyOps._ops is None:
            _LazyOps._ops = _heyoka_ops()
        return getattr(_LazyOps._ops, item)


HEYOKA = _LazyOps()


#: Most models whose constants (:func:`model_constants`) are kept at once;
#: the least recently used is dropped beyond.
CONSTANTS_MAXSIZE = 64
#: Most bytes of arrays the kept constants of all models hold (modes of a
#: large model are ``8 n_dof^2`` bytes); least recently used models dropped
#: beyond, the one in use excepted.
CONSTANTS_MAX_BYTES = 256 * 2**20
#: Validated initial states kept per model (:meth:`Model.check_state`), and
#: the largest state (components) kept.
_STATES_MAXSIZE = 16
_STATE_MAX_SIZE = 4096

_CONSTANTS: OrderedDict = OrderedDict()
_CONSTANTS_LOCK = threading.Lock()

#: The per-object caches a model may keep in its ``__dict__`` (each worked out
#: from its attributes: its compiled kernel, prepared loops, compiled
#: right-hand side, the fixed-step short path's record, a lambdified
#: expression) and the change record itself (:func:`model_current`). They are
#: dropped together when the model is found changed; a module adding such a
#: cache adds its name here (:func:`register_object_cache`).
OBJECT_CACHES = {"_fast_force_kernel", "_fast_prepared", "_references_rhs", "_fixed_short", "_V_above_fn",
                 "_rk4h_watch"}
_WATCH = "_rk4h_watch"
_UNSET = object()


def register_object_cache(name: str) -> None:
    """Declare ``name`` a per-object cache of models (see :data:`OBJECT_CACHES`)."""
    OBJECT_CACHES.add(name)


def _held_models(model) -> list:
    """``model`` and each model held in one of its attributes (a
    :class:`Defined` model's definition)."""
    return [model] + [v for v in model.__dict__.values() if isinstance(v, Model)]


def _snapshot(model):
    """``(owners, arrays, containers)``: for ``model`` and each model it
    holds, its attribute dictionary with the names and values of its
    attributes (caches excepted); every array attribute with its dtype,
    shape and bytes; every plain list or dict with a copy."""
    owners, arrays, containers = [], [], []
    for held in _held_models(model):
        attrs = held.__dict__
        names = tuple(name for name in attrs if name not in OBJECT_CACHES)
        values = tuple(attrs[name] for name in names)
        if held is not model or type(model).__setattr__ is not Model.__setattr__ \
                or type(model).__delattr__ is not Model.__delattr__:
            # the model's own rebinding goes through Model.__setattr__, which voids the record
            owners.append((attrs, names, values))
        for value in values:
            if isinstance(value, np.ndarray):
                arrays.append((value, value.dtype, value.shape, value.tobytes()))
            elif type(value) in (list, dict):
                try:
                    copy = type(value)(value)
                    if bool(copy == value):
                        containers.append((value, copy))
                except Exception:  # noqa: BLE001 - items without a plain ==: kept by identity only
                    pass
    return owners, arrays, containers


def _unchanged(snapshot) -> bool:
    owners, arrays, containers = snapshot
    is_ = operator.is_
    for attrs, names, values in owners:
        if not all(map(is_, map(attrs.get, names), values)):
            return False
    for value, dtype, shape, data in arrays:
        if value.shape != shape or (value.dtype is not dtype and value.dtype != dtype) or value.tobytes() != data:
            return False
    for value, copy in containers:
        if value != copy:
            return False
    return True


class _Watch:
    """What a model object's per-object caches were worked out from (a
    snapshot of its attributes) and its fingerprint."""

    __slots__ = ("attrs", "snapshot", "fingerprint", "key")

    def __init__(self, model):
        self.attrs = model.__dict__  # a copy of the model (copy.copy) shares this record, not this dictionary
        self.snapshot = _snapshot(model)
        self.fingerprint = _UNSET
        self.key = None  # (class, fingerprint): the key of its constants


def _watch(model):
    """``model``'s :class:`_Watch`, made anew -- every per-object cache of
    ``model`` and of the models it holds dropped first -- when there is none
    or the model changed since it was made; None for an object without a
    ``__dict__``."""
    d = getattr(model, "__dict__", None)
    if d is None:
        return None
    w = d.get(_WATCH)
    if w is not None and w.attrs is d and _unchanged(w.snapshot):  # attrs: not a copy's record
        return w
    for held in _held_models(model):
        for key in OBJECT_CACHES:
            held.__dict__.pop(key, None)
    w = d[_WATCH] = _Watch(model)
    return w


def model_current(model) -> bool:
    """True when ``model`` is as it was when its per-object caches and its
    fingerprint were worked out. Else (changed in place or an attribute
    rebound, in it or in a model it holds; or never seen) every such cache
    is dropped, the model is recorded as it now is, and False is returned:
    its kernel, constants and checks are then worked out again.

    Models are not meant to change after construction; this is the one
    change detection that every per-object cache shares (the fixed-step
    short path, the fingerprint and so the constants of
    :func:`model_constants`, the compiled kernels). It costs a comparison of
    the model's arrays (bytes) and plain lists and dicts; an attribute
    rebound on the model (``Model.__setattr__``) voids the record at once, one
    rebound in a model it holds is found by identity."""
    d = getattr(model, "__dict__", None)
    if d is None:
        return False
    w = d.get(_WATCH)
    return _watch(model) is w  # the same record: unchanged; a new one (caches dropped): changed or new


def _plain(value):
    """JSON form of a parameter value json cannot write: arrays in full (their
    ``repr`` elides entries), numpy scalars as Python numbers."""
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    return repr(value)


def model_fingerprint(model) -> str | None:
    """The text identifying ``model``'s equations: its class, ``name`` and
    :meth:`Model.params` as canonical JSON (floats written exactly), or None
    when ``params()`` fails (such a model's constants are not cached).

    Worked out once per model object and kept on it while it is unchanged
    (:func:`model_current`: a model changed in place gets the fingerprint
    of its new parameters). Two objects built with equal parameters have
    equal fingerprints and so share their constants."""
    return _fingerprint(model, _watch(model))


def _fingerprint(model, w) -> str | None:
    """:func:`model_fingerprint` of ``model`` whose watch (checked now) is ``w``."""
    if w is not None and w.fingerprint is not _UNSET:
        return w.fingerprint
    try:
        cls = type(model)
        text = json.dumps({"class": f"{cls.__module__}.{cls.__qualname__}", "name": model.name,
                           "params": model.params()}, sort_keys=True, default=_plain)
    except Exception:  # noqa: BLE001 - no parameters, no cache: the caller computes
        return None
    if w is not None:
        w.fingerprint = text
        w.key = (type(model), text)
    return text


def model_constants(model) -> dict | None:
    """The dictionary of constants computed once for models with ``model``'s
    equations (modes, Gershgorin bound, a solver's Jacobian pattern...), or
    None when the model has no fingerprint (:func:`model_fingerprint`).

    Keyed on the model's class object and its fingerprint (never on ``id``:
    a new model at a freed address has its own entry); at most
    :data:`CONSTANTS_MAXSIZE` models and :data:`CONSTANTS_MAX_BYTES` of
    arrays are kept, least recently used dropped.
    Entries are written by :meth:`Model.constant`; arrays kept there are
    read-only or copied on the way out.

    Checks first that ``model`` is unchanged (:func:`model_current`): a
    model changed in place gets the constants of its new parameters."""
    w = _watch(model)
    key = w.key if w is not None else None
    if key is None:
        text = _fingerprint(model, w)
        if text is None:
            return None
        key = (type(model), text)
    with _CONSTANTS_LOCK:
        record = _CONSTANTS.get(key)
        if record is None:
            record = _CONSTANTS[key] = {}
            while len(_CONSTANTS) > CONSTANTS_MAXSIZE:
                _CONSTANTS.popitem(last=False)
        else:
            _CONSTANTS.move_to_end(key)
    return record


def _nbytes(value) -> int:
    if isinstance(value, np.ndarray):
        return value.nbytes
    if isinstance(value, (tuple, list)):
        return sum(_nbytes(v) for v in value)
    return 0


def _account(record: dict, value) -> None:
    """Add ``value``'s array bytes to ``record``'s and drop least recently
    used models while all of them hold more than :data:`CONSTANTS_MAX_BYTES`."""
    size = _nbytes(value)
    if not size:
        return
    with _CONSTANTS_LOCK:
        record["_nbytes"] = record.get("_nbytes", 0) + size
        total = sum(r.get("_nbytes", 0) for r in _CONSTANTS.values())
        for key in list(_CONSTANTS):
            if total <= CONSTANTS_MAX_BYTES:
                break
            if _CONSTANTS[key] is not record:
                total -= _CONSTANTS.pop(key).get("_nbytes", 0)


def clear_constants() -> None:
    """Forget every model's cached constants (they are recomputed on use)."""
    with _CONSTANTS_LOCK:
        _CONSTANTS.clear()


@dataclass(frozen=True)
class Drawing:
    """How a model is drawn: read by the figures, which never branch on
    model names.

    Attributes
    ----------
    layout : {"line", "plane", "angles", "coordinates"}
        ``"line"``: masses on a line, one displacement coordinate each
        (traces per mass; a space-time image for a long line). ``"plane"``:
        points in the plane (paths, springs). ``"angles"``: coordinates are
        angles (rad). ``"coordinates"``: anything else.
    points : tuple of (int, int)
        ``"plane"``: the coordinate indices (x, y) of each drawn point.
    reference : tuple of (float, float)
        ``"plane"``: each point's reference position (m); its coordinates are
        displacements from it.
    anchors : tuple of (float, float)
        Fixed points (m).
    springs : tuple of (int, int, str)
        Springs to draw: node indices (points first, then anchors) and a
        label; their elongation (length minus ``rest``) can be plotted.
    rest : tuple of float
        Natural length of each spring (m).
    unit : str
        Unit of the coordinates (``"m"``, ``"rad"``).
    point_labels : tuple of str
        Names of the points (``"plane"``) or coordinates.
    caption : str
        A sentence on what the model's figures show (may be empty).
    """

    layout: str = "coordinates"
    points: tuple = ()
    reference: tuple = ()
    anchors: tuple = ()
    springs: tuple = ()
    rest: tuple = ()
    unit: str = "m"
    point_labels: tuple = ()
    caption: str = ""
    extra: dict = field(default_factory=dict)


class Model:
    """Base class of the mass-spring models.

    Subclasses set ``name``, ``linear``, ``n_dof``, ``mass`` (ndarray, shape
    (n_dof,)), ``coord_names`` and implement ``_potential`` and ``_force``.
    Linear models (and nonlinear ones, for their small-oscillation limit)
    implement ``stiffness_matrix`` (the Hessian of V at q = 0).
    """

    name: ClassVar[str] = "model"
    #: True when the equations of motion are linear (``F = -K q``).
    linear: bool = False
    n_dof: int
    mass: np.ndarray
    coord_names: list[str]
    #: The constructor's keyword arguments, declared once
    #: (:class:`rk4h.models.params.Param` rows); None: read from the signature.
    parameters: ClassVar[tuple | None] = None
    #: One line on what the model is (the scene reference's ``[params]`` heading).
    summary: ClassVar[str] = ""
    #: True for a first-order ODE dy/dt = f(t, y) (state y, no coordinates,
    #: force or modes); False for a mechanical model with state [q, v].
    first_order: ClassVar[bool] = False

    @classmethod
    def check_parameters(cls, values: dict) -> None:
        """Rules between parameters that no single :class:`Param` row states;
        ``values`` holds every declared parameter (defaults filled in). Raise
        :class:`rk4h.models.params.ParamRule` naming the parameter blamed.
        The default checks nothing."""

    # -- to implement -----------------------------------------------------
    def _potential(self, q, ops):  # pragma: no cover - abstract
        raise NotImplementedError

    def _force(self, q, ops):  # pragma: no cover - abstract
        raise NotImplementedError

    def stiffness_matrix(self) -> np.ndarray:
        """Hessian of ``V`` at the equilibrium ``q = 0`` (N/m, or N m/rad)."""
        raise NotImplementedError(f"{self.name} has no stiffness matrix")

    def params(self) -> dict:
        """The parameters the model was built with (plain Python values)."""
        raise NotImplementedError

    def uniform_chain(self) -> tuple[float, float] | None:
        """``(m, k)`` (kg, N/m) when the model is drawn as masses on a line and
        its linearization is that of equal masses ``m`` on equal springs ``k``
        between two walls: stiffness matrix ``k tridiag(-1, 2, -1)`` (to
        1e-12 relative). Else None. Read from the drawing and the mechanics,
        never from the model's name; a model without a stiffness matrix gives
        None."""
        import scipy.sparse as sp

        if self.drawing().layout != "line":
            return None
        mass = np.asarray(self.mass, dtype=float)
        if mass.size == 0 or np.any(mass != mass[0]):
            return None
        try:
            try:
                K = self.stiffness_matrix(sparse=True)
            except TypeError:
                K = self.stiffness_matrix()
        except NotImplementedError:
            return None
        K = sp.csr_matrix(K, dtype=float)
        diag, up, low = K.diagonal(), K.diagonal(1), K.diagonal(-1)
        outside = float(abs(K).sum() - np.abs(diag).sum() - np.abs(up).sum() - np.abs(low).sum())
        k = float(diag[0]) / 2.0
        tol = 1e-12 * abs(k)
        uniform = (k > 0 and bool(np.all(np.abs(diag - 2 * k) <= tol)) and bool(np.all(np.abs(up + k) <= tol))
                   and bool(np.all(np.abs(low + k) <= tol)) and abs(outside) <= tol * mass.size)
        return (float(mass[0]), k) if uniform else None

    def force_kernel(self):
        """The compiled form of the force (:mod:`rk4h.models.compiled`),
        printed from the model's symbolic definition, or None (a model with a
        hand-written ``_force``: it runs on the numpy path)."""
        return None

    def drawing(self) -> Drawing:
        """How the model is drawn (:class:`Drawing`); by default its
        generalized coordinates against time."""
        return Drawing(layout="coordinates", point_labels=tuple(self.coord_names))

    def frequency_range(self) -> tuple[float, float]:
        """``(omega_min, omega_max)`` (rad/s): the slowest non-zero and the
        fastest natural angular frequency of the linearization (a dense
        eigensolve; models with large sparse stiffness matrices override
        it)."""
        if self.n_dof > 400:
            raise ValueError(f"`model` {self.name!r} with {self.n_dof} DOF: no frequency estimate without a "
                             f"dense eigensolve")
        w = self.modes()[0]
        nz = w[w > 1e-12 * w[-1]] if w.size and w[-1] > 0 else w[:0]
        if not nz.size:
            raise ValueError(f"`model` {self.name!r}: its linearization has no non-zero frequency")
        return float(nz[0]), float(w[-1])

    # -- constants computed once --------------------------------------------
    def constant(self, name: str, compute):
        """``compute()`` the first time ``name`` is asked for a model with
        these equations (:func:`model_constants`), the kept value after; a
        model without a fingerprint computes every time. An exception is
        not kept. Callers never modify the value (arrays are kept read-only
        or copied by the caller)."""
        record = model_constants(self)
        if record is None:
            return compute()
        try:
            return record[name]
        except KeyError:
            value = record[name] = compute()
        _account(record, value)
        return value

    # -- validation ---------------------------------------------------------
    def _gershgorin_w2(self) -> float:
        """``max_i sum_j |K_ij| / m_i`` (rad^2/s^2): the square of
        :meth:`omega_bound`, computed once per model (:meth:`constant`).
        Raises ``NotImplementedError`` without a stiffness matrix."""
        return self.constant("gershgorin_w2", self._compute_gershgorin_w2)

    def _compute_gershgorin_w2(self) -> float:
        """:meth:`_gershgorin_w2` computed from the stiffness matrix."""
        try:
            K = self.stiffness_matrix(sparse=True)
        except TypeError:
            K = self.stiffness_matrix()
        row = np.asarray(abs(K).sum(axis=1), dtype=float).ravel()
        return float(np.max(row / self.mass))

    def omega_bound(self) -> float:
        """Gershgorin upper bound (rad/s) on the largest linearised natural
        angular frequency, ``sqrt(max_i sum_j |K_ij| / m_i)``; O(nnz(K)), no
        eigensolve. Raises ``NotImplementedError`` without a stiffness matrix."""
        return float(np.sqrt(self._gershgorin_w2()))

    def _check_scales(self, name: str) -> None:
        """Refuse parameters whose fastest linearised frequency is not finite
        and > 0 (Gershgorin bound :meth:`omega_bound`, rad/s).

        Called at the end of each model's constructor; ``name`` is the
        stiffness parameter to blame (with the masses). Raises ``ValueError``
        (one line)."""
        with np.errstate(all="ignore"):
            try:  # in the constructor: the parameters may not all be set yet, so not cached
                w2 = self._compute_gershgorin_w2()
            except NotImplementedError:  # no linearization: nothing to check
                return
        if not (math.isfinite(w2) and w2 > 0.0 and math.isfinite(math.sqrt(w2))):
            raise ValueError(f"`{name}` must give, with the masses, a finite positive fastest frequency "
                             f"(Gershgorin bound sqrt(max_i sum_j |K_ij| / m_i)), got omega^2 = {w2!r} rad^2/s^2")

    def state_problem(self, y) -> str | None:
        """Why ``y`` is not a state the equations can be integrated from, or
        None when it is.

        A state is refused when its total energy (J) or its generalized force
        (N, or N m) is not finite: a spring of zero length (planar4 on an
        anchor, two triangle masses on top of each other: the force divides
        by zero) or a displacement so large that ``k x^2`` overflows. Nothing
        is integrated; this costs one evaluation of the force and the energy.

        Parameters
        ----------
        y : array_like, shape (2 n_dof,)
            State ``[q, v]`` in the model's units (m, m/s; rad, rad/s).

        Returns
        -------
        str or None
            One clause ("the force is not finite there (...)"), or None.
        """
        y = np.asarray(y, dtype=float)
        n = self.n_dof
        if y.shape != (2 * n,):
            return f"it has shape {y.shape}, not ({2 * n},)"
        if not np.all(np.isfinite(y)):
            return "it is not finite"
        with np.errstate(all="ignore"):
            try:
                f = self.force(y[:n])
                e = float(self.energy(y))
            except Exception as exc:  # noqa: BLE001 - any failure at y0 is a refusal naming y0
                text = " ".join(str(exc).split())[:200]
                return f"evaluating the force and energy raised {type(exc).__name__}: {text}"
        bad = np.flatnonzero(~np.isfinite(f))
        if bad.size:
            return (f"the force is not finite there (component {self.coord_names[bad[0]]} = {float(f[bad[0]])!r}; "
                    f"a spring of zero length, or an overflow)")
        if not math.isfinite(e):
            return f"its energy is not finite ({e!r} J; an overflow)"
        return None

    def check_state(self, y, name: str = "y0") -> np.ndarray:
        """``y`` as a float array if :meth:`state_problem` finds nothing wrong.

        Used by ``rk4h.references.solvers.integrate`` and
        ``rk4h.references.truth.reference_solution`` on the initial state.

        Parameters
        ----------
        y : array_like, shape (2 n_dof,)
            State ``[q, v]`` (m, m/s; rad, rad/s).
        name : str
            Field named in the error.

        Returns
        -------
        ndarray, shape (2 n_dof,)

        Raises
        ------
        ValueError
            One line, e.g. "`y0` must be a state of planar4 with finite force
            and energy: the force is not finite there (...), got [...]".
        """
        problem = self._state_problem_once(y)
        if problem is not None:
            shown = np.array2string(np.asarray(y, dtype=float), precision=6, max_line_width=10**6,
                                    threshold=12, separator=", ")
            raise ValueError(f"`{name}` must be a state of {self.name} with finite force and energy: "
                             f"{problem}, got {shown}")
        return np.asarray(y, dtype=float)

    def _state_problem_once(self, y):
        """:meth:`state_problem`, kept for the last few exact states (bytes)
        checked on a model with these equations: a sweep integrates one
        ``y0`` many times."""
        a = np.asarray(y)
        keep = a.dtype == np.float64 and a.ndim == 1 and a.size <= _STATE_MAX_SIZE
        record = model_constants(self) if keep else None
        if record is None:
            return self.state_problem(y)
        key = a.tobytes()
        with _CONSTANTS_LOCK:
            states = record.setdefault("_states", OrderedDict())
            if key in states:
                states.move_to_end(key)
                return states[key]
        problem = self.state_problem(y)
        with _CONSTANTS_LOCK:
            states[key] = problem
            while len(states) > _STATES_MAXSIZE:
                states.popitem(last=False)
        return problem

    # -- change detection (model_current) ------------------------------------
    def __setattr__(self, name, value):
        # rebinding an attribute voids the change record: the next model_current
        # drops every per-object cache (a new attribute, or a cache, does not)
        d = self.__dict__
        if name in d and name not in OBJECT_CACHES:
            d.pop(_WATCH, None)
        object.__setattr__(self, name, value)

    def __delattr__(self, name):
        if name not in OBJECT_CACHES:
            self.__dict__.pop(_WATCH, None)
        object.__delattr__(self, name)

    def __getstate__(self):
        # pickle and copy take the model's attributes, never its per-object caches
        # (compiled loops, closures, the change record): the copy works them out again
        return {k: v for k, v in self.__dict__.items() if k not in OBJECT_CACHES}

    # -- numpy evaluation ---------------------------------------------------
    @property
    def n_state(self) -> int:
        return 2 * self.n_dof

    def potential(self, q) -> np.ndarray | float:
        """Potential energy (J) of ``q`` with shape (n_dof,) or (n_dof, m)."""
        return self._potential(np.asarray(q, dtype=float), NUMPY)

    def force(self, q) -> np.ndarray:
        """Generalized force ``-grad V`` (N or N m) at ``q``, same shape as ``q``."""
        q = np.asarray(q, dtype=float)
        return np.asarray(self._force(q, NUMPY), dtype=float).reshape(q.shape)

    def acceleration(self, q) -> np.ndarray:
        q = np.asarray(q, dtype=float)
        f = self.force(q)
        return f / (self.mass if q.ndim == 1 else self.mass[:, None])

    def rhs(self, t, y) -> np.ndarray:
        """``dy/dt`` for ``y = [q, v]``; the ``fun(t, y)`` every solver integrates."""
        n = self.n_dof
        out = np.empty_like(y, dtype=float)
        out[:n] = y[n:]
        out[n:] = self.acceleration(y[:n])
        return out

    def energy(self, y) -> np.ndarray | float:
        """Total energy ``T + V`` (J) of ``y`` with shape (2 n_dof,) or (2 n_dof, m)."""
        y = np.asarray(y, dtype=float)
        n = self.n_dof
        q, v = y[:n], y[n:]
        m = self.mass if y.ndim == 1 else self.mass[:, None]
        return 0.5 * np.sum(m * v * v, axis=0) + self.potential(q)

    def jacobian(self, t=None, y=None) -> np.ndarray:
        """Jacobian of ``rhs`` (dense, shape (2n, 2n)).

        Linear models: exact and constant. Nonlinear models: central
        differences of the force (relative step 1e-6 of the state scale).
        """
        n = self.n_dof
        J = np.zeros((2 * n, 2 * n))
        J[:n, n:] = np.eye(n)
        if self.linear:
            J[n:, :n] = -self.stiffness_matrix() / self.mass[:, None]
        else:
            q = np.asarray(y[:n], dtype=float)
            eps = 1e-6 * max(1.0, float(np.max(np.abs(q))) if q.size else 1.0)
            E = np.eye(n) * eps
            dF = (self.force(q[:, None] + E) - self.force(q[:, None] - E)) / (2 * eps)
            J[n:, :n] = dF / self.mass[:, None]
        return J

    # -- heyoka evaluation --------------------------------------------------
    def heyoka_system(self):
        """``(vars, rhs_exprs)`` for ``heyoka.taylor_adaptive``: state ``[q, v]``.

        The masses are numeric constants here, and heyoka folds ``f / m`` into
        ``f * fl(1/m)`` with the reciprocal rounded to double: exact to an ulp in
        double precision, but a different mass (relative ~1e-17) in ``real128``.
        The solvers therefore integrate
        :func:`rk4h.references.solvers.taylor.scaled_system`, which builds on the
        same ``_force`` and passes the masses as runtime parameters."""
        from rk4h._heyoka import heyoka as _heyoka
        hy = _heyoka()

        names = [f"q{i}" for i in range(self.n_dof)] + [f"v{i}" for i in range(self.n_dof)]
        vs = hy.make_vars(*names)
        vs = list(vs) if isinstance(vs, (list, tuple)) else [vs]
        q = np.array(vs[: self.n_dof], dtype=object)
        f = np.asarray(self._force(q, HEYOKA), dtype=object).reshape(-1)
        acc = [f[i] / float(self.mass[i]) for i in range(self.n_dof)]
        return vs, list(vs[self.n_dof:]) + acc

    def heyoka_energy(self, vs):
        """heyoka expression of the total energy, for the variables ``vs``."""
        q = np.array(vs[: self.n_dof], dtype=object)
        v = vs[self.n_dof:]
        T = sum(0.5 * float(self.mass[i]) * v[i] * v[i] for i in range(self.n_dof))
        return T + self._potential(q, HEYOKA)

    # -- linear analysis ----------------------------------------------------
    def modes(self):
        """Natural angular frequencies (rad/s, ascending) and mass-normalised
        mode shapes (columns) of the linearization: ``K phi = omega^2 M phi``.

        Solved once per model (:meth:`constant`); each call returns new
        arrays."""
        w, phi = self.constant("modes", self._compute_modes)
        # order="K": the layout eigh gave (Fortran), so that products with
        # phi.T take the BLAS path, and the rounding, they took before
        return w.copy(order="K"), phi.copy(order="K")

    def _compute_modes(self):
        """:meth:`modes` from a dense generalized eigensolve (``scipy.linalg.eigh``)."""
        from scipy.linalg import eigh

        K = np.asarray(self.stiffness_matrix(), dtype=float)
        lam, phi = eigh(K, np.diag(self.mass))
        scale = np.max(np.abs(lam)) if lam.size else 1.0
        lam = np.where(np.abs(lam) < 1e-12 * scale, 0.0, lam)  # zero modes stay zero
        return np.sqrt(np.clip(lam, 0.0, None)), phi

    def state(self, x, v=None) -> np.ndarray:
        """Flat state ``[q, v]`` from coordinates and velocities."""
        x = np.asarray(x, dtype=float)
        v = np.zeros_like(x) if v is None else np.asarray(v, dtype=float)
        return np.concatenate([x, v])

    def __repr__(self):
        args = ", ".join(f"{k}={v!r}" for k, v in self.params().items())
        return f"{type(self).__name__}({args})"


class Defined(Model):
    """A model whose mechanics is another model's definition -- a spring
    :class:`~rk4h.models.Network` or a :class:`~rk4h.models.PotentialModel`
    -- under its own parameters, name and coordinate names.

    Subclasses set ``self.definition`` (and ``name``, ``coord_names``,
    ``params``); force, potential, stiffness matrix, heyoka's equations and
    the compiled kernels are the definition's.
    """

    definition: Model

    def _adopt(self, build, blame: str) -> None:
        """Build the definition with ``build()`` and take its mass, size and
        linearity; its refusal (``ValueError``) is re-raised naming this
        model's parameter ``blame``."""
        try:
            definition = build()
        except ValueError as e:
            raise ValueError(f"`{blame}` (with the other parameters of {self.name}): {e}") from None
        self.definition = definition
        self.n_dof = definition.n_dof
        self.mass = definition.mass
        self.linear = definition.linear

    def _force(self, q, ops):
        return self.definition._force(q, ops)

    def _potential(self, q, ops):
        return self.definition._potential(q, ops)

    def stiffness_matrix(self, sparse: bool = False):
        K = self.definition.stiffness_matrix()
        K = np.asarray(K.toarray() if hasattr(K, "toarray") else K, dtype=float)
        if sparse:
            import scipy.sparse as sp

            return sp.csr_matrix(K)
        return K

    def force_kernel(self):
        return self.definition.force_kernel()
