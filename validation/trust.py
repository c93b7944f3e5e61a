"""How far to trust the method under test, per target error: the step it needs,
what that costs, the cheapest alternative and verdicts that survive a rerun.

Pure functions of run rows (``work_precision`` rows: solver, setting,
error_rel, nfev, n_steps, wall_s, wall_min, wall_max, compile_s, status, and
the confirmation runs' rows of the same shape); no integration.
:mod:`rk4h.validation.measure` builds ``cheapest.csv`` with :func:`trust_rows`,
:mod:`rk4h.validation.advise` uses the same error-constant model to predict a step
before confirming it with one run.

The step for a target
    A fixed-step method of order ``p`` has ``error_rel(h) ~ C h^p`` in its
    asymptotic range; ``C`` is fitted on the scene's runs whose relative
    error lies between :data:`rk4h.validation.metrics.ROUNDOFF_REL` and
    :data:`rk4h.validation.metrics.PREASYMPTOTIC_REL`, only where successive runs
    show the order ``p`` (:func:`fit_constant`: three runs with two observed
    orders within :data:`ORDER_TOLERANCE` of ``p``, or the two finest; the
    largest ``err / h^p`` of them), and the step for a target is
    ``(target / C)^(1/p)``, not limited to the scene's step list. Without
    such a range (planar4-case2: the error is not fourth order anywhere
    above round-off) the step comes from the measured runs themselves
    (:func:`measured_step`) or is not given.
    It is capped at :data:`STABILITY_MARGIN` times the method's stability
    limit on the fastest mode (``h_source = "stability"``), and flagged
    (``h_source = "round-off"``) when the round-off level ``sqrt(n) eps`` of
    its ``n`` steps exceeds the target: no step reaches it in double
    precision (the round-off study measured RK4's floor at 7.6e-15 after
    7.2e3 steps, where ``sqrt(n) eps = 1.9e-14``).

A verdict needs a run
    The predicted step is only a prediction: :mod:`rk4h.validation.confirm` runs
    the method at it (on the output grid, :func:`on_grid`), and a side
    counts for a target only with a measured run whose ``error_rel`` is at
    most the target (:func:`pick_measured`; columns ``confirmed``,
    ``confirmed_error_rel``, ``alt_confirmed``, ``alt_confirmed_error_rel``).
    Only one side measured: it takes every verdict; neither:
    :data:`UNMEASURED`.

Cost verdict (deterministic)
    Right-hand-side evaluations of the method's cheapest measured run that
    met the target against the cheapest alternative run that reached it
    (heyoka: Taylor steps x order, its own cost unit; see the README);
    equal counts: :data:`TIE`.

Time verdicts (survive a rerun)
    The measured times of the two runs (median, min and max of their
    repeats); where the method has no measured run, its time at the
    predicted step is ``a + b n`` fitted on its runs (median wall times),
    with the spread of the repeats of its run nearest in ``n`` (shown, never
    a winner). A side wins
    only when its slowest repeat beats the other's fastest *and* the medians
    differ by at least :data:`TIME_MARGIN`; otherwise ``tie``. ``one_run``
    adds each side's compile and start-up time (``compile_s``: heyoka's JIT,
    numba's first compile; :func:`compile_spread`); ``amortized`` leaves it
    out (many runs of one compiled model).
"""
from __future__ import annotations

import math

import numpy as np

from .metrics import PREASYMPTOTIC_REL, ROUNDOFF_REL

__all__ = ["TIME_MARGIN", "STABILITY_MARGIN", "TIE", "ORDER_TOLERANCE", "asymptotic_fit", "bracket_step",
           "fit_constant", "measured_step", "in_fit_range", "error_constant", "step_for", "roundoff_level",
           "time_model", "time_verdict", "compile_spread", "rhs_calls", "fixed_rhs", "fastest_omega", "stable_step", "trust_rows", "COLUMNS", "TIMING_COLUMNS",
           "UNMEASURED", "on_grid", "predicted_steps", "pick_measured", "rhs_verdict", "is_confirmed"]

