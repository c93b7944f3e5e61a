"""The compiled form of a model's force, printed from its symbolic definition.

A model's one definition (:mod:`rk4h.expr` expressions: the potential of a
:class:`~rk4h.models.PotentialModel`, or the one spring-energy template of
:mod:`rk4h.models.network` applied over an edge list) is turned here into
the source text of scalar code that numba compiles (:mod:`rk4h.fast`): the
fixed-step loops and the right-hand side the references call. Nothing in it is
written per model: the text is printed from the same expression trees the
numpy right-hand side (:func:`rk4h.expr.lambdify`) and heyoka's equations
(:func:`rk4h.expr.to_heyoka`) are printed from, with the operations in the
same order as the numpy path, so both give the same numbers (bit for bit where
the elementary functions agree).

A kernel is two things:

* ``fp``, ``ip`` -- float and integer parameter arrays (the numbers of the
  definition: coefficients, stiffnesses, positions, the edge list);
* text depending only on the definition's *structure*, so one compiled loop
  serves every parameter set of that structure (a 2-mass chain of any
  masses and springs, any Henon-Heiles coupling):

  - :meth:`ForceKernel.array_source`: ``def force(fp, ip, q, f, w)`` writing
    ``F(q)`` into ``f[:n_dof]`` (``w``: a work array of :attr:`work_size`),
    O(size) for any size;
  - :meth:`ForceKernel.scalar_lines`: the same force as straight-line code on
    scalar locals (for the small systems whose loop keeps the state in
    registers), or None.

Every name the kernel writes starts with ``_F`` (the loops' own locals never
do).
"""
from __future__ import annotations

import hashlib

import numpy as np

from .. import expr as ex
from .spring_template import TENSION

__all__ = ["ForceKernel", "ExprKernel", "SpringKernel", "ChainKernel", "digest"]


def digest(text: str) -> str:
    """Short SHA-256 of a kernel's text (a cache key)."""
    return hashlib.sha256(text.encode()).hexdigest()[:16]


class _Constants:
    """Numbers of an expression moved into ``fp`` slots: ``literal(v)`` gives
    the local ``_Fc{j}`` that holds ``v`` (one slot per distinct value)."""

    def __init__(self):
        self.values: list[float] = []
        self._slot: dict = {}

    def literal(self, v: float) -> str:
        key = (float(v), np.copysign(1.0, v))
        if key not in self._slot:
            self._slot[key] = len(self.values)
            self.values.append(float(v))
        return f"_Fc{self._slot[key]}"

    def loads(self, offset: int = 0) -> list[str]:
        return [f"_Fc{j} = fp[{offset + j}]" for j in range(len(self.values))]


def _print(exprs, names: dict, consts: _Constants, temp_prefix: str):
    """``(lines, results)``: ``exprs`` printed as scalar Python (``math``
    functions), numbers as ``consts`` locals, shared subexpressions once."""
    printer = ex._Printer(names, lambda f: f"math.{f}", source=True, temps=True, literal=consts.literal,
                          temp_prefix=temp_prefix)
    printer.mark_shared(exprs)
    results = [printer.print(e) for e in exprs]
    return printer.lines, results


