"""Installed distributions' versions, looked up once per process.

``importlib.metadata`` scans the installed distributions on every call
(milliseconds each); the truth cache's keys, the record keys and the
report's environment section all ask for the same few versions.
"""
from __future__ import annotations

import functools

__all__ = ["version"]


@functools.lru_cache(maxsize=64)
def version(dist: str) -> str | None:
    """The installed version of distribution ``dist``, or None when it is not installed."""
    from importlib import metadata

    try:
        return metadata.version(dist)
    except metadata.PackageNotFoundError:
        return None
