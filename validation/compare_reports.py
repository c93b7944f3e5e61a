"""Compare the tables of two reports written by rk4h run (python validation/run_all.py).

    python validation/compare_reports.py OLD_DIR NEW_DIR [--columns error_max,nfev] [--where solver=rk4]

For every CSV present in both directories (rows matched by position; tables
of different lengths are reported as such; columns only in one are named, the
common ones compared), prints, per numeric column, the
largest relative difference ``|new - old| / |old|`` and the row where it
occurs, and per text column the number of rows that differ. Timing columns
(``wall_s``, ``compile_s``, the trust table's times and time verdicts) are left out unless named with
``--columns``: they differ on every run. Read-only.

Exit status: 0 when something was compared (whether or not it differs); 1,
with one line on stderr, when the comparison compared nothing: no CSV in
both directories, a ``--columns`` name that no compared table has, or a
``--where`` whose column no table has or whose value no row holds (a
misspelt option must not read as "identical"); 2 on bad input.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
import pandas as pd

TIMING = {"wall_s", "compile_s", "wall_min", "wall_max", "time_s", "alt_time_s", "alt_compile_s",
          "verdict_one_run", "verdict_amortized", "time_context", "measured_timed"}
_KEYS = ("scene", "solver", "setting", "quantity", "study")


def compare_table(old: pd.DataFrame, new: pd.DataFrame, columns=None) -> list[str]:
    """Lines describing how ``new`` differs from ``old`` (empty: identical)."""
    if len(old) != len(new):
        return [f"  shape or columns differ: {old.shape} {list(old.columns)[:6]}... vs {new.shape}"]
    out = []
    added = [c for c in new.columns if c not in old.columns]
    dropped = [c for c in old.columns if c not in new.columns]
    if dropped:
        out.append(f"  dropped columns: {', '.join(dropped)}")
    if added:
        out.append(f"  new columns: {', '.join(added)}")
    for c in (c for c in old.columns if c in new.columns):
        if (columns and c not in columns) or (not columns and c in TIMING):
            continue
        a, b = old[c], new[c]
        if a.dtype.kind in "fi" and b.dtype.kind in "fi":
            x, y = a.to_numpy(float), b.to_numpy(float)
            same = (x == y) | (np.isnan(x) & np.isnan(y))
            if same.all():
                continue
            with np.errstate(all="ignore"):
                rel = np.where(same, 0.0, np.abs(y - x) / np.abs(x))
            i = int(np.nanargmax(np.where(np.isfinite(rel), rel, np.inf)))
            where = ", ".join(f"{k}={old.at[i, k]}" for k in _KEYS if k in old.columns)
            out.append(f"  {c}: {int((~same).sum())} rows differ, largest relative {rel[i]:.3g} ({where})")
        else:
            diff = int((a.fillna("").astype(str) != b.fillna("").astype(str)).sum())
            if diff:
                out.append(f"  {c}: {diff} rows differ (text)")
    return out


_EXAMPLES = """examples:
  %(prog)s reports /tmp/quick                       every deterministic column of every common table
  %(prog)s reports /tmp/quick --columns error_max,nfev --where solver=rk4

exit status: 0 compared (differences are printed, not failures); 1 nothing was compared
(no common table, or a --columns / --where that matches nothing); 2 bad arguments."""


def main(argv=None, *, prog=None) -> int:
    p = argparse.ArgumentParser(prog=prog, description=__doc__.splitlines()[0], epilog=_EXAMPLES,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("old", help="the first report's directory (e.g. reports)")
    p.add_argument("new", help="the second report's directory, compared with the first")
    p.add_argument("--columns", default="", help="comma-separated columns to compare (default: all but timings)")
    p.add_argument("--where", default="", help="compare only rows with COLUMN=VALUE in the old table (e.g. solver=rk4)")
    args = p.parse_args(argv)
    where = None
    if args.where:
        if "=" not in args.where:
            print(f"compare_reports: `--where` must be COLUMN=VALUE, got {args.where!r}", file=sys.stderr)
            return 2
        where = args.where.split("=", 1)
    old, new = Path(args.old), Path(args.new)
    for name, d in (("old", old), ("new", new)):
        if not d.is_dir():
            print(f"compare_reports: `{name}` must be a report directory, got {str(d)!r}", file=sys.stderr)
            return 2
    columns = {c for c in args.columns.split(",") if c}
    pairs = [(f, new / f.name) for f in sorted(old.glob("*.csv"))]
    common = [(f, g) for f, g in pairs if g.is_file()]
    if not common:
        print(f"compare_reports: no table to compare: {len(pairs)} CSV file(s) in {str(old)!r}, none of them "
              f"also in {str(new)!r}", file=sys.stderr)
        return 1
    loaded, seen_columns, where_column, where_rows = [], set(), False, 0
    for f, g in common:
        a, b = pd.read_csv(f), pd.read_csv(g)
        seen_columns.update(a.columns)
        if where is not None and where[0] in a.columns:
            where_column = True
            keep = (a[where[0]].astype(str) == where[1]).to_numpy()
            where_rows += int(keep.sum())
            if len(a) == len(b):
                a, b = a[keep].reset_index(drop=True), b[keep].reset_index(drop=True)
        skip = ("no row matches `--where`" if where is not None and where[0] in a.columns and not keep.any() else
                "none of the `--columns`" if columns and not columns & set(a.columns) else "")
        loaded.append((f, a, b, skip))
    missing = sorted(columns - seen_columns)
    if missing:
        print(f"compare_reports: `--columns` names {', '.join(repr(c) for c in missing)}, a column no compared "
              f"table has", file=sys.stderr)
        return 1
    if where is not None and not where_column:
        print(f"compare_reports: `--where` column {where[0]!r} is in no compared table", file=sys.stderr)
        return 1
    if where is not None and not where_rows:
        print(f"compare_reports: `--where` {args.where!r} matches no row of the compared tables", file=sys.stderr)
        return 1
    for f, _ in pairs:
        if not (new / f.name).is_file():
            print(f"{f.name}: only in {old}")
    for f, a, b, skip in loaded:
        if skip:
            print(f"{f.name}: not compared ({skip})")
            continue
        lines = compare_table(a, b, columns)
        print(f"{f.name}: {'identical' if not lines else 'differs'}")
        for line in lines:
            print(line)
    return 0


if __name__ == "__main__":
    sys.exit(main())