#: A time verdict needs the medians this far apart (and the repeats disjoint):
#: between two --quick reports on the shared 2-core machine (one repeat per
#: run), the wall time of the same run differed by up to 2.5x (median 1.2x,
#: 99th percentile 2.2x over 220 runs; see the README, "Verdicts").
TIME_MARGIN = 3.0
#: The predicted step is capped at this fraction of the stability limit.
STABILITY_MARGIN = 0.9
TIE = "tie"
_EPS = float(np.finfo(float).eps)

#: The verdict of a target that no measured run of any method reached.
UNMEASURED = "unmeasured"

COLUMNS = ["scene", "target_error", "method", "order", "error_constant", "h", "h_source", "n_steps",
           "rhs", "cost_unit", "time_s", "compile_s", "confirmed_error_rel", "confirmed", "alternative", "alt_setting",
           "alt_h", "alt_rtol", "alt_error_rel", "alt_rhs", "alt_cost_unit", "alt_time_s", "alt_compile_s", "alt_confirmed_error_rel", "alt_confirmed",
           "verdict_rhs", "verdict_one_run", "verdict_amortized", "note",
           "time_context"]
#: Columns that are timings (differ between runs; machine-dependent); the two
#: time verdicts are derived from them with a margin and are compared between
#: runs on one machine only.
TIMING_COLUMNS = {"time_s", "compile_s", "alt_time_s", "alt_compile_s", "verdict_one_run", "verdict_amortized",
                  "time_context"}  # time_context: the load around the timed runs (rk4h.validation.timing_context)


#: An observed order ``log(e1/e2)/log(h1/h2)`` agrees with the method's order
#: ``p`` when it lies within ``p +- ORDER_TOLERANCE``; a fit needs two
#: successive agreeing orders (three steps), since one pair can agree by
#: chance (planar4-case2: 3.90 between 6.25e-4 s and 3.1e-4 s, then -1.64
#: and 1.23: `python validation/advise.py planar4-case2 --target 1e-6 --json`
#: lists its calibration runs).
ORDER_TOLERANCE = 0.5


def in_fit_range(err: float) -> bool:
    """Whether a relative error lies where an error constant is fitted:
    above round-off and below the pre-asymptotic level
    (``ROUNDOFF_REL < err < PREASYMPTOTIC_REL``; NaN and inf never)."""
    return ROUNDOFF_REL < err < PREASYMPTOTIC_REL


def _order(a, b) -> float:
    """Observed order between the runs ``a = (h1, e1)`` and ``b = (h2, e2)``."""
    (h1, e1), (h2, e2) = a, b
    if not (e1 > 0 and e2 > 0 and math.isfinite(e1) and math.isfinite(e2) and h1 != h2):
        return math.nan
    return math.log(e1 / e2) / math.log(h1 / h2)


def asymptotic_fit(points, order: int) -> dict:
    """The error constant of ``err ~ C h^order`` from calibration runs
    ``points = [(h, err), ...]`` at successive steps (largest first).

    The fit takes the first three successive points whose errors lie in
    ``(ROUNDOFF_REL, PREASYMPTOTIC_REL)`` and whose two observed orders both
    lie within :data:`ORDER_TOLERANCE` of ``order``; ``C`` is the largest
    ``err / h^order`` of the three (conservative). A pre-asymptotic point (an
    order off ``p``) or a cancellation (an error dip: one order too high, the
    next too low) has no such window around it.

    Returns ``{"asymptotic": bool, "C": float (NaN unless asymptotic),
    "observed_order": float, "used": [indices]}``; ``observed_order`` is the
    order across the window, or, when there is none, between the last two
    usable points (NaN with fewer than two).
    """
    pts = [(float(h), float(e)) for h, e in points]
    usable = [in_fit_range(e) and h > 0
              for h, e in pts]
    for i in range(len(pts) - 2):
        if not all(usable[i:i + 3]):
            continue
        q1, q2 = _order(pts[i], pts[i + 1]), _order(pts[i + 1], pts[i + 2])
        if abs(q1 - order) <= ORDER_TOLERANCE and abs(q2 - order) <= ORDER_TOLERANCE:
            used = [i, i + 1, i + 2]
            return {"asymptotic": True, "C": max(pts[k][1] / pts[k][0] ** order for k in used),
                    "observed_order": _order(pts[i], pts[i + 2]), "used": used}
    idx = [k for k, u in enumerate(usable) if u]
    q = _order(pts[idx[-2]], pts[idx[-1]]) if len(idx) >= 2 else math.nan
    return {"asymptotic": False, "C": math.nan, "observed_order": q, "used": []}


