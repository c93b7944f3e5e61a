"""What a numba option or a variant of a generated loop's text does to its
compile time and its speed (issue 29, cold start round 3).

    python benchmarks/bench_compile_options.py METHOD N VARIANT [fput | net]
    NUMBA_OPT=2 python benchmarks/bench_compile_options.py rk4 3 base

Generates the loop ``rk4h.fast.codegen`` generates for ``METHOD`` on a chain
of ``N`` masses (``base``: the package's choice, the straight-line loop up to
8 masses, the array loop beyond; every other variant edits the form its round
measured: the straight-line loop up to 2 masses, the array loop from 3),
applies ``VARIANT`` to its text, compiles it in memory (no cache: a cold
compile every time) in this fresh process and prints the CPU seconds of the
first call (compile plus one short run), the best of five timed runs in ns per
step and a digest of the final state (equal digests: the same numbers bit for
bit). Variants: ``base`` (the text as generated); ``noinline`` (the slope and
the rhs wrapper inlined by LLVM instead of numba's ``inline="always"``);
``nonrt`` and ``nocfunc`` (``_nrt=False``, ``no_cfunc_wrapper=True`` on a
straight-line loop), ``both``; ``nocfunc_arr`` (the latter on an array loop);
``dense_call`` (an array loop's dense-output end slope through a called, not
inlined, wrapper); ``straight_line`` and ``array`` (that loop form at any N,
the straight-line one up to 8 masses). Designs (other generators of the array
loop, ``benchmarks/_loop_variants.py``; N >= 3): ``one_call_site`` (the stages
in a run-time loop, the slope inlined once), ``as_data`` and
``as_data_inline`` (one text per force structure, the method passed as data).
``net``: ``N`` masses in the plane, every pair joined by a spring and each
mass tied to two anchors (N (N - 1) / 2 + 2 N springs: 5 for N = 2, as
network-web; 14 for N = 4), instead of a chain; the variants ``base``,
``straight_line`` and ``array`` only.
``fput``: an FPUT chain (alpha 0.25, beta 0.5: a slope with powers) instead of
a linear one. Run each variant several times, interleaved: one compile's CPU
time varies by 20-40% on a loaded machine.
"""
from __future__ import annotations

import hashlib
import sys
import time
from pathlib import Path

import numpy as np

import rk4h
import rk4h.fast as fast
from rk4h.fast import codegen
from rk4h.methods import get_method
from rk4h.models import Chain

VARIANTS = ("base", "noinline", "slope_call", "straight_line", "array", "nonrt", "nocfunc", "both", "nocfunc_arr",
            "dense_call")
#: Other array-loop designs (``benchmarks/_loop_variants.py``; N >= 3).
DESIGNS = ("one_call_site", "as_data", "as_data_inline")


def model(N, kind=""):
    if kind == "net":
        positions = [c for i in range(N) for c in (float(i), 0.5 * (i % 2))]
        anchors = [c for i in range(N) for c in (float(i), -1.0, float(i) + 0.3, 1.5)]
        springs = [[i, j, 10.0 + i + j] for i in range(N) for j in range(i + 1, N)] + \
            [[i, N + 2 * i + a, 5.0 + a] for i in range(N) for a in range(2)]
        return rk4h.make_model("network", {"dim": 2, "masses": [1.0 + 0.1 * i for i in range(N)],
                                           "positions": positions, "anchors": anchors, "springs": springs})
    extra = {"alpha": 0.25, "beta": 0.5} if kind == "fput" else {}
    return Chain([1.0 + 0.1*i for i in range(N)], [1.0]*(N+1), **extra)


#: The decorators of the generated loops (``rk4h.fast.codegen``): the
#: straight-line loop's and the array loop's ``integrate``.
_SL = '@njit(error_model="numpy", nogil=True)  # on-disk'
_ARR = '@njit(error_model="numpy", nogil=True)\ndef integrate'


def _replace(text, old, new):
    """``text`` with ``old`` replaced; an error where ``old`` is missing (a
    variant that changed nothing would time the unmodified loop)."""
    if old not in text:
        raise AssertionError(f"variant: {old!r} is not in the generated text")
    return text.replace(old, new)


def variant(text, v):
    if v in ("base", "straight_line", "array"):  # the form is chosen in main
        return text
    if v == "noinline":   # slope/rhs inlined by LLVM instead of numba's IR inliner
        return _replace(text, '@njit(inline="always", error_model="numpy")', '@njit(error_model="numpy")')
    if v == "slope_call":  # the slope called; the rhs wrapper still inlined at numba's level
        return _replace(text, '@njit(inline="always", error_model="numpy")\ndef slope',
                        '@njit(error_model="numpy")\ndef slope')
    if v == "nonrt":
        return _replace(text, _SL, _SL.replace("nogil=True)", "nogil=True, _nrt=False)"))
    if v == "nocfunc":
        return _replace(text, _SL, _SL.replace("nogil=True)", "nogil=True, no_cfunc_wrapper=True)"))
    if v == "both":
        return _replace(text, _SL, _SL.replace("nogil=True)", "nogil=True, _nrt=False, no_cfunc_wrapper=True)"))
    if v == "nocfunc_arr":
        return _replace(text, _ARR, _ARR.replace("nogil=True)", "nogil=True, no_cfunc_wrapper=True)"))
    if v == "dense_call":
        # (the start slope is copied from the first stage's since 3fa7aa6: only the end slope is called)
        a = _replace(text, "                    rhs(fp, ip, mass, y_new, f1, 0, nq, w)",
                     "                    rhs_dense(fp, ip, mass, y_new, f1, 0, nq, w)")
        return _replace(a, _ARR, '@njit(error_model="numpy")\ndef rhs_dense(fp, ip, mass, y, out, r, n, w):\n'
                        '    rhs(fp, ip, mass, y, out, r, n, w)\n\n\n' + _ARR)
    raise KeyError(v)


