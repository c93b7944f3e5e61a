"""What decides a record's numbers besides the scene: the user's code a scene
names and the numerical libraries this process runs.

A spec's key (:attr:`rk4h.validation.plan.RunSpec.key`) covers the scene's digest,
and :func:`rk4h.validation.plan.scene_digest` folds in

* :func:`user_code_digest`: the content of the source files of the modules a
  scene names (``model = "package.module:Class"``, ``python =
  "package.module:function"`` methods) and of the files a ``command``
  method's argv names (the program itself, found on ``PATH`` when it has no
  directory, and every argument that is a file, e.g. a script), and GNU
  Octave's ``octave-cli`` for the ``thesis_code`` output;
* :func:`environment_digest`: the versions of numpy, scipy, heyoka,
  scikit-sundae and numba, the Python version and numpy's OpenBLAS kernel
  (:func:`rk4h.validation.report.blas_kernel`).

So a record made before a user's stepper file or a library changed has
another key and is rerun, never resumed.

Nothing here imports or runs the user's code: modules are located with
:class:`importlib.machinery.PathFinder` (a module already imported by this
process is taken from ``sys.modules``), files are read, not executed.
Limits: only the files on the dotted path of a module are hashed (``pkg/__init__.py``
and ``pkg/mod.py`` for ``pkg.mod``), not what those modules import in turn;
a command's shared libraries and the interpreter of a script are not hashed
beyond the argv's own files.
"""
from __future__ import annotations

import functools
import hashlib
import importlib.machinery
import os
import shutil
import stat
import sys

__all__ = ["LIBRARIES", "environment_digest", "library_versions", "user_code_digest", "file_digest",
           "module_files"]

#: Distributions whose version is part of every spec key.
LIBRARIES = ("numpy", "scipy", "heyoka", "scikit-sundae", "numba")
#: Files larger than this (bytes) are identified by size and modification
#: time instead of content (a program binary of hundreds of MB).
HASH_LIMIT = 256 * 2**20

_FILE_CACHE: dict = {}


@functools.lru_cache(maxsize=1)
def library_versions() -> tuple:
    """``((distribution, version or "absent"), ...)`` of :data:`LIBRARIES`,
    looked up once per process (``importlib.metadata`` is slow)."""
    from rk4h.distributions import version

    return tuple((name, version(name) or "absent") for name in LIBRARIES)


@functools.lru_cache(maxsize=1)
def environment_digest() -> str:
    """SHA-256 (hex, 16 characters) of :func:`library_versions`, the Python
    version and the BLAS kernel; computed once per process."""
    from .report import blas_kernel

    text = repr((library_versions(), sys.implementation.name, tuple(sys.version_info[:3]), blas_kernel()))
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def file_digest(path) -> str:
    """SHA-256 (hex) of the regular file ``path`` (links followed), or a
    text saying why there is none (``"missing"``, ``"not a regular file"``).
    Cached per process on the file's device, inode, size and modification
    time (ns); files over :data:`HASH_LIMIT` bytes are named by those alone."""
    try:
        st = os.stat(path)
    except OSError:
        return "missing"
    if not stat.S_ISREG(st.st_mode):
        return "not a regular file"
    ident = (st.st_dev, st.st_ino, st.st_size, st.st_mtime_ns, st.st_ctime_ns)
    cached = _FILE_CACHE.get(str(path))
    if cached is not None and cached[0] == ident:
        return cached[1]
    if st.st_size > HASH_LIMIT:
        digest = f"size {st.st_size} mtime {st.st_mtime_ns}"
    else:
        h = hashlib.sha256()
        try:
            fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK)
        except OSError:
            return "unreadable"
        try:
            if not stat.S_ISREG(os.fstat(fd).st_mode):
                return "not a regular file"
            with os.fdopen(fd, "rb", closefd=False) as f:
                for chunk in iter(lambda: f.read(1 << 20), b""):
                    h.update(chunk)
        finally:
            os.close(fd)
        digest = h.hexdigest()
    if len(_FILE_CACHE) > 4096:
        _FILE_CACHE.clear()
    _FILE_CACHE[str(path)] = (ident, digest)
    return digest


def module_files(name: str) -> list[str]:
    """The source files of module ``name`` and of the packages above it
    (``["pkg/__init__.py", "pkg/mod.py"]`` for ``pkg.mod``), without
    importing anything; an entry ``"unresolved:NAME"`` where a part cannot be
    located (the run fails there, with its own message)."""
    out, path = [], None
    parts = name.split(".")
    for i in range(len(parts)):
        full = ".".join(parts[: i + 1])
        mod = sys.modules.get(full)
        origin = getattr(mod, "__file__", None) if mod is not None else None
        locations = getattr(mod, "__path__", None) if mod is not None else None
        if origin is None:
            try:
                spec = importlib.machinery.PathFinder.find_spec(full, path)
            except (ImportError, ValueError, AttributeError):
                spec = None
            if spec is None:
                out.append(f"unresolved:{full}")
                return out
            origin = spec.origin if spec.has_location else None
            locations = spec.submodule_search_locations
        if origin:
            out.append(os.path.abspath(origin))
        path = list(locations) if locations is not None else None
        if path is None and i < len(parts) - 1:
            out.append(f"unresolved:{'.'.join(parts[: i + 2])}")
            return out
    return out


def _command_files(argv) -> list[str]:
    """Files a command's argv names: the program (looked up on ``PATH`` when
    it has no directory part) and every other argument that is an existing
    file, after ``{thesis_code}`` is expanded (the per-run placeholders
    ``{problem}``, ``{trajectory}``, ``{workdir}`` name no file yet)."""
    from rk4h.command import THESIS_CODE

    out = []
    for i, arg in enumerate(argv):
        arg = str(arg).replace("{thesis_code}", str(THESIS_CODE))
        if "{problem}" in arg or "{trajectory}" in arg or "{workdir}" in arg:
            continue
        if i == 0 and os.sep not in arg and not (os.altsep and os.altsep in arg):
            found = shutil.which(arg)
            out.append(os.path.realpath(found) if found else f"not on PATH:{arg}")
        elif os.path.isfile(arg):
            out.append(os.path.realpath(arg))
    return out


def user_code_digest(scene) -> str:
    """SHA-256 (hex, 16 characters) of the user's code ``scene`` names: its
    ``module:Class`` model and its ``python`` and ``command`` methods (see the
    module docstring); the digest of the empty list when it names none."""
    entries = []
    if isinstance(scene.model, str) and ":" in scene.model:
        entries += [("model", f) for f in module_files(scene.model.split(":")[0])]
    for name in sorted(scene.methods or {}):
        table = scene.methods[name]
        if not isinstance(table, dict):
            continue
        target = table.get("python")
        if isinstance(target, str) and ":" in target:
            entries += [(f"python {name}", f) for f in module_files(target.split(":")[0])]
        argv = table.get("command")
        if isinstance(argv, list) and argv:
            entries += [(f"command {name}", f) for f in _command_files(argv)]
    if "thesis_code" in (scene.outputs or ()):  # rk4h.references.thesis_code runs octave-cli
        entries += [("thesis_code", f) for f in _command_files(["octave-cli"])]
    h = hashlib.sha256()
    for what, f in entries:
        content = file_digest(f) if os.path.isabs(f) else "-"
        h.update(f"{what}\0{f}\0{content}\n".encode())
    return h.hexdigest()[:16]
