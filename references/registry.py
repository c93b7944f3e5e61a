"""The method registry: every integrator the harness can run, as data.

A :class:`Method` knows its kind, its expected order, its cost per step and
its style in figures; nothing outside this module decides anything from a
method's name. Kinds (docs/user-guide.md, "Bringing your own
integrator"):

``tableau``
    An explicit Runge-Kutta method given by its Butcher tableau
    (:func:`rk4h.methods.make_tableau`): order from the order conditions,
    cost per step counting first-same-as-last reuse.
``partitioned``
    A partitioned tableau for ``y = [q, v]`` with ``dq/dt = v`` (symplectic
    Euler, Stormer-Verlet).
``python``
    ``"package.module:function"``, a step ``f(fun, t, y, h) -> y_next`` with
    a declared ``order``; run on the generic loop of
    :mod:`rk4h.references.solvers.stepper`, its right-hand-side calls counted.
``command``
    An external program run through the file protocol of
    :mod:`rk4h.command` (problem in, trajectory out), with a declared
    ``order``.
``reference``
    ``dop853``, ``cvode-adams``, ``cvode-bdf``, ``heyoka``: adaptive, their
    setting is ``rtol``.

Each method also carries, as data, what the harness needs to decide about it
without reading its name: its adapter (which runner integrates a reference),
its capabilities (:attr:`Method.adaptive`, :attr:`Method.partitioned`,
``implicit``, ``stiff``), its cost unit (:class:`CostUnit`: what its ``nfev``
counts, and :meth:`Method.cost` to put every run in right-hand-side calls) and
the roles the stability study and the advisor give it (``roles``,
``long_rtol``, ``advisor_rtols``).

Built-in methods are :data:`BUILTIN`; a scene adds its own with
``[methods.NAME]`` tables (:func:`method_from_table`) and
:func:`resolve` looks a name up in the scene's methods first, then in the
built-ins. Methods of the first four kinds are *fixed-step*: their setting is
the step ``h`` (s).
"""
from __future__ import annotations

import importlib
import re
from dataclasses import dataclass, field
from enum import Enum
from typing import Mapping

__all__ = ["Kind", "CostUnit", "Style", "Method", "BUILTIN", "BUILTIN_TABLEAUX", "GEOMETRIC_TABLEAUX", "REFERENCES",
           "UNDER_TEST",
           "CONVERGENCE_ALWAYS", "BOUNDARY_ALWAYS", "GROWTH_ALWAYS", "resolve", "names", "with_role", "long_references",
           "method_from_table", "methods_from_tables", "MethodError"]


class Kind(str, Enum):
    """What a method is, and so how it is run."""

    TABLEAU = "tableau"
    PARTITIONED = "partitioned"
    PYTHON = "python"
    COMMAND = "command"
    REFERENCE = "reference"


class CostUnit(str, Enum):
    """What a method's run counts in ``nfev``, so costs compare across
    methods (:meth:`Method.cost` turns each into right-hand-side calls)."""

    #: Every call of the right-hand side: each stage of each attempted step
    #: (rejected steps included), nothing left out.
    RHS = "rhs"
    #: Every call of the right-hand side, the Jacobian's difference quotients
    #: included; evaluations of an analytic Jacobian are counted apart
    #: (``extra["njev"]``), each about two vectorised force evaluations
    #: (CVODE, references/solvers/cvode.py).
    RHS_WITH_JACOBIAN_DQ = "rhs+jacobian-dq"
    #: The solver's own count, which leaves out the right-hand-side calls of
    #: its Jacobian's difference quotients (scipy's Radau and BDF: ``njev``
    #: Jacobians of ``n`` calls each come on top); an adapter of such a solver
    #: declares this unit so its cost is not read as comparable.
    RHS_WITHOUT_JACOBIAN = "rhs-without-jacobian"
    #: No right-hand-side calls (``nfev = 0``): Taylor steps times the Taylor
    #: order, each order one pass over the equations (heyoka).
    TAYLOR_STEPS = "taylor-steps"

    @property
    def text(self) -> str:
        """One line for tables and notes."""
        return _COST_TEXT[self]


_COST_TEXT = {
    CostUnit.RHS: "right-hand-side calls",
    CostUnit.RHS_WITH_JACOBIAN_DQ: "right-hand-side calls, Jacobian difference quotients included",
    CostUnit.RHS_WITHOUT_JACOBIAN: "right-hand-side calls, Jacobian calls left out",
    CostUnit.TAYLOR_STEPS: "Taylor steps x order",
}


