"""The advisor: the cheapest method and setting that meets a target error on a
scene, whether a cheaper model would do, and what to watch out for -- without
running the report.

    python validation/advise.py SCENE --target REL [--json] [--allow-code]

``SCENE`` is a scene file or a shipped scene's name (``thesis-2dof-case1``);
``REL`` the target relative error (``error_max / max |y_ref|`` over the
scene's output grid and horizon, the report's ``error_rel``).

How (all plain data, one run per line below):

1. *Calibration.* Each fixed-step method of the scene (a tableau) runs at its
   scene's largest step, halved (on the output grid) until its error is below
   :data:`validation.metrics.PREASYMPTOTIC_REL` (at most
   :data:`CALIBRATION_HALVINGS` times), then halved further, at most
   :data:`FIT_HALVINGS` times, until three successive steps ``h, h/2, h/4``
   show the method's order: both observed orders ``log2(e(h)/e(h/2))``
   within :data:`ORDER_TOLERANCE` of ``p`` (:func:`asymptotic_fit`). ``C``
   of ``error ~ C h^p`` is then the largest ``err / h^p`` of those three
   (conservative) and gives the step for the target
   (:func:`validation.trust.step_for`: capped at 0.9 of the stability limit,
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
2. *Choice.* The candidate with the fewest predicted right-hand-side calls
   (heyoka: Taylor steps x order), a deterministic cost; wall time is
   reported, not used to choose.
3. *Confirmation.* One run at the predicted setting against the truth; if
   it misses the target, the step shrinks by the error ratio (fixed-step) or
   the rtol by 10 (adaptive), at most :data:`CONFIRM_TRIES` times.
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

from references.registry import Kind  # noqa: E402
from validation import metrics, trust  # noqa: E402
from validation.trust import ORDER_TOLERANCE, asymptotic_fit, bracket_step  # noqa: E402,F401 - re-exported

__all__ = ["Advice", "advise", "main", "asymptotic_fit", "bracket_step", "CALIBRATION_HALVINGS",
           "FIT_HALVINGS", "ORDER_TOLERANCE", "CONFIRM_TRIES"]

#: Halvings from the scene's largest step to the first error below
#: :data:`validation.metrics.PREASYMPTOTIC_REL`.
CALIBRATION_HALVINGS = 8
#: Further halvings, after that, to see the method's order or bracket the
#: target (each run costs twice the one before: at most 2^9 - 1 times the first
#: one's steps). planar4-case2 needs all 8 at a target of 1e-9 (3.1e-4 s ->
#: 1.2e-6 s; its error curve shows no fourth order anywhere above round-off).
FIT_HALVINGS = 8
CONFIRM_TRIES = 4
_RTOLS = {"heyoka": (1e-4, 1e-10)}
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
    candidates: list = field(default_factory=list)
    warnings: list = field(default_factory=list)

    def to_json(self) -> str:
        return json.dumps(asdict(self), allow_nan=True, default=float)


class _Problem:
    """The scene's model, initial state, output grid and truth, built once."""

    def __init__(self, scene):
        from validation.execute import problem

        from references.truth import reference_solution

        self.scene = scene
        self.model, self.y0 = problem(scene)
        self.t = scene.t_eval()
        self.y_ref = np.asarray(reference_solution(self.model, self.y0, self.t).y, float)
        self.scale = float(np.max(np.abs(self.y_ref)))
        self.omega_max = trust.fastest_omega(self.model)  # NaN: no stability cap, no aliasing check

    def run(self, method, setting):
        """``(error_rel, rhs calls, wall s, status)`` of one run."""
        from references.solvers import integrate

        with np.errstate(all="ignore"):
            run = integrate(method, self.model, self.y0, self.t, setting)
        err = metrics.error_max(run.y, self.y_ref) / self.scale
        rhs = trust.rhs_calls({"nfev": run.nfev, "n_steps": run.n_steps, "taylor_order": run.taylor_order or 0})
        status = getattr(run.status, "value", str(run.status))
        return (err if status == "ok" else math.nan), rhs, run.wall_s, status

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
    tols = _RTOLS.get(method.name, _RTOL_PAIR)
    pts = [(tol, *p.run(method, tol)) for tol in tols]
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


def _confirm(p: _Problem, method, cand, target):
    setting = cand["setting"]
    for _ in range(CONFIRM_TRIES):
        err, rhs, wall, status = p.run(method, setting)
        if status == "ok" and err <= target:
            return setting, err, rhs, wall, "ok"
        if method.fixed_step:
            ratio = (target / err) if status == "ok" and err > 0 else 1 / 16
            setting = p.on_grid(setting * min(0.9, 0.9 * ratio ** (1 / method.order)))
        else:
            setting = setting / 10
            if setting < _RTOL_MIN:
                break
    return setting, err, rhs, wall, "not-met"


