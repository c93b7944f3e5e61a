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
  closed pipe) is not hidden: one line on stderr, and exit status 120 in
  place of 0, as the interpreter's own exit does;
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
"""
from __future__ import annotations

import atexit
import os
import sys
import threading

__all__ = ["exit_process", "settled", "flush_streams"]


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


def _flush_stdout(code: int) -> int:
    """Flush ``sys.stdout`` as the interpreter's exit would, and return the
    exit status: where the flush fails (a full disk, a closed pipe) the
    output is incomplete, so one line on stderr says so and a status of 0
    becomes 120, the status Python's own exit gives then (another status is
    kept: it already says the command failed)."""
    try:
        sys.stdout.flush()
    except OSError as e:
        name = os.path.basename(sys.argv[0] or "") or "python"
        try:
            sys.stderr.write(f"{name}: standard output could not be written: {e.strerror or e}\n")
        except (OSError, ValueError, AttributeError):
            pass
        return code or 120
    except (ValueError, AttributeError):  # closed (flushed when it was closed) or missing
        pass
    return code


def exit_process(code: int):
    """End the process with exit status ``code`` (see the module docstring)."""
    code = int(code or 0)
    if code < 128 and not settled():
        sys.exit(code)
    if code < 128:
        atexit._run_exitfuncs()  # what the interpreter runs at exit, before its teardown
        code = _flush_stdout(code)
    flush_streams()
    os._exit(code)
