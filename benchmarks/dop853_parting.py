"""Where two DOP853 runs part: scipy's ``solve_ivp`` against itself with rtol
changed by a few ulp, and against the compiled loop (issue 29).

    python benchmarks/dop853_parting.py [--ratios 1e2,1e6] [--rtols 1e-5,1e-6] [--ulps 5]

On the stability study's stiff chain (8 unit masses, the middle spring
``ratio`` N/m, one period of the slowest mode, its lowest mode excited;
``rk4h.validation.stability.stiffness.stiff_chain``), for each rtol: the
error the cost search reads (``error_rel`` at ``t_end`` against the modal
solution) and the RHS calls of scipy's DOP853 at ``rtol * (1 + k * 2.2e-16)``
for ``k = 0 .. ulps``, and the same for the compiled loop
(``rk4h.references.solvers.integrate_compiled``): the smallest, median and
largest error of each (with ``--ulps`` up to 5, every run: error and RHS
calls). Where DOP853's step is held by stability, steps are rejected near
the tolerance and one ulp sends an accept/reject decision the other way:
the error of scipy's own run spreads as widely as the compiled loop's
differs from it. No timing; the
numbers are deterministic on one machine and library build.
"""
from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))


def main():
    from rk4h.references import solvers as S
    from rk4h.references.exact import modal_solution
    from rk4h.validation.stability import stiffness as ST

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--ratios", default="1e2,1e6")
    ap.add_argument("--rtols", default="1e-5,1e-6")
    ap.add_argument("--ulps", type=int, default=5)
    args = ap.parse_args()
    for ratio in (float(x) for x in args.ratios.split(",")):
        model, y0 = ST.stiff_chain(ratio)
        omega = model.modes()[0]
        t_end = 2 * math.pi / float(omega[omega > 0][0])
        ref = modal_solution(model, y0)(np.array([t_end]))[:, :1]
        scale = float(np.max(np.abs(y0[: model.n_dof])))
        t = np.array([0.0, t_end])

        def err(run):
            return ST.error_rel(model, run.y[:, -1:], ref, scale)

        print(f"stiff chain, ratio {ratio:g} (omega_max/omega_min {omega[-1] / omega[omega > 0][0]:.4g}):")
        for rtol in (float(x) for x in args.rtols.split(",")):
            print(f"  rtol {rtol:g}:")
            for name, integrate in (("scipy", S.integrate), ("compiled loop", S.integrate_compiled)):
                runs = [integrate("dop853", model, y0, t, rtol * (1 + k * 2.2e-16)) for k in range(args.ulps + 1)]
                e = np.array([err(r) for r in runs])
                listed = (": " + ", ".join(f"{x:.3g} ({r.nfev})" for x, r in zip(e, runs))) if args.ulps <= 5 else ""
                print(f"    {name:<13} at +0..{args.ulps} ulp: min {e.min():.3g}, median {np.median(e):.3g}, "
                      f"max {e.max():.3g} ({e.max() / e.min():.3g}x); at +0 {e[0]:.3g}{listed}")

if __name__ == "__main__":
    main()
