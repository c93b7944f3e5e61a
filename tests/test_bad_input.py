"""Bad input is refused with one line naming the file, the field and the value:
a table of broken scene files, flags and API arguments, and a property test
that mutates valid scenes and asserts they are accepted or refused cleanly."""
import copy
import math
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from rk4h.validation import budget
from rk4h.validation.run_all import main, run
from rk4h.validation.scenes import SCENE_DIR, SceneError, load_scene, load_scenes, scene_from_dict

REPO = Path(__file__).resolve().parent.parent

VALID = """\
name = "valid"
description = "a valid scene each case below breaks in one place"
model = "chain"
[params]
masses = [0.815, 3.099]
springs = [41.5, 138.0, 157.8]
walls = "both"
[initial]
x = [0.005, 0.005]
v = [0.0, 0.0]
[run]
t_end = 1.0
h = [0.1, 0.05]
tolerances = [1e-6, 1e-8]
solvers = ["rk4", "dop853"]
outputs = ["state", "energy"]
"""

# (case id, text replaced, replacement, field named, text of the value the message must show)
SCENE_CASES = [
    ("toml-syntax", "t_end = 1.0", "t_end = ", "file", "not valid TOML"),
    ("toml-unclosed-list", "h = [0.1, 0.05]", "h = [0.1, 0.05", "file", "not valid TOML"),
    ("toml-duplicate-key", "t_end = 1.0", "t_end = 1.0\nt_end = 2.0", "file", "not valid TOML"),
    ("unknown-model", 'model = "chain"', 'model = "spring"', "model", "'spring'"),
    ("model-not-a-string", 'model = "chain"', "model = [1]", "model", "[1]"),
    ("unknown-top-key", 'model = "chain"', 'model = "chain"\ncolour = "red"', "colour", "unknown key"),
    ("unknown-param", 'walls = "both"', 'walls = "both"\nmass = 1.0', "params.mass", "unknown"),
    ("unknown-run-key", "t_end = 1.0", "t_end = 1.0\nsteps = 10", "run.steps", "unknown key"),
    ("unknown-initial-key", "v = [0.0, 0.0]", "v = [0.0, 0.0]\nw = 1", "initial.w", "unknown key"),
    ("missing-name", 'name = "valid"\n', "", "name", "missing"),
    ("missing-t_end", "t_end = 1.0\n", "", "run.t_end", "missing"),
    ("params-not-a-table", "[params]", "params = 3\n[params_]", "params_", "unknown key"),
    ("negative-mass", "masses = [0.815, 3.099]", "masses = [0.815, -1.0]", "params.masses[1]", "-1.0"),
    ("zero-stiffness", "springs = [41.5, 138.0, 157.8]", "springs = [41.5, 0.0, 157.8]",
     "params.springs[1]", "0.0"),
    ("nan-mass", "masses = [0.815, 3.099]", "masses = [nan, 3.099]", "params.masses[0]", "nan"),
    ("inf-stiffness", "springs = [41.5, 138.0, 157.8]", "springs = [41.5, inf, 157.8]",
     "params.springs[1]", "inf"),
    ("string-mass", "masses = [0.815, 3.099]", 'masses = [0.815, "3"]', "params.masses[1]", "'3'"),
    ("wrong-spring-count", "springs = [41.5, 138.0, 157.8]", "springs = [41.5, 138.0]",
     "params.springs", "[41.5, 138.0]"),
    ("bad-walls", 'walls = "both"', 'walls = "ceiling"', "params.walls", "'ceiling'"),
    ("short-x", "x = [0.005, 0.005]", "x = [0.005]", "initial.x", "[0.005]"),
    ("long-v", "v = [0.0, 0.0]", "v = [0.0, 0.0, 0.0]", "initial.v", "[0.0, 0.0, 0.0]"),
    ("x-not-a-list", "x = [0.005, 0.005]", 'x = "0.005"', "initial.x", "'0.005'"),
    ("inf-x", "x = [0.005, 0.005]", "x = [-inf, 0.005]", "initial.x[0]", "-inf"),
    ("zero-t_end", "t_end = 1.0", "t_end = 0.0", "run.t_end", "0.0"),
    ("negative-t_end", "t_end = 1.0", "t_end = -5.0", "run.t_end", "-5.0"),
    ("nan-t_end", "t_end = 1.0", "t_end = nan", "run.t_end", "nan"),
    ("bool-t_end", "t_end = 1.0", "t_end = true", "run.t_end", "True"),
    ("zero-h", "h = [0.1, 0.05]", "h = [0.1, 0.0]", "run.h[1]", "0.0"),
    ("negative-h", "h = [0.1, 0.05]", "h = [-0.1]", "run.h[0]", "-0.1"),
    ("h-above-t_end", "h = [0.1, 0.05]", "h = [2.0]", "run.h[0]", "2.0"),
    ("empty-h", "h = [0.1, 0.05]", "h = []", "run.h", "[]"),
    ("tolerance-one", "tolerances = [1e-6, 1e-8]", "tolerances = [1.0]", "run.tolerances[0]", "1.0"),
    ("tolerance-zero", "tolerances = [1e-6, 1e-8]", "tolerances = [0.0]", "run.tolerances[0]", "0.0"),
    ("tolerance-above-one", "tolerances = [1e-6, 1e-8]", "tolerances = [1e-6, 5]",
     "run.tolerances[1]", "5"),
    ("empty-tolerances", "tolerances = [1e-6, 1e-8]", "tolerances = []", "run.tolerances", "[]"),
    ("unknown-solver", 'solvers = ["rk4", "dop853"]', 'solvers = ["rk4", "rk45"]', "run.solvers[1]",
     "'rk45'"),
    ("empty-solvers", 'solvers = ["rk4", "dop853"]', "solvers = []", "run.solvers", "[]"),
    ("unknown-output", 'outputs = ["state", "energy"]', 'outputs = ["state", "plots"]',
     "run.outputs[1]", "'plots'"),
    ("empty-outputs", 'outputs = ["state", "energy"]', "outputs = []", "run.outputs", "[]"),
    ("output_dt-beyond-double", "t_end = 1.0", "t_end = 1.0\noutput_dt = 1" + "0" * 400,
     "run.output_dt", "exceeds the double range"),  # TOML integers are unbounded in tomllib
    ("max_output_points-one", "t_end = 1.0", "t_end = 1.0\nmax_output_points = 1",
     "run.max_output_points", "1"),
    ("max_output_points-float", "t_end = 1.0", "t_end = 1.0\nmax_output_points = 10.5",
     "run.max_output_points", "10.5"),
    ("runaway-steps", "t_end = 1.0", "t_end = 1e8\noutput_dt = 1e4", "run", "integration steps"),
    ("runaway-memory", 'h = [0.1, 0.05]', "h = [0.1, 0.05]\noutput_dt = 0.1", "run", "GiB"),
    ("name-with-newline", 'name = "valid"', 'name = "valid\\n"', "name", "'valid\\n'"),
    ("name-too-long", 'name = "valid"', f'name = "{"v" * 101}"', "name", "vvvv"),
    ("h-not-dividing-at-step-slack", "h = [0.1, 0.05]", "h = [0.03333333333]\noutput_dt = 0.1",
     "run.h[0]", "0.03333333333"),
    ("runaway-truth", 'model = "chain"', 'model = "planar4"', "run", "quadruple-precision steps"),
    ("denormal-mass", "masses = [0.815, 3.099]", "masses = [5e-324, 3.099]", "params.masses[0]", "5e-324"),
]