class ForceKernel:
    """Base class: see the module docstring.

    Attributes
    ----------
    n_dof : int
    fp : ndarray of float64
    ip : ndarray of int64
    work_size : int
        Length of the work array ``w`` the array form needs (>= 1).
    """

    n_dof: int
    fp: np.ndarray
    ip: np.ndarray
    work_size: int = 1

    def array_source(self) -> str:  # pragma: no cover - abstract
        raise NotImplementedError

    def scalar_lines(self, q: list, f: list):
        """``(hoisted, body)`` lines computing locals ``f[i]`` from locals
        ``q[i]``; ``hoisted`` reads ``fp``/``ip`` once, before any loop.
        None when the definition has no straight-line form. Its text depends
        on the size (an edge list written out): use it for small systems only
        (:attr:`MAX_SCALAR_DOF`)."""
        return None

    #: Largest number of degrees of freedom for which :meth:`scalar_lines`
    #: writes straight-line code (its text grows with the size).
    MAX_SCALAR_DOF = 8

    def key(self) -> str:
        """Digest of the kernel's array text (its structure, not its numbers;
        computed once)."""
        cached = self.__dict__.get("_key")
        if cached is None:
            cached = self.__dict__["_key"] = digest(self.array_source() + self.slope_source())
        return cached

    def slope_source(self) -> str:
        """``def slope(fp, ip, mass, y, out, w)``: ``out = dy/dt`` for ``y =
        [q, v]`` (``q' = v``, ``v' = F(q) / mass``, as ``Model.rhs``), by
        default through :meth:`array_source`'s ``force``; a kernel may fuse
        the two passes (same numbers)."""
        return ("def slope(fp, ip, mass, y, out, w):\n"
                "    n = y.shape[0] // 2\n"
                "    force(fp, ip, y[:n], out[n:], w)\n"
                "    for i in range(n):\n"
                "        out[i] = y[n + i]\n"
                "        out[n + i] = out[n + i] / mass[i]\n")

    def _scalar_parts(self):
        """:meth:`scalar_lines` on locals ``q0 ..`` and ``f0 ..`` (computed
        once; None without a straight-line form)."""
        if "_scalar_text" not in self.__dict__:  # (not the method's own name: that would hide the method)
            self.__dict__["_scalar_text"] = self.scalar_lines([f"q{i}" for i in range(self.n_dof)],
                                                              [f"f{i}" for i in range(self.n_dof)])
        return self.__dict__["_scalar_text"]

    def scalar_key(self) -> str:
        """Digest of the straight-line text (which also depends on the edge
        list); computed once. Only for kernels with :meth:`has_scalar`."""
        cached = self.__dict__.get("_scalar_key")
        if cached is None:
            hoisted, body = self._scalar_parts()
            cached = self.__dict__["_scalar_key"] = digest("\n".join(hoisted + body))
        return cached

    def scalar_size(self) -> int:
        """Lines of the straight-line force (:meth:`scalar_lines`, the hoisted
        reads apart): what inlining it at every stage of a loop costs to
        compile. Only for kernels with :meth:`has_scalar`."""
        return len(self._scalar_parts()[1])

    def has_scalar(self) -> bool:
        """True when :meth:`scalar_lines` gives straight-line code (computed once)."""
        cached = self.__dict__.get("_has_scalar")
        if cached is None:
            cached = self.__dict__["_has_scalar"] = self.n_dof <= self.MAX_SCALAR_DOF and \
                self._scalar_parts() is not None
        return cached


class ExprKernel(ForceKernel):
    """The force ``-grad V`` of a :class:`~rk4h.models.PotentialModel`:
    one expression per coordinate, its numbers moved into ``fp``."""

    def __init__(self, force_exprs, coordinates):
        self.force_exprs = list(force_exprs)
        self.coordinates = list(coordinates)
        self.n_dof = len(self.coordinates)
        consts = _Constants()
        _print(self.force_exprs, {c: f"_Fq{i}" for i, c in enumerate(self.coordinates)}, consts, "_Ft")
        self.fp = np.asarray(consts.values, dtype=float)
        if self.fp.size == 0:
            self.fp = np.zeros(1)
        self.ip = np.zeros(1, dtype=np.int64)

    def scalar_lines(self, q, f):
        consts = _Constants()
        lines, results = _print(self.force_exprs, {c: q[i] for i, c in enumerate(self.coordinates)}, consts,
                                "_Ft")
        return consts.loads(), lines + [f"{fi} = {r}" for fi, r in zip(f, results)]

    def array_source(self) -> str:
        q = [f"_Fq{i}" for i in range(self.n_dof)]
        fl = [f"_Ff{i}" for i in range(self.n_dof)]
        hoisted, body = self.scalar_lines(q, fl)
        L = ["def force(fp, ip, q, f, w):"]
        L += [f"    {qi} = q[{i}]" for i, qi in enumerate(q)]
        L += ["    " + line for line in hoisted + body]
        L += [f"    f[{i}] = {fi}" for i, fi in enumerate(fl)]
        return "\n".join(L) + "\n"


def _tension_source(linear: bool, consts: _Constants | None = None):
    """``(lines, result)``: the tension ``E'(r)`` of the one spring-energy
    template (:data:`rk4h.models.spring_template.SPRING_ENERGY`) in the locals
    ``_Fr`` (extension), ``_Fk``, ``_Fal``, ``_Fbe``; with ``alpha = beta =
    0`` substituted when ``linear`` (it is then ``k r``)."""
    e = ex.substitute(TENSION, {"alpha": 0.0, "beta": 0.0}) if linear else TENSION
    names = {"r": "_Fr", "k": "_Fk", "alpha": "_Fal", "beta": "_Fbe"}
    lines, (result,) = _print([e], names, consts or _Constants(), "_FT")
    return lines, result


