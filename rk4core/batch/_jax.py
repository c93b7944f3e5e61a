"""The jax backend of :func:`rk4h.ensemble`.

One step is printed from the method's tableau and the force kernel's
straight-line code (:meth:`ForceKernel.scalar_lines`) by
:func:`rk4h.fast.codegen.step_lines`, the text the numba loops inline: products
``h a_ij`` and ``h b_i`` formed once, stage sums left to right over the
nonzero coefficients, a partitioned stage's velocity and position in the
order the tableau gives, a first-same-as-last method's last force carried
into the next step. Every local is an array of shape (B,) -- one lane per
instance -- so the batch is the vector width; ``math.f`` of the printed
expressions is ``jax.numpy.f``.

The steps run in a ``lax.scan`` over the output rows, each row after the
steps up to it: a ``lax.fori_loop`` whose body is :data:`UNROLL` steps written
out one after the other, then one loop of single steps for the remainder. The
written-out body is what makes a GPU fast: XLA fuses it into one kernel, so the
state stays in registers for ``UNROLL`` steps instead of going through device
memory (and a loop iteration's launch) after every step. Unrolling changes no
arithmetic: every instance does the same operations in the same order for
any ``UNROLL`` (tests/test_ensemble.py checks it bit for bit).
An instance whose new state fails the instability test keeps its last
accepted state and is marked dead (its later rows are NaN); the others run on.

Importing this module switches jax's x64 mode on (float64 arithmetic;
``jax.config.update("jax_enable_x64", True)``).
"""
from __future__ import annotations

import types

import numpy as np

import jax
import jax.numpy as jnp
from jax import lax

from ..fast.codegen import _force, _Plan, step_lines

jax.config.update("jax_enable_x64", True)

__all__ = ["run", "step_source", "UNROLL"]

#: Steps written out in one loop iteration, by jax platform (see the module's
#: docstring); any other platform: 1. On the CPU, XLA's code for a written-out
#: body is slower per step (2.7x at 16 steps, docs/performance.md), so it
#: stays 1 there; the GPU figure is measured by
#: ``benchmarks/bench_ensemble.py --unroll``.
UNROLL = {"cpu": 1, "gpu": 16}

_MATH = types.SimpleNamespace(**{name: getattr(jnp, name) for name in dir(jnp) if not name.startswith("_")})
_STEPS: dict = {}


def step_source(tab, kern) -> str:
    """Source of ``step(fp, m, y, kc, hs)`` for method ``tab`` and force kernel
    ``kern``: ``y`` the state components, ``kc`` the carried FSAL slopes
    (empty tuple otherwise), ``hs`` the dict of products ``h a_ij``, ``h b_i``;
    returns ``(new state, new kc)``."""
    nq = kern.n_dof
    dim = 2 * nq
    plan = _Plan(tab)
    hoisted, _ = kern.scalar_lines([f"s{p}" for p in range(nq)], [f"_Fo{p}" for p in range(nq)])
    L = ["def step(fp, m, y, kc, hs):"]
    L += [f"    y{p} = y[{p}]" for p in range(dim)]
    L += [f"    m{p} = m[{p}]" for p in range(nq)]
    L += ["    " + line for line in hoisted]
    names = [line.strip().split(" = ")[0] for line in plan.products("")]
    L += [f"    {nm} = hs[{nm!r}]" for nm in names]
    if plan.fsal:
        i0 = plan.fsal[0]
        L += [f"    k{i0}_{nq + p} = kc[{p}]" for p in range(nq)]
    L += step_lines(plan, kern, dim)
    new = ", ".join(f"n{p}" for p in range(dim))
    if plan.fsal:
        i1 = plan.fsal[1]
        carried = ", ".join(f"k{i1}_{nq + p}" for p in range(nq))
        L.append(f"    return ({new},), ({carried},)")
    else:
        L.append(f"    return ({new},), ()")
    return "\n".join(L) + "\n"


def _first_force_source(tab, kern) -> str:
    """``first(fp, m, y)``: the FSAL method's first evaluation, ``F(q0) / m``."""
    nq = kern.n_dof
    hoisted, _ = kern.scalar_lines([f"y{p}" for p in range(nq)], [f"_Fo{p}" for p in range(nq)])
    L = ["def first(fp, m, y):"] + [f"    y{p} = y[{p}]" for p in range(nq)] + [f"    m{p} = m[{p}]" for p in range(nq)]
    L += ["    " + line for line in hoisted + _force(kern, [f"y{p}" for p in range(nq)])]
    L.append("    return (" + ", ".join(f"_Fo{p} / m{p}" for p in range(nq)) + ",)")
    return "\n".join(L) + "\n"


