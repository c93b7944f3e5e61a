"""What each part of a straight-line loop costs to compile (issue 29, cold
start, twenty-fourth round).

    python benchmarks/bench_loop_parts.py [METHOD] [N] [--rounds R] [--helper]

Generates the straight-line loop ``rk4h.fast.codegen.source`` writes for
``METHOD`` (default ``rk4``) on a linear chain of ``N`` masses (default 2,
at most 8), cuts one part of its text at a time and compiles each text in
memory with a fresh module name (a cold compile, no cache), in this one
process after an untimed warm-up compile (numba's own first-use cost).
Printed per text: the CPU seconds (``time.process_time``) of its first call
(the compile and a 2000-step run), the median over ``R`` rounds (default 3;
the texts alternate within a round) and that median's share of the
uncut loop's. The parts:

``as generated``
    the package's loop;
``no growth bound``
    without the block that sets the instability bound after the first
    step (``if pending > 0.0``);
``no end slope``
    the off-grid output without its end slope (the copy of the force at
    the step's end, where each dense row's last derivative comes from): the
    velocity rows' end derivative is set to the state's own component;
``no dense output``
    without the off-grid output (the end slope, a copy of the force, and
    the cubic Hermite rows); the on-grid rows stay;
``no output``
    without any output rows (the whole ``if ptr < m_out ...`` block);
``empty body``
    the same signature and decorator, returning at once: numba's floor for
    one function of these 13 arguments.

The cut loops do not write what the package's loop writes: only their
compile times compare, and nothing here is a candidate loop.

``--helper`` compares instead the package's loop with a candidate that
writes the same rows: its off-grid (Hermite) rows are written by one
function outside the loop's text (``HELPER``, compiled once before the
timed compiles, as a package would compile it once per machine), to which
the loop hands the old state, the start slope, the new state and the end
slope in a ``(4, dim)`` array allocated once per call. Printed beside the
compile medians: the best of 5 runs of 20000 steps with an off-grid row in
every step (ns per step, both loops) and whether the two loops' rows are
equal bit for bit. A text the cut
does not find refuses with one line and exit 2 (a cut that changed nothing
would time the uncut loop). Compile times on a shared machine vary by 20-40%
from one compile to the next: read the medians and the load printed beside
them.
"""
from __future__ import annotations

import argparse
import os
import re
import statistics
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))  # the repository, installed or not

#: The texts that open and close each part (``start``, ``end``: the part is
#: ``text[start:end]``), as ``rk4h.fast.codegen`` writes them.
PARTS = {
    "no growth bound": ("        if pending > 0.0:\n", "        if ptr < m_out and idx[ptr] <= i + 1:\n"),
    "no dense output": ("            if idx[ptr] == i:\n", "            while ptr < m_out and idx[ptr] == i + 1"),
    "no output": ("        if ptr < m_out and idx[ptr] <= i + 1:\n", "        y0 = n0\n"),
}
SIGNATURE = "def integrate(fp, ip, mass, y_start, t0, step, n, idx, theta, ys, bound, pending, y_fail):\n"


class CutError(ValueError):
    """A part's opening or closing text is not in the generated loop."""


def _span(text: str, start: str, end: str, what: str) -> tuple[int, int]:
    """``(i, j)``: where ``start`` opens in ``text`` and where ``end`` opens
    after it; :class:`CutError` naming ``what`` where either is missing."""
    i = text.find(start)
    j = text.find(end, i + 1) if i >= 0 else -1
    if i < 0 or j < 0:
        missing = start if i < 0 else end
        raise CutError(f"the generated loop has no {what} ({missing.strip()!r}): the cut would change nothing")
    return i, j


def cut(text: str, start: str, end: str) -> str:
    """``text`` without ``text[text.index(start):text.index(end, ...)]``."""
    i, j = _span(text, start, end, "such part")
    return text[:i] + text[j:]


