"""What an integer power costs in numpy, and how its roundings differ.

    python benchmarks/bench_integer_powers.py [--size N] [--repeats R]

``rk4h.expr.lambdify`` prints ``x**n`` (integer ``2 <= n <= 64``) as the
products numba and heyoka use (binary powering). This prints, for ``n`` = 3
and 4 on ``N`` arguments with positive, mixed-sign and negative bases:

* ns per element of numpy's ``x**n`` (``np.power``) and of the products
  lambdify prints, as numpy expressions (``s = x*x``, then ``x*s`` or
  ``s*s``), the median of ``R`` timed calls each, in one process, with the
  load average;
* the fraction of arguments where numpy's ``pow``, libm's (``math.pow``)
  and the products disagree (0 between numpy and libm unless numpy uses a
  SIMD ``pow``, as on AVX-512).

It also times one block of the FPUT spring energy ``k r^2/2 + alpha r^3/3 +
beta r^4/4`` (5 springs x 16384 states, extensions in [-0.47, 0.47] as in
the energy-fput scene) through ``rk4h.models.network.spring_energy`` against
the same formula with numpy's ``**``.
"""
from __future__ import annotations

import argparse
import math
import os
import sys
from pathlib import Path

import numpy as np

from rk4h import expr as ex
from rk4h.models import network

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _timing import median_time  # noqa: E402


def _ns_per_element(fn, size, repeats):
    return median_time(fn, repeats) / size * 1e9


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--size", type=int, default=81920)
    p.add_argument("--repeats", type=int, default=50)
    args = p.parse_args(argv)
    rng = np.random.default_rng(0)
    u = rng.random(args.size)
    bases = {"positive": 0.5 * u, "mixed": u - 0.5, "negative": -0.5 * u}
    x, = ex.symbols("x")
    print(f"bench_integer_powers: {args.size} elements, median of {args.repeats}; "
          f"load {os.getloadavg()[0]:.2f}; numpy {np.__version__}")
    print("n  bases     numpy ** (ns)  products (ns)  ratio  numpy!=libm  products!=libm")
    for n in (3, 4):
        f = ex.lambdify(x**n, ["x"])
        for name, v in bases.items():
            products = (lambda: v * (v * v)) if n == 3 else (lambda: (lambda sq: sq * sq)(v * v))
            assert np.array_equal(products(), f(v))  # what lambdify prints
            a = _ns_per_element(lambda: v**n, args.size, args.repeats)
            b = _ns_per_element(products, args.size, args.repeats)
            libm = np.array([math.pow(t, n) for t in v[:20000]])
            d_np = np.mean(v[:20000]**n != libm)
            d_pr = np.mean(f(v[:20000]) != libm)
            print(f"{n}  {name:9s} {a:13.2f}  {b:13.2f}  {a / b:5.1f}  {d_np:11.3f}  {d_pr:14.3f}")
    r = (rng.random((5, 16384)) - 0.5) * 0.94
    k = np.ones((5, 1))

    def numpy_pow():
        return k * r**2 / 2 + 0.25 * r**3 / 3 + 0.0 * r**4 / 4

    a = _ns_per_element(numpy_pow, r.size, args.repeats)
    b = _ns_per_element(lambda: network.spring_energy(r, k, 0.25, 0.0), r.size, args.repeats)
    print(f"FPUT spring energy, one block of 5 x 16384: numpy ** {a:.2f} ns, products {b:.2f} ns per spring "
          f"(ratio {a / b:.1f}); load {os.getloadavg()[0]:.2f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