def _memory_case(text):
    # 5e8 output points of a 2-DOF chain: 8 B x 4 x 5e8 = 16 GB > 4 GiB, few steps
    return text.replace("t_end = 1.0", "t_end = 5e7").replace("h = [0.1, 0.05]", "h = [0.1]") \
        .replace('solvers = ["rk4", "dop853"]', 'solvers = ["dop853"]') \
        .replace('outputs = ["state", "energy"]', 'outputs = ["modes"]')


def _truth_case(text):
    # planar4 (nonlinear: a quadruple-precision reference) over 1e5 s: ~5e6 Taylor steps, ~80 min
    return text.replace("masses = [0.815, 3.099]\nsprings = [41.5, 138.0, 157.8]\nwalls = \"both\"",
                        "m = 0.815\nk = 41.5\nl = 0.01\nlinear = false") \
        .replace("t_end = 1.0", "t_end = 1e5").replace("h = [0.1, 0.05]", "h = [0.1]") \
        .replace('solvers = ["rk4", "dop853"]', 'solvers = ["heyoka"]') \
        .replace("x = [0.005, 0.005]", "x = [0.001, 0.0]")


def _scene_text(case, old, new):
    assert VALID.count(old) == 1, f"case {case}: {old!r} must occur once in VALID"
    text = VALID.replace(old, new)
    return {"runaway-memory": _memory_case, "runaway-truth": _truth_case}.get(case, lambda t: t)(text)


