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

Reading before deciding
-----------------------
Every walk that feeds a replace or delete decision fails closed: an entry it
cannot read (a directory without read permission, a file it cannot open)
stops the decision with :class:`EnvironmentRefused` (exit 3) before anything
is moved, instead of being skipped (``os.walk`` skips unreadable directories
silently unless told otherwise). A directory that no manifest entry lies
under counts as an entry the manifest does not vouch for, even when empty.

Markers are written atomically (:func:`write_json_atomic`: a temporary name,
``fsync``, ``rename``, ``fsync`` of the directory): a full disk leaves the
previous marker or none, never a truncated one.

Leftovers
---------
:func:`recover`, called with the lock held, handles leftovers of killed runs
into the same target, ``.<name>.tmp-*``, ``.<name>.old-*`` and
``.<name>.kept-*``. It removes (or, for a backup whose target is missing,
renames back) only what is provably this tool's: a name of the exact form the
tool gives (``<kind>-`` and 12 hex digits), owned by this user, and

- a ``complete`` marker naming the target whose manifest verifies byte for
  byte (the same check as ``--out`` itself); or
- an ``incomplete`` marker written by :func:`fresh_dir` for this very
  directory (it records the directory's name, device and inode: a copy
  elsewhere, or under another name, does not match); or
- no marker, and nothing in it but temporary marker files whose bytes are a
  prefix of what :func:`fresh_dir` writes for it (a run killed, or stopped by
  a full disk, while it made the directory).

Everything else that carries one of those prefixes is left as it is and named
in one line. The record store beside the target (``.<name>.records``) is
removed only when it holds nothing but a cut-short marker: zero bytes, or a
proper prefix of the marker the tool writes there (what a full disk leaves
when the store is being created); an empty store loses nothing, and without
this every later run would refuse the directory as not ours.
"""
from __future__ import annotations

import ctypes
import errno
import fcntl
import hashlib
import json
import os
import re
import secrets
import shutil
import stat
from dataclasses import dataclass
from pathlib import Path

__all__ = ["MARKER", "TargetRefused", "EnvironmentRefused", "Lock", "check_target", "fresh_dir",
           "swap_into_place", "Swapped", "recover", "exchange_supported", "read_marker", "ENVIRONMENT_ERRNOS",
           "is_environment_error", "write_json_atomic"]

#: The ownership marker in every report directory this tool writes.
MARKER = ".rk4h-report"
_MAGIC = "rk4h-report v1"
#: The record store's marker file (:mod:`rk4h.validation.records`) and its magic:
#: defined here, where every marker the tool writes is, so that clean-up can
#: recognise a store cut short without importing the store.
STORE_MARKER = ".rk4h-records"
STORE_MAGIC = "rk4h-records v1"
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


def _json_bytes(data: dict) -> bytes:
    return (json.dumps(data, indent=1, sort_keys=True) + "\n").encode("utf-8")


def write_json_atomic(path, data: dict) -> None:
    """Write ``data`` as JSON to ``path`` atomically.

    The bytes go to a new temporary file beside ``path`` (``<name>.tmp-<hex>``,
    created exclusively, never through a symbolic link), which is ``fsync``-ed
    and renamed over ``path``; then the directory is ``fsync``-ed. If any step
    fails (a full disk: ``ENOSPC``), the temporary file is removed and the
    error raised: ``path`` holds its previous content, or does not exist --
    never a truncated file. Indented with one space, keys sorted, one final
    newline."""
    path = Path(path)
    tmp = path.parent / f"{path.name}.tmp-{secrets.token_hex(4)}"
    blob = memoryview(_json_bytes(data))
    fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_NOFOLLOW", 0) | os.O_CLOEXEC, 0o644)
    try:
        try:
            while blob:
                blob = blob[os.write(fd, blob):]
            os.fsync(fd)
        finally:
            os.close(fd)
        os.replace(tmp, path)
    except BaseException:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        raise
    _fsync_path(path.parent, directory=True)


def _write_marker(directory: Path, data: dict) -> None:
    write_json_atomic(directory / MARKER, {"magic": _MAGIC, **data})


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


def _unreadable(e: OSError):
    """``os.walk``'s ``onerror``: an entry that cannot be read stops the decision."""
    raise EnvironmentRefused(e.errno, f"cannot read {e.filename} ({e.strerror}); it may hold files this tool "
                                      f"cannot verify")


