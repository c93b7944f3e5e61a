"""The thesis' own programs (Code 01-03, GNU Octave) run as command methods
and compared with rk4core and with the truth.

:func:`compare` runs every transcription in ``rk4core/thesis_code`` through
the file protocol of :mod:`rk4h.command` (11 runs of ``octave-cli``, two
at a time: about 5 s on 2 cores) and returns the rows of a ``thesis_code.csv`` table;
:func:`errata` turns the consequences of the printed code's errors into
rows of :func:`rk4h.references.errata.errata_rows`' format.

Programs and cases (``program``, ``variant``, ``case``)
-------------------------------------------------------
``code01-ode45`` printed, ``table-4.1``
    Code 01's ode45 run at Octave's default tolerances: Table 4.1's chain
    (m = 0.815, 3.099 kg; k = 41.5, 138, 157.8 N/m; x0 = 5 mm, 5 mm), the
    printed output step ``dt = 1/(20 f_max)`` = 0.01931 s and 100 steps.
``code01-euler`` printed/corrected, ``table-4.1``
    The animation listing's explicit Euler loop, printed step 0.01 s and
    horizon 1 s, from Table 4.1's state (the listing hard-codes 1 m, 1 m:
    the equations are linear, the state's size changes nothing relative).
    Printed: masses coupled through k3, k2 on the right wall; corrected: k2
    between them (Code 01's K matrix, eqs. 2.6-2.7).
``code02`` printed/corrected, ``chain10-mode2``
    The semi-implicit Euler loop: 10 masses of 0.815 kg, springs 41.5 N/m,
    both walls, started in mode 2 (mass-normalised shape, as the listing),
    printed step 0.001 s, 0.5 s (the listing reads the horizon from the
    keyboard). Printed: rows labelled ``t0 + h .. t0 + n h``
    holding the states after 0 .. n-1 steps; corrected: labelled from t0,
    one more row.
``code03`` printed/corrected, ``table-4.4``, ``table-4.5``, ``y-probe``
    The RK4 loop over 3 s with Tables 4.4-4.5's step h = 0.01 s (the
    listing's 0.001 s costs ten times the Octave time for the same
    findings), m = 0.815 kg, k = 41.5 N/m and
    Code 03's natural length l = 1 m (erratum 4: its printed ``1`` read as the
    digit one, an assumption; :func:`rk4h.references.errata.erratum_4_rows` gives
    both readings' numbers); Tables 4.4 (x0 = 5 mm) and
    4.5 (x0 = 5 mm, y0 = 30 mm) and a probe from (0, 1 um) that measures the
    y-equation near the origin. Printed: dz4 = w*T1 + T2 + T3 + T4;
    corrected: w*(T1 + T2 + T3 + T4).

Quantities (``quantity``; ``value`` from the Octave run)
-------------------------------------------------------
``diff_vs_rk4core_rel``
    max |octave - rk4core| over the outputs, positions over the largest
    |position| and velocities over the largest |velocity| of rk4core's run:
    rk4h.solve with the program's method ("euler", "symplectic-euler",
    "rk4") on the program's right-hand side (printed: a Python transcription
    of the printed equations, same operations; corrected: the harness'
    model) and the program's time labels. Expected 0; the tolerance is the
    round-off bound.
``error_vs_truth_m``
    max |q - q_truth| (m) over the outputs; the truth is the physics
    (modal superposition for the chains, heyoka in quadruple precision for
    planar4: :mod:`rk4h.references.truth`). Expected: the same for rk4core's run
    above (for ode45: none; the tolerance is then an upper bound).
``y_slope_origin_1/s2``, ``y_ratio_3s``
    (code03, y-probe) the coefficient lambda of y'' = lambda y near the
    origin, from the first RK4 step (exact for the linear equation), and
    y(3 s) / y(0). Expected: lambda from the Python transcription's
    derivative (printed: +2 1/s^2, so y grows as cosh(sqrt(2) t)) or the
    model's stiffness (corrected: -2k/m, y = y0 cos(sqrt(2k/m) t)); the
    ratio is RK4's at the same h on y'' = lambda y (the message quotes the
    exact cosh / cos).
``y_ratio_3s`` (code03, table-4.5)
    the same ratio on Table 4.5's state, where the printed equation's
    growth saturates (nonlinear); expected: rk4core's run of the printed
    equation.
``omega_1_rad/s``, ``omega_2_rad/s``
    (code01-euler) the frequencies the run produces: the one-step map G of
    the explicit Euler run is fitted to its states (least squares) and
    omega = |Im eig(G)| / h (G = I + h A exactly). Expected: sqrt(eig(K, M))
    of the stiffness matrix the listing builds (printed [k1+k3, -k3; -k3,
    k2+k3]) or of the model (corrected).
``time_shift_s``, ``diff_at_labels_rel``
    (code02) the shift s h (s = -2..2) that best aligns the run's rows
    with rk4core's states at their labels, and the relative difference at
    the labels as printed (expected: rk4core's own one-step shift).
``nfev``
    right-hand-side evaluations the driver reports (informative; expected:
    the method's count per step times the steps, none for ode45; the tolerance
    of ode45's row is inf).

``passed`` is ``|value - expected| <= tolerance`` (``value <= tolerance``
when ``expected`` is None); None when the program did not run. ``status`` is
the run's (``ok``, ``failed``, ``unavailable``) and ``message`` says what the
row measures, or why it has no value.
"""
from __future__ import annotations