def _tension_over_length(dim: int, t_lines, t_res) -> list:
    """Source lines (inside the loop over springs ``s``, the extension
    vector in ``_Fd0..``) computing the spring's length ``_FL``, extension
    ``_Fr`` and tension over length ``_FtL``; shared by the two-pass force
    and the fused slope, so both compute the same numbers."""
    L = ["        _FL2 = _Fd0 * _Fd0"]
    if dim == 2:
        L.append("        _FL2 = _FL2 + _Fd1 * _Fd1")
    L += [
        "        _FL = math.sqrt(_FL2)",
        "        _Fr = _FL - fp[ore + s]",
        "        _Fk, _Fal, _Fbe = fp[ok + s], fp[oal + s], fp[obe + s]",
    ]
    L += ["        " + line for line in t_lines]
    L += [f"        _FtL = {t_res} / _FL"]
    return L


class SpringKernel(ForceKernel):
    """The force of a spring network (:class:`~rk4h.models.Network`): the
    tension of the spring-energy template over the edge list, with exact
    geometry, accumulated as the numpy path does (``np.add.at`` on the ``a``
    ends in spring order, then on the ``b`` ends).

    ``fp = [X (n dim), A (anchors dim), k, alpha, beta, rest (per spring)]``,
    ``ip = [n, anchors, springs, a..., b...]``.
    """

    #: The fused slope (the force in it) is inlined at every stage, as a
    #: chain's: a call per stage cost a small network 1.3x its run time
    #: (benchmarks/bench_network.py); the loop takes about twice as long to
    #: compile, once per machine (numba's on-disk cache).
    inline_slope = True

    def __init__(self, dim, X, A, a, b, k, alpha, beta, rest):
        self.dim = int(dim)
        self.n_masses, self.n_anchors, self.n_springs = X.shape[0], A.shape[0], k.shape[0]
        self.n_dof = self.n_masses * self.dim
        self.linear_springs = not (np.any(alpha) or np.any(beta))
        self.fp = np.concatenate([X.ravel(), A.ravel(), k, alpha, beta, rest]).astype(float)
        self.ip = np.concatenate([[self.n_masses, self.n_anchors, self.n_springs], a, b]).astype(np.int64)
        self.a, self.b = np.asarray(a), np.asarray(b)
        # w: the spring forces (springs x dim), then the node positions and
        # the force sums of every node, anchors included (nodes x dim each):
        # the fused slope's pass over the edge list has no branch on the ends
        self.work_size = max(1, (self.n_springs + 2 * (self.n_masses + self.n_anchors)) * self.dim)

    def array_source(self) -> str:
        D = self.dim
        t_lines, t_res = _tension_source(self.linear_springs)
        L = [
            "def force(fp, ip, q, f, w):",
            "    nm, na, ns = ip[0], ip[1], ip[2]",
            f"    oA = nm * {D}",
            f"    ok = oA + na * {D}",
            "    oal, obe, ore = ok + ns, ok + 2 * ns, ok + 3 * ns",
            f"    for _Fi in range(nm * {D}):",
            "        f[_Fi] = 0.0",
            "    for s in range(ns):",
            "        a, b = ip[3 + s], ip[3 + ns + s]",
        ]
        for c in range(D):  # node positions: reference + displacement (masses), or the anchor
            for end in ("a", "b"):
                L += [f"        if {end} < nm:",
                      f"            _FP{end}{c} = fp[{end} * {D} + {c}] + q[{end} * {D} + {c}]",
                      "        else:",
                      f"            _FP{end}{c} = fp[oA + ({end} - nm) * {D} + {c}]"]
        L += [f"        _Fd{c} = _FPb{c} - _FPa{c}" for c in range(D)]
        L += _tension_over_length(D, t_lines, t_res)
        for c in range(D):
            L += [f"        w[s * {D} + {c}] = _FtL * _Fd{c}",
                  f"        if a < nm:",
                  f"            f[a * {D} + {c}] = f[a * {D} + {c}] + w[s * {D} + {c}]"]
        L += ["    for s in range(ns):",
              "        b = ip[3 + ns + s]",
              "        if b < nm:"]
        L += [f"            f[b * {D} + {c}] = f[b * {D} + {c}] + -w[s * {D} + {c}]" for c in range(D)]
        return "\n".join(L) + "\n"

    def slope_source(self) -> str:
        """``dy/dt`` in one function, the force inlined: node positions
        ``P`` (``X + u`` for the masses, ``A`` for the anchors) laid out
        once per call, then one pass over the edge list with the tension of
        the template and no branch (force sums ``g`` kept for every node,
        the anchors' never read), the ``b`` ends after, then ``v`` and ``g /
        m``. The numbers of the two-pass default bit for bit: each
        coordinate's sum takes the same terms in the same order (``a`` ends
        in spring order from 0.0, then ``b`` ends)."""
        D = self.dim
        t_lines, t_res = _tension_source(self.linear_springs)
        L = [
            "def slope(fp, ip, mass, y, out, w):",
            "    n = y.shape[0] // 2",
            "    nm, na, ns = ip[0], ip[1], ip[2]",
            f"    oA = nm * {D}",
            f"    ok = oA + na * {D}",
            "    oal, obe, ore = ok + ns, ok + 2 * ns, ok + 3 * ns",
            f"    oP = ns * {D}",
            f"    og = oP + (nm + na) * {D}",
            "    for i in range(n):",
            "        w[oP + i] = fp[i] + y[i]",
            "        w[og + i] = 0.0",
            f"    for j in range(na * {D}):",
            "        w[oP + n + j] = fp[oA + j]",
            "        w[og + n + j] = 0.0",
            "    for s in range(ns):",
            "        a, b = ip[3 + s], ip[3 + ns + s]",
        ]
        L += [f"        _Fd{c} = w[oP + b * {D} + {c}] - w[oP + a * {D} + {c}]" for c in range(D)]
        L += _tension_over_length(D, t_lines, t_res)
        for c in range(D):
            L += [f"        _FF{c} = _FtL * _Fd{c}",
                  f"        w[s * {D} + {c}] = _FF{c}",
                  f"        w[og + a * {D} + {c}] = w[og + a * {D} + {c}] + _FF{c}"]
        L += ["    for s in range(ns):",
              "        b = ip[3 + ns + s]"]
        L += [f"        w[og + b * {D} + {c}] = w[og + b * {D} + {c}] + -w[s * {D} + {c}]" for c in range(D)]
        L += ["    for i in range(n):",
              "        out[i] = y[n + i]",
              "        out[n + i] = w[og + i] / mass[i]"]
        return "\n".join(L) + "\n"

    def scalar_lines(self, q, f):
        """Straight-line code over the edge list (its structure -- which
        nodes each spring joins -- becomes part of the text)."""
        D, n, ns = self.dim, self.n_masses, self.n_springs
        oA, ok = n * D, n * D + self.n_anchors * D
        hoisted, body = [], []
        for s in range(ns):
            hoisted += [f"_Fk{s} = fp[{ok + s}]", f"_Fal{s} = fp[{ok + ns + s}]", f"_Fbe{s} = fp[{ok + 2 * ns + s}]",
                        f"_Frest{s} = fp[{ok + 3 * ns + s}]"]
        for node in range(n):
            hoisted += [f"_FX{node}_{c} = fp[{node * D + c}]" for c in range(D)]
        for j in range(self.n_anchors):
            hoisted += [f"_FA{j}_{c} = fp[{oA + j * D + c}]" for c in range(D)]

        def pos(node, c):
            return f"(_FX{node}_{c} + {q[node * D + c]})" if node < n else f"_FA{node - n}_{c}"

        t_lines, t_res = _tension_source(self.linear_springs)
        for s in range(ns):
            a, b = int(self.a[s]), int(self.b[s])
            body += [f"_Fd{c} = {pos(b, c)} - {pos(a, c)}" for c in range(D)]
            body.append("_FL2 = _Fd0 * _Fd0")
            if D == 2:
                body.append("_FL2 = _FL2 + _Fd1 * _Fd1")
            body += ["_FL = math.sqrt(_FL2)", f"_Fr = _FL - _Frest{s}",
                     f"_Fk, _Fal, _Fbe = _Fk{s}, _Fal{s}, _Fbe{s}"]
            body += t_lines
            body.append(f"_FtL = {t_res} / _FL")
            body += [f"_FF{s}_{c} = _FtL * _Fd{c}" for c in range(D)]
        acc = {i: None for i in range(n * D)}

        def add(i, term):
            acc[i] = f"0.0 + {term}" if acc[i] is None else f"({acc[i]}) + {term}"

        for s in range(ns):  # np.add.at(f, a, F): the a ends, in spring order
            if self.a[s] < n:
                for c in range(D):
                    add(int(self.a[s]) * D + c, f"_FF{s}_{c}")
        for s in range(ns):  # then np.add.at(f, b, -F)
            if self.b[s] < n:
                for c in range(D):
                    add(int(self.b[s]) * D + c, f"-_FF{s}_{c}")
        body += [f"{f[i]} = {acc[i] if acc[i] is not None else '0.0'}" for i in range(n * D)]
        return hoisted, body


