"""The advisor: the cheapest method and setting that meets a target error on a
scene, whether a cheaper model would do, and what to watch out for -- without
running the report.

    python validation/advise.py SCENE --target REL [--json] [--threads N] [--allow-code]

``SCENE`` is a scene file or a shipped scene's name (``thesis-2dof-case1``);
``REL`` the target relative error (``error_max / max |y_ref|`` over the
scene's output grid and horizon, the report's ``error_rel``).

How (all plain data):

1. *Calibration.* Each fixed-step method of the scene (a tableau) runs at its
   scene's largest step, halved (on the output grid) until its error is below
   :data:`rk4h.validation.metrics.PREASYMPTOTIC_REL` (at most
   :data:`CALIBRATION_HALVINGS` times), then halved further, at most
   :data:`FIT_HALVINGS` times, until three successive steps ``h, h/2, h/4``
   show the method's order: both observed orders ``log2(e(h)/e(h/2))``
   within :data:`ORDER_TOLERANCE` of ``p`` (:func:`asymptotic_fit`). ``C``
   of ``error ~ C h^p`` is then the largest ``err / h^p`` of those three
   (conservative) and gives the step for the target
   (:func:`rk4h.validation.trust.step_for`: capped at 0.9 of the stability limit,
   refused below the round-off level). One run is not enough: on
   planar4-case2 a single run (h = 3.1e-4 s, error 1.2e-2, in a dip of a
   non-monotone error curve) gave ``C`` 2300x below ``err / h^4`` at
   h = 2.4e-6 s. If the halvings reach the
   target before the order is seen (a step whose error exceeds the target,
   then half of it that meets it), the step is interpolated on log-log
   between those two measured runs (:func:`bracket_step`, source "measured
   bracket"); if the budget runs out first, ``C`` is the largest
   ``err / h^p`` measured (source "pre-asymptotic"). The candidate reports
   the observed order (``observed_order``) and its calibration runs
   (``calibration``: ``[step, error]`` pairs, also in ``--json``). Each adaptive
   reference runs at rtol 1e-4 and 1e-8 (heyoka: 1e-4 and 1e-10); a
   straight line through ``log error`` against ``log rtol`` gives the rtol
   for the target (rounded down to a power of ten) and the cost by the same
   interpolation.
2. *Confirmation of every candidate.* A candidate predicted to miss the
   target (an adaptive one whose rtol reached :data:`_RTOL_MIN`) or without
   a prediction is not run and not listed (``not_listed``, with the
   reason). Every other one is run at its predicted setting against the
   truth and listed only once runs confirm it (:func:`_confirm_fixed`,
   :func:`_confirm_adaptive`): an adaptive one at rtol, then rtol / 10
   after a miss (:data:`CONFIRM_TRIES` runs); a fixed-step one whose
   calibration showed its order by one run, else (no order seen, an error
   that rose when the step was halved, or a run that missed: the error is
   not known to be monotone in ``h``) only when all of at least
   :data:`SAMPLE_STEPS` steps in ``[h/2, h]`` on the output grid
   (:func:`sample_steps`) meet the target; a run that misses shrinks the
   step below it by the error ratio (at least 10 %), at most
   :data:`CONFIRM_ROUNDS` rounds. A round's first step runs alone (its
   wall time is the candidate's first timing); its other steps run side by
   side on up to ``threads`` cores where the model's loop is compiled
   (:func:`_first_miss`), recorded in their order up to the first miss, so
   the advice is the same for any number of threads. On planar4-case2
   RK4's error is erratic in
   ``h`` (623 steps per 0.02 s miss 1e-3 with 2.4e-3, 624 meet it with
   6.0e-4): the advisor says so and the sampled runs are the evidence.
   ``confirmed_error`` is the largest error of the runs that confirm the
   setting; ``cost_rhs`` the RHS calls of the run at it (heyoka: Taylor steps
   x order); ``cost_s`` the median wall time of up to
   :data:`TIMING_REPEATS` runs at it, measured on this machine (one run when
   it takes over :data:`rk4h.validation.execute.REPEAT_BELOW_S`, as in the
   report), with the compile time (``compile_s``) apart. A candidate other
   than the method under test whose predicted calls and time are both over
   :data:`SKIP_FACTOR` times the best confirmed is not run
   (:data:`SKIP_MIN_S`). CVODE (:data:`PYTHON_CALLBACK`: a Python callback
   per right-hand-side call) is calibrated after every other candidate is
   confirmed, and not past its looser calibration run when that run alone
   already took more calls than the fewest confirmed and over
   :data:`SKIP_FACTOR` times the fastest time (:func:`_late_candidate`).
3. *Choice.* The answer (``method``, ``setting``, ...) is the listed
   candidate with the fewest RHS calls, a deterministic cost; ``fastest``
   names the listed one with the smallest median wall time, with
   :func:`rk4h.validation.trust.time_verdict` against the runner-up (a ``tie``
   unless the medians are :data:`rk4h.validation.trust.TIME_MARGIN` apart and the
   repeats disjoint), and ``fastest_one_run`` the fastest with its compile
   time added.
   DOP853 (any reference with a compiled loop,
   :data:`rk4h.references.solvers.COMPILED_RUNNERS`) is calibrated, confirmed
   and timed as that loop (:func:`rk4h.references.solvers.integrate_compiled`,
   scipy's DOP853 step for step to round-off, its sums in another order:
   where steps are rejected near the tolerance a run can part from
   scipy's, as scipy's own does when rtol moves one ulp; scipy's
   ``solve_ivp`` steps in Python and is not run): its candidate says ``implementation =
   "compiled"``. So are CVODE-Adams and CVODE-BDF: SUNDIALS CVODE driven
   through ``ctypes`` with compiled callbacks, equal to scikit-sundae's run
   (:mod:`rk4h.references.solvers.cvode_compiled`). A confirmation at a setting a calibration run already ran
   reuses that run (the runs are deterministic); timing repeats are new runs.
4. *Model.* A linear model has a closed form (its modal solution: no
   integration needed for the answer); a nonlinear one with a linearization
   is compared with its linearized closed form at this amplitude.
5. *Warnings.* An output spacing that aliases the fastest mode, a scene step
   past a method's stability limit, a target below the round-off level.

Exit status: 0, or 2 on bad input (one line, no traceback).
"""
from __future__ import annotations

