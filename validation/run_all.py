"""Run the validation scenes and write the report.

Usage::

    python validation/run_all.py [--quick] [--out DIR] [--scene PATH ...] [--repeats N] [--no-figures]
                                 [--max-output-points N] [--max-steps N] [--max-truth-steps N]
                                 [--replace] [--workers N] [--exclusive-timing] [--scheduler ADDRESS]
                                 [--resume | --fresh] [--allow-code]
    python -m rk4h.validation.run_all ...

Runs every scene in ``validation/scenes/`` (``--quick``: those marked
``quick = true``; ``--scene``: the files named) and writes CSV tables,
figures and ``index.md`` into ``DIR`` (default: ``reports/`` at the
repository root). Every scene the run runs is validated, and its cost
estimated (:mod:`rk4h.validation.budget`), before anything runs; ``--quick``
reads the other files' ``quick`` mark only, and does not validate them.

``DIR`` is replaced only if it is absent, empty, or a report this tool wrote
and nothing has changed in since (:mod:`rk4h.validation.atomic`: a marker file with
a manifest); anything else is refused before any work, untouched. A ``--quick``
or ``--scene`` run never replaces a full report unless ``--replace`` is given.

A scene the project does not ship may name code (a ``command`` or ``python``
method, a ``module:Class`` model): it is refused, exit 2, before anything is
imported or started, unless ``--allow-code`` (or ``RK4H_ALLOW_CODE=1``) is
given (:mod:`rk4h.validation.scenes`, "Code in a scene").
Runs into one ``DIR`` are serialized by ``flock`` on ``.<DIR>.lock`` beside it.
The report is written into a fresh directory beside ``DIR`` and swapped into
place at the end (one atomic ``renameat2`` exchange where the filesystem has
it), so an interrupted or killed run never leaves a half-written or mixed
report; leftovers of killed runs are cleaned at the next start. SIGINT
(Ctrl-C) and SIGTERM stop the run, remove its temporary directory and print
which scenes had finished.

The work is a plan (:mod:`rk4h.validation.plan`): one record per spec, executed
on ``--workers`` local processes (default: as many as the plan's estimated
work repays, at most the cores this process may use, see
:func:`rk4h.validation.workers.choose_workers`) or on a Dask cluster
(``--scheduler``); the timed runs come last, one per worker
(``--exclusive-timing``: one at a time, the other workers idle; see
:mod:`rk4h.validation.engine`). Each record is written to ``.<DIR>.records``
beside ``DIR`` as it arrives (:mod:`rk4h.validation.records`). After an interrupted
or failed run, ``--resume`` reruns only the specs that have no usable record
(none, one that does not verify, or one made by other code, user code,
libraries or BLAS kernel: the summary line counts them); ``--fresh`` moves
the earlier records aside (``.<DIR>.records-aside-<UTC time>``, named on
stderr) and runs everything; with neither, a run that finds records of an
earlier run refuses (exit 2) and leaves them. A run that stops (interrupt,
crash, environment) keeps its records; they are removed once the report is
in place.

Exit status: 0 every expectation held; 1 at least one failed (``index.md``
lists them first); 2 bad input (one line on stderr naming the file and the
field, or the flag, or an ``--out`` it must not replace); 3 the environment
refused (lock held, not writable, disk full, mount point, name too long: one
line); 130 interrupted by SIGINT, 143 by SIGTERM.

This module is the command line: options, progress, signals, exit status;
the run itself is :func:`rk4h.validation.runner.execute`, which returns a
:class:`rk4h.validation.runner.RunReport` that :func:`main` prints.
"""
from __future__ import annotations

try:
    import os
    import signal

    if __name__ == "__main__":
        # Until main() installs its handlers (imports take a while), a signal ends
        # the process with one line; nothing has been written yet.
        def _early_exit(signum, frame):
            os.write(2, f"run_all: interrupted ({signal.Signals(signum).name}) before any scene ran\n".encode())
            os._exit(128 + signum)

        signal.signal(signal.SIGINT, _early_exit)
        signal.signal(signal.SIGTERM, _early_exit)
except KeyboardInterrupt:  # SIGINT while the early handler was being installed
    import sys as _sys

    _sys.stderr.write("run_all: interrupted (SIGINT) before any scene ran\n")
    _sys.stderr.flush()
    raise SystemExit(130) from None

