"""rk4h.ensemble: per instance, the batch equals rk4h.solve on that
instance (numba: bit for bit; jax on CPU: 1e-13 relative), diverging
instances stop alone with their t_fail, bad input is one clear ValueError."""
import subprocess
import sys

import numpy as np
import pytest

import rk4h
from rk4h import ensemble

pytest.importorskip("numba", reason="numba is not installed (the fast extra)")

SPRINGS = [41.5, 138.0, 157.8]
RALSTON2 = rk4h.make_tableau("ralston2", [["0", "0"], ["2/3", "0"]], ["1/4", "3/4"])  # as methods_2dof.toml
METHODS = ["rk4", RALSTON2, "stormer-verlet"]
T_SPAN = (0.0, 1.5)
H = 0.01


def chain(masses):
    return rk4h.make_model("chain", {"masses": list(masses), "springs": SPRINGS})


@pytest.fixture(scope="module")
def batch():
    rng = np.random.default_rng(7)
    B = 9
    y0 = rng.uniform(-0.01, 0.01, (B, 4))
    masses = rng.uniform(0.3, 4.0, (B, 2))
    return y0, masses


def scalar(masses, y0, method, **kw):
    return rk4h.solve(chain(masses).rhs, T_SPAN, y0, h=H, method=method, **kw)


def _name(m):
    return getattr(m, "name", m)


@pytest.mark.parametrize("method", METHODS, ids=_name)
def test_numba_equals_solve_bit_for_bit(batch, method):
    y0, masses = batch
    res = ensemble(chain([1.0, 1.0]), y0, T_SPAN, h=H, method=method, params={"masses": masses}, backend="numba")
    assert res.y.shape == (y0.shape[0], 151, 4) and res.backend == "numba"
    assert (res.status == 0).all() and np.isnan(res.t_fail).all()
    for b in range(y0.shape[0]):
        ref = scalar(masses[b], y0[b], method)
        np.testing.assert_array_equal(res.t, ref.t)
        assert np.array_equal(res.y[b], ref.y.T), f"instance {b} differs from rk4h.solve"


def _rel(a, ref):
    """Largest difference over each instance's and component's largest |value|."""
    scale = np.max(np.abs(ref), axis=1, keepdims=True)
    return float(np.max(np.abs(a - ref) / scale))


@pytest.mark.parametrize("method", METHODS, ids=_name)
def test_jax_equals_solve_to_1e13(batch, method):
    pytest.importorskip("jax", reason="jax is not installed (the gpu extra)")
    y0, masses = batch
    res = ensemble(chain([1.0, 1.0]), y0, T_SPAN, h=H, method=method, params={"masses": masses}, backend="jax")
    assert res.backend == "jax" and (res.status == 0).all()
    ref = np.stack([scalar(masses[b], y0[b], method).y.T for b in range(y0.shape[0])])
    assert _rel(res.y, ref) <= 1e-13
    # the comparison can fail: a different method is far off
    other = ensemble(chain([1.0, 1.0]), y0, T_SPAN, h=H, method="euler", params={"masses": masses}, backend="jax")
    assert _rel(other.y, ref) > 1e-6


def _diverging():
    # omega_max h of the 2-DOF chain grows as the masses shrink: RK4 is stable
    # below omega_max h = 2.83, so at h = 0.05 the light instances blow up.
    masses = np.array([[0.815, 3.099], [0.01, 0.02], [2.0, 1.0], [0.005, 3.0], [1.0, 1.0]])
    y0 = np.tile([0.005, 0.005, 0.0, 0.0], (5, 1))
    return masses, y0


@pytest.mark.parametrize("backend", ["numba", "jax"])
def test_diverging_instances_stop_alone(backend):
    if backend == "jax":
        pytest.importorskip("jax", reason="jax is not installed (the gpu extra)")
    masses, y0 = _diverging()
    span, h = (0.0, 20.0), 0.05
    res = ensemble(chain([1.0, 1.0]), y0, span, h=h, params={"masses": masses}, backend=backend)
    assert list(res.status) == [0, -1, 0, -1, 0]
    for b in range(5):
        ref = rk4h.solve(chain(masses[b]).rhs, span, y0[b], h=h)
        assert res.status[b] == ref.status
        rows = ref.y.shape[1]
        assert res.n_steps[b] == ref.n_steps
        if ref.status != 0:
            assert res.t_fail[b] == ref.t_fail
            assert np.isnan(res.y[b, rows:]).all() and rows < res.y.shape[1]
        else:
            assert np.isnan(res.t_fail[b])
        if backend == "numba":
            assert np.array_equal(res.y[b, :rows], ref.y.T)
        else:
            assert _rel(res.y[b:b + 1, :rows], ref.y.T[None]) <= 1e-13