import argparse
import json
import math
import sys
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

if __package__ in (None, ""):  # run as a script: python validation/advise.py
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
    try:  # the folders import as rk4h, rk4h.references, rk4h.validation once installed
        import rk4h  # noqa: F401
    except ModuleNotFoundError:
        sys.stderr.write("advise: the harness is not installed: run `pip install -e .` in the checkout first\n")
        raise SystemExit(2) from None

from rk4h.references.registry import Kind  # noqa: E402
from rk4h.validation import metrics, trust  # noqa: E402
from rk4h.validation.trust import ORDER_TOLERANCE, asymptotic_fit, bracket_step  # noqa: E402,F401 - re-exported

__all__ = ["Advice", "advise", "main", "asymptotic_fit", "bracket_step", "CALIBRATION_HALVINGS",
           "FIT_HALVINGS", "ORDER_TOLERANCE", "CONFIRM_TRIES", "CONFIRM_ROUNDS", "SAMPLE_STEPS", "TIMING_REPEATS",
           "SKIP_FACTOR", "SKIP_MIN_S", "PYTHON_CALLBACK", "sample_steps", "compiled_own_model"]

#: Halvings from the scene's largest step to the first error below
#: :data:`rk4h.validation.metrics.PREASYMPTOTIC_REL`.
CALIBRATION_HALVINGS = 8
#: Further halvings, after that, to see the method's order or bracket the
#: target (each run costs twice the one before: at most 2^9 - 1 times the first
#: one's steps). planar4-case2 needs all 8 at a target of 1e-9 (3.1e-4 s ->
#: 1.2e-6 s; its error curve shows no fourth order anywhere above round-off).
FIT_HALVINGS = 8
#: Confirmation runs of an adaptive candidate (rtol / 10 after a miss).
CONFIRM_TRIES = 4
#: Confirmation rounds of a fixed-step candidate: a run (or a sample) that
#: misses shrinks the step and starts a new round.
CONFIRM_ROUNDS = 8
#: Steps run in ``[h/2, h]`` where the error is not known to fall
#: monotonically with the step (:func:`sample_steps`).
SAMPLE_STEPS = 8
#: Wall time of a listed candidate: the median of this many runs at its
#: setting (one run when it takes longer than
#: :data:`rk4h.validation.execute.REPEAT_BELOW_S`, as in the report).
TIMING_REPEATS = 3
#: A candidate other than the scene's method under test
#: (:func:`rk4h.validation.plan.under_test`, always run) is not run, and not
#: listed, when its predicted RHS calls and
#: its predicted time both exceed this many times the fewest calls and the
#: fastest time already confirmed, and its predicted time exceeds
#: :data:`SKIP_MIN_S`: it could win neither unless its prediction were off by
#: this factor.
SKIP_FACTOR = 10.0
SKIP_MIN_S = 0.2
#: References whose right-hand side is a Python callback per call (CVODE
#: through scikit-sundae, about 10 us a call): calibrated after every other
#: candidate is confirmed, and only as far as they can still win
#: (:func:`_late_candidate`).
PYTHON_CALLBACK = ("cvode-adams", "cvode-bdf")
TIMING_NOTE = (f"wall time measured on this machine: median of up to {TIMING_REPEATS} runs at the setting, "
               f"compile time (heyoka's JIT, numba) apart; a shared machine's load moves it")
#: The two tolerances an adaptive method is first probed at, unless its
#: registry entry gives its own (``Method.advisor_rtols``: heyoka's).
_RTOL_PAIR = (1e-4, 1e-8)
_RTOL_MIN = 1e-14


@dataclass
class Advice:
    """What :func:`advise` found (SI units; errors relative, see the module docstring)."""

    scene: str
    target: float
    method: str = ""
    setting: float = math.nan
    setting_name: str = ""
    model: str = ""
    model_note: str = ""
    predicted_error: float = math.nan
    confirmed_error: float = math.nan
    cost_rhs: float = math.nan
    cost_s: float = math.nan
    predicted_rhs: float = math.nan
    status: str = "ok"
    fewest_calls: str = ""
    fastest: dict = field(default_factory=dict)
    fastest_one_run: str = ""
    timing: str = TIMING_NOTE
    candidates: list = field(default_factory=list)
    not_listed: list = field(default_factory=list)
    warnings: list = field(default_factory=list)

    def to_json(self) -> str:
        return json.dumps(asdict(self), allow_nan=True, default=float)


def compiled_own_model(model) -> bool:
    """Whether ``model`` is one of rk4h's own model classes (not a scene's
    ``module:Class`` nor a subclass defined elsewhere, whose methods could run
    the user's code) with a compiled force: a tableau's runs on it go through
    a loop that holds no lock of Python's (:mod:`rk4h.fast.codegen`:
    ``nogil``), so they may run side by side in threads."""
    import rk4h.fast

    return type(model).__module__.partition(".")[0] == "rk4h" and bool(rk4h.fast.supports(model))


