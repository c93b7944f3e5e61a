"""Linear stability of the fixed-step methods: the largest stable step.

On an undamped linear model ``y' = J y`` (eigenvalues ``+-i omega_j``) one step
of an explicit Runge-Kutta method is a matrix ``S(h)``; in each mode it acts as
the stability function ``R(i theta)``, ``theta = omega_j h``:

* RK4: ``R(z) = 1 + z + z^2/2 + z^3/6 + z^4/24``; ``|R(i theta)|^2 =
  1 - theta^6/72 + theta^8/576`` is <= 1 exactly for ``theta <= 2 sqrt 2``.
* explicit Euler: ``|R(i theta)| = sqrt(1 + theta^2) > 1`` for every ``theta > 0``.
* semi-implicit (symplectic) Euler: the mode matrix has trace ``2 - theta^2``
  and determinant 1, so its eigenvalues lie on the unit circle for
  ``theta <= 2`` and are real, one of modulus
  ``|theta^2/2 - 1| + sqrt((theta^2/2 - 1)^2 - 1) > 1``, beyond.

Definition of "stable" used here: ``h`` is stable when the spectral radius of
the *measured* one-step map over the oscillating modes, ``rho(S(h)) <= 1 +
tol`` with ``tol = 1e-12`` (see :func:`spectral_radius`). ``S(h)`` is assembled by applying the integrator's own step
(:func:`rk4h.rk_step`) to the columns of the identity, so it is the code
under test, not a formula. For a linear autonomous system ``y_n = S^n y_0``,
so ``sup_n ||y_n||`` is finite for every ``y_0`` iff ``rho(S) < 1``, or
``rho(S) = 1`` with semisimple unimodular eigenvalues (the symplectic case; the
rigid-body zero modes grow only linearly, as the exact motion does).
``tol`` admits round-off in the computed eigenvalues (about 1e-15 here) but is
far below every growth that matters: explicit Euler's excess ``theta^2/2`` is
5e-11 at the smallest ``theta = 1e-5`` probed, and RK4's excess just past the
boundary is about ``2.5 delta theta``, so the 1e-4 bisection is not affected.

References
----------
E. Hairer, G. Wanner, *Solving ODEs II*, 2nd ed., Springer 1996, sec. IV.2.
E. Hairer, C. Lubich, G. Wanner, *Geometric Numerical Integration*, sec. I.1.
"""
from __future__ import annotations

import math

import numpy as np

from rk4h import get_method, rk_step

from ._common import integrate_fixed, mode_amplitudes

__all__ = ["STABLE_TOL", "MAX_BISECTIONS", "one_step_matrix", "spectral_radius", "largest_stable_step",
           "theory_growth", "theory_boundary", "tolerance_boundary", "growth_steps", "measured_growth", "blowup_run"]

STABLE_TOL = 1e-12
THETA_MIN = 1e-5  # smallest omega h probed when looking for a stable step
#: Cap on bisection steps of :func:`largest_stable_step` (on top of ``rtol``):
#: 100 halvings of the bracket reach any double-precision width.
MAX_BISECTIONS = 100


def theory_growth(method, theta):
    """Growth factor per step (spectral radius of a harmonic mode's one-step
    map) at ``theta = omega h``, from the method's tableau: ``|R(i theta)|``
    for a classical tableau (``rk4h.stability_function.R``), the spectral
    radius of the 2x2 step matrix for a partitioned one (symplectic Euler,
    Stormer-Verlet). ``method`` is a tableau or a built-in name."""
    from rk4h.stability_function import R, partitioned_step_matrix

    tab = get_method(method)
    th = np.asarray(theta, dtype=float)
    if not tab.partitioned:
        return np.abs(R(tab, 1j * th))
    flat = np.atleast_1d(th).ravel()
    rho = np.array([np.max(np.abs(np.linalg.eigvals(partitioned_step_matrix(tab, x)))) for x in flat])
    return rho.reshape(th.shape) if th.ndim else float(rho[0])


