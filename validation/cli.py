"""The ``rk4h`` console command: ``rk4h run [run_all options]`` and ``rk4h
advise SCENE --target REL [--json]`` (the same as ``python
validation/run_all.py`` and ``python validation/advise.py``)."""
from __future__ import annotations

import sys

__all__ = ["main"]

_USAGE = "usage: rk4h {run,advise} ...  (rk4h run --help, rk4h advise --help)"


def main(argv=None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    if not argv or argv[0] in ("-h", "--help"):
        print(_USAGE)
        return 0 if argv else 2
    cmd, rest = argv[0], argv[1:]
    if cmd == "run":
        from validation.run_all import main as run

        return run(rest)
    if cmd == "advise":
        from validation.advise import main as adv

        return adv(rest)
    print(f"rk4h: unknown command {cmd!r}; {_USAGE}", file=sys.stderr)
    return 2


def entry() -> None:
    """The console script: an interrupted ``rk4h run`` ends as ``run_all.py`` does."""
    from validation.run_all import exit_process

    exit_process(main())


if __name__ == "__main__":
    entry()