import argparse
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
if __name__ == "__main__" and __package__ in (None, ""):
    # Run as a script: import the package `validation`, not its modules as top-level names.
    sys.path[:] = [p for p in sys.path if Path(p or ".").resolve() != REPO / "validation"]
    sys.path.insert(0, str(REPO))
    try:  # the folders import as rk4h, rk4h.references, rk4h.validation once installed
        import rk4h  # noqa: F401
    except ModuleNotFoundError:
        sys.stderr.write("run_all: the harness is not installed: run `pip install -e .` in the checkout first\n")
        raise SystemExit(2) from None

__all__ = ["main", "run", "Interrupted", "exit_process"]

from rk4h.validation.process_exit import exit_process, run_main  # noqa: E402,F401 - exit_process re-exported
from rk4h.validation.runner import (  # noqa: E402,F401 - the pipeline, re-exported
    DEFAULT_OUT, MAX_REPEATS, REPEATS_FULL, REPEATS_QUICK, Interrupted, _crossover_job, run)



class _Parser(argparse.ArgumentParser):
    def error(self, message):  # one line, exit 2, no usage dump
        sys.stderr.write(f"run_all: {message}\n")
        raise SystemExit(2)


def _int_at_least(lo, hi=None):
    want = f"an integer >= {lo}" if hi is None else f"an integer from {lo} to {hi}"

    def parse(text):
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"must be {want}, got {text!r}") from None
        if value < lo or (hi is not None and value > hi):
            raise argparse.ArgumentTypeError(f"must be {want}, got {text!r}")
        return value
    return parse


def _positive_float(text):
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be a positive number, got {text!r}") from None
    if not value > 0 or value == float("inf"):
        raise argparse.ArgumentTypeError(f"must be a positive finite number, got {text!r}")
    return value


_EXAMPLES = """examples:
  %(prog)s --quick --out /tmp/quick               the quick scenes (a minute), report in /tmp/quick
  %(prog)s --scene thesis-2dof-case1 --out /tmp/c1  one shipped scene, by name or path
  %(prog)s --scene my.toml --allow-code --out /tmp/m  a scene of yours that names code (read it first)
  %(prog)s --out /tmp/r --resume                  finish an interrupted run from its records
  %(prog)s                                        every shipped scene into ./reports

exit status: 0 every expectation held; 1 one failed (listed first in index.md); 2 bad input;
3 the environment refused (lock held, disk full, unwritable); 130/143 interrupted (SIGINT/SIGTERM)."""