def theory_boundary(method, omega_max: float) -> float:
    """Largest stable ``h`` (s) on a mode of ``omega_max`` (rad/s): the
    method's imaginary-axis boundary over ``omega_max``
    (``rk4h.stability_function.imaginary_axis_boundary``: 2 sqrt(2) for
    RK4, 2 for symplectic Euler and Stormer-Verlet, 0 for explicit Euler, which
    has no stable step)."""
    from rk4h.stability_function import imaginary_axis_boundary

    return imaginary_axis_boundary(get_method(method)) / omega_max


def tolerance_boundary(method, omega_max: float) -> float:
    """For a method with no stable step on the imaginary axis (explicit Euler,
    a two-stage second-order method: ``|R(i theta)| > 1`` for every
    ``theta > 0``), the largest ``h`` (s) that :func:`largest_stable_step`
    accepts: growth ``<= 1 + STABLE_TOL`` per step, from the theory growth
    (:func:`theory_growth`) by bisection; 0.0 when that ``omega h`` is below
    :data:`THETA_MIN` (the bisection then reports no stable step). For
    Ralston's method ``|R(i theta)| = sqrt(1 + theta^4/4)``, so
    ``theta = (8 STABLE_TOL)^(1/4) = 1.68e-3``."""
    def ok(th):
        return float(theory_growth(method, th)) <= 1.0 + STABLE_TOL

    if not ok(THETA_MIN):
        return 0.0
    lo, hi = THETA_MIN, 1.0
    if ok(hi):
        return theory_boundary(method, omega_max)
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if not lo < mid < hi:
            break
        lo, hi = (mid, hi) if ok(mid) else (lo, mid)
    return lo / omega_max


def one_step_matrix(model, h: float, method: str) -> np.ndarray:
    """The one-step map ``S(h)`` (shape (2n, 2n)) of ``method`` on a linear model,
    from one call of the integrator's step on the identity's columns."""
    tab = get_method(method)
    n = model.n_state
    k = np.empty((tab.n_stages, n, n))
    return rk_step(model.rhs, 0.0, np.eye(n), h, tab, k)


def spectral_radius(model, h: float, method: str, modes=None) -> float:
    """Largest spectral radius over the oscillating modes of the measured
    one-step map.

    ``S(h)`` is transformed to modal coordinates (``q = Phi eta``, ``v = Phi
    eta'``, mass-normalised ``Phi``), where it is block-diagonal, one 2 x 2
    block per mode; the radius is the maximum over the blocks of modes with
    ``omega > 0``. Zero-frequency (rigid-body) modes are left out: there the
    exact motion itself grows linearly and ``S`` has a defective eigenvalue 1,
    whose computed modulus carries a ``sqrt(eps)`` round-off.
    """
    omega, phi = modes if modes is not None else model.modes()
    n = model.n_dof
    with np.errstate(all="ignore"):
        S = one_step_matrix(model, h, method)
        if not np.all(np.isfinite(S)):
            return math.inf
        P = phi.T * model.mass  # inverse of phi for mass-normalised modes
        St = np.empty_like(S)
        St[:n, :n], St[:n, n:] = P @ S[:n, :n] @ phi, P @ S[:n, n:] @ phi
        St[n:, :n], St[n:, n:] = P @ S[n:, :n] @ phi, P @ S[n:, n:] @ phi
        rho = 0.0
        for j in np.flatnonzero(omega > 0):
            blk = St[np.ix_([j, n + j], [j, n + j])]
            rho = max(rho, float(np.max(np.abs(np.linalg.eigvals(blk)))))
        return rho


