"""benchmarks/bench_loop_parts.py: each cut removes its part of the generated
loop and nothing else, and refuses where the part is missing (a cut that
changed nothing would time the uncut loop). The timed run compiles six loops:
slow set. Timings are not asserted."""
import ast
import pathlib
import re
import subprocess
import sys

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[1]
SCRIPT = ROOT / "benchmarks" / "bench_loop_parts.py"
sys.path.insert(0, str(SCRIPT.parent))

import bench_loop_parts as parts  # noqa: E402

import rk4h.fast as fast  # noqa: E402
from rk4h.fast import codegen  # noqa: E402
from rk4h.methods import get_method  # noqa: E402
from rk4h.models import Chain  # noqa: E402


def _source(method, n):
    return codegen.source(get_method(method), fast.force_kernel(Chain([1.0 + 0.1 * i for i in range(n)], [1.0] * (n + 1))))


@pytest.mark.parametrize("method,n", [("rk4", 2), ("euler", 1), ("yoshida4", 3), ("rk4", 8), ("forest-ruth", 2)])
def test_each_cut_removes_its_part_and_stays_a_loop(method, n):
    src = _source(method, n)
    variants = parts.texts(src, n)
    assert variants["as generated"] == src
    lines = {name: text.count("\n") for name, text in variants.items()}
    for name, text in variants.items():
        ast.parse(text)  # still Python
        if name != "as generated":
            assert text != src and lines[name] < lines["as generated"], name
    assert "K.hermite_weights" in variants["no growth bound"] and "pending > 0.0" not in variants["no growth bound"]
    assert "K.hermite_weights" not in variants["no dense output"] and "idx[ptr] == i + 1" in variants["no dense output"]
    assert "idx[ptr]" not in variants["no output"].split("for i in range(n):")[1]
    if method == "yoshida4":  # its last stage is the end slope: no force evaluated for the dense output
        assert "no end slope" not in variants and "n_extra += 1" not in src
    else:
        assert "_Fr = n" in src and "_Fr = n" not in variants["no end slope"]
        assert "K.hermite_weights" in variants["no end slope"]
        # a start slope the dense output evaluates (forest-ruth: no stage at the step's start) stays
        assert variants["no end slope"].count("_Fr = y") == src.count("_Fr = y")
        assert (method == "forest-ruth") == ("d2 = _Fo0 / m0" in variants["no end slope"])
    assert variants["empty body"].rstrip().endswith("return n, 0, K.STATUS_OK, 0")


def test_a_missing_part_is_refused():
    src = _source("rk4", 2)
    with pytest.raises(parts.CutError, match="pending"):
        parts.texts(src.replace("if pending > 0.0:", "if pending >= 0.0:"), 2)
    with pytest.raises(parts.CutError, match="dense-output"):
        parts.without_end_slope(src.replace("            if idx[ptr] == i:\n", "            if idx[ptr] == i + 0:\n"), 2)
    with pytest.raises(parts.CutError, match="end positions"):
        parts.without_end_slope(src.replace("e0 = n2", "e0 = n2 + 0.0"), 2)


def test_bad_arguments_exit_2_with_one_line():
    for argv, field in ((["rk4", "9"], "N"), (["nosuch"], "METHOD"), (["rk4", "2", "--rounds", "0"], "--rounds")):
        proc = subprocess.run([sys.executable, str(SCRIPT), *argv], cwd=ROOT, capture_output=True, text=True,
                              timeout=120)
        assert proc.returncode == 2, (argv, proc.stderr)
        assert field in proc.stderr.strip().splitlines()[-1] and "Traceback" not in proc.stderr


@pytest.mark.slow
def test_the_benchmark_times_every_variant():
    proc = subprocess.run([sys.executable, str(SCRIPT), "euler", "1", "--rounds", "1"], cwd=ROOT,
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    rows = re.findall(r"^  (.+?)\s+median\s+([0-9.]+)\s+\(\s*\d+% of the loop's\)", proc.stdout, re.M)
    assert [name for name, _ in rows] == ["as generated", "no end slope", "no growth bound", "no dense output",
                                          "no output", "empty body"]
    assert all(float(v) > 0 for _, v in rows)


@pytest.mark.parametrize("method,n", [("rk4", 2), ("forest-ruth", 3)])
def test_the_helper_design_moves_only_the_off_grid_rows(method, n):
    src = _source(method, n)
    dim = 2 * n
    out = parts.with_helper(src, dim)
    ast.parse(out)
    assert "K.hermite_weights" in src and "K.hermite_weights" not in out
    assert out.count("hb[") == 4 * dim and out.count("_H.hermite_rows(") == 1
    assert f"hb = np.empty((4, {dim}))" in out and f"import {parts.HELPER_MODULE} as _H" in out
    # everything else is the generated loop's, line for line
    lines = src.splitlines()
    w = lines.index("                while ptr < m_out and idx[ptr] == i and theta[ptr] > 0.0:")
    assert lines[w + 2 + dim] == "                    ptr += 1"
    kept = lines[:w] + lines[w + 3 + dim:]
    assert [line for line in out.splitlines() if "hb" not in line and "_H" not in line] == kept
    with pytest.raises(parts.CutError, match="Hermite rows"):
        parts.with_helper(src, dim + 2)


@pytest.mark.slow
def test_the_helper_design_writes_the_same_rows():
    proc = subprocess.run([sys.executable, str(SCRIPT), "euler", "1", "--rounds", "1", "--helper"], cwd=ROOT,
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    assert "rows by a helper" in proc.stdout and "rows equal bit for bit: True" in proc.stdout, proc.stdout
