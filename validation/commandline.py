"""What the harness' ``main(argv) -> int`` functions share: argparse's
result as a value, not an exit.

A ``main`` returns its exit status (tests and ``rk4h``'s dispatcher call it
in process); argparse exits after ``--help`` and on bad arguments, so
:func:`parse` turns that exit into the status it would have had.
"""
from __future__ import annotations

import argparse
import sys

__all__ = ["parse"]


def parse(parser: argparse.ArgumentParser, argv=None) -> argparse.Namespace | int:
    """``parser.parse_args(argv)`` (``sys.argv[1:]`` when ``argv`` is None),
    or, where argparse would exit, the exit status as an ``int``: 0 after
    ``--help`` (printed), 2 for bad arguments (the usage and one error line
    on stderr)."""
    try:
        return parser.parse_args(sys.argv[1:] if argv is None else argv)
    except SystemExit as e:
        return e.code if isinstance(e.code, int) else (0 if e.code is None else 2)
