"""The runner never destroys what it did not write, serializes runs into one
``--out``, and turns environment failures into one line and exit 3.

Each case is a ``pytest.mark.parametrize`` id, so a failure names it. Runs use
a one-mass scene (RK4 only, no figures unless a case needs them): ~0.3 s each.
"""
from __future__ import annotations

import fcntl
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from validation import atomic
from validation.run_all import main

from _scenes import one_mass

REPO = Path(__file__).resolve().parent.parent
TINY = one_mass("tiny", solvers='["rk4"]', h="[0.1]", tolerances="[1e-6]")
TINY_FIGURES = one_mass("tiny-figs", solvers='["rk4"]', h="[0.1]", tolerances="[1e-6]",
                        outputs='["state", "energy", "figures"]')


def _tree(d: Path) -> dict:
    return {p.relative_to(d).as_posix(): (p.read_bytes() if p.is_file() and not p.is_symlink() else "link")
            for p in sorted(d.rglob("*")) if not p.is_dir() or p.is_symlink()}


def _main(argv, capsys):
    rc = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return rc, out, err


@pytest.fixture
def scene(tmp_path):
    p = tmp_path / "tiny.toml"
    p.write_text(TINY)
    return p


def _run_args(scene, out, *extra):
    return ["--scene", scene, "--out", out, "--repeats", "1", "--no-figures", *extra]


# -- what --out may be -------------------------------------------------------------------------
def _precious(d):
    d.mkdir()
    (d / "thesis.tex").write_text("\\section{years of work}")
    return d


def _clone(d):
    d.mkdir()
    (d / ".git").mkdir()
    (d / ".git" / "HEAD").write_text("ref: refs/heads/main\n")
    (d / "README.md").write_text("a clone")
    return d


def _file(d):
    d.write_text("not a directory")
    return d


def _link_to_file(d):
    (d.parent / "real.txt").write_text("keep me")
    d.symlink_to(d.parent / "real.txt")
    return d


def _ours_plus_foreign(d):
    d.mkdir()
    (d / atomic.MARKER).write_text(json.dumps({"magic": "rk4h-report v1", "manifest": {}}))
    (d / "notes.txt").write_text("added by hand")
    return d


def _marker_is_a_symlink(d):
    d.mkdir()
    (d.parent / "elsewhere.json").write_text(json.dumps({"magic": "rk4h-report v1", "manifest": {}}))
    (d / atomic.MARKER).symlink_to(d.parent / "elsewhere.json")
    (d / "data.csv").write_text("1,2\n")
    return d


def _marker_not_ours(d):
    d.mkdir()
    (d / atomic.MARKER).write_text('{"magic": "something else"}')
    (d / "data.csv").write_text("1,2\n")
    return d


REFUSED = [
    ("precious-directory", _precious, "was not written by this tool (it holds thesis.tex)"),
    ("a-git-clone", _clone, "was not written by this tool"),
    ("a-file", _file, "exists and is not a directory"),
    ("symlink-to-a-file", _link_to_file, "is a symbolic link to something that is not a directory"),
    ("marker-plus-foreign-file", _ours_plus_foreign, "holds files this tool did not write"),
    ("marker-is-a-symlink", _marker_is_a_symlink, "was not written by this tool"),
    ("marker-of-another-tool", _marker_not_ours, "was not written by this tool"),
]


@pytest.mark.parametrize("case, make, says", REFUSED, ids=[c[0] for c in REFUSED])
def test_out_that_is_not_ours_is_refused_untouched(tmp_path, scene, capsys, case, make, says):
    out = make(tmp_path / "out")
    before = _tree(tmp_path)
    rc, _, err = _main(_run_args(scene, out), capsys)
    assert rc == 2, err
    assert len(err.strip().splitlines()) == 1 and says in err, err
    after = _tree(tmp_path)
    assert after == before, "refused, yet something changed"


