"""Issue 6: numerical stability at the extremes (rk4h.validation.stability).

Expected values come from the stability function of each method on y' = J y
with eigenvalues +-i omega (theta = omega h):
RK4 R(z) = 1 + z + z^2/2 + z^3/6 + z^4/24, |R(i theta)| <= 1 iff theta <= 2 sqrt 2;
explicit Euler |1 + i theta| = sqrt(1 + theta^2); symplectic Euler: trace 2 - theta^2,
determinant 1, so unimodular eigenvalues iff theta <= 2.
"""
import math
import warnings

import numpy as np
import pytest

import rk4h
from rk4h.validation.stability import boundary as B
from rk4h.validation.stability import geometry as G
from rk4h.validation.stability import large_n as LN
from rk4h.validation.stability import long_horizon as LH
from rk4h.validation.stability import mass_ratio as MR
from rk4h.validation.stability import validate_params

TWO_DOF = ("chain", {"masses": [0.815, 3.099], "springs": [41.5, 138.0, 157.8]})
LINEAR_SCENES = {
    "2dof-case1": TWO_DOF,
    "chain5-free": ("chain", {"masses": [1.0, 2.0, 0.5, 1.0, 3.0], "springs": [1.0, 5.0, 2.0, 1e3],
                              "walls": "none"}),
    "oscillator2d": ("oscillator2d", {"m": 0.815, "kx": 41.5, "ky": 83.0}),
    "planar4-linear": ("planar4", {"m": 0.815, "k": 41.5, "l": 0.01, "linear": True}),
}
PLANAR = {"m": 0.815, "k": 41.5, "l": 0.01}


def _model(key):
    return rk4h.make_model(*LINEAR_SCENES[key])


@pytest.mark.parametrize("scene", sorted(LINEAR_SCENES))
@pytest.mark.parametrize("method, factor", [("rk4", 2 * math.sqrt(2)), ("symplectic-euler", 2.0)])
def test_largest_stable_step_within_half_percent(scene, method, factor):
    model = _model(scene)
    omega_max = float(model.modes()[0][-1])
    h_star, _ = B.largest_stable_step(model, method, rtol=1e-4)
    assert h_star == pytest.approx(factor / omega_max, rel=0.005)


@pytest.mark.parametrize("scene", sorted(LINEAR_SCENES))
def test_explicit_euler_has_no_stable_step(scene):
    h_star, _ = B.largest_stable_step(_model(scene), "euler")
    assert h_star == 0.0


@pytest.mark.parametrize("theta", [1e-3, 0.1, 0.5, 1.0, 2.0])
def test_explicit_euler_growth_measured_from_run(theta):
    model = rk4h.make_model(*TWO_DOF)
    g, res = B.measured_growth(model, "euler", theta, n_steps=400)
    assert res.success
    # growth per step sqrt(1 + theta^2): compare the excess g - 1 (small at small theta)
    assert (g - 1) == pytest.approx(math.sqrt(1 + theta**2) - 1, rel=1e-6)


@pytest.mark.parametrize("method", ["rk4", "symplectic-euler"])
@pytest.mark.parametrize("theta", [0.5, 1.5, 2.5, 3.2])
def test_measured_growth_follows_theory(method, theta):
    model = rk4h.make_model(*TWO_DOF)
    g, _ = B.measured_growth(model, method, theta, n_steps=2000)
    # symplectic Euler's amplitude oscillates (non-normal mode map): the fit over
    # the run averages it, so only ~1e-3 agreement is expected there.
    rel = 1e-8 if method == "rk4" else 2e-3
    assert g == pytest.approx(float(B.theory_growth(method, theta)), rel=rel)


def test_rk4_growth_theory_is_the_stability_polynomial():
    theta = np.array([0.3, 1.0, 2.0, 2 * math.sqrt(2), 3.0])
    # |R(i theta)|^2 = 1 - theta^6/72 + theta^8/576
    assert np.allclose(B.theory_growth("rk4", theta) ** 2, 1 - theta**6 / 72 + theta**8 / 576, rtol=1e-13)


