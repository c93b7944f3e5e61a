"""Energy over time: growth exponents, RK4's per-step energy factor, phase errors.

The long runs use the compiled loops (rk4h.fast). Every symplectic method
of the registry (rk4h.methods.METHODS; ``energy_time.is_symplectic``)
takes part, so methods added to the registry join these checks.
"""
import math

import numpy as np
import pytest

import rk4h
import rk4h.fast
from rk4h.energy import relative_energy_error
from rk4h.methods import METHODS, RK4
from rk4h.validation import energy_study
from rk4h.validation import energy_time as et
from rk4h.validation.metrics import rk4_energy_factor

pytest.importorskip("numba")

MASSES, SPRINGS = [0.815, 3.099], [41.5, 138.0, 157.8]  # the thesis' 2-DOF chain (case 1)
H_RK4 = 0.004  # s: theta = 0.065 on the fast mode; RK4 loses ~1.7e-4 of the energy over 1e5 periods


def _chain(x0=(0.005, 0.005)):
    """The 2-DOF chain; the thesis' initial state excites almost only the slow mode."""
    m = rk4h.make_model("chain", {"masses": MASSES, "springs": SPRINGS})
    return m, m.state(list(x0))


def _symplectic():
    return [tab for tab in METHODS.values() if et.is_symplectic(tab)]


def test_growth_exponent_recovers_known_laws():
    t = np.linspace(0.0, 1e4, 20001)
    k1, t0, t1 = et.growth_exponent(t, 3e-7 * t)
    assert abs(k1 - 1.0) < 1e-9 and t1 == 1e4 and t0 == pytest.approx(1e4 / 10 ** et.FIT_DECADES)
    k2, _, _ = et.growth_exponent(t, 1e-3 * np.sin(7.0 * t) ** 2)  # bounded, oscillating
    assert abs(k2) < 0.01
    k3, _, _ = et.growth_exponent(t, 1e-9 * np.sqrt(t) * np.cos(3.0 * t))
    assert abs(k3 - 0.5) < 0.02
    assert math.isnan(et.growth_exponent(t, np.zeros_like(t))[0])  # no error: nothing to fit


def test_rk4_energy_factor_per_step_on_a_harmonic_oscillator():
    """One mass between two walls: E_{n} / E_0 = (1 - theta^6/72 + theta^8/576)^n."""
    m = rk4h.make_model("chain", {"masses": [2.0], "springs": [3.0, 5.0]})
    omega = float(m.modes()[0][0])
    y0 = m.state([0.01])
    for h in (0.05, 0.2, 0.5):
        theta = omega * h
        res = rk4h.fast.solve_model(m, (0.0, 200 * h), y0, n_steps=200, method="rk4")
        E = np.asarray(m.energy(res.y), float)
        per_step = (E[-1] / E[0]) ** (1.0 / 200)
        factor = 1 - theta ** 6 / 72 + theta ** 8 / 576
        assert float(rk4_energy_factor(theta)) == pytest.approx(factor, rel=1e-15)
        assert 1.0 - per_step == pytest.approx(1.0 - factor, rel=1e-6), (h, theta)


def test_rk4_energy_factor_per_step_in_modal_coordinates():
    """The 2-DOF chain: each mode's energy shrinks by its own factor every step."""
    from rk4h.references.exact import modal_solution

    m, y0 = _chain((0.005, -0.002))  # both modes excited
    ms = modal_solution(m, y0)
    h, n = 0.02, 500
    res = rk4h.fast.solve_model(m, (0.0, n * h), y0, n_steps=n, method="rk4")
    M = np.asarray(m.mass)[:, None]
    eta, deta = ms.phi.T @ (M * res.y[:2]), ms.phi.T @ (M * res.y[2:])
    Ej = 0.5 * (deta ** 2 + (ms.omega[:, None] * eta) ** 2)
    for j, w in enumerate(ms.omega):
        theta = w * h
        measured = 1.0 - (Ej[j, -1] / Ej[j, 0]) ** (1.0 / n)
        assert measured == pytest.approx(theta ** 6 / 72 - theta ** 8 / 576, rel=1e-6), j


def _long(periods):
    m, y0 = _chain()
    t_end = periods * et.slowest_period(m)
    out = {}
    for tab in [RK4] + _symplectic():
        h = et.equal_cost_step(tab, H_RK4)
        res, _ = et.long_run(m, y0, tab, h, t_end, et.dense_samples(m, t_end))
        assert res.success, tab.name
        assert abs(res.nfev - 4 * t_end / H_RK4) < 0.01 * res.nfev, (tab.name, res.nfev)  # equal cost
        out[tab.name] = (res, et.summary(m, y0, res.t, res.y))
    return m, y0, out


