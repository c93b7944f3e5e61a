"""The generated documents under ``docs/``, written by one command.

Four documents are generated from the declarations they describe and never
edited by hand::

    python -m rk4h.validation.docs_gen            # rewrite the stale ones in docs/
    python -m rk4h.validation.docs_gen --check    # exit 1 naming each stale one; writes nothing
    python -m rk4h.validation.docs_gen --out DIR  # write all four into DIR instead

==========================  ===============================================
file                        generated from
==========================  ===============================================
``scene-reference.md``      the scene schema (:mod:`rk4h.validation.scene_schema`)
``scene.schema.json``       the same models, as JSON Schema (for editors)
``columns.md``              every table's columns (:mod:`rk4h.validation.columns`)
``stability-params.md``     ``[stability]`` keys (:mod:`rk4h.validation.stability.params`)
==========================  ===============================================

Each generator keeps its own entry point (``python -m
rk4h.validation.scene_schema --markdown``, ``python -m rk4h.validation.columns``,
``python -m rk4h.validation.stability.params``); this module only gathers them.
Only the four names above are ever written, each through a temporary file
beside it and a rename, and only when its content differs.
"""
from __future__ import annotations

import argparse
import os
import sys
import tempfile
from pathlib import Path

from .commandline import parse

__all__ = ["DOCS", "DOCS_DIR", "documents", "stale", "write", "main"]

#: The repository's ``docs/`` directory (the default target).
DOCS_DIR = Path(__file__).resolve().parent.parent / "docs"


def _scene_reference() -> str:
    from rk4h.validation.scene_schema import reference_markdown

    return reference_markdown()


def _scene_schema_json() -> str:
    from rk4h.validation.scene_schema import json_schema_text

    return json_schema_text()


def _columns() -> str:
    from rk4h.validation.columns import markdown

    return markdown()


def _stability_params() -> str:
    from rk4h.validation.stability.params import params_document

    return params_document()


#: File name under ``docs/`` -> the function that returns its text.
DOCS = {
    "scene-reference.md": _scene_reference,
    "scene.schema.json": _scene_schema_json,
    "columns.md": _columns,
    "stability-params.md": _stability_params,
}


def documents() -> dict[str, str]:
    """File name -> fresh text of every generated document (UTF-8 text)."""
    return {name: make() for name, make in DOCS.items()}


def _read(path: Path) -> str | None:
    try:
        return path.read_text(encoding="utf-8")
    except (FileNotFoundError, UnicodeDecodeError):
        return None


def stale(directory=DOCS_DIR, fresh: dict | None = None) -> list[str]:
    """Names of the generated documents in ``directory`` that are missing or
    differ from fresh output (``fresh``: :func:`documents`, computed if None)."""
    fresh = documents() if fresh is None else fresh
    directory = Path(directory)
    return [name for name, text in fresh.items() if _read(directory / name) != text]


def write(directory=DOCS_DIR) -> list[str]:
    """Write every stale generated document into ``directory`` (an existing
    directory); returns the names written. Each file is replaced by a rename
    of a complete temporary file beside it, so a reader never sees half."""
    directory = Path(directory)
    fresh = documents()
    written = []
    for name in stale(directory, fresh):
        fd, tmp = tempfile.mkstemp(prefix=f".{name}.", suffix=".tmp", dir=directory)
        try:
            with os.fdopen(fd, "w", encoding="utf-8", newline="") as f:
                f.write(fresh[name])
            os.replace(tmp, directory / name)
        except BaseException:
            try:
                os.unlink(tmp)
            except FileNotFoundError:
                pass
            raise
        written.append(name)
    return written


def main(argv=None, *, prog="python -m rk4h.validation.docs_gen") -> int:
    """Write (or with ``--check`` compare) the generated documents; returns the
    exit status: 0 done or current, 1 stale (``--check``), 2 bad arguments."""
    p = argparse.ArgumentParser(prog=prog, description="Write the generated documents (scene reference, "
                                "scene JSON Schema, table columns, stability keys) into docs/.",
                                epilog=f"documents: {', '.join(DOCS)}")
    p.add_argument("--check", action="store_true", help="write nothing; exit 1 naming each stale document")
    p.add_argument("--out", metavar="DIR", help="write into DIR (an existing directory) instead of docs/")
    args = parse(p, argv)
    if isinstance(args, int):
        return args
    directory = DOCS_DIR if args.out is None else Path(args.out)
    if not directory.is_dir():
        print(f"{prog}: --out: must be an existing directory (got {str(directory)!r})", file=sys.stderr)
        return 2
    if args.check:
        names = stale(directory)
        for name in names:
            print(f"{directory / name} is stale: run {prog}", file=sys.stderr)
        return 1 if names else 0
    for name in write(directory):
        print(f"wrote {directory / name}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
