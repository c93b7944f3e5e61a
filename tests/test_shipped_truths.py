"""The quadruple-precision truths shipped as package data (issue 29, cold start):
read only under their exact cache key and after their SHA-256 verifies, equal bit
for bit to a fresh computation, and never trusted when tampered with."""
import functools
import json
import os
import shutil
import warnings

import numpy as np
import pytest

import rk4h
from rk4h.references import truth as T

SHIPPED = T.SHIPPED_DIR


def _manifest():
    return json.loads((SHIPPED / T.SHIPPED_MANIFEST).read_text())


def _same_versions():
    return (SHIPPED / T.SHIPPED_MANIFEST).exists() and _manifest()["versions"] == T._versions()


needs_versions = pytest.mark.skipif(not _same_versions(), reason="the shipped truths were made with other "
                                    "heyoka/numpy/scipy versions: their keys cannot match here")


@pytest.fixture
def fresh(tmp_path):
    T.clear_memory_cache()
    T._SHIPPED.clear()
    yield tmp_path
    T.clear_memory_cache()
    T._SHIPPED.clear()


def _assert_same(a, b):
    for name in ("t", "y", "y_lo"):
        x, y = getattr(a, name), getattr(b, name)
        assert x.dtype == y.dtype and x.shape == y.shape
        assert x.tobytes() == y.tobytes(), name  # bit for bit
    assert (a.kind, a.n_steps, a.status, a.tol) == (b.kind, b.n_steps, b.status, b.tol)
    assert a.energy_drift == b.energy_drift


@functools.lru_cache(maxsize=1)
def _all_problems():
    from rk4h.validation.ship_truths import shipped_problems

    return tuple(shipped_problems())


def _problems(smallest=None):
    probs = list(_all_problems())
    if smallest:
        # the cheapest few, one per model kind
        probs = sorted(probs, key=lambda p: len(p[5]))
        out, kinds = [], set()
        for p in probs:
            if p[3].name not in kinds:
                kinds.add(p[3].name)
                out.append(p)
        probs = out[:smallest]
    return probs


@needs_versions
def test_shipped_truths_are_current():
    """Every real128 truth the shipped scenes ask for is in the manifest (else:
    ``python -m rk4h.validation.ship_truths``), and every file the manifest names
    verifies."""
    have = T.shipped_manifest(SHIPPED)
    missing = [f"{p[1]} ({p[2]} grid)" for p in _problems() if p[0] not in have]
    assert not missing, f"regenerate with `python -m rk4h.validation.ship_truths`: {missing}"
    import hashlib
    for key, (name, digest) in have.items():
        assert hashlib.sha256((SHIPPED / name).read_bytes()).hexdigest() == digest, name


def _recompute_and_compare(problems, tmp_path):
    assert problems
    for key, scene, grid, model, y0, t in problems:
        T.clear_memory_cache()
        got = T.reference_solution(model, y0, t, path=tmp_path)
        assert got.source == "shipped", scene
        assert got.key == key
        fresh = T.reference_solution(model, y0, t, cache=False)
        _assert_same(got, fresh)


@needs_versions
def test_a_few_shipped_truths_equal_a_fresh_computation_bit_for_bit(fresh):
    _recompute_and_compare(_problems(smallest=3), fresh)


@pytest.mark.slow
@needs_versions
def test_every_shipped_truth_equals_a_fresh_computation_bit_for_bit(fresh):
    _recompute_and_compare(_problems(), fresh)


# -- a shipped folder of one's own: tampering and mismatches ----------------------------------
def _small_problem(t_end=0.5):
    model = rk4h.make_model("pendulums", {"m": 1.0, "length": 1.0, "g": 9.81, "k": 2.0})
    y0 = model.state([0.3, 0.0], [0.0, 0.5])
    t = np.linspace(0.0, t_end, 11)
    key = T._key(model, y0, t, "heyoka-real128", T.TOL_REAL128)
    return key, "test", "scene", model, y0, t


@pytest.fixture
def own_shipped(fresh, monkeypatch):
    from rk4h.validation.ship_truths import write_shipped

    folder = fresh / "shipped"
    prob = _small_problem()
    write_shipped([prob], folder, say=lambda *_: None)
    monkeypatch.setattr(T, "SHIPPED_DIR", folder)
    T._SHIPPED.clear()
    return folder, prob


def _solve(prob, cache_dir):
    T.clear_memory_cache()
    _, _, _, model, y0, t = prob
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        got = T.reference_solution(model, y0, t, path=cache_dir)
    return got, [str(w.message) for w in caught if issubclass(w.category, T.TruthCacheWarning)]


def test_an_intact_entry_is_read(own_shipped, tmp_path):
    folder, prob = own_shipped
    got, said = _solve(prob, tmp_path / "c")
    assert got.source == "shipped" and not said
    assert not any((tmp_path / "c").glob("*.npz"))  # nothing computed, nothing written to the disk cache


