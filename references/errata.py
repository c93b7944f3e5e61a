"""The seed's known errata (docs/scenes.md, "The thesis' errata"), recomputed.

:func:`errata_rows` returns one row per corrected quantity. In the
``thesis`` column a number the thesis prints is quoted as printed (typed:
it is a quotation); where the thesis prints only a formula, the column holds
what that formula gives, evaluated here, and the note says so. Every number
in the ``corrected`` column is computed by the code (closed forms, the
models' eigenproblems and forces, the dispersion relation), never typed.

Units: SI (kg, N/m, m, s, rad/s, Hz, J, N).
"""
from __future__ import annotations

import math

import numpy as np

from rk4h.references import closed_forms as cf
from rk4h.references import dispersion as disp
from rk4h.models import Chain, Model, Oscillator2D, Planar4

__all__ = ["errata_rows", "errata_markdown", "erratum_4_rows", "THESIS_PRINTED", "ERRATUM_4_READINGS"]

#: Numbers as printed in the thesis (quotations, not results).
THESIS_PRINTED = {
    "table_4_3": {1: (50.9198, 264.7758, 2.5898), 2: (50.9198, 264.7758, 2.5898),
                  3: (50.9202, 152.7607, 1.9671)},  # omega_1, omega_2 (labelled rad/s), f_max (Hz)
    "table_4_6": {"omega": 10.30, "T": 0.61},
    "code_03_l": 1.0,    # natural length (m) hard-coded in Code 03
    "table_4_4_l": 0.01,  # natural length (m) in Tables 4.4-4.5
}

#: Table 4.4's initial state (x, y) in m.
_TABLE_4_4_X0 = (0.005, 0.0)


def _printed_planar4_force(q, m, k, l):  # noqa: E741 - the thesis' symbol
    """x-force (N) of eqs. 2.63-2.78 as printed: the spring extension is
    ``length - l^2`` (erratum 3), the geometry otherwise exact."""
    x, y = q
    fx = 0.0
    for ax, ay in ((-l, 0.0), (l, 0.0), (0.0, -l), (0.0, l)):
        dx, dy = x - ax, y - ay
        L = math.hypot(dx, dy)
        fx -= k * (L - l * l) * dx / L
    return fx


def _row(item, quantity, thesis, corrected, note):
    return {"item": item, "quantity": quantity, "thesis": thesis, "corrected": corrected, "note": note}


def _table_4_3_rows():
    rows = []
    printed = THESIS_PRINTED["table_4_3"]
    for r in cf.thesis_table_4_3():
        if r["case"] == 2:  # same parameters as case 1 (only x0 differs): same frequencies
            continue
        w1p, w2p, fp = printed[r["case"]]
        for name, p, w in (("omega_1", w1p, r["omega_1"]), ("omega_2", w2p, r["omega_2"])):
            rows.append(_row(
                1, f"Table 4.3 case {r['case']}: {name} (rad/s)", p, w,
                f"the printed value is {name}^2 = {w * w:.4f} rad^2/s^2 (eq. 2.28); "
                f"eigenproblem: {r[name + '_eig']:.4f} rad/s"))
        rows.append(_row(
            1, f"Table 4.3 case {r['case']}: f_max (Hz)", fp, r["f_max"],
            "f_max = omega_2 / (2 pi); printed correctly"))
    return rows


