"""Where the test suite's time goes: per-file sums and the longest tests.

    python -m pytest -p no:randomly --junitxml=/tmp/suite.xml
    python benchmarks/suite_durations.py /tmp/suite.xml [--top 20]

Reads the JUnit XML that pytest writes (``--junitxml``) and prints the
number of tests, their summed time (setup, call and teardown of each test,
as pytest records it; collection and worker start-up are not in it), the
time in tests under one second, the files by summed time and the ``--top``
longest tests. Nothing is asserted.
"""
from __future__ import annotations

import argparse
import collections
import sys
import xml.etree.ElementTree as ET


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("xml", help="the file pytest --junitxml wrote")
    ap.add_argument("--top", type=int, default=20, help="longest tests to list (default 20)")
    args = ap.parse_args(argv)
    try:
        root = ET.parse(args.xml).getroot()
    except (OSError, ET.ParseError) as e:
        print(f"suite_durations: cannot read `xml` {args.xml!r}: {e}", file=sys.stderr)
        return 2
    per_file, count, rows = collections.Counter(), collections.Counter(), []
    for tc in root.iter("testcase"):
        module = tc.get("classname", "").split(".")
        name = module[1] if len(module) > 1 else module[0]
        t = float(tc.get("time", 0.0))
        per_file[name] += t
        count[name] += 1
        rows.append((t, f"{tc.get('classname', '').split('.')[-1]}::{tc.get('name')}"))
    total = sum(per_file.values())
    print(f"{sum(count.values())} tests, {total:.1f} s summed, {sum(t for t, _ in rows if t < 1):.1f} s in tests "
          f"under 1 s")
    print("by file (summed s, tests):")
    for name, t in per_file.most_common(15):
        print(f"  {t:7.1f} {count[name]:5d}  {name}")
    print(f"the {args.top} longest tests (s):")
    for t, name in sorted(rows, reverse=True)[:args.top]:
        print(f"  {t:7.2f}  {name}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
