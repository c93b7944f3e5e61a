"""Where a damped mode's phase turns to round-off: RK4's measured phase error
against its lag, step by step (the bar ``energy_time.PHASE_RESOLVED_AMPLITUDE``).

    python benchmarks/phase_floor.py [SCENE:H ...]     # default: lattice100:0.1 co2:0.1 thesis-2dof-case2:0.1

For each shipped linear scene and RK4 step ``H`` (s): the scene's RK4 run
(``rk4h.solve`` on the scene's output grid, as the report's run), the
unwrapped angle between each computed and exact modal coordinate (without
the bar: ``energy_time.phase_errors``' own computation), and the exact lag
of RK4 after ``n`` steps, ``-n (theta - arg R(i theta))``. Printed per scene:
the modes whose measured angle leaves the lag by more than 1e-6 rad, the
smallest amplitude (the computed mode's ``|omega eta - i eta'|`` over the
motion's at t = 0, ``sqrt`` of twice its modal energy) at which a mode is still
on the lag, the largest at which one has left it, and the bar. The bar is safe
where modes leave the lag only at amplitudes below it.
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))  # the repository, installed or not

DEFAULT = ("lattice100:0.1", "co2:0.1", "thesis-2dof-case2:0.1")
TOL = 1e-6  # rad: "on the lag"


def measure(scene_name: str, h: float) -> dict:
    """Per-sample measured angle, lag and relative amplitude of every mode of the
    scene's RK4 run at step ``h`` that holds ``PHASE_MIN_SHARE`` at t = 0."""
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
    ms = modal_solution(model, y0)
    w = np.where(ms.zero, 1.0, ms.omega)
    e0 = 0.5 * (ms.deta0 ** 2 + (ms.omega * ms.eta0) ** 2)
    keep = (~ms.zero) & (e0 >= et.PHASE_MIN_SHARE * e0.sum())
    n = model.n_dof
    M = np.asarray(model.mass, float)[:, None]
    z = (w[:, None] * (ms.phi.T @ (M * y[:n])) - 1j * (ms.phi.T @ (M * y[n:])))[keep]
    eta_x, deta_x = ms.modal(t)
    zx = (w[:, None] * eta_x - 1j * deta_x)[keep]
    angle = np.unwrap(np.angle(z * np.conj(zx)), axis=1)
    steps = np.round((t - t[0]) / h)
    lag = -steps[None, :] * phase_lag(RK4, ms.omega[keep][:, None] * h)
    amplitude = np.abs(z) / np.sqrt(2.0 * e0.sum())
    return {"angle": angle, "lag": lag, "amplitude": amplitude}


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
    bar = et.PHASE_RESOLVED_AMPLITUDE
    print(f"bar (energy_time.PHASE_RESOLVED_AMPLITUDE): {bar:.2e}; on the lag: within {TOL:g} rad")
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
        low_on = float(m["amplitude"][on].min())
        high_off = float(m["amplitude"][~on].max()) if (~on).any() else float("nan")
        print(f"{name} h = {h:g} s: {int(left.sum())} of {left.size} modes leave the lag; smallest amplitude still "
              f"on it {low_on:.1e}; largest amplitude off it {high_off:.1e}; "
              f"{'below the bar' if not high_off >= bar else 'ABOVE the bar'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