def _compile(text: str, name: str):
    ns = {"math": _MATH}
    exec(compile(text, f"<rk4h.batch jax {name}>", "exec"), ns)
    return ns[name]


def _runner(tab, kern, dtype: str, unroll: int):
    key = (tab.name, id(tab), kern.key(), kern.scalar_key(), dtype, unroll)
    hit = _STEPS.get(key)
    if hit is not None:
        return hit[0]
    plan = _Plan(tab)
    step = _compile(step_source(tab, kern), "step")
    first = _compile(_first_force_source(tab, kern), "first") if plan.fsal else None
    names = [line.strip().split(" = ")[0] for line in plan.products("")]
    coefs = [line.strip().split(" * ")[1] for line in plan.products("")]
    dt = jnp.dtype(dtype)
    dim = 2 * kern.n_dof
    big = float(np.finfo(dt).max)

    @jax.jit
    def run(fp, m, y0, bound, pending, h, counts):
        # fp (n_fp, B), m (n_dof, B), y0 (dim, B), bound (dim, B), pending (B,)
        hs = {nm: h * jnp.asarray(float(c), dtype=dt) for nm, c in zip(names, coefs)}
        fpt = tuple(fp[j] for j in range(fp.shape[0]))
        mt = tuple(m[j] for j in range(m.shape[0]))
        y = tuple(y0[p] for p in range(dim))
        kc = first(fpt, mt, y) if first is not None else ()
        B = y0.shape[1]
        alive = jnp.ones(B, dtype=bool)
        done = jnp.zeros(B, dtype=jnp.int64)

        def one(_, c):
            y, kc, bound, pending, alive, done = c
            new, kc_new = step(fpt, mt, y, kc, hs)
            ok = alive
            for p in range(dim):
                ok = ok & (jnp.abs(new[p]) <= bound[p])
            y = tuple(jnp.where(ok, a, b) for a, b in zip(new, y))
            kc = tuple(jnp.where(ok, a, b) for a, b in zip(kc_new, kc))
            norm = jnp.zeros_like(new[0])
            for p in range(dim):
                norm = jnp.maximum(norm, jnp.abs(new[p]))
            arm = ok & (pending > 0) & (norm > 0)
            bound = jnp.where(arm[None, :], jnp.minimum(pending * norm, big)[None, :], bound)
            pending = jnp.where(arm, 0.0, pending)
            return y, kc, bound, pending, ok, done + ok.astype(done.dtype)

        def block(i, c):
            for _ in range(unroll):
                c = one(i, c)
            return c

        def row(c, count):
            c = lax.fori_loop(0, count // unroll, block, c)
            c = lax.fori_loop(0, count % unroll, one, c)
            out = jnp.stack([jnp.where(c[4], yp, jnp.nan) for yp in c[0]], axis=-1)
            return c, out

        c, ys = lax.scan(row, (y, kc, bound, pending, alive, done), counts)
        return ys, c[5], c[4]

    _STEPS[key] = (run, tab)  # the tableau is kept, so its id is never reused
    return run


def run(tab, kern, fp, mass, y0, t0, step, n, idx, theta, ys, bound, pending, *, dtype="float64", unroll=None):
    """Integrate the rows of ``y0`` (one chunk), writing ``ys`` (B, rows, dim)
    in place; returns ``(steps completed, status)`` per instance. The output
    points ``idx`` are grid steps (``theta`` all zero). ``unroll``: steps per
    loop iteration (default: :data:`UNROLL` of jax's default platform)."""
    unroll = UNROLL.get(jax.default_backend(), 1) if unroll is None else unroll
    if isinstance(unroll, bool) or not isinstance(unroll, int) or unroll < 1:
        raise ValueError(f"`unroll` must be an integer >= 1, got {unroll!r}")
    if not kern.has_scalar():
        raise ValueError(f"backend='jax' needs a force with a straight-line form (at most "
                         f"{kern.MAX_SCALAR_DOF} degrees of freedom), got {kern.n_dof}; use backend='numba'")
    dt = np.dtype(dtype)
    fn = _runner(tab, kern, dtype, unroll)
    counts = np.diff(np.concatenate([[0], idx])).astype(np.int64)
    big = np.finfo(dt).max
    out, done, alive = fn(jnp.asarray(fp.T, dtype=dt), jnp.asarray(mass.T, dtype=dt), jnp.asarray(y0.T, dtype=dt),
                          jnp.asarray(np.minimum(bound, big).T, dtype=dt), jnp.asarray(pending, dtype=dt),
                          jnp.asarray(step, dtype=dt), jnp.asarray(counts))
    ys[...] = np.swapaxes(np.asarray(out, dtype=np.float64), 0, 1)
    return np.asarray(done, dtype=np.int64), np.where(np.asarray(alive), 0, -1).astype(np.int64)