def _check_long(periods):
    m, y0, out = _long(periods)
    assert len(out) >= 3  # rk4, symplectic Euler, Stormer-Verlet at least
    for name, (res, s) in out.items():
        assert s["energy_fit_t1"] == pytest.approx(res.t[-1])
        if name == "rk4":
            assert abs(s["energy_growth_exponent"] - 1.0) < 0.1, s
        else:
            assert s["energy_growth_exponent"] < 0.1, (name, s)
    # RK4's loss over the run: every step multiplies each mode's energy by its factor.
    from rk4h.references.exact import modal_solution

    res, _ = out["rk4"]
    ms = modal_solution(m, y0)
    Ej0 = 0.5 * (ms.deta0 ** 2 + (ms.omega * ms.eta0) ** 2)
    theory = float(np.sum(Ej0 * (1.0 - rk4_energy_factor(ms.omega * res.h) ** res.n_steps)) / np.sum(Ej0))
    measured = -float(relative_energy_error(m, res.y)[-1])
    assert measured == pytest.approx(theory, rel=1e-3)
    return out


def test_energy_growth_over_1e3_periods_at_equal_cost():
    _check_long(1e3)


@pytest.mark.slow
def test_energy_growth_over_1e5_periods_at_equal_cost():
    """About 20 s: 8.8e7 RHS calls per method."""
    _check_long(1e5)


def test_growth_exponent_fails_on_rk4_if_called_bounded():
    """The check can fail: RK4's exponent is far from the symplectic bound."""
    m, y0 = _chain()
    res, _ = et.long_run(m, y0, RK4, 0.02, 1e3 * et.slowest_period(m))
    assert et.summary(m, y0, res.t, res.y)["energy_growth_exponent"] > 0.5


def test_phase_error_of_rk4_matches_its_lag_and_grows_linearly():
    from rk4h.validation.metrics import phase_lag

    m, y0 = _chain((0.005, -0.002))
    h, n = 0.01, 20000
    res = rk4h.fast.solve_model(m, (0.0, n * h), y0, n_steps=n, method="rk4", record_every=10)
    ph = et.phase_errors(m, y0, res.t, res.y)
    assert ph.shape == (2, res.t.size)
    omega = np.sort(m.modes()[0])
    lag = -n * phase_lag(RK4, omega * h)  # the computed mode lags: negative phase error
    np.testing.assert_allclose(ph[:, -1], lag, rtol=1e-4)
    s = et.summary(m, y0, res.t, res.y)
    assert abs(s["phase_growth_exponent"] - 1.0) < 0.05
    assert s["phase_error_max"] == pytest.approx(float(np.max(np.abs(lag))), rel=1e-3)


def test_a_mode_damped_to_round_off_has_no_phase_error():
    # RK4 near its stability limit (omega h up to 1.43, as lattice100 at h = 0.1)
    # damps the fast modes by orders of magnitude: their angle turns to
    # round-off, whose unwrapped walk was reported as a phase error (lattice100:
    # 236-249 rad, the run's largest lag 18.8 rad). A mode's angle counts while
    # its rounding bound stays within PHASE_RESOLUTION, and is its lag step for
    # step; the largest error is taken over the modes resolved to the end, the
    # others counted.
    from rk4h.references.exact import modal_solution
    from rk4h.validation.metrics import phase_lag

    n_m = 30
    m = rk4h.make_model("chain", {"masses": [0.815] * n_m, "springs": [41.5] * (n_m + 1)})
    y0 = m.state([0.005] + [0.0] * (n_m - 1))
    ms = modal_solution(m, y0)
    h = 1.43 / float(ms.omega.max())
    n = 1000
    res = rk4h.fast.solve_model(m, (0.0, n * h), y0, n_steps=n, method="rk4")
    ph = et.phase_errors(m, y0, res.t, res.y)
    kept = et.energetic_modes(ms)
    alive = ~np.isnan(ph)
    assert np.all(alive[:, 0]) and np.all(np.diff(alive.astype(int), axis=1) <= 0)  # once below the bar, below
    _, rounding = et.phase_angles(m, y0, res.t, res.y)
    assert np.array_equal(alive, np.logical_and.accumulate(rounding <= et.PHASE_RESOLUTION, axis=1))
    damped = ~alive[:, -1]
    assert 0 < damped.sum() < kept.sum()
    lag = phase_lag(RK4, ms.omega[kept] * h)
    steps = np.arange(n + 1)
    for k in range(kept.sum()):  # every resolved sample is on the lag
        np.testing.assert_allclose(ph[k, alive[k]], -steps[alive[k]] * lag[k], rtol=1e-6, atol=1e-9)
    s = et.summary(m, y0, res.t, res.y)
    assert s["phase_modes_unresolved"] == int(damped.sum())
    assert s["phase_error_max"] == pytest.approx(n * float(lag[~damped].max()), rel=1e-6)
    assert s["phase_error_max"] < n * float(lag.max())  # the damped modes' lag is larger, and not measured