import math
from concurrent.futures import ThreadPoolExecutor

import numpy as np
from scipy.linalg import eigh

import rk4h
from rk4h.models import Chain, Planar4

from .exact import modal_solution
from .solvers.base import Status
from .solvers.command import run_command_method

__all__ = ["compare", "errata", "CASES", "OCTAVE_FLAGS", "argv_for", "printed_code01_rhs", "printed_code03_rhs",
           "COLUMNS"]

COLUMNS = ("program", "variant", "case", "quantity", "value", "expected", "tolerance", "passed", "status",
           "message")
#: Octave's flags for the drivers (no history file: Octave 7 then prints a
#: spurious "error: ignoring const execution_exception&" at exit).
OCTAVE_FLAGS = ("--no-history", "--norc", "--quiet")
_DRIVER = {"code01-ode45": "run_code01_ode45.m", "code01-euler": "run_code01_euler.m", "code02": "run_code02.m",
           "code03": "run_code03.m"}
_METHOD = {"code01-euler": "euler", "code02": "symplectic-euler", "code03": "rk4"}
#: Round-off bounds: relative (to the amplitude) difference from rk4core on
#: the same equations. Measured on 2026-11-24 (Octave 7.3.0, numpy, x86-64):
#: code01-euler 0 (bit-identical) printed / 9.9e-16 corrected; code02
#: 4.7e-16; code03 1.2e-15 .. 7.9e-15. Set about ten times above.
ROUNDOFF = {"code01-euler": 1e-14, "code02": 1e-14, "code03": 1e-13}
#: The corrected y-probe compares two different spring formulas at 1e-6 l
#: from the origin, where the extension L - l cancels (eps l / y0 = 2.2e-10
#: per evaluation): measured 2.4e-14 (9.3e-13 with 3000 steps of 0.001 s).
ROUNDOFF_PROBE = 1e-11
#: Upper bound (m) on Code 01's ode45 error at Octave's default tolerances
#: (RelTol 1e-3, AbsTol 1e-6) on the 5 mm amplitude; measured 8.0e-6 m.
ODE45_BOUND = 2e-5

_TABLE_41 = {"masses": [0.815, 3.099], "springs": [41.5, 138.0, 157.8]}
_PLANAR = {"m": 0.815, "k": 41.5, "l": 1.0}


def _chain10_mode2():
    model = Chain([0.815] * 10, [41.5] * 11)
    phi = model.modes()[1]
    return model, np.concatenate([phi[:, 1], np.zeros(10)])


def _cases():
    """(program, variant, case) -> (model, y0, h, n_steps)."""
    c41 = Chain(**_TABLE_41)
    y41 = np.array([0.005, 0.005, 0.0, 0.0])
    w_max = float(np.max(c41.modes()[0]))
    dt = 1.0 / (w_max / (2.0 * math.pi) * 20.0)  # Code 01: dt = 1/(max_freq*20)
    c10, y10 = _chain10_mode2()
    p4 = Planar4(**_PLANAR)
    out = {("code01-ode45", "printed", "table-4.1"): (c41, y41, dt, 100)}
    for v in ("printed", "corrected"):
        out[("code01-euler", v, "table-4.1")] = (c41, y41, 0.01, 100)
        out[("code02", v, "chain10-mode2")] = (c10, y10, 0.001, 500)
        out[("code03", v, "table-4.4")] = (p4, np.array([0.005, 0.0, 0.0, 0.0]), 0.01, 300)
        out[("code03", v, "table-4.5")] = (p4, np.array([0.005, 0.03, 0.0, 0.0]), 0.01, 300)
        out[("code03", v, "y-probe")] = (p4, np.array([0.0, 1e-6, 0.0, 0.0]), 0.01, 300)
    return out


