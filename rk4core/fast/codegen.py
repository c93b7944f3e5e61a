"""Fixed-step loops generated from a method's tableau and a model's force kernel.

Nothing here is written per method or per model: the inputs are the method's
Butcher tableau and the force kernel printed from the model's symbolic
definition (:mod:`rk4h.models.compiled`). The loop is written out for one
tableau: the products ``h a_ij`` and ``h b_i`` are formed once and terms with
a zero coefficient are left out.

* :func:`source` -- a small state (``dim <= MAX_UNROLLED_DIM``, up to 8
  degrees of freedom): the state and the stage slopes are scalar locals and
  the force is the kernel's straight-line code inlined on them (a 2-DOF step
  is about 40 flops, so overhead is everything);
* :func:`array_source` -- any size: arrays, one fused pass per stage (a
  classical method's position and velocity halves together), the kernel's
  ``slope`` (a chain's force, velocity copy and division by the mass in one
  pass), the instability test folded into the update pass;
* :func:`model_source` -- the compiled right-hand sides the references call
  (:class:`rk4h.fast.CompiledRHS`).

A loop's text depends on the definition's structure, not on its numbers
(those are the ``fp``/``ip`` arrays), so one compiled loop serves every model
of that structure (and, for the straight-line loop, that size); nor on the
method's name, only its coefficients, so two methods with equal tableaux
(``forest-ruth`` and a scene's ``forest-ruth-as-data``) share one file and one
compile in every process.

The arithmetic is that of ``rk4h.rk_step``: stage ``s`` is
``y + (h a_s0) k_0 + (h a_s1) k_1 + ...`` summed left to right over the
nonzero ``a_sj`` (position and velocity halves with their own coefficients for
a partitioned method), the new state ``y + (h b_0) k_0 + ...``, each sum
that begins with the one the stage state holds continued from it
(:class:`_Held`: the same additions, so the same double), and off-grid
outputs the cubic Hermite interpolant of ``_kernels._hermite``; with the
force printed in the numpy path's operation order, the results equal
``rk4h.solve(model.rhs, ...)`` bit for bit wherever the elementary
functions agree. Which stages call the force, in which order a partitioned
stage forms its velocity and position, and which evaluation a
first-same-as-last method carries into the next step are read from the
tableau's computed properties (``stage_evaluated``, ``fsal_stages``,
``start_stage``; :class:`_Plan`), as ``rk_step`` reads them: the same calls,
so the same ``nfev``.

Each generated source is written once to a file named by a hash of its text
and compiled with numba's on-disk cache, so a second process loads it warm.
The text embeds a hash of ``_kernels.py`` and of this module: numba's cache
checks only the file holding the cached function, so a change of the kernels
it calls yields a new file (and a fresh compile), never a stale cached loop.

Cache security. The files live in the per-user directory
``rk4h.cachedir.private_dir("fast")`` (``$RK4H_CACHE/fast``, else
``~/.cache/rk4h/fast``; created 0700 and verified: a real directory, owned by
the user, closed to group and others) and numba's index and data files in its
``__pycache__`` (pinned there, ``NUMBA_CACHE_DIR`` notwithstanding). The code
run is always the text generated in this process; a file on disk that is not
a regular file owned by the user, closed to writes by others, with exactly
that text, is rewritten and reported by a :class:`CacheWarning` (Python's
``warnings``: one line on stderr by default). When the directory cannot be
verified nothing is read from it: the loop is compiled in memory, without an
on-disk cache, after one :class:`CacheWarning`.
"""
from __future__ import annotations

import contextlib
import hashlib
import inspect
import linecache
import os
import pathlib
import re
import secrets
import stat
import sys
import types
import warnings

import numpy as np

from .. import cachedir
from ..cachedir import UntrustedCacheError, private_dir
from ..methods import Tableau
from . import _kernels as K

__all__ = ["MAX_UNROLLED_DIM", "MAX_UNROLLED_FORCE_LINES", "source", "array_source", "model_source", "kernel",
           "array_kernel", "array_loop", "model_module", "load_generated", "loop_key", "compiled_kernels",
           "module_name", "CacheWarning"]

#: Largest state size (2 n_dof) that gets the straight-line loop: up to 8
#: degrees of freedom, the largest force a kernel writes as straight-line code
#: (``ForceKernel.MAX_SCALAR_DOF``). On chains of 3 to 8 masses that loop ran
#: 1.4-3.3x faster than the array loop (whose vectorized passes pay run-time
#: alias checks and remainders on short arrays) and compiled in about half the
#: time for the many-stage methods, within 15% either way for RK4
#: (docs/performance.md, twenty-second and twenty-third rounds). Its text holds
#: the size (and a network's edge list), so it is compiled per number of
#: degrees of freedom; larger states run the array loop, one text per force
#: structure for every size.
MAX_UNROLLED_DIM = 16

#: Largest force, in lines of straight-line code (``ForceKernel.scalar_size``),
#: that the straight-line loop inlines at each stage; a longer one runs the
#: array loop. The straight-line loop's compile grows with the force's text
#: times the stages, the array loop's hardly: on planar networks of 2, 3 and 4
#: masses (54, 96 and 148 lines) the straight-line RK4 loop compiled in 0.6,
#: 0.9 and 1.3 times the array loop's time and ran 2.3-2.5, 1.3-2.0 and 1.7-1.8
#: times as fast (docs/performance.md, twenty-third round). Every shipped scene's
#: force is within the bound (the largest, network-web's 5 planar springs, 54
#: lines).
MAX_UNROLLED_FORCE_LINES = 128

_HERE = pathlib.Path(__file__).resolve().parent
_KERNELS: dict[tuple, object] = {}