@pytest.mark.parametrize("method, factor, n", [("rk4", 1.2, 3000), ("euler", None, 6000)])
def test_blowup_is_a_status_with_a_time_and_no_warning(method, factor, n):
    model = rk4h.make_model(*TWO_DOF)
    w = float(model.modes()[0][-1])
    h = factor * B.theory_boundary("rk4", w) if factor else 1.0 / w
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        res = B.blowup_run(model, method, h, n)
    assert res.status == -1 and not res.success
    # the top-mode amplitude (order 1 to omega) grows by g per step: overflow of
    # float64 (max 1.8e308) after about log(1.8e308)/log(g) steps
    g = float(B.theory_growth(method, h * w))
    assert res.t_fail / h == pytest.approx(math.log(np.finfo(float).max) / math.log(g), rel=0.05)
    assert f"{res.t_fail:.6g}" in res.message


@pytest.mark.parametrize("theta", [0.1, 0.25, 0.5])
def test_rk4_energy_loss_and_phase_lag_per_step(theta):
    model = rk4h.make_model(*TWO_DOF)
    w = model.modes()[0]
    d = LH.measure_drift_and_phase(model, model.state([0.005, 0.005]), theta / w[-1], 1500)
    th = d["theta"]
    assert th[-1] == pytest.approx(theta)
    # exact per-step rates: 1 - |R(i theta)|^2 = theta^6/72 - theta^8/576 and theta - arg R(i theta)
    z = 1j * th
    R = 1 + z + z**2 / 2 + z**3 / 6 + z**4 / 24
    assert d["energy_loss"] == pytest.approx(th**6 / 72 - th**8 / 576, rel=0.02)
    assert d["phase_lag"] == pytest.approx(th - np.angle(R), rel=0.02)


def test_rk4_rates_measured_while_a_fast_mode_decays_to_round_off():
    # At theta = 1 the fast mode loses 1 - |R(i)|^2 = 1/72 - 1/576 of its energy
    # per step: its amplitude reaches the round-off floor (1e-16 of the state)
    # after about 2 ln(1e16) / 0.01215 ~ 6000 steps. A 20000-step run must still
    # give the exact per-step rates for both modes (the fit must stop where the
    # mode is gone, not average round-off noise into the slope).
    model = rk4h.make_model(*TWO_DOF)
    w = model.modes()[0]
    d = LH.measure_drift_and_phase(model, model.state([0.005, 0.005]), 1.0 / w[-1], 20000)
    th = d["theta"]
    z = 1j * th
    R = 1 + z + z**2 / 2 + z**3 / 6 + z**4 / 24
    assert d["steps_fitted"][-1] < 20000  # the fast mode was cut off ...
    assert d["steps_fitted"][0] == 20000  # ... the slow one was not
    assert d["energy_loss"] == pytest.approx(1 - np.abs(R) ** 2, rel=0.02)
    assert d["phase_lag"] == pytest.approx(th - np.angle(R), rel=0.02)


@pytest.mark.parametrize("theta", [0.1, 0.2])
def test_rk4_rates_match_leading_order_at_small_theta(theta):
    # leading terms theta^6/72 and theta^5/120: relative corrections theta^2/8 and
    # about theta^2 * 120/336 (< 2 % for theta <= 0.2)
    model = rk4h.make_model(*TWO_DOF)
    w = model.modes()[0]
    d = LH.measure_drift_and_phase(model, model.state([0.005, 0.005]), theta / w[-1], 1500)
    assert d["energy_loss"][-1] == pytest.approx(theta**6 / 72, rel=0.02)
    assert d["phase_lag"][-1] == pytest.approx(theta**5 / 120, rel=0.02)


@pytest.mark.parametrize("mu", [1e-6, 1e-4, 1.0, 1e4, 1e6])
def test_eq_2_31_both_roots_against_50_digits_and_eigenproblem(mu):
    cf = MR.closed_form_sq(1.0, 1.0, mu)
    ref = MR.omega_sq_decimal(1.0, 1.0, mu)
    eig = MR.omega_sq_eig(1.0, 1.0, mu)
    eps = np.finfo(float).eps
    assert cf == pytest.approx(ref, rel=4 * eps)
    # symmetric-definite eigenvalue bound: |d lam| <= c eps lam_max
    assert cf == pytest.approx(eig, rel=8 * eps * eig[1] / eig[0])