def test_out_dot_inside_a_clone_is_refused(tmp_path, scene, capsys, monkeypatch):
    clone = _clone(tmp_path / "clone")
    monkeypatch.chdir(clone)
    before = _tree(clone)
    rc, _, err = _main(_run_args(scene, "."), capsys)
    assert rc == 2 and "not written by this tool" in err
    assert _tree(clone) == before


@pytest.mark.parametrize("state", ["absent", "empty", "written-by-the-tool"])
def test_out_that_may_be_replaced(tmp_path, scene, capsys, state):
    out = tmp_path / "out"
    if state == "empty":
        out.mkdir()
    elif state == "written-by-the-tool":
        assert _main(_run_args(scene, out), capsys)[0] == 0
    rc, stdout, err = _main(_run_args(scene, out), capsys)
    assert rc == 0, err
    marker = atomic.read_marker(out)
    assert marker["state"] == "complete" and marker["scope"] == "subset" and marker["scenes"] == ["tiny"]
    assert set(marker["manifest"]) == {"accuracy.csv", "index.md"}
    assert sorted(p.name for p in tmp_path.iterdir()) == [".out.lock", "out", "tiny.toml"]


@pytest.mark.parametrize("how", ["file-added", "file-edited"])
def test_a_report_changed_by_hand_is_refused(tmp_path, scene, capsys, how):
    out = tmp_path / "out"
    assert _main(_run_args(scene, out), capsys)[0] == 0
    if how == "file-added":
        (out / "my-notes.md").write_text("mine")
    else:
        (out / "index.md").write_text((out / "index.md").read_text() + "\nmy remark\n")
    before = _tree(out)
    rc, _, err = _main(_run_args(scene, out), capsys)
    assert rc == 2 and "did not write or that changed since" in err, err
    assert _tree(out) == before


def _full_report(out: Path):
    """A complete report marked as a full run (as `python validation/run_all.py` leaves it)."""
    out.mkdir()
    (out / "index.md").write_text("the full report\n")
    tmp = atomic.fresh_dir(out)
    (tmp / "index.md").write_text("the full report\n")
    atomic.swap_into_place(tmp, out, scope="full", scenes=[f"s{i}" for i in range(23)])
    return out


@pytest.mark.parametrize("flags, rc_expected", [([], 2), (["--replace"], 0)], ids=["default", "replace"])
def test_a_subset_run_never_replaces_a_full_report_unless_asked(tmp_path, scene, capsys, flags, rc_expected):
    out = _full_report(tmp_path / "reports")
    before = _tree(out)
    rc, _, err = _main(_run_args(scene, out, *flags), capsys)
    assert rc == rc_expected, err
    if rc_expected == 2:
        assert "holds a full report (23 scenes)" in err and "--replace" in err
        assert _tree(out) == before
    else:
        assert atomic.read_marker(out)["scope"] == "subset"


def test_the_default_out_is_refused_for_a_subset(scene, capsys):
    reports = REPO / "reports"
    marker = atomic.read_marker(reports)
    # never run main() against the repository's reports/ unless it holds the full report
    assert marker is not None and marker.get("scope") == "full", "reports/ must hold a full report"
    before = {p.name: p.stat().st_mtime_ns for p in reports.iterdir()}
    rc, _, err = _main(["--scene", scene, "--repeats", "1", "--no-figures"], capsys)
    assert rc == 2 and str(reports) in err
    assert {p.name: p.stat().st_mtime_ns for p in reports.iterdir()} == before


def test_previous_report_changed_during_the_run_is_kept_aside(tmp_path):
    out = _full_report(tmp_path / "reports")
    tmp = atomic.fresh_dir(out)
    (tmp / "index.md").write_text("new\n")
    (out / "late-notes.txt").write_text("written while the run ran")
    atomic.swap_into_place(tmp, out, scope="full", scenes=["a"])
    kept = atomic.swap_into_place.kept
    assert kept is not None and (kept / "late-notes.txt").read_text() == "written while the run ran"
    assert (out / "index.md").read_text() == "new\n"


