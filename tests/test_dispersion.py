"""The monatomic-lattice dispersion relation (thesis sec. 2.2.2, eqs. 2.49-2.54)
against the finite chain's eigenproblem and forces, and against a wave packet
integrated by RK4 (rk4h.references.wavepacket)."""
import math

import numpy as np
import pytest

import rk4h
from rk4h.references import dispersion as disp
from rk4h.references.wavepacket import measure_group_velocity, packet_state

M, K, D = disp.THESIS_LATTICE["m"], disp.THESIS_LATTICE["k"], disp.THESIS_LATTICE["d"]
V0 = D * math.sqrt(K / M)
EPS = np.finfo(float).eps


def _chain(N, m=M, k=K):
    return rk4h.make_model("chain", {"masses": [m] * N, "springs": [k] * (N + 1), "walls": "both"})


@pytest.mark.parametrize("N", [1, 2, 3, 10, 100])
def test_finite_chain_frequencies_match_eigenproblem(N):
    omega_eig, _ = _chain(N).modes()
    omega = disp.finite_chain_frequencies(N, M, K)
    # eigh's absolute eigenvalue error is ~ eps * ||M^-1 K|| <= eps * 4k/m; compare omega^2
    assert np.max(np.abs(omega**2 - omega_eig**2)) < 50 * EPS * 4 * K / M


@pytest.mark.parametrize("N", [1, 5, 40])
def test_finite_chain_frequencies_closed_form(N):
    # issue 2: omega_n = 2 sqrt(k/m) sin(n pi / (2 (N + 1)))
    n = np.arange(1, N + 1)
    expected = 2 * math.sqrt(K / M) * np.sin(n * math.pi / (2 * (N + 1)))
    assert disp.finite_chain_frequencies(N, M, K) == pytest.approx(expected, rel=4 * EPS)


@pytest.mark.parametrize("n", [1, 4, 9, 12])
def test_standing_wave_is_an_eigenvector_of_the_chain_force(n):
    # x_j = sin(j kp_n d), j = 1..N, with m x_j'' = k (x_{j-1} - 2 x_j + x_{j+1}) (erratum 6's
    # sign) gives acceleration -omega(kp_n)^2 x_j: the dispersion relation from the model.
    N = 12
    kp = disp.finite_chain_wavenumbers(N, D)[n - 1]
    x = np.sin(np.arange(1, N + 1) * kp * D)
    acc = _chain(N).acceleration(x)
    w = disp.omega(kp, M, K, D)
    assert np.max(np.abs(acc + w**2 * x)) < 1e-12 * 4 * K / M


@pytest.mark.parametrize("frac", [-0.9, -0.5, -0.1, 0.1, 0.3, 0.6, 0.99])
def test_group_velocity_is_d_omega_d_kp(frac):
    # central difference, step delta: truncation ~ delta^2 |omega'''| / 6, round-off ~ eps omega / delta
    kp = frac * math.pi / D
    delta = 1e-5 * math.pi / D
    fd = (disp.omega(kp + delta, M, K, D) - disp.omega(kp - delta, M, K, D)) / (2 * delta)
    assert disp.group_velocity(kp, M, K, D) == pytest.approx(fd, rel=1e-8, abs=1e-12)


@pytest.mark.parametrize("frac", [-0.7, 0.2, 0.5])
def test_group_velocity_closed_form_on_first_zone(frac):
    # eq. 2.54 signed: v_g = d sqrt(k/m) cos(kp d / 2) sign(kp)
    kp = frac * math.pi / D
    assert disp.group_velocity(kp, M, K, D) == pytest.approx(
        math.copysign(V0 * math.cos(kp * D / 2), kp), rel=4 * EPS)


def test_velocities_at_zone_centre_and_edge():
    edge = math.pi / D
    assert disp.group_velocity(0.0, M, K, D) == pytest.approx(V0, rel=EPS)
    assert disp.phase_velocity(0.0, M, K, D) == pytest.approx(V0, rel=EPS)
    assert abs(disp.group_velocity(edge, M, K, D)) < 1e-15  # standing wave: no energy flow
    assert disp.omega(edge, M, K, D) == pytest.approx(disp.omega_0(M, K), rel=EPS)  # eq. 2.50
    # v_p(pi/d) = omega_0 d / pi = 2 v_0 / pi
    assert disp.phase_velocity(edge, M, K, D) == pytest.approx(2 * V0 / math.pi, rel=4 * EPS)
    assert disp.v_0(M, K, D) == pytest.approx(V0, rel=EPS)  # eq. 2.52


@pytest.mark.parametrize("frac", [-0.8, -0.3, 0.25, 0.75])
def test_phase_velocity_is_omega_over_kp(frac):
    kp = frac * math.pi / D
    assert disp.phase_velocity(kp, M, K, D) == pytest.approx(disp.omega(kp, M, K, D) / kp, rel=4 * EPS)


@pytest.mark.parametrize("frac", [-0.95, -0.4, 0.0, 0.3, 0.8])
@pytest.mark.parametrize("n", [-3, -1, 1, 2])
def test_folding_into_first_zone(frac, n):
    kp = frac * math.pi / D
    shifted = kp + 2 * math.pi * n / D
    folded = disp.fold_to_first_zone(shifted, D)
    assert folded == pytest.approx(kp, abs=1e-9 * math.pi / D)
    assert disp.in_first_zone(folded, D)
    # same frequency and the same lattice displacements exp(i kp j d) at every site
    assert disp.omega(shifted, M, K, D) == pytest.approx(disp.omega(kp, M, K, D), rel=1e-9, abs=1e-12)
    j = np.arange(50)
    assert np.max(np.abs(np.exp(1j * shifted * j * D) - np.exp(1j * folded * j * D))) < 1e-9