def errata_rows(with_wavepacket: bool = False) -> list[dict]:
    """The errata table, one dict per corrected quantity.

    Parameters
    ----------
    with_wavepacket : bool
        Also integrate a wave packet with RK4 (about 0.3 s) and quote its
        measured group velocity in item 7's note.

    Returns
    -------
    list of dict
        Keys ``item`` (int, the numbering of docs/scenes.md's errata list), ``quantity`` (str, with
        units), ``thesis`` (float or str), ``corrected`` (float or str),
        ``note`` (str).
    """
    rows = _table_4_3_rows()

    # 2. eq. 2.2's potential: k3 x3^2 -> k3 x2^2 (there is no x3 in the 2-DOF system).
    case1 = cf.TABLE_4_3_CASES[0]
    chain = Chain([case1["m1"], case1["m2"]], [case1["k1"], case1["k2"], case1["k3"]])
    V0 = 1e3 * float(chain.potential(np.array(case1["x0"])))
    rows.append(_row(
        2, "Table 4.1 initial potential energy V(x0) (mJ)", "k1 x^2/2 + k2 (x2 - x1)^2/2 + k3 x3^2/2",
        V0, "eq. 2.2's last term is k3 x2^2 / 2 (x3 does not exist); corrected value from "
            "the chain model's potential at x0 = (0.005, 0.005) m"))

    # 3. eqs. 2.63-2.78: extension length - l^2 -> length - l (Table 4.4's state).
    m, k, l_tab = 0.815, 41.5, THESIS_PRINTED["table_4_4_l"]
    exact = Planar4(m, k, l_tab)
    fx_exact = float(exact.force(np.array(_TABLE_4_4_X0))[0])
    fx_printed = _printed_planar4_force(_TABLE_4_4_X0, m, k, l_tab)
    rows.append(_row(
        3, "planar4 force F_x (N) at Table 4.4's x = 0.005 m, y = 0, l = 0.01 m", fx_printed, fx_exact,
        "thesis column: eqs. 2.63-2.78 as printed (extension sqrt(...) - l^2), evaluated; "
        f"corrected: extension length - l; small-oscillation -2kx = {-2 * k * _TABLE_4_4_X0[0]:.4f} N"))

    # 4. Code 03's natural length: an ASSUMPTION, not a certainty. The printed `1` of
    # dz3/dz4 is read as the digit one (l = 1 m), but the same OCR renders the letter l
    # as 1 elsewhere (the project repairs "1 = 0.01" to "l = 0.01" on that ground), so
    # it may be l = 0.01 m. Both readings are computed (run), never typed.
    rows += erratum_4_rows()

    # 5. Table 4.6: omega = sqrt(2k/m), T = 2 pi / omega.
    t46 = cf.thesis_table_4_6()
    rows.append(_row(5, "Table 4.6 omega (rad/s)", THESIS_PRINTED["table_4_6"]["omega"], t46["omega"],
                     "omega = sqrt(2k/m), m = 0.815 kg, k = 41.5 N/m (m x'' = -2kx, eqs. 2.81-2.82)"))
    rows.append(_row(5, "Table 4.6 period T (s)", THESIS_PRINTED["table_4_6"]["T"], t46["T"],
                     "T = 2 pi / omega"))

    # 6. eqs. 2.41-2.43: m x_n'' = k (x_{n-1} - 2 x_n + x_{n+1}).
    lat = disp.THESIS_LATTICE
    kp_edge = math.pi / lat["d"]
    # Printed eq. 2.42, m x_n'' = k (x_{n-1} + 2 x_n - x_{n+1}), with x_n ~ exp(i (kp n d - omega t)):
    # -m omega^2 = k (exp(-i kp d) + 2 - exp(i kp d)); at kp d = pi this is 2k, so omega^2 = -2k/m.
    w2_printed = -2.0 * lat["k"] / lat["m"]
    w2_edge = float(disp.omega(kp_edge, lat["m"], lat["k"], lat["d"])) ** 2
    rows.append(_row(
        6, "lattice omega^2 at the zone edge kp = pi/d (rad^2/s^2)", w2_printed, w2_edge,
        "thesis column: printed eq. 2.42 m x_n'' = k (x_{n-1} + 2 x_n - x_{n+1}), evaluated "
        "(omega^2 < 0: growth, not oscillation); corrected m x_n'' = k (x_{n-1} - 2 x_n + x_{n+1}) "
        "gives omega_0^2 = 4k/m (eq. 2.50)"))

    # 7. eq. 2.53: v_g = d omega / d kp (a steady wave's omega does not change in time).
    kp = 0.3 * math.pi / lat["d"]
    vg = float(disp.group_velocity(kp, lat["m"], lat["k"], lat["d"]))
    note = ("thesis column: d omega / dt, which is 0 for a wave of fixed frequency; corrected: "
            "d omega / d kp = d sqrt(k/m) cos(kp d/2) (eq. 2.54 is right)")
    if with_wavepacket:
        from rk4h.references.wavepacket import measure_group_velocity

        wp = measure_group_velocity(kp, m=lat["m"], k=lat["k"], d=lat["d"])
        note += (f"; an RK4 wave packet (N = {wp.N}, sigma = {wp.sigma / lat['d']:g} d) measures "
                 f"{wp.v_measured:.5f} m/s, its spectrum's mean v_g is {wp.v_spectral:.5f} m/s")
    rows.append(_row(7, "group velocity at kp = 0.3 pi/d (m/s), thesis lattice", 0.0, vg, note))

    # 8. abstract: omega_x = sqrt(2) omega_y, not sqrt(2 omega_y); omega_y of Table 4.6.
    ky = 2.0 * t46["k"]  # the four-spring mass: effective stiffness 2k per axis
    osc = Oscillator2D(t46["m"], kx=2.0 * ky, ky=ky)
    (w_y, w_x), _ = osc.modes()
    rows.append(_row(
        8, "anisotropic omega_x (rad/s) for omega_y = sqrt(2k/m) of Table 4.6", math.sqrt(2.0 * w_y), float(w_x),
        f"thesis column: sqrt(2 omega_y) evaluated (not even a frequency: units rad^1/2 s^-1/2); "
        f"corrected: sqrt(2) omega_y, the oscillator2d with kx = 2 ky (omega_y = {w_y:.4f} rad/s)"))
    return rows