def test_a_mode_cut_early_does_not_count_its_error_before_the_cut():
    # a fast mode near RK4's limit lags far more before it is cut than the slow
    # mode does over the whole run: the largest error is the slow mode's, and
    # the fast one is counted, not read
    from rk4h.references.exact import modal_solution
    from rk4h.validation.metrics import phase_lag

    m = rk4h.make_model("chain", {"masses": [1.0, 1.0], "springs": [1.0, 1000.0, 1.0]})
    y0 = m.state([0.005, 0.0])
    ms = modal_solution(m, y0)
    h = 1.43 / float(ms.omega.max())
    n = 1000
    res = rk4h.fast.solve_model(m, (0.0, n * h), y0, n_steps=n, method="rk4")
    ph = et.phase_errors(m, y0, res.t, res.y)
    fast_mode = int(np.argmax(ms.omega))
    assert ph.shape[0] == 2 and np.isnan(ph[fast_mode, -1]) and not np.isnan(ph[1 - fast_mode]).any()
    s = et.summary(m, y0, res.t, res.y)
    slow_lag = n * float(phase_lag(RK4, ms.omega[1 - fast_mode] * h))
    assert s["phase_modes_unresolved"] == 1
    assert s["phase_error_max"] == pytest.approx(slow_lag, rel=1e-6)
    assert np.nanmax(np.abs(ph[fast_mode])) > 100 * s["phase_error_max"]  # read before its cut, not counted


def test_no_error_and_nonlinear_model_give_nan():
    m = rk4h.make_model("chain", {"masses": [1.0, 1.0], "springs": [1.0, 1.0, 1.0]})
    t = np.linspace(0, 1, 5)
    s = et.summary(m, m.state([0.1, 0.0]), t, np.tile(m.state([0.1, 0.0])[:, None], (1, 5)))
    assert math.isnan(s["energy_growth_exponent"])  # a constant state: no error to fit
    assert et.phase_errors(type("M", (), {"linear": False})(), None, t, None).shape == (0, 5)
    fput = rk4h.make_model("chain", {"masses": [1.0, 1.0], "springs": [1.0, 1.0, 1.0], "beta": 1.0})
    res = rk4h.solve(fput.rhs, (0.0, 1.0), fput.state([0.1, 0.0]), h=0.01)
    s = et.summary(fput, fput.state([0.1, 0.0]), res.t, res.y)
    assert all(math.isnan(s[c]) for c in ("phase_error_max", "phase_growth_exponent", "phase_modes_unresolved"))


def test_energy_work_precision_rows_fall_with_the_step_at_each_method_s_order():
    m, y0 = _chain((0.005, -0.002))
    tabs = [RK4] + _symplectic()
    rows = et.work_precision_rows("chain", m, y0, tabs, steps_per_period=(32, 64), horizons=(10,))
    assert len(rows) == 2 * len(tabs) and all(r["status"] == "ok" for r in rows)
    for tab in tabs:
        a, b = [r for r in rows if r["solver"] == tab.name]
        assert b["h"] == pytest.approx(a["h"] / 2) and b["nfev"] == pytest.approx(2 * a["nfev"], rel=0.01)
        order = math.log2(a["energy_drift_max"] / b["energy_drift_max"])
        # RK4 on a linear model: the loss per step ~ h^6, per unit time ~ h^5; a symplectic
        # method's bounded error ~ h^p
        expected = 5 if tab is RK4 else tab.order
        assert abs(order - expected) < 0.3, (tab.name, order)


def test_energy_study_cli_writes_table_and_figures_and_refuses_a_used_folder(tmp_path, capsys):
    pytest.importorskip("matplotlib")
    out = tmp_path / "e"
    assert energy_study.main(["thesis-2dof-case1", "--periods", "5", "--steps", "16", "--out", str(out)]) == 0
    names = sorted(p.name for p in out.iterdir())
    assert names == ["energy_work_precision.csv", "thesis_2dof_case1_energy_growth.png",
                     "thesis_2dof_case1_energy_work_precision.png"]
    import csv

    rows = list(csv.DictReader(open(out / "energy_work_precision.csv")))
    solvers = {r["solver"] for r in rows}
    assert {"rk4", "stormer-verlet", "heyoka"} <= solvers
    heyoka = sorted((r for r in rows if r["solver"] == "heyoka"), key=lambda r: -float(r["rtol"]))
    assert [float(r["rtol"]) for r in heyoka] == [1e-6, 1e-8, 1e-10, 1e-12] and all(r["status"] == "ok" for r in heyoka)
    assert float(heyoka[-1]["energy_drift_max"]) < float(heyoka[0]["energy_drift_max"])
    before = (out / "energy_work_precision.csv").read_bytes()
    assert energy_study.main(["thesis-2dof-case1", "--periods", "5", "--out", str(out)]) == 2
    assert "--out" in capsys.readouterr().err and (out / "energy_work_precision.csv").read_bytes() == before
    assert energy_study.main(["thesis-2dof-case1", "--periods", "-1", "--out", str(tmp_path / "f")]) == 2
    assert energy_study.main(["thesis-2dof-case1", "--references", "nope", "--out", str(tmp_path / "g")]) == 2


