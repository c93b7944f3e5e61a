"""The command-method file protocol (rk4h.command, rk4h.references.solvers.command),
driven by a small Python program written to tmp_path and run with sys.executable."""
import json
import os
import sys
import textwrap

import numpy as np
import pytest

import rk4h
from rk4h.command import LAYOUT, PROTOCOL_VERSION, THESIS_CODE, expand_argv, run_command
from rk4h.models import Chain, Planar4
from rk4h.references.solvers.base import Status
from rk4h.references.solvers.command import build_problem, run_command_method

# The program: explicit Euler on y' = [v, -M^-1 K q] built from problem.json's
# stiffness_matrix and masses; its behaviour is chosen by argv[3].
PROGRAM = textwrap.dedent('''
    import json, os, sys, time
    problem_path, traj_path, mode = sys.argv[1], sys.argv[2], sys.argv[3]
    extra = sys.argv[4] if len(sys.argv) > 4 else None
    P = json.load(open(problem_path))
    if mode == "fail":
        sys.stderr.write("starting\\nboom: the matrix is singular\\n")
        sys.exit(3)
    if mode == "sleep":
        time.sleep(30)
    if mode == "copy":
        open(extra, "w").write(json.dumps(P))
    n = P["n_dof"]; K = P["stiffness_matrix"]; m = P["masses"]; h = P["h"]
    y = list(P["y0"]); rows = [[P["t0"]] + y]
    for i in range(1, P["n_steps"] + 1):
        acc = [-sum(K[r][c] * y[c] for c in range(n)) / m[r] for r in range(n)]
        y = [y[r] + h * y[n + r] for r in range(n)] + [y[n + r] + h * acc[r] for r in range(n)]
        rows.append([P["t0"] + i * h] + y)
    if mode == "teval":
        want = set(round((t - P["t0"]) / h) for t in P["t_eval"])
        rows = [r for i, r in enumerate(rows) if i in want]
    header = "t," + ",".join("y%d" % (i + 1) for i in range(2 * n))
    if mode == "bad-header":
        header = "time," + ",".join("x%d" % (i + 1) for i in range(2 * n))
    if mode == "short":
        rows = rows[:-2]
    if mode == "bad-time":
        rows[3][0] += 0.5 * h
    if mode == "nan-time":
        rows[2][0] = float("nan")
    if mode == "inf-state":
        for r in rows[5:]:
            r[1] = float("inf")
    lines = [header] + [",".join(repr(v) for v in r) for r in rows]
    if mode == "not-a-number":
        lines[4] = lines[4].replace(",", ",abc", 1)
    open(traj_path, "w").write("\\n".join(lines) + "\\n")
    if mode in ("stats", "leftovers"):
        json.dump({"nfev": 1234}, open(os.path.join(os.path.dirname(traj_path), "stats.json"), "w"))
    if mode == "bad-stats":
        open(os.path.join(os.path.dirname(traj_path), "stats.json"), "w").write('{"nfev": -1}')
    if mode == "leftovers":
        os.symlink(extra, "link-to-outside")           # cwd is the work directory
        os.mkdir("sub")
        os.symlink(os.path.dirname(extra), os.path.join("sub", "link-to-outside-dir"))
        open(os.path.join("sub", "scratch.txt"), "w").write("x")
        open("octave-workspace", "w").write("y")
''')


@pytest.fixture(scope="module")
def program(tmp_path_factory):
    path = tmp_path_factory.mktemp("prog") / "euler_program.py"
    path.write_text(PROGRAM)
    return str(path)


def argv(program, mode, *extra):
    return [sys.executable, "-I", program, "{problem}", "{trajectory}", mode, *extra]


CHAIN = Chain([0.815, 3.099], [41.5, 138.0, 157.8])
Y0 = np.array([0.005, 0.005, 0.0, 0.0])
H = 0.01
T = H * np.arange(21)


def problem(t_eval=T, model=CHAIN, y0=Y0, h=H):
    return build_problem(model, y0, t_eval, h)[0]


