"""Figures of the energy over time: growth at equal cost, and energy work-precision.

Both draw measured rows only (:mod:`rk4h.validation.energy_time` produced them);
nothing here integrates.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

__all__ = ["energy_growth", "energy_work_precision"]


def energy_growth(out_dir, scene_name, series, exponents):
    """Relative energy error against time, log-log, one line per method.

    Parameters
    ----------
    out_dir : path-like
    scene_name : str
    series : dict
        ``label -> (t, rel_energy_error)`` (t in s), the label starting with the
        method's name (``"rk4 h=0.004"``).
    exponents : dict
        ``label -> growth exponent`` (:func:`rk4h.validation.energy_time.growth_exponent`),
        added to the legend.

    Returns
    -------
    (Path, caption)
        As :func:`rk4h.validation.figures.energy_error`, whose drawing this reuses
        (file stem ``<scene>_energy_growth``).
    """
    from rk4h.validation import figures

    labelled = {f"{lab} (k = {exponents.get(lab, math.nan):.2f})": v for lab, v in series.items()}
    return figures.energy_error(out_dir, scene_name, labelled,
                                title=f"{scene_name}: relative energy error at equal cost (k: growth exponent)",
                                stem=f"{figures.slug(scene_name)}_energy_growth")


def energy_work_precision(out_dir, scene_name, rows) -> Path:
    """max |E(t) - E0| / E_motion against RHS calls (left) and wall time (right).

    Parameters
    ----------
    out_dir : path-like
    scene_name : str
    rows : list of dict
        :func:`rk4h.validation.energy_time.work_precision_rows` of one scene: one
        line per (method, horizon), markers at its steps or rtols; rows that did not
        end ``ok`` are left out.

    Returns
    -------
    Path
        ``<out_dir>/<scene>_energy_work_precision.png``.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from rk4h.validation import figures

    fig, axes = plt.subplots(1, 2, figsize=(11, 4.8), constrained_layout=True)
    fig.suptitle(f"{scene_name}: energy work-precision (periods of the slowest mode)")
    styles = ["-", "--", ":", "-."]
    horizons = sorted({r["periods"] for r in rows})
    methods = list(dict.fromkeys(r["solver"] for r in rows))
    cmap = plt.get_cmap("tab10")
    for mi, name in enumerate(methods):
        for hi, per in enumerate(horizons):
            mine = sorted((r for r in rows if r["solver"] == name and r["periods"] == per
                           and r["status"] == "ok" and r["energy_drift_max"] > 0), key=lambda r: r["nfev"])
            if not mine:
                continue
            e = np.array([r["energy_drift_max"] for r in mine])
            for ax, key in zip(axes, ("nfev", "wall_s")):
                ax.plot([r[key] for r in mine], e, marker="o", ms=3, color=cmap(mi % 10),
                        ls=styles[hi % len(styles)], label=f"{name}, {per:g} periods")
    for ax, xl in zip(axes, ("right-hand-side calls", "wall time (s, one run, compile time apart)")):
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel(xl)
        ax.set_ylabel("max |E(t) - E0| / E_motion")
        ax.grid(True, which="both", alpha=0.3)
    axes[0].legend(fontsize=7, ncol=2)
    out = Path(out_dir) / f"{figures.slug(scene_name)}_energy_work_precision.png"
    fig.savefig(out, dpi=110)
    plt.close(fig)
    return out