def test_energy_study_cli_reports_a_reference_over_its_step_cap(tmp_path, capsys, monkeypatch):
    """A reference whose run would need more steps than the ceiling is a
    step_cap row, a line on stderr and exit 1 (the rest is written)."""
    pytest.importorskip("matplotlib")
    monkeypatch.setattr(et, "STEP_CAP_CEILING", 1000)
    out = tmp_path / "e"
    assert energy_study.main(["thesis-2dof-case1", "--periods", "200", "--steps", "16", "--out", str(out)]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 4 and all("heyoka at rtol" in e and "above the ceiling 1e+03: not run" in e for e in err)
    import csv

    rows = list(csv.DictReader(open(out / "energy_work_precision.csv")))
    assert {r["status"] for r in rows if r["solver"] == "heyoka"} == {et.STEP_CAP_STATUS}
    assert {r["status"] for r in rows if r["solver"] == "rk4"} == {"ok"}


def _fput4():
    from rk4h.validation.execute import problem
    from rk4h.validation.scenes import load_scenes

    return problem(load_scenes(["energy-fput"])[0])


def test_exchange_period_of_fput_alpha_is_its_2_to_1_beat_and_the_measured_one():
    """The 4-mass FPUT-alpha chain with its energy in mode 1: 2 pi / (2 omega_1 -
    omega_2) = 103.9 s, from the model's linear frequencies; the energy share
    of mode 1 along a Stormer-Verlet run over 300 slowest periods oscillates
    with that period within 10 % (measured 95.3 s: the amplitude shifts the
    frequencies). Linear models and models without alpha: NaN."""
    from rk4h.validation.execute import problem
    from rk4h.validation.scenes import load_scenes

    model, y0 = _fput4()
    omega, V = model.modes()[:2]
    T_ex = et.exchange_period(model, y0)
    assert T_ex == pytest.approx(2 * math.pi / (2 * omega[0] - omega[1]), rel=1e-12)
    assert T_ex == pytest.approx(103.86, abs=0.01)
    res, _ = et.long_run(model, y0, METHODS["stormer-verlet"], 3.3 / 16, 300 * et.slowest_period(model), 30000)
    n = model.n_dof
    eta, etad = V.T @ res.y[:n], V.T @ res.y[n:]  # unit masses
    e = 0.5 * (etad ** 2 + (np.asarray(omega)[:, None] * eta) ** 2)
    share = e[0] / e.sum(axis=0)
    f = np.fft.rfftfreq(share.size, res.t[1] - res.t[0])
    spectrum = np.abs(np.fft.rfft(share - share.mean()))
    measured = 1 / f[1 + np.argmax(spectrum[1:])]
    assert measured == pytest.approx(T_ex, rel=0.10)
    for name in ("thesis-2dof-case1", "energy-henon-heiles"):
        assert math.isnan(et.exchange_period(*problem(load_scenes([name])[0])))


def test_fput_growth_law_is_not_fitted_over_a_horizon_shorter_than_the_exchange():
    from types import SimpleNamespace

    from rk4h.validation import outputs
    from rk4h.validation.measure import SceneTables
    from rk4h.validation.outputs import energy_work_precision as ewp

    model, y0 = _fput4()
    rows = et.work_precision_rows("energy-fput", model, y0, [METHODS["stormer-verlet"]], (16,), (100.0, 1000.0))
    short, long_ = rows
    assert short["status"] == "ok" and math.isnan(short["energy_growth_exponent"])
    assert short["message"].startswith("not fitted: the fit window starts at 10.17 s, before half the 2:1 "
                                       "exchange period 103.9 s")
    assert long_["energy_growth_exponent"] < ewp.BOUNDED_EXPONENT and long_["message"] == ""
    m = outputs.Measuring(scene=SimpleNamespace(name="energy-fput"), by={}, records={}, res=SceneTables("s"),
                          quick=False, draw=False)
    ewp._bounded_checks(m, [dict(r, symplectic=True) for r in rows])
    assert [c.passed for c in m.res.checks] == [True]  # 1e3 checked and bounded; 1e2 not checked, said so
    assert any("over 100 periods: bounded-energy check not made, not fitted" in f for f in m.res.findings)
