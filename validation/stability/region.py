"""Linear stability regions in the complex plane, and where they meet the imaginary axis.

What is drawn
-------------
Classical tableaux: the boundary ``|R(z)| = 1`` of the stability region of
``y' = lambda y``, ``z = h lambda`` (:func:`rk4h.stability_function.R`;
HW II, sec. IV.2), and the interval ``[-i y*, i y*]`` of the imaginary axis
inside it, ``y* = imaginary_axis_boundary`` (RK4 ``2 sqrt 2``, Heun's third
order ``sqrt 3``, Euler none).

Partitioned tableaux have no scalar test equation. They are drawn on their
``q-v`` test equation ``q'' = lambda^2 q`` (``q' = v``, ``v' = lambda^2 q``,
eigenvalues ``+-lambda``; ``lambda = +-i w`` is the undamped oscillator), with
``z = h lambda``: one step is the 2 x 2 matrix ``M`` of
:func:`rk4h.stability_function.partitioned_step_matrix` at ``(h w)^2 =
-z^2``, and the region is where its spectral radius ``rho(M(z)) <= 1``. A
symplectic method has ``det M = 1`` for every ``z``, so ``rho >= 1``
everywhere and ``rho = 1`` only on its imaginary-axis interval: its region
*is* that interval (drawn as a bar), with no area off the axis. The figure
adds, dashed, the curve ``rho(M(z)) = 1 + RHO_MARGIN``: the band around the
interval in which a step amplifies by less than ``RHO_MARGIN`` (a damped or
slightly growing mode grows by at most ``e`` over ``1/RHO_MARGIN`` steps); it
hugs the axis (``rho - 1`` grows about as ``|Re z|``), so that panel is
narrow in ``Re z``.

Crossings of the imaginary axis (:func:`axis_crossing`) are found on the
drawn function itself: sign changes of ``|R(i y)| - 1`` (``rho - 1`` for a
partitioned method, which is >= 0 on a symplectic method's axis: there the
end of the interval is where ``rho`` leaves 1) on a grid, refined by
bisection to 1e-13; they agree with the exact
:func:`rk4h.stability_function.imaginary_axis_boundary`.

Units: ``z`` is dimensionless (step times eigenvalue).
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

__all__ = ["RHO_MARGIN", "amplification", "axis_crossing", "region_data", "region_plot", "draw_regions", "main"]

#: Spectral-radius margin of the dashed curve drawn around a partitioned method's interval.
RHO_MARGIN = 0.05


def _poly(tab):
    from rk4h.stability_function import _step_matrix_poly, stability_polynomial

    if tab.partitioned:
        return [[[float(a) for a in p] for p in row] for row in _step_matrix_poly(tab)]
    return [float(a) for a in stability_polynomial(tab)]


def _horner(coeffs, x):
    acc = np.zeros_like(x)
    for a in reversed(coeffs):
        acc = acc * x + a
    return acc


def amplification(tab, z):
    """``|R(z)|`` (classical) or the spectral radius of ``M(z)`` on ``q'' =
    lambda^2 q`` (partitioned; module docstring), elementwise.

    Parameters
    ----------
    tab : rk4h.methods.Tableau
    z : complex or array_like of complex
        ``h lambda`` (dimensionless).

    Returns
    -------
    ndarray of float, same shape as ``z``
    """
    return _amplification(tab, _poly(tab), z)


def _amplification(tab, P, z):
    """:func:`amplification` with ``tab``'s polynomial(s) ``P`` (:func:`_poly`)
    given: the exact polynomial costs more than evaluating it at one point."""
    z = np.asarray(z, dtype=complex)
    if not tab.partitioned:
        return np.abs(_horner(P, z))
    x = -z * z  # (h w)^2 of the oscillator form
    (m11, m12), (m21, m22) = [[_horner(p, x) for p in row] for row in P]
    tr, det = m11 + m22, m11 * m22 - m12 * m21
    disc = np.sqrt(tr * tr / 4 - det)
    return np.maximum(np.abs(tr / 2 + disc), np.abs(tr / 2 - disc))


def axis_crossing(tab, y_max: float = 10.0, n: int = 20001, tol: float = 1e-13) -> float:
    """Smallest ``y > 0`` where the stability boundary leaves the imaginary
    axis: the first sign change of ``g(y) = amplification(tab, i y) - 1``
    (classical: from <= 0 to > 0; partitioned: the end of the run where
    ``g`` is 0 to round-off, ``g <= 1e-12``) on ``n`` grid points in ``(0,
    y_max]``, bisected to ``tol``. 0.0 when unstable at the first grid point
    (Euler, Ralston: ``|R(iy)| - 1 ~ y^4/72``); ``inf``
    when stable up to ``y_max``."""
    ys = np.linspace(0.0, y_max, n)[1:]
    slack = 1e-12 if tab.partitioned else 0.0
    P = _poly(tab)  # once, not once per bisection step
    bad = _amplification(tab, P, 1j * ys) - 1 > slack
    if not bad.any():
        return math.inf
    k = int(np.argmax(bad))
    if k == 0:  # unstable from the first grid point on: no interval (Euler, Ralston)
        return 0.0
    lo, hi = float(ys[k - 1]), float(ys[k])
    while hi - lo > tol:
        mid = 0.5 * (lo + hi)
        if float(_amplification(tab, P, 1j * mid)) - 1 > slack:
            hi = mid
        else:
            lo = mid
    return 0.5 * (lo + hi)


def region_data(tab, re=(-4.0, 1.0), im=(-4.0, 4.0), n: int = 401) -> dict:
    """The grid and amplification a figure contours, plus the axis interval.

    Returns
    -------
    dict
        ``x`` (n,), ``y`` (n,) the real and imaginary parts of ``z``;
        ``amp`` (n, n) :func:`amplification` on the grid (rows: ``y``);
        ``interval`` ``y*`` from
        :func:`rk4h.stability_function.imaginary_axis_boundary` (exact);
        ``crossing`` :func:`axis_crossing`; ``partitioned`` bool.
    """
    from rk4h.stability_function import imaginary_axis_boundary

    x = np.linspace(re[0], re[1], n)
    y = np.linspace(im[0], im[1], n)
    Z = x[None, :] + 1j * y[:, None]
    return {"x": x, "y": y, "amp": amplification(tab, Z), "interval": imaginary_axis_boundary(tab),
            "crossing": axis_crossing(tab), "partitioned": tab.partitioned, "name": tab.name}


def region_plot(scene_name: str, tabs, *, n: int = 241) -> dict:
    """The report's stability-region figure of ``tabs`` as a plot description
    of the stability study (``{"kind": "region", ...}``, drawn by
    :func:`rk4h.validation.stability.plots.draw`): per method its
    :func:`region_data` on a window that holds every method's axis
    interval (classical: ``Re z`` in ``[-4, 1]``; partitioned: ``[-0.6,
    0.6]``, where the ``1 + RHO_MARGIN`` band lies).

    Parameters
    ----------
    scene_name : str
    tabs : sequence of rk4h.methods.Tableau
        Named as the scene names them (``tab.name``), in legend order.
    n : int
        Grid points per axis.

    Returns
    -------
    dict
        ``data``: ``classical`` and ``partitioned``, lists of
        :func:`region_data` dicts (``name`` the method); ``rho_margin``;
        ``im_max`` the half-height of the window (dimensionless ``Im z``).
    """
    from rk4h.stability_function import imaginary_axis_boundary

    finite = [b for b in map(imaginary_axis_boundary, tabs) if math.isfinite(b)]
    im_max = max([3.5] + [1.2 * b for b in finite])
    data = {"classical": [], "partitioned": [], "rho_margin": RHO_MARGIN, "im_max": im_max}
    for tab in tabs:
        re = (-0.6, 0.6) if tab.partitioned else (-4.0, 1.0)
        data["partitioned" if tab.partitioned else "classical"].append(
            region_data(tab, re=re, im=(-im_max, im_max), n=n))
    return {"kind": "region", "scene": scene_name, "study": "region", "name": "region", "data": data}


def draw_regions(tabs, path, *, n: int = 401) -> tuple[Path, str]:
    """Draw every tableau's stability region (module docstring) in one
    figure: classical methods left, partitioned right; returns the file and
    a caption sentence that says what is drawn."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    classical = [t for t in tabs if not t.partitioned]
    part = [t for t in tabs if t.partitioned]
    fig, axes = plt.subplots(1, 2, figsize=(11, 5.2), constrained_layout=True)
    colours = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    for ax, group, title in ((axes[0], classical, "classical: |R(z)| = 1, z = h lambda on y' = lambda y"),
                             (axes[1], part, f"partitioned on q'' = lambda^2 q: rho(M(z)) = 1 + {RHO_MARGIN:g}")):
        handles = []
        for k, tab in enumerate(group):
            col = colours[k % len(colours)]
            d = region_data(tab, n=n, re=(-0.6, 0.6) if tab.partitioned else (-4.0, 1.0))
            level = 1.0 + (RHO_MARGIN if tab.partitioned else 0.0)
            ax.contour(d["x"], d["y"], d["amp"], levels=[level], colors=[col],
                       linestyles="--" if tab.partitioned else "-", linewidths=1.2)
            y_star = d["interval"]
            label = f"{tab.name} (|Im z| <= {y_star:.4g})" if y_star > 0 else f"{tab.name} (no axis interval)"
            if math.isfinite(y_star) and y_star > 0:
                off = (0.025 if tab.partitioned else -0.04) * (k + 1)
                ax.plot([off, off], [-y_star, y_star], color=col, linewidth=3, alpha=0.7, solid_capstyle="butt")
            handles.append(plt.Line2D([], [], color=col, linestyle="--" if tab.partitioned else "-", label=label))
        ax.axhline(0, color="0.6", linewidth=0.6)
        ax.axvline(0, color="0.6", linewidth=0.6)
        ax.set_xlabel("Re z")
        ax.set_ylabel("Im z")
        if group is classical:
            ax.set_aspect("equal")
        ax.set_title(title, fontsize=9)
        if handles:
            ax.legend(handles=handles, fontsize=8, loc="upper left", bbox_to_anchor=(0.0, -0.12), ncol=2,
                      frameon=False)
    fig.suptitle("Linear stability regions; bars: the stable interval of the imaginary axis", fontsize=11)
    path = Path(path)
    fig.savefig(path, dpi=120, bbox_inches="tight")
    plt.close(fig)
    caption = ("Stability regions in the complex plane of z = h lambda. Left, classical methods: the curve "
               "|R(z)| = 1, the region on its inner side. Right, partitioned methods on q'' = lambda^2 q: a "
               "symplectic method has det M = 1, so it is stable only on the imaginary-axis interval (bars); the "
               f"dashed curve bounds where one step amplifies by less than {RHO_MARGIN:g}.")
    return path, caption


def main(argv=None) -> int:
    """``python -m rk4h.validation.stability.region --out FILE [METHOD ...]``: draw
    the regions of the named methods of ``rk4h.METHODS`` (default: all)."""
    import argparse

    from rk4h.methods import METHODS

    p = argparse.ArgumentParser(description="Draw linear stability regions (|R(z)| = 1; partitioned methods "
                                            "on q'' = lambda^2 q).")
    p.add_argument("--out", required=True, help="PNG file to write")
    p.add_argument("methods", nargs="*", help=f"methods (default: all of {', '.join(sorted(METHODS))})")
    args = p.parse_args(argv)
    names = args.methods or list(METHODS)
    for name in names:
        if name not in METHODS:
            print(f"error: method {name!r} is not one of {', '.join(sorted(METHODS))}")
            return 2
    out = Path(args.out)
    if out.exists():
        print(f"error: --out {str(out)!r} exists; choose a new file (nothing is overwritten)")
        return 2
    path, caption = draw_regions([METHODS[n] for n in names], out)
    print(f"{path}: {caption}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
