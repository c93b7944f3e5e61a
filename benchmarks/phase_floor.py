"""Where a damped mode's phase turns to round-off: RK4's measured phase error
against its exact lag, step by step, beside the rounding estimate that decides
where the report stops reading it (``energy_time.PHASE_RESOLUTION``).

    python benchmarks/phase_floor.py [SCENE:H ...]
    # default: lattice100:0.1 co2:0.1 thesis-2dof-case2:0.1 three-blocks:0.1
    #          oscillator-aniso-2:0.1 oscillator-aniso-sqrt2:0.1 thesis-2dof-case3:0.1

For each shipped linear scene and RK4 step ``H`` (s): the scene's RK4 run
(``rk4h.solve`` on the scene's output grid, as the report's run), each
energetic mode's unwrapped angle against the exact one and its rounding estimate
(``energy_time.phase_angles``), and RK4's exact lag after ``n`` steps,
``-n (theta - arg R(i theta))``. Printed per scene: how many modes leave the
lag by more than 1e-6 rad, the smallest rounding estimate at which a mode has left
it (the bar is safe when that is above ``PHASE_RESOLUTION``: every sample the
report reads is on the lag), the largest estimate at which a mode is still on it,
and how many modes the report counts as unresolved.
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))  # the repository, installed or not

DEFAULT = ("lattice100:0.1", "co2:0.1", "thesis-2dof-case2:0.1", "three-blocks:0.1", "oscillator-aniso-2:0.1",
           "oscillator-aniso-sqrt2:0.1", "thesis-2dof-case3:0.1")
TOL = 1e-6  # rad: "on the lag"


def measure(scene_name: str, h: float) -> dict:
    """The scene's RK4 run at step ``h``: per energetic mode and sample, the measured
    angle, RK4's exact lag and the angle's rounding estimate (rad)."""
    import rk4h
    from rk4h.methods import RK4
    from rk4h.references.exact import modal_solution
    from rk4h.validation import energy_time as et
    from rk4h.validation import execute, plan
    from rk4h.validation.metrics import phase_lag
    from rk4h.validation.scenes import load_scenes

    scene = load_scenes([scene_name])[0]
    model, y0 = execute.problem(scene)
    specs = [s for s in plan.plan(scene) if s.purpose == "run" and s.solver == "rk4" and abs(s.setting - h) < 1e-12]
    if not specs or not model.linear:
        raise ValueError(f"{scene_name}:{h:g}: not a linear scene with an RK4 run at h = {h:g} s")
    t = execute.grid(scene, model, specs[0])
    y = rk4h.solve(model.rhs, (t[0], t[-1]), y0, h=h, t_eval=t, method="rk4").y
    angle, rounding = et.phase_angles(model, y0, t, y)
    ms = modal_solution(model, y0)
    keep = et.energetic_modes(ms)
    steps = np.round((t - t[0]) / h)
    lag = -steps[None, :] * phase_lag(RK4, ms.omega[keep][:, None] * h)
    unresolved = et.summary(model, y0, t, y)["phase_modes_unresolved"]
    return {"angle": angle, "lag": lag, "rounding": rounding, "unresolved": unresolved}


def main(argv=None) -> int:
    args = sys.argv[1:] if argv is None else argv
    from rk4h.validation import energy_time as et

    cases = []
    for a in args or DEFAULT:
        name, _, h = a.partition(":")
        try:
            cases.append((name, float(h)))
        except ValueError:
            print(f"phase_floor.py: SCENE:H: H must be a step in seconds, got {a!r}", file=sys.stderr)
            return 2
    bar = et.PHASE_RESOLUTION
    print(f"bar (energy_time.PHASE_RESOLUTION): {bar:g} rad; on the lag: within {TOL:g} rad")
    for name, h in cases:
        try:
            m = measure(name, h)
        except (ValueError, KeyError) as e:
            print(f"phase_floor.py: {e}", file=sys.stderr)
            return 2
        off = np.abs(m["angle"] - m["lag"]) > TOL
        left = off.any(axis=1)
        # a mode is on the lag up to its first sample off it
        first = np.where(left, np.argmax(off, axis=1), off.shape[1])
        on = np.arange(off.shape[1])[None, :] < first[:, None]
        low_off = float(m["rounding"][~on].min()) if (~on).any() else float("nan")
        high_on = float(m["rounding"][on].max())
        verdict = "no mode leaves it" if not left.any() else ("safe" if low_off > bar else "NOT SAFE")
        print(f"{name} h = {h:g} s: {int(left.sum())} of {left.size} modes leave the lag; smallest rounding estimate "
              f"off it {low_off:.1e} rad, largest on it {high_on:.1e} rad; {verdict}; unresolved in the report: "
              f"{m['unresolved']}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