def _digest(*parts: bytes) -> str:
    h = hashlib.sha256()
    for p in parts:
        h.update(p)
    return h.hexdigest()[:16]


def _dependencies_digest() -> str:
    return _digest((_HERE / "_kernels.py").read_bytes(), pathlib.Path(__file__).read_bytes())


def _coefficients(tab: Tableau):
    A = np.asarray(tab.A, dtype=float)
    b = np.asarray(tab.b, dtype=float)
    A_v = np.asarray(tab.A_v if tab.partitioned else tab.A, dtype=float)
    b_v = np.asarray(tab.b_v if tab.partitioned else tab.b, dtype=float)
    return A, b, A_v, b_v


def _cache_key(tab: Tableau) -> tuple:
    """What a generated loop depends on: the coefficients (float64), the nodes
    (they decide the start stage and FSAL) and whether the method is partitioned."""
    A, b, A_v, b_v = _coefficients(tab)
    c = np.asarray(tab.c, dtype=float)
    return (A.tobytes(), A.shape, b.tobytes(), A_v.tobytes(), b_v.tobytes(), c.tobytes(), tab.partitioned)


class _Plan:
    """How one step of ``tab`` runs, read from the tableau's data (the same
    reading as ``rk4h.rk_step``): which stages call the force
    (``evaluate[i]``; a FSAL method's stage ``i0`` takes the previous step's
    stage ``i_last`` instead), which form their velocity first
    (``v_first[i]``: ``A_v[i][i] == 0``), where the dense-output slopes come
    from."""

    def __init__(self, tab: Tableau):
        self.A, self.b, self.A_v, self.b_v = _coefficients(tab)
        self.ns = self.b.shape[0]
        self.partitioned = tab.partitioned
        self.fsal = tab.fsal_stages  # (i0, i_last) or None
        self.start = tab.start_stage
        reused = self.fsal[0] if self.fsal else -1
        self.evaluate = [bool(e) and i != reused for i, e in enumerate(tab.stage_evaluated)]
        self.v_first = [self.A_v[i, i] == 0.0 for i in range(self.ns)]

    def q_row(self, i) -> tuple:
        """Position sum of stage ``i`` as ``((j, a_ij, product name), ...)``
        over the nonzero ``a_ij``, ``j <= i`` (``j < i`` when the position
        comes first)."""
        upto = i + 1 if self.v_first[i] else i
        return tuple((j, float(self.A[i, j]), f"hq_{i}_{j}") for j in range(upto) if self.A[i, j] != 0.0)

    def v_row(self, i, diagonal=False) -> tuple:
        """Velocity sum of stage ``i`` (as :meth:`q_row`): ``j < i``, and
        ``j = i`` too when ``diagonal``."""
        upto = i + 1 if diagonal else i
        return tuple((j, float(self.A_v[i, j]), f"hv_{i}_{j}") for j in range(upto) if self.A_v[i, j] != 0.0)

    def new_row(self, half: str) -> tuple:
        """The new state's sum of ``half`` (``"q"``: weights ``b``, ``"v"``:
        ``b_v``) as :meth:`q_row`."""
        bh = self.b if half == "q" else self.b_v
        return tuple((j, float(bh[j]), f"h{half}b_{j}") for j in range(self.ns) if bh[j] != 0.0)

    def coefficients(self, used=None) -> list:
        """``(product name, coefficient)`` for every nonzero ``a_ij`` and
        ``b_i`` of both halves (only the names in ``used`` when given): the
        products ``h a_ij``, ``h b_i`` a loop forms once, before its steps."""
        out = []
        for half, (Ah, bh) in (("q", (self.A, self.b)), ("v", (self.A_v, self.b_v))):
            for i in range(self.ns):
                for j in range(i + 1):
                    if Ah[i, j] != 0.0:
                        out.append((f"h{half}_{i}_{j}", float(Ah[i, j])))
                if bh[i] != 0.0:
                    out.append((f"h{half}b_{i}", float(bh[i])))
        return out if used is None else [(name, c) for name, c in out if name in used]

    def products(self, indent, used=None):
        """The lines forming :meth:`coefficients`' products (``step *
        coefficient``, as the generic path forms them)."""
        return [f"{indent}{name} = step * {c!r}" for name, c in self.coefficients(used)]


class _Held:
    """The sums a step's stage state holds while the step is written out, so
    that a sum beginning with the held one is written as the held value plus
    its new terms.

    ``y + c0 k0 + c1 k1 + c2 k2`` is added left to right: after ``c1 k1`` the
    running value is the double ``y + c0 k0 + c1 k1``, which a held sum with
    the same slopes and coefficients in the same order is. Adding ``c2 k2``
    to the held value performs the same roundings as the whole sum, so the
    result is the same double. A splitting method's stage ``i`` is stage
    ``i - 1`` plus one drift (``A[i][j] = a_j``; HLW sec. III.2.2), so its
    loop adds one term per stage instead of ``i``, and its new position is
    its last stage's. ``half``: ``"q"``, ``"v"`` (the state's halves), or
    ``"all"`` (a classical method's array loop, one pass over both).
    """

    def __init__(self):
        self._rows: dict[str, tuple] = {}

    def split(self, half: str, row: tuple) -> tuple:
        """``(True, the terms after the held ones)`` when ``half`` holds a
        nonempty sum that ``row`` begins with (the same slopes and
        coefficients, in order), else ``(False, row)``."""
        held = self._rows.get(half, ())
        n = len(held)
        if n and len(row) >= n and [t[:2] for t in row[:n]] == [t[:2] for t in held]:
            return True, row[n:]
        return False, row

    def hold(self, half: str, row: tuple) -> None:
        """The stage state's ``half`` now holds the sum ``row``."""
        self._rows[half] = row


