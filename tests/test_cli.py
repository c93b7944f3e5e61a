"""The ``rk4h`` command line: subcommands with their own help, a version,
one line for an unknown command, and progress that does not flood a log."""
import io

import sys

import pytest

from rk4h.validation import run_all
from rk4h.validation.cli import _COMMANDS, main, version


def test_version_is_the_distributions(capsys):
    assert main(["--version"]) == 0
    assert capsys.readouterr().out.strip() == f"rk4h {version()}"
    assert version()[0].isdigit()


@pytest.mark.parametrize("command", sorted(_COMMANDS))
def test_each_subcommand_has_its_own_help_with_examples(command, capsys):
    try:
        code = main([command, "--help"])
    except SystemExit as e:
        code = e.code
    out = capsys.readouterr().out
    assert code == 0
    assert out.startswith(f"usage: rk4h {command}"), out[:80]
    assert "examples:" in out


@pytest.mark.parametrize("command", sorted(_COMMANDS))
def test_subcommand_help_names_rk4h_commands_not_scripts(command, capsys):
    """A wheel user has no validation/*.py: the help names rk4h commands, shows no reST
    markup, and says what every positional argument is."""
    import re

    try:
        rc = main([command, "--help"])
    except SystemExit as e:
        rc = e.code
    out = capsys.readouterr().out
    assert rc in (0, None) and f"usage: rk4h {command}" in out, out[:300]  # else every check below holds on ""
    assert "``" not in out
    assert not re.search(r"(?<!python validation/)\b\w+\.py\b", out), out[:300]
    positional = out.split("positional arguments:\n", 1)[1].split("\n\n", 1)[0] if "positional arguments:" in out else ""
    for line in positional.splitlines():
        if line.startswith("  ") and not line.startswith("   "):
            assert len(line.split()) > 1, f"positional argument without a help text: {line.strip()}"


def test_top_level_help_lists_every_subcommand(capsys):
    assert main(["--help"]) == 0
    out = capsys.readouterr().out
    assert all(c in out for c in _COMMANDS) and "examples:" in out


def test_no_command_is_bad_input(capsys):
    assert main([]) == 2
    assert "usage: rk4h" in capsys.readouterr().err


def _progress(monkeypatch, n):
    """A progress bar of ``n`` specs written to a string (off a terminal), on a clock of 1 ms per call,
    after every spec has reported."""
    clock = iter(range(10**6))
    monkeypatch.setattr(run_all.time, "perf_counter", lambda: next(clock) * 1e-3)  # 1 ms per call
    out = io.StringIO()
    bar = run_all.Progress(n, stream=out)
    for i in range(n):
        bar(f"spec {i}")
    return out, bar


def test_progress_off_a_terminal_prints_a_line_per_5_percent_or_10_s(monkeypatch):
    out, bar = _progress(monkeypatch, 1065)
    bar.close()  # the runner closes it; the last line comes then
    lines = out.getvalue().splitlines()
    assert 20 <= len(lines) <= 23, len(lines)
    assert lines[0].startswith("[1/1065]") and lines[-1].startswith("[1065/1065]")


def test_progress_extended_by_confirmation_runs_still_prints_one_line_per_5_percent(monkeypatch):
    """Confirmation runs extend the plan a few specs at a time at its end: each extension used to
    complete the plan again and print a line (306 specs: [295/295], [302/302], [304/304], [306/306]
    within 1 s). At most one line per 5 % or 10 s, then the last line on close."""
    out, bar = _progress(monkeypatch, 100)
    for _ in range(3):  # three rounds of two confirmation runs
        bar.extend(2)
        bar("confirmation")
        bar("confirmation")
    bar.close()
    done = [int(line[1:].split("/")[0]) for line in out.getvalue().splitlines()]
    assert done[0] == 1 and done[-1] == 106
    gaps = [b - a for a, b in zip(done, done[1:])]
    assert all(g >= 5 for g in gaps[:-1]), done  # 5 % of 100..106 specs; the closing line may be closer


