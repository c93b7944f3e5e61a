"""Figures of the stability study (Agg backend). Each function only draws the
data it is given, saves ``OUT/<scene>_stability_<what>.png`` and returns
``(Path, sentence)``."""
from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.ticker  # noqa: E402
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

__all__ = ["growth_figure", "cost_figure", "drift_figure", "roundoff_figure", "large_n_figure",
           "amplitude_figure"]

_COLORS = {"rk4": "C0", "euler": "C3", "symplectic-euler": "C2", "dop853": "C1", "cvode-bdf": "C4",
           "heyoka": "C5", "cvode-adams": "C6"}


def _save(fig, out_dir, scene, what, sentence):
    path = Path(out_dir) / f"{scene.replace('-', '_').lower()}_stability_{what}.png"
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path, sentence


def growth_figure(out_dir, scene, theta, theory, measured):
    """``theory``: method -> growth over ``theta``; ``measured``: method ->
    (theta points, growth points)."""
    fig, ax = plt.subplots(figsize=(6.5, 4.2))
    for meth, g in theory.items():
        ax.plot(theta, g, color=_COLORS.get(meth), label=f"{meth} theory")
        th, gm = measured.get(meth, ([], []))
        ax.plot(th, gm, "o", mfc="none", color=_COLORS.get(meth), label=f"{meth} measured")
    ax.axhline(1.0, color="k", lw=0.6)
    ax.axvline(2.0, color="C2", ls=":", lw=0.8)
    ax.axvline(2 * np.sqrt(2), color="C0", ls=":", lw=0.8)
    ax.set_yscale("log")
    ax.set_xlabel(r"$\omega h$")
    ax.set_ylabel("growth factor per step")
    ax.legend(fontsize=7, ncol=2)
    return _save(fig, out_dir, scene, "growth", (
        "Amplitude growth per step of the fastest mode against omega*h: RK4 stays <= 1 up to 2.83, "
        "symplectic Euler is exactly 1 up to 2, explicit Euler exceeds 1 for every step; "
        "circles are measured from integrated runs."))


def cost_figure(out_dir, scene, curves, xlabel):
    """``curves``: solver -> (x, nfev, wall_s) arrays (NaN where not reached)."""
    fig, axs = plt.subplots(1, 2, figsize=(10, 4))
    for solver, (x, nfev, wall) in curves.items():
        axs[0].loglog(x, nfev, "o-", color=_COLORS.get(solver), label=solver)
        axs[1].loglog(x, wall, "o-", color=_COLORS.get(solver), label=solver)
    axs[0].set_ylabel("RHS evaluations (heyoka: steps x order)")
    axs[1].set_ylabel("wall time (s)")
    for ax in axs:
        ax.set_xlabel(xlabel)
        ax.legend(fontsize=8)
    return _save(fig, out_dir, scene, "cost", (
        f"Cost of reaching the target error against {xlabel}: the explicit methods' cost grows with "
        "omega_max (RK4 ~ omega_max), BDF's stays flat when the fast mode is not excited."))


def drift_figure(out_dir, scene, theta_line, loss_th, lag_th, points, series):
    """Per-step energy loss / phase lag vs theta (theory lines, measured
    points) and relative energy error vs time of the long runs (``series``:
    label -> (t, err))."""
    fig, axs = plt.subplots(1, 3, figsize=(14, 4))
    axs[0].loglog(theta_line, loss_th, "C0-", label=r"$1-|R(i\theta)|^2$")
    axs[0].loglog(theta_line, theta_line**6 / 72, "k:", label=r"$\theta^6/72$")
    axs[0].loglog(points["theta"], points["energy_loss"], "C0o", mfc="none", label="measured")
    axs[0].set_ylabel("energy loss per step")
    axs[1].loglog(theta_line, lag_th, "C1-", label=r"$\theta-\arg R(i\theta)$")
    axs[1].loglog(theta_line, theta_line**5 / 120, "k:", label=r"$\theta^5/120$")
    axs[1].loglog(points["theta"], points["phase_lag"], "C1o", mfc="none", label="measured")
    axs[1].set_ylabel("phase lag per step (rad)")
    for ax in axs[:2]:
        ax.xaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())
        ax.set_xlabel(r"$\theta = \omega h$")
        ax.legend(fontsize=8)
    for label, (t, e) in series.items():
        sel = (t > 0) & (e > 0)
        axs[2].loglog(t[sel], e[sel], label=label)
    axs[2].set_xlabel("t (s)")
    axs[2].set_ylabel(r"$|E(t)-E_0|/|E_0|$")
    axs[2].legend(fontsize=8)
    return _save(fig, out_dir, scene, "drift", (
        "RK4 loses energy and phase at the predicted rates per step (left, middle: measured circles on "
        "the exact curves, leading-order terms dotted); right: energy error over the long run for RK4 "
        "and the references."))


def roundoff_figure(out_dir, scene, h, err, h_best):
    fig, ax = plt.subplots(figsize=(6, 4))
    ax.loglog(h, err, "o-", label="RK4 error at t_end")
    i = int(np.nanargmin(err))
    ax.loglog([h_best], [err[i]], "r*", ms=14, label=f"best h = {h_best:.2g} s")
    ax.set_xlabel("h (s)")
    ax.set_ylabel("max |q - q_exact| / max |q0|")
    ax.legend()
    return _save(fig, out_dir, scene, "roundoff", (
        "RK4 error against step: slope 4 down to the star (best h), below which accumulated round-off "
        "makes the error grow again."))


def large_n_figure(out_dir, scene, N, rk4_time, rk4_bytes, cvode_time, fits):
    fig, axs = plt.subplots(1, 2, figsize=(10, 4))
    axs[0].loglog(N, rk4_time, "C0o-", label=f"RK4 (slope {fits['rk4_time']:.2f})")
    if cvode_time is not None:
        axs[0].loglog(N, cvode_time, "C4s-", label=f"CVODE-BDF band (slope {fits['cvode_time']:.2f})")
    axs[0].set_ylabel("wall time per step (s)")
    axs[1].loglog(N, rk4_bytes, "C0o-", label=f"RK4 peak bytes (slope {fits['rk4_bytes']:.2f})")
    axs[1].set_ylabel("peak bytes (tracemalloc)")
    for ax in axs:
        ax.set_xlabel("N masses")
        ax.legend(fontsize=8)
    return _save(fig, out_dir, scene, "large_n", (
        "Cost per step and memory against chain length N: slopes near 1 mean O(N) work and storage."))


def amplitude_figure(out_dir, scene, a, err, slope):
    fig, ax = plt.subplots(figsize=(6, 4))
    ax.loglog(a, err, "o-", label=f"measured (slope {slope:.2f} for a <= 1e-2)")
    sel = np.isfinite(err)
    i = np.argmin(np.abs(np.log(a[sel]) - np.log(1e-3)))
    ax.loglog(a, err[sel][i] * (a / a[sel][i]) ** 2, "k:", label="slope 2")
    ax.set_xlabel("initial amplitude / l")
    ax.set_ylabel("linearized model error / amplitude")
    ax.legend()
    return _save(fig, out_dir, scene, "amplitude", (
        "Relative error of the small-oscillation model over 5 periods against amplitude: grows like "
        "(r/l)^2; read off the largest amplitude at which the cheap model is good enough."))
