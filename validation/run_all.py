"""Run the validation scenes and write the report.

Usage::

    python validation/run_all.py [--quick] [--out DIR] [--scene PATH ...] [--repeats N] [--no-figures]
    python -m validation.run_all ...

Runs every scene in ``validation/scenes/`` (``--quick``: those marked
``quick = true``; ``--scene``: the files named) and writes CSV tables,
figures and ``index.md`` into ``DIR`` (default: ``reports/`` at the
repository root). All scenes are validated before anything runs.

The report is written into a fresh temporary directory beside ``DIR`` and
moved into place at the end (old -> backup, new -> DIR, backup removed), so an
interrupted run never leaves a half-written report.

Exit status: 0 every expectation held; 1 at least one failed (``index.md``
lists them first); 2 bad input (one line on stderr naming the file and the
field); 130 interrupted.
"""
from __future__ import annotations

import argparse
import os
import shutil
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
if __name__ == "__main__" and __package__ in (None, ""):
    # Run as a script: import the package `validation`, not its modules as top-level names.
    sys.path[:] = [p for p in sys.path if Path(p or ".").resolve() != REPO / "validation"]
    sys.path.insert(0, str(REPO))

__all__ = ["main", "run"]

DEFAULT_OUT = REPO / "reports"
REPEATS_FULL, REPEATS_QUICK = 3, 1


class _Parser(argparse.ArgumentParser):
    def error(self, message):  # one line, exit 2, no usage dump
        sys.stderr.write(f"run_all: {message}\n")
        raise SystemExit(2)


def _parser():
    p = _Parser(prog="run_all", description="Run the RK4 validation scenes and write the report.")
    p.add_argument("--quick", action="store_true", help="run only the scenes marked quick = true")
    p.add_argument("--out", default=str(DEFAULT_OUT), help="output directory (default: reports/)")
    p.add_argument("--scene", action="append", default=[], metavar="PATH",
                   help="scene file to run (repeatable; default: all in validation/scenes/)")
    p.add_argument("--repeats", type=int, default=None,
                   help=f"timing repeats per run (median; default {REPEATS_FULL}, --quick {REPEATS_QUICK})")
    p.add_argument("--no-figures", action="store_true", help="tables and index.md only")
    return p


class Progress:
    """A bar on a terminal, plain lines otherwise."""

    def __init__(self, total, stream=None):
        self.total, self.done = max(total, 1), 0
        self.stream = stream or sys.stdout
        self.tty = hasattr(self.stream, "isatty") and self.stream.isatty()
        self.t0 = time.perf_counter()

    def __call__(self, msg):
        self.done = min(self.done + 1, self.total)
        el = time.perf_counter() - self.t0
        if self.tty:
            width = 30
            fill = int(width * self.done / self.total)
            line = f"\r[{'#' * fill}{'.' * (width - fill)}] {self.done}/{self.total} {el:5.0f}s {msg[:60]:<60}"
            self.stream.write(line)
        else:
            self.stream.write(f"[{self.done}/{self.total}] {el:.1f}s {msg}\n")
        self.stream.flush()

    def close(self):
        if self.tty:
            self.stream.write("\n")
            self.stream.flush()


def run(scenes, out_dir, *, quick=False, repeats=REPEATS_FULL, figures=True, progress=None):
    """Run ``scenes`` and write the report into ``out_dir`` (which must exist).

    Returns ``(results, failures)``.
    """
    from validation import experiments, report

    t0 = time.perf_counter()
    results, tables, failures, findings = [], {}, [], []
    for scene in scenes:
        try:
            r = experiments.run_scene(scene, out_dir, quick=quick, repeats=repeats, figures=figures,
                                      progress=progress)
        except KeyboardInterrupt:
            raise
        except Exception as e:  # noqa: BLE001 - one scene's fault does not stop the run
            r = experiments.SceneResult(scene.name)
            r.failures.append(f"{scene.name}: the scene raised {type(e).__name__}: "
                              f"{str(e).splitlines()[0] if str(e) else ''}")
        results.append(r)
        for name, rows in r.tables.items():
            tables.setdefault(name, []).extend(rows)
        failures += r.failures
        findings += r.findings
        run.completed.append(scene.name)
    findings = report.summarize(tables) + findings
    if figures and tables.get("cheapest"):
        import pandas as pd

        from validation import figures as fig

        try:
            path, sentence = fig.crossover(out_dir, pd.DataFrame(tables["cheapest"]))
            r = experiments.SceneResult("all scenes", figures=[(path, sentence)])
            results.append(r)
        except Exception as e:  # noqa: BLE001
            findings.append(f"(crossover figure not drawn: {type(e).__name__}: {e})")
    paths = report.write_tables(out_dir, tables)
    report.write_index(out_dir, results=results, tables=tables, table_paths=paths,
                       failures=failures, findings=findings, mode="quick" if quick else "full",
                       repeats=repeats, seconds=time.perf_counter() - t0, n_scenes=len(scenes))
    return results, failures


run.completed = []


def _swap_into_place(tmp: Path, target: Path):
    """Replace ``target`` by ``tmp``: two renames on one filesystem."""
    backup = None
    if target.exists():
        backup = Path(tempfile.mkdtemp(prefix=f".{target.name}.old-", dir=target.parent))
        backup.rmdir()
        os.replace(target, backup)
    os.replace(tmp, target)
    if backup is not None:
        shutil.rmtree(backup, ignore_errors=True)


def main(argv=None) -> int:
    args = _parser().parse_args(argv)
    from validation.scenes import SceneError, load_scenes

    try:
        scenes = load_scenes(args.scene or None, quick=args.quick)
    except SceneError as e:
        sys.stderr.write(f"{e}\n")
        return 2
    if not scenes:
        sys.stderr.write("run_all: no scenes to run\n")
        return 2
    repeats = args.repeats if args.repeats is not None else (REPEATS_QUICK if args.quick else REPEATS_FULL)
    if repeats < 1:
        sys.stderr.write(f"run_all: --repeats must be >= 1, got {repeats}\n")
        return 2
    target = Path(args.out).resolve()
    if target.exists() and not target.is_dir():
        sys.stderr.write(f"run_all: --out {args.out} exists and is not a directory\n")
        return 2
    target.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{target.name}.tmp-", dir=target.parent))
    from validation.experiments import planned_units

    progress = Progress(sum(planned_units(s) for s in scenes))
    try:
        _, failures = run(scenes, tmp, quick=args.quick, repeats=repeats,
                          figures=not args.no_figures, progress=progress)
        progress.close()
        _swap_into_place(tmp, target)
    except KeyboardInterrupt:
        progress.close()
        shutil.rmtree(tmp, ignore_errors=True)
        done = ", ".join(run.completed) or "none"
        sys.stderr.write(f"run_all: interrupted; scenes completed: {done}; {args.out} left unchanged\n")
        return 130
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    print(f"report written to {target} ({len(scenes)} scene(s)); "
          f"{'all expectations held' if not failures else f'{len(failures)} expectation(s) failed'}")
    for f in failures:
        print(f"FAILED: {f}")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