def test_progress_off_a_terminal_prints_every_10_s_when_specs_are_slow(monkeypatch):
    t = [0.0]

    def tick():
        t[0] += 12.0  # 12 s between two specs
        return t[0]

    monkeypatch.setattr(run_all.time, "perf_counter", tick)
    out = io.StringIO()
    bar = run_all.Progress(1000, stream=out)
    for i in range(10):
        bar(f"spec {i}")
    assert len(out.getvalue().splitlines()) == 10


@pytest.mark.parametrize("command, extra", [("run", "references"), ("advise", "fast"), ("compare", "report"),
                                            ("schema", "report")])
def test_a_missing_extra_is_one_line_naming_it(command, extra, monkeypatch, capsys):
    from rk4h.validation import extras

    gone = set(extras.EXTRAS[extra])
    monkeypatch.setattr(extras, "_importable", lambda m: m not in gone)
    assert main([command]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"rk4h {command}: needs the extra {extra} " in err
    assert f"pip install 'rk4-validation-harness[{extra}]'" in err


@pytest.mark.parametrize("command, extra", [("run", "references"), ("advise", "fast"), ("compare", "report")])
def test_help_works_without_the_extras(command, extra, monkeypatch, capsys):
    from rk4h.validation import extras

    gone = set(extras.EXTRAS[extra])
    monkeypatch.setattr(extras, "_importable", lambda m: m not in gone)
    assert main([command, "--help"]) == 0
    out = capsys.readouterr().out
    assert f"usage: rk4h {command}" in out
    assert out.rstrip().splitlines()[-1].startswith(f"rk4h {command}: needs the extra {extra} ")


@pytest.mark.parametrize("command", ["run", "advise"])
def test_help_without_extras_when_the_module_cannot_import(command, monkeypatch, capsys):
    import importlib

    from rk4h.validation import cli, extras

    monkeypatch.setattr(extras, "_importable", lambda m: m != "numba")
    module, real = cli._COMMANDS[command][0], importlib.import_module

    def import_module(name, *args):
        if name == module:
            raise ModuleNotFoundError(f"No module named {name!r}")
        return real(name, *args)

    monkeypatch.setattr(importlib, "import_module", import_module)
    assert main([command, "--help"]) == 0
    out = capsys.readouterr().out
    assert out.startswith(f"usage: rk4h {command} ...") and cli._COMMANDS[command][1] in out
    assert "needs the extra" in out.rstrip().splitlines()[-1]


def test_scheduler_needs_the_cluster_extra(monkeypatch, capsys):
    from rk4h.validation import extras

    monkeypatch.setattr(extras, "_importable", lambda m: m not in {"dask", "distributed"})
    assert main(["run", "--scheduler", "tcp://127.0.0.1:1", "--out", "/nonexistent/x"]) == 2
    assert "needs the extra cluster" in capsys.readouterr().err


def test_nothing_missing_here():
    from rk4h.validation import extras

    assert all(extras.missing(c) == [] for c in extras.NEEDS)


def test_rk4core_solves_without_any_extra():
    """The base install: numpy and scipy only. Every extra's modules are made
    unimportable in a fresh interpreter; rk4core imports and solves."""
    import subprocess
    import sys

    from rk4h.validation import extras

    blocked = [m for mods in extras.EXTRAS.values() for m in mods]
    code = (f"import sys\nfor m in {blocked!r}: sys.modules[m] = None\n"
            "import numpy as np, rk4h\n"
            "res = rk4h.solve(lambda t, y: [y[1], -y[0]], (0.0, 10.0), [1.0, 0.0], h=0.01)\n"
            "assert abs(res.y[0, -1] - np.cos(10.0)) < 1e-8, res.y[0, -1]\n"
            "m = rk4h.make_model('chain', {'masses': [1.0, 2.0], 'springs': [1.0, 2.0, 3.0]})\n"
            "assert rk4h.solve(m.rhs, (0.0, 1.0), m.state([0.01, 0.0]), h=0.01).success\n"
            "print('ok')\n")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0 and proc.stdout.strip() == "ok", proc.stderr[-2000:]


@pytest.mark.parametrize("args, field", [(["--target", "2"], "--target"), (["--target", "x"], "--target"),
                                         (["--energy-target", "1e-6"], "--energy-target")])
def test_advise_errors_name_the_rk4h_command(args, field, capsys):
    assert main(["advise", "thesis-2dof-case1", *args]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith(f"rk4h advise: {field}: ")