def bracket_step(points, target: float):
    """The step for ``target`` between two measured successive runs: the last
    pair of ``points = [(h, err), ...]`` (largest step first) whose first
    error exceeds ``target`` and whose second meets it, interpolated on
    ``log err`` against ``log h`` (clamped to the pair). ``(h, err, local
    order)``, or None when no pair brackets the target."""
    for k in range(len(points) - 1, 0, -1):
        (ha, ea), (hb, eb) = points[k - 1], points[k]
        if math.isfinite(ea) and math.isfinite(eb) and ea > target >= eb and ha > hb:
            q = _order((ha, ea), (hb, eb)) if eb > 0 else math.inf
            if not (math.isfinite(q) and q > 0):
                return hb, eb, q
            h = min(ha, max(hb, ha * (target / ea) ** (1.0 / q)))
            return h, ea * (h / ha) ** q, q
    return None


def fit_constant(h, err, order: int) -> tuple[float, str, float]:
    """``(C, source, observed_order)`` of ``err ~ C h^order`` from runs at the
    steps ``h`` (any order; sorted here, largest first).

    ``C`` comes from :func:`asymptotic_fit` (three successive usable runs,
    two observed orders within :data:`ORDER_TOLERANCE` of ``order``; source
    ``"error constant"``), else from the two smallest usable steps when their
    observed order agrees (``"error constant (2 runs)"``: a scene's step list
    may hold only two runs between the pre-asymptotic range and round-off),
    else NaN (``"no asymptotic fit"``). The largest ``err / h^order`` of the
    runs used is taken (conservative).
    """
    pts = sorted(((float(a), float(b)) for a, b in zip(h, err) if float(a) > 0), reverse=True)
    fit = asymptotic_fit(pts, order)
    if fit["asymptotic"]:
        return fit["C"], "error constant", fit["observed_order"]
    usable = [(a, b) for a, b in pts if in_fit_range(b)]
    if len(usable) >= 2:
        i = pts.index(usable[-2])
        if pts[i + 1] == usable[-1] and abs(_order(usable[-2], usable[-1]) - order) <= ORDER_TOLERANCE:
            return (max(b / a ** order for a, b in usable[-2:]), "error constant (2 runs)",
                    _order(usable[-2], usable[-1]))
    return math.nan, "no asymptotic fit", fit["observed_order"]


def error_constant(h, err, order: int) -> float:
    """``C`` of ``err ~ C h^order`` (:func:`fit_constant`); NaN when the runs
    show no asymptotic range."""
    return fit_constant(h, err, order)[0]


def roundoff_level(n_steps: float) -> float:
    """Relative round-off after ``n_steps`` steps, ``sqrt(n) eps`` (random walk)."""
    return math.sqrt(max(float(n_steps), 1.0)) * _EPS


def step_for(target: float, C: float, order: int, t_span: float, h_stab: float = math.inf):
    """``(h, source, n_steps)``: the largest step with ``C h^order <= target``
    over ``t_span`` s, capped at :data:`STABILITY_MARGIN` x ``h_stab``.
    ``source``: ``"error constant"``, ``"stability"``, ``"round-off"`` (the
    target is below the round-off level at that step: ``h`` is NaN) or
    ``"no fit"``."""
    if not (math.isfinite(C) and C > 0):
        return math.nan, "no fit", 0
    h = (target / C) ** (1.0 / order)
    source = "error constant"
    if math.isfinite(h_stab) and h > STABILITY_MARGIN * h_stab:
        h, source = STABILITY_MARGIN * h_stab, "stability"
    h = min(h, t_span)
    n = int(math.ceil(t_span / h * (1 - 1e-12)))
    if roundoff_level(n) > target:
        return math.nan, "round-off", n
    return t_span / n, source, n