def _load_and_check(path):
    """What run_all does before anything runs: load and validate, then the caps."""
    for s in load_scenes([path]):
        budget.check(s)


def test_valid_scene_is_accepted(tmp_path):
    # guards the table: every case differs from this accepted file in one place
    p = tmp_path / "valid.toml"
    p.write_text(VALID)
    _load_and_check(p)


def _fifo(d):
    import os

    p = d / "pipe.toml"
    os.mkfifo(p)
    return [p]


def _oversize(d):
    p = d / "big.toml"
    p.write_text(VALID + "#" * (1 << 20))
    return [p]


def _dup(a, b):
    def make(d):
        pa, pb = d / "a.toml", d / "b.toml"
        pa.write_text(VALID.replace('name = "valid"', f'name = "{a}"'))
        pb.write_text(VALID.replace('name = "valid"', f'name = "{b}"'))
        return [pa, pb]
    return make


# (case, make(dir) -> scene paths, field, text in the message); each must refuse within seconds
FILE_CASES = [
    ("fifo", _fifo, "file", "it is a FIFO"),
    ("dev-zero", lambda d: [Path("/dev/zero")], "file", "it is a device"),
    ("directory", lambda d: [d], "file", "it is a directory"),
    ("oversize", _oversize, "file", "above the 1048576-byte cap"),
    ("missing", lambda d: [d / "missing.toml"], "file", "cannot be read"),
    ("not-utf8", lambda d: [d / "x.toml"] if (d / "x.toml").write_bytes(b"name = \"\xff\"") else [],
     "file", "not UTF-8"),
    ("same-name", _dup("dup-a", "dup-a"), "name", "is also used by"),
    ("names-whose-figures-collide", _dup("dup-a", "dup_a"), "name", "figure files would collide"),
]


@pytest.mark.parametrize("case, make, fld, shown", FILE_CASES, ids=[c[0] for c in FILE_CASES])
def test_bad_scene_file_kind_is_refused_promptly(tmp_path, case, make, fld, shown):
    import time

    paths = make(tmp_path)
    start = time.monotonic()
    with pytest.raises(SceneError) as info:
        load_scenes(paths)
    assert time.monotonic() - start < 5.0
    assert info.value.field == fld and shown in str(info.value) and "\n" not in str(info.value), str(info.value)


def test_scene_by_shipped_name():
    assert [s.name for s in load_scenes(["three-blocks", "thesis_2dof_case1"])] == ["three-blocks",
                                                                                    "thesis-2dof-case1"]


@pytest.mark.parametrize("case, old, new, fld, shown", SCENE_CASES, ids=[c[0] for c in SCENE_CASES])
def test_bad_scene_file_gives_one_line_naming_file_field_value(tmp_path, case, old, new, fld, shown):
    p = tmp_path / f"{case}.toml"
    p.write_text(_scene_text(case, old, new))
    with pytest.raises(SceneError) as info:
        _load_and_check(p)
    msg = str(info.value)
    assert "\n" not in msg
    assert msg.startswith(f"{p}: field `{fld}`: "), msg
    assert info.value.field == fld
    assert shown in msg, msg


# -- the command line, in-process (exit status and stderr of main()) --------------
def _exit_code(argv):
    try:
        return main(argv)
    except SystemExit as e:  # argparse refuses a flag this way
        return e.code


