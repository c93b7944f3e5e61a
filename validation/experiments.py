"""What a scene measures: the runs it needs and the table rows they give.

:func:`run_scene` integrates one scene with every solver and setting it names,
measures each run against the reference (``references.truth``: exact modal
superposition for linear models, heyoka in quadruple precision otherwise) and
returns table rows, figures and findings. Which parts run depends on the
scene's ``outputs``:

``state``, ``energy``, ``work_precision``
    one run per (solver, setting) over ``[0, t_end]`` on the scene's output
    grid: ``accuracy`` rows, ``energy`` rows (RK4 beside the exact theory of
    its energy decay on linear models), ``work_precision`` and ``cheapest`` rows.
``convergence``
    the fixed-step methods on a short horizon (default one period of the
    fastest mode, ``2 pi / omega_max``) over a sweep of steps ``h = theta /
    omega_max`` chosen inside the asymptotic range (RK4 theta = 0.2 ... 0.025,
    Euler and symplectic Euler 0.01 ... 0.00125: Euler's error grows like
    ``exp(omega^2 h t / 2)``, so ``omega^2 h T`` must stay small); the order
    is the least-squares slope of log error vs log h (:class:`metrics.OrderFit`).
    Adaptive solvers: the error must not grow as the tolerance tightens (by
    more than a factor 10, the slack of local error control).
``modes``
    natural frequencies of the (linearized) model.
``dispersion``
    the finite chain's eigenfrequencies against the lattice dispersion relation,
    and wave packets integrated by RK4 against the group velocity.
``figures``
    the thesis' state figures from an RK4 run at the finest ``h``, plus the
    convergence, work-precision and energy figures of the parts above.
``stability``
    ``validation.stability.run``.

Timing: every run shorter than ``REPEAT_BELOW_S`` (1 s) is repeated
``repeats`` times and the median wall time is reported (longer runs once:
their relative noise is small); compile time is apart (``compile_s``).
Accuracy numbers come from the first repeat and do not depend on the repeats.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from . import metrics
from . import interrupt
from .atomic import is_environment_error
from .scenes import Scene

__all__ = ["SceneResult", "run_scene", "TARGETS", "EXPECTED_ORDER", "ORDER_TOL",
           "RK4_THETAS", "EULER_THETAS", "planned_units", "order_sweep",
           "convergence_horizon"]

#: Target relative errors of the cheapest-solver table.
TARGETS = (1e-3, 1e-6, 1e-9, 1e-12)
#: Classical orders of the fixed-step methods, and the accepted deviation of a fit.
EXPECTED_ORDER = {"rk4": 4.0, "euler": 1.0, "symplectic-euler": 1.0}
ORDER_TOL = 0.1
#: Default omega_max * h of the convergence sweeps (halving: nested step grids).
RK4_THETAS = (0.2, 0.1, 0.05, 0.025)
EULER_THETAS = (0.01, 0.005, 0.0025, 0.00125)
#: RK4 energy drift: measured vs theory, relative slack and round-off per step.
ENERGY_RTOL = 1e-6
ENERGY_ROUNDOFF_PER_STEP = 10 * np.finfo(float).eps
#: Adaptive solvers: tightening the tolerance may not raise the error more than this.
TOLERANCE_SLACK = 10.0
#: Wave packets of the dispersion output (carrier in units of pi/d) and accepted error.
PACKET_KP = (0.3, 0.6)
PACKET_RTOL = 0.02
#: Runs longer than this (s) are timed once: their relative timing noise is small.
REPEAT_BELOW_S = 1.0
#: Points of the trajectory drawn in the state figures (at most).
FIGURE_POINTS = 4000


@dataclass
class SceneResult:
    """Everything one scene produced.

    ``tables`` maps a table name (``accuracy``, ``convergence``, ``modes``,
    ``work_precision``, ``energy``, ``cheapest``, ``dispersion``,
    ``stability``) to its rows; ``failures`` lists the expectations that did
    not hold (one line each); ``findings`` are one-line results for index.md.
    """

    scene: str
    tables: dict = field(default_factory=dict)
    figures: list = field(default_factory=list)
    findings: list = field(default_factory=list)
    failures: list = field(default_factory=list)
    truth_kind: str = ""
    seconds: float = 0.0

    def add(self, table, row):
        self.tables.setdefault(table, []).append(row)


def _settings(scene: Scene, solver: str):
    return scene.h if solver in EXPECTED_ORDER else scene.tolerances


def planned_units(scene: Scene, figures: bool = True) -> int:
    """Work units of a scene for the progress bar: one per solver run and per
    part, and for the stability study one per study it names (each says so
    once; some say more, which the bar absorbs)."""
    n = 0
    if {"state", "energy", "work_precision"} & set(scene.outputs):
        n += sum(len(_settings(scene, s)) for s in scene.solvers)
    n += sum(o in scene.outputs for o in ("convergence", "dispersion", "stability", "modes", "modal_energy"))
    n += bool(figures and "figures" in scene.outputs)
    if "stability" in scene.outputs:
        n += len((scene.stability or {}).get("studies") or ())
    return max(n, 1)


def _status(run) -> str:
    s = run.status
    return getattr(s, "value", str(s))


def _timed(solver, model, y0, t, setting, repeats):
    """First run plus the median wall time of ``repeats`` runs; an exception
    inside a solver becomes a failed run, not a crash."""
    from references.solvers import integrate

    runs = []
    for _ in range(max(1, repeats)):
        try:
            run = integrate(solver, model, y0, t, setting)
        except Exception as e:  # noqa: BLE001 - a solver fault is a row, not a crash
            return None, f"{type(e).__name__}: {e}".splitlines()[0]
        runs.append(run)
        if _status(run) != "ok" or run.wall_s > REPEAT_BELOW_S:
            break
    first = runs[0]
    wall = float(np.median([r.wall_s for r in runs]))
    return (first, wall), ""


def _truth(model, y0, t):
    from references.truth import reference_solution

    return reference_solution(model, y0, t)


def run_scene(scene: Scene, out_dir, *, quick=False, repeats=3, figures=True,
              progress=None) -> SceneResult:
    """Run one scene; see the module docstring. ``progress(str)`` is called
    once per work unit (:func:`planned_units`)."""
    tick = progress or (lambda msg: None)
    t_start = time.perf_counter()
    out_dir = Path(out_dir)
    res = SceneResult(scene.name)
    model = scene.build_model()
    y0 = scene.y0()
    want = set(scene.outputs)
    draw = figures and "figures" in want

    parts = [
        ("trajectories", bool({"state", "energy", "work_precision"} & want),
         lambda: _trajectories(scene, model, y0, res, repeats, draw, out_dir, tick)),
        ("convergence", "convergence" in want, lambda: _convergence(scene, model, y0, res, draw, out_dir)),
        ("modes", "modes" in want, lambda: _modes(scene, model, res)),
        ("dispersion", "dispersion" in want, lambda: _dispersion(scene, model, res, draw, out_dir)),
        ("figures", draw, lambda: _state_figures(scene, model, y0, res, out_dir)),
        ("stability", "stability" in want, lambda: _stability(scene, res, out_dir, quick, progress)),
        ("modal_energy", "modal_energy" in want, lambda: _modal_energy(scene, model, y0, res, draw, out_dir)),
    ]
    for what, wanted, part in parts:
        if not wanted:
            continue
        try:
            part()
        except Exception as e:  # noqa: BLE001 - one part's fault is a failure line, the rest still runs
            if is_environment_error(e) or interrupt.pending():
                raise
            res.failures.append(f"{scene.name}: the {what} part raised {type(e).__name__}: "
                                f"{str(e).splitlines()[0] if str(e) else ''}")
        if what != "trajectories":
            tick(f"{scene.name}: {what}")
    res.seconds = time.perf_counter() - t_start
    return res


# -- accuracy, energy, work-precision --------------------------------------------
def _trajectories(scene, model, y0, res, repeats, draw, out_dir, tick):
    t = scene.t_eval()
    truth = _truth(model, y0, t)
    res.truth_kind = truth.kind
    y_ref = np.asarray(truth.y, float)
    scale = float(np.max(np.abs(y_ref)))
    linear_modes = None
    if model.linear:
        from references.exact import modal_solution

        ms = modal_solution(model, y0)
        linear_modes = (ms.omega, ms.eta0, ms.deta0)
    series = {}
    for solver in scene.solvers:
        for setting in _settings(scene, solver):
            timed, err = _timed(solver, model, y0, t, setting, repeats)
            tick(f"{scene.name}: {solver} {setting:g}")
            row = {"scene": scene.name, "solver": solver, "setting": float(setting)}
            if timed is None:
                res.failures.append(f"{scene.name}: {solver} at {setting:g} raised {err}")
                res.add("accuracy", {**row, "error_max": math.nan, "error_rel": math.nan,
                                     "error_final": math.nan, "energy_drift_max": math.nan,
                                     "nfev": 0, "n_steps": 0, "wall_s": math.nan,
                                     "compile_s": math.nan, "status": "failed", "message": err})
                continue
            run, wall = timed
            status = _status(run)
            _note_status(scene, res, row, status, run)
            e_max = metrics.error_max(run.y, y_ref)
            drift = metrics.energy_drift_max(model, run.y)
            acc = {**row, "error_max": e_max, "error_rel": e_max / scale,
                   "error_final": metrics.error_final(run.y, y_ref), "energy_drift_max": drift,
                   "nfev": int(run.nfev), "n_steps": int(run.n_steps), "wall_s": wall,
                   "compile_s": float(run.compile_s), "status": status,
                   "message": (run.message or "").splitlines()[0] if run.message else ""}
            res.add("accuracy", acc)
            if "work_precision" in scene.outputs:
                res.add("work_precision", {**row, "error_max": e_max, "error_rel": e_max / scale,
                                           "wall_s": wall, "nfev": int(run.nfev),
                                           "n_steps": int(run.n_steps),
                                           "taylor_order": run.taylor_order or 0, "status": status})
            if "energy" in scene.outputs:
                res.add("energy", _energy_row(scene, model, run, row, status, linear_modes, res))
                if status == "ok" and math.isfinite(acc["energy_drift_max"]) and acc["error_rel"] <= 10.0:
                    rel = np.abs(metrics.relative_energy_error(model, run.y))
                    series[solver] = (f"{solver} {'h' if solver in EXPECTED_ORDER else 'rtol'}="
                                      f"{setting:g}", t, rel)
    if "work_precision" in scene.outputs:
        _cheapest(scene, res)
        if draw:
            import pandas as pd

            # Runs with no correct digit left (error above 10x the state scale, e.g. explicit
            # Euler's growth) have no place on a work-precision diagram.
            wp = [r for r in res.tables["work_precision"] if r["error_rel"] <= 10.0]
            _figure(res, "work_precision", lambda f: f.work_precision(out_dir, scene.name, pd.DataFrame(wp)))
    if draw and series:
        _figure(res, "energy_error", lambda f: f.energy_error(
            out_dir, scene.name, {lab: (tt, e) for lab, tt, e in series.values()}))


def _note_status(scene, res, row, status, run):
    """A ``failed`` run (a solver's error flag or an exception inside it) is a
    failure line; an ``unstable`` one (non-finite state: a fixed step beyond the
    stability boundary) is a measured result and a finding."""
    message = (run.message or "").splitlines()[0] if run.message else ""
    what = f"{scene.name}: {row['solver']} at {row['setting']:g}"
    if status == "failed":
        res.failures.append(f"{what} failed: {message or 'no message'}")
    elif status == "unstable":
        res.findings.append(f"{what} became unstable: {message or 'non-finite state'}")


def _energy_row(scene, model, run, row, status, linear_modes, res):
    t = np.asarray(run.t, float)
    ok = status == "ok"
    measured = metrics.drift_per_time(model, t, run.y) if ok else math.nan
    out = {**row, "drift_per_time": measured, "theory_drift_per_time": math.nan,
           "energy_drift_max": metrics.energy_drift_max(model, run.y) if ok else math.nan,
           "passed": "", "status": status}
    if row["solver"] == "rk4" and linear_modes is not None and ok:
        duration = t[-1] - t[0]
        h = duration / run.n_steps
        theory = metrics.rk4_drift_theory(*linear_modes, h, run.n_steps, duration)
        slack = ENERGY_RTOL * abs(theory) + ENERGY_ROUNDOFF_PER_STEP * run.n_steps / duration
        passed = bool(abs(measured - theory) <= slack)
        out.update(theory_drift_per_time=theory, passed=passed)
        if not passed:
            res.failures.append(f"{scene.name}: RK4 energy drift per time at h={row['setting']:g} is "
                                f"{measured:.6e} 1/s, theory {theory:.6e} 1/s")
    return out


def _cheapest(scene, res):
    rows = [r for r in res.tables.get("work_precision", [])]
    best = metrics.cheapest(rows, TARGETS, cost="wall_s")
    crossover = None
    for b in best:
        rk4_best = b["rk4_setting"] is not None and b["solver"] == "rk4"
        if crossover is None and not rk4_best:
            crossover = b["target_error"]
        res.add("cheapest", {"scene": scene.name, "target_error": b["target_error"],
                             "solver": b["solver"] or "", "setting": b["setting"],
                             "wall_s": b["cost"], "rk4_h": b["rk4_setting"],
                             "rk4_wall_s": b["rk4_cost"],
                             "rk4_is_cheapest": bool(b["solver"] == "rk4")})
    if "rk4" in scene.solvers:
        first = best[0]
        if crossover is None:
            res.findings.append(f"{scene.name}: RK4 is the cheapest solver for every target error down to "
                                f"{TARGETS[-1]:g}.")
        elif first["solver"] is None:
            res.findings.append(f"{scene.name}: no solver reaches a relative error of {TARGETS[0]:g}.")
        elif crossover == TARGETS[0]:
            rk4 = (f"RK4 needs {first['rk4_cost'] / first['cost']:.3g}x its wall time (h = {first['rk4_setting']:g} s)"
                   if first["rk4_cost"] is not None and first["cost"] else "RK4 does not reach it")
            res.findings.append(f"{scene.name}: RK4 is not the cheapest solver for any target; at "
                                f"{TARGETS[0]:g} the cheapest is {first['solver']} (rtol {first['setting']:g}, "
                                f"compile time excluded); {rk4}.")
        else:
            res.findings.append(f"{scene.name}: RK4 is the cheapest solver down to a relative error of "
                                f"{TARGETS[TARGETS.index(crossover) - 1]:g} and stops being it at {crossover:g}.")


# -- convergence ----------------------------------------------------------------
def convergence_horizon(scene, model) -> float:
    """Horizon (s) of the convergence sweeps: ``[convergence] t_end`` or one
    period of the fastest (linearized) mode, at most the scene's ``t_end``."""
    omega_max = float(np.max(model.modes()[0]))
    return min(scene.convergence.get("t_end", 2.0 * math.pi / omega_max), scene.t_end)


def order_sweep(model, y0, method, thetas, T):
    """Errors of fixed-step ``method`` over ``[0, T]`` for ``h = T / (n0 r)``,
    ``r = theta_0 / theta`` rounded (nested grids), ``n0 = ceil(T omega_max / theta_0)``.

    The error is the largest over every step of the coarsest run (all runs
    share those grid points) and all components. Returns ``(OrderFit, hs,
    errs)``.
    """
    omega_max = float(np.max(model.modes()[0]))
    thetas = sorted(thetas, reverse=True)
    n0 = max(1, math.ceil(T * omega_max / thetas[0]))
    t = np.linspace(0.0, T, n0 + 1)
    y_ref = np.asarray(_truth(model, y0, t).y, float)
    scale = float(np.max(np.abs(y_ref)))
    hs, errs = [], []
    for th in thetas:
        h = T / (n0 * max(1, round(thetas[0] / th)))
        timed, _ = _timed(method, model, y0, t, h, 1)
        ok = timed is not None and _status(timed[0]) == "ok"
        hs.append(h)
        errs.append(metrics.error_max(timed[0].y, y_ref) if ok else math.nan)
    return metrics.fit_order(hs, errs, scale), hs, errs


def _convergence(scene, model, y0, res, draw, out_dir):
    conv = scene.convergence
    T = convergence_horizon(scene, model)
    points = []
    for method, thetas in (("rk4", conv.get("theta", RK4_THETAS)),
                           ("euler", conv.get("theta_euler", EULER_THETAS)),
                           ("symplectic-euler", conv.get("theta_euler", EULER_THETAS))):
        fit, hs, errs = order_sweep(model, y0, method, thetas, T)
        points += [{"solver": method, "h": h, "error_max": e} for h, e in zip(hs, errs)]
        expected = EXPECTED_ORDER[method]
        passed = fit.passed(expected, ORDER_TOL)
        res.add("convergence", {"scene": scene.name, "solver": method, "quantity": "order in h",
                                "observed_order": fit.order, "expected_order": expected,
                                "passed": passed, "h_min": fit.h_min, "h_max": fit.h_max,
                                "n_points": fit.n_points, "t_end": T})
        if not passed:
            res.failures.append(f"{scene.name}: {method} observed order {fit.order:.3f}, expected "
                                f"{expected:g} +- {ORDER_TOL:g} (h in [{fit.h_min:.3g}, {fit.h_max:.3g}], "
                                f"{fit.n_points} points)")
    _tolerance_checks(scene, res)
    if draw:
        import pandas as pd

        fits = pd.DataFrame([r for r in res.tables["convergence"] if r["quantity"] == "order in h"])
        _figure(res, "convergence", lambda f: f.convergence(out_dir, scene.name, pd.DataFrame(points), fits))


def _tolerance_checks(scene, res):
    """Adaptive solvers: error vs tolerance from the accuracy rows."""
    rows = res.tables.get("accuracy", [])
    for solver in scene.adaptive_solvers:
        mine = sorted((r for r in rows if r["solver"] == solver), key=lambda r: -r["setting"])
        if len(mine) < 2:
            continue
        tol = np.array([r["setting"] for r in mine])
        err = np.array([r["error_rel"] for r in mine])
        ok = np.isfinite(err)
        monotone = bool(ok.all() and np.all(err[1:] <= TOLERANCE_SLACK * err[:-1])
                        and err[-1] < err[0])
        above = ok & (err > metrics.ROUNDOFF_REL)
        slope = float(np.polyfit(np.log(tol[above]), np.log(err[above]), 1)[0]) if above.sum() >= 2 else math.nan
        res.add("convergence", {"scene": scene.name, "solver": solver, "quantity": "error vs tolerance",
                                "observed_order": slope, "expected_order": math.nan, "passed": monotone,
                                "h_min": float(tol.min()), "h_max": float(tol.max()),
                                "n_points": int(above.sum()), "t_end": scene.t_end})
        if not monotone:
            res.failures.append(f"{scene.name}: {solver}'s error does not decrease with the tolerance "
                                f"(relative errors {', '.join(f'{e:.2g}' for e in err)})")


# -- modes, dispersion -------------------------------------------------------------
def _modes(scene, model, res):
    omega, _ = model.modes()
    for j, w in enumerate(omega, start=1):
        res.add("modes", {"scene": scene.name, "mode": j, "omega_rad_s": float(w),
                          "freq_hz": float(w) / (2 * math.pi), "linearized": not model.linear})


def _uniform_chain(model):
    """``(m, k)`` (kg, N/m) when ``model`` is drawn as masses on a line
    (``drawing().layout == "line"``) and its linearization is that of equal
    masses ``m`` on equal springs ``k`` between two walls: stiffness matrix
    ``k tridiag(-1, 2, -1)`` (to 1e-12). Else None. Read from the drawing and
    the mechanics, never from the model's name."""
    import scipy.sparse as sp

    if model.drawing().layout != "line":
        return None
    mass = np.asarray(model.mass, dtype=float)
    if mass.size == 0 or np.any(mass != mass[0]):
        return None
    try:
        try:
            K = model.stiffness_matrix(sparse=True)
        except TypeError:
            K = model.stiffness_matrix()
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


def _dispersion(scene, model, res, draw, out_dir):
    from references import dispersion
    from validation import wavepacket

    mk = _uniform_chain(model)
    if mk is None:
        res.failures.append(f"{scene.name}: the dispersion output needs a uniform chain between walls")
        return
    m, k = mk
    d = dispersion.THESIS_LATTICE["d"]
    N = model.n_dof
    finite = model.modes()[0]
    theory = np.asarray(dispersion.finite_chain_frequencies(N, m, k), float)
    kp_n = np.asarray(dispersion.finite_chain_wavenumbers(N, d), float)
    rel = np.abs(finite - theory) / theory
    worst = float(rel.max())
    passed = worst <= 1e-10
    for n in range(N):
        res.add("dispersion", {"scene": scene.name, "quantity": "finite-chain omega", "index": n + 1,
                               "kp_rad_m": kp_n[n], "measured": float(finite[n]),
                               "theory": float(theory[n]), "rel_error": float(rel[n]),
                               "passed": bool(rel[n] <= 1e-10)})
    if not passed:
        res.failures.append(f"{scene.name}: finite-chain frequencies differ from the dispersion "
                            f"relation by {worst:.2e} (relative)")
    packets = []
    for frac in PACKET_KP:
        kp0 = frac * math.pi / d
        p = wavepacket.measure_group_velocity(kp0, m=m, k=k, d=d)
        ok = bool(p.success and abs(p.rel_error) <= PACKET_RTOL)
        res.add("dispersion", {"scene": scene.name, "quantity": "wave-packet group velocity",
                               "index": frac, "kp_rad_m": kp0, "measured": p.v_measured,
                               "theory": p.v_theory, "rel_error": p.rel_error, "passed": ok})
        packets.append((kp0, p.v_measured))
        if not ok:
            res.failures.append(f"{scene.name}: wave packet at kp0 = {frac:g} pi/d moves at "
                                f"{p.v_measured:.5g} m/s, v_g = {p.v_theory:.5g} m/s")
        else:
            res.findings.append(f"{scene.name}: a wave packet at kp0 = {frac:g} pi/d integrated by RK4 moves "
                                f"at {p.v_measured:.5g} m/s vs v_g = {p.v_theory:.5g} m/s "
                                f"({100 * p.rel_error:+.2f}%).")
    if draw:
        _figure(res, "dispersion", lambda f: f.dispersion(out_dir, m, k, d, N, finite, packets,
                                                          scene_name=scene.name))


# -- modal energy (FPUT recurrence) ----------------------------------------------------
MODAL_MODES = 4  # the lowest linear modes followed


def modal_energies(model, y, omega, phi):
    """Energy (J) in each linear mode, shape (modes, m), of states ``y`` (2n, m):
    ``E_k = (adot_k^2 + omega_k^2 a_k^2) / 2`` with modal coordinates
    ``a = phi^T M q`` (``phi`` mass-normalised)."""
    n = model.n_dof
    Mphi = phi * model.mass[:, None]
    a, adot = Mphi.T @ y[:n], Mphi.T @ y[n:]
    return 0.5 * (adot * adot + (omega[:, None] * a) ** 2)


def _modal_energy(scene, model, y0, res, draw, out_dir):
    """Energy in the lowest modes over time, per solver at its finest setting:
    the Fermi-Pasta-Ulam-Tsingou recurrence (energy put in mode 1 spreads to
    modes 2, 3, ... and comes back). No reference trajectory is needed: the
    solvers are compared with each other, the tightest adaptive one first."""
    omega, phi = model.modes()
    k = min(MODAL_MODES, model.n_dof)
    order = np.argsort(omega)[:k]
    omega, phi = omega[order], phi[:, order]
    t = scene.t_eval()
    E0 = float(np.asarray(model.energy(y0)))
    series = {}
    for solver in scene.solvers:
        setting = min(_settings(scene, solver))
        timed, err = _timed(solver, model, y0, t, setting, 1)
        if timed is None:
            res.failures.append(f"{scene.name}: {solver} at {setting:g} raised {err}")
            continue
        run = timed[0]
        status = _status(run)
        frac = modal_energies(model, np.asarray(run.y, float), omega, phi) / E0
        label = f"{solver} {'h' if solver in EXPECTED_ORDER else 'rtol'}={setting:g}"
        series[label] = frac
        for j in range(k):
            f = frac[j]
            i_min = int(np.nanargmin(f)) if np.isfinite(f).any() else 0
            row = {"scene": scene.name, "solver": solver, "setting": float(setting), "mode": j + 1,
                   "omega_rad_s": float(omega[j]), "fraction_start": float(f[0]),
                   "fraction_min": float(f[i_min]), "t_min": float(t[i_min]), "status": status}
            if j > 0 and np.isfinite(f).any():  # a mode that starts empty: its largest share
                i_pk = int(np.nanargmax(f))
                row.update(fraction_peak=float(f[i_pk]), t_peak=float(t[i_pk]))
            elif i_min < f.size - 1 and np.isfinite(f[i_min:]).any():
                i_ret = i_min + int(np.nanargmax(f[i_min:]))
                row.update(fraction_peak=float(f[i_ret]), t_peak=float(t[i_ret]))
                res.findings.append(
                    f"{scene.name}: {label}: mode 1 holds {f[0]:.1%} of the energy at t = 0, falls to "
                    f"{f[i_min]:.1%} at t = {t[i_min]:.4g} s and returns to {f[i_ret]:.1%} at "
                    f"t = {t[i_ret]:.4g} s (FPUT recurrence).")
            else:
                row.update(fraction_peak=math.nan, t_peak=math.nan)
            res.add("modal_energy", row)
    if draw and series:
        _figure(res, "modal_energy", lambda fg: fg.modal_energy(out_dir, scene.name, t, series, omega))


# -- figures, stability --------------------------------------------------------------
def _figure(res, what, draw, many=False):
    """Call ``draw(figures_module)``; a plotting fault is a failure line, not a lost scene."""
    from . import figures

    try:
        out = draw(figures)
    except Exception as e:  # noqa: BLE001
        if is_environment_error(e) or interrupt.pending():
            raise
        res.failures.append(f"{res.scene}: the {what} figure failed: {type(e).__name__}: "
                            f"{str(e).splitlines()[0] if str(e) else ''}")
        return
    if many:
        res.figures.extend(out)
    else:
        res.figures.append(out)


def _state_figures(scene, model, y0, res, out_dir):
    """The thesis' state figures, from RK4 at the scene's finest h (or the reference)."""
    if scene.h and "rk4" in scene.solvers:
        h = min(scene.h)
        n = round(scene.t_end / h)
        stride = max(1, math.ceil(n / FIGURE_POINTS))
        t = h * np.arange(0, n + 1, stride)
        t[-1] = min(t[-1], scene.t_end)
        timed, _ = _timed("rk4", model, y0, t, h, 1)
        run = timed[0] if timed else None
        if run is not None and _status(run) == "ok":
            title = f"{scene.name}: RK4, h = {h:g} s"
            _figure(res, "state", lambda f: f.scene_figures(out_dir, scene.name, model, run.t, run.y,
                                                            title=title), many=True)
            return
    t = np.linspace(0.0, scene.t_end, FIGURE_POINTS + 1)
    truth = _truth(model, y0, t)
    _figure(res, "state", lambda f: f.scene_figures(out_dir, scene.name, model, t, np.asarray(truth.y),
                                                    title=f"{scene.name}: reference ({truth.kind})"),
            many=True)


def _stability(scene, res, out_dir, quick, progress):
    from . import stability

    study = stability.run(scene, out_dir, quick, progress=progress)
    for row in study.rows:
        res.add("stability", row)
        passed = row.get("passed")
        if isinstance(passed, (bool, np.bool_)) and not passed:  # numpy's False is not `False`
            res.failures.append(f"{scene.name}: stability {row.get('solver')} {row.get('quantity')}: "
                                f"measured {row.get('measured')}, theory {row.get('theory')}")
    res.figures.extend(study.figures)
    res.findings.extend(study.findings)