#: The comparison cases, built on first use.
CASES = None


def argv_for(program: str, variant: str, octave: str = "octave-cli") -> list[str]:
    """The command line of a thesis program's driver."""
    return [octave, *OCTAVE_FLAGS, "{thesis_code}/" + _DRIVER[program], "{problem}", "{trajectory}", variant]


# -- the printed equations, transcribed to Python (same operations) ------------
def printed_code01_rhs(m1, m2, k1, k2, k3):
    """``f(t, y)`` of Code 01's animation listing as printed: a1 = (k3*(x2-x1)
    + -k1*x1)/m1, a2 = (-(k2+k3)*x2 + k3*x1)/m2 (masses coupled through k3)."""
    def f(t, y):
        x1, x2, v1, v2 = y
        return np.array([v1, v2, (k3 * (x2 - x1) + -k1 * x1) / m1, (-(k2 + k3) * x2 + k3 * x1) / m2])
    return f


def printed_code01_K(k1, k2, k3) -> np.ndarray:
    """The stiffness matrix the printed accelerations of Code 01's animation imply."""
    return np.array([[k1 + k3, -k3], [-k3, k2 + k3]])


def _dz3(z1, z2, w, L=1.0):
    """Code 03's dz3 as printed; ``L`` is its literal ``1`` (the natural length
    and anchor distance, m: erratum 4 reads it as the digit one)."""
    sq = math.sqrt
    return w * ((((z1 + L) * (sq((z1 + L) ** 2 + z2 ** 2) - L)) / (sq((z1 + L) ** 2 + z2 ** 2)))
                + ((z1 * (sq((z2 + L) ** 2 + z1 ** 2) - L)) / (sq((z2 + L) ** 2 + z1 ** 2)))
                - (((L - z1) * (sq((L - z1) ** 2 + z2 ** 2) - L)) / (sq((L - z1) ** 2 + z2 ** 2)))
                + ((z1 * (sq((L - z2) ** 2 + z1 ** 2) - L)) / (sq((L - z2) ** 2 + z1 ** 2))))


def _dz4_printed(z1, z2, w, L=1.0):
    """Code 03's dz4 as printed (``w`` multiplies the first term only); ``L`` as in :func:`_dz3`."""
    sq = math.sqrt
    return (w * (((z2 * (sq((z1 + L) ** 2 + z2 ** 2) - L))) / (sq((z1 + L) ** 2 + z2 ** 2)))
            + ((z2 * (sq((L - z1) ** 2 + z2 ** 2) - L)) / (sq((L - z1) ** 2 + z2 ** 2)))
            + (((z2 + L) * (sq(z1 ** 2 + (z2 + L) ** 2) - L)) / (sq(z1 ** 2 + (z2 + L) ** 2)))
            + (((z2 - L) * (sq(z1 ** 2 + (L - z2) ** 2) - L)) / (sq(z1 ** 2 + (L - z2) ** 2))))


def printed_code03_rhs(m, k, l=1.0):  # noqa: E741 - the thesis' symbol
    """``f(t, y)`` of Code 03 as printed: dz3, dz4 with the natural length ``l``
    (default the printed literal 1, m; erratum 4) and dz4 = w*T1 + T2 + T3 + T4
    (w = -k/m). ``l = 0.01`` is the other reading of that literal: the letter
    l of Tables 4.4-4.5."""
    w = (-k) / m
    L = float(l)

    def f(t, y):
        z1, z2, z3, z4 = (float(v) for v in y)
        return np.array([z3, z4, _dz3(z1, z2, w, L), _dz4_printed(z1, z2, w, L)])
    return f


