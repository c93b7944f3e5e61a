"""The work a scene needs, as data: ``plan(scene) -> [RunSpec]``.

A :class:`RunSpec` is frozen, hashable and serializable: the scene it belongs
to (its name and a digest of its content and of the code), the purpose of the
run, the method and its setting, and the few parameters the purpose needs. Its
:attr:`RunSpec.key` (SHA-256) names its record (:mod:`rk4h.validation.records`): an
interrupted run resumes from the records it has, a cluster can run any subset,
and two specs with one key are one run.

Purposes (``RunSpec.purpose``):

``truth``
    the reference on a grid (``grid = "scene"``: the scene's output grid;
    ``"order"``: the convergence grid of a sweep starting at ``theta0``;
    ``"figure"``: the state figures' grid). Fills the truth cache before the runs
    that measure against it, so parallel workers do not compute it twice.
``run``
    one solver at one setting over ``[0, t_end]`` on the output grid, timed
    (``repeats``): accuracy, energy, work-precision rows.
``order``
    one fixed-step run of a convergence sweep: ``h = T / (n0 r)`` with
    ``r = theta_0 / theta`` (nested grids; ``theta = omega_max h``).
``figure``
    RK4 at the scene's finest step on a grid of at most ``FIGURE_POINTS``
    points (the output grid is often too coarse to draw): the trajectory of
    the state figures, kept in the record.
``modal``
    the energy in the lowest linear modes over time (FPUT recurrence), per
    solver at its finest setting.
``modes``, ``dispersion``, ``packet``
    the natural frequencies; the finite chain against the dispersion
    relation; one RK4 wave packet against the group velocity.
``linearization``
    the linearized model's exact solution against the truth of the nonlinear
    one (how much a cheaper model costs in accuracy at this amplitude).
``stability``
    one unit of the stability study (:func:`rk4h.validation.stability.units`).
``thesis_code``
    the thesis' programs run in GNU Octave and compared with rk4core and the
    truth (:func:`rk4h.references.thesis_code.compare`), with their computed errata.
``confirm``
    a ``run`` made to confirm a verdict of the trust table (the method under
    test at a predicted step, a reference at a tighter tolerance); planned
    after the plan has run, from its records (:mod:`rk4h.validation.confirm`),
    not by :func:`plan`.

The order of the plan is the order of the report; execution order is the
engine's business (:mod:`rk4h.validation.engine`).
"""
from __future__ import annotations

import dataclasses
import hashlib
import json
import math
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

from rk4h.references.registry import CONVERGENCE_ALWAYS

__all__ = ["RunSpec", "plan", "plan_all", "scene_digest", "code_digest", "TARGETS",
           "ORDER_TOL", "RK4_THETAS", "EULER_THETAS", "order_methods", "settings_of", "PURPOSES",
           "TIMED_UNITS"]

#: Target relative errors of the cheapest-solver table.
TARGETS = (1e-3, 1e-6, 1e-9, 1e-12)
#: Accepted deviation of a fitted order from the method's expected order
#: (``rk4h.references.registry.Method.order``: computed from the order conditions
#: for a tableau, declared for python and command methods).
ORDER_TOL = 0.1
#: Default omega_max * h of the convergence sweeps (halving: nested step grids):
#: methods of order >= 3 (scene key ``convergence.theta``), and of order 1-2
#: (``convergence.theta_euler``), whose error at 0.2 would leave the
#: asymptotic range.
RK4_THETAS = (0.2, 0.1, 0.05, 0.025)
EULER_THETAS = (0.01, 0.005, 0.0025, 0.00125)
#: Wave packets of the dispersion output (carrier in units of pi/d).
PACKET_KP = (0.3, 0.6)
PURPOSES = ("truth", "run", "figure", "order", "modal", "modes", "dispersion", "packet", "linearization", "stability",
            "thesis_code", "confirm")
#: Points of the trajectory drawn in the state figures (at most).
FIGURE_POINTS = 4000
#: Stability units whose rows hold timings (they run with the timed specs).
TIMED_UNITS = ("large_n",)


@dataclass(frozen=True)
class RunSpec:
    """One run of the plan; see the module docstring.

    ``setting`` is ``h`` (s) for a fixed-step solver, ``rtol`` for an adaptive
    one, ``theta = omega_max h`` for an ``order`` run, ``kp0 d / pi`` for a
    ``packet``; ``params`` holds what else the purpose needs, as sorted
    ``(name, value)`` pairs.
    """

    scene: str
    digest: str
    purpose: str
    solver: str = ""
    setting: float = 0.0
    grid: str = ""
    unit: str = ""
    repeats: int = 1
    keep: tuple = ()
    params: tuple = ()

    @property
    def key(self) -> str:
        """SHA-256 (hex, 24 characters) of the spec's canonical JSON."""
        return _key(self)

    @property
    def timed(self) -> bool:
        """Whether the record holds a wall time that a verdict reads."""
        return self.purpose in ("run", "confirm") or (self.purpose == "stability" and self.unit.split(":")[0] in TIMED_UNITS)

    def param(self, name, default=None):
        return dict(self.params).get(name, default)

    def to_json(self) -> dict:
        return dataclasses.asdict(self) | {"keep": list(self.keep), "params": [list(p) for p in self.params]}

    @classmethod
    def from_json(cls, d: dict) -> "RunSpec":
        return cls(**{**d, "keep": tuple(d["keep"]), "params": tuple(tuple(p) for p in d["params"])})

    def label(self) -> str:
        """A short description for the progress line."""
        what = {"run": f"{self.solver} {self.setting:g}", "confirm": f"{self.solver} {self.setting:g} (confirmation)",
                "order": f"{self.solver} order theta={self.setting:g}",
                "truth": f"reference ({self.grid} grid)", "stability": f"stability {self.unit}",
                "modal": f"modal energy {self.solver}", "packet": f"wave packet {self.setting:g} pi/d"}
        return f"{self.scene}: {what.get(self.purpose, self.purpose)}"