class _Problem:
    """The scene's model, initial state, output grid and truth, built once."""

    def __init__(self, scene, threads: int = 1):
        from rk4h.validation.execute import problem

        from rk4h.references.truth import reference_solution

        self.scene = scene
        self.threads = max(1, int(threads))  # at most this many sampled runs side by side (_first_miss)
        self.model, self.y0 = problem(scene)
        self.t = scene.t_eval()
        self.y_ref = np.asarray(reference_solution(self.model, self.y0, self.t).y, float)
        self.scale = float(np.max(np.abs(self.y_ref)))
        self.omega_max = trust.fastest_omega(self.model)  # NaN: no stability cap, no aliasing check
        self.rate = {}      # method name -> the smallest wall s per RHS call of its runs
        self.compile = {}   # (method name, setting) and method name -> largest compile s (heyoka's JIT, numba)
        self.implementation = {}  # method name -> "compiled" where its compiled loop ran (see run)
        self.runs = {}      # (method name, setting) -> the first run's result (see measured)
        self._compiled_model = compiled_own_model(self.model)

    def side_by_side(self, method) -> bool:
        """Whether runs of ``method`` may go side by side in threads
        (:func:`_first_miss`): a tableau method on one of rk4h's own models
        with a compiled loop, so no code of the user's runs in a thread."""
        return self._compiled_model and method.kind in (Kind.TABLEAU, Kind.PARTITIONED)

    def run(self, method, setting):
        """``(error_rel, rhs calls, wall s, status)`` of one run.

        A reference with a compiled loop (DOP853:
        :func:`rk4h.references.solvers.integrate_compiled`, scipy's step for
        step to round-off; see the module docstring for where runs part) runs
        it, for its calibration, confirmation and timing alike;
        :attr:`implementation` records that it did."""
        return self.commit(method, setting, self.execute(method, setting))

    def execute(self, method, setting):
        """The :class:`~rk4h.references.solvers.SolverRun` of one run, recorded
        nowhere (:meth:`commit` records it); it changes nothing of ``self``,
        so sampled runs may call it from threads side by side."""
        from rk4h.references.solvers import COMPILED_RUNNERS, integrate, integrate_compiled

        runner = integrate_compiled if method.runner_key in COMPILED_RUNNERS else integrate
        with np.errstate(all="ignore"):
            return runner(method, self.model, self.y0, self.t, setting)

    def commit(self, method, setting, run, alone: bool = True):
        """Record ``run`` (:meth:`execute`'s at ``setting``) as :meth:`run` does
        and return its ``(error_rel, rhs calls, wall s, status)``. A run that
        went beside others (``alone`` False) gives no wall time per RHS call
        (:attr:`rate`): the others shared the machine with it."""
        if (run.extra or {}).get("implementation") == "compiled":
            self.implementation[method.name] = "compiled"
        err = metrics.error_max(run.y, self.y_ref) / self.scale
        rhs = trust.rhs_calls({"nfev": run.nfev, "n_steps": run.n_steps, "taylor_order": run.taylor_order or 0})
        status = getattr(run.status, "value", str(run.status))
        if rhs > 0 and status == "ok" and alone:
            self.rate[method.name] = min(self.rate.get(method.name, math.inf), run.wall_s / rhs)
        for key in ((method.name, float(setting)), method.name):
            self.compile[key] = max(self.compile.get(key, 0.0), float(run.compile_s or 0.0))
        out = (err if status == "ok" else math.nan), rhs, run.wall_s, status
        self.runs.setdefault((method.name, float(setting)), out)
        return out

    def measured(self, method, setting):
        """:meth:`run`'s result at ``setting``, from the run already made there
        (a calibration run reused as a confirmation) or from a new run; the
        runs are deterministic, so the error and calls are the same."""
        hit = self.runs.get((method.name, float(setting)))
        return hit if hit is not None else self.run(method, setting)

    def known(self, method, setting) -> bool:
        """Whether :meth:`measured` at ``setting`` reuses a run already made."""
        return (method.name, float(setting)) in self.runs

    def h_stab(self, method) -> float:
        return trust.stable_step(method, self.omega_max)

    def on_grid(self, h) -> float:
        """The largest step <= ``h`` that divides the output spacing."""
        dt = self.scene.output_dt
        return dt / math.ceil(dt / h * (1 - 1e-12)) if h < dt else dt * max(1, math.floor(h / dt))


def _fixed_candidate(p: _Problem, method, target):
    order = method.order
    h = p.on_grid(min(max(p.scene.h) if p.scene.h else p.scene.output_dt,
                      trust.STABILITY_MARGIN * p.h_stab(method)))
    pts, first = [], None  # (h, err) of every run, NaN when it failed; index of the first below PREASYMPTOTIC_REL
    for k in range(CALIBRATION_HALVINGS + FIT_HALVINGS + 1):
        err, rhs, wall, status = p.run(method, h)
        pts.append((h, err if status == "ok" else math.nan))
        if first is None and status == "ok" and err < metrics.PREASYMPTOTIC_REL:
            first = len(pts) - 1
        if first is None:
            if k >= CALIBRATION_HALVINGS:
                break
        else:
            tail = pts[first:]
            if (asymptotic_fit(tail, order)["asymptotic"] or pts[-1][1] <= metrics.ROUNDOFF_REL
                    or bracket_step(tail, target) is not None or len(tail) > FIT_HALVINGS):
                break
        h_next = p.on_grid(h / 2)
        if not h_next < h:
            break
        h = h_next
    tail = pts[first:] if first is not None else []
    fit = asymptotic_fit(tail, order)
    base = {"method": method.name, "observed_order": fit["observed_order"], "calibration": pts}

    def at_step(h_t, pred_e, source):
        n = math.ceil(p.scene.t_end / h_t * (1 - 1e-12))
        return {**base, "setting": h_t, "predicted_error": pred_e,
                "predicted_rhs": float(trust.fixed_rhs(method, n)), "source": source}

    if fit["asymptotic"]:
        C, source = fit["C"], "error constant"
    else:
        br = bracket_step(tail, target)
        if br is not None:  # measured: one step misses the target, half of it meets it
            h_b, e_b, q = br
            h_t = p.on_grid(h_b)
            base["observed_order"] = q
            return at_step(h_t, e_b * (h_t / h_b) ** q if math.isfinite(q) else e_b, "measured bracket")
        meets = [(a, b) for a, b in tail if math.isfinite(b) and b <= target]
        usable = [(a, b) for a, b in tail if trust.in_fit_range(b)]
        if meets and not usable:  # at the round-off floor already: the largest step measured to meet it
            return at_step(*max(meets), "calibration run")
        C = max((b / a ** order for a, b in usable), default=math.nan)  # conservative: the largest err / h^p
        source = "pre-asymptotic"
    h_t, src, n = trust.step_for(target, C, order, p.scene.t_end, p.h_stab(method))
    if src == "error constant":
        src = source
    if not math.isfinite(h_t):
        return {**base, "setting": math.nan, "predicted_error": math.nan, "predicted_rhs": math.inf, "source": src}
    h_t = p.on_grid(h_t)
    return at_step(h_t, C * h_t ** order, src)


