"""Compare the tables of two reports written by ``run_all.py``.

    python validation/compare_reports.py OLD_DIR NEW_DIR [--columns error_max,nfev] [--where solver=rk4]

For every CSV present in both directories (rows matched by position; tables
of different shape are reported as such), prints, per numeric column, the
largest relative difference ``|new - old| / |old|`` and the row where it
occurs, and per text column the number of rows that differ. Timing columns
(``wall_s``, ``compile_s``, the trust table's times and time verdicts) are left out unless named with
``--columns``: they differ on every run. Read-only; exit 0, or 2 on bad input.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
import pandas as pd

TIMING = {"wall_s", "compile_s", "wall_min", "wall_max", "time_s", "alt_time_s", "alt_compile_s",
          "verdict_one_run", "verdict_amortized"}
_KEYS = ("scene", "solver", "setting", "quantity", "study")


def compare_table(old: pd.DataFrame, new: pd.DataFrame, columns=None) -> list[str]:
    """Lines describing how ``new`` differs from ``old`` (empty: identical)."""
    if old.shape != new.shape or list(old.columns) != list(new.columns):
        return [f"  shape or columns differ: {old.shape} {list(old.columns)[:6]}... vs {new.shape}"]
    out = []
    for c in old.columns:
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


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("old")
    p.add_argument("new")
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
    for f in sorted(old.glob("*.csv")):
        g = new / f.name
        if not g.is_file():
            print(f"{f.name}: only in {old}")
            continue
        a, b = pd.read_csv(f), pd.read_csv(g)
        if where is not None and where[0] in a.columns and a.shape == b.shape:
            keep = (a[where[0]].astype(str) == where[1]).to_numpy()
            a, b = a[keep].reset_index(drop=True), b[keep].reset_index(drop=True)
        lines = compare_table(a, b, columns)
        print(f"{f.name}: {'identical' if not lines else 'differs'}")
        for line in lines:
            print(line)
    return 0


if __name__ == "__main__":
    sys.exit(main())
