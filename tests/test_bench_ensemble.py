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