def _adaptive_candidate(p: _Problem, method, target):
    tols = method.advisor_rtols or _RTOL_PAIR
    pts = [(tol, *getattr(p, "measured", p.run)(method, tol)) for tol in tols]
    good = [(tol, e, rhs) for tol, e, rhs, _, st in pts if st == "ok" and e > 0 and math.isfinite(e)]
    if len(good) < 2:
        return {"method": method.name, "setting": math.nan, "predicted_error": math.nan,
                "predicted_rhs": math.inf, "source": "calibration failed", "observed_order": math.nan,
                "calibration": pts}
    (t1, e1, c1), (t2, e2, c2) = good[0], good[-1]
    slope = math.log(e2 / e1) / math.log(t2 / t1) if e2 != e1 else 1.0
    slope = slope if slope > 0.1 else 1.0
    tol = t1 * (target / e1) ** (1 / slope)
    tol = 10.0 ** math.floor(math.log10(max(min(tol, 1e-2), _RTOL_MIN)))
    pred_e = e1 * (tol / t1) ** slope
    cs = math.log(c2 / c1) / math.log(t2 / t1) if c1 > 0 and c2 > 0 and c2 != c1 else 0.0
    pred_c = c1 * (tol / t1) ** cs if c1 > 0 else math.inf
    return {"method": method.name, "setting": tol, "predicted_error": pred_e, "predicted_rhs": pred_c,
            "source": "log-log line through 2 rtol", "observed_order": math.nan,
            "calibration": [(t, e) for t, e, _ in good]}


def _grid_up(p, x: float) -> float:
    """The smallest step >= ``x`` (up to 1e-12) on the output grid (a divisor
    of the output spacing, or a multiple of it above the spacing)."""
    dt = p.scene.output_dt
    if x <= dt:
        return dt / max(1, math.floor(dt / x * (1 + 1e-12)))
    return dt * math.ceil(x / dt * (1 - 1e-12))


def _next_below(p, h: float) -> float:
    """The largest step on the output grid strictly below the grid step ``h``."""
    dt = p.scene.output_dt
    if h > dt * (1 + 1e-12):
        return dt * (round(h / dt) - 1)
    return dt / (round(dt / h) + 1)


def sample_steps(p, h: float, n: int = SAMPLE_STEPS) -> list:
    """``n`` distinct steps in ``[h/2, h]`` on ``p``'s output grid (dividing the
    output spacing, as every step the advisor runs), largest first: ``h`` and
    ``h 2^(-i/(n-1))`` rounded onto the grid, the last one ``h/2`` rounded up.
    Where the grid has fewer than ``n`` steps there, all of them."""
    h = p.on_grid(h)
    out = []
    for i in range(n):
        s = p.on_grid(h * 2.0 ** (-i / (n - 1))) if i < n - 1 else _grid_up(p, h / 2)
        if s < h / 2 * (1 - 1e-12):
            s = _grid_up(p, h / 2)
        if not any(math.isclose(s, o, rel_tol=1e-12) for o in out):
            out.append(s)
    if len(out) < n:  # a coarse grid: every grid step in [h/2, h]
        out, s = [], h
        while s >= h / 2 * (1 - 1e-12) and len(out) < 4 * n:
            out.append(s)
            s = _next_below(p, s)
    return sorted(out, reverse=True)


def _rise(points):
    """The strongest sign that the error is not monotone in the step: among
    ``points = [(h, err), ...]`` with errors where a constant is fitted
    (:func:`rk4h.validation.trust.in_fit_range`: above round-off, below the
    pre-asymptotic level), the pair where a smaller step has the larger
    error, by the largest ratio: ``(h_large, e_large, h_small, e_small)``, or
    None."""
    pts = [(float(a), float(b)) for a, b in points if trust.in_fit_range(float(b))]
    best, ratio = None, 1.0
    for h1, e1 in pts:
        for h2, e2 in pts:
            if h2 < h1 and e2 > e1 * ratio:
                best, ratio = (h1, e1, h2, e2), e2 / e1
    return best


def _confirm_fixed(p, method, cand, target) -> dict:
    """Run the fixed-step ``cand`` until a step is confirmed to meet ``target``.

    Where the calibration showed the method's order (source ``"error
    constant"``) and its errors fall with the step, one run at the predicted
    step confirms it. Otherwise (a bracket or a pre-asymptotic constant, an
    error that rose when the step was halved, or a confirmation run that
    missed) the error is not known to be monotone in ``h``, and the step is
    confirmed only when all of :func:`sample_steps` ``(h)``, at least
    :data:`SAMPLE_STEPS` steps in ``[h/2, h]``, meet the target. A run that
    misses shrinks the step below it by the error ratio (at least 10 %) and
    starts a new round, at most :data:`CONFIRM_ROUNDS` rounds.

    Returns ``{"status": "ok" | "not-met", "setting", "error" (the largest of
    the runs that confirm it), "rhs", "wall", "sample" (the sampled steps, []
    for one run), "evidence" (every confirmation run, ``[h, err]``), "why"
    (why it was sampled, "" when not)}``.
    """
    cache = {}
    run = _cached(p, method, cache)

    rise = _rise(cand["calibration"])
    why = ""
    if cand["source"] != "error constant":
        why = f"no order-{method.order} range seen in the calibration ({cand['source']})"
    elif rise is not None:
        why = (f"the calibration error rose from {rise[1]:.2g} at h = {rise[0]:.3g} s to {rise[3]:.2g} at "
               f"h = {rise[2]:.3g} s")
    h = cand["setting"]
    for _ in range(CONFIRM_ROUNDS):
        steps = sample_steps(p, h) if why else [h]
        miss = _first_miss(p, method, steps, target, cache)
        if miss is None:
            err, rhs, wall, _ = run(h)
            return {"status": "ok", "setting": h, "error": max(run(s)[0] for s in steps), "rhs": rhs, "wall": wall,
                    "sample": steps if why else [], "evidence": sorted(([k, v[0]] for k, v in cache.items()),
                                                                   reverse=True), "why": why}
        s, err, status = miss
        if not why:
            why = f"the run at the predicted step {s:.3g} s missed the target (error {err:.2g})"
        ratio = target / err if status == "ok" and err > 0 else 1 / 16
        h_new = p.on_grid(s * min(0.9, 0.9 * ratio ** (1 / method.order)))
        h = h_new if h_new < s else _next_below(p, s)
    err, rhs, wall, _ = run(s)
    return {"status": "not-met", "setting": s, "error": err, "rhs": rhs, "wall": wall, "sample": [],
            "evidence": sorted(([k, v[0]] for k, v in cache.items()), reverse=True), "why": why}


def _cached(p, method, cache):
    """``run(h)``: ``method``'s result at step ``h`` from ``cache`` (step ->
    ``(error, rhs, wall, status)``), else from ``p.measured`` (``p.run`` for a
    problem without it), entered in ``cache``."""
    measured = getattr(p, "measured", None) or p.run

    def run(h):
        if h not in cache:
            cache[h] = measured(method, h)
        return cache[h]

    return run