def without_end_slope(text: str, n_dof: int) -> str | None:
    """``text`` whose dense output's end slope (the force at the step's end)
    is replaced by ``e_j = n_j`` for the velocity components; None where
    the loop evaluates no end slope (a method whose last stage is it). A
    start slope the dense output evaluates (a method without a stage at the
    step's start) stays."""
    start = "            if idx[ptr] == i:\n"
    rows = "                while ptr < m_out and idx[ptr] == i and theta[ptr] > 0.0:\n"
    i, w = _span(text, start, rows, "dense-output block")
    keep = "".join(f"                e{k} = n{k + n_dof}\n" for k in range(n_dof))
    a = text.find(keep, i, w)
    if a < 0:
        raise CutError("the dense-output block has no end positions' derivatives (e_k = n_(k+n))")
    b = a + len(keep)
    j = text.find("                n_extra += 1\n", b, w)
    if j < 0:  # no slope evaluated at the step's end: the last stage's is the end slope (FSAL)
        return None
    return text[:b] + "".join(f"                e{k} = n{k}\n" for k in range(n_dof, 2 * n_dof)) + text[j:]


def texts(source: str, n_dof: int) -> dict[str, str]:
    """Every variant of the generated loop ``source`` (``n_dof`` degrees of
    freedom), by name."""
    out = {"as generated": source}
    no_end_slope = without_end_slope(source, n_dof)
    if no_end_slope is not None:
        out["no end slope"] = no_end_slope
    for name, (start, end) in PARTS.items():
        out[name] = cut(source, start, end)
    head = source.split(SIGNATURE)[0]
    if head == source:
        raise CutError(f"the generated loop has no {SIGNATURE.strip()!r}")
    out["empty body"] = head + SIGNATURE + "    return n, 0, K.STATUS_OK, 0\n"
    return out


#: ``--helper``: the off-grid rows written by one function outside the loop's
#: text, compiled once (here: before the timed compiles, as the package would
#: compile it once per machine), the same arithmetic in the same order.
HELPER = """import numpy as np
from numba import njit

from rk4h.fast import _kernels as K


@njit(error_model="numpy", nogil=True)
def hermite_rows(ys, idx, theta, ptr, i, step, hb):
    m_out = idx.shape[0]
    d = hb.shape[1]
    while ptr < m_out and idx[ptr] == i and theta[ptr] > 0.0:
        w00, w10, w01, w11 = K.hermite_weights(theta[ptr], step)
        for p in range(d):
            ys[ptr, p] = w00 * hb[0, p] + w10 * hb[1, p] + w01 * hb[2, p] + w11 * hb[3, p]
        ptr += 1
    return ptr
"""
HELPER_MODULE = "_bench_loop_parts_helper"
_ROW = re.compile(r"^ {20}ys\[ptr, (\d+)\] = w00 \* (\w+) \+ w10 \* (\w+) \+ w01 \* (\w+) \+ w11 \* (\w+)$")


def with_helper(text: str, dim: int) -> str:
    """``text`` whose off-grid rows are written by :data:`HELPER`'s
    ``hermite_rows``: the loop stores the old state, the start slope, the
    new state and the end slope into a ``(4, dim)`` array allocated once per
    call, and calls it."""
    start = "                while ptr < m_out and idx[ptr] == i and theta[ptr] > 0.0:\n"
    end = "                    ptr += 1\n"
    i, j = _span(text, start, end, "off-grid rows")
    rows = [_ROW.match(line) for line in text[i + len(start):j].splitlines()[1:]]
    if len(rows) != dim or not all(rows) or [int(r.group(1)) for r in rows] != list(range(dim)):
        raise CutError(f"the off-grid rows are not the {dim} Hermite rows this variant rewrites")
    stores = [f"                hb[{a}, {p}] = {r.group(2 + a)}\n" for a in range(4) for p, r in enumerate(rows)]
    call = "                ptr = _H.hermite_rows(ys, idx, theta, ptr, i, step, hb)\n"
    out = text[:i] + "".join(stores) + call + text[j + len(end):]
    out = out.replace("from rk4h.fast import _kernels as K\n",
                      f"from rk4h.fast import _kernels as K\nimport {HELPER_MODULE} as _H\n", 1)
    head = SIGNATURE
    return out.replace(head, head + f"    hb = np.empty((4, {dim}))\n", 1)


