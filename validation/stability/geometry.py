"""The four-spring mass (planar4) at large amplitude and at a singular point.

Linearization error. By symmetry the cubic terms of ``V`` cancel (the springs
come in opposite pairs), so ``V = k (x^2 + y^2) + O(r^4 / l^2)``: the force
error of the linear model is ``O(k r^3 / l^2)`` and, over a fixed number of
periods, the trajectory error relative to the amplitude ``r`` grows like
``(r/l)^2``. Both models are integrated by RK4 with the same step, so RK4's
own error (nearly the same in both) cancels from the difference.

Singular geometry. At an anchor a spring has zero length: its direction, and
the force ``k (L - l) (r - a)/L`` (magnitude ``k l``), is undefined. A mass
aimed along the x axis at the anchor ``(l, 0)`` with a tiny offset in y passes
within that offset of it; the force turns through 180 degrees within a time
``offset / speed`` far below any step, so a fixed step cannot follow it and
the energy jumps. The study reports where and when this happens (closest
approach, anchor, time) instead of failing silently; a state exactly on an
anchor makes the force NaN and the run ends with status ``unstable``.
"""
from __future__ import annotations

import math

import numpy as np

import rk4h
from rk4h.energy import energy_scale

from ._common import integrate_fixed, loglog_slope

__all__ = ["linearization_error", "closest_approach", "singular_pass", "amplitude_exponent",
           "four_spring_params", "FOUR_SPRING_NEEDS"]

#: Direction of the initial displacement: Table 4.5's (x, y) = (0.005, 0.03) m.
TABLE_4_5_DIRECTION = (1 / 6, 1.0)


#: What :func:`four_spring_params` looks for, for the note of a skipped study.
FOUR_SPRING_NEEDS = ("needs the four-spring geometry: one mass drawn in the plane on four springs of equal natural "
                     "length l to anchors at distance l on the axes through its rest position")


def four_spring_params(model):
    """``{"m", "k", "l"}`` (kg, N/m, m) of a model drawn as the four-spring
    mass, or None.

    Read from ``model.drawing()`` and the model's mechanics, never from its
    name: the drawing must have layout ``"plane"``, one point, four anchors
    at ``reference + (-l, 0), (l, 0), (0, -l), (0, l)`` and four springs, each
    joining the point to a different anchor, of natural length ``l``; the
    point's two coordinates must carry the same mass ``m``, and the
    linearization at rest must be ``K = 2 k I`` (the two springs along each
    axis: each spring's own ``k`` is not in the drawing, so they are taken
    equal).
    """
    d = model.drawing()
    if d.layout != "plane" or len(d.points) != 1 or len(d.anchors) != 4 or len(d.springs) != 4:
        return None
    (ix, iy), (rx, ry) = d.points[0], d.reference[0]
    rest = np.asarray(d.rest, dtype=float)
    l_ = float(rest[0]) if rest.size == 4 else 0.0
    if not (l_ > 0 and np.all(np.abs(rest - l_) <= 1e-12 * l_)):
        return None
    ends = sorted(max(int(a), int(b)) for a, b, _ in d.springs)
    if ends != [1, 2, 3, 4] or any(min(int(a), int(b)) != 0 for a, b, _ in d.springs):
        return None
    offsets = sorted((round((ax - rx) / l_, 9), round((ay - ry) / l_, 9)) for ax, ay in d.anchors)
    if offsets != [(-1.0, 0.0), (0.0, -1.0), (0.0, 1.0), (1.0, 0.0)]:
        return None
    m = float(model.mass[ix])
    if float(model.mass[iy]) != m:
        return None
    try:
        K = np.asarray(model.stiffness_matrix(), dtype=float)
    except NotImplementedError:
        return None
    k = 0.5 * float(K[ix, ix])
    block = K[np.ix_([ix, iy], [ix, iy])]
    if not (k > 0 and np.allclose(block, 2 * k * np.eye(2), rtol=0.0, atol=1e-12 * k)):
        return None
    return {"m": m, "k": k, "l": l_}