@pytest.mark.parametrize("mu", [1e-6, 1e-5, 1e5, 1e6])
def test_eq_2_31_limits_without_cancellation(mu):
    # mu -> 0: omega_low^2 = 3k/(2 m1) (1 - mu/4), omega_high^2 = 2k/m2 (1 + mu/4);
    # mu -> inf: omega_low^2 = 3k/(2 m2) (1 - 1/(4mu)), omega_high^2 = 2k/m1 (1 + 1/(4mu)); remainder O(x^2)
    x = min(mu, 1 / mu)
    cf = MR.closed_form_sq(1.0, 1.0, mu)
    lim = MR.omega_sq_limits(1.0, 1.0, mu)
    assert cf == pytest.approx(lim, rel=x * x)


def test_printed_eq_2_31_would_fail_the_limit_check():
    # the check above can fail: the formula as printed cancels ~1e-10 at mu = 1e-6
    lo_naive, _ = MR.omega_sq_naive(1.0, 1.0, 1e-6)
    lo_lim, _ = MR.omega_sq_limits(1.0, 1.0, 1e-6)
    assert abs(lo_naive / lo_lim - 1) > 1e-12


@pytest.mark.parametrize("mu", [0.0, -1.0, float("nan")])
def test_eq_2_31_refuses_nonpositive_mu(mu):
    from rk4h.references.closed_forms import two_dof_equal_k

    with pytest.raises(ValueError, match="mu"):
        two_dof_equal_k(1.0, m1=1.0, mu=mu)


NS = [1000, 3000, 10000, 30000]


def test_rk4_memory_grows_linearly_in_n():
    peaks = [LN.peak_bytes(N) for N in NS]
    assert LN.fit_exponent(NS, peaks) == pytest.approx(1.0, abs=0.1)


def test_dense_control_makes_the_memory_fit_fail():
    # a right-hand side holding the dense N x N stiffness matrix: exponent ~2
    Ns = [700, 1400, 2000]
    assert LN.fit_exponent(Ns, [LN.dense_rhs_peak_bytes(N) for N in Ns]) > 1.8


@pytest.mark.parametrize("N", [1000, 30000])
def test_rk4_work_per_step_is_four_rhs_calls(N):
    _, nfev_per_step, _ = LN.step_cost(N, n_steps=5, repeats=1)
    assert nfev_per_step == 4


@pytest.mark.slow
def test_rk4_wall_time_per_step_linear_up_to_1e5():
    # from N = 3e3: below that the working set is cache-resident (see large_n docs)
    Ns = [3000, 10000, 30000, 100000]
    times = [LN.step_cost(N, n_steps=1000, repeats=3)[0] for N in Ns]
    assert LN.fit_exponent(Ns, times) <= 1.1
    peaks = [LN.peak_bytes(N) for N in Ns]
    assert LN.fit_exponent(Ns, peaks) == pytest.approx(1.0, abs=0.1)


@pytest.mark.slow
def test_cvode_band_cost_per_step_linear():
    Ns = [3000, 10000, 30000, 100000]
    runs = [LN.cvode_band_cost(N) for N in Ns]
    assert all(r["success"] for r in runs)
    assert LN.fit_exponent(Ns, [r["wall_per_step"] for r in runs]) <= 1.1


def test_linearization_error_grows_like_amplitude_squared():
    a = np.array([1e-4, 1e-3, 1e-2])
    err = G.linearization_error(PLANAR, a, periods=2.0, steps_per_period=200)
    # the cubic terms of V cancel by symmetry: force error ~ r^3, relative error ~ (r/l)^2
    assert G.amplitude_exponent(a, err) == pytest.approx(2.0, abs=0.1)


def test_pass_near_anchor_returns_status_where_and_when_without_warnings():
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        out = G.singular_pass(PLANAR, 1e-9, 1e-3, 0.3)
    assert out["status"] == "singular"
    assert out["d_min"] <= 1e-9 and out["anchor"] == 1  # anchor (l, 0)
    assert 0 < out["t_min"] < 0.3
    assert "anchor 1" in out["message"] and "t =" in out["message"]


