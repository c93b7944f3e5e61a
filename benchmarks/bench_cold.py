"""Where a cold start's extra CPU goes: numba compiles, truths, the rest.

    python benchmarks/bench_cold.py [--scene NAME ... | --quick] [--workers N] [--rounds N]
                                    [--no-shipped] [--verbose]

Runs ``run_all.py ARGS --workers 1`` twice in one fresh, empty ``RK4H_CACHE``
(cold, then warm: the second run finds what the first one wrote), each in a
child process of this script that records, in that process:

* every numba compile (numba's ``numba:compile`` event, which fires only when
  a function is compiled, not when it is loaded from numba's cache), in the
  run's process and in every worker process it starts (a ``sitecustomize``
  on ``PYTHONPATH``): the function's name, the process and the CPU seconds
  (``time.process_time``) of each outermost compile (functions compiled
  inside another's compile are counted, their time is in the outer one's);
* every reference truth computed (not read from a cache): its kind, where it
  came from (``computed``, ``shipped`` package data, ``disk``) and the CPU
  seconds of the computation.

With ``--verbose`` it lists each compile (a generated module by its first
line, ``dim 4`` to ``dim 16`` or ``array loop``, and a digest of its code without
comments) and the duplicates in effect: one function compiled for two
signatures or in two processes, two generated modules with the same code.
It prints both ledgers and the split of ``CPU(cold) - CPU(warm)`` into numba
compiles, truths and the rest (imports, loaders, noise). CPU seconds are
``getrusage(RUSAGE_CHILDREN)`` of the child (user + system), the load
average beside them: on a shared machine compare the CPU seconds, not the
wall times. The truths are recorded in the run's own process only: with
``--workers 2`` those the workers compute are in "the rest". The loops compiled with ``cache=True`` inside the package
(:mod:`rk4h.fast._kernels`, the DOP853 loop) are cached next to the
package, not under ``RK4H_CACHE``: a fresh ``RK4H_CACHE`` does not recompile
them (a fresh install does, once).
"""
from __future__ import annotations

import argparse
import datetime
import json
import os
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))  # the benchmarks' own helpers
from _child import timed_run  # noqa: E402

REPO = Path(__file__).resolve().parent.parent


def _load() -> str:
    return " ".join(Path("/proc/loadavg").read_text().split()[:3]) if Path("/proc/loadavg").exists() else "?"


#: Installed as ``sitecustomize`` (through ``PYTHONPATH``) in the measured run
#: and in every worker process it starts: one JSON line per numba compile.
_SITE = """
import json, os, time
_path = os.environ.get("RK4H_BENCH_COMPILES")
if _path:
    try:
        from numba.core import event as _event
    except ImportError:
        _event = None
    if _event is not None:
        _stack = []

        class _Compiles(_event.Listener):
            def on_start(self, ev):
                _stack.append(time.process_time())

            def on_end(self, ev):
                cpu = time.process_time() - _stack.pop()
                data = ev.data if isinstance(ev.data, dict) else {}
                fn = getattr(data.get("dispatcher"), "py_func", None)
                rec = {"name": f"{getattr(fn, '__module__', '?')}.{getattr(fn, '__qualname__', '?')}",
                       "cpu": cpu, "outer": not _stack, "pid": os.getpid(), "args": str(data.get("args", "?"))}
                try:  # a generated module: its first line and a digest of its code without comments
                    import hashlib, sys
                    _file = sys.modules[fn.__module__].__file__
                    if os.path.basename(_file).startswith("_rk4core_fast_gen_"):
                        _lines = open(_file).read().splitlines()
                        rec["header"] = _lines[0]
                        rec["code"] = hashlib.sha256("\\n".join(
                            ln.split("  #")[0] for ln in _lines if not ln.lstrip().startswith("#")).encode()
                        ).hexdigest()[:12]
                except Exception:
                    pass
                line = json.dumps(rec)
                with open(_path, "a") as f:
                    f.write(line + "\\n")

        _event.register("numba:compile", _Compiles())
"""