def _sum_text(held, half: str, row: tuple, base: str, here: str, k) -> str | None:
    """The sum ``row`` from the state ``base``, or from ``here`` (the stage
    state's element) when it holds a sum ``row`` extends (``held``: a
    :class:`_Held`, or None); None when ``here`` holds ``row`` already.
    ``k(j)`` names slope ``j``."""
    extends, rest = held.split(half, row) if held is not None else (False, row)
    if extends and not rest:
        return None
    return _combination(here if extends else base, [(name, k(j)) for j, _, name in rest])


def _used_products(lines) -> set:
    """The product names (``hq_i_j``, ``hvb_j``...) the lines use."""
    return set(re.findall(r"\bh(?:q|v)b?_[0-9_]+\b", "\n".join(lines)))


def _combination(base, terms):
    """``base + c0 * k0 + c1 * k1 ...`` (left to right, as ``rk_step``)."""
    return " + ".join([base] + [f"{c} * {k}" for c, k in terms])


_HEADER = [
    "import math",
    "import numpy as np",
    "from numba import njit",
    "",
    "from rk4h.fast import _kernels as K",
    "",
]


def _rhs_lines(kern) -> list:
    """The kernel's ``force`` and ``slope`` and the ``rhs(fp, ip, mass, y,
    out, r, n, w)`` wrapper (``out[r] = dy/dt``), as every generated module
    holding an array form starts. The slope and the wrapper are inlined at
    numba's level (a chain's fused slope must be, for speed); the force is a
    call (inlining it at every stage multiplied a network's compile time),
    and so is a slope whose kernel says ``inline_slope = False`` (a
    network's, which holds its force: one call per stage, none per spring)."""
    return [
        "",
        "@njit(error_model=\"numpy\")",
        kern.array_source(),
        "",
        "@njit(inline=\"always\", error_model=\"numpy\")" if getattr(kern, "inline_slope", True)
        else "@njit(error_model=\"numpy\")",
        kern.slope_source(),
        "",
        "@njit(inline=\"always\", error_model=\"numpy\")",
        "def rhs(fp, ip, mass, y, out, r, n, w):",
        "    slope(fp, ip, mass, y, out[r], w)",
        "",
        "",
    ]


def model_source(kern) -> str:
    """Python source of the compiled right-hand sides of one force kernel
    (:class:`rk4h.models.compiled.ForceKernel`):

    * ``force(fp, ip, q, f, w)``: the kernel's own text (``F(q)`` into ``f``);
    * ``rhs(fp, ip, mass, y, out, r, n, w)``: ``out[r] = dy/dt`` (``q' = v``,
      ``v' = F(q) / mass``, as ``Model.rhs``);
    * ``rhs_permuted(fp, ip, mass, z, zp, perm, buf, w)``: ``zp = (dy/dt)[perm]``
      at ``y[perm] = z``, and whether it is non-finite at a finite state --
      the one entry point of the references' right-hand sides
      (:class:`rk4h.fast.CompiledRHS`; DOP853 passes the identity).

    The loops are :func:`source` (straight-line) and :func:`array_source`.
    """
    L = [f"# Generated by rk4h.fast.codegen from a model's definition; do not edit.",
         f"# depends on: {_dependencies_digest()}"] + _HEADER + _rhs_lines(kern) + [
        "@njit(error_model=\"numpy\")",
        "def rhs_permuted(fp, ip, mass, z, zp, perm, buf, w):",
        "    # zp = dy/dt in the order z = y[perm] (buf: 3 rows of scratch); returns",
        "    # whether dy/dt is non-finite at a finite state",
        "    n2 = z.shape[0]",
        "    finite_in = True",
        "    for i in range(n2):",
        "        buf[0, perm[i]] = z[i]",
        "        finite_in = finite_in and math.isfinite(z[i])",
        "    rhs(fp, ip, mass, buf[0], buf, 1, n2 // 2, w)",
        "    finite_out = True",
        "    for i in range(n2):",
        "        zp[i] = buf[1, perm[i]]",
        "        finite_out = finite_out and math.isfinite(zp[i])",
        "    return finite_in and not finite_out",
        "",
    ]
    return "\n".join(L)