def test_state_on_anchor_is_unstable_status_not_exception():
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        out = G.singular_pass(PLANAR, 0.0, 1e-3, 0.1, start_on_anchor=True)
    assert out["status"] == "unstable"
    assert out["result"].t_fail == pytest.approx(1e-3)


@pytest.mark.parametrize("params, field", [
    ({}, "studies"),
    ({"studies": ["boundary"], "bogus": 1}, "bogus"),
    ({"studies": ["nope"]}, "studies"),
    ({"studies": ["boundary"], "bisection_rtol": -1e-4}, "bisection_rtol"),
    ({"studies": ["large_n"], "n_values": [1e3, 2.5]}, "n_values"),
])
def test_validate_params_names_the_field(params, field):
    with pytest.raises(ValueError, match=field):
        validate_params(params, "stability")


def test_run_contract_on_a_small_scene(tmp_path):
    from rk4h.validation.scenes import scene_from_dict
    from rk4h.validation.stability import run

    doc = {"name": "stab_tiny", "model": "planar4", "params": {**PLANAR, "linear": False},
           "initial": {"x": [0.005, 0.03]}, "run": {"t_end": 1.0, "h": [0.01], "solvers": ["rk4"],
                                                      "outputs": ["stability"]},
           "stability": {"studies": ["singular"]}}
    result = run(scene_from_dict(doc), tmp_path, quick=True)
    assert {"scene", "solver", "quantity", "measured", "theory", "passed"} <= set(result.rows[0])
    statuses = {r["quantity"]: r["status"] for r in result.rows}
    assert statuses["blowup_time_on_anchor_s"] == "unstable"
    assert all(r["passed"] for r in result.rows)
    assert result.findings


# -- no model names: frequencies and the four-spring test come from the model ------------------
def _four_spring_network(m=0.815, k=41.5, l=0.01, anchors=((-1, 0), (1, 0), (0, -1), (0, 1)), ref=(0.3, -0.2)):
    """planar4's mechanics as a `network` (another class, another name); springs of natural length l."""
    flat = [c for ax, ay in anchors for c in (ref[0] + ax * l, ref[1] + ay * l)]
    return rk4h.make_model("network", {"dim": 2, "masses": [m], "positions": list(ref), "anchors": flat,
                                          "springs": [[0, j + 1, k, l] for j in range(len(anchors))]})


@pytest.mark.parametrize("key", sorted(LINEAR_SCENES) + ["pendulums", "triangle", "long chain"])
def test_frequency_range_is_the_models_own(key):
    from rk4h.validation.stability.estimate import frequency_range

    extra = {"pendulums": ("pendulums", {"m": 0.5, "length": 1.0, "g": 9.81, "k": 0.2}),
             "triangle": ("triangle", {"m": 1.0, "k": 10.0, "side": 1.0}),
             "long chain": ("chain", {"masses": [1.0, 2.0] * 30, "springs": [3.0] * 61})}
    model = rk4h.make_model(*(extra.get(key) or LINEAR_SCENES[key]))
    lo, hi = frequency_range(model)
    assert (lo, hi) == model.frequency_range()
    w = model.modes()[0]
    w = w[w > 1e-9 * w[-1]]
    assert (lo, hi) == pytest.approx((w[0], w[-1]), rel=1e-10)


def test_frequency_range_of_a_long_chain_needs_no_dense_eigensolve(monkeypatch):
    from rk4h.validation.stability.estimate import frequency_range

    model = rk4h.make_model("chain", {"masses": [1.0] * 100_000, "springs": [1.0] * 100_001})
    monkeypatch.setattr(type(model), "modes", lambda self: pytest.fail("dense eigensolve"))
    lo, hi = frequency_range(model)
    N = 100_000  # fixed ends: omega_n = 2 sin(n pi / (2 (N + 1)))
    assert (lo, hi) == pytest.approx((2 * math.sin(math.pi / (2 * (N + 1))), 2 * math.sin(N * math.pi / (2 * (N + 1)))),
                                     rel=1e-9)