def run(fn, m, kern, unrolled, nsteps, plan=(), every_step=False):
    """CPU s of the first call (the compile), best ns per step of five more,
    and the output rows: the start, one off-grid row in the last step and the
    end; with ``every_step``, one off-grid row (theta 0.5) in every step."""
    fp = np.ascontiguousarray(kern.fp, float); ip = np.ascontiguousarray(kern.ip, np.int64)
    mass = np.ascontiguousarray(m.mass, float)
    d = 2*m.n_dof
    y = np.linspace(0.01, 0.02, d)
    if every_step:
        idx = np.arange(nsteps, dtype=np.int64); theta = np.full(nsteps, 0.5)
    else:
        idx = np.array([0, nsteps-1, nsteps], np.int64); theta = np.array([0.0, 0.5, 0.0])
    ys = np.empty((idx.size, d)); bound = np.full(d, 1e300); yf = np.empty(d)
    if unrolled:
        args = (fp, ip, mass, y, 0.0, 1e-3, nsteps, idx, theta, ys, bound, 0.0, yf)
    else:
        args = (*plan, fp, ip, mass, np.zeros(kern.work_size), y, 0.0, 1e-3, nsteps, idx, theta, ys, bound, 0.0,
                yf)
    t0 = time.process_time(); fn(*args); tc = time.process_time() - t0
    best = 1e9
    for _ in range(5):
        t0 = time.perf_counter(); fn(*args); best = min(best, time.perf_counter() - t0)
    return tc, best / nsteps * 1e9, ys.copy()

def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if len(argv) not in (3, 4) or argv[2] not in VARIANTS + DESIGNS or not argv[1].isdigit() or int(argv[1]) < 1 \
            or argv[3:] not in ([], ["fput"], ["net"]) \
            or (argv[3:] == ["net"] and argv[2] not in ("base", "straight_line", "array")):
        print(f"usage: bench_compile_options.py METHOD N VARIANT [fput | net] (N >= 1, VARIANT one of "
              f"{', '.join(VARIANTS + DESIGNS)}), got {' '.join(argv)!r}", file=sys.stderr)
        return 2
    method, N, v, kind = argv[0], int(argv[1]), argv[2], "".join(argv[3:])
    try:
        tab = get_method(method)
    except ValueError as e:
        print(e, file=sys.stderr)
        return 2
    m = model(N, kind)
    kern = fast.force_kernel(m)
    # The variants edit the loop form their rounds measured: straight-line up
    # to 2 masses, the array loop beyond; ``base`` is the package's choice.
    # (The step count follows the package's choice, so that the variants of
    # one N compare; on 3 to 8 masses it is 200000 since the twenty-third
    # round, 50000 before: digests of those sizes differ from older rounds'.)
    unrolled = N <= 2
    package_array = codegen.array_loop(kern, 2 * m.n_dof)
    if v == "base":
        unrolled = not package_array
    nsteps = 50000 if package_array else 200000
    if v == "straight_line":
        if not kern.has_scalar():
            print(f"bench_compile_options.py: straight_line: N must be <= "
                  f"{kern.MAX_SCALAR_DOF * N // m.n_dof}, got {N}", file=sys.stderr)
            return 2
        unrolled = True
    if v == "array":
        unrolled = False
    plan = ()
    if v in DESIGNS:
        if unrolled:
            print(f"bench_compile_options.py: {v} is an array loop: N must be >= 3, got {N}", file=sys.stderr)
            return 2
        sys.path.insert(0, str(Path(__file__).resolve().parent))
        import _loop_variants as lv

        if v == "one_call_site":
            text = lv.one_call_site_source(tab, kern)
        else:
            text, plan = lv.as_data_source(kern, inline_comb=v == "as_data_inline"), lv.plan_data(tab)
    else:
        try:
            text = variant(codegen.source(tab, kern) if unrolled else codegen.array_source(tab, kern), v)
        except AssertionError as e:  # the variant's edit does not apply to this loop form
            form = "straight-line" if unrolled else "array"
            print(f"bench_compile_options.py: {v} does not apply to the {form} loop of N={N}: {e}", file=sys.stderr)
            return 2
    text += f"\n# variant {v} {time.time()}\n"  # a new module name: a cold compile
    mod = codegen._in_memory(codegen.module_name(text), text)
    tc, ns, rows = run(mod.integrate, m, kern, unrolled, nsteps, plan)
    yend = rows[-1]
    print(f"{method} N={N} {v}{' ' + kind if kind else ''}: compile+1run {tc:.2f} s CPU, {ns:.1f} ns/step, "
          f"y_end {hashlib.sha1(yend.tobytes()).hexdigest()[:10]}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