def _entry(folder):
    manifest = json.loads((folder / T.SHIPPED_MANIFEST).read_text())
    (key, entry), = manifest["entries"].items()
    return manifest, key, folder / entry["file"]


def test_a_tampered_entry_is_recomputed_never_trusted(own_shipped, tmp_path):
    folder, prob = own_shipped
    _, _, file = _entry(folder)
    data = bytearray(file.read_bytes())
    data[len(data) // 2] ^= 1
    file.write_bytes(bytes(data))
    got, said = _solve(prob, tmp_path / "c")
    assert got.source == "computed"
    assert any("SHA-256 differs" in s and str(file) in s for s in said), said
    _assert_same(got, T.reference_solution(*prob[3:], cache=False))


def test_a_changed_entry_with_a_matching_manifest_hash_is_recomputed(own_shipped, tmp_path):
    """Values changed and the manifest's hash updated to match: the entry's own
    checksums still refuse it."""
    import hashlib
    import io

    folder, prob = own_shipped
    manifest, key, file = _entry(folder)
    with np.load(file) as z:
        arrays = {name: z[name] for name in z.files}
    arrays["y"] = arrays["y"].copy()
    arrays["y"][0, -1] += 1e-3
    buf = io.BytesIO()
    np.savez(buf, **arrays)
    file.write_bytes(buf.getvalue())
    manifest["entries"][key]["sha256"] = hashlib.sha256(buf.getvalue()).hexdigest()
    (folder / T.SHIPPED_MANIFEST).write_text(json.dumps(manifest))
    T._SHIPPED.clear()
    got, said = _solve(prob, tmp_path / "c")
    assert got.source == "computed"
    assert any("checksum mismatch" in s for s in said), said
    _assert_same(got, T.reference_solution(*prob[3:], cache=False))


def test_an_entry_under_another_key_is_not_used(own_shipped, tmp_path):
    """The manifest claims the entry for another key (another horizon): the
    entry's own key differs, so it is refused and the truth computed."""
    folder, prob = own_shipped
    other = _small_problem(t_end=0.6)
    manifest, key, file = _entry(folder)
    manifest["entries"] = {other[0]: manifest["entries"][key]}
    (folder / T.SHIPPED_MANIFEST).write_text(json.dumps(manifest))
    T._SHIPPED.clear()
    got, said = _solve(other, tmp_path / "c")
    assert got.source == "computed" and got.key == other[0]
    assert any("another key" in s or "output times" in s for s in said), said
    # ... and the key it was made for is no longer listed: computed, silently
    got, said = _solve(prob, tmp_path / "d")
    assert got.source == "computed" and not said


def test_other_library_versions_or_format_mean_no_shipped_entry(own_shipped, tmp_path, monkeypatch):
    folder, prob = own_shipped
    manifest, _, _ = _entry(folder)
    manifest["format"] = T._FORMAT + 1
    (folder / T.SHIPPED_MANIFEST).write_text(json.dumps(manifest))
    T._SHIPPED.clear()
    got, said = _solve(prob, tmp_path / "c")
    assert got.source == "computed" and not said
    # another heyoka version: another key, so the (intact) entry is not looked up
    shutil.rmtree(folder)
    from rk4h.validation.ship_truths import write_shipped
    write_shipped([prob], folder, say=lambda *_: None)
    T._SHIPPED.clear()
    monkeypatch.setattr(T, "_versions", lambda: {"heyoka": "0.0.0", "numpy": "0", "scipy": "0"})
    got, said = _solve(prob, tmp_path / "d")
    assert got.source == "computed" and got.key != prob[0] and not said


def test_no_manifest_computes(fresh, monkeypatch, tmp_path):
    monkeypatch.setattr(T, "SHIPPED_DIR", tmp_path / "absent")
    got, said = _solve(_small_problem(), tmp_path / "c")
    assert got.source == "computed" and not said


def test_the_shipped_folder_is_package_data():
    import tomllib
    from pathlib import Path

    conf = tomllib.loads((Path(__file__).resolve().parent.parent / "pyproject.toml").read_text())
    assert "rk4h.references.shipped_truths" in conf["tool"]["setuptools"]["packages"]
    data = conf["tool"]["setuptools"]["package-data"]["rk4h.references.shipped_truths"]
    assert "*.npz" in data and "MANIFEST.json" in data
    assert SHIPPED.parent == Path(T.__file__).resolve().parent
    assert os.path.basename(SHIPPED) == "shipped_truths"


# -- the shipped folder is read like any file it did not write: regular files, a size cap ------
def _solve_in_thread(prob, cache_dir, unblock):
    """``_solve`` with a deadline: a read that blocks (a FIFO) fails the test
    instead of hanging it (``unblock`` then releases the reader)."""
    import threading

    out = {}
    th = threading.Thread(target=lambda: out.update(r=_solve(prob, cache_dir)), daemon=True)
    th.start()
    th.join(60)
    if th.is_alive():
        unblock()
        th.join(10)
        pytest.fail("reading the shipped folder blocked on a FIFO")
    return out["r"]


def _release_fifo(path):
    def unblock():
        fd = os.open(path, os.O_WRONLY | os.O_NONBLOCK)
        os.close(fd)
    return unblock


def test_a_symlinked_entry_is_not_followed(own_shipped, tmp_path):
    folder, prob = own_shipped
    _, _, file = _entry(folder)
    elsewhere = tmp_path / "elsewhere.npz"
    shutil.move(file, elsewhere)
    os.symlink(elsewhere, file)
    got, said = _solve(prob, tmp_path / "c")
    assert got.source == "computed"
    assert any("symbolic link" in s and str(file) in s for s in said), said


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="no FIFOs here")
def test_a_fifo_entry_or_manifest_does_not_block(own_shipped, tmp_path):
    folder, prob = own_shipped
    _, _, file = _entry(folder)
    file.unlink()
    os.mkfifo(file)
    got, said = _solve_in_thread(prob, tmp_path / "c", _release_fifo(file))
    assert got.source == "computed"
    assert any("not a regular file" in s for s in said), said
    manifest = folder / T.SHIPPED_MANIFEST
    manifest.unlink()
    os.mkfifo(manifest)
    T._SHIPPED.clear()
    got, said = _solve_in_thread(prob, tmp_path / "d", _release_fifo(manifest))
    assert got.source == "computed" and not said