CLI_CASES = [
    # (case id, argv, text the one stderr line must hold)
    ("repeats-zero", ["--repeats", "0"], "--repeats: must be an integer from 1 to 100, got '0'"),
    ("repeats-text", ["--repeats", "many"], "--repeats: must be an integer from 1 to 100, got 'many'"),
    ("repeats-huge", ["--repeats", "1000000000"], "--repeats: must be an integer from 1 to 100, got '1000000000'"),
    ("repeats-float", ["--repeats", "1.5"], "got '1.5'"),
    ("max-output-points-one", ["--max-output-points", "1"], "--max-output-points: must be an integer >= 2"),
    ("max-steps-negative", ["--max-steps", "-1"], "--max-steps: must be a positive finite number, got '-1'"),
    ("max-steps-nan", ["--max-steps", "nan"], "got 'nan'"),
    ("max-steps-inf", ["--max-steps", "inf"], "got 'inf'"),
    ("unknown-flag", ["--fast"], "unrecognized arguments: --fast"),
    ("flag-without-value", ["--out"], "--out: expected one argument"),
    ("missing-scene-file", ["--scene", "nowhere.toml"], "nowhere.toml: field `file`: cannot be read"),
    ("scene-is-a-directory", ["--scene", "validation"], "validation: field `file`: must be a regular file, but it is a directory"),
    ("out-is-a-file", ["--scene", "SCENE", "--out", "README.md"], f"--out {REPO / 'README.md'} exists and is not a directory"),
]


@pytest.mark.parametrize("case, argv, expected", CLI_CASES, ids=[c[0] for c in CLI_CASES])
def test_bad_flag_exits_2_with_one_line(capsys, monkeypatch, tmp_path, case, argv, expected):
    monkeypatch.chdir(REPO)
    scene = tmp_path / "valid.toml"
    scene.write_text(VALID)
    rc = _exit_code([str(scene) if a == "SCENE" else a for a in argv])
    err = capsys.readouterr().err
    assert rc == 2
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert expected in lines[0]


# -- API arguments -------------------------------------------------------------------
def _valid_scene(tmp_path):
    p = tmp_path / "valid.toml"
    p.write_text(VALID)
    return load_scene(p)


API_CASES = [
    ("scenes-a-string", lambda s, d: run("valid.toml", d), "`scenes`"),
    ("scenes-of-dicts", lambda s, d: run([{"name": "x"}], d), "`scenes[0]`"),
    ("out_dir-missing", lambda s, d: run([s], d / "nowhere"), "`out_dir`"),
    ("out_dir-none", lambda s, d: run([s], None), "`out_dir`"),
    ("repeats-zero", lambda s, d: run([s], d, repeats=0), "`repeats`"),
    ("repeats-float", lambda s, d: run([s], d, repeats=1.5), "`repeats`"),
    ("repeats-bool", lambda s, d: run([s], d, repeats=True), "`repeats`"),
    ("repeats-huge", lambda s, d: run([s], d, repeats=10**9), "`repeats`"),
    ("quick-string", lambda s, d: run([s], d, quick="yes"), "`quick`"),
    ("figures-int", lambda s, d: run([s], d, figures=2), "`figures`"),
    ("progress-not-callable", lambda s, d: run([s], d, progress=5), "`progress`"),
    ("doc-not-a-table", lambda s, d: scene_from_dict([1, 2], "api.toml"), "field `file`"),
]


@pytest.mark.parametrize("case, call, named", API_CASES, ids=[c[0] for c in API_CASES])
def test_bad_api_argument_raises_value_error_naming_it(tmp_path, case, call, named):
    s = _valid_scene(tmp_path)
    out = tmp_path / "out"
    out.mkdir()
    with pytest.raises(ValueError) as info:
        call(s, out)
    msg = str(info.value)
    assert "\n" not in msg and named in msg, msg
    assert list(out.iterdir()) == []  # refused before anything was written