#: Erratum 4's two readings of Code 03's printed literal `1` (natural length, m).
ERRATUM_4_READINGS = {"digit": THESIS_PRINTED["code_03_l"], "letter": THESIS_PRINTED["table_4_4_l"]}
_ASSUMPTION = ("ASSUMPTION (a reading, not a certainty): Code 03's printed `1` is read as the digit one "
               "(l = 1 m; thesis column); the same OCR renders the letter l as 1 elsewhere, so it may be "
               "l = 0.01 m as in Tables 4.4-4.5 (corrected column)")


def _y_ratio_3s(fun, y0, h=0.01, t_end=3.0) -> float:
    """``y(t_end) / y(0)`` of an RK4 run of ``fun`` from ``y0``: a function
    ``fun(t, y)`` through :func:`rk4h.solve`, a model through its compiled loop
    (:func:`rk4h.fast.solve_model`, the numbers of ``rk4h.solve(model.rhs, ...)``)."""
    import rk4h
    from rk4h import fast

    n = int(round(t_end / h))
    y0 = np.asarray(y0, float)
    if isinstance(fun, Model):
        res = fast.solve_model(fun, (0.0, t_end), y0, n_steps=n, method="rk4")
    else:
        res = rk4h.solve(fun, (0.0, t_end), y0, n_steps=n, method="rk4")
    return float(res.y[1, -1] / y0[1]) if res.success else float("nan")


def erratum_4_rows() -> list[dict]:
    """Erratum 4 under both readings of Code 03's literal `1` (l = 1 m or l = 0.01 m).

    Three rows, each with the digit reading (l = 1 m) in ``thesis`` and the
    letter reading (l = 0.01 m) in ``corrected``, computed here: the x-force
    at Table 4.4's state; ``y(3 s) / y(0)`` on Table 4.5's state (x0 = 5 mm,
    y0 = 30 mm) of Code 03 as printed (its dz4 bracket kept; RK4, h = 0.01 s,
    the Python transcription that tests/test_thesis_code.py checks against
    the Octave run); and the same with the physics' equations (the planar4
    model, dz4 repaired).
    """
    from rk4h.references.thesis_code import printed_code03_rhs

    m, k = 0.815, 41.5
    l1, l2 = ERRATUM_4_READINGS["digit"], ERRATUM_4_READINGS["letter"]
    x = _TABLE_4_4_X0[0]
    f1, f2 = (float(Planar4(m, k, L).force(np.array(_TABLE_4_4_X0))[0]) for L in (l1, l2))
    y45 = np.array([0.005, 0.03, 0.0, 0.0])
    printed = [_y_ratio_3s(printed_code03_rhs(m, k, L), y45) for L in (l1, l2)]
    physics = [_y_ratio_3s(Planar4(m, k, L), y45) for L in (l1, l2)]
    return [
        _row(4, "planar4 force F_x (N) at x = 0.005 m, y = 0: l = 1 m vs l = 0.01 m", f1, f2,
             f"{_ASSUMPTION}. With l = 1 m the amplitude is x/l = {x / l1:g} and the motion is linear "
             f"({f1 / (-2 * k * x):.6f} x -2kx); with l = 0.01 m x/l = {x / l2:g} and the force is "
             f"{f2 / (-2 * k * x):.4f} x -2kx"),
        _row(4, "Code 03 as printed: y(3 s) / y(0) on Table 4.5's state (RK4, h = 0.01 s): l = 1 m vs l = 0.01 m",
             printed[0], printed[1],
             f"{_ASSUMPTION}. The printed dz4 (w on its first term only) grows from y0 = 0.03 m when l = 1 m "
             f"({printed[0]:.4g}); read as l = 0.01 m the same program gives {printed[1]:.4g}: the reading "
             f"decides this number"),
        _row(4, "planar4 (dz4 repaired): y(3 s) / y(0) on Table 4.5's state (RK4, h = 0.01 s): l = 1 m vs "
                "l = 0.01 m", physics[0], physics[1],
             f"{_ASSUMPTION}. The physics' equations under each reading: {physics[0]:.4g} (l = 1 m, y0 = 0.03 l) "
             f"and {physics[1]:.4g} (l = 0.01 m, y0 = 3 l: beyond the anchor at (0, l))"),
    ]


def _fmt(v, digits):
    return f"{v:.{digits}f}" if isinstance(v, float) else str(v)


def errata_markdown(rows: list[dict] | None = None, digits: int = 4) -> str:
    """The rows as a Markdown table (numbers to ``digits`` decimals)."""
    rows = errata_rows() if rows is None else rows
    lines = ["| item | quantity | thesis | corrected | note |", "|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['item']} | {r['quantity']} | {_fmt(r['thesis'], digits)} | "
                     f"{_fmt(r['corrected'], digits)} | {r['note']} |")
    return "\n".join(lines) + "\n"