def _files(directory: Path) -> dict[str, os.stat_result]:
    """Every entry below ``directory`` (relative POSIX path -> lstat),
    directories included, the marker excluded. Raises
    :class:`EnvironmentRefused` on an entry it cannot read."""
    out = {}
    for dirpath, dirnames, filenames in os.walk(directory, onerror=_unreadable):
        for name in filenames + dirnames:
            p = Path(dirpath) / name
            rel = p.relative_to(directory).as_posix()
            if rel != MARKER:
                out[rel] = os.lstat(p)
    return out


def _manifest(directory: Path) -> dict:
    return {rel: {"size": st.st_size, "sha256": _sha256(directory / rel)}
            for rel, st in sorted(_files(directory).items()) if stat.S_ISREG(st.st_mode)}


def _foreign(directory: Path, marker: dict) -> list[str]:
    """Entries of ``directory`` that its manifest does not vouch for (added,
    changed, not regular files, directories no manifest entry lies under);
    missing ones are harmless and not listed. Raises
    :class:`EnvironmentRefused` or ``OSError`` on an entry it cannot read."""
    manifest = marker.get("manifest")
    if not isinstance(manifest, dict):
        return sorted(_files(directory))
    parents = {rel.rsplit("/", i)[0] for rel in manifest for i in range(1, rel.count("/") + 1)}
    bad = []
    for rel, st in sorted(_files(directory).items()):
        if stat.S_ISDIR(st.st_mode):
            if rel not in parents:
                bad.append(rel)
            continue
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


def _ours_by_name(target: Path, name: str, kind: str) -> bool:
    """Whether ``name`` has the exact form :func:`_new_name` gives."""
    return re.fullmatch(re.escape(_prefix(target, kind)) + "[0-9a-f]{12}", name) is not None


def _incomplete_marker(target: Path, directory: Path, st: os.stat_result) -> dict:
    """What :func:`fresh_dir` writes into ``directory`` (``st``: its lstat)."""
    return {"magic": _MAGIC, "state": "incomplete", "target": target.name, "dir": directory.name,
            "dev": st.st_dev, "ino": st.st_ino}


def fresh_dir(target) -> Path:
    """A new empty directory beside ``target`` for a run to write into, with the
    permissions a plain ``mkdir`` gives, and an ``incomplete`` marker naming
    ``target`` and the directory itself (its name, device and inode: so
    :func:`recover` knows this directory, and not a copy of it, as ours)."""
    target = Path(target)
    tmp = _new_name(target, "tmp")
    os.mkdir(tmp)
    try:
        write_json_atomic(tmp / MARKER, _incomplete_marker(target, tmp, os.lstat(tmp)))
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
    for dirpath, _, files in os.walk(root, onerror=_unreadable):
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


@dataclass(frozen=True)
class Swapped:
    """What :func:`swap_into_place` did.

    Attributes
    ----------
    how : str
        ``"exchange"``, ``"rename"`` (no previous target) or ``"two renames"``.
    kept : Path or None
        Where a previous report was kept aside because it could not be
        verified (it changed during the run, or could not be read) or
        removed; None when it was removed (or there was none).
    why : str or None
        Which of those it was (None when ``kept`` is None).
    """

    how: str
    kept: Path | None = None
    why: str | None = None