class ChainKernel(ForceKernel):
    """The force of a 1-D chain (:class:`~rk4h.models.Chain`): tensions
    ``T_j = E'(r_j)`` of the extensions ``r_j = u_{j+1} - u_j`` of the
    wall-padded displacements (zero tension beyond a free end), ``F_i =
    T_{i+1} - T_i``; each tension formed once and carried to the next mass.

    ``fp = [k (per spring), alpha, beta]``, ``ip = [left wall, right wall]``.
    """

    def __init__(self, k, alpha, beta, left, right, linear):
        self.n_dof = int(k.shape[0] - (1 if left and right else 0 if (left or right) else -1))
        self.fp = np.concatenate([k, [alpha, beta]]).astype(float)
        self.ip = np.array([int(left), int(right)], dtype=np.int64)
        self.left, self.right, self.linear = bool(left), bool(right), bool(linear)

    def _pass(self, slope: bool) -> str:
        """One pass over the chain, each tension formed once and carried to
        the next mass: ``force`` (``F`` into ``f``) or, when ``slope``, the
        fused ``slope`` (velocity copy and ``F / m`` in the same pass; the
        numbers of the two-pass default)."""
        t_lines, t_res = _tension_source(self.linear)
        T = lambda r, k: ["_Fr = " + r, "_Fk = " + k] + t_lines + [f"_Fnxt = {t_res}"]  # noqa: E731
        q = "y" if slope else "q"

        def store(i, n_):  # F_i = T_{i+1} - T_i, stored
            if slope:
                return [f"out[{i}] = y[{n_} + {i}]", f"out[{n_} + {i}] = (_Fnxt - _Fprev) / mass[{i}]"]
            return [f"f[{i}] = _Fnxt - _Fprev"]

        L = ["def slope(fp, ip, mass, y, out, w):" if slope else "def force(fp, ip, q, f, w):",
             "    n = y.shape[0] // 2" if slope else "    n = f.shape[0]",
             "    nk = fp.shape[0] - 2",
             "    _Fal, _Fbe = fp[nk], fp[nk + 1]",
             "    off = 1 if ip[0] != 0 else 0",
             "    _Fprev = 0.0",
             "    if ip[0] != 0:"]
        L += ["        " + line for line in T(f"{q}[0] - 0.0", "fp[0]")]
        L += ["        _Fprev = _Fnxt",
              "    for i in range(n - 1):  # the springs between masses: no branch inside"]
        L += ["        " + line for line in T(f"{q}[i + 1] - {q}[i]", "fp[i + off]")]
        L += ["        " + line for line in store("i", "n")] + ["        _Fprev = _Fnxt", "    if ip[1] != 0:"]
        L += ["        " + line for line in T(f"0.0 - {q}[n - 1]", "fp[n - 1 + off]")]
        L += ["    else:", "        _Fnxt = 0.0"] + ["    " + line for line in store("n - 1", "n")]
        return "\n".join(L) + "\n"

    def array_source(self) -> str:
        return self._pass(slope=False)

    def slope_source(self) -> str:
        """The force, the velocity copy and the division by the mass in one
        pass over the chain (the numbers of the two-pass default)."""
        return self._pass(slope=True)

    def scalar_lines(self, q, f):
        n = self.n_dof
        nk = self.fp.shape[0] - 2
        hoisted = [f"_Fk{j} = fp[{j}]" for j in range(nk)] + [f"_Fal = fp[{nk}]", f"_Fbe = fp[{nk + 1}]"]
        t_lines, t_res = _tension_source(self.linear)
        body = []
        pad = (["0.0"] if self.left else []) + list(q) + (["0.0"] if self.right else [])
        for j in range(nk):  # the tension of each spring, left to right
            body += [f"_Fr = {pad[j + 1]} - {pad[j]}", f"_Fk = _Fk{j}"] + t_lines + [f"_FT{j}s = {t_res}"]
        T = (["0.0"] if not self.left else []) + [f"_FT{j}s" for j in range(nk)] + \
            (["0.0"] if not self.right else [])
        body += [f"{f[i]} = {T[i + 1]} - {T[i]}" for i in range(n)]
        return hoisted, body