def time_model(rows):
    """``f(n) -> (median, lo, hi)`` seconds for ``n`` steps of a fixed-step
    method from its runs (``n_steps``, ``wall_s``, ``wall_min``,
    ``wall_max``): ``a + b n`` by least squares on the medians (``a >= 0``),
    the spread scaled from the run nearest in ``n``."""
    rows = [r for r in rows if r.get("n_steps", 0) > 0 and np.isfinite(r.get("wall_s", math.nan))]
    if not rows:
        return lambda n: (math.nan, math.nan, math.nan)
    n = np.array([r["n_steps"] for r in rows], float)
    w = np.array([r["wall_s"] for r in rows], float)
    if len(rows) >= 2 and np.ptp(n) > 0:
        b, a = np.polyfit(n, w, 1)
        if a < 0 or b <= 0:
            a, b = 0.0, float(np.median(w / n))
    else:
        a, b = 0.0, float(w[0] / n[0])

    def f(steps):
        med = a + b * steps
        near = rows[int(np.argmin(np.abs(np.log(n) - math.log(max(steps, 1)))))]
        lo = med * near.get("wall_min", near["wall_s"]) / near["wall_s"]
        hi = med * near.get("wall_max", near["wall_s"]) / near["wall_s"]
        return float(med), float(lo), float(hi)

    return f


def is_confirmed(x) -> bool:
    """A ``confirmed`` / ``alt_confirmed`` cell: True as built (bool,
    ``numpy.bool_``) or as read back from a table (the text ``"True"``)."""
    return str(x).strip().lower() == "true"


def time_verdict(a: str, ta, b: str, tb) -> str:
    """``a``, ``b`` or :data:`TIE` from ``(median, lo, hi)`` times: a side wins
    when its slowest repeat beats the other's fastest and the medians differ
    by :data:`TIME_MARGIN`."""
    fa, fb = all(np.isfinite(ta)), all(np.isfinite(tb))
    if not (fa and fb):
        return a if fa else (b if fb else TIE)
    if ta[2] < tb[1] and tb[0] >= TIME_MARGIN * ta[0]:
        return a
    if tb[2] < ta[1] and ta[0] >= TIME_MARGIN * tb[0]:
        return b
    return TIE


def compile_spread(rows) -> tuple:
    """``(largest, smallest, largest)`` ``compile_s`` over a solver's runs
    (zeros when there are none), added to its ``(median, lo, hi)`` time for
    ``verdict_one_run``.

    One run pays one compile; the largest is the cautious figure. But a
    compile is timed once per run, with no repeats, so its spread between
    reruns is unknown: the smallest compile of the solver's runs is the
    lower end (in three runs of thesis-2dof-case1, heyoka's five
    compiles spanned 2.5 to 4.4 ms, up to 1.6x within one run), and a
    one-run verdict against a method whose time lies inside that range is a
    ``tie`` rather than a flip between reruns.
    """
    c = [float(r.get("compile_s", 0.0) or 0.0) for r in rows]
    c = [x for x in c if math.isfinite(x)] or [0.0]
    return max(c), min(c), max(c)


def _plus(t, c):
    return tuple(a + b for a, b in zip(t, c))


def rhs_calls(row) -> float:
    """A run's cost in right-hand-side evaluations: ``nfev``, or for a Taylor
    method (``taylor_order > 0``, heyoka) its steps times its order."""
    order = row.get("taylor_order", 0) or 0
    return float(row["n_steps"] * order) if order > 0 else float(row["nfev"])


def fixed_rhs(method, n_steps: int) -> int:
    """RHS calls of ``n_steps`` steps of the fixed-step ``method`` (a
    :class:`rk4h.references.registry.Method`): its first step's calls, then
    ``nfev_per_step`` each (first-same-as-last reuse counted)."""
    per = int(method.nfev_per_step)
    first = int(getattr(method.tableau, "nfev_first_step", per) or per)
    return first + (int(n_steps) - 1) * per


def fastest_omega(model) -> float:
    """Largest angular frequency (rad/s) of ``model``'s modes (its
    linearization's for a nonlinear model); NaN when it has none."""
    try:
        omega = np.asarray(model.modes()[0], float)
    except Exception:  # noqa: BLE001 - a model without modes
        return math.nan
    return float(np.max(np.abs(omega))) if omega.size else math.nan


