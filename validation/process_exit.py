"""How a command's process ends once its work is settled.

A command (``rk4h run``, ``rk4h advise``) has printed its last line and
closed every file it wrote when its ``main`` returns. What the interpreter
would still do is tear down what the command built: numba's and heyoka's
JIT-compiled code (LLVM's objects and their memory), the module tables,
every object left. That has nothing left to save, and it is slow: about
0.2 s of the thesis case's 1.05 s ``advise`` on the 2-core development
machine (``docs/performance.md``, "Twentieth round"). The worker processes
of :mod:`rk4h.validation.engine` already end without it.

:func:`exit_process` ends the process at once only where nothing of
Python's is still running:

* the ``atexit`` handlers run first (a ``weakref.finalize`` with
  ``atexit=True``, such as a ``TemporaryDirectory``'s clean-up, is one);
* standard output is flushed, and a flush that fails (a full disk, a
  closed pipe) is not hidden: one line on stderr, and exit status 3 (the
  environment refused: it cannot be written) in place of 0;
* a non-daemon thread still alive (an unjoined pool's thread, a user's) or
  a ``multiprocessing`` child still running means the interpreter's own
  exit, which joins them, so the process ends with :func:`sys.exit` there;
* an interrupted run (``code >= 128``) ends at once in any case, after its
  streams are flushed: the worker processes it killed can leave a
  ``concurrent.futures`` manager thread waiting on a queue forever, and the
  interpreter would join it (seen once in CI under load: a SIGTERM'd run
  printed its line, then hung 120 s).

What this asks of a command: every file it writes is closed (``with``
blocks, :mod:`rk4h.validation.atomic`) before ``main`` returns. A file object
left open would lose its buffer, where the interpreter's teardown would
have flushed it.

:func:`run_main` calls a command's ``main`` so that a write that fails
because the environment refused it (the reader of standard output has
gone, a full disk or quota) ends the command with one line and status 3,
not a traceback: ``rk4h compare OLD NEW | head -1`` is a normal use.
"""
from __future__ import annotations

import atexit
import errno
import os
import sys
import threading

__all__ = ["exit_process", "run_main", "settled", "flush_streams"]

#: The exit status of a command whose output the environment refused (the
#: harness's status for "cannot write, disk full").
REFUSED = 3
#: Errors of a write that say the environment refused it, not that the
#: command is wrong: a full disk, a full quota (a closed pipe is
#: ``BrokenPipeError``).
_REFUSED_WRITE = (errno.ENOSPC, errno.EDQUOT)


def settled() -> bool:
    """Whether no thread but the main one (daemon threads aside) and no
    ``multiprocessing`` child process is still running."""
    me = threading.current_thread()
    if any(t is not me and t.is_alive() and not t.daemon for t in threading.enumerate()):
        return False
    mp = sys.modules.get("multiprocessing")  # not imported: no child of its
    return mp is None or not mp.active_children()


def flush_streams():
    """Flush ``sys.stdout`` and ``sys.stderr`` (a closed or missing one is skipped)."""
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError, AttributeError):
            pass


def _say_refused(e: OSError, what: str = "") -> None:
    """One line on stderr: the command could not write (``what``: which file)."""
    name = os.path.basename(sys.argv[0] or "") or "python"
    where = what or (f" {e.filename}" if e.filename else "")
    try:
        sys.stderr.write(f"{name}: cannot write{where}: {e.strerror or e}\n")
        sys.stderr.flush()
    except (OSError, ValueError, AttributeError):
        pass


def _drop_stdout() -> None:
    """Point standard output at the null device, so that nothing buffered
    for a reader that is gone is tried again at exit."""
    try:
        null = os.open(os.devnull, os.O_WRONLY)
        os.dup2(null, sys.stdout.fileno())
        os.close(null)
    except (OSError, ValueError, AttributeError):
        pass


def _stdout_error() -> OSError | None:
    """Flush ``sys.stdout``; the error if it cannot be written (a closed or
    missing stream counts as flushed: it was flushed when it was closed)."""
    try:
        sys.stdout.flush()
    except OSError as e:
        return e
    except (ValueError, AttributeError):
        pass
    return None


def run_main(main) -> int:
    """``main()``'s exit status; where a write fails because the environment
    refused it (``BrokenPipeError``: the reader of standard output has gone;
    a full disk or quota), one line on stderr and :data:`REFUSED` in place
    of a traceback. Any other exception goes on as it would."""
    try:
        return main()
    except OSError as e:
        if not (isinstance(e, BrokenPipeError) or e.errno in _REFUSED_WRITE):
            raise
        # Standard output is the one refused when a pipe broke or it cannot be
        # flushed now; then what it still buffers goes nowhere. Another file
        # (a full disk under a cache) leaves standard output and its lines alone.
        stdout = (isinstance(e, BrokenPipeError) and not e.filename) or _stdout_error() is not None
        _say_refused(e, " standard output" if stdout and not e.filename else "")
        if stdout:
            _drop_stdout()
        return REFUSED


def exit_process(code: int):
    """End the process with exit status ``code`` (see the module docstring)."""
    code = int(code or 0)
    if code >= 128:  # interrupted: everything is settled, end at once
        flush_streams()
        os._exit(code)
    if not settled():
        sys.exit(code)
    atexit._run_exitfuncs()  # what the interpreter runs at exit, before its teardown
    # A flush that fails (a full disk, a closed pipe): the output is incomplete,
    # so one line says so and a status of 0 becomes REFUSED (another status is
    # kept: it already says the command did not succeed).
    e = _stdout_error()
    if e is not None:
        _say_refused(e, " standard output")
        _drop_stdout()
        code = code or REFUSED
    flush_streams()
    os._exit(code)