def _child(ledger_path: str, argv: list[str], no_shipped: bool = False) -> int:
    """In the child: record computed truths around ``run_all.main(argv)``
    (``no_shipped``: as if the package shipped no truths); the compiles are
    recorded by :data:`_SITE` in every process."""
    ledger = {"truths": []}

    from rk4h.references import truth as T

    if no_shipped:
        T.SHIPPED_DIR = Path(ledger_path).with_name("no-shipped-truths")

    def _timed(fn, label):
        def wrapper(*args, **kwargs):
            t0 = time.process_time()
            out = fn(*args, **kwargs)
            ledger["truths"].append({"kind": label, "cpu": time.process_time() - t0,
                                     "model": getattr(args[0], "name", "?")})
            return out
        return wrapper

    T._real128 = _timed(T._real128, "heyoka-real128")
    T._exact_modal = _timed(T._exact_modal, "exact-modal")
    shipped = getattr(T, "_shipped_hit", None)
    if shipped is not None:
        def counted(*args, **kwargs):
            t0 = time.process_time()
            out = shipped(*args, **kwargs)
            if out is not None:
                ledger["truths"].append({"kind": "shipped", "cpu": time.process_time() - t0,
                                         "model": f"key {str(args[0])[:12]}"})
            return out
        T._shipped_hit = counted

    sys.argv = ["run_all.py", *argv]
    from rk4h.validation import run_all

    try:
        rc = run_all.main(argv)
    finally:
        Path(ledger_path).write_text(json.dumps(ledger))
    return rc


def measure(args: list[str], cache: Path, workers: int = 1, no_shipped: bool = False) -> dict:
    """One child run of ``run_all.py args --workers N`` on ``RK4H_CACHE=cache``."""
    env = {k: v for k, v in os.environ.items() if k != "RK4H_WORKERS"}
    env["RK4H_CACHE"] = str(cache)
    env.setdefault("MPLBACKEND", "Agg")
    with tempfile.TemporaryDirectory(prefix="rk4h-cold-") as tmp:
        ledger = Path(tmp) / "ledger.json"
        site = Path(tmp) / "site"
        site.mkdir()
        (site / "sitecustomize.py").write_text(_SITE)
        compiles = Path(tmp) / "compiles.jsonl"
        env["PYTHONPATH"] = os.pathsep.join([str(site), *filter(None, [env.get("PYTHONPATH")])])
        env["RK4H_BENCH_COMPILES"] = str(compiles)
        load0 = _load()
        r, wall, cpu, _ = timed_run([sys.executable, __file__, "--child", str(ledger),
                                     *(["--no-shipped"] if no_shipped else []), "--",
                                     *args, "--workers", str(workers), "--out", str(Path(tmp) / "r")],
                                    cwd=REPO, env=env)
        led = json.loads(ledger.read_text()) if ledger.exists() else {"truths": []}
        led["numba"] = [json.loads(ln) for ln in compiles.read_text().splitlines()] if compiles.exists() else []
    if r.returncode != 0:
        sys.stderr.write(r.stderr[-3000:])
    return {"wall": wall, "cpu": cpu, "rc": r.returncode, "load": (load0, _load()), **led}


def _summary(name: str, m: dict) -> dict:
    outer = [c for c in m["numba"] if c["outer"]]
    names = [c["name"] for c in outer]
    twice = len(names) - len(set(names))
    computed = [t for t in m["truths"] if t["kind"] != "shipped"]
    shipped = [t for t in m["truths"] if t["kind"] == "shipped"]
    s = {"cpu": m["cpu"], "numba_n": len(outer), "numba_all": len(m["numba"]),
         "numba_cpu": sum(c["cpu"] for c in outer), "truth_n": len(computed),
         "truth_cpu": sum(t["cpu"] for t in computed), "shipped_n": len(shipped),
         "shipped_cpu": sum(t["cpu"] for t in shipped)}
    print(f"{name}: {m['wall']:.1f} s wall, {m['cpu']:.1f} s CPU, exit {m['rc']}, load {m['load'][0]} -> "
          f"{m['load'][1]}; numba: {s['numba_n']} outermost compiles ({s['numba_all']} functions; "
          f"{len({c['pid'] for c in outer})} processes; {twice} compiles of a name compiled before), "
          f"{s['numba_cpu']:.1f} s CPU; truths computed: {s['truth_n']}, {s['truth_cpu']:.1f} s CPU; "
          f"truths from package data: {s['shipped_n']}, {s['shipped_cpu']:.2f} s CPU", flush=True)
    return s