def test_round_trip_matches_rk4core_euler(program):
    res = run_command(argv(program, "every-step"), problem())
    assert res.status == "ok", res.message
    ref = rk4h.solve(CHAIN.rhs, (0.0, T[-1]), Y0, n_steps=20, method="euler")
    assert res.t.tolist() == T.tolist()
    assert res.y.shape == (4, 21)
    assert np.max(np.abs(res.y - ref.y)) <= 1e-15
    assert res.nfev is None and res.returncode == 0 and res.leftovers == ()


def test_t_eval_rows_and_subset(program):
    t = T[::5]
    for mode in ("every-step", "teval"):
        res = run_command(argv(program, mode), problem(t_eval=t))
        assert res.status == "ok", res.message
        ref = rk4h.solve(CHAIN.rhs, (0.0, T[-1]), Y0, n_steps=20, method="euler", t_eval=t)
        assert np.max(np.abs(res.y - ref.y)) <= 1e-15


def test_problem_file_contents(program, tmp_path):
    copy = tmp_path / "copy.json"
    res = run_command(argv(program, "copy", str(copy)), problem())
    assert res.ok, res.message
    P = json.loads(copy.read_text())
    assert P["protocol"] == PROTOCOL_VERSION == 1
    assert P["model"] == "chain" and P["params"]["springs"] == [41.5, 138.0, 157.8]
    assert P["n_dof"] == 2 and P["layout"] == LAYOUT and P["y0"] == Y0.tolist()
    assert P["t0"] == 0.0 and P["t_end"] == T[-1] and P["n_steps"] == 20 and P["h"] == pytest.approx(H)
    assert P["t_eval"] == pytest.approx(T.tolist(), abs=1e-15)
    assert P["stiffness_matrix"] == [[179.5, -138.0], [-138.0, 295.8]] and P["masses"] == [0.815, 3.099]
    assert "stiffness_matrix" in P["rhs"]
    nonlinear = build_problem(Planar4(0.815, 41.5, 1.0), Y0, T, H)[0]
    assert "stiffness_matrix" not in nonlinear and "masses" not in nonlinear
    assert nonlinear["params"] == {"m": 0.815, "k": 41.5, "l": 1.0, "linear": False}
    assert "planar4" in nonlinear["rhs"] and "0.815" in nonlinear["rhs"]


def test_stats_nfev(program):
    res = run_command(argv(program, "stats"), problem())
    assert res.ok and res.nfev == 1234


def test_missing_program_is_unavailable(tmp_path, monkeypatch):
    res = run_command(["rk4h-no-such-program-xyz", "{problem}"], problem())
    assert res.status == "unavailable" and "rk4h-no-such-program-xyz not found on PATH" in res.message
    monkeypatch.setenv("PATH", str(tmp_path))  # an empty directory: no octave-cli
    res = run_command(["octave-cli", "{thesis_code}/run_code03.m", "{problem}", "{trajectory}"], problem())
    assert res.status == "unavailable"
    assert res.message == "octave-cli not found on PATH; install GNU Octave (apt-get install -y octave)"
    res = run_command([str(tmp_path / "octave-cli")], problem())
    assert res.status == "unavailable" and "install GNU Octave" in res.message


def test_nonzero_exit_is_failed_with_last_stderr_line(program):
    res = run_command(argv(program, "fail"), problem())
    assert res.status == "failed" and res.returncode == 3
    assert res.message.endswith("exited with status 3: boom: the matrix is singular")
    assert res.y.shape == (4, 0)


@pytest.mark.parametrize("mode, words", [
    ("bad-header", "the header must be 't,y1,...,y4'"),
    ("short", "has 19 rows; expected n_steps + 1 = 21"),
    ("bad-time", "line 5: t = "),
    ("nan-time", "a time is not finite"),
    ("not-a-number", "line 5: not a number"),
    ("bad-stats", "`nfev` must be an integer >= 0"),
    ("no-output", "wrote no trajectory.csv"),
])
def test_malformed_output_is_failed(program, mode, words):
    if mode == "no-output":
        res = run_command([sys.executable, "-I", "-c", "pass"], problem())
    else:
        res = run_command(argv(program, mode), problem())
    assert res.status == "failed", res.message
    assert words in res.message, res.message


