"""Networks compiled like chains (issue 29): the network's fused slope (the
force inlined, one branch-free pass over the edge list) gives the numbers of
the numpy right-hand side and of the two-pass default slope, bit for bit."""
from __future__ import annotations

import numpy as np
import pytest

import rk4h
import rk4h.fast as fast
from rk4h.models.compiled import ForceKernel, SpringKernel


def _random_network(dim, n, n_anchors, seed):
    rng = np.random.default_rng(seed)
    positions = rng.uniform(-1.0, 1.0, n * dim).tolist()
    anchors = rng.uniform(-2.0, 2.0, n_anchors * dim).tolist()
    springs, seen = [], set()
    nodes = n + n_anchors
    while len(springs) < 2 * n + n_anchors:
        a, b = (int(v) for v in rng.integers(0, nodes, 2))
        key = (min(a, b), max(a, b))
        if a == b or (a >= n and b >= n) or key in seen:
            continue
        seen.add(key)
        spring = [a, b, float(rng.uniform(5.0, 50.0))]
        if rng.random() < 0.3:  # pre-stressed
            spring.append(float(rng.uniform(0.1, 1.0)))
        springs.append(spring)
    model = rk4h.make_model("network", {"dim": dim, "masses": rng.uniform(0.2, 2.0, n).tolist(),
                                           "positions": positions, "springs": springs, "anchors": anchors})
    y = np.concatenate([0.05 * rng.standard_normal(model.n_dof), rng.standard_normal(model.n_dof)])
    return model, y


def _default_slope_module(kern):
    """The kernel's module built with the base class's two-pass slope (force, then v and F / m)."""
    from rk4h.fast.codegen import _module, model_source

    class TwoPass(SpringKernel):
        slope_source = ForceKernel.slope_source
        inline_slope = True

    two = TwoPass.__new__(TwoPass)
    two.__dict__.update({k: v for k, v in kern.__dict__.items() if not k.startswith("_")})
    return _module(model_source(two)), two


@pytest.mark.parametrize("dim, n, n_anchors, seed", [(2, 2, 4, 0), (2, 7, 3, 1), (1, 5, 2, 2), (2, 40, 10, 3),
                                                     (1, 30, 0, 4)])
def test_fused_slope_equals_numpy_and_two_pass(dim, n, n_anchors, seed):
    model, y = _random_network(dim, n, n_anchors, seed)
    kern = model.force_kernel()
    assert "force(" not in kern.slope_source()  # the force is inside the slope: no call per stage
    rhs = fast.compiled_rhs(model)
    np.testing.assert_array_equal(rhs(0.0, y), model.rhs(0.0, y))
    module, two = _default_slope_module(kern)
    out = np.empty((2, y.shape[0]))
    module.rhs(two.fp, two.ip, model.mass, y, out, 1, model.n_dof, np.zeros(two.work_size))
    np.testing.assert_array_equal(rhs(0.0, y), out[1])


# 4 degrees of freedom, an 84-line force: the straight-line loop; 24: the array loop
@pytest.mark.parametrize("dim, n, n_anchors, seed", [(2, 2, 4, 5), (2, 12, 6, 6)])
def test_network_loop_equals_python_loop(dim, n, n_anchors, seed):
    model, y = _random_network(dim, n, n_anchors, seed)
    y[model.n_dof:] *= 0.01
    t = np.linspace(0.0, 0.2, 7)
    res = fast.solve_model(model, (0.0, 0.2), y, h=0.01, t_eval=t)
    ref = rk4h.solve(model.rhs, (0.0, 0.2), y, h=0.01, t_eval=t)
    assert res.success and ref.success
    np.testing.assert_array_equal(res.y, ref.y)



def test_a_force_longer_than_the_bound_runs_the_array_loop():
    # The network docs/performance.md measures the bound on
    # (benchmarks/bench_compile_options.py's `net`): 4 masses in the plane (8
    # degrees of freedom), every pair joined and each tied to two anchors, 14
    # springs, a straight-line force of 148 lines, over
    # codegen.MAX_UNROLLED_FORCE_LINES: the array loop (whose compile does not
    # grow with the edge list), with the same numbers.
    import pathlib
    import sys

    from rk4h.fast import codegen
    from rk4h.fast.solve import _loop_of
    from rk4h.methods import RK4

    benchmarks = str(pathlib.Path(__file__).resolve().parents[1] / "benchmarks")
    sys.path.insert(0, benchmarks)
    try:
        import bench_compile_options
    finally:
        sys.path.remove(benchmarks)
    model = bench_compile_options.model(4, "net")
    kern = fast.force_kernel(model)
    assert kern.has_scalar() and kern.scalar_size() > codegen.MAX_UNROLLED_FORCE_LINES
    assert _loop_of(model, "rk4") is codegen.array_kernel(RK4, kern)
    y = np.concatenate([np.linspace(-0.01, 0.02, model.n_dof), np.zeros(model.n_dof)])
    t = np.linspace(0.0, 0.2, 7)
    res = fast.solve_model(model, (0.0, 0.2), y, h=0.01, t_eval=t)
    ref = rk4h.solve(model.rhs, (0.0, 0.2), y, h=0.01, t_eval=t)
    assert res.success and not np.array_equal(res.y[:, -1], y)
    np.testing.assert_array_equal(res.y, ref.y)

def test_work_array_holds_forces_positions_and_sums():
    model, _ = _random_network(2, 7, 3, 1)
    kern = model.force_kernel()
    assert kern.work_size == (kern.n_springs + 2 * (kern.n_masses + kern.n_anchors)) * kern.dim


def test_benchmark_prints_ratios_and_bit_identity():
    import subprocess
    import sys
    from pathlib import Path

    root = Path(__file__).resolve().parent.parent
    proc = subprocess.run([sys.executable, str(root / "benchmarks" / "bench_network.py"), "--repeats", "1"],
                          capture_output=True, text=True, timeout=600, cwd=root)
    assert proc.returncode == 0, proc.stderr
    rows = [line for line in proc.stdout.splitlines() if "per spring-step" in line]
    assert [r.split()[0] for r in rows] == ["network_web", "lattice"]
    assert all("ratio" in r and r.endswith("bit-identical True") for r in rows), proc.stdout
    bad = subprocess.run([sys.executable, str(root / "benchmarks" / "bench_network.py"), "--repeats", "0"],
                         capture_output=True, text=True, timeout=600, cwd=root)
    assert bad.returncode == 2
    assert bad.stderr.strip().splitlines() == ["bench_network: `--repeats` must be >= 1, got 0"]
