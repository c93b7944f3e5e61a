"""The reference trajectory (rk4h.references.truth): exact-modal for linear models,
heyoka real128 below double round-off for nonlinear ones, cached per scene."""
import mpmath as mp
import numpy as np
import pytest

import rk4h
from rk4h.references.exact import modal_solution
from rk4h.references.truth import cache_dir, clear_memory_cache, reference_solution

LINEAR = {
    "chain-2dof": ("chain", {"masses": [0.815, 3.099], "springs": [41.5, 138.0, 157.8]},
                   [0.005, 0.005], [0.0, 0.0]),
    "oscillator2d": ("oscillator2d", {"m": 0.815, "kx": 41.5, "ky": 20.75}, [0.005, 0.003], [0.0, 0.02]),
    "chain-free": ("chain", {"masses": [1.0, 2.0, 1.0, 3.0], "springs": [10.0, 20.0, 15.0], "walls": "none"},
                   [0.01, 0.0, -0.01, 0.0], [0.1, 0.0, 0.0, 0.0]),
}
NONLINEAR = {
    "planar4": ("planar4", {"m": 0.815, "k": 41.5, "l": 0.01}, [0.005, 0.0], [0.0, 0.0]),  # Table 4.4
    "planar4-case2": ("planar4", {"m": 0.815, "k": 41.5, "l": 0.01}, [0.005, 0.03], [0.0, 0.0]),  # Table 4.5
    "pendulums": ("pendulums", {"m": 1.0, "length": 1.0, "g": 9.81, "k": 2.0}, [0.3, 0.0], [0.0, 0.5]),
    "triangle": ("triangle", {"m": 1.0, "k": 10.0, "side": 1.0},
                 [0.05, 0.0, -0.02, 0.01, 0.0, 0.03], [0.0, 0.01, 0.0, 0.0, 0.02, 0.0]),
}
ALL = {**LINEAR, **NONLINEAR}


def scene(name):
    model_name, params, x0, v0 = ALL[name]
    model = rk4h.make_model(model_name, params)
    return model, model.state(x0, v0)


@pytest.fixture
def tmp_cache(tmp_path):
    clear_memory_cache()
    yield tmp_path
    clear_memory_cache()


@pytest.mark.parametrize("name", sorted(LINEAR))
def test_linear_model_truth_is_the_modal_solution(name, tmp_cache):
    model, y0 = scene(name)
    t = np.linspace(0.0, 5.0, 51)
    truth = reference_solution(model, y0, t, path=tmp_cache)
    assert truth.kind == "exact-modal" and truth.ok and truth.y_lo is None
    np.testing.assert_array_equal(truth.y, modal_solution(model, y0)(t))
    # Exact motion conserves energy; what is left is the float64 evaluation (a few eps).
    assert truth.energy_drift < 1e-14


# -- real128 against an exact solution evaluated in 40-digit arithmetic -----------------------
def _mp_oscillator2d(model, y0, t):
    """x(t) = x0 cos(w t) + v0/w sin(w t) per axis, w = sqrt(k/m) of the model's doubles."""
    m = mp.mpf(model.m)
    out = []
    for k, x0, v0 in ((model.kx, y0[0], y0[2]), (model.ky, y0[1], y0[3])):
        w = mp.sqrt(mp.mpf(k) / m)
        x0, v0 = mp.mpf(x0), mp.mpf(v0)
        out.append([(x0 * mp.cos(w * mp.mpf(s)) + v0 / w * mp.sin(w * mp.mpf(s)),
                     -x0 * w * mp.sin(w * mp.mpf(s)) + v0 * mp.cos(w * mp.mpf(s))) for s in t])
    return [[p[0] for p in out[0]], [p[0] for p in out[1]], [p[1] for p in out[0]], [p[1] for p in out[1]]]


def _mp_chain(model, y0, t):
    """Modal superposition in mpmath: M^-1/2 K M^-1/2 = U diag(w^2) U^T (eigsy), all in 40 digits."""
    n = model.n_dof
    K = model.stiffness_matrix()
    M = [mp.mpf(float(mi)) for mi in model.mass]
    A = mp.matrix(n, n)
    for i in range(n):
        for j in range(n):
            A[i, j] = mp.mpf(float(K[i, j])) / mp.sqrt(M[i] * M[j])
    lam, U = mp.eigsy(A)
    # Mass-weighted coordinates u = M^1/2 q; modal u = U a.
    u0 = [mp.sqrt(M[i]) * mp.mpf(y0[i]) for i in range(n)]
    du0 = [mp.sqrt(M[i]) * mp.mpf(y0[n + i]) for i in range(n)]
    a0 = [sum(U[i, j] * u0[i] for i in range(n)) for j in range(n)]
    da0 = [sum(U[i, j] * du0[i] for i in range(n)) for j in range(n)]
    w = [mp.sqrt(lam[j]) for j in range(n)]
    rows = [[None] * len(t) for _ in range(2 * n)]
    for c, s in enumerate(t):
        s = mp.mpf(s)
        a = [a0[j] * mp.cos(w[j] * s) + da0[j] / w[j] * mp.sin(w[j] * s) for j in range(n)]
        da = [-a0[j] * w[j] * mp.sin(w[j] * s) + da0[j] * mp.cos(w[j] * s) for j in range(n)]
        for i in range(n):
            rows[i][c] = sum(U[i, j] * a[j] for j in range(n)) / mp.sqrt(M[i])
            rows[n + i][c] = sum(U[i, j] * da[j] for j in range(n)) / mp.sqrt(M[i])
    return rows


