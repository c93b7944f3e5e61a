"""Large chains: RK4 and CVODE-BDF cost per step, and memory, against N.

Cost is counted two ways. *Work*: RK4 makes 4 right-hand-side calls per step
whatever N, each touching O(N) numbers; the bytes it allocates are measured
with :mod:`tracemalloc` on the generic path (:func:`rk4h.solve`, whose
arrays are all numpy arrays and hence traced): the peak over a short run must
grow like N (a dense N x N matrix anywhere would make it grow like N^2).
*Time*: the wall time per step of the compiled path, minimum over repeats
(load from other processes only adds time, so the minimum is the least noisy
estimate of the cost), whose log-log slope against N is reported; only the
slow tests assert it. Below N of a few thousand the whole working set (state,
four stage slopes: ~10 arrays of 2N doubles) stays in the L1/L2 caches and
the time per mass is about half of that at large N (measured: 18 ns/mass at
N = 1e3, 37-43 ns/mass for N = 3e3 ... 1e5), so fits start at N = 3e3.

CVODE-BDF runs with the banded direct solver on the interleaved state
``[q1, v1, q2, v2, ...]`` (lower/upper bandwidth 3/1 for a chain) and the
solver's own banded difference-quotient Jacobian: sksundae hands a
user-supplied ``jacfn`` a dense (2N, 2N) array even for the band solver, so an
analytic Jacobian would cost O(N^2) memory. The difference-quotient Jacobian
costs ``lband + uband + 1 = 5`` extra RHS calls per Jacobian, counted here in
``nfev_total = nfev + 5 njev``.
"""
from __future__ import annotations

import time
import tracemalloc

import numpy as np

import rk4h

from ._common import integrate_fixed, loglog_slope

__all__ = ["uniform_chain", "step_cost", "peak_bytes", "cvode_band_cost", "dense_rhs_peak_bytes"]


def uniform_chain(N: int, m: float = 1.0, k: float = 1.0):
    """``N`` equal masses (kg) and ``N + 1`` equal springs (N/m), walls both
    ends; initial state: the lowest mode shape with amplitude 1e-3 m, at rest."""
    model = rk4h.make_model("chain", {"masses": [m] * N, "springs": [k] * (N + 1), "walls": "both"})
    x = 1e-3 * np.sin(np.pi * np.arange(1, N + 1) / (N + 1))
    return model, model.state(x)


def step_cost(N: int, n_steps: int = 200, repeats: int = 5, h: float = 0.1, method="rk4"):
    """Wall time per step (s, minimum of ``repeats``) of ``method`` (a tableau
    or its name; RK4 by default) on an N-mass chain, RHS calls per step and the
    path used; ``h = 0.1`` s is stable for RK4 (omega_max < 2 for m = k = 1)."""
    model, y0 = uniform_chain(N)
    integrate_fixed(model, (0.0, h), y0, n_steps=1, t_eval=[h], method=method)  # warm-up / compile
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        res, path = integrate_fixed(model, (0.0, n_steps * h), y0, n_steps=n_steps,
                                    t_eval=[n_steps * h], method=method)
        times.append((time.perf_counter() - t0) / n_steps)
    return min(times), res.nfev / res.n_steps, path


def peak_bytes(N: int, n_steps: int = 3, method="rk4") -> int:
    """Peak bytes allocated (tracemalloc) by a short generic-path run of
    ``method`` (RK4 by default) on an N-mass chain, model construction excluded."""
    model, y0 = uniform_chain(N)
    tracemalloc.start()
    try:
        tracemalloc.reset_peak()
        base = tracemalloc.get_traced_memory()[0]
        rk4h.solve(model.rhs, (0.0, 0.1 * n_steps), y0, n_steps=n_steps, t_eval=[0.1 * n_steps], method=method)
        peak = tracemalloc.get_traced_memory()[1] - base
    finally:
        tracemalloc.stop()
    return int(peak)


def dense_rhs_peak_bytes(N: int, n_steps: int = 3) -> int:
    """The same measurement with a right-hand side that builds the dense
    stiffness matrix: the negative control (its peak grows like N^2)."""
    model, y0 = uniform_chain(N)

    def rhs(t, y):
        K = model.stiffness_matrix()  # dense (N, N)
        return np.concatenate([y[N:], -(K @ y[:N]) / model.mass])

    tracemalloc.start()
    try:
        tracemalloc.reset_peak()
        base = tracemalloc.get_traced_memory()[0]
        rk4h.solve(rhs, (0.0, 0.1 * n_steps), y0, n_steps=n_steps, t_eval=[0.1 * n_steps])
        peak = tracemalloc.get_traced_memory()[1] - base
    finally:
        tracemalloc.stop()
    return int(peak)


def cvode_band_cost(N: int, rtol: float = 1e-6, periods: float = 1.0):
    """CVODE-BDF with the banded solver on an N-mass chain, over ``periods``
    periods of the lowest mode (so the step count hardly depends on N).

    Returns dict with ``wall_per_step`` (s), ``n_steps``, ``nfev``, ``njev``,
    ``nfev_total`` and ``success``.
    """
    from sksundae.cvode import CVODE

    model, y0 = uniform_chain(N)
    t_end = periods * 2 * np.pi / (2 * np.sin(np.pi / (2 * (N + 1))))  # omega_1 (m = k = 1)
    perm = np.empty(2 * N, dtype=np.intp)
    perm[0::2], perm[1::2] = np.arange(N), np.arange(N) + N
    ybuf = np.empty(2 * N)

    def rhsfn(t, z, zp):
        ybuf[perm] = z
        zp[:] = model.rhs(t, ybuf)[perm]

    atol = rtol * 1e-3 * np.where(np.arange(2 * N) % 2 == 0, 1.0, 2.0)  # amplitude 1e-3 m, omega <= 2
    solver = CVODE(rhsfn, method="BDF", rtol=rtol, atol=atol, linsolver="band", lband=3, uband=1,
                   max_num_steps=1_000_000)
    t0 = time.perf_counter()
    solver.init_step(0.0, y0[perm])
    n_steps = 0
    while True:
        res = solver.step(t_end, method="onestep", tstop=t_end)
        if not res.success:
            break
        n_steps += 1
        if res.t >= t_end:
            break
    wall = time.perf_counter() - t0
    return {"wall_per_step": wall / max(n_steps, 1), "n_steps": n_steps, "nfev": int(res.nfev),
            "njev": int(res.njev), "nfev_total": int(res.nfev) + 5 * int(res.njev),
            "success": bool(res.success)}


def fit_exponent(Ns, values) -> float:
    """Least-squares log-log slope (the fitted exponent of ``values ~ N^p``)."""
    return loglog_slope(Ns, values)
