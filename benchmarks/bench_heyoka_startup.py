"""heyoka's one-time start-up in a process against the compile of a model.

In each of ``--rounds`` fresh Python processes (heyoka imported first,
untimed): the wall time of a first ``taylor_adaptive`` compile of the
2-DOF case-1 model (``rk4h.references.solvers.taylor.get_integrator``'s system),
then of the same system compiled again after it; and, in a second set of
processes, of that compile after the untimed start-up
``taylor.start_up`` (what the harness times as ``compile_s``). Prints the
medians in milliseconds. Run::

    python benchmarks/bench_heyoka_startup.py [--rounds 5]
"""
from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent

_CHILD = """
import time, heyoka as hy, numpy as np
from rk4h.references.solvers import taylor
from rk4h.validation.scenes import load_scene, SCENE_DIR
model = load_scene(SCENE_DIR / "thesis_2dof_case1.toml").build_model()
_, sys_ = taylor.scaled_system(model)
pars = taylor._pars(model, (1.0, 1.0))
def compile_once():
    t = time.perf_counter()
    hy.taylor_adaptive(sys_, np.zeros(2 * model.n_dof), tol=1e-9, pars=pars)
    return time.perf_counter() - t
if {started}:
    taylor.start_up()
print(compile_once(), compile_once())
"""


def _child(started: bool) -> tuple[float, float]:
    r = subprocess.run([sys.executable, "-c", _CHILD.format(started=started)], cwd=REPO, capture_output=True,
                       text=True, check=True)
    a, b = r.stdout.split()
    return float(a), float(b)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--rounds", type=int, default=5)
    args = p.parse_args(argv)
    cold = [_child(False) for _ in range(args.rounds)]
    warm = [_child(True) for _ in range(args.rounds)]
    ms = lambda xs: 1e3 * statistics.median(xs)  # noqa: E731
    print(f"medians over {args.rounds} fresh processes (ms):")
    print(f"  first compile in a process:               {ms([a for a, _ in cold]):7.1f}")
    print(f"  the same system compiled again after it:  {ms([b for _, b in cold]):7.1f}")
    print(f"  first compile after taylor.start_up:      {ms([a for a, _ in warm]):7.1f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