def stable_step(method, omega_max: float) -> float:
    """The largest stable step (s) of ``method`` on a mode of ``omega_max``
    rad/s: its imaginary-axis boundary over ``omega_max``; inf when unknown
    (no tableau, no modes, or no stable interval on the imaginary axis)."""
    from rk4h.stability_function import imaginary_axis_boundary

    if method.tableau is None or not (math.isfinite(omega_max) and omega_max > 0):
        return math.inf
    b = imaginary_axis_boundary(method.tableau)
    return b / omega_max if b > 0 else math.inf


def measured_step(points, target: float, t_span: float, h_stab: float, fit_source: str, q_obs: float):
    """``(h, source, n_steps)`` for ``target`` from the runs ``points = [(h,
    err), ...]`` (largest step first) when they give no error constant:
    interpolated between the two successive runs that bracket the target
    (:func:`bracket_step`, ``"measured bracket"``), else the largest run that
    meets it (``"measured run"``: a larger step may also do), else NaN with
    ``fit_source`` and the observed order. Capped at
    :data:`STABILITY_MARGIN` x ``h_stab``."""
    br = bracket_step(points, target)
    if br is not None:
        h, source = br[0], "measured bracket"
    else:
        met = [a for a, b in points if math.isfinite(b) and b <= target]
        if not met:
            why = (f"observed order {q_obs:.2f} at the finest steps" if math.isfinite(q_obs) else
                   f"fewer than two runs with error in ({ROUNDOFF_REL:g}, {PREASYMPTOTIC_REL:g})")
            return math.nan, f"{fit_source}: {why}", 0
        h, source = max(met), "measured run"
    if math.isfinite(h_stab) and h > STABILITY_MARGIN * h_stab:
        h, source = STABILITY_MARGIN * h_stab, "stability"
    n = int(math.ceil(t_span / min(h, t_span) * (1 - 1e-12)))
    return t_span / n, source, n


def on_grid(h: float, output_dt=None) -> float:
    """The step (s) a confirmation run uses for a predicted step ``h``: the
    largest step ``<= h`` that divides the output spacing ``output_dt`` (s),
    ``output_dt / k`` with the smallest integer ``k`` (``output_dt`` itself
    when ``h`` exceeds it), so that every output time is a step and none is
    interpolated (off the step grid a fixed-step run interpolates its
    outputs, a third-order error: :mod:`rk4h.references.solvers.fixed`). ``h``
    unchanged when ``output_dt`` is None or not positive; NaN stays NaN."""
    if not math.isfinite(h) or h <= 0 or output_dt is None or not output_dt > 0:
        return h
    dt = float(output_dt)
    return dt / math.ceil(dt / h * (1 - 1e-12)) if h < dt else dt


def predicted_steps(rows, method, t_span: float, h_stab: float, targets) -> dict:
    """The step the fixed-step ``method`` needs for each target, predicted
    from its runs among ``rows`` (no integration): ``{"C", "fit_source",
    "observed_order", "steps": [(h, source, n_steps), ...]}``, one step per
    target (:func:`step_for` from the error constant, else
    :func:`measured_step`; ``h`` NaN where neither gives one). The prediction
    a confirmation run checks (:mod:`rk4h.validation.confirm`)."""
    ok = [r for r in rows if r["status"] == "ok" and np.isfinite(r["error_rel"]) and r["solver"] == method.name]
    order = int(method.order)
    pts = sorted(((r["setting"], r["error_rel"]) for r in ok), reverse=True)
    C, fit_source, q_obs = fit_constant(*zip(*pts), order) if pts else (math.nan, "no run", math.nan)
    steps = []
    for target in targets:
        h, source, n = step_for(target, C, order, t_span, h_stab)
        if source == "error constant":
            source = fit_source
        elif source == "no fit":
            h, source, n = measured_step(pts, target, t_span, h_stab, fit_source, q_obs)
        steps.append((h, source, n))
    return {"C": C, "fit_source": fit_source, "observed_order": q_obs, "steps": steps}