def _first_miss(p, method, steps, target, cache):
    """Run ``steps`` in their order until one misses ``target``: ``(step,
    error, status)`` of the first that does, or None. Each result enters
    ``cache`` (step -> ``(error, rhs, wall, status)``).

    The first step runs alone: its wall time is the candidate's first timing
    (:func:`_timed`). Where ``p`` allows it (:meth:`_Problem.side_by_side`,
    more than one of :attr:`_Problem.threads`) the rest run side by side in
    threads, and their results are recorded in the order of ``steps`` and
    only up to the first miss: every number of the advice is that of the
    runs one after the other (their wall times, measured beside each other,
    enter no figure of it). A run started beside one that missed is waited
    for and thrown away, so nothing runs beside the next round's first step."""
    run = _cached(p, method, cache)

    def outcome(s):
        err, _, _, status = run(s)
        return None if status == "ok" and err <= target else (s, err, status)

    miss = outcome(steps[0])
    todo = [s for s in steps[1:] if s not in cache and not p.known(method, s)] \
        if miss is None and hasattr(p, "side_by_side") and p.side_by_side(method) else []
    threads = min(getattr(p, "threads", 1), len(todo))
    if threads < 2:
        for s in steps[1:]:
            if miss is not None:
                break
            miss = outcome(s)
        return miss
    from concurrent.futures import ThreadPoolExecutor

    pool = ThreadPoolExecutor(threads, thread_name_prefix="rk4h-advise")
    try:
        running = {s: pool.submit(p.execute, method, s) for s in todo}
        for s in steps[1:]:
            if s in running and s not in cache:
                cache[s] = p.commit(method, s, running[s].result(), alone=False)
            miss = outcome(s)
            if miss is not None:
                return miss
        return None
    finally:
        pool.shutdown(wait=True, cancel_futures=True)


def _confirm_adaptive(p, method, cand, target) -> dict:
    """Run the adaptive ``cand`` at its predicted rtol, then at rtol / 10 after
    each miss (at most :data:`CONFIRM_TRIES` runs); the result as
    :func:`_confirm_fixed`'s."""
    setting, evidence = cand["setting"], []
    for _ in range(CONFIRM_TRIES):
        err, rhs, wall, status = getattr(p, "measured", p.run)(method, setting)
        evidence.append([setting, err])
        if status == "ok" and err <= target:
            return {"status": "ok", "setting": setting, "error": err, "rhs": rhs, "wall": wall, "sample": [],
                    "evidence": evidence, "why": ""}
        if setting / 10 < _RTOL_MIN:
            break
        setting = setting / 10
    return {"status": "not-met", "setting": setting, "error": err, "rhs": rhs, "wall": wall, "sample": [],
            "evidence": evidence, "why": ""}


def _timed(p, method, setting, first_wall):
    """``(median, min, max, runs)`` wall seconds at ``setting``: the confirming
    run and repeats, :data:`TIMING_REPEATS` in all (one run when it took more
    than :data:`rk4h.validation.execute.REPEAT_BELOW_S`, as in the report)."""
    from rk4h.validation.execute import REPEAT_BELOW_S

    walls = [float(first_wall)]
    while len(walls) < TIMING_REPEATS and max(walls) <= REPEAT_BELOW_S:
        walls.append(float(p.run(method, setting)[2]))
    return float(np.median(walls)), min(walls), max(walls), len(walls)


def _model_advice(p: _Problem, target):
    from rk4h.references.exact import modal_solution

    m = p.model
    if getattr(m, "first_order", False):  # any ODE: its exact solution if it came with one
        if m.exact_solution(p.t[:2]) is not None:
            return "closed form", ("the ODE came with its exact solution: it gives the answer without "
                                   "integrating; integrate only to test an integrator")
        return m.name, "a first-order ODE without a closed form; integrate"
    if m.linear:
        return "closed form", ("the model is linear: its exact modal solution (rk4h.references.exact.modal_solution) "
                               "gives the answer without integrating; integrate only to test an integrator")
    try:
        y_lin = np.asarray(modal_solution(m, p.y0)(p.t), float)
    except Exception as e:  # noqa: BLE001 - no linearization for this model
        return m.name, f"nonlinear and no linearized closed form ({type(e).__name__}); integrate"
    n = m.n_dof
    err = float(np.max(np.abs(y_lin[:n] - p.y_ref[:n]))) / float(np.max(np.abs(p.y_ref[:n])))
    if err <= target:
        return "linearized closed form", (f"at this amplitude the linearized model's closed form is within "
                                          f"{err:.2g} of the nonlinear truth (target {target:g}): no integration "
                                          f"needed")
    return m.name, (f"the linearized model is {err:.2g} off the nonlinear truth at this amplitude (target "
                    f"{target:g}): keep the nonlinear model")


def _warnings(p: _Problem, methods, best, target):
    out = []
    s = p.scene
    if math.isfinite(p.omega_max) and s.output_dt * s.output_stride > math.pi / p.omega_max:
        out.append(f"output spacing {s.output_dt * s.output_stride:g} s is above pi/omega_max = "
                   f"{math.pi / p.omega_max:.3g} s: the fastest mode ({p.omega_max:.4g} rad/s) aliases in the "
                   f"output (the error is still measured on this grid)")
    for m in methods:
        if m.fixed_step and m.tableau is not None:
            hs = p.h_stab(m)
            bad = [h for h in s.h if h > hs]
            if bad:
                out.append(f"{m.name}: step(s) {', '.join(f'{h:g}' for h in bad)} s of the scene exceed its "
                           f"stability limit {hs:.3g} s (omega_max h = {hs * p.omega_max:.3g})")
    for c in best:
        if c["source"] == "round-off":
            out.append(f"{c['method']}: the target {target:g} is below its round-off level sqrt(n) eps at the "
                       f"step it would need: no fixed step reaches it in double precision")
    return out


