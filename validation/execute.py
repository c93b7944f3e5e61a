"""``execute(scene, spec) -> RunRecord``: one run of the plan, measured.

Every integration of the report happens here (and in the stability units it
calls); everything after it reads records. The record holds the run's
deterministic scalars (errors against the truth, energy drift, nfev, steps,
status), its timings apart, and the arrays a figure needs. A fault inside a
solver or a unit becomes a record with status ``failed`` and the message,
never an exception (except the environment refusing, and interrupts).

Timing (``run`` specs): the first run gives every accuracy number; runs
shorter than :data:`REPEAT_BELOW_S` are repeated ``spec.repeats`` times and
the median wall time is reported with the minimum and maximum of the repeats
(``timing["wall_min"]``, ``["wall_max"]``). Compile time is apart
(``compile_s``).

Models are built once per process and scene (:func:`problem`), as heyoka's
JIT and the compiled loops are: a worker that runs many specs of one scene
pays them once.
"""
from __future__ import annotations

import math
import time

import numpy as np

from rk4h.references.registry import Kind

from . import metrics
from .look import record_look
from .plan import FIGURE_POINTS, RunSpec
from .records import RunRecord, failed_record

__all__ = ["execute", "problem", "grid", "REPEAT_BELOW_S", "MODAL_MODES", "modal_energies", "modal_content",
           "recorded_modal", "MAX_MODAL_DOF",
           "convergence_horizon", "NoTruth", "truth_problem"]

#: Runs longer than this (s) are timed once (the median of repeats guards the short runs,
#: where a scheduler tick is a large fraction of the time).
REPEAT_BELOW_S = 0.1
#: The lowest linear modes followed by the modal-energy output.
MODAL_MODES = 4
#: The modal content of a drawn trajectory (a dense eigenproblem) only up to this many degrees of freedom.
MAX_MODAL_DOF = 500
#: The dominant mode's share over a drawn run is read at most at this many output times.
_SHARE_POINTS = 4000

_PROBLEMS: dict = {}


def clear_problems() -> None:
    """Forget the models built so far (a new run starts from its scenes)."""
    _PROBLEMS.clear()


def problem(scene):
    """``(model, y0)`` of ``scene``, built once per process."""
    from .plan import scene_digest

    key = scene_digest(scene)
    if key not in _PROBLEMS:
        if len(_PROBLEMS) > 64:
            _PROBLEMS.clear()
        _PROBLEMS[key] = (scene.build_model(), np.asarray(scene.y0(), float))
    return _PROBLEMS[key]


def fastest_rate(scene, model) -> float:
    """``omega_max`` (rad/s) of the convergence sweeps' ``theta = omega_max h``:
    the fastest (linearized) mode; for a first-order ODE (``model.first_order``)
    the spectral radius of its Jacobian at the initial state
    (:meth:`rk4h.models.OdeModel.rate`, 1/s), or ``2 pi / t_end`` where
    that is 0 or not finite."""
    if getattr(model, "first_order", False):
        r = model.rate(scene.y0())
        return r if math.isfinite(r) and r > 0 else 2.0 * math.pi / scene.t_end
    return float(np.max(model.modes()[0]))


def convergence_horizon(scene, model) -> float:
    """Horizon (s) of the convergence sweeps: ``[convergence] t_end`` or one
    period of the fastest (linearized) mode (:func:`fastest_rate`), at most
    the scene's ``t_end``."""
    omega_max = fastest_rate(scene, model)
    return min(scene.convergence.get("t_end", 2.0 * math.pi / omega_max), scene.t_end)


def grid(scene, model, spec: RunSpec) -> np.ndarray:
    """The output times (s) of ``spec``: the scene's grid, the convergence
    grid of the sweep (``n0 = ceil(T omega_max / theta_0)`` intervals of one
    period), or the figure grid."""
    if spec.grid == "scene":
        return scene.t_eval()
    if spec.grid == "order":
        T = convergence_horizon(scene, model)
        omega_max = fastest_rate(scene, model)
        n0 = max(1, math.ceil(T * omega_max / spec.param("theta0")))
        return np.linspace(0.0, T, n0 + 1)
    if spec.grid == "figure":
        if spec.solver:  # on the step grid of the finest h, at most FIGURE_POINTS points
            h = spec.setting
            n = round(scene.t_end / h)
            stride = max(1, math.ceil(n / FIGURE_POINTS))
            t = h * np.arange(0, n + 1, stride)
            t[-1] = min(t[-1], scene.t_end)
            return t
        return np.linspace(0.0, scene.t_end, FIGURE_POINTS + 1)
    raise ValueError(f"unknown grid {spec.grid!r}")


