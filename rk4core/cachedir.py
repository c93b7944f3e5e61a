"""The per-user cache directory: created private, verified before every use.

Everything the harness keeps between processes (generated fixed-step loops and
numba's compiled copies of them, quadruple-precision truth trajectories) lives
under one root:

``$RK4H_CACHE`` if set, else ``$XDG_CACHE_HOME/rk4h``, else ``~/.cache/rk4h``.

A directory is trusted only if it is a real directory (not a symbolic link),
owned by the current user and closed to group and others (no bit of 0o077).
The tool creates missing directories with mode 0700; it never loosens, adopts
or deletes a directory it did not create. Code is imported and data loaded from
a directory only after :func:`private_dir` has verified it (and every directory
between it and the root), so a directory planted by another user, or opened to
others, is refused instead of trusted (:class:`UntrustedCacheError`).
"""
from __future__ import annotations

import os
import stat
from pathlib import Path

__all__ = ["cache_root", "private_dir", "verify", "UntrustedCacheError"]


class UntrustedCacheError(OSError):
    """A cache directory failed the ownership/mode check; the message says why
    in one line, naming the path."""


def cache_root() -> Path:
    """``$RK4H_CACHE``, else ``$XDG_CACHE_HOME/rk4h``, else ``~/.cache/rk4h``."""
    env = os.environ.get("RK4H_CACHE")
    if env:
        return Path(env).expanduser().absolute()
    xdg = os.environ.get("XDG_CACHE_HOME")
    base = Path(xdg).expanduser() if xdg and Path(xdg).is_absolute() else Path.home() / ".cache"
    return (base / "rk4h").absolute()


def _uid() -> int:
    return os.getuid() if hasattr(os, "getuid") else 0


def verify(path) -> Path:
    """Return ``path`` if it is a directory that only the current user can
    write (see the module docstring); else raise :class:`UntrustedCacheError`."""
    path = Path(path)
    try:
        st = os.lstat(path)
    except OSError as e:
        raise UntrustedCacheError(e.errno, f"cache directory {path}: {e.strerror}") from None
    if stat.S_ISLNK(st.st_mode):
        raise UntrustedCacheError(f"cache directory {path} is a symbolic link; refusing to use it")
    if not stat.S_ISDIR(st.st_mode):
        raise UntrustedCacheError(f"cache directory {path} is not a directory")
    if st.st_uid != _uid():
        raise UntrustedCacheError(f"cache directory {path} is owned by uid {st.st_uid}, not by you "
                                  f"(uid {_uid()}); refusing to use it (set RK4H_CACHE elsewhere)")
    if st.st_mode & 0o077:
        raise UntrustedCacheError(f"cache directory {path} has mode {stat.S_IMODE(st.st_mode):04o}; "
                                  f"it must be 0700 (chmod 700 it, or set RK4H_CACHE elsewhere)")
    return path


def private_dir(*parts: str, root=None) -> Path:
    """The verified directory ``root / parts...`` (default root:
    :func:`cache_root`), created with mode 0700 where missing.

    Raises :class:`UntrustedCacheError` when the root or a part exists but is
    not private to the current user, or cannot be created."""
    here = Path(root) if root is not None else cache_root()
    for i, part in enumerate((None, *parts)):
        if part is not None:
            if part in ("", ".", "..") or "/" in part or os.sep in part:
                raise ValueError(f"cache directory part must be a plain name, got {part!r}")
            here = here / part
        try:
            if i == 0:
                here.parent.mkdir(parents=True, exist_ok=True)
            os.mkdir(here, 0o700)
        except FileExistsError:
            pass
        except OSError as e:
            raise UntrustedCacheError(e.errno, f"cache directory {here}: cannot create it "
                                               f"({e.strerror})") from None
        verify(here)
    return here
