"""Run records: what one :class:`~rk4h.validation.plan.RunSpec` measured, and where
records are kept between an interrupted run and its ``--resume``.

A :class:`RunRecord` holds scalars only in ``values`` (deterministic: errors,
energy drift, nfev, steps, status), timings apart in ``timing`` (wall times,
compile time, spread of the repeats), arrays a figure needs in ``arrays`` and,
for stability units, the unit's rows, findings and plot data in ``result``.

:class:`RecordStore` keeps records in a directory this tool made and marked
(``.<out>.records`` beside the output directory; marker
:data:`STORE_MARKER`): one ``<key>.json`` per record (the spec, the record,
the size of its arrays file and one SHA-256 over the JSON and the arrays
together) and ``<key>.npz`` (numpy arrays, loaded with ``allow_pickle=False``).
The spec's key covers the harness code, the user's code the scene names, the
library versions and the BLAS kernel (:func:`rk4h.validation.plan.scene_digest`),
so a record is evidence only if it is the one this code, on these
libraries, made. Files are written under a temporary name and renamed, so a
killed run leaves whole records or none. A record is trusted only when its
JSON parses, names the spec's key and its digest matches; only regular files
are read (opened without following links and without blocking, checked with
``fstat``, size capped: a FIFO or a link to ``/dev/zero`` is never read);
anything else in the directory is ignored, and the directory itself is used
only if its marker is ours. Nothing is unpickled.

Records are never thrown away silently: a store that holds records of an
earlier run is resumed (``resume=True``), moved aside under a new name that
:attr:`RecordStore.moved_aside` gives (``fresh=True``), or refused
(:class:`RecordsLeft`, with a hint).
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
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from . import atomic
from .atomic import STORE_MAGIC, STORE_MARKER, TargetRefused

__all__ = ["RunRecord", "RecordStore", "RecordsLeft", "STORE_MARKER", "failed_record"]

_MAGIC = STORE_MAGIC
#: 2: one digest over the JSON and the arrays, the spec and the arrays' size in the JSON.
_FORMAT = 2
#: Largest record JSON read (bytes); its arrays file must have the size the JSON gives, at most
#: :data:`MAX_ARRAYS_BYTES`.
MAX_JSON_BYTES = 256 * 2**20
MAX_ARRAYS_BYTES = 2 * 2**30


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


def _digest(body: dict, npz: bytes) -> str:
    """SHA-256 of the record's JSON body (canonical: sorted keys, without the
    digest itself) and its arrays file together."""
    text = json.dumps({k: v for k, v in body.items() if k != "digest"}, sort_keys=True, allow_nan=True,
                      separators=(",", ":"))
    h = hashlib.sha256(text.encode())
    h.update(b"\0")
    h.update(npz)
    return h.hexdigest()


def dumps(record: RunRecord, spec=None) -> tuple[bytes, bytes]:
    """``(json bytes, npz bytes)`` of a record; ``spec`` (a
    :class:`~rk4h.validation.plan.RunSpec`, optional) is kept in the JSON, so a
    later run can tell a stale record of the same run from a foreign one."""
    arrays = {}
    body = {"key": record.key, "status": record.status, "message": record.message,
            "values": _encode(record.values, arrays), "timing": _encode(record.timing, arrays),
            "arrays": _encode(record.arrays, arrays), "result": _encode(record.result, arrays),
            "seconds": record.seconds, "spec": spec.to_json() if spec is not None else None}
    buf = io.BytesIO()
    np.savez(buf, **arrays)
    npz = buf.getvalue()
    body["npz_size"] = len(npz)
    body["format"] = _FORMAT
    body["digest"] = _digest(body, npz)
    return json.dumps(body, allow_nan=True).encode(), npz


def _body(text: bytes) -> dict:
    body = json.loads(text)
    if not isinstance(body, dict) or body.get("format") != _FORMAT:
        raise ValueError("record of another format")
    return body


def loads(text: bytes, npz: bytes) -> RunRecord:
    """The record of ``(json bytes, npz bytes)``; ``ValueError`` unless its
    digest (JSON and arrays together) matches."""
    body = _body(text)
    if len(npz) != body.get("npz_size") or _digest(body, npz) != body.get("digest"):
        raise ValueError("record does not verify")
    with np.load(io.BytesIO(npz), allow_pickle=False) as z:
        arrays = {k: z[k] for k in z.files}
    return RunRecord(key=body["key"], status=body["status"], message=body["message"],
                     values=_decode(body["values"], arrays), timing=_decode(body["timing"], arrays),
                     arrays=_decode(body["arrays"], arrays), result=_decode(body["result"], arrays),
                     seconds=float(body["seconds"]))


def read_regular(path, cap: int, *, exact: int | None = None) -> bytes:
    """The bytes of ``path`` if it is a regular file (not a link, FIFO,
    device or directory) of at most ``cap`` bytes (exactly ``exact`` bytes
    when given); else ``ValueError`` (``OSError`` if it cannot be opened).
    Opened with ``O_NONBLOCK | O_NOFOLLOW``: a FIFO does not block, a link
    is not followed."""
    flags = os.O_RDONLY | os.O_NONBLOCK | getattr(os, "O_NOFOLLOW", 0) | getattr(os, "O_CLOEXEC", 0)
    fd = os.open(path, flags)
    try:
        st = os.fstat(fd)
        if not stat.S_ISREG(st.st_mode):
            raise ValueError(f"{path} is not a regular file")
        want = st.st_size if exact is None else exact
        if st.st_size > cap or st.st_size != want:
            raise ValueError(f"{path} has {st.st_size} bytes, expected {want} (at most {cap})")
        chunks, left = [], want + 1  # one byte more: a file that grew is refused
        while left > 0:
            chunk = os.read(fd, min(left, 1 << 24))
            if not chunk:
                break
            chunks.append(chunk)
            left -= len(chunk)
        data = b"".join(chunks)
        if len(data) != want:
            raise ValueError(f"{path} changed while it was read")
        return data
    finally:
        os.close(fd)


def _identity(spec_json) -> str | None:
    """The spec without its digest (scene, purpose, solver, setting...): what
    a record of the same run made by other code, libraries or user code
    shares with the current spec."""
    if not isinstance(spec_json, dict):
        return None
    text = json.dumps({k: v for k, v in spec_json.items() if k != "digest"}, sort_keys=True, default=str)
    return hashlib.sha256(text.encode()).hexdigest()


class RecordsLeft(TargetRefused):
    """The store holds records of an earlier run and neither ``resume`` nor
    ``fresh`` says what to do with them (the message names both)."""


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
        Keep the records already there (``--resume``); :meth:`audit` says
        which of them cannot be used.
    fresh : bool
        Move a store holding records aside (``.<name>.records-aside-<UTC
        time>``, named by :attr:`moved_aside`) and start an empty one
        (``--fresh``).

    Raises
    ------
    RecordsLeft
        The store holds records of an earlier run and neither ``resume`` nor
        ``fresh`` is given; nothing is changed.
    rk4h.validation.atomic.TargetRefused
        ``.<name>.records`` exists and is not a store of this tool.

    A store without records is used as it is (temporary files of a killed
    write are removed: only names of this tool, regular files, in a
    directory carrying our marker).
    """

    def __init__(self, target, *, resume: bool, fresh: bool = False):
        target = Path(target)
        self.path = target.parent / f".{target.name}.records"
        self.target = target.name
        #: ``(path, number of records)`` of the store moved aside by ``fresh``, else None.
        self.moved_aside = None
        #: Number of records found at opening (0 for a new store).
        self.found = 0
        self._open(resume, fresh)

    def _owned(self) -> bool:
        try:
            st = os.lstat(self.path)
        except FileNotFoundError:
            return False
        if not stat.S_ISDIR(st.st_mode) or st.st_uid != os.getuid():
            return None
        try:
            marker = json.loads(read_regular(self.path / STORE_MARKER, 4096))
        except (OSError, ValueError):
            return None
        return isinstance(marker, dict) and marker.get("magic") == _MAGIC and marker.get("target") == self.target

    def _create(self):
        os.mkdir(self.path)
        atomic.write_json_atomic(self.path / STORE_MARKER, {"magic": _MAGIC, "target": self.target})

    def _open(self, resume, fresh):
        owned = self._owned()
        if owned is None:
            raise TargetRefused(f"{self.path} exists and was not written by this tool; move it away")
        if not owned:
            self._create()
            return
        self.found = len(self.keys())
        if not self.found:
            self._clear()
        elif resume:
            pass
        elif fresh:
            aside = self._aside()
            os.rename(self.path, aside)
            self.moved_aside = (aside, self.found)
            self.found = 0
            self._create()
        else:
            raise RecordsLeft(f"{self.path} holds {self.found} record(s) of an earlier run into {self.target}; "
                              f"rerun with --resume to use them or with --fresh to move them aside")

    def _aside(self) -> Path:
        stamp = time.strftime("%Y%m%dT%H%M%SZ", time.gmtime())
        for i in range(1000):
            p = self.path.parent / f"{self.path.name}-aside-{stamp}{f'-{i}' if i else ''}"
            if not os.path.lexists(p):
                return p
        raise TargetRefused(f"{self.path}: no free name to move it aside; remove old {self.path.name}-aside-* "
                            f"directories")

    def _ours(self, name: str) -> bool:
        stem, _, ext = name.partition(".")
        return (ext in ("json", "npz") or ext.startswith("tmp-")) and len(stem) == 24 and \
            all(c in "0123456789abcdef" for c in stem)

    def _regular(self, p: Path) -> bool:
        try:
            return stat.S_ISREG(os.lstat(p).st_mode)
        except OSError:
            return False

    def _clear(self):
        for p in self.path.iterdir():
            if self._ours(p.name) and self._regular(p):
                p.unlink()

    def keys(self) -> set:
        """Keys of the records in the store: ``<key>.json`` regular files
        (whether they verify is :meth:`get`'s business)."""
        return {p.name[:-5] for p in self.path.iterdir()
                if p.name.endswith(".json") and self._ours(p.name) and self._regular(p)}

    def get(self, key: str) -> RunRecord | None:
        """The stored record of ``key`` if it verifies, else None. Reads only
        regular files, the JSON up to :data:`MAX_JSON_BYTES`, the arrays at
        exactly the size the JSON gives."""
        try:
            text = read_regular(self.path / f"{key}.json", MAX_JSON_BYTES)
            size = _body(text).get("npz_size")
            if isinstance(size, bool) or not isinstance(size, int) or not 0 <= size <= MAX_ARRAYS_BYTES:
                return None
            npz = read_regular(self.path / f"{key}.npz", MAX_ARRAYS_BYTES, exact=size)
            rec = loads(text, npz)
        except (OSError, ValueError, KeyError, TypeError):
            return None
        return rec if rec.key == key else None

    def audit(self, rerun, planned) -> dict:
        """Why the specs ``rerun`` (planned, without a usable record) run
        although the store holds something: ``{"mismatch": n, "stale": n,
        "unused": n}``. ``mismatch``: a ``<key>.json`` of the spec's key is
        there but does not verify (edited, truncated, not a regular file);
        ``stale``: a record of the same run (scene, purpose, solver,
        setting...) made by other code, user code, libraries or BLAS kernel
        (another key); ``unused``: records whose keys no spec of ``planned``
        (keys) has and that are not stale."""
        planned = set(planned)
        names = {p.name for p in self.path.iterdir()}
        mismatch = [s for s in rerun if f"{s.key}.json" in names]
        others = {}
        for key in self.keys() - planned:
            try:
                spec = _body(read_regular(self.path / f"{key}.json", MAX_JSON_BYTES)).get("spec")
            except (OSError, ValueError):
                spec = None
            others[key] = _identity(spec)
        left = {_identity(s.to_json()): s for s in rerun if f"{s.key}.json" not in names}
        stale = {ident for ident in others.values() if ident in left}
        unused = sum(1 for ident in others.values() if ident not in stale)
        return {"mismatch": len(mismatch), "stale": len(stale), "unused": unused}

    def put(self, record: RunRecord, spec=None) -> None:
        """Write ``record`` (arrays first, then its JSON: a JSON file always has
        its arrays); ``spec`` is kept in the JSON (see :func:`dumps`)."""
        text, npz = dumps(record, spec)
        for ext, data in (("npz", npz), ("json", text)):
            final = self.path / f"{record.key}.{ext}"
            tmp = self.path / f"{record.key}.tmp-{secrets.token_hex(4)}"
            fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_CLOEXEC", 0), 0o644)
            with os.fdopen(fd, "wb") as f:
                f.write(data)
            os.replace(tmp, final)

    def remove(self) -> bool:
        """Delete the store after a completed report: only if it is still ours
        and holds nothing but our regular files. Returns whether it is gone."""
        if self._owned() is not True:
            return not os.path.lexists(self.path)
        foreign = [p for p in self.path.iterdir()
                   if p.name != STORE_MARKER and not (self._ours(p.name) and self._regular(p))]
        if foreign:
            return False
        shutil.rmtree(self.path)
        return True


def nan(x):
    return math.nan if x is None else float(x)