def _listed(m, c, conf, timing, compile_s) -> dict:
    """A listed candidate: its prediction, the confirming runs, the cost."""
    return {**c, "setting_name": m.setting_name, "predicted_setting": c["setting"],
            "setting": float(conf["setting"]), "confirmed_error": float(conf["error"]),
            "cost_rhs": float(conf["rhs"]), "cost_s": timing[0], "cost_s_min": timing[1], "cost_s_max": timing[2],
            "timing_runs": timing[3], "compile_s": float(compile_s), "sample": [float(s) for s in conf["sample"]],
            "evidence": [[float(h), float(e)] for h, e in conf["evidence"]], "sampled_because": conf["why"],
            "non_monotone": ""}


def _not_listed(m, c, reason) -> dict:
    return {"method": m.name, "setting_name": m.setting_name, "predicted_setting": float(c["setting"]),
            "predicted_error": float(c["predicted_error"]), "predicted_rhs": float(c["predicted_rhs"]),
            "source": c["source"], "reason": reason}


def _skip_reason(p, m, c, listed):
    """Why ``c`` is not worth running, given the candidates ``listed`` so far
    (see :data:`SKIP_FACTOR`); "" to run it."""
    if not listed:
        return ""
    fewest = min(x["cost_rhs"] for x in listed)
    fastest = min(x["cost_s"] for x in listed)
    t_pred = getattr(p, "rate", {}).get(m.name, 0.0) * c["predicted_rhs"]  # the best rate of its calibration runs
    if c["predicted_rhs"] > SKIP_FACTOR * fewest and t_pred > SKIP_FACTOR * fastest and t_pred > SKIP_MIN_S:
        return (f"not run: predicted {c['predicted_rhs']:.3g} RHS calls and {t_pred:.3g} s (at its calibration "
                f"runs' rate), over {SKIP_FACTOR:g}x both the fewest calls ({fewest:.3g}) and the fastest time "
                f"({fastest:.3g} s) confirmed; a prediction, not a measurement")
    return ""


def _screen(m, c, target) -> str:
    """Why the calibrated candidate ``c`` is not run at all ("" to run it)."""
    if not (math.isfinite(c["setting"]) and math.isfinite(c["predicted_rhs"])):
        return f"no setting predicted ({c['source']})"
    if not c["predicted_error"] <= target:
        return (f"predicted to miss: error {c['predicted_error']:.2g} at {m.setting_name} = {c['setting']:.3g} "
                f"({c['source']})")
    return ""


def _late_candidate(p, m, target, listed, under) -> dict:
    """A reference with a Python callback per RHS call (:data:`PYTHON_CALLBACK`),
    calibrated after every other candidate was confirmed: its run at the
    looser calibration rtol first; where that one run already took more RHS
    calls than the fewest confirmed and over :data:`SKIP_FACTOR` times the
    fastest time confirmed (and over :data:`SKIP_MIN_S`), it can win neither
    choice at a tighter rtol, which takes more calls and time (a prediction),
    and it is not calibrated further: ``c["skip"]`` says so. Else
    :func:`_adaptive_candidate` (which reuses that run)."""
    tol = (m.advisor_rtols or _RTOL_PAIR)[0]
    err, rhs, wall, status = p.measured(m, tol)
    if listed and m.name != under and status == "ok":
        fewest = min(x["cost_rhs"] for x in listed)
        fastest = min(x["cost_s"] for x in listed)
        if rhs > fewest and wall > SKIP_FACTOR * fastest and wall > SKIP_MIN_S:
            return {"setting": tol, "predicted_error": err, "predicted_rhs": rhs, "source": "one calibration run",
                    "skip": (f"not run past its calibration run at {m.setting_name} = {tol:g}: that run already "
                             f"took {rhs:.3g} RHS calls and {wall:.3g} s ({wall / rhs * 1e6:.3g} us per call), more "
                             f"than the fewest calls confirmed ({fewest:.3g}) and over {SKIP_FACTOR:g}x the "
                             f"fastest time confirmed ({fastest:.3g} s); a tighter {m.setting_name} takes more "
                             f"(a prediction, not a measurement)")}
    c = _adaptive_candidate(p, m, target)
    return {**c, "calibration": [[float(x[0]), float(x[1])] for x in c["calibration"]]}