def _truth(model, y0, t):
    from rk4h.references.truth import reference_solution

    return reference_solution(model, y0, t)


class NoTruth(RuntimeError):
    """The reference of a run could not be computed (its message says why,
    starting with ``no truth``)."""


def truth_problem(truth) -> str | None:
    """Why ``truth`` is no reference (a failed or truncated run, a non-finite
    value), or None when every output time holds finite values."""
    status = getattr(truth.status, "value", str(truth.status))
    if not truth.ok:
        return f"no truth: {truth.kind} {status}: {_first_line(truth.message) or 'no message'}"
    y = np.asarray(truth.y, float)
    if y.size == 0 or not np.all(np.isfinite(y)):
        bad = int(np.sum(~np.all(np.isfinite(y), axis=0))) if y.ndim == 2 else y.size
        return f"no truth: {truth.kind} is not finite at {bad} of {y.shape[-1] if y.ndim else 0} output times"
    return None


def _truth_or_reason(model, y0, t):
    """``(truth, None)`` with a usable reference, else ``(truth or None, reason)``:
    a reference that raised, failed or holds NaN is a reason, never a number."""
    from .atomic import is_environment_error

    try:
        truth = _truth(model, y0, t)
    except Exception as e:  # noqa: BLE001 - a reference that raises is no truth, said in the record
        if is_environment_error(e):
            raise
        return None, f"no truth: the reference raised {type(e).__name__}: {_first_line(str(e))}"
    return truth, truth_problem(truth)


def _usable_truth_y(model, y0, t) -> np.ndarray:
    """The reference states on ``t``, or :class:`NoTruth` (a failed record)."""
    truth, reason = _truth_or_reason(model, y0, t)
    if reason:
        raise NoTruth(reason)
    return np.asarray(truth.y, float)


def _status(run) -> str:
    s = run.status
    return getattr(s, "value", str(s))


def _first_line(text) -> str:
    return str(text).splitlines()[0] if text else ""


def _timed(solver, model, y0, t, setting, repeats, compiled=False):
    """The first run, and the wall times of up to ``repeats`` runs;
    ``compiled``: through :func:`rk4h.references.solvers.integrate_compiled`
    (a reference's compiled loop, for confirmation runs)."""
    from rk4h.references.solvers import integrate, integrate_compiled

    walls, first = [], None
    for _ in range(max(1, repeats)):
        run = (integrate_compiled if compiled else integrate)(solver, model, y0, t, setting)
        first = first or run
        walls.append(run.wall_s)
        if _status(run) != "ok" or run.wall_s > REPEAT_BELOW_S:
            break
    return first, walls


def execute(scene, spec: RunSpec, quick: bool = False) -> RunRecord:
    """Run ``spec`` (a spec of ``scene``) and return its record."""
    from . import interrupt
    from .atomic import is_environment_error

    t0 = time.perf_counter()
    try:
        with np.errstate(all="ignore"):
            rec = _executor(spec.purpose)(scene, spec, quick)
    except Exception as e:  # noqa: BLE001 - a fault in one run is a failed record
        if is_environment_error(e) or interrupt.pending():
            raise
        rec = failed_record(spec.key, e)
    rec.key = spec.key
    rec.seconds = time.perf_counter() - t0
    return rec


#: Runs made before their spec executes (a sweep's batch, :mod:`rk4h.validation.sweep_batch`):
#: spec key -> SolverRun, taken by the spec's executor in place of its own integration.
PREPARED: dict = {}