def test_omega_even_and_bounded():
    kp = np.linspace(-3 * math.pi / D, 3 * math.pi / D, 601)
    w = disp.omega(kp, M, K, D)
    assert np.array_equal(w, disp.omega(-kp, M, K, D))
    assert np.all(w >= 0) and np.all(w <= disp.omega_0(M, K) * (1 + EPS))


@pytest.mark.parametrize("call,name", [
    (lambda: disp.omega(1.0, M, K, 0.0), "d"),
    (lambda: disp.omega(1.0, -M, K, D), "m"),
    (lambda: disp.group_velocity(1.0, M, float("nan"), D), "k"),
    (lambda: disp.finite_chain_wavenumbers(0, D), "N"),
    (lambda: disp.fold_to_first_zone(1.0, -1.0), "d"),
])
def test_bad_arguments_raise_naming_them(call, name):
    with pytest.raises(ValueError, match=f"`{name}`"):
        call()


# -- wave packet integrated by RK4 ------------------------------------------------

@pytest.fixture(scope="module", params=[0.3, 0.6], ids=["kp0=0.3pi/d", "kp0=0.6pi/d"])
def packet(request):
    return measure_group_velocity(request.param * math.pi / D)


def test_wave_packet_moves_at_group_velocity(packet):
    assert packet.success
    assert abs(packet.rel_error) < 0.02


def test_wave_packet_is_not_moving_at_phase_velocity(packet):
    # the check discriminates: v_p and v_g differ by > 5% at these carriers
    v_p = disp.phase_velocity(packet.kp0, M, K, D)
    assert abs(v_p / packet.v_theory - 1) > 0.05
    assert abs(packet.v_measured - packet.v_theory) < 0.2 * abs(packet.v_measured - v_p)


def test_wave_packet_centroid_speed_is_the_spectral_mean_group_velocity(packet):
    # The energy centroid moves at the energy-weighted mean v_g of the spectrum,
    # v_g(kp0) (1 - 5 d^2 / (16 sigma^2) + ...) for a Gaussian of width sigma;
    # RK4's dispersion error (omega h)^4 / 120 ~ 1e-5 is far below 1e-3.
    assert packet.v_spectral / packet.v_theory - 1 == pytest.approx(-5 * D**2 / (16 * packet.sigma**2), rel=0.1)
    assert packet.v_measured == pytest.approx(packet.v_spectral, rel=1e-3)


def test_wave_packet_stays_away_from_walls(packet):
    L = (packet.N + 1) * D
    assert packet.centroid.min() > 10 * packet.sigma
    assert packet.centroid.max() < L - 10 * packet.sigma


@pytest.mark.parametrize("frac", [0.3, 0.6])
def test_packet_state_is_right_moving(frac):
    # u + i v / omega on each DFT component is the amplitude of exp(i (K x - omega t)):
    # for a right-moving packet the left-moving (K < 0) part carries no energy.
    N, kp0 = 400, frac * math.pi / D
    y0 = packet_state(N, kp0, 8 * D, 100 * D)
    Kw = 2 * math.pi * np.fft.fftfreq(N, D)
    w = disp.omega(Kw, M, K, D)
    u_hat, v_hat = np.fft.fft(y0[:N]), np.fft.fft(y0[N:])
    nz = w > 0
    energy = np.zeros(N)
    energy[nz] = w[nz] ** 2 * np.abs(u_hat[nz] + 1j * v_hat[nz] / w[nz]) ** 2
    assert energy[Kw < 0].sum() < 1e-12 * energy.sum()


@pytest.mark.parametrize("frac,N,h", [(0.3, 400, 0.02), (0.6, 400, 0.02), (0.8, 60, 0.05)])
def test_packet_compiled_loop_equals_the_generic_solver_bit_for_bit(monkeypatch, frac, N, h):
    # measure_group_velocity steps RK4's compiled loop; rk4h.solve on the chain's numpy
    # right-hand side must give the very same centroid track and fitted speed
    import rk4h.fast
    from rk4h.references import wavepacket

    kp0 = frac * math.pi / D
    fast = wavepacket.measure_group_velocity(kp0, N=N, h=h)
    calls = []

    def generic(model, t_span, y0, **kw):
        calls.append(model.n_dof)
        return rk4h.solve(model.rhs, t_span, y0, **kw)

    monkeypatch.setattr(rk4h.fast, "solve_model", generic)
    slow = wavepacket.measure_group_velocity(kp0, N=N, h=h)
    assert calls == [N] and fast.success and slow.success
    assert np.array_equal(fast.t, slow.t)
    assert np.array_equal(fast.centroid, slow.centroid)
    assert (fast.v_measured, fast.energy_drift, fast.h) == (slow.v_measured, slow.energy_drift, slow.h)


def test_packet_runs_without_numba_with_the_same_numbers():
    # the base install (no numba): the generic stepper runs the packet, and gives the
    # compiled loop's numbers (printed with repr: every bit)
    import subprocess
    import sys

    code = ("import sys\nsys.modules['numba'] = None\nimport math\n"
            "from rk4h.references import wavepacket as w\n"
            "r = w.measure_group_velocity(0.8 * math.pi / w.THESIS_LATTICE['d'], N=60, h=0.05)\n"
            "assert 'numba' not in sys.modules or sys.modules['numba'] is None\n"
            "print(repr(r.v_measured), repr(r.energy_drift), repr(float(r.centroid[-1])))\n")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr[-2000:]
    here = measure_group_velocity(0.8 * math.pi / D, N=60, h=0.05)
    assert proc.stdout.split() == [repr(here.v_measured), repr(here.energy_drift), repr(float(here.centroid[-1]))]