@dataclass(frozen=True)
class Style:
    """How a method looks in every figure."""

    color: str
    marker: str


@dataclass(frozen=True, eq=False)
class Method:
    """One integrator.

    Attributes
    ----------
    name : str
        Registry name, as scenes list it in ``run.solvers``.
    kind : Kind
    order : int or None
        Expected order of accuracy: computed from the order conditions for a
        tableau, declared for ``python`` and ``command`` methods, None for the
        adaptive references.
    nfev_per_step : int or None
        Right-hand-side evaluations per step in steady state (first-same-as-last
        reuse counted); None when unknown before a run (python, command,
        references).
    style : Style
    description : str
    tableau : rk4h.methods.Tableau or None
        For ``tableau`` and ``partitioned`` methods.
    target : str or None
        ``"package.module:function"`` of a ``python`` method.
    argv : tuple of str or None
        The command line of a ``command`` method, with the placeholders of
        :mod:`rk4h.command`.
    definition : dict
        The scene's ``[methods.NAME]`` table as written (empty for built-ins);
        part of the scene's digest, so a changed definition reruns.
    adapter : str or None
        The runner of a ``reference`` (a key of
        ``rk4h.references.solvers.REFERENCE_RUNNERS``); None for the other kinds,
        whose kind names their runner.
    implicit : bool
        Solves an implicit (Newton) system each step.
    stiff : bool
        Meant for stiff problems: its step is not held by the fastest mode's
        stability (BDF).
    cost_unit : CostUnit
        What ``nfev`` of its runs counts.
    roles : frozenset of str
        Where the harness uses it as a comparison: ``"cost"`` (a reference
        of the stability study's cost sweeps), ``"banded"`` (the large-N
        study's reference, run with a banded linear solver:
        :func:`rk4h.validation.stability.large_n.cvode_band_cost`).
    long_rtol : float or None
        ``rtol`` of its run as a long-horizon reference of the stability
        study; None: not one.
    advisor_rtols : tuple of float or None
        The two tolerances the advisor first probes it at; None: the
        advisor's default pair.
    rtol_floor : float or None
        The tightest ``rtol`` the harness runs it at (confirmation runs);
        None: the harness' default (100 machine epsilons).
    native_steps : bool
        A reference whose steps run in compiled code, no Python call per
        step (heyoka's Taylor integrator, compiled once per process); the
        other references step through Python (scipy's DOP853, CVODE calling
        a Python right-hand side). Read by the workers' cost estimate
        (:mod:`rk4h.validation.workers`).
    """

    name: str
    kind: Kind
    order: int | None
    nfev_per_step: int | None
    style: Style
    description: str = ""
    tableau: object = None
    target: str | None = None
    argv: tuple | None = None
    definition: dict = field(default_factory=dict)
    adapter: str | None = None
    implicit: bool = False
    stiff: bool = False
    cost_unit: CostUnit = CostUnit.RHS
    roles: frozenset = frozenset()
    long_rtol: float | None = None
    advisor_rtols: tuple | None = None
    rtol_floor: float | None = None
    native_steps: bool = False

    @property
    def adaptive(self) -> bool:
        """True for the references: the setting is ``rtol``, the step chosen
        by the method."""
        return not self.fixed_step

    @property
    def runner_key(self) -> str:
        """What dispatch tables are keyed by: :attr:`adapter` (the runner of a
        reference), else the method's name (a method without one)."""
        return self.adapter or self.name

    @property
    def partitioned(self) -> bool:
        """True for a partitioned tableau (positions and velocities advanced by
        different weights)."""
        return self.kind is Kind.PARTITIONED

    @property
    def taylor(self) -> bool:
        """True for a Taylor method: its cost is steps x order, not calls."""
        return self.cost_unit is CostUnit.TAYLOR_STEPS

    def cost(self, nfev: int, n_steps: int, taylor_order: int = 0) -> float:
        """A run's cost in right-hand-side calls (or passes over the
        equations), read in this method's :attr:`cost_unit`: ``nfev``, or
        ``n_steps * taylor_order`` for a Taylor method."""
        if self.taylor:
            return float(n_steps * (taylor_order or 0))
        return float(nfev)

    @property
    def fixed_step(self) -> bool:
        """True for every kind but ``reference``: the setting is the step ``h``."""
        return self.kind is not Kind.REFERENCE

    @property
    def setting_name(self) -> str:
        """``"h"`` for fixed-step methods, ``"rtol"`` for the references."""
        return "h" if self.fixed_step else "rtol"

    def step_function(self):
        """The imported step function of a ``python`` method."""
        if self.kind is not Kind.PYTHON:
            raise ValueError(f"method {self.name!r} is a {self.kind.value} method, not a python one")
        return _import_target(self.name, self.target)

    def __repr__(self):
        return f"Method({self.name!r}, {self.kind.value}, order={self.order})"