# -- a few real subprocesses: exit 2, one line, no traceback -------------------------
@pytest.mark.parametrize("case, argv", [
    ("bad-scene", ["--scene", "BAD"]),
    ("bad-flag", ["--max-output-points", "zero"]),
    ("runaway", ["--scene", "RUNAWAY"]),
])
def test_cli_subprocess_exits_2_without_traceback(tmp_path, case, argv):
    bad = tmp_path / "bad.toml"
    bad.write_text(VALID.replace("t_end = 1.0", "t_end = -1.0"))
    runaway = tmp_path / "runaway.toml"
    runaway.write_text(VALID.replace("t_end = 1.0", "t_end = 1e9\noutput_dt = 1e3"))
    argv = [str(bad) if a == "BAD" else str(runaway) if a == "RUNAWAY" else a for a in argv]
    out = tmp_path / "out"
    r = subprocess.run([sys.executable, "validation/run_all.py", *argv, "--out", str(out)], cwd=REPO,
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 2, r.stderr
    assert "Traceback" not in r.stderr
    assert len(r.stderr.strip().splitlines()) == 1, r.stderr
    assert not out.exists() and [p.name for p in tmp_path.iterdir() if p.name.startswith(".")] == []


# -- property: mutated valid scenes are accepted or refused cleanly --------------------
SHIPPED = {p.name: p.read_text() for p in sorted(SCENE_DIR.glob("*.toml"))}
DOCS = {name: tomllib.loads(text) for name, text in SHIPPED.items()}

BAD_VALUES = st.one_of(
    st.sampled_from([math.nan, math.inf, -math.inf, -1.0, 0, 0.0, -(10**30), 10**30, 10**400, 1e308,
                     1e-300, -1e-300, "", "x", "chain", [], {}, True, False, [1.0, "a"], [[1.0]],
                     [math.nan], {"studies": []}]),
    st.floats(allow_nan=True, allow_infinity=True),
    st.integers(min_value=-(10**20), max_value=10**20),
    st.text(max_size=4),
    st.lists(st.floats(allow_nan=True, allow_infinity=True, width=64), max_size=4),
)


def _paths(node, prefix=()):
    items = node.items() if isinstance(node, dict) else enumerate(node) if isinstance(node, list) else ()
    for k, v in items:
        yield prefix + (k,)
        yield from _paths(v, prefix + (k,))


def _refused_cleanly(err: SceneError, where: str):
    msg = str(err)
    assert "\n" not in msg and msg.startswith(f"{where}: field `"), msg


@settings(max_examples=80, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
@given(name=st.sampled_from(sorted(DOCS)), data=st.data())
def test_mutated_scene_document_is_accepted_or_refused_cleanly(name, data):
    doc = copy.deepcopy(DOCS[name])
    for _ in range(data.draw(st.integers(1, 3), label="mutations")):
        path = data.draw(st.sampled_from(list(_paths(doc)) or [("name",)]), label="path")
        parent = doc
        for k in path[:-1]:
            parent = parent[k]
        action = data.draw(st.sampled_from(["delete", "replace", "swap-type", "add-key"]), label="action")
        key = path[-1]
        if action == "delete":
            del parent[key]
        elif action == "replace":
            parent[key] = data.draw(BAD_VALUES, label="value")
        elif action == "swap-type":
            old = parent[key]
            parent[key] = [old] if not isinstance(old, list) else (old[0] if old else "")
        elif isinstance(parent, dict):
            parent[data.draw(st.sampled_from(["extra", "t_end", "h", "mode", "x"]))] = \
                data.draw(BAD_VALUES, label="value")
    try:
        scene = scene_from_dict(doc, name)
        budget.check(scene)
    except SceneError as e:
        _refused_cleanly(e, name)


@settings(max_examples=60, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.too_slow])
@given(name=st.sampled_from(sorted(SHIPPED)), data=st.data())
def test_mutated_scene_text_is_accepted_or_refused_cleanly(tmp_path_factory, name, data):
    text = SHIPPED[name]
    pos = data.draw(st.integers(0, len(text) - 1), label="position")
    cut = data.draw(st.integers(0, 8), label="deleted")
    insert = data.draw(st.sampled_from(["", "=", "[", "]", '"', "\n", "nan", "-", "1e999", "0x", "#", "\x00",
                                        "\u00e9", "[run]\n", "t_end = 0\n"]), label="inserted")
    path = tmp_path_factory.mktemp("mut") / name
    path.write_text(text[:pos] + insert + text[pos + cut:], encoding="utf-8")
    try:
        for scene in load_scenes([path]):
            budget.check(scene)
    except SceneError as e:
        _refused_cleanly(e, str(path))
