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
    ours = atomic.fresh_dir(target)  # as a killed run leaves it: marked incomplete, half-written
    (ours / "index.md").write_text("half")
    hand_made = _leftover(tmp_path, ".reports.tmp-aaaaaaaaaaaa", {"state": "incomplete", "target": "reports"})
    unmarked = _leftover(tmp_path, ".reports.tmp-bbbb", None)
    other_target = _leftover(tmp_path, ".reports.tmp-cccc", {"state": "incomplete", "target": "elsewhere"})
    someone_elses = atomic.fresh_dir(target)
    os.chown(someone_elses, 12345, 12345) if os.getuid() == 0 else None
    kept_aside = _leftover(tmp_path, ".reports.kept-eeee", {"state": "complete", "target": "reports"})
    done = atomic.recover(target)
    assert not ours.exists() and done[0] == f"removed {ours.name} left by a killed run"
    assert hand_made.exists() and unmarked.exists() and other_target.exists() and kept_aside.exists()
    assert len(done) == 2 + (os.getuid() != 0)
    for d in (hand_made, unmarked, other_target, kept_aside):
        assert d.name in done[-1], done  # named, in one line
    if os.getuid() == 0:
        assert someone_elses.exists() and f"{someone_elses.name} (owned by another user)" in done[-1]


def _backup_of(report: Path, name: str) -> Path:
    """A copy of ``report`` (marker included) under ``name`` beside it."""
    import shutil

    return Path(shutil.copytree(report, report.parent / name))


def test_recover_restores_a_backup_when_killed_between_the_two_renames(tmp_path):
    report = _full_report(tmp_path / "reports")
    backup = report.rename(tmp_path / ".reports.old-0123456789ab")
    atomic.recover(report)
    assert not backup.exists() and (report / "index.md").read_text() == "the full report\n"


def test_recover_does_not_restore_a_backup_it_cannot_verify(tmp_path):
    report = _full_report(tmp_path / "reports")
    backup = report.rename(tmp_path / ".reports.old-0123456789ab")
    (backup / "index.md").write_text("edited since")
    done = atomic.recover(report)
    assert not report.exists() and (backup / "index.md").read_text() == "edited since"
    assert done == [f"left beside reports, as not provably leftovers of this tool: {backup.name} (its manifest "
                    f"does not vouch for index.md)"]


# A copy of a report (its marker copied along) under a leftover's name, then
# worked on: its manifest does not verify, so it is not this tool's to delete.
COPIES = [".reports.old-backup", ".reports.tmp-mywork", ".reports.old-0123456789ab", ".reports.kept-0123456789ab"]


@pytest.mark.parametrize("name", COPIES)
def test_a_copied_marker_does_not_make_a_directory_deletable(tmp_path, name):
    report = _full_report(tmp_path / "reports")
    copy = _backup_of(report, name)
    (copy / "my-work.txt").write_text("days of work")
    before = _tree(copy)
    done = atomic.recover(report)
    assert _tree(copy) == before
    assert len(done) == 1 and done[0].startswith("left beside reports") and name in done[0], done


@pytest.mark.parametrize("name", [".reports.tmp-0123456789ab", ".reports.kept-0123456789ab"])
def test_a_leftover_whose_manifest_verifies_is_removed(tmp_path, name):
    report = _full_report(tmp_path / "reports")
    copy = _backup_of(report, name)
    assert atomic.recover(report) == [f"removed {name} left by a killed run"] and not copy.exists()


def test_a_copy_of_an_incomplete_directory_is_not_removed(tmp_path):
    """The marker of a killed run's directory names that directory (name,
    device, inode): a copy of it, even under a name of the tool's form, is not
    the tool's to delete."""
    import shutil

    target = tmp_path / "reports"
    stale = atomic.fresh_dir(target)
    (stale / "index.md").write_text("half")
    copy = Path(shutil.copytree(stale, tmp_path / ".reports.tmp-0123456789ab"))
    (copy / "mine.txt").write_text("mine")
    shutil.rmtree(stale)
    done = atomic.recover(target)
    assert (copy / "mine.txt").read_text() == "mine"
    assert done == [f"left beside reports, as not provably leftovers of this tool: {copy.name} (its marker was "
                    f"written for another directory)"]


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


def test_disk_full_is_exit_3_one_line_and_leaves_nothing(tmp_path, tmpfs, capsys):
    scene = tmp_path / "figs.toml"
    scene.write_text(TINY_FIGURES)
    subprocess.run(["mount", "-o", "remount,size=24k", str(tmpfs)], check=True)  # the figures do not fit
    out = tmpfs / "out"
    rc, _, err = _main(["--scene", scene, "--out", out, "--repeats", "1"], capsys)
    assert rc == 3, err
    assert len(err.strip().splitlines()) == 1 and "No space left on device" in err and "Traceback" not in err
    assert sorted(p.name for p in tmpfs.iterdir()) == [".out.lock"]


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