_XLA5, _PALLAS = ("xla", 5, 128), ("pallas-interpret", 1, 4)


# The Pallas kernel (the GPU's default) with every kind of method: classical, a
# scene tableau, partitioned with a carried force, a composition with and
# without one; jax's written-out loop (the GPU's fallback) with two.
@pytest.mark.parametrize("method, variant", [(m, _PALLAS) for m in METHODS + ["yoshida4", "forest-ruth"]]
                         + [("rk4", _XLA5), ("yoshida4", _XLA5)],
                         ids=lambda v: v[0] if isinstance(v, tuple) else _name(v))
def test_jax_gpu_loops_are_bit_for_bit_the_one_step_loop(monkeypatch, method, variant):
    # The GPU's loops must change no arithmetic: on the CPU, jax's loop with 5
    # steps written out per iteration, and the Pallas kernel (run by Pallas'
    # interpreter; 4 instances per program, so 5 instances need a padded
    # program), against jax's one-step loop. Step counts between outputs (23,
    # 77, 50) that 5 does not divide; instances that diverge mid-row (t_fail
    # and n_steps equal too).
    pytest.importorskip("jax", reason="jax is not installed (the gpu extra)")
    from rk4h.batch import _jax

    kernel, unroll, lanes = variant
    masses, y0 = _diverging()
    span, h = (0.0, 7.5), 0.05
    t_eval = [0.0, 23 * h, 100 * h, 7.5]
    runs = {}
    for key, (k, u) in {"one": ("xla", 1), "other": (kernel, unroll)}.items():
        monkeypatch.setattr(_jax, "UNROLL", {"cpu": u, "gpu": u})
        monkeypatch.setattr(_jax, "KERNEL", {"cpu": k, "gpu": k})
        monkeypatch.setattr(_jax, "LANES", lanes)
        runs[key] = ensemble(chain([1.0, 1.0]), y0, span, h=h, method=method, params={"masses": masses},
                             t_eval=t_eval, backend="jax")
    one, other = runs["one"], runs["other"]
    assert (one.status != 0).any() and (one.status == 0).any()  # both kinds of instance are there
    assert np.array_equal(one.y, other.y, equal_nan=True)
    assert np.array_equal(one.n_steps, other.n_steps) and np.array_equal(one.status, other.status)
    assert np.array_equal(one.t_fail, other.t_fail, equal_nan=True)


def test_jax_pallas_programs_follow_lanes(monkeypatch):
    # A compiled kernel is kept per programs' width: after a run with 4
    # instances per program, a run with 2 must not reuse the 4-wide kernel
    # (5 instances padded to 6 would leave a program's worth unrun).
    pytest.importorskip("jax", reason="jax is not installed (the gpu extra)")
    from rk4h.batch import _jax

    masses, y0 = _diverging()
    kw = dict(params={"masses": masses}, t_eval=[0.0, 1.0, 3.0], backend="jax")
    monkeypatch.setattr(_jax, "KERNEL", {"cpu": "xla", "gpu": "xla"})
    ref = ensemble(chain([1.0, 1.0]), y0, (0.0, 3.0), h=0.05, **kw)
    monkeypatch.setattr(_jax, "KERNEL", {"cpu": "pallas-interpret", "gpu": "pallas-interpret"})
    for lanes in (4, 2, 8):
        monkeypatch.setattr(_jax, "LANES", lanes)
        res = ensemble(chain([1.0, 1.0]), y0, (0.0, 3.0), h=0.05, **kw)
        assert np.array_equal(res.y, ref.y, equal_nan=True), lanes
        assert np.array_equal(res.n_steps, ref.n_steps) and np.array_equal(res.status, ref.status)


