"""Whether SIGINT/SIGTERM arrived, for code that catches broad exceptions.

``run_all``'s signal handler raises ``KeyboardInterrupt`` wherever the program
is; inside a C extension's initialization that can surface as another
exception (``ImportError: initialization failed``), which a catch-all would
turn into a failed row and run on. The handler therefore also records the
signal here, and every catch-all asks :func:`pending` first.
"""
from __future__ import annotations

__all__ = ["fired", "record", "pending", "reset"]

#: The signal number received, or None.
fired: int | None = None


def record(signum: int) -> None:
    global fired
    fired = fired or signum


def pending() -> int | None:
    """The signal number if one arrived since :func:`reset`, else None."""
    return fired


def reset() -> None:
    global fired
    fired = None
