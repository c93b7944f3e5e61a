"""Run records: what one :class:`~validation.plan.RunSpec` measured, and where
records are kept between an interrupted run and its ``--resume``.

A :class:`RunRecord` holds scalars only in ``values`` (deterministic: errors,
energy drift, nfev, steps, status), timings apart in ``timing`` (wall times,
compile time, spread of the repeats), arrays a figure needs in ``arrays`` and,
for stability units, the unit's rows, findings and plot data in ``result``.

:class:`RecordStore` keeps records in a directory this tool made and marked
(``.<out>.records`` beside the output directory; marker
:data:`STORE_MARKER`): one ``<key>.json`` per record (the spec, the record, and
the SHA-256 of its arrays file) and ``<key>.npz`` (numpy arrays, loaded with
``allow_pickle=False``). Files are written under a temporary name and renamed,
so a killed run leaves whole records or none. A record is trusted only when its
JSON parses, names the spec's key and its arrays match their checksum;
anything else in the directory is ignored, and the directory itself is used
only if its marker is ours. Nothing is unpickled.
"""
from __future__ import annotations

import hashlib
import io
import json
import math
import os
import secrets
import shutil
import stat
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

__all__ = ["RunRecord", "RecordStore", "STORE_MARKER", "failed_record"]

STORE_MARKER = ".rk4h-records"
_MAGIC = "rk4h-records v1"
_FORMAT = 1


@dataclass
class RunRecord:
    """The outcome of one spec; see the module docstring. ``status`` is one of
    ``ok``, ``unstable``, ``failed``, ``skipped``."""

    key: str
    status: str = "ok"
    message: str = ""
    values: dict = field(default_factory=dict)
    timing: dict = field(default_factory=dict)
    arrays: dict = field(default_factory=dict)
    result: dict | None = None
    seconds: float = 0.0

    @property
    def ok(self) -> bool:
        return self.status == "ok"


def failed_record(key, exc) -> RunRecord:
    """The record of a spec whose execution raised: status ``failed`` and the
    exception's first line."""
    text = str(exc).splitlines()[0] if str(exc) else ""
    return RunRecord(key, status="failed", message=f"{type(exc).__name__}: {text}")


# -- serialization: JSON for structure, one npz for every array ------------------
def _encode(obj, arrays):
    if isinstance(obj, np.ndarray):
        name = f"a{len(arrays)}"
        arrays[name] = obj
        return {"__array__": name}
    if isinstance(obj, dict):
        return {"__dict__": [[_encode(k, arrays), _encode(v, arrays)] for k, v in obj.items()]}
    if isinstance(obj, (list, tuple)):
        return {"__tuple__" if isinstance(obj, tuple) else "__list__": [_encode(v, arrays) for v in obj]}
    if isinstance(obj, (np.bool_, bool)):
        return bool(obj)
    if isinstance(obj, np.integer):
        return int(obj)
    if isinstance(obj, np.floating):
        return float(obj)
    if obj is None or isinstance(obj, (str, int, float)):
        return obj
    if isinstance(obj, Path):
        return str(obj)
    raise TypeError(f"a record cannot hold {type(obj).__name__}")


def _decode(obj, arrays):
    if isinstance(obj, dict):
        if "__array__" in obj:
            return arrays[obj["__array__"]]
        if "__dict__" in obj:
            return {_decode(k, arrays): _decode(v, arrays) for k, v in obj["__dict__"]}
        if "__tuple__" in obj:
            return tuple(_decode(v, arrays) for v in obj["__tuple__"])
        if "__list__" in obj:
            return [_decode(v, arrays) for v in obj["__list__"]]
        raise ValueError("unknown object in record")
    return obj


def dumps(record: RunRecord) -> tuple[bytes, bytes]:
    """``(json bytes, npz bytes)`` of a record."""
    arrays = {}
    body = {"key": record.key, "status": record.status, "message": record.message,
            "values": _encode(record.values, arrays), "timing": _encode(record.timing, arrays),
            "arrays": _encode(record.arrays, arrays), "result": _encode(record.result, arrays),
            "seconds": record.seconds}
    buf = io.BytesIO()
    np.savez(buf, **arrays)
    npz = buf.getvalue()
    body["npz_sha256"] = hashlib.sha256(npz).hexdigest()
    body["format"] = _FORMAT
    return json.dumps(body, allow_nan=True).encode(), npz