def test_jax_without_pallas_triton_runs_xla_loops_and_says_so(monkeypatch):
    # jax 0.11 deprecates Pallas' Triton backend: without it the default GPU
    # kernel becomes jax's own loops with one warning (equal numbers here), and an
    # explicit request for the Pallas kernel is refused.
    pytest.importorskip("jax", reason="jax is not installed (the gpu extra)")
    from rk4h.batch import _jax

    y0 = np.random.default_rng(6).uniform(-0.01, 0.01, (3, 4))
    monkeypatch.setattr(_jax, "KERNEL", {"cpu": "xla", "gpu": "xla"})
    ref = ensemble(chain([0.815, 3.099]), y0, (0.0, 0.5), h=0.01, backend="jax")
    monkeypatch.setattr(_jax, "KERNEL", {"cpu": "pallas-interpret", "gpu": "pallas"})
    monkeypatch.setattr(_jax, "_has_pallas_triton", lambda: False)
    with pytest.warns(RuntimeWarning, match="has no Pallas Triton backend"):
        res = ensemble(chain([0.815, 3.099]), y0, (0.0, 0.5), h=0.01, backend="jax")
    assert np.array_equal(res.y, ref.y)
    with pytest.raises(ValueError, match="needs jax's Pallas Triton backend"):
        _jax.run(None, None, None, None, None, 0.0, 0.01, 1, np.array([1]), None, None, None, None,
                 kernel="pallas")


def test_jax_pallas_kernel_float32_and_bad_settings(monkeypatch):
    pytest.importorskip("jax", reason="jax is not installed (the gpu extra)")
    from rk4h.batch import _jax

    y0 = np.random.default_rng(5).uniform(-0.01, 0.01, (3, 4))
    monkeypatch.setattr(_jax, "LANES", 2)
    kw = dict(t_eval=[0.0, 0.5, 1.0], backend="jax", dtype="float32")
    monkeypatch.setattr(_jax, "KERNEL", {"cpu": "xla"})
    ref = ensemble(chain([0.815, 3.099]), y0, (0.0, 1.0), h=0.01, **kw)
    monkeypatch.setattr(_jax, "KERNEL", {"cpu": "pallas-interpret"})
    res = ensemble(chain([0.815, 3.099]), y0, (0.0, 1.0), h=0.01, **kw)
    assert np.array_equal(res.y, ref.y)
    # the float32 states are float32 numbers (a float64 run differs from them)
    assert np.array_equal(res.y, res.y.astype(np.float32).astype(np.float64))
    with pytest.raises(ValueError, match="`unroll` must be an integer >= 1, got 0"):
        _jax.run(None, None, None, None, None, 0.0, 0.01, 1, np.array([1]), None, None, None, None, unroll=0)
    with pytest.raises(ValueError, match="`kernel` must be one of .*, got 'cuda'"):
        _jax.run(None, None, None, None, None, 0.0, 0.01, 1, np.array([1]), None, None, None, None, kernel="cuda")


def test_array_loop_and_off_grid_output_bit_for_bit():
    # nine masses: the array loop (beyond the straight-line loop's 8); t_eval off the grid: Hermite
    rng = np.random.default_rng(3)
    base = rk4h.make_model("chain", {"masses": [1.0] * 9, "springs": [10.0] * 10})
    B = 4
    y0 = rng.uniform(-0.1, 0.1, (B, 18))
    springs = rng.uniform(5.0, 50.0, (B, 10))
    t_eval = np.linspace(0.0, 1.0, 7)
    for method in ("rk4", "stormer-verlet"):
        res = ensemble(base, y0, (0.0, 1.0), h=0.03, params={"springs": springs}, t_eval=t_eval, backend="numba",
                       method=method)
        for b in range(B):
            m = rk4h.make_model("chain", {"masses": [1.0] * 9, "springs": list(springs[b])})
            ref = rk4h.solve(m.rhs, (0.0, 1.0), y0[b], h=0.03, t_eval=t_eval, method=method)
            assert np.array_equal(res.y[b], ref.y.T), (method, b)


def test_nonlinear_chain_equals_the_scalar_compiled_path():
    # FPUT-beta chain of nine masses (the array loop): the batch runs the loop
    # of rk4h.fast.solve_model, so it equals that bit for bit (rk4h.fast
    # itself agrees with the numpy path to round-off where numba's and
    # numpy's arithmetic differ)
    import rk4h.fast

    rng = np.random.default_rng(4)
    base = rk4h.make_model("chain", {"masses": [1.0] * 9, "springs": [10.0] * 10, "beta": 50.0})
    y0 = rng.uniform(-0.1, 0.1, (3, 18))
    beta = rng.uniform(0.0, 100.0, 3)
    res = ensemble(base, y0, (0.0, 1.0), h=0.03, params={"beta": beta}, backend="numba")
    for b in range(3):
        m = rk4h.make_model("chain", {"masses": [1.0] * 9, "springs": [10.0] * 10, "beta": float(beta[b])})
        ref = rk4h.fast.solve_model(m, (0.0, 1.0), y0[b], h=0.03)
        assert np.array_equal(res.y[b], ref.y.T)
        assert _rel(res.y[b:b + 1], rk4h.solve(m.rhs, (0.0, 1.0), y0[b], h=0.03).y.T[None]) <= 1e-13