def _model_advice(p: _Problem, target):
    from references.exact import modal_solution

    m = p.model
    if m.linear:
        return "closed form", ("the model is linear: its exact modal solution (references.exact.modal_solution) "
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


def advise(scene, target: float) -> Advice:
    """Advice for ``scene`` (a :class:`validation.scenes.Scene`) at the target
    relative error ``target``; see the module docstring."""
    p = _Problem(scene)
    adv = Advice(scene.name, float(target))
    methods = [scene.method(s) for s in scene.solvers]
    cands = []
    for m in methods:
        if m.fixed_step and m.kind in (Kind.TABLEAU, Kind.PARTITIONED):
            cands.append((m, _fixed_candidate(p, m, target)))
        elif not m.fixed_step:
            cands.append((m, _adaptive_candidate(p, m, target)))
    adv.candidates = [{**c, "calibration": [[float(x[0]), float(x[1])] for x in c["calibration"]]}  # (setting, error)
                      for _, c in cands]
    ok = [(m, c) for m, c in cands if math.isfinite(c["setting"]) and math.isfinite(c["predicted_rhs"])]
    adv.model, adv.model_note = _model_advice(p, target)
    adv.warnings = _warnings(p, methods, [c for _, c in cands], target)
    if not ok:
        adv.status = "no method predicted to reach the target"
        return adv
    m, c = min(ok, key=lambda mc: (mc[1]["predicted_rhs"], mc[0].name))
    setting, err, rhs, wall, status = _confirm(p, m, c, target)
    adv.method, adv.setting, adv.setting_name = m.name, float(setting), m.setting_name
    adv.predicted_error, adv.predicted_rhs = float(c["predicted_error"]), float(c["predicted_rhs"])
    adv.confirmed_error, adv.cost_rhs, adv.cost_s, adv.status = float(err), float(rhs), float(wall), status
    return adv


def _text(adv: Advice) -> str:
    lines = [f"{adv.scene}: target relative error {adv.target:g}"]
    if adv.method:
        lines.append(f"  use {adv.method} with {adv.setting_name} = {adv.setting:.4g}: predicted error "
                     f"{adv.predicted_error:.2g}, confirmed {adv.confirmed_error:.2g} ({adv.status}); "
                     f"{adv.cost_rhs:.3g} RHS calls, {adv.cost_s * 1e3:.3g} ms")
    else:
        lines.append(f"  {adv.status}")
    lines.append("  candidates (fewest predicted RHS calls wins):")
    for c in sorted(adv.candidates, key=lambda c: c["predicted_rhs"]):
        lines.append(f"    {c['method']:<18} setting {c['setting']:.3g}  predicted error {c['predicted_error']:.2g}"
                     f"  RHS calls {c['predicted_rhs']:.3g}  ({c['source']}"
                     + (f", observed order {c['observed_order']:.2f})" if math.isfinite(c["observed_order"]) else ")"))
    lines.append(f"  model: {adv.model}: {adv.model_note}")
    for w in adv.warnings:
        lines.append(f"  warning: {w}")
    return "\n".join(lines)


_EXAMPLES = """examples:
  %(prog)s thesis-2dof-case1 --target 1e-6          which method and setting reach 1e-6 most cheaply
  %(prog)s planar4-case2 --target 1e-3 --json        the same as one JSON object
  %(prog)s my.toml --target 1e-8 --allow-code        a scene of yours that names code (read it first)"""


def main(argv=None, *, prog="advise.py") -> int:
    from validation import extras

    lack = extras.message("advise", prog)
    if lack:
        print(lack, file=sys.stderr)
        return 2
    parser = argparse.ArgumentParser(prog=prog, description=" ".join(__doc__.split("\n\n")[0].split()),
                                     epilog=_EXAMPLES,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("scene", help="a scene file or a shipped scene's name")
    parser.add_argument("--target", required=True, help="target relative error, e.g. 1e-6")
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    parser.add_argument("--allow-code", action="store_true",
                        help="run the programs and import the Python modules a scene not shipped with the "
                             "project names; read it first (default: refused; also RK4H_ALLOW_CODE=1)")
    args = parser.parse_args(argv)
    from validation.scenes import SceneError, load_scenes

    try:
        target = float(args.target)
    except ValueError:
        print(f"advise: --target: must be a number, got {args.target!r}", file=sys.stderr)
        return 2
    if not (math.isfinite(target) and 0 < target < 1):
        print(f"advise: --target: must lie in (0, 1), got {args.target!r}", file=sys.stderr)
        return 2
    try:
        scenes = load_scenes([args.scene], allow_code=True if args.allow_code else None)
    except SceneError as e:
        print(str(e).splitlines()[0], file=sys.stderr)
        return 2
    t0 = time.perf_counter()
    for scene in scenes[:1]:
        adv = advise(scene, target)
        print(adv.to_json() if args.json else _text(adv) + f"\n  ({time.perf_counter() - t0:.1f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
