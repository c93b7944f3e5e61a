"""Replacing a report directory so that no interruption leaves it half-written.

A run writes into a fresh directory beside the target (same parent, hence same
filesystem), ``.<name>.tmp-<pid>-<random>``, and :func:`swap_into_place` puts
it in place at the end:

1. every file of the new directory is ``fsync``-ed (durable before it is visible);
2. if the target exists, the two directories are exchanged with one
   ``renameat2(..., RENAME_EXCHANGE)`` system call (Linux >= 3.15, glibc >= 2.28;
   ext4, xfs, btrfs, tmpfs): atomic, the target path always names a complete
   report, old or new. Elsewhere (or if the filesystem refuses the flag) two
   ``rename`` calls: target -> ``.<name>.old-<pid>-<random>``, new -> target;
   between them the target path is briefly absent, and :func:`recover`
   renames the backup back if a process died there;
3. the parent directory is ``fsync``-ed and the old report (now under the
   temporary name) removed.

:func:`recover`, called before a run, removes the temporary and backup
directories of dead processes (``kill -9`` leaves them) and leaves those of
live processes alone, so concurrent runs into one target do not disturb each
other (the last to finish wins, whole).
"""
from __future__ import annotations

import ctypes
import errno
import os
import re
import shutil
import tempfile
from pathlib import Path

__all__ = ["fresh_dir", "swap_into_place", "recover", "exchange_supported"]

_AT_FDCWD = -100
_RENAME_EXCHANGE = 2


def _prefix(target: Path, kind: str) -> str:
    return f".{target.name}.{kind}-"


def fresh_dir(target) -> Path:
    """A new empty directory beside ``target`` for a run to write into, with the
    permissions a plain ``mkdir`` would give (``mkdtemp`` gives 0700)."""
    target = Path(target)
    tmp = Path(tempfile.mkdtemp(prefix=f"{_prefix(target, 'tmp')}{os.getpid()}-", dir=target.parent))
    umask = os.umask(0)
    os.umask(umask)
    os.chmod(tmp, 0o777 & ~umask)
    return tmp


def _fsync_path(path: Path, directory=False):
    fd = os.open(path, os.O_RDONLY | (getattr(os, "O_DIRECTORY", 0) if directory else 0))
    try:
        os.fsync(fd)
    except OSError:  # some filesystems cannot fsync a directory
        pass
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
    a = Path(tempfile.mkdtemp(prefix=".exchange-probe-", dir=directory))
    b = Path(tempfile.mkdtemp(prefix=".exchange-probe-", dir=directory))
    try:
        return _exchange(a, b)
    finally:
        shutil.rmtree(a, ignore_errors=True)
        shutil.rmtree(b, ignore_errors=True)


def swap_into_place(tmp, target) -> str:
    """Put directory ``tmp`` in place of ``target`` (see the module docstring);
    returns ``"exchange"``, ``"rename"`` (no previous target) or ``"two renames"``."""
    tmp, target = Path(tmp), Path(target)
    _fsync_tree(tmp)
    if not target.exists():
        os.replace(tmp, target)
        how = "rename"
    elif _exchange(tmp, target):
        how = "exchange"   # tmp now holds the previous report
    else:
        backup = Path(tempfile.mkdtemp(prefix=f"{_prefix(target, 'old')}{os.getpid()}-", dir=target.parent))
        backup.rmdir()
        os.replace(target, backup)
        os.replace(tmp, target)
        tmp = backup
        how = "two renames"
    _fsync_path(target.parent, directory=True)
    shutil.rmtree(tmp, ignore_errors=True)
    return how


_OWNED = re.compile(r"^\.(?P<name>.+)\.(?P<kind>tmp|old)-(?P<pid>\d+)-[^/]+$")


def _alive(pid: int) -> bool:
    if pid == os.getpid():
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # someone else's live process
        return True
    return True


def recover(target) -> list[str]:
    """Clean up after runs into ``target`` that died (e.g. ``kill -9``).

    Temporary directories of dead processes are removed. A backup of a dead
    process is renamed back to ``target`` if ``target`` is missing (the process
    died between the two renames of the fallback swap), else removed.
    Returns what was done, one line each."""
    target = Path(target)
    if not target.parent.is_dir():
        return []
    done = []
    for p in sorted(target.parent.iterdir()):
        m = _OWNED.match(p.name)
        if not m or m["name"] != target.name or not p.is_dir() or _alive(int(m["pid"])):
            continue
        if m["kind"] == "old" and not target.exists():
            os.replace(p, target)
            done.append(f"restored the previous report from {p.name}")
        else:
            shutil.rmtree(p, ignore_errors=True)
            done.append(f"removed {p.name} left by dead process {m['pid']}")
    return done