def source(tab: Tableau, kern) -> str:
    """Python source of the straight-line loop for method ``tab`` and force
    kernel ``kern`` (one with :meth:`scalar_lines`): same arguments and
    returns as :func:`array_source`'s ``integrate`` without the work array.
    The force is the kernel's straight-line code on the stage's scalar locals
    (no call, no buffer). Locals: ``y{p}`` state, ``s{p}``
    stage state, ``k{i}_{p}`` stage slopes, ``n{p}`` new state, ``m{p}`` the
    masses; the kernel's own start with ``_F``. A FSAL method evaluates its
    first stage once before the loop and carries its last stage's force
    into the next step."""
    nq = kern.n_dof
    dim = 2 * nq
    plan = _Plan(tab)
    hoisted, _ = kern.scalar_lines([f"s{p}" for p in range(nq)], [f"_Fo{p}" for p in range(nq)])
    L = [
        # no method name: two methods with equal coefficients share one file (one compile)
        f"# Generated by rk4h.fast.codegen: a straight-line loop, dim {dim}; do not edit.",
        f"# depends on: {_dependencies_digest()}",
    ] + _HEADER + [
        "",
        # nogil: the loop touches no Python object, so runs may go side by side in threads
        "@njit(error_model=\"numpy\", nogil=True)  # on-disk caching is switched on by codegen.kernel",
        "def integrate(fp, ip, mass, y_start, t0, step, n, idx, theta, ys, bound, pending, y_fail):",
    ]
    L += [f"    y{p} = y_start[{p}]" for p in range(dim)]
    L += [f"    b{p} = bound[{p}]" for p in range(dim)]
    L += [f"    m{p} = mass[{p}]" for p in range(nq)]
    L += ["    " + line for line in hoisted]
    loop = ["    " + line for line in _loop(plan, kern, dim)]
    # h a_ij and h b_i as the generic path forms them (step * coefficient).
    L += plan.products("    ", _used_products(loop))
    if plan.fsal:  # the first step's evaluation of the reused stage, at y_start
        i0 = plan.fsal[0]
        L += ["    " + line for line in _force(kern, [f"y{p}" for p in range(nq)])]
        L += [f"    k{i0}_{nq + p} = _Fo{p} / m{p}" for p in range(nq)]
    L += [
        "    m_out = idx.shape[0]",
        "    n_extra = 0",
        "    ptr = 0",
        "    while ptr < m_out and idx[ptr] == 0 and theta[ptr] == 0.0:",
    ]
    L += [f"        ys[ptr, {p}] = y{p}" for p in range(dim)]
    L += ["        ptr += 1"]
    L += loop
    L += ["    return n, ptr, K.STATUS_OK, n_extra", ""]
    return "\n".join(L)


def step_lines(plan: _Plan, kern, dim) -> list:
    """Lines of one step, indented by four spaces: the stages ``s*`` and
    slopes ``k{i}_*`` from the state ``y0 .. y{dim-1}``, masses ``m*`` and the
    products of :meth:`_Plan.products`, then the new state ``n0 ..
    n{dim-1}``; each evaluated stage runs the force kernel's straight-line
    code, and a sum that extends the one the stage state holds starts from
    it (:class:`_Held`). The numba loops (:func:`source`) and the jax backend
    (``rk4h.batch._jax``) print their step from this one text, so the two
    dialects do the same arithmetic in the same order."""
    ns, nq = plan.ns, dim // 2
    held = _Held()
    L = []

    def component(half, row, name_of, p):
        # component p of the sum `row` (None: the stage state holds it already)
        return _sum_text(held, half, row, name_of("y", p), name_of("s", p), lambda j: name_of(f"k{j}_", p))

    def half_sum(half, row, name_of):
        # "s{p} = ..." for each component of the half, unless it holds `row` already
        out = []
        for p in range(nq):
            e = component(half, row, name_of, p)
            if e is not None:
                out.append(f"    {name_of('s', p)} = {e}")
        held.hold(half, row)
        return out

    def q_name(prefix, p):
        return f"{prefix}{p}"

    def v_name(prefix, p):
        return f"{prefix}{nq + p}"

    for i in range(ns):
        L.append(f"    # stage {i}")
        force = ["    " + line for line in _force(kern, [f"s{p}" for p in range(nq)])]
        force += [f"    k{i}_{nq + p} = _Fo{p} / m{p}" for p in range(nq)]
        if plan.v_first[i]:  # V_i from earlier accelerations, then Q_i (which may use V_i)
            L += half_sum("v", plan.v_row(i), v_name)
            # q' = v is the stage's own velocity; v' = F / m.
            L += [f"    k{i}_{p} = s{nq + p}" for p in range(nq)]
            if plan.evaluate[i]:
                L += half_sum("q", plan.q_row(i), q_name)
                L += force
        else:  # Q_i first, its acceleration, then V_i with it
            L += half_sum("q", plan.q_row(i), q_name)
            if plan.evaluate[i]:
                L += force
            L += half_sum("v", plan.v_row(i, diagonal=True), v_name)
            L += [f"    k{i}_{p} = s{nq + p}" for p in range(nq)]
    L.append("    # new state")
    for half, name_of in (("q", q_name), ("v", v_name)):
        row = plan.new_row(half)
        for p in range(nq):
            e = component(half, row, name_of, p)
            L.append(f"    {name_of('n', p)} = {name_of('s', p) if e is None else e}")
    return L