# -- helpers ---------------------------------------------------------------------
def _rel_diff(a, b, n):
    """max |a - b| over positions / max |b_q|, and over velocities / max |b_v|."""
    out = 0.0
    for part in (slice(0, n), slice(n, 2 * n)):
        scale = float(np.max(np.abs(b[part])))
        d = float(np.max(np.abs(a[part] - b[part])))
        out = max(out, d / scale if scale > 0 else d)
    return out


def _pos_err(y, truth, n):
    return float(np.max(np.abs(y[:n] - truth[:n])))


def _truth(model, y0, t):
    if model.linear:
        return modal_solution(model, y0)(t)
    from .truth import reference_solution

    return reference_solution(model, y0, t).y


def _twin(program, variant, model, y0, h, n):
    """rk4core's run of what the program computes: (labels, states)."""
    t_grid = h * np.arange(n + 1)
    p = model.params()
    if program == "code01-euler" and variant == "printed":
        m1, m2 = p["masses"]
        fun = printed_code01_rhs(m1, m2, *p["springs"])
    elif program == "code03" and variant == "printed":
        fun = printed_code03_rhs(p["m"], p["k"])
    else:
        fun = model.rhs
    res = rk4h.solve(fun, (0.0, n * h), y0, n_steps=n, method=_METHOD[program])
    y = res.y
    if program == "code02" and variant == "printed":  # rows = states after 0..n-1 steps, labelled h..n h
        return t_grid[1:], y[:, :-1], y
    return t_grid, y, y


def _slope_from_first_step(y0, y1, v1, h):
    """lambda of y'' = lambda y from one RK4 step from (y0, 0): v1 = y0 (h lam +
    h^3 lam^2 / 6) exactly for the linear equation."""
    a, b, c = h ** 3 / 6.0, h, -v1 / y0
    return (-b + math.sqrt(b * b - 4 * a * c)) / (2 * a)


def _rk4_linear_ratio(lam, h, n):
    """y_n / y_0 of classical RK4 on y' = v, v' = lam y from (y0, 0), n steps."""
    A = np.array([[0.0, 1.0], [lam, 0.0]]) * h
    M = np.eye(2) + A + A @ A / 2 + A @ A @ A / 6 + A @ A @ A @ A / 24
    return float(np.linalg.matrix_power(M, n)[0, 0])


def _fd_slope_printed(m, k, eps=1e-6):
    w = (-k) / m
    return (_dz4_printed(0.0, eps, w) - _dz4_printed(0.0, -eps, w)) / (2 * eps)


def _euler_frequencies(y, h):
    """Angular frequencies of the linear one-step map fitted to an explicit
    Euler run's states (columns of ``y``): |Im eig(G)| / h, ascending, one per
    conjugate pair."""
    G = np.linalg.lstsq(y[:, :-1].T, y[:, 1:].T, rcond=None)[0].T
    lam = (np.linalg.eigvals(G) - 1.0) / h
    w = np.sort(np.abs(lam.imag))
    return w[::2]


def _row(program, variant, case, quantity, value, expected, tolerance, status, message):
    if status != "ok" or value is None or not np.isfinite(value):
        passed = None
    elif expected is None:
        passed = bool(value <= tolerance)
    else:
        passed = bool(abs(value - expected) <= tolerance)
    f = (lambda v: None if v is None else float(v))
    return {"program": program, "variant": variant, "case": case, "quantity": quantity,
            "value": f(value) if status == "ok" else None, "expected": f(expected), "tolerance": f(tolerance),
            "passed": passed, "status": status, "message": message}


# -- the comparison ---------------------------------------------------------------
def _run(key, case, octave, timeout):
    program, variant, _ = key
    model, y0, h, n = case
    t = h * np.arange(n + 1)
    t0 = None
    if program == "code02" and variant == "printed":
        t, t0 = t[1:], 0.0  # its rows are labelled h .. n h
    return run_command_method(f"{program}-{variant}", argv_for(program, variant, octave), model, y0, t, h,
                              t0=t0, timeout=timeout)