# -- the lock ------------------------------------------------------------------------------------
def test_a_held_lock_is_exit_3_and_nothing_is_touched(tmp_path, scene, capsys):
    out = tmp_path / "out"
    assert _main(_run_args(scene, out), capsys)[0] == 0
    before = _tree(tmp_path)
    fd = os.open(tmp_path / ".out.lock", os.O_RDWR)
    holder = subprocess.Popen([sys.executable, "-c", "import fcntl, os, sys, time; "
                               f"fd = os.open({str(tmp_path / '.out.lock')!r}, os.O_RDWR); "
                               "fcntl.flock(fd, fcntl.LOCK_EX); print('held', flush=True); time.sleep(30)"],
                              stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline().strip() == "held"
        rc, _, err = _main(_run_args(scene, out), capsys)
    finally:
        holder.kill()
        holder.wait()
        os.close(fd)
    assert rc == 3 and "another run holds the lock" in err and len(err.strip().splitlines()) == 1
    assert _tree(tmp_path) == before


def test_two_concurrent_runs_one_waits_out_the_other(tmp_path):
    """Run A holds the lock for its whole run; B started meanwhile gets exit 3 and
    touches nothing of A's (the bug: B deleted A's temporary directory)."""
    slow = tmp_path / "slow.toml"
    slow.write_text(one_mass("slow", t_end=2000.0, h="[0.001]", solvers='["rk4"]', tolerances="[1e-6]"))
    out = tmp_path / "out"
    cli = [sys.executable, "validation/run_all.py", "--out", str(out), "--repeats", "1", "--no-figures"]
    a = subprocess.Popen([*cli, "--scene", str(slow)], cwd=REPO, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                         text=True)
    deadline = time.monotonic() + 60
    while not any(p.name.startswith(".out.tmp-") for p in tmp_path.iterdir()):
        assert a.poll() is None and time.monotonic() < deadline, "run A never started writing"
        time.sleep(0.05)
    b = subprocess.run([*cli, "--scene", str(slow)], cwd=REPO, capture_output=True, text=True, timeout=120)
    assert b.returncode == 3 and "another run holds the lock" in b.stderr, b.stderr
    stdout, stderr = a.communicate(timeout=300)
    assert a.returncode == 0, stderr
    assert atomic.read_marker(out)["scenes"] == ["slow"]


# -- leftovers of killed runs ------------------------------------------------------------------------
def _leftover(parent: Path, name: str, marker: dict | None, files=("index.md",)):
    d = parent / name
    d.mkdir()
    for f in files:
        (d / f).write_text("half")
    if marker is not None:
        (d / atomic.MARKER).write_text(json.dumps({"magic": "rk4h-report v1", **marker}))
    return d


def test_recover_touches_only_its_own_leftovers(tmp_path):
    target = _full_report(tmp_path / "reports")
    ours = _leftover(tmp_path, ".reports.tmp-aaaa", {"state": "incomplete", "target": "reports"})
    unmarked = _leftover(tmp_path, ".reports.tmp-bbbb", None)
    other_target = _leftover(tmp_path, ".reports.tmp-cccc", {"state": "incomplete", "target": "elsewhere"})
    someone_elses = _leftover(tmp_path, ".reports.tmp-dddd", {"state": "incomplete", "target": "reports"})
    os.chown(someone_elses, 12345, 12345) if os.getuid() == 0 else None
    kept_aside = _leftover(tmp_path, ".reports.kept-eeee", {"state": "complete", "target": "reports"})
    done = atomic.recover(target)
    assert not ours.exists() and len(done) == 1 + (os.getuid() != 0)
    assert unmarked.exists() and other_target.exists() and kept_aside.exists()
    if os.getuid() == 0:
        assert someone_elses.exists()


def test_recover_restores_a_backup_when_killed_between_the_two_renames(tmp_path):
    target = tmp_path / "reports"
    backup = _leftover(tmp_path, ".reports.old-ffff", {"state": "complete", "target": "reports"})
    atomic.recover(target)
    assert not backup.exists() and (target / "index.md").read_text() == "half"


# -- environment failures: one line, exit 3 ----------------------------------------------------------
@pytest.fixture
def tmpfs(tmp_path):
    """A 160 KiB tmpfs (root only); unmounted after the test."""
    mnt = tmp_path / "mnt"
    mnt.mkdir()
    r = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=160k", "tmpfs", str(mnt)], capture_output=True)
    if r.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs here: {r.stderr.decode().strip()}")
    yield mnt
    subprocess.run(["umount", "-l", str(mnt)], check=False)


def test_disk_full_is_exit_3_one_line_and_keeps_only_its_records(tmp_path, tmpfs, capsys):
    scene = tmp_path / "figs.toml"
    scene.write_text(TINY_FIGURES)
    subprocess.run(["mount", "-o", "remount,size=24k", str(tmpfs)], check=True)  # the figures do not fit
    out = tmpfs / "out"
    rc, _, err = _main(["--scene", scene, "--out", out, "--repeats", "1"], capsys)
    assert rc == 3, err
    assert len(err.strip().splitlines()) == 1 and "No space left on device" in err and "Traceback" not in err
    # the records it made stay for --resume, and the line says where; nothing else is left
    store = tmpfs / ".out.records"
    kept = len(list(store.glob("*.json"))) if store.exists() else 0
    assert (f"{kept} record(s) kept in {store}: rerun with --resume" in err) == (kept > 0), err
    assert sorted(p.name for p in tmpfs.iterdir()) == [".out.lock"] + ([".out.records"] if kept else [])


def test_read_only_filesystem_is_exit_3(tmp_path, tmpfs, scene, capsys):
    subprocess.run(["mount", "-o", "remount,ro", str(tmpfs)], check=True)
    rc, _, err = _main(_run_args(scene, tmpfs / "out"), capsys)
    assert rc == 3 and "Read-only file system" in err and len(err.strip().splitlines()) == 1, err


def test_out_on_a_mount_point_is_refused_before_work(tmpfs, scene, capsys):
    rc, _, err = _main(_run_args(scene, tmpfs), capsys)
    assert rc == 3 and "is a mount point" in err, err
    assert list(tmpfs.iterdir()) == []


@pytest.mark.parametrize("length", [250, 300])
def test_a_name_too_long_is_exit_3(tmp_path, scene, capsys, length):
    rc, _, err = _main(_run_args(scene, tmp_path / ("r" * length)), capsys)
    assert rc == 3 and len(err.strip().splitlines()) == 1 and "Traceback" not in err, err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["tiny.toml"]


def test_sigint_in_the_first_milliseconds_is_one_line(tmp_path, scene):
    """From the script's first line on -- imports, loading, the run -- SIGINT is
    one line and exit 130. A signal inside the interpreter's own start-up (before
    a line of ours runs; 50-170 ms on a loaded machine) is Python's business: it
    dies by the signal (-2), prints "init_import_site", or prints a bare
    "KeyboardInterrupt" (exit 1) while it compiles the script; such draws are
    not counted, and most draws must land in our code."""
    landed = 0
    for delay in (0.05, 0.1, 0.15, 0.2, 0.3, 0.45, 0.6):
        p = subprocess.Popen([sys.executable, "validation/run_all.py", *map(str, _run_args(scene, tmp_path / "o"))],
                             cwd=REPO, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        time.sleep(delay)
        p.send_signal(signal.SIGINT)
        _, err = p.communicate(timeout=60)
        if p.returncode == -signal.SIGINT and not err or "init_import_site" in err or "<frozen " in err \
                or (p.returncode == 1 and err.strip() == "KeyboardInterrupt"):
            # the interpreter's start-up before our first line: site, zipimport (frozen
            # modules), or compiling the script itself (no frame of ours: a bare "KeyboardInterrupt")
            continue
        landed += 1
        assert p.returncode == 130, (delay, p.returncode, err)
        assert "Traceback" not in err and len(err.strip().splitlines()) == 1, (delay, err)
        assert "interrupted (SIGINT)" in err
    assert landed >= 4