def pick_measured(runs, target: float):
    """The cheapest run of ``runs`` (rows with ``status``, ``error_rel``,
    ``nfev``, ``n_steps``, ``setting``) whose measured ``error_rel`` is at most
    ``target``: fewest RHS calls (:func:`rhs_calls`), then the larger
    setting; None when no run reached it. Only such a run can make its method
    a winner."""
    met = [r for r in runs if r["status"] == "ok" and np.isfinite(r["error_rel"]) and r["error_rel"] <= target]
    return min(met, key=lambda r: (rhs_calls(r), -float(r["setting"])), default=None)


def rhs_verdict(a: str, rhs_a: float, b: str, rhs_b: float) -> str:
    """``a`` or ``b``, whichever needs fewer RHS calls; :data:`TIE` when the
    counts are equal."""
    if rhs_a < rhs_b:
        return a
    if rhs_b < rhs_a:
        return b
    return TIE


def _timing_of(r) -> tuple:
    return (float(r["wall_s"]), float(r.get("wall_min", r["wall_s"])), float(r.get("wall_max", r["wall_s"])))


def _builtin_cost_unit(solver: str) -> str:
    """The cost unit a built-in method declares (``""`` for another name)."""
    from rk4h.references.registry import resolve

    try:
        return resolve(solver).cost_unit.value
    except ValueError:
        return ""