def _helper_module():
    """Compile :data:`HELPER` once, as an importable module."""
    import types

    if HELPER_MODULE not in sys.modules:
        mod = types.ModuleType(HELPER_MODULE)
        exec(compile(HELPER, f"<{HELPER_MODULE}>", "exec"), mod.__dict__)
        sys.modules[HELPER_MODULE] = mod
    return sys.modules[HELPER_MODULE]


def _compile(text):
    """``text`` as a fresh in-memory module (a cold compile at its first call)."""
    from rk4h.fast import codegen

    text = text + f"\n# bench_loop_parts {time.time()!r} {os.getpid()}\n"  # a new module name: a cold compile
    return codegen._in_memory(codegen.module_name(text), text).integrate


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("method", nargs="?", default="rk4")
    ap.add_argument("n", nargs="?", type=int, default=2, help="masses of the chain, 1..8 (default 2)")
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--helper", action="store_true",
                    help="compare the loop with one whose off-grid rows a helper writes (compile and run)")
    args = ap.parse_args(argv)
    if not 1 <= args.n <= 8:
        ap.error(f"N: the straight-line loop takes 1..8 masses, got {args.n}")
    if args.rounds < 1:
        ap.error(f"--rounds: at least 1, got {args.rounds}")

    sys.path.insert(0, str(Path(__file__).resolve().parent))
    import bench_compile_options as bco  # its chain and its call of a loop
    import rk4h.fast as fast
    from rk4h.fast import codegen
    from rk4h.methods import get_method

    try:
        tab = get_method(args.method)
    except ValueError as e:
        print(f"bench_loop_parts.py: METHOD: {e}", file=sys.stderr)
        return 2
    model = bco.model(args.n)
    kern = fast.force_kernel(model)
    try:
        source = codegen.source(tab, kern)
        if args.helper:
            variants = {"as generated": source, "rows by a helper": with_helper(source, 2 * args.n)}
        else:
            variants = texts(source, args.n)
    except CutError as e:
        print(f"bench_loop_parts.py: {e}", file=sys.stderr)
        return 2
    d = 2 * args.n
    nsteps = 2000

    def compile_cpu(fn):
        return bco.run(fn, model, kern, True, nsteps)[0]

    load = os.getloadavg()[0]
    if args.helper:
        _helper_module()
    compile_cpu(_compile(variants["as generated"]))  # numba's first use in this process: not timed
    cpu = {name: [] for name in variants}
    loops = {}
    for _ in range(args.rounds):
        for name, text in variants.items():
            loops[name] = _compile(text)
            cpu[name].append(compile_cpu(loops[name]))
    full = statistics.median(cpu["as generated"])
    print(f"{args.method}, chain of {args.n} masses (dim {d}), {args.rounds} round(s), "
          f"load {load:.2f} -> {os.getloadavg()[0]:.2f}; compile + {nsteps}-step run, CPU s:")
    for name, values in cpu.items():
        med = statistics.median(values)
        print(f"  {name:16s} median {med:6.3f}  ({med / full:4.0%} of the loop's)  "
              + " ".join(f"{v:.3f}" for v in values))
    if args.helper:
        steps = 20000
        (_, ns0, ys0), (_, ns1, ys1) = (bco.run(loops[k], model, kern, True, steps, every_step=True)
                                        for k in variants)
        print(f"  an off-grid row in every step ({steps} steps, best of 5): {ns0:.1f} ns per step as generated, "
              f"{ns1:.1f} with the helper ({ns1 / ns0:.2f}x); rows equal bit for bit: {np.array_equal(ys0, ys1)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