def swap_into_place(tmp, target, *, scope: str = "full", scenes=()) -> Swapped:
    """Put directory ``tmp`` (from :func:`fresh_dir`) in place of ``target``
    (see the module docstring). Returns a :class:`Swapped`: how the swap was
    made and, when the previous report was kept aside rather than removed,
    where and why.

    An error before the swap leaves ``target`` as it was; once the new report
    is in place nothing raises (the previous report is then only ever kept
    aside, never lost to a caller's clean-up of ``tmp``)."""
    tmp, target = Path(tmp), Path(target)
    _write_marker(tmp, {"state": "complete", "target": target.name, "scope": scope,
                        "scenes": list(scenes), "manifest": _manifest(tmp)})
    _fsync_tree(tmp)
    if not target.exists():
        os.rename(tmp, target)
        _fsync_parent(target)
        return Swapped("rename")
    if _exchange(tmp, target):
        how, old = "exchange", tmp  # tmp now holds the previous report
    else:
        old = _new_name(target, "old")
        os.rename(target, old)
        try:
            os.rename(tmp, target)
        except BaseException:
            os.rename(old, target)
            raise
        how = "two renames"
    _fsync_parent(target)
    kept, why = _discard_previous(old, target)
    return Swapped(how, kept, why)


def _fsync_parent(target: Path) -> None:
    try:
        _fsync_path(target.parent, directory=True)
    except OSError:  # the rename is done; durability is the filesystem's best effort
        pass


def _verified(directory: Path) -> bool:
    """Whether ``directory`` is empty, or carries our marker and holds nothing
    its manifest does not vouch for, byte for byte. False (never an error)
    when anything in it cannot be read."""
    try:
        if not os.listdir(directory):
            return True
        marker = read_marker(directory)
        return marker is not None and isinstance(marker.get("manifest"), dict) and not _foreign(directory, marker)
    except OSError:
        return False


def _remove_ours(directory: Path) -> None:
    """Remove ``directory`` (verified as ours by the caller), its marker last:
    a process killed half-way leaves a directory that still verifies (missing
    files are harmless), so the next :func:`recover` finishes the job."""
    for dirpath, dirnames, filenames in os.walk(directory, topdown=False, onerror=_unreadable):
        for name in filenames + [d for d in dirnames if os.path.islink(os.path.join(dirpath, d))]:
            if not (dirpath == str(directory) and name == MARKER):
                os.unlink(os.path.join(dirpath, name))
        if dirpath != str(directory):
            os.rmdir(dirpath)
    try:
        os.unlink(directory / MARKER)
    except FileNotFoundError:
        pass
    os.rmdir(directory)


def _discard_previous(old: Path, target: Path) -> tuple:
    """Remove the previous report only if it is still exactly what its manifest
    says (or empty); otherwise keep it aside. Returns ``(kept, why)``: where it
    was kept and why, or ``(None, None)`` once removed. Never raises."""
    if _verified(old):
        try:
            _remove_ours(old)
            return None, None
        except OSError as e:
            why = f"it could not be removed ({e.strerror})"
    else:
        why = "it changed during the run, or could not be read"
    kept = _new_name(target, "kept")
    try:
        os.rename(old, kept)
    except OSError:
        kept = old
    return kept, why


_KINDS = ("tmp", "old", "kept")


def _half_made(target: Path, directory: Path, st: os.stat_result) -> bool:
    """Whether ``directory`` (no marker) holds nothing but temporary marker
    files whose bytes are a prefix of what :func:`fresh_dir` writes into it:
    a run stopped while it made the directory (killed, or a full disk)."""
    expected = _json_bytes(_incomplete_marker(target, directory, st))
    try:
        for entry in os.scandir(directory):
            if not entry.name.startswith(f"{MARKER}.tmp-") or not entry.is_file(follow_symlinks=False):
                return False
            with open(entry.path, "rb") as f:
                data = f.read(len(expected) + 1)
            if not expected.startswith(data):
                return False
    except OSError:
        return False
    return True