def _integrate(scene, spec, model, y0, t, h):
    """``integrate`` of ``spec``'s method, or the run :data:`PREPARED` holds for it."""
    run = PREPARED.pop(spec.key, None)
    if run is not None:
        return run
    from rk4h.references.solvers import integrate

    return integrate(scene.method(spec.solver), model, y0, t, h)


def _truth_spec(scene, spec, quick):
    from .trust import fastest_omega

    model, y0 = problem(scene)
    t = grid(scene, model, spec)
    truth, reason = _truth_or_reason(model, y0, t)
    # the fastest mode (rad/s, NaN without modes): the trust table's stability cap, recorded so that
    # the measurement builds no model; an eigensolve, so only for the output whose table uses it
    omega_max = fastest_omega(model) if "work_precision" in scene.outputs else math.nan
    if reason:
        return RunRecord(spec.key, status="failed", message=reason,
                         values={"truth_kind": truth.kind if truth is not None else "", "scale": math.nan,
                                 "no_truth": reason, "omega_max": omega_max})
    y = np.asarray(truth.y, float)
    values = {"truth_kind": truth.kind, "scale": float(np.max(np.abs(y))), "omega_max": omega_max}
    if "agreement_rel" in truth.extra:  # any ODE: two references that agree (rk4h.references.ode_truth)
        values |= {"agreement_rel": float(truth.extra["agreement_rel"]), "truth_note": _first_line(truth.message)}
    arrays = {}
    if "trajectory" in spec.keep:
        arrays = {"t": t, "y": y}
        _record_modal(model, t, y, values, arrays)
        record_look(model, values, arrays)
    return RunRecord(spec.key, values=values, arrays=arrays)


def _run_spec(scene, spec, quick):
    model, y0 = problem(scene)
    t = grid(scene, model, spec)
    truth, reason = _truth_or_reason(model, y0, t)
    method = scene.method(spec.solver)
    # a reference's confirmation run steps a compiled loop (same method, steps round-off apart)
    compiled = spec.purpose == "confirm" and method.kind is Kind.REFERENCE
    run, walls = _timed(method, model, y0, t, spec.setting, spec.repeats, compiled)
    status = _status(run)
    if reason:  # the run is measured (energy, cost), its errors are not: NaN and the reason
        e_max = e_final = scale = math.nan
    else:
        y_ref = np.asarray(truth.y, float)
        scale = float(np.max(np.abs(y_ref)))
        e_max, e_final = metrics.error_max(run.y, y_ref), metrics.error_final(run.y, y_ref)
    ok = status == "ok"
    values = {"truth_kind": truth.kind if truth is not None else "", "error_max": e_max,
              "error_rel": e_max / scale, "error_final": e_final, "no_truth": reason or "",
              "energy_drift_max": metrics.energy_drift_max(model, run.y),
              "drift_per_time": metrics.drift_per_time(model, t, run.y) if ok else math.nan,
              "theory_drift_per_time": math.nan, "nfev": int(run.nfev), "n_steps": int(run.n_steps),
              "taylor_order": int(run.taylor_order or 0), "duration": float(t[-1] - t[0]),
              "implementation": str(run.extra.get("implementation", ""))}
    if method.kind is Kind.TABLEAU and model.linear and ok:
        from rk4h.references.exact import modal_solution

        ms = modal_solution(model, y0)
        duration = values["duration"]
        values["theory_drift_per_time"] = metrics.drift_theory(
            method.tableau, ms.omega, ms.eta0, ms.deta0, duration / run.n_steps, run.n_steps, duration)
    if ok:  # energy over time: growth law and phase error (rk4h.validation.energy_time)
        from . import energy_time

        values.update(energy_time.summary(model, y0, t, run.y))
    arrays = {}
    if "energy" in spec.keep and ok:
        arrays["energy_t"] = t
        arrays["energy_rel"] = np.abs(metrics.relative_energy_error(model, run.y))
    if "trajectory" in spec.keep:  # the trajectory output (rk4h.validation.outputs.trajectory)
        arrays.update(_trajectory(model, t, run))
    timing = {"wall_s": float(np.median(walls)), "wall_min": float(min(walls)), "wall_max": float(max(walls)),
              "repeats": len(walls), "compile_s": float(run.compile_s)}
    return RunRecord(spec.key, status=status, message=_first_line(run.message), values=values, timing=timing,
                     arrays=arrays)


