"""Write the quadruple-precision truths of the shipped scenes as package data.

    python -m rk4h.validation.ship_truths [--check] [--dir DIR]

Plans every shipped scene (the full report's plan, figures included, and the
``--quick`` plan), takes each ``truth`` spec whose reference is heyoka's
real128 run (a nonlinear, second-order model), computes it afresh (no cache
is read) and writes it to ``references/shipped_truths/`` (``--dir``: another
folder): one ``<key>.npz`` per truth, in the disk cache's format and under its
key (:func:`rk4h.references.truth.reference_solution`), and
``MANIFEST.json`` with each entry's key, file, SHA-256, scene and grid, the
cache format and the library versions in the key. Files of the previous
manifest that the new one does not name are removed when they still are
what it recorded (named ``<key>.npz``, a regular file, the same SHA-256);
nothing else is.

``--check`` computes nothing: it lists the truths the plans ask for that the
manifest lacks (a stale folder after a model, a scene or a library changed)
and exits 1 when there is any.

Run it after changing a shipped scene, a model's code, or the heyoka, numpy
or scipy version the project is built with; the entries of the old key are
then never read (see "Shipped truths" in :mod:`rk4h.references.truth`).
"""
from __future__ import annotations

import argparse
import hashlib
import os
import sys
import time
from pathlib import Path

__all__ = ["shipped_problems", "write_shipped", "main"]


def shipped_problems() -> list[tuple]:
    """``(key, scene name, grid, model, y0, t)`` for every real128 truth the
    shipped scenes' plans (full and ``--quick``) ask for, one per key."""
    from rk4h.references import truth as T
    from rk4h.validate import check_model_y0, check_output_times

    from .execute import grid, problem
    from .plan import plan_all
    from .scenes import load_scenes

    out, seen = [], set()
    for quick in (False, True):
        for scene, spec in plan_all(load_scenes(quick=quick), quick=quick, figures=True, repeats=1):
            if spec.purpose != "truth":
                continue
            model, y0 = problem(scene)
            if model.linear or getattr(model, "first_order", False) or T.definition_hash(model) is None:
                continue
            t = check_output_times(grid(scene, model, spec))
            key = T._key(model, model.check_state(check_model_y0(model, y0), "y0"), t, "heyoka-real128",
                         T.TOL_REAL128)
            if key not in seen:
                seen.add(key)
                out.append((key, scene.name, spec.grid, model, y0, t))
    return out


def write_shipped(problems, directory, *, say=print) -> dict:
    """Compute each real128 truth of ``problems`` (as :func:`shipped_problems`
    gives them) without any cache and write it with a manifest into
    ``directory``; returns the manifest. Only truths whose run succeeded are
    written."""
    from rk4h.references import truth as T

    from .atomic import write_json_atomic

    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    manifest_file = directory / T.SHIPPED_MANIFEST
    old = _old_entries(manifest_file)
    entries = {}
    for key, scene, grid_name, model, y0, t in problems:
        t0 = time.process_time()
        truth = T.reference_solution(model, y0, t, kind="heyoka-real128", cache=False)
        if not truth.ok:
            say(f"  {scene} ({grid_name} grid): {truth.status.value}: {truth.message}; not shipped")
            continue
        if truth.key != key:  # the key reference_solution computed; a difference is a bug here
            raise RuntimeError(f"{scene}: key {truth.key} is not the planned {key}")
        file = directory / f"{key}.npz"
        if not T._save(file, truth):
            raise OSError(f"could not write {file}")
        os.chmod(file, 0o644)
        data = file.read_bytes()
        entries[key] = {"file": file.name, "sha256": hashlib.sha256(data).hexdigest(), "scene": scene,
                        "grid": grid_name, "bytes": len(data)}
        say(f"  {scene} ({grid_name} grid, {len(t)} times): {time.process_time() - t0:.2f} s CPU, "
            f"{len(data)} bytes")
    manifest = {"format": T._FORMAT, "generator": "python -m rk4h.validation.ship_truths",
                "versions": T._versions(), "tol": T.TOL_REAL128, "entries": dict(sorted(entries.items()))}
    write_json_atomic(manifest_file, manifest)
    for key, (name, digest) in old.items():
        if key not in entries:
            _remove_if_written(directory / name, digest, say)
    T._SHIPPED.pop(str(directory), None)
    return manifest


def _old_entries(manifest_file: Path) -> dict:
    """``{key: (file name, sha256)}`` of the previous manifest, whatever its
    format, only entries whose file is named ``<key>.npz`` for a
    64-hex-digit key (the names this tool gives); ``{}`` when there is no
    readable manifest."""
    from rk4h.references import truth as T

    _, entries = T.manifest_entries(manifest_file)
    return {key: (name, digest) for key, (name, digest) in entries.items()
            if len(key) == 64 and set(key) <= set("0123456789abcdef") and name == f"{key}.npz"}


def _remove_if_written(file: Path, digest: str, say) -> None:
    """Remove ``file`` only if it still is what the previous manifest
    recorded: a regular file (not a link) whose SHA-256 is ``digest``;
    anything else is left, with one line."""
    from rk4h.references import truth as T

    try:
        data = T._read_regular(file, 2**30)
    except (OSError, T._Corrupt) as e:
        say(f"  left {file}: {e}")
        return
    if data is None:
        return
    if hashlib.sha256(data).hexdigest() != digest:
        say(f"  left {file}: not the file the previous manifest names (its SHA-256 differs)")
        return
    try:
        file.unlink()
    except FileNotFoundError:
        pass


def main(argv=None) -> int:
    from rk4h.references import truth as T

    ap = argparse.ArgumentParser(prog="python -m rk4h.validation.ship_truths", description=__doc__.splitlines()[0])
    ap.add_argument("--dir", default=None, help=f"output folder (default {T.SHIPPED_DIR})")
    ap.add_argument("--check", action="store_true", help="only list the truths the manifest lacks (exit 1 if any)")
    a = ap.parse_args(argv)
    directory = Path(a.dir) if a.dir else Path(T.SHIPPED_DIR)
    problems = shipped_problems()
    if a.check:
        have = T.shipped_manifest(directory)
        missing = [p for p in problems if p[0] not in have]
        for key, scene, grid_name, *_ in missing:
            print(f"missing: {scene} ({grid_name} grid) {key}")
        print(f"{len(problems) - len(missing)} of {len(problems)} shipped truths current in {directory}")
        return 1 if missing else 0
    print(f"computing {len(problems)} real128 truths into {directory}")
    t0 = time.process_time()
    manifest = write_shipped(problems, directory)
    size = sum(e["bytes"] for e in manifest["entries"].values())
    print(f"wrote {len(manifest['entries'])} truths ({size / 1e6:.2f} MB) in {time.process_time() - t0:.1f} s CPU; "
          f"versions {manifest['versions']}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
