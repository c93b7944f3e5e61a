"""What a scene may ask for in ``run.outputs``: one module per output.

Every module of this package whose name does not start with ``_`` defines
``OUTPUT``, an :class:`Output`; :data:`OUTPUTS` (name -> output, in
:attr:`Output.rank` order) is discovered from them, never from a list of
names. A new output outside the package goes through :func:`register`
(``docs/outputs.md`` shows one in a single file).

The rest of the harness iterates the registry:

* the scene schema's ``run.outputs`` enum and the scene reference
  (:mod:`rk4h.validation.scene_schema`), from :attr:`Output.name`,
  :attr:`Output.when` and :attr:`Output.what`;
* the default ``run.outputs`` (:func:`rk4h.validation.scenes.default_outputs`),
  from :attr:`Output.applies`;
* the plan (:func:`rk4h.validation.plan.plan`), from :attr:`Output.plan` and
  :attr:`Output.run_keep`; the execution of a purpose no built-in executes
  (:func:`executor`);
* the measurement (:func:`rk4h.validation.measure.measure`), from
  :attr:`Output.measure`;
* the report's tables, ``columns.json`` and ``docs/columns.md``
  (:mod:`rk4h.validation.tables`, :mod:`rk4h.validation.columns`), from
  :attr:`Output.tables`;
* figures (:mod:`rk4h.validation.draw`) and other files of the report
  (:func:`write_files`), from :attr:`Output.draw` and :attr:`Output.write`.

Nothing here imports the modules that iterate the registry (the layers test
forbids a pair of modules importing each other); the output modules import
what they delegate to inside their functions.
"""
from __future__ import annotations

import importlib
import pkgutil
from dataclasses import dataclass, field
from functools import cached_property
from types import MappingProxyType
from typing import Any, Callable, Mapping

__all__ = ["Output", "Table", "ModelFacts", "Planning", "Measuring", "FileJob", "OUTPUTS", "register",
           "unregister", "on_register", "names", "get", "help_rows", "table_names", "own_table", "executor", "drawer",
           "loops", "solver_loop", "run_keep", "write_files"]


def solver_loop(scene, spec) -> list:
    """``[("loop", spec.solver)]`` (:attr:`Output.loops`): the loop a spec
    that runs its own solver runs; none for a spec without a solver."""
    solver = getattr(spec, "solver", "")
    return [("loop", solver)] if solver else []


def _never(facts) -> bool:
    return False


@dataclass(frozen=True)
class Table:
    """A report table an output writes.

    ``columns`` is ``((name, unit, dtype, description), ...)`` in written
    order (units and dtypes as in :mod:`rk4h.validation.columns`); None for a
    built-in table declared in :mod:`rk4h.validation.tables` and
    :mod:`rk4h.validation.columns`. ``timing`` names the columns that hold
    timings (not reproducible between two runs)."""

    name: str
    columns: tuple | None = None
    description: str = ""
    timing: frozenset = frozenset()


@dataclass(frozen=True)
class Output:
    """One output: everything the harness needs to plan, run, measure and
    report it.

    Parameters
    ----------
    name : str
        The word a scene lists in ``run.outputs``.
    when, what : str
        The scene reference's text: when it applies (so is in the default
        ``run.outputs``), and what it adds to the report.
    rank : float
        Its place in :data:`OUTPUTS` (the schema's enum, the default list).
    applies : callable
        ``applies(facts: ModelFacts) -> bool``: whether it is in the default
        ``run.outputs`` of a scene with that model.
    plan : callable or None
        ``plan(p: Planning) -> [RunSpec]``: the runs it needs. Two outputs
        may plan the same spec; the plan keeps one run per key.
    plan_rank, measure_rank : float
        The order of the plan (= the report's order of runs) and of the
        measurement (the order of checks and findings in ``index.md``);
        default ``rank``.
    purposes : mapping
        purpose -> what a run of it records (documentation; ``docs/outputs.md``).
    execute : mapping
        purpose -> ``fn(scene, spec, quick) -> RunRecord`` for purposes no
        built-in executor knows (:mod:`rk4h.validation.execute`).
    run_keep : callable or None
        ``run_keep(draw: bool) -> tuple``: what the scene's timed ``run``
        specs keep in their records for this output (``"energy"``,
        ``"trajectory"``).
    measure : callable or None
        ``measure(m: Measuring) -> None``: adds rows, checks, findings, figure
        jobs and file jobs to ``m.res``. Outputs sharing one function (the
        scene's runs feed ``state``, ``energy`` and ``work_precision``) call
        it once.
    tables : tuple of Table
        The tables it writes (their columns and descriptions).
    draw : mapping
        figure kind -> ``fn(out_dir, job, scene) -> [(Path, sentence)]`` for
        kinds :mod:`rk4h.validation.draw` does not know.
    write : callable or None
        ``write(out_dir, jobs: [FileJob]) -> [(Path, sentence)]``: files
        other than tables and figures (called once per report with every
        scene's jobs of this output, figures or not).
    loops : mapping
        purpose -> ``fn(scene, spec) -> [(kind, solver)]``: the numba loops a
        spec of that purpose runs on the scene's model, for
        :mod:`rk4h.validation.warm` to compile once per machine before the
        runs (with several workers). ``kind`` is ``"loop"`` (the solver's
        fixed-step loop, or a reference's compiled right-hand side, as a
        ``run`` spec runs them), ``"batch"`` (the solver's ensemble loop,
        ``rk4h.ensemble``'s numba backend), ``"compiled"`` (a reference's
        compiled loop for untimed work, as a confirmation runs it; nothing
        for another solver) or ``"stability"`` (the scene's
        ``stability.method`` on its model; ``solver`` unused); ``solver`` is
        a name ``scene.method`` knows. :func:`solver_loop` is the
        declaration of a spec that runs its own ``solver`` (the scene's
        runs, confirmations, convergence sweeps, the state figures' run). A
        speed-up only: a loop left out is compiled where it runs.
    """

    name: str
    when: str
    what: str
    rank: float = 100.0
    applies: Callable[[Any], bool] = _never
    plan: Callable | None = None
    plan_rank: float | None = None
    measure_rank: float | None = None
    purposes: Mapping[str, str] = field(default_factory=dict)
    execute: Mapping[str, Callable] = field(default_factory=dict)
    run_keep: Callable[[bool], tuple] | None = None
    measure: Callable | None = None
    tables: tuple = ()
    draw: Mapping[str, Callable] = field(default_factory=dict)
    write: Callable | None = None
    loops: Mapping[str, Callable] = field(default_factory=dict)