class MethodError(ValueError):
    """A method definition that cannot be used: ``field`` names the key
    (``A``, ``python``, ``order``...) of ``[methods.NAME]``."""

    def __init__(self, name: str, fld: str, problem: str):
        self.name, self.field, self.problem = name, fld, problem
        super().__init__(f"method {name!r}: `{fld}` {problem}")


# -- built-ins -------------------------------------------------------------------
_STYLES = {
    "rk4": Style("#d62728", "o"),
    "euler": Style("#ff7f0e", "v"),
    "symplectic-euler": Style("#8c564b", "^"),
    "stormer-verlet": Style("#e377c2", "<"),
    "rk38": Style("#bcbd22", ">"),
    "heun3": Style("#7f7f7f", "h"),
    "ralston": Style("#aec7e8", "p"),
    "yoshida4": Style("#637939", "d"),
    "yoshida6": Style("#8c6d31", "H"),
    "suzuki4": Style("#843c39", "8"),
    "forest-ruth": Style("#7b4173", "X"),
    "blanes-moan4": Style("#3182bd", "1"),
    "blanes-moan6": Style("#31a354", "2"),
    "dop853": Style("#1f77b4", "s"),
    "cvode-adams": Style("#2ca02c", "D"),
    "cvode-bdf": Style("#17becf", "P"),
    "heyoka": Style("#9467bd", "*"),
}
#: Colours and markers handed, in scene order, to a scene's own methods.
_USER_STYLES = (Style("#ff9896", "X"), Style("#98df8a", "d"), Style("#c5b0d5", "H"), Style("#c49c94", "8"),
                Style("#f7b6d2", "1"), Style("#dbdb8d", "2"), Style("#9edae5", "3"), Style("#393b79", "4"))
_REFERENCE_TEXT = {
    "dop853": "scipy's explicit Runge-Kutta 8(5,3), adaptive",
    "cvode-adams": "SUNDIALS CVODE, variable-order Adams-Moulton, adaptive",
    "cvode-bdf": "SUNDIALS CVODE, variable-order BDF, adaptive",
    "heyoka": "heyoka's Taylor method, adaptive order and step",
}
#: The adaptive references as data: adapter, capabilities, cost unit, roles.
_REFERENCE_DATA = {
    "dop853": dict(adapter="dop853", cost_unit=CostUnit.RHS, roles=frozenset({"cost"})),
    "cvode-adams": dict(adapter="cvode-adams", implicit=True, cost_unit=CostUnit.RHS_WITH_JACOBIAN_DQ),
    "cvode-bdf": dict(adapter="cvode-bdf", implicit=True, stiff=True, cost_unit=CostUnit.RHS_WITH_JACOBIAN_DQ,
                      roles=frozenset({"cost", "banded"}), long_rtol=1e-10),
    # heyoka's Taylor method in double precision runs down to 10 eps (scipy
    # raises DOP853's rtol below 100 eps to 100 eps; CVODE's is taken the same)
    "heyoka": dict(adapter="heyoka", cost_unit=CostUnit.TAYLOR_STEPS, roles=frozenset({"cost"}), long_rtol=1e-12,
                   advisor_rtols=(1e-4, 1e-10), rtol_floor=10 * 2.0 ** -52, native_steps=True),
}
#: The method whose trust the harness measures first (the thesis' RK4): the
#: one the state figures, the modal-energy runs, the wave packets and the
#: stability study integrate with.
UNDER_TEST = "rk4"
#: Methods whose convergence order every scene with a ``convergence`` output
#: measures, beside its own fixed-step methods: the thesis' RK4 and its
#: first-order contrasts.
CONVERGENCE_ALWAYS = ("rk4", "euler", "symplectic-euler")
#: Built-in methods whose stability boundary every stability ``boundary``
#: study measures (a scene's own tableaux in ``run.solvers`` are added).
BOUNDARY_ALWAYS = ("rk4", "symplectic-euler", "stormer-verlet", "euler")
#: Built-in methods drawn in every growth-factor figure of the stability
#: study, beside its own method: BOUNDARY_ALWAYS less Stormer-Verlet, whose
#: step matrix on a harmonic mode has the trace (2 - theta^2) and determinant
#: (1) of symplectic Euler's, so the same growth factor: its curve would hide
#: under symplectic Euler's.
GROWTH_ALWAYS = ("rk4", "symplectic-euler", "euler")