def _parser(prog="run_all.py"):
    from rk4h.validation.budget import MAX_STEPS, MAX_TRUTH_STEPS

    p = _Parser(prog=prog, description="Run the validation scenes (every shipped one by default) and write the "
                "report: tables, figures and index.md.", epilog=_EXAMPLES,
                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--quick", action="store_true", help="run only the scenes marked quick = true")
    p.add_argument("--out", default=str(DEFAULT_OUT), help="output directory (default: ./reports of the working directory)")
    p.add_argument("--scene", action="append", default=[], metavar="PATH",
                   help="scene file to run (repeatable; default: all in validation/scenes/)")
    p.add_argument("--repeats", type=_int_at_least(1, MAX_REPEATS), default=None,
                   help=f"timing repeats per run, 1..{MAX_REPEATS} (median; default {REPEATS_FULL}, "
                        f"--quick {REPEATS_QUICK})")
    p.add_argument("--replace", action="store_true",
                   help="let a --quick or --scene run replace a full report in --out")
    p.add_argument("--no-figures", action="store_true", help="tables and index.md only")
    p.add_argument("--workers", type=_int_at_least(1, 1024), default=None, metavar="N",
                   help="local worker processes (default: $RK4H_WORKERS, else as many as the plan's "
                        "estimated work repays, at most the cores this process may use; 1: no pool)")
    p.add_argument("--exclusive-timing", action="store_true",
                   help="time each run alone, the other workers idle (slower; for a machine where parallel "
                        "runs disturb each other's timings)")
    p.add_argument("--scheduler", default=None, metavar="ADDRESS",
                   help="run the plan on the Dask distributed scheduler at ADDRESS (tcp://host:port)")
    again = p.add_mutually_exclusive_group()
    again.add_argument("--resume", action="store_true",
                       help="use the records of an interrupted run into the same --out and run only the rest "
                            "(records that do not verify or were made by other code or libraries are rerun)")
    again.add_argument("--fresh", action="store_true",
                       help="move the records of an earlier run into the same --out aside and run everything")
    p.add_argument("--allow-code", action="store_true",
                   help="run the programs and import the Python modules that scenes not shipped with the "
                        "project name (command/python methods, module:Class models); read them first "
                        "(default: refused; also RK4H_ALLOW_CODE=1)")
    p.add_argument("--max-output-points", type=_int_at_least(2), default=None, metavar="N",
                   help="decimate each scene's output grid to at most N points (every k-th point; "
                        "a scene's own [run] max_output_points wins)")
    p.add_argument("--max-steps", type=_positive_float, default=MAX_STEPS, metavar="N",
                   help=f"refuse scenes estimated above N integration steps (default {MAX_STEPS:g})")
    p.add_argument("--max-truth-steps", type=_positive_float, default=MAX_TRUTH_STEPS, metavar="N",
                   help=f"refuse scenes whose quadruple-precision reference is estimated above N Taylor "
                        f"steps (default {MAX_TRUTH_STEPS:g})")
    return p


class Progress:
    """A bar on a terminal, plain lines otherwise: ``total`` is the plan's
    length; the ETA assumes the remaining specs cost the mean so far (the plan
    starts the longest ones, so it errs high early)."""

    def __init__(self, total, stream=None):
        self.total, self.done = max(total, 1), 0
        self.stream = stream or sys.stdout
        self.tty = hasattr(self.stream, "isatty") and self.stream.isatty()
        self.t0 = time.perf_counter()

    def __call__(self, msg):
        self.done += 1
        if self.done > self.total:
            raise RuntimeError(f"progress: unit {self.done} of a plan of {self.total}")
        el = time.perf_counter() - self.t0
        eta = f" ETA {el / self.done * (self.total - self.done):.0f}s" if self.done < self.total else ""
        if self.tty:
            width = 30
            fill = int(width * self.done / self.total)
            line = (f"\r[{'#' * fill}{'.' * (width - fill)}] {self.done}/{self.total} {el:5.0f}s{eta:>10} "
                    f"{msg[:55]:<55}")
            self.stream.write(line)
        elif self._due(el):
            self.stream.write(f"[{self.done}/{self.total}] {el:.1f}s{eta} {msg}\n")
        else:
            self._unprinted = (el, msg)
            return
        self._unprinted = None
        self.stream.flush()

    #: Off a terminal (a log file, CI) the first line, then a line at most
    #: every this fraction of the plan or this many seconds, and the last
    #: (written by :meth:`close`: confirmation runs may still extend the plan).
    LOG_FRACTION, LOG_SECONDS = 0.05, 10.0

    def _due(self, elapsed) -> bool:
        last_done, last_t = getattr(self, "_last", (0, 0.0))
        if (self.done == 1 or self.done - last_done >= self.LOG_FRACTION * self.total
                or elapsed - last_t >= self.LOG_SECONDS):
            self._last = (self.done, elapsed)
            return True
        return False

    def extend(self, n: int):
        """``n`` more specs to come (confirmation runs planned from the records)."""
        self.total += int(n)

    def close(self):
        if self.tty:
            self.stream.write("\n")
            self.stream.flush()
        elif getattr(self, "_unprinted", None) is not None:  # the last unit, not yet written
            el, msg = self._unprinted
            self._unprinted = None
            self.stream.write(f"[{self.done}/{self.total}] {el:.1f}s {msg}\n")
            self.stream.flush()


class _Signals:
    """SIGINT/SIGTERM raise :class:`Interrupted`, except inside ``critical()``
    sections, where they are held until the section ends."""

    SIGNALS = (signal.SIGINT, signal.SIGTERM)

    def __init__(self, restore=True):
        self.held, self.pending, self.saved, self.restore = False, None, {}, restore

    def _handler(self, signum, frame):
        from rk4h.validation import interrupt

        interrupt.record(signum)
        if self.held:
            self.pending = self.pending or signum
            return
        raise Interrupted(signum)

    def _unraisable(self, info):
        # An Interrupted raised where Python cannot propagate it (a ctypes
        # callback) is already recorded (interrupt.pending); say nothing.
        if isinstance(info.exc_value, Interrupted):
            return
        self.saved_hook(info)

    def __enter__(self):
        for s in self.SIGNALS:
            self.saved[s] = signal.signal(s, self._handler)
        self.saved_hook, sys.unraisablehook = sys.unraisablehook, self._unraisable
        return self

    def __exit__(self, *exc):
        for s, h in self.saved.items():
            # the command line's outcome is decided: a late signal no longer changes it
            signal.signal(s, h if self.restore else signal.SIG_IGN)
        sys.unraisablehook = self.saved_hook
        return False

    def hold(self):
        self.held = True

    def release(self):
        """End a held section; an interrupt that came meanwhile is raised now."""
        self.held = False
        if self.pending is not None:
            signum, self.pending = self.pending, None
            raise Interrupted(signum)


def main(argv=None, *, restore_signals=True, prog="run_all.py") -> int:
    """The command line (see the module docstring); returns the exit status.

    SIGINT and SIGTERM handlers are installed for the call and restored after
    it (``restore_signals=False``: ignored after it, for the process's exit)."""
    from rk4h import _heyoka
    from rk4h.validation import extras, interrupt

    _heyoka.own_process()  # this process is rk4h's: heyoka may come without sympy
    lack = extras.message("run", prog)
    if lack is None and argv is not None and "--scheduler" in argv:
        lack = extras.message("cluster", prog)
    if lack and not extras.asks_help(argv):
        print(lack, file=sys.stderr)
        return 2
    interrupt.reset()
    with _Signals(restore_signals) as sig:
        try:
            return _main(argv, sig, prog)
        except BaseException as e:  # noqa: BLE001 - before any output directory was made
            # A signal inside a C extension's initialization can surface as another exception.
            signum = getattr(e, "signum", None) or interrupt.pending()
            if signum is None and isinstance(e, KeyboardInterrupt):
                signum = signal.SIGINT
            if signum is None:
                raise
            sys.stderr.write(f"run_all: interrupted ({signal.Signals(signum).name}) before any scene ran\n")
            return 128 + signum


def _main(argv, sig, prog="run_all.py") -> int:
    from rk4h.validation import runner

    args = _parser(prog).parse_args(argv)

    def notify(line, err=False):
        if err:
            sys.stderr.write(f"{line}\n")
        else:
            print(line)
            sys.stdout.flush()

    report = runner.execute(runner.RunOptions.from_namespace(args), progress=Progress, notify=notify, guard=sig)
    return _print_report(report)


def _print_report(report) -> int:
    """Print what the run did (stdout) or why it stopped (stderr); returns
    its exit status."""
    if report.message is not None:
        sys.stderr.write(f"{report.message}\n")
        return report.status
    if report.kept_aside is not None:
        kept, why = report.kept_aside
        sys.stderr.write(f"run_all: the previous report was not removed ({why}); it was kept aside as {kept}\n")
    phases = ", ".join(f"{k} {v:.1f} s" for k, v in report.phases.items())
    where = f"Dask at {report.scheduler}" if report.scheduler else f"{report.workers} worker(s)"
    if report.workers_why and not report.scheduler and report.workers_why != "as asked":
        where += f": {report.workers_why}"
    print(f"{report.planned} runs planned, {report.resumed} resumed, {report.executed} executed ({where}); "
          f"{phases}")
    if report.records_found:
        a = report.audit
        print(f"records: {report.resumed} resumed, {a['mismatch'] + a['stale']} rerun ({a['mismatch']} digest "
              f"mismatch, {a['stale']} stale: made by other code or libraries)"
              + (f", {a['unused']} unused (no planned run)" if a["unused"] else ""))
    n = len(report.failures)
    print(f"report written to {report.out} ({len(report.scenes)} scene(s)); "
          f"{'all expectations held' if not n else f'{n} expectation(s) failed'}")
    for f in report.failures:
        print(f"FAILED: {f}")
    return report.status


if __name__ == "__main__":
    exit_process(run_main(lambda: main(restore_signals=False)))
