"""Which optional part of the installation a command needs, and one line
saying how to get it when it is missing.

The base install (numpy, scipy) is what :func:`rk4h.solve` needs. The
report and the advisor need the extras ``fast`` (numba: the compiled
loops), ``references`` (heyoka, scikit-sundae) and ``report`` (pandas,
matplotlib, pydantic, pyarrow: the Parquet tables; xarray: netCDF trajectories); ``--scheduler`` needs ``cluster`` (dask,
distributed). ``pip install 'rk4-validation-harness[all]'`` installs them all.
"""
from __future__ import annotations

import importlib.util

__all__ = ["EXTRAS", "NEEDS", "missing", "message"]

#: Extra -> the importable modules it provides.
EXTRAS = {
    "fast": ("numba",),
    "references": ("heyoka", "sksundae"),
    "report": ("pandas", "matplotlib", "pydantic", "pyarrow", "xarray"),
    "cluster": ("dask", "distributed"),
}
#: Command -> the extras it cannot run without.
NEEDS = {
    "run": ("fast", "references", "report"),
    "advise": ("fast", "references", "report"),
    "compare": ("report",),
    "schema": ("report",),
    "cluster": ("cluster",),
}


def _importable(module: str) -> bool:
    try:
        return importlib.util.find_spec(module) is not None
    except (ImportError, ValueError):
        return False


def missing(command: str) -> list[str]:
    """The extras ``command`` needs that are not installed (in :data:`NEEDS` order)."""
    return [x for x in NEEDS[command] if not all(_importable(m) for m in EXTRAS[x])]


def message(command: str, prog: str) -> str | None:
    """One line naming the missing extras of ``command``, or None when none is missing."""
    lack = missing(command)
    if not lack:
        return None
    mods = ", ".join(m for x in lack for m in EXTRAS[x] if not _importable(m))
    return (f"{prog}: needs the extra{'s' if len(lack) > 1 else ''} {', '.join(lack)} (missing: {mods}): "
            f"pip install 'rk4-validation-harness[{','.join(lack)}]'")


def asks_help(argv) -> bool:
    """Whether a command line asks for help (``-h`` or ``--help``): help is
    printed whatever extras are missing."""
    return argv is not None and bool({"-h", "--help"} & set(argv))