def _trajectory(model, t, run) -> dict:
    """The run's times (s), states (2 n_dof, m; a first-order ODE's
    variables) and energies (J, where the model has an energy; a first-order
    ODE's invariant) when it covers the whole grid ``t``; else nothing."""
    y = np.asarray(run.y, float)
    if y.ndim != 2 or y.shape[1] != t.shape[0]:
        return {}
    names = [str(n) for n in getattr(model, "coord_names", [])]
    first_order = bool(getattr(model, "first_order", False))
    out = {"trajectory_t": np.asarray(t, float), "trajectory_y": y,
           "trajectory_first_order": np.array(first_order)}  # the file's reader builds no model
    if first_order:  # a first-order ODE: y is its variables
        if len(names) == y.shape[0]:
            out["trajectory_names"] = np.array(names, dtype=str)
    elif len(names) == model.n_dof:  # the state's components: q names, then their rates
        out["trajectory_names"] = np.array(names + [f"d{n}/dt" for n in names], dtype=str)
    try:
        out["trajectory_energy"] = np.asarray(model.energy(y), float).reshape(t.shape)
    except Exception:  # noqa: BLE001 - a model without an energy: none recorded
        pass
    return out


def _figure_spec(scene, spec, quick):
    model, y0 = problem(scene)
    t = grid(scene, model, spec)
    run = _integrate(scene, spec, model, y0, t, spec.setting)
    status = _status(run)
    values, arrays = {}, {}
    if status == "ok":
        arrays = {"t": np.asarray(run.t, float), "y": np.asarray(run.y, float)}
        _record_modal(model, arrays["t"], arrays["y"], values, arrays)
        record_look(model, values, arrays)
    return RunRecord(spec.key, status=status, message=_first_line(run.message), values=values, arrays=arrays)


def _order_spec(scene, spec, quick):
    model, y0 = problem(scene)
    t = grid(scene, model, spec)
    y_ref = _usable_truth_y(model, y0, t)
    n0 = t.shape[0] - 1
    h = float(t[-1]) / (n0 * max(1, round(spec.param("theta0") / spec.setting)))
    run = _integrate(scene, spec, model, y0, t, h)
    status = _status(run)
    err = metrics.error_max(run.y, y_ref) if status == "ok" else math.nan
    return RunRecord(spec.key, status=status, message=_first_line(run.message),
                     values={"h": h, "error_max": err, "scale": float(np.max(np.abs(y_ref))),
                             "t_end": float(t[-1])})


def modal_energies(model, y, omega, phi):
    """Energy (J) in each linear mode, shape (modes, m), of states ``y`` (2n, m):
    ``E_k = (adot_k^2 + omega_k^2 a_k^2) / 2`` with modal coordinates
    ``a = phi^T M q`` (``phi`` mass-normalised)."""
    n = model.n_dof
    Mphi = phi * np.asarray(model.mass, float)[:, None]
    a, adot = Mphi.T @ y[:n], Mphi.T @ y[n:]
    return 0.5 * (adot * adot + (omega[:, None] * a) ** 2)


