"""The ``rk4h`` command line: subcommands with their own help, a version,
one line for an unknown command, and progress that does not flood a log."""
import io

import pytest

from validation import run_all
from validation.cli import _COMMANDS, main, version


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


def test_top_level_help_lists_every_subcommand(capsys):
    assert main(["--help"]) == 0
    out = capsys.readouterr().out
    assert all(c in out for c in _COMMANDS) and "examples:" in out


def test_no_command_is_bad_input(capsys):
    assert main([]) == 2
    assert "usage: rk4h" in capsys.readouterr().err


def test_progress_off_a_terminal_prints_a_line_per_5_percent_or_10_s(monkeypatch):
    clock = iter(range(10**6))
    monkeypatch.setattr(run_all.time, "perf_counter", lambda: next(clock) * 1e-3)  # 1 ms per call
    out = io.StringIO()
    bar = run_all.Progress(1065, stream=out)
    for i in range(1065):
        bar(f"spec {i}")
    lines = out.getvalue().splitlines()
    assert 20 <= len(lines) <= 22, len(lines)
    assert lines[-1].startswith("[1065/1065]")


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