def test_an_oversized_entry_is_not_read(own_shipped, tmp_path):
    """A file far larger than the truth can be (its SHA-256 in the manifest
    matching) is refused by its size, before it is read into memory."""
    import hashlib

    folder, prob = own_shipped
    manifest, key, file = _entry(folder)
    big = b"\0" * (8 * 2**20)
    file.write_bytes(big)
    manifest["entries"][key]["sha256"] = hashlib.sha256(big).hexdigest()
    (folder / T.SHIPPED_MANIFEST).write_text(json.dumps(manifest))
    T._SHIPPED.clear()
    got, said = _solve(prob, tmp_path / "c")
    assert got.source == "computed"
    assert any("bytes, more than" in s for s in said), said


@pytest.mark.parametrize("text", ["[" * 100_000, '{"format": 3, "entries": [1]}', "[]", "\xff"],
                         ids=["deep", "entries-list", "list", "not-utf8"])
def test_a_malformed_manifest_means_no_shipped_entry(own_shipped, tmp_path, text):
    folder, prob = own_shipped
    (folder / T.SHIPPED_MANIFEST).write_bytes(text.encode("latin-1"))
    T._SHIPPED.clear()
    got, said = _solve(prob, tmp_path / "c")
    assert got.source == "computed" and not said


# -- ship_truths removes only the files its previous manifest names and that are unchanged ----
def _rewrite_with_other_problem(folder):
    from rk4h.validation.ship_truths import write_shipped

    said = []
    write_shipped([_small_problem(t_end=0.6)], folder, say=said.append)
    return said


def test_ship_truths_removes_its_own_stale_entry(own_shipped):
    folder, prob = own_shipped
    _, key, file = _entry(folder)
    _rewrite_with_other_problem(folder)
    assert not file.exists()
    assert key not in json.loads((folder / T.SHIPPED_MANIFEST).read_text())["entries"]


def test_ship_truths_never_removes_a_file_its_manifest_did_not_write(own_shipped):
    """The old manifest (not verified by anything) names a file of the user's,
    and its own entry was changed after it was written: both are left."""
    folder, prob = own_shipped
    manifest, key, file = _entry(folder)
    precious = folder / "precious.npz"
    precious.write_bytes(b"the user's")
    manifest["entries"]["0" * 64] = {"file": "precious.npz", "sha256": "0" * 64}
    (folder / T.SHIPPED_MANIFEST).write_text(json.dumps(manifest))
    file.write_bytes(file.read_bytes() + b"edited")
    said = _rewrite_with_other_problem(folder)
    assert precious.read_bytes() == b"the user's"
    assert file.exists()
    assert any("SHA-256 differs" in s and str(file) in s for s in said), said


@pytest.mark.parametrize("edited", ["_real128", "_exact_modal", "taylor", "exact"])
def test_an_edit_to_the_code_computing_truths_keys_them_anew(own_shipped, tmp_path, monkeypatch, edited):
    """A shipped (or cached) entry computed by other truth code is never read:
    the key holds the source of the code that computes a truth."""
    folder, prob = own_shipped
    real_source = T._source

    def edited_source(obj):
        text = real_source(obj)
        name = getattr(obj, "__name__", "")
        return text + "\n# edited" if name == edited or name.endswith("." + edited) else text

    T.method_hash.cache_clear()
    monkeypatch.setattr(T, "_source", edited_source)
    try:
        key = T._key(*prob[3:], "heyoka-real128", T.TOL_REAL128)
        assert key != prob[0]
        got, said = _solve(prob, tmp_path / "c")
        assert got.source == "computed" and got.key == key and not said
    finally:
        T.method_hash.cache_clear()