def _loop(plan: _Plan, kern, dim):
    """Lines of the step loop (indented from 0): :func:`step_lines`, the
    instability test and the output points."""
    nq = dim // 2
    L = ["for i in range(n):"] + step_lines(plan, kern, dim)
    # The instability test of rk4h.solve: NOT(|y_p| <= b_p) for some p
    # (also true for inf and NaN, b_p being finite); while `pending`, the
    # first non-zero state sets the bounds.
    L += ["    if not (" + " and ".join(f"abs(n{p}) <= b{p}" for p in range(dim)) + "):"]
    L += [f"        y_fail[{p}] = n{p}" for p in range(dim)]
    L += [
        "        return i, ptr, K.STATUS_UNSTABLE, n_extra",
        "    if pending > 0.0:",
        "        norm = 0.0",
    ]
    L += [f"        norm = max(norm, abs(n{p}))" for p in range(dim)]
    L += [
        "        if norm > 0.0:",
        "            bnd = min(pending * norm, K.DBL_MAX)",
    ]
    L += [f"            b{p} = bnd" for p in range(dim)]
    L += [f"            bound[{p}] = bnd" for p in range(dim)]
    L += [
        "            pending = 0.0",
        # Output points, in order: inside the step (cubic Hermite between the
        # old and the new state, start slope d and end slope e: from the
        # stages when the method has them, else one force call each per such
        # step), then at its end.
        "    if ptr < m_out and idx[ptr] <= i + 1:",
        "        if idx[ptr] == i:",
    ]
    if plan.start is None:
        L += ["            " + line for line in _force(kern, [f"y{p}" for p in range(nq)])]
        L += [f"            d{nq + p} = _Fo{p} / m{p}" for p in range(nq)] + ["            n_extra += 1"]
        start = [f"y{nq + p}" for p in range(nq)] + [f"d{nq + p}" for p in range(nq)]
    else:
        start = [f"y{nq + p}" for p in range(nq)] + [f"k{plan.start}_{nq + p}" for p in range(nq)]
    L += [f"            e{p} = n{nq + p}" for p in range(nq)]
    if plan.fsal:  # the last stage was evaluated at the new state
        L += [f"            e{nq + p} = k{plan.fsal[1]}_{nq + p}" for p in range(nq)]
    else:
        L += ["            " + line for line in _force(kern, [f"n{p}" for p in range(nq)])]
        L += [f"            e{nq + p} = _Fo{p} / m{p}" for p in range(nq)] + ["            n_extra += 1"]
    L += [
        "            while ptr < m_out and idx[ptr] == i and theta[ptr] > 0.0:",
        "                w00, w10, w01, w11 = K.hermite_weights(theta[ptr], step)",
    ]
    L += [f"                ys[ptr, {p}] = w00 * y{p} + w10 * {start[p]} + w01 * n{p} + w11 * e{p}"
          for p in range(dim)]
    L += [
        "                ptr += 1",
        "        while ptr < m_out and idx[ptr] == i + 1 and theta[ptr] == 0.0:",
    ]
    L += [f"            ys[ptr, {p}] = n{p}" for p in range(dim)]
    L += ["            ptr += 1"]
    if plan.fsal:  # first same as last: the next step's stage i0 is this step's stage i_last
        L += [f"    k{plan.fsal[0]}_{nq + p} = k{plan.fsal[1]}_{nq + p}" for p in range(nq)]
    L += [f"    y{p} = n{p}" for p in range(dim)]
    return L


def array_source(tab: Tableau, kern) -> str:
    """Python source of the array loop for method ``tab`` and force kernel
    ``kern`` (any size): the tableau written out as in :func:`source` --
    ``h a_ij``, ``h b_i`` formed once, zero coefficients dropped, the
    additions in ``rk_step``'s order, the same stages evaluated and reused --
    but over arrays: one fused pass per stage (a classical method's position
    and velocity halves together) and one for the new state (with the
    instability test), the state arrays swapped instead of copied:
    ``integrate(fp, ip, mass, w, y0, t0, step, n, idx, theta, ys, bound,
    pending, y_fail) -> (n_done, n_out, status, n_extra)``; the same numbers
    as :func:`source` bit for bit."""
    plan = _Plan(tab)
    held = _Held()
    body = []
    for i in range(plan.ns):
        body += _array_stage(plan, i, held)
    body += _array_new_state(plan, held)
    L = _array_head(plan, kern, _used_products(body)) + body
    # Dense-output slopes: from the stages when the method has them.
    pad = "                    "
    copy, start_array = _start_slope(plan)
    if copy is None:
        start = [pad + "rhs(fp, ip, mass, y, f0, 0, nq, w)", pad + "n_extra += 1"]
    else:
        start = [pad + line for line in copy]
    if not plan.fsal:
        end = [pad + "rhs(fp, ip, mass, y_new, f1, 0, nq, w)", pad + "n_extra += 1"]
    else:
        end = [pad + line for line in _slope_copy(plan, plan.fsal[1], "y_new", "f1")]
    return "\n".join(L + _ARRAY_STEP_END + start + end + _array_output_rest(start_array) + _array_close(plan))


def _start_slope(plan: _Plan) -> tuple:
    """``(lines, array)`` for the slope at a step's start: ``(None, "f0")``
    where no stage holds it (one force call fills ``f0``), ``([], "k")`` where
    a classical method's first stage is it (read in place), else the lines
    copying it into ``f0`` (:func:`_slope_copy`) and ``"f0"``."""
    if plan.start is None:
        return None, "f0"
    if not plan.partitioned and plan.start == 0:
        return [], "k"
    return _slope_copy(plan, plan.start, "y", "f0"), "f0"


def _slope_copy(plan: _Plan, row: int, state: str, arr: str) -> list:
    """Lines (not indented) copying the slope at one end of a step, stage
    ``row``'s, into the dense output's ``arr`` (``f0`` or ``f1``): a classical
    method's whole slope; a partitioned one's velocity half from the state
    ``state`` at that end (``q' = v``) and its acceleration from the stage."""
    if not plan.partitioned:
        return ["for p in range(dim):", f"    {arr}[0, p] = k[{row}, p]"]
    return ["for p in range(nq):", f"    {arr}[0, p] = {state}[nq + p]", f"    {arr}[0, nq + p] = k[{row}, nq + p]"]


# The array loop in pieces, which benchmarks/_loop_variants.py builds its
# variants of this loop from (each returns lines of the loop's text).

#: Before the steps: write the output points at t0, then the step loop's head.
_ARRAY_OUTPUT_START = [
    "    m_out = idx.shape[0]",
    "    ptr = 0",
    "    n_extra = 0",
    "    while ptr < m_out and idx[ptr] == 0 and theta[ptr] == 0.0:",
    "        for p in range(dim):",
    "            ys[ptr, p] = y[p]",
    "        ptr += 1",
    "    for i in range(n):",
]

