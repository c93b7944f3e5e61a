"""A command's process ends without the interpreter's teardown only where
nothing is left to do: atexit handlers run, buffered output arrives, a live
thread or child process is waited for as the interpreter would."""
import subprocess
import sys
import textwrap

import pytest

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


def _run(body: str):
    r = subprocess.run([sys.executable, "-c", _HEAD + textwrap.dedent(body)], capture_output=True, text=True,
                       timeout=60)
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
                        "--json"], capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    assert json.loads(r.stdout)["target"] == 1e-3