def test_element_parameter_and_chunks(batch):
    y0, masses = batch
    m1 = masses[:, 1]
    whole = ensemble(chain([0.815, 3.099]), y0, T_SPAN, h=H, params={"masses[1]": m1}, backend="numba")
    chunked = ensemble(chain([0.815, 3.099]), y0, T_SPAN, h=H, params={"masses[1]": m1}, backend="numba", chunk=2)
    assert np.array_equal(whole.y, chunked.y)
    ref = scalar([0.815, m1[4]], y0[4], "rk4")
    assert np.array_equal(whole.y[4], ref.y.T)
    plain = ensemble(chain([0.815, 3.099]), y0, T_SPAN, h=H, backend="numba")
    assert not np.array_equal(plain.y[4], whole.y[4])


def test_float32_is_float32():
    pytest.importorskip("jax", reason="jax is not installed (the gpu extra)")
    y0 = np.tile([0.005, 0.005, 0.0, 0.0], (3, 1))
    r64 = ensemble(chain([0.815, 3.099]), y0, (0.0, 5.0), h=0.01, backend="jax")
    r32 = ensemble(chain([0.815, 3.099]), y0, (0.0, 5.0), h=0.01, backend="jax", dtype="float32")
    err = _rel(r32.y, r64.y)
    assert 1e-9 < err < 1e-4  # float32 round-off: far above float64's, far below the signal


@pytest.mark.parametrize("method", METHODS, ids=_name)
def test_jax_and_numba_print_one_step_text(method):
    """The jax step and the numba loop inline the same printed step
    (rk4h.fast.codegen.step_lines), so the two backends cannot drift apart."""
    pytest.importorskip("jax", reason="jax is not installed (the gpu extra)")
    from rk4h.batch import _jax
    from rk4h.fast import codegen

    tab = rk4h.methods.get_method(method)
    kern = chain([1.0, 2.0]).force_kernel()
    lines = codegen.step_lines(codegen._Plan(tab), kern, 2 * kern.n_dof)
    # the new state's last component (from y3, or from the stage state that
    # holds the sum it extends: rk4h.fast.codegen._Held)
    assert any(line.startswith(("    n3 = y3 + ", "    n3 = s3")) for line in lines)
    assert "\n".join(lines) in _jax.step_source(tab, kern)
    # the numba loop: the same lines inside its function body (four spaces more)
    assert "\n".join("    " + line for line in lines) in codegen.source(tab, kern)


@pytest.mark.parametrize("kwargs, field", [
    ({"params": {"mass": np.ones(2)}}, "`params` key 'mass'"),
    ({"params": {"masses[1]": np.ones(3)}}, "length B = 2"),
    ({"params": {"masses[5]": np.ones(2)}}, "no element 5"),
    ({"params": {"masses[1]": [1.0, -1.0]}}, "instance 1"),
    ({"backend": "gpu"}, "`backend`"),
    ({"dtype": "float32", "backend": "numba"}, "`dtype`"),
    ({"chunk": 0}, "`chunk`"),
])
def test_bad_input_names_the_field(kwargs, field):
    y0 = np.zeros((2, 4))
    y0[:, 0] = 0.001
    with pytest.raises(ValueError, match=field.replace("[", r"\[").replace("]", r"\]")):
        ensemble(chain([1.0, 1.0]), y0, T_SPAN, h=H, **kwargs)


def test_bad_y0_shape():
    with pytest.raises(ValueError, match=r"`y0` must have shape \(B, 4\)"):
        ensemble(chain([1.0, 1.0]), np.zeros((2, 3)), T_SPAN, h=H, backend="numba")