def advise(scene, target: float, threads: int | None = None) -> Advice:
    """Advice for ``scene`` (a :class:`rk4h.validation.scenes.Scene`) at the target
    relative error ``target``; see the module docstring. ``threads``: at most
    this many sampled runs side by side (:func:`_first_miss`; default the
    cores this process may use); the advice is the same for any number."""
    if threads is None:
        from rk4h.validation.engine import default_workers

        threads = default_workers()
    p = _Problem(scene, threads)
    adv = Advice(scene.name, float(target))
    methods = [scene.method(s) for s in scene.solvers]
    late = [m for m in methods if not m.fixed_step and m.runner_key in PYTHON_CALLBACK]
    cands = []
    for m in methods:
        if any(m is x for x in late):
            continue
        if m.fixed_step and m.kind in (Kind.TABLEAU, Kind.PARTITIONED):
            cands.append((m, _fixed_candidate(p, m, target)))
        elif not m.fixed_step:
            cands.append((m, _adaptive_candidate(p, m, target)))
    cands = [(m, {**c, "calibration": [[float(x[0]), float(x[1])] for x in c["calibration"]]})  # (setting, error)
             for m, c in cands]
    adv.model, adv.model_note = _model_advice(p, target)
    adv.warnings = _warnings(p, methods, [c for _, c in cands], target)
    todo = []
    for m, c in cands:
        why = _screen(m, c, target)
        if why:
            adv.not_listed.append(_not_listed(m, c, why))
        else:
            todo.append((m, c))
    from rk4h.validation.plan import under_test

    under = under_test(scene)  # the method under test is always confirmed
    listed = []

    def consider(m, c):
        """Confirm ``c`` (unless it cannot win) and list it, or say why not."""
        skip = "" if m.name == under else _skip_reason(p, m, c, listed)
        if skip:
            adv.not_listed.append(_not_listed(m, c, skip))
            return
        conf = (_confirm_fixed if m.fixed_step else _confirm_adaptive)(p, m, c, target)
        if conf["status"] != "ok":
            adv.not_listed.append(_not_listed(m, c, f"not confirmed: the last run, at {m.setting_name} = "
                                                    f"{conf['setting']:.3g}, gave error {conf['error']:.2g}"))
            return
        compile_s = getattr(p, "compile", {}).get(m.name if m.fixed_step else (m.name, float(conf["setting"])), 0.0)
        cand = _listed(m, c, conf, _timed(p, m, conf["setting"], conf["wall"]), compile_s)
        cand["implementation"] = getattr(p, "implementation", {}).get(m.name, "")
        if m.fixed_step:
            rise = _rise([(h, e) for h, e in cand["calibration"] + cand["evidence"]
                          if cand["setting"] / 8 <= h <= 8 * cand["setting"]])
            if rise is not None:
                cand["non_monotone"] = (f"h = {rise[0]:.3g} s gave {rise[1]:.2g}, the smaller h = {rise[2]:.3g} s "
                                        f"{rise[3]:.2g}")
            if cand["sample"]:
                lead = (f"the error is not monotone in h near the answer ({cand['non_monotone']})"
                        if rise is not None else f"the error is not known to be monotone in h ({conf['why']})")
                missed = [(h, e) for h, e in cand["evidence"] if not e <= target]
                above = (f"; the larger step {min(missed)[0]:.4g} s missed it ({min(missed)[1]:.2g})" if missed
                         else "")
                adv.warnings.append(
                    f"{m.name}: {lead}. Recommended h = {cand['setting']:.4g} s: all {len(cand['sample'])} steps "
                    f"sampled in [h/2, h] met the target when run (worst {cand['confirmed_error']:.2g}){above}; "
                    f"a step that was not run may still miss")
        listed.append(cand)
    for m, c in sorted(todo, key=lambda mc: (mc[1]["predicted_rhs"], mc[0].name)):
        consider(m, c)
    for m in late:  # a Python callback per RHS call: calibrated only as far as it can still win
        c = _late_candidate(p, m, target, listed, under)
        why = c.get("skip") or _screen(m, c, target)
        if why:
            adv.not_listed.append(_not_listed(m, c, why))
        else:
            consider(m, c)
    adv.candidates = listed
    if not listed:
        adv.status = "no method confirmed to reach the target"
        return adv
    best = min(listed, key=lambda x: (x["cost_rhs"], x["method"]))
    adv.method, adv.setting, adv.setting_name = best["method"], best["setting"], best["setting_name"]
    adv.predicted_error, adv.predicted_rhs = float(best["predicted_error"]), float(best["predicted_rhs"])
    adv.confirmed_error, adv.cost_rhs, adv.cost_s = best["confirmed_error"], best["cost_rhs"], best["cost_s"]
    adv.fewest_calls = best["method"]
    by_time = sorted(listed, key=lambda x: (x["cost_s"], x["method"]))
    fast = by_time[0]
    adv.fastest = {k: fast[k] for k in ("method", "setting", "setting_name", "confirmed_error", "cost_rhs", "cost_s",
                                        "cost_s_min", "cost_s_max", "compile_s", "implementation")}
    if len(by_time) > 1:
        nxt = by_time[1]
        adv.fastest["runner_up"] = nxt["method"]
        adv.fastest["verdict"] = trust.time_verdict(
            fast["method"], (fast["cost_s"], fast["cost_s_min"], fast["cost_s_max"]),
            nxt["method"], (nxt["cost_s"], nxt["cost_s_min"], nxt["cost_s_max"]))
    else:
        adv.fastest["runner_up"], adv.fastest["verdict"] = "", fast["method"]
    adv.fastest_one_run = min(listed, key=lambda x: (x["cost_s"] + x["compile_s"], x["method"]))["method"]
    return adv


def _text(adv: Advice) -> str:
    lines = [f"{adv.scene}: target relative error {adv.target:g}"]
    if adv.method:
        lines.append(f"  fewest RHS calls: {adv.method} with {adv.setting_name} = {adv.setting:.4g}: "
                     f"{adv.cost_rhs:.3g} RHS calls, {adv.cost_s * 1e3:.3g} ms; error predicted "
                     f"{adv.predicted_error:.2g}, confirmed {adv.confirmed_error:.2g}")
        f = adv.fastest
        if not f["runner_up"]:
            margin = "the only candidate"
        elif f["verdict"] == f["method"]:
            margin = f"over {trust.TIME_MARGIN:g}x faster than the runner-up {f['runner_up']}, repeats disjoint"
        else:
            margin = (f"a tie with {f['runner_up']}: not {trust.TIME_MARGIN:g}x apart with disjoint repeats")
        lines.append(f"  fastest here: {f['method']} with {f['setting_name']} = {f['setting']:.4g}: "
                     f"{f['cost_s'] * 1e3:.3g} ms ({margin}); error confirmed {f['confirmed_error']:.2g}, "
                     f"{f['cost_rhs']:.3g} RHS calls")
        if adv.fastest_one_run != f["method"]:
            lines.append(f"  fastest for one run, compile included: {adv.fastest_one_run}")
    else:
        lines.append(f"  {adv.status}")
    lines.append("  candidates, each run at the setting listed and meeting the target there:")
    lines.append(f"    {'method':<18} {'setting':>9} {'predicted':>9} {'confirmed':>9} {'RHS calls':>9} "
                 f"{'time ms':>8} {'compile ms':>10}  how")
    for c in sorted(adv.candidates, key=lambda c: (c["cost_rhs"], c["method"])):
        how = c["source"] + (f", observed order {c['observed_order']:.2f}" if math.isfinite(c["observed_order"])
                             else "")
        if c["predicted_setting"] != c["setting"]:
            how += f"; predicted error for {c['predicted_setting']:.3g}"
        if c["sample"]:
            how += f"; {len(c['sample'])} steps in [h/2, h] run"
        lines.append(f"    {c['method']:<18} {c['setting']:>9.3g} {c['predicted_error']:>9.2g} "
                     f"{c['confirmed_error']:>9.2g} {c['cost_rhs']:>9.3g} {c['cost_s'] * 1e3:>8.3g} "
                     f"{c['compile_s'] * 1e3:>10.3g}  {how}")
    lines.append(f"  time: {adv.timing}")
    for c in adv.candidates:
        if c.get("implementation") == "compiled":
            if c["method"].startswith("cvode"):  # CVODE with compiled callbacks (references/solvers/cvode_compiled.py)
                lines.append(f"  {c['method']}: run and timed as SUNDIALS CVODE with compiled callbacks "
                             f"(rk4h.references.solvers.integrate_compiled, equal to scikit-sundae's run); "
                             f"scikit-sundae, which calls a Python function per evaluation, was not run")
                continue
            lines.append(f"  {c['method']}: run and timed as its compiled loop "
                         f"(rk4h.references.solvers.integrate_compiled: scipy's method, its sums in another order; where "
                         f"steps are rejected near the tolerance a run can part from scipy's); scipy's "
                         f"solve_ivp, which steps in Python, was not run")
    if adv.not_listed:
        lines.append("  not listed:")
        for c in adv.not_listed:
            lines.append(f"    {c['method']:<18} {c['reason']}")
    lines.append(f"  model: {adv.model}: {adv.model_note}")
    for w in adv.warnings:
        lines.append(f"  warning: {w}")
    return "\n".join(lines)


