"""heyoka, imported without sympy.

heyoka's compiled core imports sympy when it can, for its ``to_sympy`` /
``from_sympy`` bridges, which nothing in rk4h uses; sympy is most of
heyoka's import time (about 2 s of 2.7 s on the development machine, and
that in every process that runs a heyoka reference or truth).
:func:`heyoka` imports heyoka with sympy hidden for the duration of that one
import, so its core skips the bridge; sympy itself stays importable
afterwards (a later ``import sympy`` loads it as usual). Where sympy is
already loaded nothing is hidden and heyoka gets its bridges.
"""
from __future__ import annotations

import importlib
import sys
import threading

__all__ = ["heyoka", "own_process"]

_LOCK = threading.Lock()
_OWN_PROCESS = False


def own_process() -> None:
    """Say that this process is rk4h's own (a command-line tool or one of its
    workers), where nothing needs heyoka's sympy bridges: :func:`heyoka`
    may then import heyoka without sympy."""
    global _OWN_PROCESS
    _OWN_PROCESS = True


def heyoka():
    """The ``heyoka`` module (imported on the first call; without sympy in a
    process marked by :func:`own_process` where sympy is not loaded yet);
    ``ImportError`` when heyoka is not installed, as ``import heyoka``
    would."""
    mod = sys.modules.get("heyoka")
    if mod is not None:
        return mod
    with _LOCK:
        if not _OWN_PROCESS or "sympy" in sys.modules:
            return importlib.import_module("heyoka")
        sys.modules["sympy"] = None  # an import of sympy now raises ImportError, which heyoka's core allows
        try:
            return importlib.import_module("heyoka")
        finally:
            if sys.modules.get("sympy", 0) is None:
                del sys.modules["sympy"]