class ModelFacts:
    """What :attr:`Output.applies` reads about a scene's model: computed once,
    on demand. ``dense`` is False above the dense-eigensolve limit
    (:data:`rk4h.validation.scenes.MAX_DENSE_DOF`), where only outputs that need
    no eigensolve apply; ``stability`` whether the scene has a
    ``[stability]`` table."""

    def __init__(self, model, *, stability: bool = False, dense: bool = True):
        self.model, self.stability, self.dense = model, bool(stability), bool(dense)

    @cached_property
    def linearized(self) -> bool:
        """The model has a linearization (a stiffness matrix: ``omega_bound``
        is O(nnz), no eigensolve)."""
        if self.first_order:  # dy/dt = f(t, y): no stiffness matrix, no modes
            return False
        try:
            self.model.omega_bound()
            return True
        except Exception:  # noqa: BLE001 - a model without a linearization
            return False

    @property
    def linear(self) -> bool:
        return bool(self.model.linear)

    @property
    def first_order(self) -> bool:
        """A first-order ODE (model ``ode``): state y, no coordinates or modes."""
        return bool(self.model.first_order)

    @property
    def conserved(self) -> bool:
        """The model has an energy or invariant whose drift is measured: every
        mechanical model; a first-order ODE when it declares an invariant."""
        return not self.first_order or bool(self.model.has_invariant())


@dataclass
class Planning:
    """What :attr:`Output.plan` receives: the scene, the outputs it wants,
    whether figures are drawn, the quick flag, timing repeats, and
    ``spec(purpose, **fields)`` making a :class:`rk4h.validation.plan.RunSpec` of
    the scene."""

    scene: Any
    want: frozenset
    draw: bool
    quick: bool
    repeats: int
    spec: Callable

    @property
    def keep(self) -> tuple:
        """What the scene's timed runs keep (:func:`run_keep`)."""
        return run_keep(self.want, self.draw)


@dataclass
class Measuring:
    """What :attr:`Output.measure` receives: the scene, its specs by purpose,
    the records (key -> RunRecord), the scene's
    :class:`rk4h.validation.measure.SceneTables` to fill, the quick flag and
    whether figures are drawn."""

    scene: Any
    by: dict
    records: dict
    res: Any
    quick: bool
    draw: bool

    def specs(self, purpose: str) -> list:
        return self.by.get(purpose, [])


@dataclass
class FileJob:
    """A file an output writes into the report (:attr:`Output.write`):
    ``data`` came from records."""

    scene: str
    output: str
    data: dict


_REGISTRY: dict[str, Output] = {}
#: name -> Output in rank order (a read-only view of the registry).
OUTPUTS: Mapping[str, Output] = MappingProxyType(_REGISTRY)


def _sort() -> None:
    items = sorted(_REGISTRY.values(), key=lambda o: (o.rank, o.name))
    _REGISTRY.clear()
    _REGISTRY.update((o.name, o) for o in items)


def register(output: Output, *, replace: bool = False) -> Output:
    """Add ``output`` to :data:`OUTPUTS` (and its tables to the report's
    declarations); returns it. A name already registered raises
    ``ValueError`` unless ``replace``."""
    if not isinstance(output, Output):
        raise TypeError(f"register() takes an Output, not {type(output).__name__}")
    if output.name in _REGISTRY and not replace:
        raise ValueError(f"output {output.name!r} is already registered")
    _REGISTRY[output.name] = output
    _sort()
    for hook in _ON_REGISTER:
        hook(output)
    return output