@pytest.mark.parametrize("linear", [False, True])
def test_four_spring_params_read_from_the_drawing(linear):
    assert G.four_spring_params(rk4h.make_model("planar4", {**PLANAR, "linear": linear})) == \
        pytest.approx(PLANAR, rel=1e-12)
    net = _four_spring_network()
    net.name = "chain"  # the name plays no part
    assert G.four_spring_params(net) == pytest.approx(PLANAR, rel=1e-12)


@pytest.mark.parametrize("model", [
    ("oscillator2d", {"m": 0.815, "kx": 41.5, "ky": 41.5}),  # one point, no anchors
    ("triangle", {"m": 1.0, "k": 10.0, "side": 1.0}),  # three points
    TWO_DOF,  # a line
    ("pendulums", {"m": 0.5, "length": 1.0, "g": 9.81, "k": 0.2}),  # angles
    "three anchors", "anchors at 2 l",  # a network like planar4 but for one thing
])
def test_four_spring_params_refuse_other_geometries(model):
    if model == "three anchors":
        m = _four_spring_network(anchors=((-1, 0), (1, 0), (0, -1)))
    elif model == "anchors at 2 l":
        m = _four_spring_network(anchors=((-2, 0), (2, 0), (0, -2), (0, 2)))  # pre-stretched springs
    else:
        m = rk4h.make_model(*model)
    assert G.four_spring_params(m) is None


def test_closest_approach_uses_the_drawings_anchors_about_its_reference():
    net = _four_spring_network(ref=(0.3, -0.2))
    t = np.array([0.0, 1.0])
    q = np.array([[0.02, 0.0], [0.0, 0.0]])  # displacement: from 2 l to 0 along x through the anchor (l, 0)
    d, j, tm = G.closest_approach(net, t, q)
    assert (d, j) == (pytest.approx(0.0, abs=1e-15), 1) and tm == pytest.approx(0.5)


def _study_ctx(model):
    from rk4h.validation.stability.studies import Context

    return Context("s", model, model.state(np.zeros(model.n_dof)),
                   validate_params({"studies": ["amplitude", "singular"], "singular_offset": 1e-9}), True)


@pytest.mark.parametrize("study", ["amplitude", "singular"])
def test_planar_studies_skip_a_model_not_drawn_as_the_four_spring_mass(study):
    from rk4h.validation.stability.studies import run_unit_in

    model = rk4h.make_model("oscillator2d", {"m": 0.815, "kx": 41.5, "ky": 41.5})
    model.name = "planar4"  # the name plays no part
    res = run_unit_in(_study_ctx(model), study)
    (r,) = res.rows
    assert r["status"] == "skipped" and "four-spring geometry" in r["note"]


def test_singular_study_runs_on_the_four_spring_network():
    from rk4h.validation.stability.studies import run_unit_in

    res = run_unit_in(_study_ctx(_four_spring_network()), "singular")
    statuses = {r["quantity"]: r["status"] for r in res.rows}
    assert statuses["blowup_time_on_anchor_s"] == "unstable"
    assert all(r["passed"] for r in res.rows)


def test_estimate_counts_planar_studies_only_for_the_four_spring_mass():
    from rk4h.validation.scenes import scene_from_dict

    def scene(model, params, x):
        return scene_from_dict({"name": "e", "model": model, "params": params, "initial": {"x": x},
                                "run": {"t_end": 1.0, "h": [0.01], "solvers": ["rk4"], "outputs": ["stability"]},
                                "stability": {"studies": ["amplitude", "singular"]}})

    from rk4h.validation.stability import estimate_steps

    planar = estimate_steps(scene("planar4", {**PLANAR, "linear": False}, [0.005, 0.03]), quick=True, detail=True)
    assert planar["amplitude"]["rk4"] > 0 and planar["singular"]["rk4"] > 0
    osc = estimate_steps(scene("oscillator2d", {"m": 0.815, "kx": 41.5, "ky": 41.5}, [0.005, 0.03]), quick=True,
                         detail=True)
    assert osc == {"amplitude": {}, "singular": {}}