def largest_stable_step(model, method: str, rtol: float = 1e-4, omega_max: float | None = None):
    """Largest stable ``h`` (s) by bisection to relative precision ``rtol``.

    The bracket is found without theory: start at ``h = 1/omega_max``, double
    until unstable (or halve until stable). The bisection stops at relative
    width ``rtol``, after :data:`MAX_BISECTIONS` halvings, or when the midpoint
    is no longer between the ends (the bracket is one ulp wide), whichever
    comes first, so it ends for every ``rtol`` (even 1e-300).

    Returns ``(h_star, n_probes)``; ``h_star = 0.0`` when no step down to
    ``omega h = 1e-5`` is stable, ``inf`` when every step up to ``omega h =
    1e3`` is.
    """
    modes = model.modes()
    if omega_max is None:
        omega_max = float(modes[0][-1])

    def stable(h):
        return spectral_radius(model, h, method, modes) <= 1.0 + STABLE_TOL

    probes = 0
    h = 1.0 / omega_max
    probes += 1
    if stable(h):
        lo, hi = h, 2 * h
        while (probes := probes + 1) and stable(hi):
            lo, hi = hi, 2 * hi
            if hi * omega_max > 1e3:
                return math.inf, probes
    else:
        hi, lo = h, h / 2
        while (probes := probes + 1) and not stable(lo):
            hi, lo = lo, lo / 2
            if lo * omega_max < THETA_MIN:
                return 0.0, probes
    for _ in range(MAX_BISECTIONS):
        if not (hi - lo) > rtol * lo:
            break
        mid = 0.5 * (lo + hi)
        if not lo < mid < hi:
            break
        probes += 1
        if stable(mid):
            lo = mid
        else:
            hi = mid
    return lo, probes


def growth_steps(method: str, theta: float, n_steps: int = 1000) -> int:
    """Steps :func:`measured_growth` integrates at ``theta``: ``n_steps``, cut
    to ``230 / log g`` where the theory growth ``g > 1`` (far from overflow)
    and to ``25 / -log g`` where ``g < 1`` (before the mode sinks into
    round-off), never below 8."""
    g_th = float(theory_growth(method, theta))
    if g_th > 1.0:  # stay far from overflow
        return max(8, min(n_steps, int(230.0 / math.log(g_th))))
    if g_th < 1.0:  # a decaying mode sinks into the round-off of the others
        return max(8, min(n_steps, int(25.0 / -math.log(g_th))))
    return n_steps


def measured_growth(model, method: str, theta: float, n_steps: int = 1000, modes=None):
    """Growth factor per step of the fastest mode, measured from an integrated run.

    The run starts in the top mode (``q = phi_max``, ``v = 0``); the growth is
    ``exp(slope)`` of a least-squares line through ``log |z_k|`` over the steps,
    with ``z`` the mode's complex amplitude (``|z|^2/2`` is its energy). For RK4
    and Euler ``|z_k| = |R|^k |z_0|`` exactly; the symplectic Euler amplitude
    oscillates within a bounded ratio, which the fit averages out. The run is
    cut short where the theory predicts growth beyond 1e100 or decay below
    1e-11 (beyond that the mode sinks under the round-off of the others).

    Returns (growth, result) with the solver result of the run.
    """
    omega, phi = modes if modes is not None else model.modes()
    w = float(omega[-1])
    n_steps = growth_steps(method, theta, n_steps)
    y0 = model.state(phi[:, -1] / np.max(np.abs(phi[:, -1])))
    h = theta / w
    res, _ = integrate_fixed(model, (0.0, n_steps * h), y0, n_steps=n_steps, method=method)
    _, z = mode_amplitudes(model, res.y, (omega, phi))
    logz = np.log(np.abs(z[-1]))
    k = np.arange(logz.shape[0])
    slope = np.polyfit(k, logz, 1)[0]
    return float(math.exp(slope)), res


def blowup_run(model, method: str, h: float, n_steps: int):
    """Integrate from the top mode at step ``h`` for ``n_steps``: a blow-up ends
    with ``status = -1`` and ``t_fail`` (no exception, no warning)."""
    omega, phi = model.modes()
    y0 = model.state(phi[:, -1] / np.max(np.abs(phi[:, -1])))
    res, _ = integrate_fixed(model, (0.0, n_steps * h), y0, n_steps=n_steps, method=method,
                             t_eval=[n_steps * h])
    return res
