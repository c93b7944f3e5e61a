"""benchmarks/bench_ensemble.py's long-chain and diffrax parts, at toy sizes:
the jax scan and the numba loop agree on one chain; diffrax stays optional."""
import importlib.util
import sys
from pathlib import Path

import pytest

pytest.importorskip("numba", reason="numba is not installed (the fast extra)")
BENCH = Path(__file__).resolve().parent.parent / "benchmarks" / "bench_ensemble.py"


@pytest.fixture(scope="module")
def bench():
    spec = importlib.util.spec_from_file_location("bench_ensemble", BENCH)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_one_chain_numba_and_jax_agree(bench):
    pytest.importorskip("jax")
    N, steps, nb, jx, diff = bench.bench_chain(300, 7, 1, with_jax=True)
    assert (N, steps) == (300, 7) and nb > 0 and jx > 0
    assert diff <= 1e-12  # two expressions of one force: round-off apart


def test_diffrax_missing_is_one_line(bench, monkeypatch, capsys):
    monkeypatch.setitem(sys.modules, "diffrax", None)  # import diffrax raises ImportError
    assert bench.bench_diffrax(None, [10], 1) == []
    out = capsys.readouterr().out.strip().splitlines()
    assert len(out) == 1 and out[0].startswith("diffrax is not importable")


def test_kernel_sweep_compares_and_restores(bench):
    pytest.importorskip("jax")
    import numpy as np

    import rk4h
    from rk4h.batch import _jax

    before = dict(_jax.UNROLL), dict(_jax.KERNEL), _jax.LANES
    model = rk4h.make_model("chain", {"masses": bench.MASSES, "springs": bench.SPRINGS})
    variants = ["xla:1", "xla:3", "xla:8", "pallas-interpret:16"]
    rows = bench.bench_kernels(model, 40, 37, variants, 1)
    assert [r[0] for r in rows] == variants and all(r[1] > 0 for r in rows)
    assert all(r[2] for r in rows)  # every variant gives the one-step loop's states bit for bit (on the CPU)
    assert all(r[3] <= 1e-13 for r in rows)  # and the numba batch's to 1e-13 per instance
    assert (dict(_jax.UNROLL), dict(_jax.KERNEL), _jax.LANES) == before  # the package's settings are left as they were
    # the per-instance measure sees one instance off by 1e-9 of its size
    a = np.ones((3, 2, 4))
    b = a.copy()
    b[1, 1, 2] += 1e-9
    assert abs(bench.rel_diff(b, a) - 1e-9) < 1e-15


def test_overhead_benchmark_times_calls(capsys):
    spec = importlib.util.spec_from_file_location(
        "bench_ensemble_overhead", BENCH.parent / "bench_ensemble_overhead.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    ts = mod.per_call("numba", 300, 2, 3)
    assert len(ts) == 3 and all(t > 0 for t in ts)
    assert mod.main(["--B", "200", "--repeats", "2"]) == 0
    line = capsys.readouterr().out.strip().splitlines()[-1]
    assert line.startswith("numba: B = 2e+02, 2 steps: median") and "load average" in line


def test_gpu_script_parses():
    import subprocess

    script = BENCH.parent / "gpu_ensemble.sh"
    assert subprocess.run(["bash", "-n", str(script)]).returncode == 0
    # it asks for the arguments it needs instead of running with none
    r = subprocess.run(["bash", str(script)], capture_output=True, text=True)
    assert r.returncode != 0 and "usage: gpu_ensemble.sh OUTDIR" in r.stderr


def test_pallas_rows_refused_without_triton(bench, monkeypatch, capsys):
    # without Pallas' Triton backend rk4h runs jax's loops (with a warning): the
    # benchmark must not label such a row "pallas"
    pytest.importorskip("jax")
    from rk4h.batch import _jax

    monkeypatch.setattr(_jax, "_has_pallas_triton", lambda: False)
    monkeypatch.setattr(_jax, "KERNEL", dict(_jax.KERNEL))  # main sets the kernel it is asked for
    args = ["--sizes", "4", "--work", "40", "--min-steps", "10", "--repeats", "1", "--chains", "--diffrax"]
    assert bench.main(args + ["--kernels", "xla:1", "pallas:4"]) == 2
    assert bench.main(args + ["--jax-kernel", "pallas"]) == 2
    err = capsys.readouterr().err
    assert err.count("has no Pallas Triton backend") == 2
    assert _jax.KERNEL.get("cpu") == "xla"  # refused before anything was set