def compare(octave: str = "octave-cli", *, jobs: int = 2, timeout: float = 300.0) -> list[dict]:
    """Run the thesis' programs and compare them (see the module docstring).

    Parameters
    ----------
    octave : str
        The Octave executable (name on PATH or path).
    jobs : int
        Programs run at once.
    timeout : float
        Seconds per program.

    Returns
    -------
    list of dict
        Keys :data:`COLUMNS`. When ``octave`` is not installed every row has
        status "unavailable", no value and the message naming it; nothing
        raises.
    """
    global CASES
    if CASES is None:
        CASES = _cases()
    keys = list(CASES)
    with ThreadPoolExecutor(max_workers=max(1, int(jobs))) as pool:
        runs = dict(zip(keys, pool.map(lambda k: _run(k, CASES[k], octave, timeout), keys)))
    rows = []
    for key in keys:
        rows.extend(_rows_of(key, CASES[key], runs[key], runs))
    return rows


def _rows_of(key, case, run, runs):
    program, variant, cname = key
    model, y0, h, n = case
    nd = model.n_dof
    status = run.status.value if isinstance(run.status, Status) else str(run.status)
    why = "" if status == "ok" else run.message
    y = run.y
    R = lambda q, value, expected, tol, msg: _row(program, variant, cname, q, value, expected, tol,  # noqa: E731
                                                  status, msg if status == "ok" else why)
    rows = []
    t_out = run.t
    truth = _truth(model, y0, t_out)
    if program == "code01-ode45":
        err = _pos_err(y, truth, nd) if status == "ok" else None
        rows.append(R("error_vs_truth_m", err, None, ODE45_BOUND,
                      f"max |x - x_exact| (m) of Octave's ode45 at its default RelTol 1e-3, AbsTol 1e-6 on a "
                      f"5 mm amplitude, h = {h:.5g} s (Code 01's dt = 1/(20 f_max)), 100 outputs; bound "
                      f"{ODE45_BOUND:g} m"))
        rows.append(R("nfev", run.nfev if status == "ok" else None, None, math.inf,
                      "calls of testcode (the reconstructed y' = CC*y) by ode45"))
        return rows
    labels, twin, twin_full = _twin(program, variant, model, y0, h, n)
    bound = ROUNDOFF_PROBE if (cname == "y-probe" and variant == "corrected") else ROUNDOFF[program]
    same = "the Python transcription of the printed equations" if variant == "printed" else \
        f"the harness' {model.name} model"
    d = _rel_diff(y, twin, nd) if status == "ok" else None
    rows.append(R("diff_vs_rk4core_rel", d, 0.0, bound,
                  f"max |octave - rk4core| / amplitude; rk4h.solve(method={_METHOD[program]!r}) on {same}, "
                  f"h = {h:g} s, {n} steps"))
    twin_err = _pos_err(twin, _truth(model, y0, labels), nd)
    amp = float(np.max(np.abs(twin[:nd])))
    rows.append(R("error_vs_truth_m", _pos_err(y, truth, nd) if status == "ok" else None, twin_err,
                  bound * amp + 1e-15,
                  f"max |q - q_truth| (m) at the run's time labels; the truth is the physics "
                  f"({'modal superposition' if model.linear else 'heyoka real128'}); expected: rk4core's "
                  f"run of the same equations"))
    nfev_per_step = {"code01-euler": 1, "code02": 1, "code03": 4}[program]
    steps = n - 1 if (program == "code02" and variant == "printed") else n
    extra_eval = 1 if program == "code01-euler" else 0  # the listing evaluates a at the last state too
    rows.append(R("nfev", run.nfev if status == "ok" else None, nfev_per_step * steps + extra_eval, 0.0,
                  "right-hand-side evaluations the driver reports (code03: 4 per step for the 4 component "
                  "functions' stages counted as state evaluations)"))
    if program == "code01-euler":
        p = model.params()
        if variant == "printed":
            K = printed_code01_K(*p["springs"])
            what = "the listing's K = [k1+k3, -k3; -k3, k2+k3]"
        else:
            K = model.stiffness_matrix()
            what = "the chain's K = [k1+k2, -k2; -k2, k2+k3] (eqs. 2.6-2.7)"
        w_exp = np.sqrt(eigh(K, np.diag(model.mass), eigvals_only=True))
        w_run = _euler_frequencies(y, h) if status == "ok" else [None, None]
        for i in range(2):
            rows.append(R(f"omega_{i + 1}_rad/s", w_run[i], w_exp[i], 1e-9 * w_exp[i],
                          f"|Im eig(G)| / h of the one-step map G fitted to the run; expected sqrt(eig(K, M)) "
                          f"of {what}"))
    if program == "code02" and variant == "printed":
        _, ref = _twin(program, "corrected", model, y0, h, n)[1:]
        # the printed rows j = 1..n are labelled j h; compare them with rk4core's state at j - s steps
        shifts = {}
        if status == "ok":
            for s in range(-2, 3):
                j = np.arange(1, n + 1)
                ok = (j - s >= 0) & (j - s <= n)
                shifts[s] = _rel_diff(y[:, ok], ref[:, j[ok] - s], nd)
            s_best = min(shifts, key=shifts.get)
        own = _rel_diff(ref[:, :-1], ref[:, 1:], nd)
        rows.append(R("time_shift_s", s_best * h if status == "ok" else None, h, 1e-12 * h,
                      f"the shift s h (s = -2..2) aligning the rows with rk4core's states: the row labelled "
                      f"i h holds the state after i - 1 steps (h = {h:g} s)"))
        rows.append(R("diff_at_labels_rel", shifts.get(0), own, bound,
                      "max |octave at its labels - rk4core at the same times| / amplitude: the one-step "
                      "label shift; expected: rk4core's own states one step apart"))
    if program == "code03" and cname == "y-probe":
        p = model.params()
        i3 = int(round(3.0 / h))
        if variant == "printed":
            lam = _fd_slope_printed(p["m"], p["k"])
            how = (f"printed dz4: d(dz4)/dy at the origin by central differences of its Python "
                   f"transcription = {lam:.6f} 1/s^2")
            exact = f"cosh(sqrt(lambda) 3 s) = {math.cosh(math.sqrt(lam) * 3.0):.6f}"
        else:
            lam = -float(model.stiffness_matrix()[1, 1]) / float(model.mass[1])
            how = f"-2k/m from the model's stiffness = {lam:.4f} 1/s^2"
            exact = f"cos(sqrt(2k/m) 3 s) = {math.cos(math.sqrt(-lam) * 3.0):.6f}"
        ratio = _rk4_linear_ratio(lam, h, i3)
        slope = _slope_from_first_step(y0[1], y[1, 1], y[3, 1], h) if status == "ok" else None
        rows.append(R("y_slope_origin_1/s2", slope, lam, 1e-8 * abs(lam),
                      f"lambda of y'' = lambda y from the run's first RK4 step from y0 = 1e-6 m; expected: {how}"))
        rows.append(R("y_ratio_3s", y[1, i3] / y0[1] if status == "ok" else None, ratio,
                      1e-7 * max(1.0, abs(ratio)),
                      f"y(3 s) / y(0) from y0 = 1e-6 m (linear regime); expected: RK4 at h = {h:g} s on "
                      f"y'' = lambda y, {how} (exactly: {exact})"))
    if program == "code03" and cname == "table-4.5":
        i3 = int(round(3.0 / h))
        rows.append(R("y_ratio_3s", y[1, i3] / y0[1] if status == "ok" else None, twin[1, i3] / y0[1],
                      bound * max(1.0, abs(twin[1, i3] / y0[1])),
                      "y(3 s) / y(0) on Table 4.5's state (y0 = 0.03 m = 0.03 l); expected: rk4core's run of "
                      "the same equations"))
    return rows


