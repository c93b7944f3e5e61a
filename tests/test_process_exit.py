"""A command's process ends without the interpreter's teardown only where
nothing is left to do: atexit handlers run, buffered output arrives, a live
thread or child process is waited for as the interpreter would."""
import os
import subprocess
import sys
import textwrap

import pytest

#: The children's environment: block-buffered output (as in a pipe or a
#: file), so that a line arrives only if the exit flushes it.
_ENV = {k: v for k, v in os.environ.items() if k != "PYTHONUNBUFFERED"}
#: The ``rk4h`` console script, run from a fresh interpreter (its ``argv[0]`` is ``-c``).
_RK4H = [sys.executable, "-c", "from rk4h.validation.cli import entry; entry()"]

#: Prints "teardown" when the interpreter tears the module down: the marker
#: of the slow path (a fast exit skips it).
_HEAD = textwrap.dedent("""
    import atexit, sys, threading, time
    from rk4h.validation.process_exit import exit_process

    class _Torn:
        def __del__(self):
            sys.stderr.write("teardown\\n")

    torn = _Torn()
""")


def _run(body: str, stdout=subprocess.PIPE):
    r = subprocess.run([sys.executable, "-c", _HEAD + textwrap.dedent(body)], stdout=stdout,
                       stderr=subprocess.PIPE, text=True, timeout=60, env=_ENV)
    return r.returncode, r.stdout, r.stderr


def test_a_settled_process_ends_without_teardown_and_keeps_its_output():
    # stdout is a pipe here: block-buffered, so the line arrives only if it is flushed
    rc, out, err = _run("""
        atexit.register(lambda: print("handler ran"))
        print("result line")
        exit_process(3)
    """)
    assert (rc, out) == (3, "result line\nhandler ran\n"), (rc, out, err)
    assert "teardown" not in err


def test_a_temporary_directory_left_open_is_still_removed(tmp_path):
    # TemporaryDirectory cleans up through weakref.finalize(atexit=True): an atexit handler
    rc, out, err = _run(f"""
        import tempfile
        keep = tempfile.TemporaryDirectory(dir={str(tmp_path)!r})
        print(keep.name)
        exit_process(0)
    """)
    assert rc == 0, err
    assert list(tmp_path.iterdir()) == [], out


def test_a_live_thread_is_waited_for_as_the_interpreter_would():
    rc, out, err = _run("""
        threading.Thread(target=lambda: (time.sleep(0.3), print("thread finished"))).start()
        exit_process(0)
    """)
    assert (rc, out) == (0, "thread finished\n"), (rc, out, err)
    assert "teardown" in err  # the interpreter's own exit ran


@pytest.mark.parametrize("daemon", [True, False])
def test_a_running_child_process_means_the_interpreters_exit(daemon):
    rc, out, err = _run(f"""
        import multiprocessing
        if __name__ == "__main__":
            child = multiprocessing.get_context("fork").Process(target=time.sleep, args=(0.3,), daemon={daemon})
            child.start()
            exit_process(0)
    """)
    assert rc == 0, err
    assert "teardown" in err


def test_a_daemon_thread_does_not_hold_the_exit():
    rc, out, err = _run("""
        threading.Thread(target=threading.Event().wait, daemon=True).start()
        print("done")
        exit_process(0)
    """)
    assert (rc, out) == (0, "done\n"), (rc, out, err)
    assert "teardown" not in err


def test_the_advise_command_prints_its_whole_answer_into_a_pipe():
    import json

    r = subprocess.run([sys.executable, "-m", "rk4h.validation.advise", "thesis-2dof-case1", "--target", "1e-3",
                        "--json"], capture_output=True, text=True, timeout=300, env=_ENV)
    assert r.returncode == 0, r.stderr
    assert json.loads(r.stdout)["target"] == 1e-3


@pytest.mark.parametrize("code, expected", [(0, 3), (2, 2)])
def test_output_that_cannot_be_written_is_not_a_silent_success(code, expected):
    # /dev/full: every write fails with ENOSPC, as on a full disk
    with open("/dev/full", "w") as full:
        rc, _, err = _run(f"""
            print("the answer")  # fits the buffer: only the flush at exit writes it
            exit_process({code})
        """, stdout=full)
    assert rc == expected, err
    assert "cannot write standard output: No space left on device" in err and "teardown" not in err


@pytest.mark.parametrize("argv, code", [(["rk4h", "schema", "--markdown"], 0), (["rk4h", "advise", "x.toml"], 2)])
def test_the_console_script_takes_the_fast_exit(argv, code):
    rc, out, err = _run(f"""
        sys.argv = {argv!r}
        from rk4h.validation.cli import entry
        entry()
    """)
    assert rc == code, err
    assert "teardown" not in err
    assert (len(out) > 1000) if code == 0 else ("--target" in err)


def test_a_reader_that_goes_away_is_one_line_and_status_3():
    # `rk4h schema --json-schema | head -1`: 1e5 bytes, more than a pipe holds
    p = subprocess.Popen([*_RK4H, "schema", "--json-schema"], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                         env=_ENV)
    p.stdout.read(10)
    p.stdout.close()
    err = p.stderr.read().decode()
    assert p.wait(timeout=60) == 3, err
    assert err.splitlines() == ["-c: cannot write standard output: Broken pipe"], err


def test_a_full_disk_inside_main_is_one_line_and_status_3():
    with open("/dev/full", "w") as full:
        r = subprocess.run([*_RK4H, "schema", "--markdown"], stdout=full, stderr=subprocess.PIPE, text=True,
                           timeout=60, env=_ENV)
    assert r.returncode == 3, r.stderr
    assert r.stderr.splitlines() == ["-c: cannot write: No space left on device"], r.stderr


def test_other_errors_of_main_are_not_taken_for_a_refused_write():
    rc, out, err = _run("""
        from rk4h.validation.process_exit import run_main
        def main():
            raise PermissionError(13, "Permission denied", "/etc/shadow")
        exit_process(run_main(main))
    """)
    assert rc == 1 and "Traceback" in err and "PermissionError" in err, err


def test_a_run_whose_reader_goes_away_stops_and_leaves_no_partial_report(tmp_path):
    # `rk4h run ... | head -1`: the run stops at its next progress line
    out = tmp_path / "report"
    p = subprocess.Popen([*_RK4H, "run", "--scene", "thesis-2dof-case1", "--out", str(out), "--no-figures",
                          "--repeats", "1", "--workers", "1"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=_ENV)
    first = p.stdout.readline()
    p.stdout.close()
    err = p.stderr.read().decode()
    assert first.startswith(b"[1/"), err
    assert p.wait(timeout=300) == 3, err
    assert err.splitlines()[-1] == "-c: cannot write standard output: Broken pipe" and "Traceback" not in err
    assert not out.exists()
    # no temporary report left beside it (the lock file and the records for --resume stay, by design)
    assert [q.name for q in tmp_path.iterdir() if ".tmp-" in q.name] == []


def test_a_full_disk_under_another_file_keeps_the_lines_already_printed():
    # ENOSPC from a file that is not standard output: the answer printed before it still arrives
    rc, out, err = _run("""
        from rk4h.validation.process_exit import run_main
        def main():
            print("the answer so far")
            raise OSError(28, "No space left on device", "/cache/truth.npz")
        exit_process(run_main(main))
    """)
    assert (rc, out) == (3, "the answer so far\n"), (rc, out, err)
    assert err.splitlines() == ["-c: cannot write /cache/truth.npz: No space left on device"], err
