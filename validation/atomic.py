"""Report directories: owned, locked, replaced whole, never anything else.

Ownership
---------
Every report directory this tool writes carries a marker file,
:data:`MARKER` (``.rk4h-report``): JSON with a magic line, the run's scope
(``full``, ``quick`` or ``subset``), the scenes it holds and a manifest (name,
size and SHA-256 of every file the run wrote). :func:`check_target` accepts an
``--out`` that is absent, an empty directory, or a directory whose marker
verifies and whose files are exactly those of its manifest, byte for byte.
Anything else (a directory holding a file the tool did not write, a file
edited since, a symbolic link or a special file where the marker belongs, a
mount point) is refused before any work starts and left untouched
(:class:`TargetRefused`). A run that covers less than the report it would
replace (``subset`` or ``quick`` over a ``full`` report) is refused too, unless
the caller passes ``replace=True`` (``run_all --replace``).

Locking
-------
Runs into one target are serialized by ``fcntl.flock`` on ``.<name>.lock``
beside it (:class:`Lock`); a second run finds the lock held and stops with
:class:`EnvironmentRefused` (exit 3). Process ids are never consulted: in
containers and on network filesystems they do not identify a live process.
The lock file is left in place (deleting a lock file races with its users).

Swapping
--------
A run writes into a fresh directory beside the target (same parent, hence same
filesystem), ``.<name>.tmp-<random>``, created with an ``incomplete`` marker,
and :func:`swap_into_place` puts it in place at the end:

1. the manifest is written into the marker and every file is ``fsync``-ed;
2. if the target exists, the two directories are exchanged with one
   ``renameat2(..., RENAME_EXCHANGE)`` (Linux >= 3.15; ext4, xfs, btrfs,
   tmpfs): atomic, the target path always names a complete report. Elsewhere
   two ``rename`` calls: target -> ``.<name>.old-<random>``, new -> target;
   :func:`recover` renames the backup back if a process died between them;
3. the parent directory is ``fsync``-ed, and the previous report (now under
   the temporary name) is verified against its own manifest once more and only
   then removed; if anything was added or changed in it during the run it is
   kept aside under ``.<name>.kept-<random>`` and said so.

:func:`recover`, called with the lock held, handles leftovers of killed runs
into the same target: a temporary or backup directory is removed only if it
is owned by this user and carries a marker naming this target.
"""
from __future__ import annotations

import ctypes
import errno
import fcntl
import hashlib
import json
import os
import secrets
import shutil
import stat
from pathlib import Path

__all__ = ["MARKER", "TargetRefused", "EnvironmentRefused", "Lock", "check_target", "fresh_dir",
           "swap_into_place", "recover", "exchange_supported", "read_marker", "ENVIRONMENT_ERRNOS",
           "is_environment_error"]

#: The ownership marker in every report directory this tool writes.
MARKER = ".rk4h-report"
_MAGIC = "rk4h-report v1"
_MARKER_MAX = 1 << 20  # bytes; a larger "marker" is not ours
_AT_FDCWD = -100
_RENAME_EXCHANGE = 2
_SCOPE_RANK = {"subset": 0, "quick": 1, "full": 2}

#: errno values that mean "the environment refused" (exit 3), not bad input.
ENVIRONMENT_ERRNOS = frozenset(getattr(errno, n) for n in (
    "ENOSPC", "EDQUOT", "EROFS", "EACCES", "EPERM", "EBUSY", "EXDEV", "ENAMETOOLONG", "EMLINK", "EIO",
    "ENOTDIR", "ELOOP", "EFBIG") if hasattr(errno, n))


def is_environment_error(exc: BaseException) -> bool:
    """Whether ``exc`` is the environment refusing (disk full, read-only, ...):
    such an error stops a run (exit 3) instead of becoming a failed row."""
    return isinstance(exc, EnvironmentRefused) or (isinstance(exc, OSError)
                                                     and exc.errno in ENVIRONMENT_ERRNOS)