def modal_content(model, t, y) -> dict:
    """The modal numbers a drawing of one trajectory quotes, from the model's
    linearization (``model.modes()``, ``phi`` mass-normalised).

    Parameters
    ----------
    model : rk4h.models.Model
    t : ndarray, shape (m,)
        Output times (s).
    y : ndarray, shape (2 n_dof, m)
        States ``[q, v]`` at ``t`` (SI units; NaN after a blow-up).

    Returns
    -------
    dict
        ``{}`` when the model has no usable linearization or more than
        :data:`MAX_MODAL_DOF` degrees of freedom; else ``"omega"`` (the
        modes' angular frequencies, rad/s, shape (modes,)) and, when there is
        one mass per coordinate and the initial state is finite with positive
        linear modal energy, ``"fraction0"`` (each mode's fraction of that
        energy, :func:`modal_energies` of ``y[:, 0]``), ``"share_min"`` and
        ``"share_t"``: the lowest share, along the run (finite states, at
        most 4000 output times), of the modes of the initial state's dominant
        frequency (the modes whose frequency equals, to 1e-9 relative, that of
        the mode with the largest fraction) in the linear modal energy, and its
        time (s); both NaN unless that frequency holds at least 99.9% of the
        initial energy.
    """
    if model.first_order:  # dy/dt = f(t, y): no linearization, no modes
        return {}
    n = model.n_dof
    if n > MAX_MODAL_DOF:
        return {}
    try:
        omega, phi = model.modes()
    except (NotImplementedError, ValueError, AttributeError, TypeError, np.linalg.LinAlgError):
        return {}
    omega, phi = np.asarray(omega, float), np.asarray(phi, float)
    if omega.ndim != 1 or phi.shape != (n, omega.size) or not np.isfinite(omega).all():
        return {}
    out = {"omega": omega}
    t, y = np.asarray(t, float), np.asarray(y, float)
    if np.asarray(model.mass).shape != (n,) or y.shape != (2 * n, t.size) or not np.isfinite(y[:, 0]).all():
        return out
    e0 = modal_energies(model, y[:, :1], omega, phi)[:, 0]
    total = float(e0.sum())
    if not (math.isfinite(total) and total > 0):
        return out
    frac = e0 / total
    k = int(np.argmax(frac))
    idx = np.flatnonzero(np.abs(omega - omega[k]) <= 1e-9 * max(1.0, float(omega[k])))
    share_min = share_t = math.nan
    if float(frac[idx].sum()) >= 0.999:
        step = max(1, t.size // _SHARE_POINTS)
        ts, ys = t[::step], y[:, ::step]
        ok = np.isfinite(ys).all(axis=0)
        if ok.any():
            e = modal_energies(model, ys[:, ok], omega, phi)
            tot = e.sum(axis=0)
            share = np.where(tot > 0, e[idx].sum(axis=0) / np.where(tot > 0, tot, 1.0), 1.0)
            i = int(np.argmin(share))
            share_min, share_t = float(share[i]), float(ts[ok][i])
    out.update(fraction0=frac, share_min=share_min, share_t=share_t)
    return out


def _record_modal(model, t, y, values, arrays) -> None:
    """:func:`modal_content` of a kept trajectory into a record: arrays
    ``modal_omega``, ``modal_fraction0``; values ``modal_share_min``,
    ``modal_share_t``."""
    content = modal_content(model, t, y)
    for key in ("omega", "fraction0"):
        if key in content:
            arrays[f"modal_{key}"] = np.asarray(content[key], float)
    for key in ("share_min", "share_t"):
        if key in content:
            values[f"modal_{key}"] = float(content[key])


def recorded_modal(record) -> dict:
    """The :func:`modal_content` a record holds (``{}`` when it holds none)."""
    out = {key: record.arrays[f"modal_{key}"] for key in ("omega", "fraction0") if f"modal_{key}" in record.arrays}
    out.update({key: record.values[f"modal_{key}"] for key in ("share_min", "share_t")
                if f"modal_{key}" in record.values})
    return out


def _modal_spec(scene, spec, quick):
    model, y0 = problem(scene)
    omega, phi = model.modes()
    k = min(MODAL_MODES, model.n_dof)
    order = np.argsort(omega)[:k]
    omega, phi = omega[order], phi[:, order]
    t = grid(scene, model, spec)
    run = _integrate(scene, spec, model, y0, t, spec.setting)
    from rk4h.energy import energy_scale

    # fractions of the energy of the motion (E0 - V(q*)), which the modes share
    E_motion = energy_scale(model, float(np.asarray(model.energy(y0))))
    frac = modal_energies(model, np.asarray(run.y, float), omega, phi) / E_motion
    return RunRecord(spec.key, status=_status(run), message=_first_line(run.message),
                     values={"linear": bool(model.linear)}, arrays={"t": t, "fraction": frac, "omega": omega})


def _modes_spec(scene, spec, quick):
    model, _ = problem(scene)
    omega, _ = model.modes()
    return RunRecord(spec.key, values={"omega": [float(w) for w in omega], "linear": bool(model.linear)})


def _lattice(scene, spec):
    """``(model, m, k, d)`` of a scene whose model is a uniform chain between
    walls (:meth:`rk4h.models.Model.uniform_chain`; ``d`` the thesis' lattice spacing), or the
    failed record of ``spec`` saying why not."""
    from rk4h.references import dispersion

    model, _ = problem(scene)
    mk = model.uniform_chain()
    if mk is None:
        return RunRecord(spec.key, status="failed", message="the dispersion output needs a uniform chain "
                                                             "between walls")
    return model, *mk, dispersion.THESIS_LATTICE["d"]


def _dispersion_spec(scene, spec, quick):
    from rk4h.references import dispersion

    lattice = _lattice(scene, spec)
    if isinstance(lattice, RunRecord):
        return lattice
    model, m, k, d = lattice
    N = model.n_dof
    finite = np.asarray(model.modes()[0], float)
    theory = np.asarray(dispersion.finite_chain_frequencies(N, m, k), float)
    kp_n = np.asarray(dispersion.finite_chain_wavenumbers(N, d), float)
    return RunRecord(spec.key, values={"m": m, "k": k, "d": d, "n": N},
                     arrays={"finite": finite, "theory": theory, "kp": kp_n})


def _packet_spec(scene, spec, quick):
    from rk4h.references import wavepacket

    lattice = _lattice(scene, spec)
    if isinstance(lattice, RunRecord):
        return lattice
    _, m, k, d = lattice
    kp0 = spec.setting * math.pi / d
    p = wavepacket.measure_group_velocity(kp0, m=m, k=k, d=d)
    return RunRecord(spec.key, status="ok" if p.success else "failed", values={
        "kp0": kp0, "sigma": float(p.sigma), "v_measured": float(p.v_measured),
        "v_theory": float(p.v_theory), "v_spectral": float(p.v_spectral), "rel_error": float(p.rel_error),
        "rel_error_spectral": float(p.rel_error_spectral), "spectral_offset": float(p.spectral_offset),
        "rk4_offset": float(p.rk4_offset), "success": bool(p.success)})


def _linearization_spec(scene, spec, quick):
    """The linearized model's exact modal solution against the nonlinear truth."""
    from rk4h.references.exact import modal_solution

    model, y0 = problem(scene)
    t = grid(scene, model, spec)
    y_ref = _usable_truth_y(model, y0, t)
    y_lin = np.asarray(modal_solution(model, y0)(t), float)
    n = model.n_dof
    scale_q = float(np.max(np.abs(y_ref[:n])))
    err_q = float(np.max(np.abs(y_lin[:n] - y_ref[:n])))
    arrays = {"t": t, "y_linear": y_lin, "y": y_ref} if "trajectory" in spec.keep else {}
    return RunRecord(spec.key, values={"error_max_q": err_q, "error_rel_q": err_q / scale_q if scale_q else math.nan,
                                       "amplitude_q": scale_q}, arrays=arrays)


def _stability_spec(scene, spec, quick):
    from . import stability

    r = stability.run_unit(scene, spec.unit, quick)
    return RunRecord(spec.key, result={"rows": list(r.rows), "findings": list(r.findings),
                                       "plots": list(r.plots)})


def _thesis_code_spec(scene, spec, quick):
    from rk4h.references import thesis_code

    rows = thesis_code.compare()
    return RunRecord(spec.key, values={"rows": rows, "errata": thesis_code.errata(rows)})


_PURPOSE = {"truth": _truth_spec, "run": _run_spec, "figure": _figure_spec, "order": _order_spec,
            "confirm": _run_spec, "modal": _modal_spec, "modes": _modes_spec, "dispersion": _dispersion_spec,
            "packet": _packet_spec, "linearization": _linearization_spec, "stability": _stability_spec,
            "thesis_code": _thesis_code_spec}


def _executor(purpose: str):
    """The function running a spec of ``purpose``: a built-in, else the one an
    output declares (:attr:`rk4h.validation.outputs.Output.execute`)."""
    fn = _PURPOSE.get(purpose)
    if fn is None:
        from . import outputs

        fn = outputs.executor(purpose)
    if fn is None:
        raise ValueError(f"no executor for purpose {purpose!r}")
    return fn