def _duplicates(compiles: list) -> None:
    """Print the compiles that are duplicates in effect: one function compiled
    for two signatures, in two processes, or two generated modules whose code
    (comments stripped) is the same."""
    outer = [c for c in compiles if c["outer"]]
    by_name: dict = {}
    for c in outer:
        by_name.setdefault(c["name"], []).append(c)
    for name, cs in by_name.items():
        if len({c.get("args") for c in cs}) > 1:
            print(f"  duplicate: {name} compiled for {len(cs)} signatures, {sum(c['cpu'] for c in cs):.2f} s")
        if len({c["pid"] for c in cs}) > 1:
            print(f"  duplicate: {name} compiled in {len({c['pid'] for c in cs})} processes")
    by_code: dict = {}
    for c in outer:
        if "code" in c:
            by_code.setdefault((c["code"], c["name"].rsplit(".", 1)[-1]), set()).add(c["name"])
    for (code, fn), names in by_code.items():
        if len(names) > 1:
            print(f"  duplicate: {len(names)} generated modules with the same code {code} ({fn}): "
                  f"{', '.join(sorted(names))}")
    print(f"  {len(outer)} outermost compiles, {sum(c['cpu'] for c in outer):.1f} s CPU")


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if argv[:1] == ["--child"]:
        rest = argv[2:]
        no_shipped = rest[:1] == ["--no-shipped"]
        return _child(argv[1], rest[1 + no_shipped:], no_shipped)
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scene", action="append", default=None, help="a scene to run (repeatable)")
    ap.add_argument("--quick", action="store_true", help="the --quick scenes (the default)")
    ap.add_argument("--rounds", type=int, default=1, help="cold + warm pairs, each in a fresh cache (default 1)")
    ap.add_argument("--workers", type=int, default=1,
                    help="workers of the runs (default 1; with more, the compiles and truths of the worker "
                         "processes are not in the ledger, only in the CPU seconds)")
    ap.add_argument("--no-shipped", action="store_true",
                    help="ignore the truths shipped with the package (the cold start before they shipped; "
                         "with --workers 1 only: worker processes would still read them)")
    ap.add_argument("--verbose", action="store_true", help="list every compile and truth of the cold run")
    a = ap.parse_args(argv)
    case = [x for s in a.scene or [] for x in ("--scene", s)] or ["--quick"]
    print(f"python benchmarks/bench_cold.py {' '.join(argv)} on "
          f"{datetime.datetime.now(datetime.timezone.utc):%Y-%m-%d %H:%M} UTC, {os.cpu_count()} CPUs; "
          f"run_all.py {' '.join(case)} --workers {a.workers}")
    for _ in range(a.rounds):
        with tempfile.TemporaryDirectory(prefix="rk4h-cold-cache-") as cache:
            cold = measure(case, Path(cache), a.workers, a.no_shipped)
            warm = measure(case, Path(cache), a.workers, a.no_shipped)
        c, w = _summary("cold", cold), _summary("warm", warm)
        if a.verbose:
            for x in sorted((x for x in cold["numba"] if x["outer"]), key=lambda x: -x["cpu"]):
                what = x.get("header", "").replace("# Generated by rk4h.fast.codegen ", "").replace("; do not edit.", "")
                print(f"  compile {x['cpu']:7.2f} s  {x['name']}  (process {x['pid']}) {what}"
                      f"{' code ' + x['code'] if 'code' in x else ''}")
            _duplicates(cold["numba"])
            for x in sorted(cold["truths"], key=lambda x: -x["cpu"]):
                print(f"  truth   {x['cpu']:7.2f} s  {x['kind']}  {x['model']}")
        extra = c["cpu"] - w["cpu"]
        dn = c["numba_cpu"] - w["numba_cpu"]
        dt = c["truth_cpu"] + c["shipped_cpu"] - w["truth_cpu"] - w["shipped_cpu"]
        print(f"cold / warm = {c['cpu'] / w['cpu']:.2f} (CPU); extra {extra:.1f} s CPU = numba compiles "
              f"{dn:.1f} s + truths {dt:.1f} s + the rest {extra - dn - dt:.1f} s", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