def test_import_loads_neither_numba_nor_jax():
    code = ("import sys, rk4h; rk4h.ensemble; "
            "print('numba' in sys.modules, 'jax' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.split() == ["False", "False"]


def test_stability_map_boundary_is_2_8284_along_the_mass_ratio_axis():
    from rk4h.batch.maps import RK4_IMAGINARY_LIMIT, stability_map

    model = chain([0.815, 3.099])
    values = 0.815 * np.geomspace(0.1, 10.0, 12)  # masses[1] over masses[0] from 0.1 to 10
    h = np.linspace(0.035, 0.23, 40)
    y0 = [0.005, -0.003, 0.0, 0.0]
    rk4 = stability_map(model, "masses[1]", values, h, y0=y0)
    dh = h[1] - h[0]
    assert not np.isnan(rk4.h_max).any() and (rk4.h_max < h[-1]).all()  # the boundary lies inside the grid
    # largest stable grid step: omega_max h at most 2.8284, the next grid step past it
    assert (rk4.z_max <= RK4_IMAGINARY_LIMIT).all()
    assert (RK4_IMAGINARY_LIMIT - rk4.z_max < rk4.omega_max * dh).all()
    # a method with another stability function has another boundary (sqrt(3) on the imaginary axis)
    heun3 = stability_map(model, "masses[1]", values[-3:], h, y0=y0, method="heun3")
    assert (np.abs(heun3.z_max - np.sqrt(3.0)) < heun3.omega_max * dh).all()


def test_float32_floor_grows_like_sqrt_n_eps32():
    pytest.importorskip("jax", reason="jax is not installed (the gpu extra)")
    from rk4h.batch.maps import float32_floor

    y0 = np.random.default_rng(1).uniform(-0.01, 0.01, (16, 4))
    n = np.array([100, 10000])
    floor = float32_floor(chain([0.815, 3.099]), y0, 10.0, n)
    eps32 = float(np.finfo(np.float32).eps)
    assert floor[1] > 3 * floor[0]  # grows with the step count
    ratio = floor / (np.sqrt(n) * eps32)
    assert ((ratio > 0.2) & (ratio < 5.0)).all(), ratio


@pytest.mark.parametrize("name, params, swept", [
    ("planar4", {"m": 1.0, "k": 10.0, "l": 1.0}, "k"),
    ("oscillator2d", {"m": 1.0, "kx": 10.0, "ky": 20.0}, "ky"),
    ("pendulums", {"m": 1.0, "length": 1.0, "g": 9.81, "k": 5.0}, "length"),
    ("triangle", {"m": 1.0, "k": 10.0, "side": 1.0}, "side"),
])
def test_every_two_dof_model_per_instance(name, params, swept):
    # the exact (nonlinear) planar models and the potential-defined ones: each
    # instance with its own parameter, against rk4h.solve on that instance
    model = rk4h.make_model(name, params)
    rng = np.random.default_rng(2)
    y0 = rng.uniform(-0.1, 0.1, (4, 2 * model.n_dof))
    values = rng.uniform(0.5, 2.0, 4)
    values[2] = params[swept]  # equal numbers can print another force (shared constants): a second structure
    # every other parameter as model.params() gives it (pendulums: the separation the base length implied)
    ref = np.stack([rk4h.solve(rk4h.make_model(name, {**model.params(), swept: values[b]}).rhs, (0.0, 1.0), y0[b],
                                  h=0.01, method="stormer-verlet").y.T for b in range(4)])
    res = ensemble(model, y0, (0.0, 1.0), h=0.01, method="stormer-verlet", params={swept: values}, backend="numba")
    assert np.array_equal(res.y, ref)
    if pytest.importorskip("jax", reason="jax is not installed (the gpu extra)"):
        res = ensemble(model, y0, (0.0, 1.0), h=0.01, method="stormer-verlet", params={swept: values},
                       backend="jax")
        assert _rel(res.y, ref) <= 1e-13


def test_second_process_loads_the_batch_wrapper_from_the_disk_cache():
    # The prange wrapper is generated beside its loop and loaded through codegen's loader: after
    # this process has run a batch, a new process finds the wrapper in numba's on-disk cache (no
    # compilation), and its instances still equal the scalar path bit for bit.
    code = ("import numpy as np, rk4h\n"
            "from rk4h.batch import _numba\n"
            "from rk4h.references.solvers import integrate\n"
            "m = rk4h.make_model('chain', {'masses': [0.815, 3.099], 'springs': [41.5, 138.0, 157.8]})\n"
            "y0 = np.tile(m.state(np.array([0.005, 0.005])), (3, 1)); y0[:, 0] *= [0.5, 1.0, 1.5]\n"
            "te = np.array([0.0, 0.5])\n"
            "r = rk4h.ensemble(m, y0, (0.0, 0.5), h=0.01, method='rk4', backend='numba', t_eval=te)\n"
            "(fn,) = _numba._BATCH.values()\n"
            "same = all(np.array_equal(r.y[i], integrate('rk4', m, y0[i].copy(), te, 0.01).y.T) for i in range(3))\n"
            "print(sum(fn.stats.cache_misses.values()), sum(fn.stats.cache_hits.values()), same)\n")
    first = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300, check=True)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300, check=True)
    assert first.stdout.split()[2] == "True"
    misses, hits, same = out.stdout.split()
    assert (int(misses), int(hits), same) == (0, 1, "True")