def _value(rows, program, variant, case, quantity):
    for r in rows:
        if (r["program"], r["variant"], r["case"], r["quantity"]) == (program, variant, case, quantity):
            return r["value"]
    return None


def _scaled(x, factor):
    return x * factor if isinstance(x, float) else x


def _rk4_error_code01_grid() -> float:
    """max |x - x_exact| (m) of rk4core's RK4 on Code 01's ode45 case, step = its dt."""
    global CASES
    if CASES is None:
        CASES = _cases()
    model, y0, h, n = CASES[("code01-ode45", "printed", "table-4.1")]
    res = rk4h.solve(model.rhs, (0.0, n * h), y0, n_steps=n, method="rk4")
    return _pos_err(res.y, modal_solution(model, y0)(res.t), model.n_dof)


def errata(rows: list[dict] | None = None, octave: str = "octave-cli") -> list[dict]:
    """The printed code's errors as computed errata, in the format of
    :func:`rk4h.references.errata.errata_rows` (keys ``item``, ``quantity``,
    ``thesis``, ``corrected``, ``note``): ``thesis`` is what the printed
    program's run gives, ``corrected`` what the corrected run gives, both
    measured here (``rows``: :func:`compare`'s, run when not given). A value
    that could not be measured is the string "not run" (the note says why).
    """
    rows = compare(octave) if rows is None else rows

    def v(*key):
        x = _value(rows, *key)
        return "not run" if x is None else x

    missing = next((r["message"] for r in rows if r["status"] != "ok"), "")
    tail = f" (not run: {missing})" if missing else ""
    m, k = _PLANAR["m"], _PLANAR["k"]
    out = [
        {"item": "code03-dz4", "quantity": "Code 03: coefficient lambda of y'' = lambda y at the origin (1/s^2)",
         "thesis": v("code03", "printed", "y-probe", "y_slope_origin_1/s2"),
         "corrected": v("code03", "corrected", "y-probe", "y_slope_origin_1/s2"),
         "note": f"dz4 as printed closes w*( after the first of its four spring terms: dz4 = w*T1 + T2 + T3 + T4 "
                 f"instead of w*(T1 + T2 + T3 + T4); measured from the first RK4 step of each run from "
                 f"y0 = 1e-6 m (physics: -2k/m = {-2 * k / m:.4f}){tail}"},
        {"item": "code03-dz4", "quantity": "Code 03: y(3 s) / y(0) from y0 = 1e-6 m",
         "thesis": v("code03", "printed", "y-probe", "y_ratio_3s"),
         "corrected": v("code03", "corrected", "y-probe", "y_ratio_3s"),
         "note": f"printed: exponential growth like cosh(sqrt(2) t) (cosh(3 sqrt 2) = {math.cosh(3 * math.sqrt(2)):.4f}); "
                 f"corrected: oscillation cos(sqrt(2k/m) t){tail}"},
        {"item": "code03-dz4", "quantity": "Code 03: y(3 s) / y(0) on Table 4.5's state (y0 = 0.03 m, l = 1 m)",
         "thesis": v("code03", "printed", "table-4.5", "y_ratio_3s"),
         "corrected": v("code03", "corrected", "table-4.5", "y_ratio_3s"),
         "note": f"the printed equation's growth saturates at this amplitude (nonlinear springs){tail}"},
        {"item": "code01-euler", "quantity": "Code 01 animation: omega_1 (rad/s), Table 4.1",
         "thesis": v("code01-euler", "printed", "table-4.1", "omega_1_rad/s"),
         "corrected": v("code01-euler", "corrected", "table-4.1", "omega_1_rad/s"),
         "note": f"the listing couples the masses through k3 and puts k2 on the right wall (K = [k1+k3, -k3; "
                 f"-k3, k2+k3]); Code 01's K and eqs. 2.6-2.7 put k2 between them; measured from the explicit "
                 f"Euler runs (one-step map){tail}"},
        {"item": "code01-euler", "quantity": "Code 01 animation: omega_2 (rad/s), Table 4.1",
         "thesis": v("code01-euler", "printed", "table-4.1", "omega_2_rad/s"),
         "corrected": v("code01-euler", "corrected", "table-4.1", "omega_2_rad/s"),
         "note": f"as omega_1{tail}"},
        {"item": "code02", "quantity": "Code 02: time label minus the state's time (s), h = 0.001 s",
         "thesis": v("code02", "printed", "chain10-mode2", "time_shift_s"), "corrected": 0.0,
         "note": f"tVector = tStep.*(1:iterations) labels the state after i-1 steps as i h: every state is "
                 f"plotted one step late; measured by aligning the run with rk4core's states{tail}"},
        {"item": "code01-ode45", "quantity": "Code 01 ode45 (default tolerances): max |x - x_exact| (um), "
                                            "Table 4.1, 5 mm amplitude",
         "thesis": _scaled(v("code01-ode45", "printed", "table-4.1", "error_vs_truth_m"), 1e6),
         "corrected": 1e6 * _rk4_error_code01_grid(),
         "note": f"not an error in the code: Octave's ode45 at its defaults (RelTol 1e-3, AbsTol 1e-6) on the "
                 f"printed output grid dt = 1/(20 f_max), 100 outputs; corrected column: classical RK4 "
                 f"(rk4core) with that dt as its step, for scale{tail}"},
    ]
    return out