def unregister(name: str) -> None:
    """Remove output ``name`` (a test's clean-up), and the tables only it declared."""
    out = _REGISTRY.pop(name, None)
    if out is not None:
        for hook in _ON_UNREGISTER:
            hook(out)


#: Called with each newly registered output (rk4h.validation.tables declares its tables).
_ON_REGISTER: list[Callable[[Output], None]] = []


_ON_UNREGISTER: list[Callable[[Output], None]] = []


def on_register(hook: Callable[[Output], None], unregister: Callable[[Output], None] | None = None) -> None:
    """Call ``hook(output)`` for every output registered from now on (and
    ``unregister(output)`` for every one removed)."""
    _ON_REGISTER.append(hook)
    if unregister is not None:
        _ON_UNREGISTER.append(unregister)


def _discover() -> None:
    for info in sorted(pkgutil.iter_modules(__path__), key=lambda i: i.name):
        if info.name.startswith("_"):
            continue
        module = importlib.import_module(f"{__name__}.{info.name}")
        out = getattr(module, "OUTPUT", None)
        if not isinstance(out, Output):
            raise TypeError(f"{module.__name__} defines no OUTPUT (an rk4h.validation.outputs.Output)")
        _REGISTRY[out.name] = out
    _sort()


def names() -> tuple[str, ...]:
    """Every output's name, in rank order."""
    return tuple(_REGISTRY)


def get(name: str) -> Output:
    return _REGISTRY[name]


def help_rows() -> dict[str, tuple[str, str]]:
    """name -> (when it applies, what it adds): the scene reference's table."""
    return {o.name: (o.when, o.what) for o in _REGISTRY.values()}


def table_names() -> list[str]:
    """Every output's tables, in rank order (a table once)."""
    return list(dict.fromkeys(t.name for o in _REGISTRY.values() for t in o.tables))


def own_table(name: str) -> Table | None:
    """The table ``name`` whose columns an output declares itself, or None
    (a built-in table, or no output's)."""
    for o in _REGISTRY.values():
        for t in o.tables:
            if t.name == name and t.columns is not None:
                return t
    return None


def default_outputs(facts: ModelFacts) -> list[str]:
    """Every output that applies to ``facts``, in rank order."""
    return [o.name for o in _REGISTRY.values() if o.applies(facts)]


def run_keep(want, draw: bool) -> tuple:
    """What a scene's timed runs keep for the outputs it ``want``s (sorted)."""
    keep = set()
    for o in _REGISTRY.values():
        if o.name in want and o.run_keep is not None:
            keep.update(o.run_keep(draw))
    return tuple(sorted(keep))


def _ranked(want, attr: str, rank: str) -> list:
    outs = [o for o in _REGISTRY.values() if o.name in want and getattr(o, attr) is not None]
    outs.sort(key=lambda o: (getattr(o, rank) if getattr(o, rank) is not None else o.rank, o.rank))
    return list(dict.fromkeys(getattr(o, attr) for o in outs))  # a shared function once


def plan_hooks(want) -> list:
    """The distinct :attr:`Output.plan` functions of ``want``, in plan order."""
    return _ranked(want, "plan", "plan_rank")


def measure_hooks(want) -> list:
    """The distinct :attr:`Output.measure` functions of ``want``, in measure order."""
    return _ranked(want, "measure", "measure_rank")


def executor(purpose: str) -> Callable | None:
    """The function an output declares for ``purpose``, or None."""
    for o in _REGISTRY.values():
        if purpose in o.execute:
            return o.execute[purpose]
    return None


def loops(purpose: str) -> Callable | None:
    """The :attr:`Output.loops` function an output declares for ``purpose``, or None."""
    for o in _REGISTRY.values():
        if purpose in o.loops:
            return o.loops[purpose]
    return None


def drawer(kind: str) -> Callable | None:
    """The function an output declares for figure ``kind``, or None."""
    for o in _REGISTRY.values():
        if kind in o.draw:
            return o.draw[kind]
    return None


def write_files(out_dir, results) -> tuple[list, list]:
    """Every output's files (:attr:`Output.write`) from the scenes' results
    (:class:`rk4h.validation.measure.SceneTables`, their ``files``).

    Returns
    -------
    written : list
        ``(Path, sentence)`` per file written.
    failures : list of str
        One line per output whose files could not be written (the run goes
        on; ``index.md`` lists it as a failure).
    """
    jobs: dict[str, list] = {}
    for r in results:
        for job in getattr(r, "files", ()):
            jobs.setdefault(job.output, []).append(job)
    written, failures = [], []
    for name, js in jobs.items():
        out = _REGISTRY.get(name)
        if out is None or out.write is None:
            continue
        try:
            written += list(out.write(out_dir, js))
        except (ImportError, ValueError, TypeError, OSError) as e:
            if isinstance(e, OSError) and not isinstance(e, FileNotFoundError):
                raise  # the disk or the directory: the environment's fault, not the output's
            failures.append(f"output {name}: its files were not written: {type(e).__name__}: "
                            f"{str(e).splitlines()[0] if str(e) else ''}")
    return written, failures


_discover()
