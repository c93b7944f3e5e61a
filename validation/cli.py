"""The ``rk4h`` console command.

``rk4h run [options]``        every scene (or ``--quick``, ``--scene ...``), the report in ``--out``
``rk4h advise SCENE --target REL``  the cheapest method and setting for a target, confirmed by runs
``rk4h compare OLD NEW``       what changed between two reports' tables
``rk4h schema [--markdown | --json-schema]``  the scene file reference

``rk4h run`` is ``python validation/run_all.py`` and ``rk4h advise`` is
``python validation/advise.py``; each subcommand's ``--help`` lists its
options with examples. ``rk4h --version`` prints the harness's version.
"""
from __future__ import annotations

import argparse
import sys

__all__ = ["main", "entry", "version"]

_EXAMPLES = """examples:
  rk4h run --quick --out /tmp/quick            # the quick scenes, report in /tmp/quick
  rk4h run --scene thesis-2dof-case1 --out /tmp/case1
  rk4h advise thesis-2dof-case1 --target 1e-6  # which method and step reach 1e-6, measured
  rk4h compare reports /tmp/quick              # what differs between two reports
  rk4h schema --markdown > scene-reference.md  # every key a scene may hold
"""

#: Subcommand -> (module, help line). Each module's ``main(argv, prog=...)``
#: parses the rest of the command line itself.
_COMMANDS = {
    "run": ("rk4h.validation.run_all", "run the scenes and write the report (default: every shipped scene)"),
    "advise": ("rk4h.validation.advise", "the cheapest method and setting for a target error, confirmed by runs"),
    "compare": ("rk4h.validation.compare_reports", "compare two reports' tables column by column"),
    "schema": ("rk4h.validation.scene_schema", "print the scene file reference (Markdown) or its JSON Schema"),
}


def version() -> str:
    """The installed distribution's version (one place: ``pyproject.toml``)."""
    from importlib import metadata

    try:
        return metadata.version("rk4-validation-harness")
    except metadata.PackageNotFoundError:
        return "unknown (not installed)"


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="rk4h", description="How far to trust a fixed-step integrator (classical "
                                "RK4 first) on oscillating systems: accuracy, cost, limits, alternatives.",
                                epilog=_EXAMPLES, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--version", action="version", version=f"rk4h {version()}")
    sub = p.add_subparsers(dest="command", metavar="{" + ",".join(_COMMANDS) + "}")
    for name, (_, text) in _COMMANDS.items():
        sub.add_parser(name, help=text, add_help=False)
    return p


def main(argv=None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    parser = _parser()
    if not argv:
        parser.print_help(sys.stderr)
        return 2
    if argv[0] not in _COMMANDS:
        if argv[0].startswith("-"):
            try:
                parser.parse_args(argv[:1])  # --help and --version print and exit here
            except SystemExit as e:
                return int(e.code or 0)
        print(f"rk4h: unknown command {argv[0]!r} (commands: {', '.join(_COMMANDS)}; rk4h --help)",
              file=sys.stderr)
        return 2
    module, _ = _COMMANDS[argv[0]]
    from rk4h.validation import extras

    lack = extras.message(argv[0], f"rk4h {argv[0]}")
    if lack and {"-h", "--help"} & set(argv[1:]):
        return _help_without_extras(argv[0], module, lack)
    if lack:  # before the module is imported: it may need what is missing
        print(lack, file=sys.stderr)
        return 2
    import importlib

    return importlib.import_module(module).main(argv[1:], prog=f"rk4h {argv[0]}")


def _help_without_extras(command: str, module: str, lack: str) -> int:
    """``rk4h COMMAND --help`` where COMMAND's extras are missing: its full
    help when its module imports without them, else its one-line summary;
    then the line naming the missing extras. Exit 0 (help was asked for)."""
    import importlib

    try:
        mod = importlib.import_module(module)
    except ImportError:
        print(f"usage: rk4h {command} ...\n\n{_COMMANDS[command][1]}\n")
    else:
        try:
            mod.main(["--help"], prog=f"rk4h {command}")
        except SystemExit:
            pass
    print(lack)
    return 0


def entry() -> None:
    """The console script. The process ends as ``run_all.py`` and ``advise.py``
    end theirs (:func:`rk4h.validation.process_exit.exit_process`)."""
    from rk4h.validation.process_exit import exit_process, run_main

    exit_process(run_main(main))


if __name__ == "__main__":
    entry()