def loads(text: bytes, npz: bytes) -> RunRecord:
    body = json.loads(text)
    if body.get("format") != _FORMAT or hashlib.sha256(npz).hexdigest() != body.get("npz_sha256"):
        raise ValueError("record does not verify")
    with np.load(io.BytesIO(npz), allow_pickle=False) as z:
        arrays = {k: z[k] for k in z.files}
    return RunRecord(key=body["key"], status=body["status"], message=body["message"],
                     values=_decode(body["values"], arrays), timing=_decode(body["timing"], arrays),
                     arrays=_decode(body["arrays"], arrays), result=_decode(body["result"], arrays),
                     seconds=float(body["seconds"]))


def roundtrip(record: RunRecord) -> RunRecord:
    """The record as it will be read back (what a resumed run sees)."""
    return loads(*dumps(record))


class RecordStore:
    """Records of the runs into one output directory (see the module docstring).

    Parameters
    ----------
    target : Path
        The output directory (``--out``); the store is ``.<name>.records``
        beside it.
    resume : bool
        Keep the records already there (``--resume``). Otherwise the store is
        emptied of its own files first (only ``<key>.json``/``.npz`` files and
        temporary files of this tool, in a directory carrying our marker).
    """

    def __init__(self, target, *, resume: bool):
        target = Path(target)
        self.path = target.parent / f".{target.name}.records"
        self.target = target.name
        self._open(resume)

    def _owned(self) -> bool:
        try:
            st = os.lstat(self.path)
        except FileNotFoundError:
            return False
        if not stat.S_ISDIR(st.st_mode) or st.st_uid != os.getuid():
            return None
        try:
            marker = json.loads((self.path / STORE_MARKER).read_text())
        except (OSError, ValueError):
            return None
        return isinstance(marker, dict) and marker.get("magic") == _MAGIC and marker.get("target") == self.target

    def _open(self, resume):
        from .atomic import TargetRefused

        owned = self._owned()
        if owned is None:
            raise TargetRefused(f"{self.path} exists and was not written by this tool; move it away")
        if not owned:
            os.mkdir(self.path)
            (self.path / STORE_MARKER).write_text(json.dumps({"magic": _MAGIC, "target": self.target}))
        elif not resume:
            self._clear()

    def _ours(self, name: str) -> bool:
        stem, _, ext = name.partition(".")
        return (ext in ("json", "npz") or ext.startswith("tmp-")) and len(stem) == 24 and \
            all(c in "0123456789abcdef" for c in stem)

    def _clear(self):
        for p in self.path.iterdir():
            if self._ours(p.name) and p.is_file() and not p.is_symlink():
                p.unlink()

    def keys(self) -> set:
        return {p.name[:-5] for p in self.path.iterdir() if p.name.endswith(".json") and self._ours(p.name)}

    def get(self, key: str) -> RunRecord | None:
        """The stored record of ``key`` if it verifies, else None."""
        try:
            text = (self.path / f"{key}.json").read_bytes()
            npz = (self.path / f"{key}.npz").read_bytes()
            rec = loads(text, npz)
        except (OSError, ValueError, KeyError, TypeError):
            return None
        return rec if rec.key == key else None

    def put(self, record: RunRecord) -> None:
        """Write ``record`` (arrays first, then its JSON: a JSON file always has
        its arrays)."""
        text, npz = dumps(record)
        for ext, data in (("npz", npz), ("json", text)):
            final = self.path / f"{record.key}.{ext}"
            tmp = self.path / f"{record.key}.tmp-{secrets.token_hex(4)}"
            with open(tmp, "wb") as f:
                f.write(data)
            os.replace(tmp, final)

    def remove(self) -> None:
        """Delete the store after a completed report: only if it is still ours
        and holds nothing but our files."""
        if self._owned() is not True:
            return
        foreign = [p for p in self.path.iterdir() if p.name != STORE_MARKER and not self._ours(p.name)]
        if foreign:
            return
        shutil.rmtree(self.path)


def nan(x):
    return math.nan if x is None else float(x)