#: After a step's new state, to the dense output's slopes: the instability
#: test's exit, the growth bound's first scale, the output loop's head.
_ARRAY_STEP_END = [
    "        if not accept:",
    "            for p in range(dim):",
    "                y_fail[p] = y_new[p]",
    "            return i, ptr, K.STATUS_UNSTABLE, n_extra",
    "        if pending > 0.0:",
    "            norm = 0.0",
    "            for p in range(dim):",
    "                norm = max(norm, abs(y_new[p]))",
    "            if norm > 0.0:  # the first non-zero state sets the scale",
    "                bnd = min(pending * norm, K.DBL_MAX)",
    "                for p in range(dim):",
    "                    bound[p] = bnd",
    "                pending = 0.0",
    "        have_f1 = False",
    "        while ptr < m_out:",
    "            if idx[ptr] == i and theta[ptr] > 0.0:",
    "                if not have_f1:  # the slopes at both ends, once per step",
]


def _array_head(plan: _Plan, kern, used=None) -> list:
    """The array loop's text up to the head of its step loop: the force, the
    signature, the work arrays, the products (those in ``used`` when given),
    a FSAL method's first evaluation and the output points at t0."""
    L = [
        "# Generated by rk4h.fast.codegen: an array loop; do not edit.",
        f"# depends on: {_dependencies_digest()}",
    ] + _HEADER + _rhs_lines(kern) + [
        "@njit(error_model=\"numpy\", nogil=True)",
        "def integrate(fp, ip, mass, w, y_start, t0, step, n, idx, theta, ys, bound, pending, y_fail):",
        "    dim = y_start.shape[0]",
        "    nq = dim // 2",
        f"    k = np.empty(({plan.ns}, dim))",
        "    yi = np.empty(dim)",
        "    f0 = np.empty((1, dim))",
        "    f1 = np.empty((1, dim))",
        "    y = y_start.copy()",
        "    y_new = np.empty(dim)",
    ]
    L += plan.products("    ", used)
    if plan.fsal:  # the first step's evaluation of the reused stage, at y_start
        L.append(f"    rhs(fp, ip, mass, y, k, {plan.fsal[0]}, nq, w)")
    return L + _ARRAY_OUTPUT_START


def _array_slope(j) -> str:
    """Component ``p`` of slope ``j`` in the array loop's text."""
    return f"k[{j}, p]"


def _array_new_state(plan: _Plan, held=None) -> list:
    """The new state ``y + h sum b_i k_i`` with the instability test (from
    the stage state where it holds a sum the new one extends: ``held``, a
    :class:`_Held` or None)."""
    L = ["        accept = True"]
    # The instability test NOT(|y_p| <= bound_p) folded into the same pass,
    # without a short circuit (no branch in the loop).
    if not plan.partitioned:
        halves = [("0", "dim", "all", plan.new_row("q"))]
    else:
        halves = [("0", "nq", "q", plan.new_row("q")), ("nq", "dim", "v", plan.new_row("v"))]
    for lo, hi, half, row in halves:
        e = _sum_text(held, half, row, "y[p]", "yi[p]", _array_slope)
        L += [f"        for p in range({lo}, {hi}):",
              f"            v = {'yi[p]' if e is None else e}",
              "            y_new[p] = v",
              "            accept &= abs(v) <= bound[p]"]
    return L


def _array_output_rest(start_array: str) -> list:
    """The output loop after the dense output's slopes (``start_array``: the
    array holding the start slope)."""
    return [
        "                    have_f1 = True",
        f"                K._hermite(ys, ptr, theta[ptr], y, y_new, {start_array}, step, f1)",
        "            elif idx[ptr] == i + 1 and theta[ptr] == 0.0:",
        "                for p in range(dim):",
        "                    ys[ptr, p] = y_new[p]",
        "            else:",
        "                break",
        "            ptr += 1",
    ]


def _array_close(plan: _Plan) -> list:
    """The step's end (a FSAL method's carried slope, the swap) and the return."""
    L = []
    if plan.fsal:  # first same as last: the next step's stage i0 is this step's stage i_last
        i0, i1 = plan.fsal
        lo = "0" if not plan.partitioned else "nq"
        L += [f"        for p in range({lo}, dim):", f"            k[{i0}, p] = k[{i1}, p]"]
    return L + [
        "        y, y_new = y_new, y",
        "    return n, ptr, K.STATUS_OK, n_extra",
        "",
    ]


def _array_stage(plan: _Plan, i: int, held=None) -> list:
    """Lines (indented for the step loop) of stage ``i`` of the array loop."""
    before, ev, src, after = _array_stage_parts(plan, i, "        ", held)
    return before + ([f"        rhs(fp, ip, mass, {src}, k, {i}, nq, w)"] if ev else []) + after


def _array_stage_parts(plan: _Plan, i: int, pad: str, held=None) -> tuple:
    """Stage ``i`` of the array loop around its force call: ``(lines before
    the call, whether the stage calls the force, the state it calls it at,
    lines after the call)``, the lines indented by ``pad``. ``held`` (a
    :class:`_Held`, or None: every sum from the state) follows the stage
    state ``yi`` from stage to stage of one step, in order."""
    ev = plan.evaluate[i]

    def half_sum(half, lo, hi, row):
        e = _sum_text(held, half, row, "y[p]", "yi[p]", _array_slope)
        if held is not None:
            held.hold(half, row)
        return [] if e is None else [pad + f"for p in range({lo}, {hi}):", pad + f"    yi[p] = {e}"]

    if not plan.partitioned:  # a classical method: one pass over the whole state
        if not ev:  # the reused first stage
            return [], False, "y", []
        row = tuple(t for t in plan.q_row(i) if t[0] < i)
        if not row:  # the stage state is the state itself
            return [], True, "y", []
        return half_sum("all", "0", "dim", row), True, "yi", []
    tq, tv = plan.q_row(i), plan.v_row(i)
    if plan.v_first[i]:  # V_i from earlier accelerations, then Q_i (which may use V_i)
        if ev and not tq and not tv:  # the stage state is the state itself
            return [], True, "y", []
        L = half_sum("v", "nq", "dim", tv)
        if plan.A[i, i] != 0.0 or not ev:  # q' = v: the stage's velocity (rhs writes it when called)
            L += [pad + "for p in range(nq):", pad + f"    k[{i}, p] = yi[nq + p]"]
        if ev:
            L += half_sum("q", "0", "nq", tq)
        return L, ev, "yi", []
    # Q_i first, its acceleration, then V_i with it
    L = half_sum("q", "0", "nq", tq) + half_sum("v", "nq", "dim", tv)
    after = half_sum("v", "nq", "dim", plan.v_row(i, diagonal=True))
    after += [pad + "for p in range(nq):", pad + f"    k[{i}, p] = yi[nq + p]"]
    return L, ev, "yi", after