_EXAMPLES = """examples:
  %(prog)s thesis-2dof-case1 --target 1e-6          which method and setting reach 1e-6 most cheaply
  %(prog)s planar4-case2 --target 1e-3 --json        the same as one JSON object
  %(prog)s my.toml --target 1e-8 --allow-code        a scene of yours that names code (read it first)
  %(prog)s thesis-2dof-case1 --periods 1e5 --energy-target 1e-6
                                                    the cheapest method keeping the energy within 1e-6
                                                    over 1e5 periods, confirmed by a full-horizon run"""


def main(argv=None, *, prog="advise.py") -> int:
    from rk4h import _heyoka
    from rk4h.validation import extras

    _heyoka.own_process()  # this process is rk4h's: heyoka may come without sympy
    lack = extras.message("advise", prog)
    if lack and not extras.asks_help(argv):
        print(lack, file=sys.stderr)
        return 2
    parser = argparse.ArgumentParser(prog=prog, description=" ".join(__doc__.split("\n\n")[0].split()),
                                     epilog=_EXAMPLES,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("scene", help="a scene file or a shipped scene's name")
    parser.add_argument("--target", help="target relative error, e.g. 1e-6 (required unless --energy-target)")
    parser.add_argument("--energy-target", metavar="E",
                        help="bound on max |E(t) - E0| / E_motion over the horizon (rk4h.validation.advise_energy)")
    horizon = parser.add_mutually_exclusive_group()
    horizon.add_argument("--periods", metavar="N", help="horizon in periods of the slowest mode (--energy-target)")
    horizon.add_argument("--horizon", metavar="T", help="horizon in s (--energy-target)")
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    parser.add_argument("--threads", metavar="N",
                        help="at most N sampled fixed-step runs side by side (default: the cores this process "
                             "may use; the advice is the same for any N)")
    parser.add_argument("--allow-code", action="store_true",
                        help="run the programs and import the Python modules a scene not shipped with the "
                             "project names; read it first (default: refused; also RK4H_ALLOW_CODE=1)")
    args = parser.parse_args(argv)
    args.prog = prog  # error lines start with the command as the user typed it
    from rk4h.validation.scenes import SceneError, load_scenes

    if args.energy_target is not None or args.periods is not None or args.horizon is not None:
        return _energy_main(args)
    if args.target is None:
        print(f"{args.prog}: --target: required (or --energy-target with --periods or --horizon)", file=sys.stderr)
        return 2
    try:
        target = float(args.target)
    except ValueError:
        print(f"{args.prog}: --target: must be a number, got {args.target!r}", file=sys.stderr)
        return 2
    if not (math.isfinite(target) and 0 < target < 1):
        print(f"{args.prog}: --target: must lie in (0, 1), got {args.target!r}", file=sys.stderr)
        return 2
    threads = _threads(args)
    if threads == 0:
        return 2
    try:
        scenes = load_scenes([args.scene], allow_code=True if args.allow_code else None)
    except SceneError as e:
        print(str(e).splitlines()[0], file=sys.stderr)
        return 2
    t0 = time.perf_counter()
    for scene in scenes[:1]:
        adv = advise(scene, target, threads)
        print(adv.to_json() if args.json else _text(adv) + f"\n  ({time.perf_counter() - t0:.1f} s)")
    return 0


def _threads(args):
    """``--threads`` as an int, None when not given, 0 after printing why it is refused."""
    if args.threads is None:
        return None
    try:
        threads = int(args.threads)
    except ValueError:
        threads = 0
    if not 1 <= threads <= 1024:
        print(f"{args.prog}: --threads: must be an integer from 1 to 1024, got {args.threads!r}", file=sys.stderr)
        return 0
    return threads


def _energy_main(args) -> int:
    """The horizon-and-energy path (:mod:`rk4h.validation.advise_energy`)."""
    from rk4h.validation.scenes import SceneError, load_scenes

    def number(flag, text, lo, hi, what):
        try:
            x = float(text)
        except (TypeError, ValueError):
            x = math.nan
        if not (math.isfinite(x) and lo < x < hi):
            print(f"{args.prog}: {flag}: must be {what}, got {text!r}", file=sys.stderr)
            return None
        return x

    if args.energy_target is None or (args.periods is None and args.horizon is None):
        print(f"{args.prog}: --energy-target: needs --periods N or --horizon T (and the other way round)",
              file=sys.stderr)
        return 2
    if args.target is not None:
        print(f"{args.prog}: --target: not with --energy-target (one question per call)", file=sys.stderr)
        return 2
    args.energy_target = number("--energy-target", args.energy_target, 0, 1, "a number in (0, 1)")
    if args.energy_target is None:
        return 2
    if args.periods is not None:
        args.periods = number("--periods", args.periods, 0, math.inf, "a positive number")
        if args.periods is None:
            return 2
    else:
        args.horizon = number("--horizon", args.horizon, 0, math.inf, "a positive number of seconds")
        if args.horizon is None:
            return 2
    if args.threads is not None:
        print(f"{args.prog}: --threads: only with --target (the energy advice runs no sample of steps)",
              file=sys.stderr)
        return 2
    try:
        scenes = load_scenes([args.scene], allow_code=True if args.allow_code else None)
    except SceneError as e:
        print(str(e).splitlines()[0], file=sys.stderr)
        return 2
    from rk4h.validation import advise_energy

    try:
        return advise_energy.run_cli(scenes[0], args, time.perf_counter())
    except ValueError as e:  # a model without an oscillating mode: no horizon in periods
        print(f"{args.prog}: {e}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    from rk4h.validation.process_exit import exit_process, run_main

    exit_process(run_main(main))