def trust_rows(scene: str, rows, method, t_span: float, h_stab: float, targets, *,
               setting_name=lambda s: "setting", confirmations=(), output_dt=None,
               cost_unit=_builtin_cost_unit) -> list[dict]:
    """One row per target (:data:`COLUMNS`): the step ``method`` (a
    :class:`rk4h.references.registry.Method`: name, order, RHS calls per step)
    needs over ``t_span`` s, its cost, the cheapest other run reaching the
    target (by RHS calls), and the three verdicts. ``h_stab``: the method's
    largest stable step on the model's fastest mode (inf when unknown).

    ``rows`` are the scene's runs (``work_precision`` rows) and predict the
    step (:func:`predicted_steps`, put on the output grid with
    :func:`on_grid` when ``output_dt`` (s) is given); ``confirmations`` are
    the extra runs made to check it (:mod:`rk4h.validation.confirm`: the method
    at the predicted steps, the references at tighter tolerances), rows of
    the same shape.

    A verdict needs a run: a side counts only with a measured run whose
    ``error_rel`` is at most the target (:func:`pick_measured`, over
    ``rows`` and ``confirmations``). The method's side is its cheapest such
    run (``h``, ``n_steps``, ``rhs``, ``time_s`` are that run's,
    ``confirmed_error_rel`` its error, ``confirmed`` true); without one, ``h``
    is the prediction, ``confirmed`` false, ``confirmed_error_rel`` the error
    of the run at the predicted step (NaN when it was not run) and the method
    wins nothing. The alternative likewise (``alt_confirmed``). Neither side
    measured: every verdict is :data:`UNMEASURED`. Equal RHS calls:
    :data:`TIE`. ``cost_unit(solver)``: the cost unit (``CostUnit`` value)
    ``solver`` declares, for ``alt_cost_unit``; ``cost_unit`` is ``method``'s.
    """
    ok = [r for r in rows if r["status"] == "ok" and np.isfinite(r["error_rel"])]
    extra = [r for r in confirmations if r["status"] == "ok" and np.isfinite(r["error_rel"])]
    name = method.name
    mine = [r for r in ok if r["solver"] == name]
    mine_all = mine + [r for r in extra if r["solver"] == name]
    others = [r for r in ok + extra if r["solver"] != name]
    order = int(method.order)
    pred = predicted_steps(rows, method, t_span, h_stab, targets)
    C = pred["C"]
    timing = time_model(mine)
    compile_m = compile_spread(mine_all)
    out = []
    for target, (h, source, n) in zip(targets, pred["steps"]):
        if math.isfinite(h) and output_dt is not None:
            h = on_grid(h, output_dt)
            n = int(round(t_span / h))
        at_h = [r for r in mine_all if math.isfinite(h) and math.isclose(float(r["setting"]), h, rel_tol=1e-9)]
        got = pick_measured(mine_all, target)
        if got is not None:
            h_run = float(got["setting"])
            confirming = any(r is got for r in extra)
            row_src = (source if confirming and math.isfinite(h) and math.isclose(h_run, h, rel_tol=1e-9)
                       else "confirmation run" if confirming else "measured run")
            h, n, rhs, tm = h_run, int(got["n_steps"]), rhs_calls(got), _timing_of(got)
            source = row_src
            conf_err = float(got["error_rel"])
        else:
            rhs = fixed_rhs(method, n) if math.isfinite(h) else math.nan
            tm = timing(n) if math.isfinite(h) else (math.nan,) * 3
            conf_err = float(min(r["error_rel"] for r in at_h)) if at_h else math.nan
        alt = min((r for r in others if r["error_rel"] <= target), key=lambda r: (rhs_calls(r), r["setting"]),
                  default=None)
        row = {"scene": scene, "target_error": target, "method": name, "order": order, "error_constant": C,
               "h": h, "h_source": source, "n_steps": n if math.isfinite(h) else 0, "rhs": rhs,
               "cost_unit": method.cost_unit.value, "alt_cost_unit": "",
               "time_s": tm[0], "compile_s": compile_m[0], "confirmed_error_rel": conf_err,
               "confirmed": got is not None, "alternative": "", "alt_setting": math.nan,
               "alt_error_rel": math.nan, "alt_rhs": math.nan, "alt_time_s": math.nan, "alt_compile_s": math.nan,
               "alt_confirmed_error_rel": math.nan, "alt_confirmed": False}
        missed = ("" if got is not None or not math.isfinite(conf_err) else
                  f"; {name} at the predicted h = {h:.3g} s measured {conf_err:.2g}, above the target")
        if alt is None:
            if got is None:
                what = (f"{name} predicted h = {h:.3g} s ({source}), not confirmed by a run" if math.isfinite(h)
                        else f"{name}: {source}")
                row.update(verdict_rhs=UNMEASURED, verdict_one_run=UNMEASURED, verdict_amortized=UNMEASURED,
                           note=f"no run of any method reached the target; {what}" + missed)
            else:
                row.update(verdict_rhs=name, verdict_one_run=name, verdict_amortized=name,
                           note=f"{name} at h = {h:.3g} s measured {conf_err:.2g}; no other run of the scene "
                                f"reached the target")
            out.append(row)
            continue
        ta = _timing_of(alt)
        ca = compile_spread([r for r in ok + extra if r["solver"] == alt["solver"]])
        row.update(alternative=alt["solver"], alt_setting=alt["setting"], alt_error_rel=alt["error_rel"],
                   alt_rhs=rhs_calls(alt), alt_cost_unit=cost_unit(alt["solver"]), alt_time_s=ta[0],
                   alt_compile_s=ca[0],
                   alt_confirmed_error_rel=alt["error_rel"], alt_confirmed=True)
        reached = (f"{alt['solver']} {setting_name(alt['solver'])} {alt['setting']:g} reached "
                   f"{alt['error_rel']:.2g}")
        if alt.get("implementation") == "compiled":
            cvode = str(alt["solver"]).startswith("cvode")
            how = "compiled callbacks" if cvode else "compiled loop"
            timed = "scikit-sundae's" if cvode else "scipy's"
            reached += f" (its {how}, a confirmation run; the scene's runs time {timed})"
        if got is None:
            why = (f"{name} predicted h = {h:.3g} s ({source}), not confirmed by a run" if math.isfinite(h)
                   else f"{name}: {source}")
            row.update(verdict_rhs=alt["solver"], verdict_one_run=alt["solver"], verdict_amortized=alt["solver"],
                       note=f"{why}{missed}; {reached}")
        else:
            row["verdict_rhs"] = rhs_verdict(name, rhs, alt["solver"], rhs_calls(alt))
            row["verdict_amortized"] = time_verdict(name, tm, alt["solver"], ta)
            row["verdict_one_run"] = time_verdict(name, _plus(tm, compile_m), alt["solver"], _plus(ta, ca))
            row["note"] = f"{name} at h = {h:.3g} s ({source}) measured {conf_err:.2g}; {reached}"
        out.append(row)
    return out