def array_kernel(tab: Tableau, kern):
    """The array loop of :func:`array_source` for ``(tab, kern)``, loaded as
    :func:`kernel` loads a straight-line loop."""
    key = loop_key(tab, kern, True)
    fn = _KERNELS.get(key)
    if fn is None:
        fn = _KERNELS[key] = _module(array_source(tab, kern)).integrate
    return fn


def _force(kern, q):
    """The kernel's straight-line force at the locals ``q`` into ``_Fo{p}``."""
    return kern.scalar_lines(q, [f"_Fo{p}" for p in range(len(q))])[1]


class CacheWarning(UserWarning):
    """The private cache directory could not be verified (the loops are
    compiled in memory), or a generated file in it had been altered (it was
    rewritten). One line, naming the path and the reason."""


def module_name(text: str) -> str:
    """Name (and file stem) of the module holding generated source ``text``."""
    return f"_rk4core_fast_gen_{_digest(text.encode())}"


def _cache_dirs():
    """``(source dir, numba cache dir)``: ``rk4h.cachedir.private_dir("fast")``
    and its ``__pycache__``, both verified private (raises
    :class:`~rk4h.cachedir.UntrustedCacheError` otherwise)."""
    d = private_dir("fast")
    return d, private_dir("fast", "__pycache__")


def _file_problem(path: pathlib.Path, data: bytes) -> str | None:
    """Why the file at ``path`` cannot be trusted to hold ``data`` (None: it can).

    Trusted: a regular file (not followed if a symbolic link), owned by the
    current user, not writable by group or others, with exactly ``data`` as
    content. Read through one descriptor opened with ``O_NOFOLLOW``."""
    flags = os.O_RDONLY | getattr(os, "O_NOFOLLOW", 0) | getattr(os, "O_NONBLOCK", 0)
    try:
        fd = os.open(path, flags)
    except FileNotFoundError:
        return "missing"
    except OSError as e:  # ELOOP: a symbolic link
        return f"cannot be opened safely ({e.strerror})"
    try:
        st = os.fstat(fd)
        if not stat.S_ISREG(st.st_mode):
            return "is not a regular file"
        uid = os.getuid() if hasattr(os, "getuid") else st.st_uid
        if st.st_uid != uid:
            return f"is owned by uid {st.st_uid}, not by you (uid {uid})"
        if st.st_mode & 0o022:
            return f"is writable by group or others (mode {stat.S_IMODE(st.st_mode):04o})"
        chunks, size = [], 0
        while size <= len(data):
            chunk = os.read(fd, 1 << 16)
            if not chunk:
                break
            chunks.append(chunk)
            size += len(chunk)
        if b"".join(chunks) != data:
            return "differs from the source rk4core generates"
        return None
    finally:
        os.close(fd)


def _write_atomically(path: pathlib.Path, data: bytes) -> None:
    """Write ``data`` to ``path`` (mode 0600) through a new temporary file in
    the same directory, fsynced, then renamed over ``path`` (a symbolic link
    or foreign file there is replaced, not followed)."""
    tmp = path.with_name(f".{path.name}.{os.getpid()}.{secrets.token_hex(4)}.tmp")
    fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_NOFOLLOW", 0), 0o600)
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise
    with contextlib.suppress(OSError):  # make the rename durable
        dfd = os.open(path.parent, os.O_RDONLY)
        try:
            os.fsync(dfd)
        finally:
            os.close(dfd)


def _private_cache_class(cache_dir: str):
    """A numba ``FunctionCache`` that keeps its index and data files in
    ``cache_dir`` whatever ``NUMBA_CACHE_DIR`` or
    ``NUMBA_CACHE_LOCATOR_CLASSES`` say, keyed on the source file's content
    as numba's own locators are."""
    from numba.core import caching

    class Locator(caching._SourceFileBackedLocatorMixin, caching._CacheLocator):
        def __init__(self, py_func, py_file):
            self._py_file = py_file
            self._lineno = py_func.__code__.co_firstlineno

        def get_cache_path(self):
            return cache_dir

    class Impl(caching.CompileResultCacheImpl):
        def __init__(self, py_func):  # numba's, with the locator fixed
            self._lineno = py_func.__code__.co_firstlineno
            source_path = inspect.getfile(py_func)
            self._locator = Locator(py_func, source_path)
            modname = os.path.splitext(os.path.basename(source_path))[0]
            self._filename_base = self.get_filename_base(f"{modname}.{py_func.__qualname__}",
                                                         getattr(sys, "abiflags", ""))

    class Cache(caching.FunctionCache):
        _impl_class = Impl

    return Cache