@pytest.mark.parametrize("name, exact", [("oscillator2d", _mp_oscillator2d), ("chain-2dof", _mp_chain)])
def test_real128_matches_extended_precision_exact_solution(name, exact, tmp_cache):
    model, y0 = scene(name)
    t = np.linspace(0.0, 5.0, 11)
    truth = reference_solution(model, y0, t, kind="heyoka-real128", path=tmp_cache)
    assert truth.kind == "heyoka-real128" and truth.ok
    with mp.workdps(40):
        ref = exact(model, y0, t)
        got = truth.y_ext()
        n = model.n_dof
        for rows in (range(n), range(n, 2 * n)):  # positions, velocities: each against its amplitude
            amp = max(abs(ref[i][c]) for i in rows for c in range(len(t)))
            err = max(abs(mp.mpf(str(got[i, c])) - ref[i][c]) for i in rows for c in range(len(t)))
            assert err / amp < 1e-25
    # The float64 rounding is the correctly rounded real128 value (hi/lo split).
    assert np.all(np.abs(truth.y_lo) <= 0.5 * np.spacing(np.abs(truth.y)))


@pytest.mark.parametrize("name", sorted(NONLINEAR))
def test_real128_reference_conserves_energy(name, tmp_cache):
    model, y0 = scene(name)
    t = np.linspace(0.0, 3.0, 31)
    truth = reference_solution(model, y0, t, path=tmp_cache)
    assert truth.kind == "heyoka-real128" and truth.ok, truth.message
    assert truth.n_steps > 0 and np.all(np.isfinite(truth.y))
    np.testing.assert_array_equal(truth.y[:, 0], y0)
    assert truth.energy_drift < 1e-25


def test_truth_is_cached_in_memory_and_on_disk(tmp_cache):
    model, y0 = scene("pendulums")
    t = np.linspace(0.0, 1.0, 11)
    first = reference_solution(model, y0, t, path=tmp_cache)
    assert first.source == "computed"
    files = list(tmp_cache.glob("*.npz"))
    assert [f.stem for f in files] == [first.key]
    assert reference_solution(model, y0, t, path=tmp_cache).source == "memory"
    clear_memory_cache()
    again = reference_solution(model, y0, t, path=tmp_cache)
    assert again.source == "disk"
    np.testing.assert_array_equal(again.y, first.y)
    np.testing.assert_array_equal(again.y_lo, first.y_lo)
    assert again.energy_drift == first.energy_drift and again.kind == first.kind
    # Another scene is another key.
    other = reference_solution(model, y0 * 0.5, t, path=tmp_cache)
    assert other.key != first.key and other.source == "computed"


def test_cache_dir_from_environment(monkeypatch, tmp_path):
    # RK4H_CACHE is the root of every cache; the truth lives in its truth/ (created 0700)
    monkeypatch.setenv("RK4H_CACHE", str(tmp_path / "elsewhere"))
    assert cache_dir() == tmp_path / "elsewhere" / "truth"
    assert (cache_dir().stat().st_mode & 0o777) == 0o700
    monkeypatch.delenv("RK4H_CACHE")
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    assert cache_dir() == tmp_path / "xdg" / "rk4h" / "truth"


@pytest.mark.parametrize("name, kwargs, named", [
    ("planar4", {"kind": "exact-modal"}, "kind"),
    ("chain-2dof", {"kind": "rk4"}, "kind"),
    ("chain-2dof", {"y0": [0.0, 0.0]}, "y0"),
    ("chain-2dof", {"t_eval": [1.0, 0.0]}, "t_eval"),
    ("chain-2dof", {"t_eval": ["start", "end"]}, "t_eval"),
    ("chain-2dof", {"y0": [float("inf"), 0.0, 0.0, 0.0]}, "y0"),
])
def test_bad_arguments_raise_naming_them(name, kwargs, named):
    model, y0 = scene(name)
    args = {"y0": y0, "t_eval": [0.0, 1.0], **kwargs}
    with pytest.raises(ValueError, match=named):
        reference_solution(model, args.pop("y0"), args.pop("t_eval"), cache=False, **args)