def _tableau_method(tab, order: int | None = None) -> Method:
    kind = Kind.PARTITIONED if tab.partitioned else Kind.TABLEAU
    return Method(tab.name, kind, int(tab.order if order is None else order), int(tab.nfev_per_step),
                  _STYLES.get(tab.name, _USER_STYLES[0]), tab.description, tableau=tab)


#: The tableaux of ``rk4h.methods.METHODS`` a scene may list without
#: defining them: the thesis' three methods, Stormer-Verlet and the shipped
#: geometric methods (:data:`GEOMETRIC_TABLEAUX`). The other tableaux of
#: rk4core's library (``rk38``, ``heun3``, ``ralston``) serve ``rk4h.solve``
#: callers; a scene defines its own (the README's ``[methods.rk38]``
#: example), so their names stay free for scenes.
BUILTIN_TABLEAUX = ("rk4", "euler", "symplectic-euler", "stormer-verlet")
#: The shipped splitting and composition methods (``rk4h.geometric.GEOMETRIC``),
#: built-ins of every scene: what a user runs instead of RK4 over long
#: horizons, so a scene names them in ``run.solvers`` without copying their
#: coefficients. Listed by name so that importing the registry does not
#: build their tableaux; a test holds the list equal to ``GEOMETRIC``.
GEOMETRIC_TABLEAUX = ("yoshida4", "yoshida6", "suzuki4", "forest-ruth", "blanes-moan4", "blanes-moan6")
#: The order of each of :data:`GEOMETRIC_TABLEAUX`, as data: their order
#: conditions in exact arithmetic cost about 0.5 s CPU (yoshida6 most), which
#: every process importing the registry would pay for methods most runs never
#: use. Each tableau's own ``order`` is still computed from its order
#: conditions when a table or check reads it, and ``tests/test_startup.py``
#: recomputes each and holds it equal to this.
_GEOMETRIC_ORDERS = {"yoshida4": 4, "yoshida6": 6, "suzuki4": 4, "forest-ruth": 4, "blanes-moan4": 4,
                     "blanes-moan6": 6}


def _builtins() -> dict[str, Method]:
    from rk4h.methods import METHODS

    out = {name: _tableau_method(METHODS[name], _GEOMETRIC_ORDERS.get(name))
           for name in BUILTIN_TABLEAUX + GEOMETRIC_TABLEAUX}
    for name, text in _REFERENCE_TEXT.items():
        out[name] = Method(name, Kind.REFERENCE, None, None, _STYLES[name], text, **_REFERENCE_DATA[name])
    return out


#: Every built-in method by name: the tableaux of ``rk4h.methods.METHODS``
#: named in :data:`BUILTIN_TABLEAUX` and :data:`GEOMETRIC_TABLEAUX`, and the
#: four adaptive references.
BUILTIN: dict[str, Method] = _builtins()
#: Names of the adaptive references.
REFERENCES: tuple[str, ...] = tuple(n for n, m in BUILTIN.items() if m.kind is Kind.REFERENCE)


def with_role(role: str) -> tuple[str, ...]:
    """Names of the built-in methods whose ``roles`` hold ``role``, in
    :data:`BUILTIN` order."""
    return tuple(n for n, m in BUILTIN.items() if role in m.roles)


def long_references() -> tuple[tuple[str, float], ...]:
    """``(name, rtol)`` of the built-ins with a ``long_rtol``: the stability
    study's long-horizon references, tightest first."""
    return tuple(sorted(((n, m.long_rtol) for n, m in BUILTIN.items() if m.long_rtol is not None),
                        key=lambda p: p[1]))


def names(local: Mapping[str, Method] | None = None) -> list[str]:
    """Every method name a scene with methods ``local`` may list."""
    return list(BUILTIN) + [n for n in (local or {}) if n not in BUILTIN]


def resolve(method, local: Mapping[str, Method] | None = None) -> Method:
    """The :class:`Method` named ``method`` (the scene's ``local`` methods
    first, then :data:`BUILTIN`); a :class:`Method` is returned as is.

    Raises ``ValueError`` naming ``solver`` for an unknown name."""
    if isinstance(method, Method):
        return method
    if local and method in local:
        return local[method]
    try:
        return BUILTIN[method]
    except (KeyError, TypeError):
        raise ValueError(f"`solver` must be one of {names(local)}, got {method!r}") from None