def linearization_error(params: dict, amplitudes, periods: float = 5.0, steps_per_period: int = 400,
                        method="rk4"):
    """Max over ``periods`` small-oscillation periods of ``|q_nonlinear -
    q_linear| / r0`` for initial displacements ``a l (1/6, 1)``, ``a`` in
    ``amplitudes`` (units of l), both models integrated with ``method`` (RK4
    by default; at 400 steps per period its own error is far below the
    difference measured). Returns an array of errors."""
    p = {k: params[k] for k in ("m", "k", "l")}
    nl = rk4h.make_model("planar4", {**p, "linear": False})
    lin = rk4h.make_model("planar4", {**p, "linear": True})
    T = 2 * math.pi / math.sqrt(2 * p["k"] / p["m"])
    n = int(round(periods * steps_per_period))
    errs = []
    for a in amplitudes:
        q0 = a * p["l"] * np.array(TABLE_4_5_DIRECTION)
        y0 = nl.state(q0)
        r_nl, _ = integrate_fixed(nl, (0.0, periods * T), y0, n_steps=n, method=method)
        r_li, _ = integrate_fixed(lin, (0.0, periods * T), y0, n_steps=n, method=method)
        if not (r_nl.success and r_li.success):
            errs.append(math.nan)
            continue
        errs.append(float(np.max(np.abs(r_nl.y[:2] - r_li.y[:2]))) / float(np.hypot(*q0)))
    return np.array(errs)


def closest_approach(model, t, q):
    """Closest approach of the path ``q`` (shape (2, m): the displacement of
    the drawing's one point from its reference position) to any anchor of
    ``model.drawing()``, with the path taken straight between output points.

    Returns (distance (m), anchor index, time (s)).
    """
    drawing = model.drawing()
    rx, ry = drawing.reference[0] if drawing.reference else (0.0, 0.0)
    best = (math.inf, -1, math.nan)
    for j, (ax, ay) in enumerate(drawing.anchors):
        p0 = q[:, :-1] - np.array([[ax - rx], [ay - ry]])
        d = q[:, 1:] - q[:, :-1]
        dd = np.sum(d * d, axis=0)
        s = np.clip(-np.sum(p0 * d, axis=0) / np.where(dd > 0, dd, 1.0), 0.0, 1.0)
        dist = np.hypot(p0[0] + s * d[0], p0[1] + s * d[1])
        i = int(np.argmin(dist))
        if dist[i] < best[0]:
            best = (float(dist[i]), j, float(t[i] + s[i] * (t[i + 1] - t[i])))
    return best


def singular_pass(params: dict, offset: float, h: float, t_end: float, start_on_anchor=False, method="rk4"):
    """Aim the mass at the anchor ``(l, 0)``: start at rest at ``(2l, offset)``
    (or exactly on the anchor when ``start_on_anchor``) and integrate with
    ``method`` (RK4 by default).

    Returns dict: ``status`` ("singular" when the path comes within 1e-6 l of an
    anchor, "unstable" on a non-finite state, else "ok"), ``message`` (where and
    when), ``d_min`` (m), ``anchor``, ``t_min`` (s), ``energy_jump`` (relative
    energy change over the run), ``result``.
    """
    model = rk4h.make_model("planar4", {k: params[k] for k in ("m", "k", "l")} | {"linear": False})
    l_ = float(params["l"])
    anchors = model.drawing().anchors
    q0 = np.array([l_, 0.0]) if start_on_anchor else np.array([2 * l_, offset])
    res, _ = integrate_fixed(model, (0.0, t_end), model.state(q0), h=h, method=method)
    out = {"result": res, "d_min": math.nan, "anchor": -1, "t_min": math.nan, "energy_jump": math.nan}
    if not res.success:
        last = res.y[:2, -1]
        out.update(status="unstable", message=(
            f"{res.message}; last finite position ({last[0]:.6g}, {last[1]:.6g}) m at t = {res.t[-1]:.6g} s, "
            f"anchors at distance {min(np.hypot(last[0] - a, last[1] - b) for a, b in anchors):.3g} m"))
        return out
    d, j, tm = closest_approach(model, res.t, res.y[:2])
    with np.errstate(all="ignore"):
        E = model.energy(res.y)
    jump = float(np.max(np.abs(E - E[0])) / energy_scale(model, E[0]))
    ax, ay = anchors[j]
    status = "singular" if d < 1e-6 * l_ else "ok"
    out.update(status=status, d_min=d, anchor=j, t_min=tm, energy_jump=jump, message=(
        f"closest approach {d:.3g} m to anchor {j} at ({ax:g}, {ay:g}) m at t = {tm:.6g} s "
        f"(h = {res.h:.3g} s); spring direction undefined there; max |E - E0|/E_motion = {jump:.3g}"))
    return out


def amplitude_exponent(amplitudes, errors, a_max: float = 1e-2) -> float:
    """Log-log slope of the linearization error for ``a <= a_max`` (theory: 2)."""
    a, e = np.asarray(amplitudes), np.asarray(errors)
    sel = (a <= a_max) & np.isfinite(e) & (e > 0)
    return loglog_slope(a[sel], e[sel])