@lru_cache(maxsize=4096)
def _key(spec: RunSpec) -> str:
    text = json.dumps(spec.to_json(), sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()[:24]


@lru_cache(maxsize=1)
def code_digest() -> str:
    """SHA-256 over the sources of the packages a record depends on
    (``rk4h``, ``rk4h.references``, ``rk4h.validation``: their Python files
    and the thesis' GNU Octave programs in ``rk4h``'s ``thesis_code``): a
    record made by other code is never resumed.

    Each file is named by its module path inside ``rk4h`` (``fast/codegen.py``,
    ``validation/plan.py``), so a checkout (three folders) and a wheel (one
    ``rk4h`` folder holding the other two) of the same code agree."""
    import rk4h
    import rk4h.references
    import rk4h.validation
    files = {}
    for sub, mod in (("", rk4h), ("references/", rk4h.references), ("validation/", rk4h.validation)):
        root = Path(mod.__file__).resolve().parent
        for pattern in ("*.py", "*.m"):
            for p in root.rglob(pattern):
                if "__pycache__" not in p.parts:
                    files.setdefault(sub + p.relative_to(root).as_posix(), p)
    h = hashlib.sha256()
    for name in sorted(files):
        h.update(name.encode())
        h.update(files[name].read_bytes())
    return h.hexdigest()[:16]


def scene_digest(scene) -> str:
    """Digest of everything in ``scene`` that a run depends on (not its file
    path or description), of the harness code (:func:`code_digest`), of the
    user's code the scene names and of the library versions and BLAS kernel
    (:mod:`rk4h.validation.provenance`)."""
    from .provenance import environment_digest, user_code_digest

    d = dataclasses.asdict(scene)
    for k in ("path", "description"):
        d.pop(k, None)
    text = json.dumps(d, sort_keys=True, default=str)
    head = code_digest() + environment_digest() + user_code_digest(scene)
    return hashlib.sha256((head + text).encode()).hexdigest()[:16]


def settings_of(scene, solver) -> list:
    """The settings a scene runs ``solver`` at: its steps or its tolerances."""
    return list(scene.h if scene.method(solver).fixed_step else scene.tolerances)


def order_methods(scene) -> list[tuple[str, str, tuple]]:
    """``(method, scene key of its thetas, default thetas)`` of every
    convergence sweep of ``scene``: :data:`rk4h.references.registry.CONVERGENCE_ALWAYS` and the scene's
    own fixed-step methods, in that order."""
    out = []
    first_order = _first_order(scene)
    for name in dict.fromkeys((*CONVERGENCE_ALWAYS, *scene.fixed_solvers)):
        if first_order:  # a partitioned tableau integrates q' = v: not a first-order ODE's method
            from rk4h.references.solvers import mechanical_only

            if mechanical_only(scene.method(name)):
                continue
        high = (scene.method(name).order or 1) >= 3
        out.append((name, "theta", RK4_THETAS) if high else (name, "theta_euler", EULER_THETAS))
    return out


def under_test(scene) -> str | None:
    """The method under test of ``scene``: the first fixed-step method it
    lists (the state figures, modal energies of the packets use it); None if
    it lists none."""
    fixed = scene.fixed_solvers
    return fixed[0] if fixed else None


def plan(scene, *, quick: bool = False, figures: bool = True, repeats: int = 1) -> list[RunSpec]:
    """Every run ``scene`` needs, in report order (see the module docstring).

    ``figures`` adds what the figures keep (energy series, the trajectory of
    the state figures); ``repeats`` is the timing repeats of ``run`` specs."""
    from . import outputs

    dig = scene_digest(scene)
    want = frozenset(scene.outputs)
    draw = figures and "figures" in want
    p = outputs.Planning(scene, want, draw, quick, int(repeats),
                         lambda purpose, **kw: RunSpec(scene.name, dig, purpose, **kw))
    out = []
    for hook in outputs.plan_hooks(want):  # each output's runs (rk4h.validation.outputs), in plan order
        out += hook(p)
    seen = set()  # one run per key (two sweeps on one grid share their reference)
    return [s for s in out if not (s.key in seen or seen.add(s.key))]


def _first_order(scene) -> bool:
    """Whether ``scene``'s model is a first-order ODE (``model.first_order``)."""
    try:
        return bool(getattr(scene.build_model(), "first_order", False))
    except Exception:  # noqa: BLE001 - a scene that cannot build fails at execution, with its message
        return False


def _nonlinear(scene) -> bool:
    try:
        return not scene.build_model().linear
    except Exception:  # noqa: BLE001 - a scene that cannot build fails at execution, with its message
        return False


def plan_all(scenes, **kw) -> list[tuple[object, RunSpec]]:
    """``(scene, spec)`` for every spec of every scene, duplicates (one key) once."""
    seen, out = set(), []
    for scene in scenes:
        for s in plan(scene, **kw):
            if s.key not in seen:
                seen.add(s.key)
                out.append((scene, s))
    return out


def nan_if_none(x):
    return math.nan if x is None else x