class TargetRefused(ValueError):
    """``--out`` names something this tool must not replace (exit 2)."""


class EnvironmentRefused(OSError):
    """The environment refused: lock held, not writable, mount point, name too
    long, disk full (exit 3). The message is one line."""


def _prefix(target: Path, kind: str) -> str:
    return f".{target.name}.{kind}-"


# -- the marker --------------------------------------------------------------------------
def _sha256(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for chunk in iter(lambda: f.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


def _write_marker(directory: Path, data: dict) -> None:
    tmp = directory / f"{MARKER}.tmp"
    with open(tmp, "w", encoding="utf-8") as f:
        json.dump({"magic": _MAGIC, **data}, f, indent=1, sort_keys=True)
        f.write("\n")
        f.flush()
        os.fsync(f.fileno())
    os.replace(tmp, directory / MARKER)


def read_marker(directory) -> dict | None:
    """The marker of ``directory`` if it is one of ours (a regular file owned by
    this user, of bounded size, JSON with the magic line); else None."""
    path = Path(directory) / MARKER
    try:
        st = os.lstat(path)
    except OSError:
        return None
    if not stat.S_ISREG(st.st_mode) or st.st_size > _MARKER_MAX or st.st_uid != os.getuid():
        return None
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError, UnicodeDecodeError):
        return None
    return data if isinstance(data, dict) and data.get("magic") == _MAGIC else None


def _files(directory: Path) -> dict[str, os.stat_result]:
    """Every entry below ``directory`` (relative POSIX path -> lstat), marker and
    its temporary file excluded; directories themselves are not listed."""
    out = {}
    for dirpath, dirnames, filenames in os.walk(directory):
        for name in filenames + [d for d in dirnames if os.path.islink(os.path.join(dirpath, d))]:
            p = Path(dirpath) / name
            rel = p.relative_to(directory).as_posix()
            if rel not in (MARKER, f"{MARKER}.tmp"):
                out[rel] = os.lstat(p)
    return out


def _manifest(directory: Path) -> dict:
    return {rel: {"size": st.st_size, "sha256": _sha256(directory / rel)}
            for rel, st in sorted(_files(directory).items()) if stat.S_ISREG(st.st_mode)}


def _foreign(directory: Path, marker: dict) -> list[str]:
    """Entries of ``directory`` that its manifest does not vouch for (added,
    changed, not regular files); missing ones are harmless and not listed."""
    manifest = marker.get("manifest")
    if not isinstance(manifest, dict):
        return sorted(_files(directory))
    bad = []
    for rel, st in sorted(_files(directory).items()):
        entry = manifest.get(rel)
        if (not isinstance(entry, dict) or not stat.S_ISREG(st.st_mode) or entry.get("size") != st.st_size
                or entry.get("sha256") != _sha256(directory / rel)):
            bad.append(rel)
    return bad


def _list(names, most=3) -> str:
    shown = ", ".join(names[:most])
    return shown + (f" and {len(names) - most} more" if len(names) > most else "")


def check_target(target, *, scope: str, n_scenes: int, replace: bool = False) -> None:
    """Refuse a ``target`` this run must not replace (see the module docstring).

    Raises :class:`TargetRefused` (bad input, exit 2) or
    :class:`EnvironmentRefused` (a mount point, exit 3); returns None when the
    target may be replaced by a report of ``scope`` (``full``/``quick``/``subset``)."""
    target = Path(target)
    try:
        st = os.lstat(target)
    except FileNotFoundError:
        return
    except OSError as e:
        raise EnvironmentRefused(e.errno, f"--out {target}: {e.strerror}") from None
    if stat.S_ISLNK(st.st_mode) and not target.is_dir():
        raise TargetRefused(f"--out {target} is a symbolic link to something that is not a directory")
    if not target.is_dir():
        raise TargetRefused(f"--out {target} exists and is not a directory")
    if os.path.ismount(target):
        raise EnvironmentRefused(errno.EBUSY, f"--out {target} is a mount point: a report is swapped in "
                                              f"by renaming, which a mount point refuses; name a directory "
                                              f"inside it")
    try:
        entries = sorted(os.listdir(target))
    except OSError as e:
        raise EnvironmentRefused(e.errno, f"--out {target}: cannot list it ({e.strerror})") from None
    if not entries:
        return
    marker = read_marker(target)
    if marker is None:
        raise TargetRefused(f"--out {target} is not empty and was not written by this tool (it holds "
                            f"{_list(entries)}); refusing to replace it: name a new or empty directory")
    foreign = _foreign(target, marker)
    if foreign:
        raise TargetRefused(f"--out {target} holds files this tool did not write or that changed since "
                            f"({_list(foreign)}); refusing to replace it: move them out or name another "
                            f"directory")
    old = marker.get("scope", "full")
    if not replace and _SCOPE_RANK.get(scope, 0) < _SCOPE_RANK.get(old, 2):
        held = len(marker.get("scenes") or [])
        raise TargetRefused(f"--out {target} holds a {old} report ({held} scenes) and this {scope} run of "
                            f"{n_scenes} scene(s) would replace it: name another directory with --out, "
                            f"or pass --replace")


# -- the lock ------------------------------------------------------------------------------
class Lock:
    """``fcntl.flock`` (exclusive, non-blocking) on ``.<name>.lock`` beside
    ``target``; a context manager. Raises :class:`EnvironmentRefused` when
    another process holds it or the file cannot be opened."""

    def __init__(self, target):
        target = Path(target)
        self.path = target.parent / f".{target.name}.lock"
        self.fd = None

    def __enter__(self):
        try:
            fd = os.open(self.path, os.O_RDWR | os.O_CREAT | getattr(os, "O_NOFOLLOW", 0) | os.O_CLOEXEC, 0o644)
        except OSError as e:
            raise EnvironmentRefused(e.errno, f"cannot open the lock file {self.path} ({e.strerror})") from None
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError as e:
            os.close(fd)
            if e.errno in (errno.EWOULDBLOCK, errno.EAGAIN, errno.EACCES):
                raise EnvironmentRefused(e.errno, f"another run holds the lock {self.path}; wait for it "
                                                  f"to finish (or name another --out)") from None
            raise EnvironmentRefused(e.errno, f"cannot lock {self.path} ({e.strerror})") from None
        self.fd = fd
        return self

    def __exit__(self, *exc):
        if self.fd is not None:
            os.close(self.fd)  # closing releases the flock
            self.fd = None
        return False


# -- the temporary directory and the swap -----------------------------------------------------
def _new_name(target: Path, kind: str) -> Path:
    return target.parent / f"{_prefix(target, kind)}{secrets.token_hex(6)}"


def fresh_dir(target) -> Path:
    """A new empty directory beside ``target`` for a run to write into, with the
    permissions a plain ``mkdir`` gives, and an ``incomplete`` marker naming
    ``target`` (so :func:`recover` knows it as ours)."""
    target = Path(target)
    tmp = _new_name(target, "tmp")
    os.mkdir(tmp)
    try:
        _write_marker(tmp, {"state": "incomplete", "target": target.name})
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return tmp


def _fsync_path(path: Path, directory=False):
    fd = os.open(path, os.O_RDONLY | (getattr(os, "O_DIRECTORY", 0) if directory else 0))
    try:
        os.fsync(fd)
    except OSError as e:  # some filesystems cannot fsync a directory
        if not directory:
            raise
    finally:
        os.close(fd)


def _fsync_tree(root: Path):
    for dirpath, _, files in os.walk(root):
        for f in files:
            _fsync_path(Path(dirpath) / f)
        _fsync_path(Path(dirpath), directory=True)


def _exchange(a: Path, b: Path) -> bool:
    """Atomically exchange directories ``a`` and ``b``; False when unsupported."""
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        fn = libc.renameat2
    except (OSError, AttributeError):
        return False
    fn.argtypes = [ctypes.c_int, ctypes.c_char_p, ctypes.c_int, ctypes.c_char_p, ctypes.c_uint]
    fn.restype = ctypes.c_int
    if fn(_AT_FDCWD, os.fsencode(a), _AT_FDCWD, os.fsencode(b), _RENAME_EXCHANGE) == 0:
        return True
    err = ctypes.get_errno()
    if err in (errno.EINVAL, errno.ENOSYS, errno.ENOTSUP, errno.EOPNOTSUPP):
        return False
    raise OSError(err, f"renameat2(RENAME_EXCHANGE) failed: {os.strerror(err)}", str(b))


def exchange_supported(directory) -> bool:
    """Whether :func:`swap_into_place` is a single atomic exchange in ``directory``."""
    a = Path(directory) / f".exchange-probe-{secrets.token_hex(6)}"
    b = Path(directory) / f".exchange-probe-{secrets.token_hex(6)}"
    os.mkdir(a)
    try:
        os.mkdir(b)
        try:
            return _exchange(a, b)
        finally:
            os.rmdir(b)
    finally:
        os.rmdir(a)


def swap_into_place(tmp, target, *, scope: str = "full", scenes=()) -> str:
    """Put directory ``tmp`` (from :func:`fresh_dir`) in place of ``target``
    (see the module docstring). Returns ``"exchange"``, ``"rename"`` (no
    previous target) or ``"two renames"``; ``swap_into_place.kept`` names a
    previous report kept aside because it changed during the run (else None)."""
    tmp, target = Path(tmp), Path(target)
    swap_into_place.kept = None
    _write_marker(tmp, {"state": "complete", "target": target.name, "scope": scope,
                        "scenes": list(scenes), "manifest": _manifest(tmp)})
    _fsync_tree(tmp)
    if not target.exists():
        os.rename(tmp, target)
        _fsync_path(target.parent, directory=True)
        return "rename"
    if _exchange(tmp, target):
        how, old = "exchange", tmp  # tmp now holds the previous report
    else:
        old = _new_name(target, "old")
        os.rename(target, old)
        os.rename(tmp, target)
        how = "two renames"
    _fsync_path(target.parent, directory=True)
    _discard_previous(old, target)
    return how


swap_into_place.kept = None


def _discard_previous(old: Path, target: Path) -> None:
    """Remove the previous report only if it is still exactly what its manifest
    says (or empty); otherwise keep it aside and say where."""
    entries = os.listdir(old)
    marker = read_marker(old)
    if not entries or (marker is not None and not _foreign(old, marker)):
        shutil.rmtree(old)
        return
    kept = _new_name(target, "kept")
    os.rename(old, kept)
    swap_into_place.kept = kept


_OWNED_KINDS = ("tmp", "old")


def recover(target) -> list[str]:
    """Clean up after runs into ``target`` that were killed (``kill -9``).

    Call it with the target's :class:`Lock` held: then no live run writes into
    any ``.<name>.tmp-*`` directory. Only directories owned by this user and
    carrying a marker that names ``target`` are touched: a backup is renamed
    back to ``target`` if ``target`` is missing (the process died between the
    two renames of the fallback swap); other leftovers are removed. Returns
    what was done, one line each."""
    target = Path(target)
    if not target.parent.is_dir():
        return []
    done = []
    for p in sorted(target.parent.iterdir()):
        kind = next((k for k in _OWNED_KINDS if p.name.startswith(_prefix(target, k))), None)
        if kind is None:
            continue
        try:
            st = os.lstat(p)
        except OSError:
            continue
        marker = read_marker(p) if stat.S_ISDIR(st.st_mode) else None
        if st.st_uid != os.getuid() or marker is None or marker.get("target") != target.name:
            continue
        if kind == "old" and not target.exists() and marker.get("state") == "complete":
            os.rename(p, target)
            done.append(f"restored the previous report from {p.name}")
        else:
            shutil.rmtree(p)
            done.append(f"removed {p.name} left by a killed run")
    return done