def test_timeout_kills_and_fails(program):
    res = run_command(argv(program, "sleep"), problem(), timeout=0.5)
    assert res.status == "failed" and "timed out after 0.5 s" in res.message
    assert res.wall_s < 10


def test_work_directory_removed_and_nothing_outside_touched(program, tmp_path):
    outside = tmp_path / "outside.txt"
    outside.write_text("keep me")
    (tmp_path / "other").mkdir()
    before = sorted(p.name for p in tmp_path.iterdir())
    res = run_command(argv(program, "leftovers", str(outside)), problem())
    assert res.ok, res.message
    workdir = os.path.dirname(res.argv[3])
    assert not os.path.exists(workdir)
    assert res.leftovers == ("link-to-outside", "octave-workspace", "sub")
    assert outside.read_text() == "keep me"
    assert sorted(p.name for p in tmp_path.iterdir()) == before
    for mode in ("fail", "bad-header"):
        res = run_command(argv(program, mode), problem())
        assert not os.path.exists(os.path.dirname(res.argv[3]))


def test_placeholders():
    out = expand_argv(["x", "{problem}", "--out={trajectory}", "{workdir}/a", "{thesis_code}/f.m", "{other}"],
                      problem="/w/problem.json", trajectory="/w/trajectory.csv", workdir="/w")
    assert out == ["x", "/w/problem.json", "--out=/w/trajectory.csv", "/w/a", f"{THESIS_CODE}/f.m", "{other}"]
    assert (THESIS_CODE / "run_code03.m").is_file()
    with pytest.raises(ValueError):
        expand_argv("octave-cli file.m", problem="p", trajectory="t", workdir="w")


def test_bad_problem_raises():
    bad = problem()
    bad["t_eval"] = [0.0, 0.015]
    with pytest.raises(ValueError, match="step grid"):
        run_command(["true"], bad)
    bad = problem()
    bad["y0"] = [float("nan")] * 4
    with pytest.raises(ValueError):
        run_command(["true"], bad)


def test_run_command_method(program):
    run = run_command_method("mine", argv(program, "every-step"), CHAIN, Y0, T, H)
    ref = rk4h.solve(CHAIN.rhs, (0.0, T[-1]), Y0, n_steps=20, method="euler")
    assert run.status is Status.OK and run.n_steps == 20 and run.extra["h_used"] == pytest.approx(H)
    assert np.max(np.abs(run.y - ref.y)) <= 1e-15 and run.t is not None
    assert run.nfev == 0 and run.extra["nfev_source"] == "unknown" and "nfev is unknown" in run.extra["nfev_note"]
    run = run_command_method("mine", argv(program, "every-step"), CHAIN, Y0, T, H, nfev_per_step=1)
    assert run.nfev == 20 and run.extra["nfev_source"] == "nfev_per_step"
    run = run_command_method("mine", argv(program, "stats"), CHAIN, Y0, T, H, nfev_per_step=1)
    assert run.nfev == 1234 and run.extra["nfev_source"] == "stats.json"
    run = run_command_method("mine", ["rk4h-no-such-program-xyz"], CHAIN, Y0, T, H)
    assert run.status is Status.UNAVAILABLE and np.all(np.isnan(run.y))
    run = run_command_method("mine", argv(program, "fail"), CHAIN, Y0, T, H)
    assert run.status is Status.FAILED and "boom" in run.message
    run = run_command_method("mine", argv(program, "inf-state"), CHAIN, Y0, T, H)
    assert run.status is Status.UNSTABLE and run.t_fail == pytest.approx(T[5])
    assert np.all(np.isnan(run.y[:, 5:])) and np.all(np.isfinite(run.y[:, :5]))
    run = run_command_method("mine", argv(program, "every-step"), CHAIN, Y0, [0.0, 0.015, 0.2], H)
    assert run.status is Status.FAILED and "not on the step grid" in run.message