# -- methods from scenes ---------------------------------------------------------
_TARGET = re.compile(r"[A-Za-z_][A-Za-z0-9_]*(\.[A-Za-z_][A-Za-z0-9_]*)*:[A-Za-z_][A-Za-z0-9_]*")
_KEYS = {"A", "b", "c", "A_v", "b_v", "description", "python", "command", "order", "nfev_per_step",
         "kind", "a", "base", "gamma"}
#: Keys of a ``kind = "splitting"`` / ``"composition"`` method (rk4h.geometric).
_GEOMETRIC_KEYS = {"splitting": ("a", "b"), "composition": ("base", "gamma")}
_METHOD_NAME = re.compile(r"[a-z0-9][a-z0-9_.-]{0,39}")


def _import_target(name: str, target: str):
    mod, _, fn = target.partition(":")
    try:
        obj = getattr(importlib.import_module(mod), fn)
    except Exception as e:  # noqa: BLE001 - any import failure is the definition's
        raise MethodError(name, "python", f"cannot be imported ({type(e).__name__}: {e}), got {target!r}") from None
    if not callable(obj):
        raise MethodError(name, "python", f"must name a callable, got {target!r}")
    return obj


def _declared_order(name, table) -> int:
    if "order" not in table:
        raise MethodError(name, "order", "is missing (python and command methods declare their order)")
    order = table["order"]
    if isinstance(order, bool) or not isinstance(order, int) or not 1 <= order <= 20:
        raise MethodError(name, "order", f"must be an integer in 1..20, got {order!r}")
    return order


def _declared_cost(name, table) -> int | None:
    cost = table.get("nfev_per_step")
    if cost is not None and (isinstance(cost, bool) or not isinstance(cost, int) or cost < 0):
        raise MethodError(name, "nfev_per_step", f"must be an integer >= 0, got {cost!r}")
    return cost


def _builtin_clash(name: str) -> str:
    """Why a scene's ``[methods.NAME]`` may not take a built-in's name: the
    built-in it names, and the two ways out."""
    m = BUILTIN[name]
    what = m.description.split(" (")[0] if m.description else m.kind.value
    return (f"is the built-in method {name!r} ({what}); list {name!r} in `run.solvers` without a [methods] "
            f"table to run it, or give your own method another name (e.g. {name + '-as-data'!r})")


def method_from_table(name: str, table: Mapping, index: int = 0) -> Method:
    """A :class:`Method` from a scene's ``[methods.NAME]`` table.

    Exactly one of: a tableau (``A``, ``b``, optional ``c``; ``A_v`` and
    ``b_v`` make it partitioned; numbers or rational strings such as
    ``"1/3"``), ``python = "package.module:function"`` or ``command = [argv...]``;
    the last two need ``order``. Raises :class:`MethodError` naming the key."""
    from rk4h.methods import make_tableau

    if not isinstance(name, str) or not _METHOD_NAME.fullmatch(name):
        raise MethodError(str(name), "name", "must be 1 to 40 lowercase letters, digits, '.', '-' or '_'")
    if name in BUILTIN:
        raise MethodError(name, "name", _builtin_clash(name))
    if not isinstance(table, Mapping):
        raise MethodError(name, "table", f"must be a table, got {table!r:.60}")
    unknown = sorted(set(table) - _KEYS)
    if unknown:
        raise MethodError(name, unknown[0], f"is not a method key (known: {', '.join(sorted(_KEYS))})")
    if "kind" in table or any(k in table for k in ("a", "base", "gamma")):
        return _geometric_method(name, table, index)
    kinds = [k for k in ("A", "python", "command") if k in table]
    if len(kinds) != 1:
        raise MethodError(name, "A", "give exactly one of a tableau (`A`, `b`), `python` or `command`")
    description = table.get("description", "")
    if not isinstance(description, str):
        raise MethodError(name, "description", f"must be a string, got {description!r:.60}")
    st = _USER_STYLES[index % len(_USER_STYLES)]
    definition = dict(table)
    if kinds[0] == "A":
        for key in ("order", "nfev_per_step"):
            if key in table:
                raise MethodError(name, key, "is computed from the tableau; remove it")
        if "b" not in table:
            raise MethodError(name, "b", "is missing")
        try:
            tab = make_tableau(name, table["A"], table["b"], table.get("c"), A_v=table.get("A_v"),
                               b_v=table.get("b_v"), description=description)
        except ValueError as e:
            text = str(e).splitlines()[0]
            m = re.search(r"`([A-Za-z_]+)`", text)
            raise MethodError(name, m.group(1) if m else "A", text.split(": ", 1)[-1]) from None
        kind = Kind.PARTITIONED if tab.partitioned else Kind.TABLEAU
        return Method(name, kind, int(tab.order), int(tab.nfev_per_step), st, description or "tableau",
                      tableau=tab, definition=definition)
    order = _declared_order(name, table)
    cost = _declared_cost(name, table)
    if kinds[0] == "python":
        target = table["python"]
        if not isinstance(target, str) or not _TARGET.fullmatch(target):
            raise MethodError(name, "python", f"must be 'package.module:function', got {target!r:.60}")
        _import_target(name, target)
        return Method(name, Kind.PYTHON, order, cost, st, description or f"python stepper {target}",
                      target=target, definition=definition)
    argv = table["command"]
    if (not isinstance(argv, list) or not argv or not all(isinstance(a, str) and a for a in argv)
            or len(argv) > 100):
        raise MethodError(name, "command", f"must be a non-empty list of non-empty strings, got {argv!r:.60}")
    return Method(name, Kind.COMMAND, order, cost, st, description or f"external program {argv[0]}",
                  argv=tuple(argv), definition=definition)