def _cut_short_store(target: Path) -> Path | None:
    """The record store beside ``target`` if it holds nothing but a marker
    (or its temporary files) cut short: zero bytes, or a proper prefix of the
    JSON the tool writes there (a full disk while the store was created)."""
    store = target.parent / f".{target.name}.records"
    try:
        st = os.lstat(store)
        if not stat.S_ISDIR(st.st_mode) or st.st_uid != os.getuid():
            return None
        whole = {"magic": STORE_MAGIC, "target": target.name}
        renderings = (json.dumps(whole).encode(), _json_bytes(whole))
        entries = list(os.scandir(store))
        for entry in entries:
            if entry.name != STORE_MARKER and not entry.name.startswith(f"{STORE_MARKER}.tmp"):
                return None
            if not entry.is_file(follow_symlinks=False):
                return None
            with open(entry.path, "rb") as f:
                data = f.read(_MARKER_MAX)
            if not any(len(data) < len(r) and r.startswith(data) for r in renderings):
                return None
    except OSError:
        return None
    return store  # (an empty one too: removing it loses nothing)


def recover(target) -> list[str]:
    """Clean up after runs into ``target`` that were killed (``kill -9``) or
    stopped by a full disk.

    Call it with the target's :class:`Lock` held: then no live run writes into
    any ``.<name>.tmp-*`` directory. Only what is provably this tool's is
    touched (see "Leftovers" in the module docstring): a verified backup is
    renamed back to ``target`` if ``target`` is missing (the process died
    between the two renames of the fallback swap); other provable leftovers
    are removed. Returns what was done, one line each; the last line names
    what was left because it could not be verified."""
    target = Path(target)
    if not target.parent.is_dir():
        return []
    done, left = [], []
    for p in sorted(target.parent.iterdir()):
        kind = next((k for k in _KINDS if p.name.startswith(_prefix(target, k))), None)
        if kind is None:
            continue
        try:
            st = os.lstat(p)
        except OSError:
            continue
        why = _why_not_ours(target, p, kind, st)
        if why:
            left.append(f"{p.name} ({why})")
            continue
        try:
            if kind == "old" and not os.path.lexists(target):
                os.rename(p, target)
                done.append(f"restored the previous report from {p.name}")
            elif read_marker(p) is None:
                for entry in os.scandir(p):
                    os.unlink(entry.path)
                os.rmdir(p)
                done.append(f"removed {p.name}, a directory a stopped run had only begun")
            else:
                _remove_ours(p)
                done.append(f"removed {p.name} left by a killed run")
        except OSError as e:
            left.append(f"{p.name} (could not be removed: {e.strerror})")
    store = _cut_short_store(target)
    if store is not None:
        try:
            for entry in os.scandir(store):
                os.unlink(entry.path)
            os.rmdir(store)
            done.append(f"removed {store.name}: an empty record store whose marker was cut short "
                        f"(a full disk while it was made)")
        except OSError as e:
            left.append(f"{store.name} (could not be removed: {e.strerror})")
    if left:
        done.append(f"left beside {target.name}, as not provably leftovers of this tool: {'; '.join(left)}")
    return done


def _why_not_ours(target: Path, p: Path, kind: str, st: os.stat_result) -> str | None:
    """None when leftover ``p`` is provably this tool's (see "Leftovers" in the
    module docstring), else why not, in a few words."""
    if not stat.S_ISDIR(st.st_mode):
        return "not a directory"
    if st.st_uid != os.getuid():
        return "owned by another user"
    if not _ours_by_name(target, p.name, kind):
        return "not a name this tool gives"
    marker = read_marker(p)
    if marker is None:
        return None if kind == "tmp" and _half_made(target, p, st) else "no marker of this tool"
    if marker.get("target") != target.name:
        return "its marker names another report"
    if marker.get("state") == "incomplete":
        if kind != "tmp":
            return "an unfinished run's marker under another kind of name"
        if marker != _incomplete_marker(target, p, st):
            return "its marker was written for another directory"
        try:  # every entry must be readable, or the removal would stop half-way
            _files(p)
        except OSError:
            return "not all of it can be read"
        return None
    if marker.get("state") != "complete" or not isinstance(marker.get("manifest"), dict):
        return "its marker is not a complete report's"
    try:
        foreign = _foreign(p, marker)
    except OSError:
        return "not all of it can be read"
    return f"its manifest does not vouch for {_list(foreign)}" if foreign else None