def _exec_module(name: str, text: str, filename: str):
    """A fresh module ``name`` (registered in ``sys.modules``: numba looks a
    cached function's module up by name) holding ``text`` compiled as if read
    from ``filename``. The text executed is ours, never the file's."""
    module = types.ModuleType(name)
    module.__file__ = filename
    sys.modules[name] = module
    try:
        exec(compile(text, filename, "exec"), module.__dict__)
    except BaseException:
        sys.modules.pop(name, None)
        raise
    return module


def _in_memory(name: str, text: str):
    """The module of ``text`` compiled from memory (numba's cache off)."""
    filename = f"<rk4h.fast generated {name}>"
    linecache.cache[filename] = (len(text), None, text.splitlines(True), filename)
    return _exec_module(name, text, filename)


def _load(name: str, text: str):
    """The module of generated ``text``: from the verified private cache
    directory, with numba's on-disk cache beside it, or compiled in memory
    (no on-disk cache) when the directory cannot be verified."""
    data = text.encode()
    root = "(unknown)"
    try:
        root = cachedir.cache_root()
        src_dir, numba_dir = _cache_dirs()
    except (UntrustedCacheError, OSError, ValueError, RuntimeError) as e:  # RuntimeError: no home directory
        warnings.warn(f"rk4h.fast: not using cache directory {root}: {e}; "
                      f"the generated loop is compiled in memory, without an on-disk cache",
                      CacheWarning, stacklevel=4)
        return _in_memory(name, text)
    path = src_dir / f"{name}.py"
    problem = _file_problem(path, data)
    if problem is not None:
        try:
            _write_atomically(path, data)
        except OSError as e:
            warnings.warn(f"rk4h.fast: generated file {path} {problem} and cannot be rewritten "
                          f"({e.strerror or e}); the loop is compiled in memory, without an on-disk cache",
                          CacheWarning, stacklevel=4)
            return _in_memory(name, text)
        if problem != "missing":
            warnings.warn(f"rk4h.fast: generated file {path} {problem}; it is not trusted and was "
                          f"rewritten with the generated source", CacheWarning, stacklevel=4)
    module = _exec_module(name, text, str(path))
    try:
        for fn in vars(module).values():
            if hasattr(fn, "py_func") and getattr(fn.py_func, "__module__", None) == name:
                fn._cache = _private_cache_class(str(numba_dir))(fn.py_func)
    except (AttributeError, ImportError, TypeError) as e:  # numba's caching internals changed
        warnings.warn(f"rk4h.fast: cannot pin numba's cache to {numba_dir} ({type(e).__name__}: {e}); "
                      f"the generated loop is compiled without an on-disk cache", CacheWarning, stacklevel=4)
    return module


def _module(text: str):
    name = module_name(text)
    module = sys.modules.get(name)
    if module is None:
        module = _load(name, text)
    return module


def load_generated(text: str):
    """The module of generated source ``text`` (a loop's text with more
    generated functions after it), loaded as :func:`kernel` loads a loop:
    from the verified private cache directory, numba's on-disk cache of every
    function in it beside it."""
    return _module(text)


def array_loop(kern, dim: int) -> bool:
    """Whether a state of ``dim`` components on force kernel ``kern`` runs the
    array loop (:func:`array_kernel`) rather than the straight-line one
    (:func:`kernel`): above :data:`MAX_UNROLLED_DIM`, where the kernel has
    no straight-line form, or where that form is longer than
    :data:`MAX_UNROLLED_FORCE_LINES`. :func:`rk4h.fast.solve_model`, the
    ensemble's batch and the warm-up before a multi-worker run all choose by
    it."""
    return not (dim <= MAX_UNROLLED_DIM and kern.has_scalar() and kern.scalar_size() <= MAX_UNROLLED_FORCE_LINES)


def loop_key(tab: Tableau, kern, array: bool) -> tuple:
    """The key of :func:`kernel` (``array`` False) or :func:`array_kernel`
    (True) for ``(tab, kern)``: equal keys, equal generated text."""
    if array:
        return ("array",) + _cache_key(tab) + (kern.key(),)
    return ("loop",) + _cache_key(tab) + (kern.n_dof, kern.key(), kern.scalar_key())


def kernel(tab: Tableau, kern):
    """The straight-line loop for method ``tab`` and force kernel ``kern``
    (:func:`source`): generated on first use in a process, then kept (numba
    compiles it on its first call, or loads it from the on-disk cache).

    The source lives in ``rk4h.cachedir.private_dir("fast")`` (a per-user
    directory verified to be a real directory owned by the user with mode
    0700) and numba's cache of it in that directory's ``__pycache__``,
    whatever ``NUMBA_CACHE_DIR`` says. The code executed is always the text
    generated here: an existing file is only used (for numba's cache
    freshness) after checking that it is a regular file owned by the user,
    not writable by group or others, with exactly that text; otherwise it is
    rewritten atomically and a :class:`CacheWarning` says so. If the
    directory cannot be verified, the loop is compiled in memory (no on-disk
    cache; one :class:`CacheWarning` names the directory and why)."""
    key = loop_key(tab, kern, False)
    fn = _KERNELS.get(key)
    if fn is None:
        fn = _KERNELS[key] = _module(source(tab, kern)).integrate
    return fn


def model_module(kern):
    """The module of :func:`model_source` for force kernel ``kern`` (its
    right-hand sides), loaded as :func:`kernel` loads a
    loop."""
    key = ("model", kern.key())
    module = _KERNELS.get(key)
    if module is None:
        module = _KERNELS[key] = _module(model_source(kern))
    return module


def compiled_kernels() -> int:
    """Number of generated loops loaded in this process (one per method and
    state size used)."""
    return len(_KERNELS)