def methods_from_tables(tables: Mapping) -> dict[str, Method]:
    """Every ``[methods.NAME]`` of a scene, by name, in the order written."""
    if not isinstance(tables, Mapping):
        raise MethodError("methods", "methods", f"must be a table of method tables, got {tables!r:.60}")
    return {name: method_from_table(name, t, i) for i, (name, t) in enumerate(tables.items())}


def _geometric_method(name: str, table: Mapping, index: int) -> Method:
    """A ``kind = "splitting"`` (``a``, ``b``) or ``kind = "composition"``
    (``base``, ``gamma``) method, converted to its partitioned tableau by
    :mod:`rk4h.geometric`; ``kind = "tableau"`` is the plain tableau."""
    from rk4h.geometric import composition_tableau, splitting_tableau

    kind = table.get("kind")
    allowed = ("tableau", "splitting", "composition")
    if kind is None:
        extra = next(k for k in ("a", "base", "gamma") if k in table)
        raise MethodError(name, "kind", f"is missing: `{extra}` belongs to kind = \"splitting\" (a, b) or "
                                        f"\"composition\" (base, gamma)")
    if kind not in allowed:
        raise MethodError(name, "kind", f"must be one of {', '.join(allowed)}, got {kind!r:.40}")
    if kind == "tableau":
        for key in ("a", "base", "gamma"):
            if key in table:
                raise MethodError(name, key, "is not a key of a tableau (kind = \"tableau\" takes A, b, c, A_v, b_v)")
        return method_from_table(name, {k: v for k, v in table.items() if k != "kind"}, index)
    keys = _GEOMETRIC_KEYS[kind]
    for key in sorted(set(table) - set(keys) - {"kind", "description"}):
        raise MethodError(name, key, f"is not a key of kind = {kind!r} (it takes {', '.join(keys)}, description)")
    for key in keys:
        if key not in table:
            raise MethodError(name, key, "is missing")
    description = table.get("description", "")
    if not isinstance(description, str):
        raise MethodError(name, "description", f"must be a string, got {description!r:.60}")
    if kind == "composition" and not isinstance(table["base"], str):
        raise MethodError(name, "base", f"must be a method name, got {table['base']!r:.60}")
    try:
        if kind == "splitting":
            tab = splitting_tableau(name, table["a"], table["b"], description=description)
        else:
            tab = composition_tableau(name, table["base"], table["gamma"], description=description)
    except ValueError as e:
        text = str(e).splitlines()[0].split(": ", 1)[-1]
        m = re.match(r"`([A-Za-z_]+)` ", text)
        raise MethodError(name, m.group(1) if m else keys[0], text[m.end():] if m else text) from None
    kind_ = Kind.PARTITIONED if tab.partitioned else Kind.TABLEAU
    return Method(name, kind_, int(tab.order), int(tab.nfev_per_step), _USER_STYLES[index % len(_USER_STYLES)],
                  description or f"{kind} method", tableau=tab, definition=dict(table))
