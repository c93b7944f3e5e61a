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
steps up to it, by one of two loop kernels (:data:`KERNEL`, by platform):

* ``"pallas"`` (GPU): one Pallas kernel (Triton) per output row. Each program
  loads :data:`LANES` instances' states once, runs all the row's steps with
  them in registers and stores them once: on an H200, about 4 us per step for
  10^6 instances (derived from two timed calls in docs/performance.md).
* ``"xla"`` (CPU, and the GPU when jax lacks Pallas' Triton backend): a
  ``lax.fori_loop`` whose body is :data:`UNROLL` steps written out, then the
  remainder one at a time. On a GPU every iteration still sends the state
  through device memory: a whole call of 10^6 instances for 10^4 steps took
  0.066 ns per instance-step at 16 steps per iteration, against 0.050 with
  the Pallas kernel (H200, docs/performance.md).

Both trace one function (step, then the instability test), so they ask
for the same operations in the same order. tests/test_ensemble.py checks
them bit for bit against each other on the CPU (the Pallas program through
Pallas' interpreter, ``"pallas-interpret"``) at one batch layout. That is
as far as bit-identity goes here: XLA's CPU code treats a batch's vector
lanes and its leftover lanes differently, so an instance's last bits can
depend on the batch size and on where the instance sits in it (2-DOF chain,
200 steps of rk4, Stormer-Verlet and Yoshida 4: 18 of 27 instances run
alone differed from the same instances in a batch of 9, by at most 5e-15
relative). Every instance stays within the backend's 1e-13 of
:func:`rk4h.solve`. On an H200 the Pallas kernel and jax's loops both gave
the numba batch's states bit for bit (docs/performance.md).
An instance whose new state fails the
instability test keeps its last accepted state and is marked dead (its later
rows are NaN); the others run on.

Importing this module switches jax's x64 mode on (float64 arithmetic;
``jax.config.update("jax_enable_x64", True)``).
"""
from __future__ import annotations

import types
import warnings

import numpy as np

import jax
import jax.numpy as jnp
from jax import lax

from ..fast.codegen import _force, _Plan, step_lines

jax.config.update("jax_enable_x64", True)

__all__ = ["run", "step_source", "KERNEL", "KERNELS", "LANES", "UNROLL"]

#: Steps written out in one iteration of the ``"xla"`` kernel, by jax platform
#: (any other: 1). On the CPU a written-out body is slower per step (2.7x at
#: 16 steps, docs/performance.md), so it stays 1 there. Measured by
#: ``benchmarks/bench_ensemble.py --kernels xla:1 xla:16``.
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
    L += [f"    {nm} = hs[{nm!r}]" for nm, _ in plan.coefficients()]
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


def _step_products(h, names, coefs, dt) -> dict:
    """The tableau's products ``h a_ij``, ``h b_i`` (``names``: their locals in
    the printed step) for the step ``h``, in dtype ``dt``."""
    return {nm: h * jnp.asarray(cf, dtype=dt) for nm, cf in zip(names, coefs)}


def _checked_step(step, dim, big):
    """``one(c, fp, m, hs)``: one step of every lane of the carry ``c = (y, kc,
    bound, pending, alive, done)`` (tuples of lane arrays for ``y``, ``kc`` and
    ``bound``), with the instability test. Both kernels trace this one
    function, so they ask for the same operations in the same order."""

    def one(c, fpt, mt, hs):
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
        armed = jnp.minimum(pending * norm, big)
        bound = tuple(jnp.where(arm, armed, b) for b in bound)
        pending = jnp.where(arm, 0.0, pending)
        return y, kc, bound, pending, ok, done + ok.astype(done.dtype)

    return one


def _xla_steps(one, unroll):
    """``steps(c, count, fpt, mt, hs)``: ``count`` steps as XLA loops,
    ``unroll`` written out per iteration, then the remainder one at a time."""

    def steps(c, count, fpt, mt, hs):
        def single(_, c):
            return one(c, fpt, mt, hs)

        def block(_, c):
            for _ in range(unroll):
                c = one(c, fpt, mt, hs)
            return c

        c = lax.fori_loop(0, count // unroll, block, c)
        return lax.fori_loop(0, count % unroll, single, c)

    return steps


def _pallas_steps(one, names, coefs, dt, lanes, interpret):
    """``steps(c, count, fpt, mt, h)`` as one Pallas kernel: each program takes
    ``lanes`` instances, loads their state once, runs all ``count`` steps with
    it in registers and stores it once. Every lane array must have a length
    that ``lanes`` divides (the caller pads)."""
    from jax.experimental import pallas as pl
    from jax.experimental.pallas import triton as pltriton

    def steps(c, count, fpt, mt, h):
        y, kc, bound, pending, alive, done = c
        ins = (*fpt, *mt, *y, *kc, *bound, pending, alive.astype(jnp.int32), done)
        sizes = (len(fpt), len(mt), len(y), len(kc), len(bound))
        B = pending.shape[0]
        if B % lanes:
            raise ValueError(f"{B} instances do not fill programs of {lanes} (the caller pads)")

        def kernel(count_ref, h_ref, *refs):
            loaded = [r[...] for r in refs[:len(ins)]]
            parts, at = [], 0
            for size in sizes:
                parts.append(tuple(loaded[at:at + size]))
                at += size
            fpk, mk, yk, kck, boundk = parts
            pendk, alivek, donek = loaded[at], loaded[at + 1] != 0, loaded[at + 2]
            hk = h_ref[0]
            hs = _step_products(hk, names, coefs, dt)

            def single(_, c):
                return one(c, fpk, mk, hs)

            out = lax.fori_loop(0, count_ref[0], single, (yk, kck, boundk, pendk, alivek, donek))
            flat = (*out[0], *out[1], *out[2], out[3], out[4].astype(jnp.int32), out[5])
            for r, v in zip(refs[len(ins):], flat):
                r[...] = v

        lane = pl.BlockSpec((lanes,), lambda i: (i,))
        one_value = pl.BlockSpec((1,), lambda i: (0,))
        outs = pl.pallas_call(
            kernel, grid=(B // lanes,),
            in_specs=[one_value, one_value] + [lane] * len(ins),
            out_specs=[lane] * (len(ins) - len(fpt) - len(mt)),
            out_shape=[jax.ShapeDtypeStruct((B,), a.dtype) for a in ins[len(fpt) + len(mt):]],
            interpret=interpret,
            compiler_params=pltriton.CompilerParams(),  # Triton: jax's default GPU lowering is Mosaic
        )(jnp.reshape(count, (1,)).astype(jnp.int64), jnp.reshape(h, (1,)), *ins)
        ny, nk, nb = len(y), len(kc), len(bound)
        return (tuple(outs[:ny]), tuple(outs[ny:ny + nk]), tuple(outs[ny + nk:ny + nk + nb]),
                outs[-3], outs[-2] != 0, outs[-1])

    return steps


#: Instances per Pallas program (a power of two, as Triton's blocks must be).
LANES = 128
#: The loop's kernels: ``"xla"`` (jax's own loops, :data:`UNROLL` steps per
#: iteration), ``"pallas"`` (one Pallas kernel per output row: the state
#: stays in registers for all the row's steps; GPU only) and
#: ``"pallas-interpret"`` (that kernel's jax program run by Pallas'
#: interpreter: any platform, slow; the tests' check of its arithmetic).
KERNELS = ("xla", "pallas", "pallas-interpret")
#: Kernel by jax platform; any other platform: ``"xla"``.
KERNEL = {"cpu": "xla", "gpu": "pallas"}


def _runner(tab, kern, dtype: str, unroll: int, kernel: str, lanes: int):
    key = (tab.name, id(tab), kern.key(), kern.scalar_key(), dtype, unroll, kernel, lanes)
    hit = _STEPS.get(key)
    if hit is not None:
        return hit[0]
    plan = _Plan(tab)
    step = _compile(step_source(tab, kern), "step")
    first = _compile(_first_force_source(tab, kern), "first") if plan.fsal else None
    names, coefs = zip(*plan.coefficients())
    dt = jnp.dtype(dtype)
    dim = 2 * kern.n_dof
    big = float(np.finfo(dt).max)
    one = _checked_step(step, dim, big)
    if kernel == "xla":
        steps = _xla_steps(one, unroll)
    else:
        steps = _pallas_steps(one, names, coefs, dt, lanes, interpret=kernel == "pallas-interpret")

    @jax.jit
    def run(fp, m, y0, bound, pending, h, counts):
        # instance-major, as the caller holds them: fp (B, n_fp), m (B, n_dof), y0 (B, dim),
        # bound (B, dim) and pending (B,) in float64; the lanes are formed here, on the device.
        B = y0.shape[0]
        pad = (-B) % lanes

        def lane_arrays(a, fill):  # (B, k) -> k arrays of B + pad lanes, the padding a copy of `fill`
            a = a.T.astype(dt)
            if pad:
                a = jnp.concatenate([a, jnp.broadcast_to(jnp.asarray(fill, dtype=dt), (a.shape[0], pad))], axis=1)
            return tuple(a[j] for j in range(a.shape[0]))

        # padding lanes: the first instance's parameters, a zero state, no growth test; never read back
        fpt = lane_arrays(fp, fp[:1].T)
        mt = lane_arrays(m, m[:1].T)
        y = lane_arrays(y0, 0.0)
        bounds = lane_arrays(jnp.minimum(bound, big), big)
        (pending,) = lane_arrays(pending[:, None], 0.0)
        hs = _step_products(h, names, coefs, dt)
        kc = first(fpt, mt, y) if first is not None else ()
        alive = jnp.ones(B + pad, dtype=bool)
        done = jnp.zeros(B + pad, dtype=jnp.int64)
        per_step = h if kernel != "xla" else hs  # the Pallas kernel forms the products itself

        def row(c, count):
            c = steps(c, count, fpt, mt, per_step)
            out = jnp.stack([jnp.where(c[4], yp, jnp.nan) for yp in c[0]], axis=-1)
            return c, out

        c, ys = lax.scan(row, (y, kc, bounds, pending, alive, done), counts)
        return jnp.swapaxes(ys, 0, 1)[:B].astype(jnp.float64), c[5][:B], c[4][:B]

    _STEPS[key] = (run, tab)  # the tableau is kept, so its id is never reused
    return run


def _has_pallas_triton() -> bool:
    """Whether jax's Pallas has its Triton backend (deprecated in jax 0.11, to
    be removed: then the GPU runs jax's own loops, with a warning)."""
    try:
        from jax.experimental.pallas import triton  # noqa: F401
    except ImportError:
        return False
    return hasattr(triton, "CompilerParams")


def run(tab, kern, fp, mass, y0, t0, step, n, idx, theta, ys, bound, pending, *, dtype="float64", unroll=None,
        kernel=None):
    """Integrate the rows of ``y0`` (one chunk), writing ``ys`` (B, rows, dim)
    in place; returns ``(steps completed, status)`` per instance. The output
    points ``idx`` are grid steps (``theta`` all zero). ``unroll``: steps per
    XLA loop iteration (default: :data:`UNROLL` of jax's default platform);
    ``kernel``: one of :data:`KERNELS` (default: :data:`KERNEL` of that
    platform)."""
    platform = jax.default_backend()
    unroll = UNROLL.get(platform, 1) if unroll is None else unroll
    if isinstance(unroll, bool) or not isinstance(unroll, int) or unroll < 1:
        raise ValueError(f"`unroll` must be an integer >= 1, got {unroll!r}")
    chosen = kernel is None
    kernel = KERNEL.get(platform, "xla") if chosen else kernel
    if kernel not in KERNELS:
        raise ValueError(f"`kernel` must be one of {KERNELS}, got {kernel!r}")
    if kernel != "xla" and not _has_pallas_triton():
        if not chosen:
            raise ValueError(f"`kernel` = {kernel!r} needs jax's Pallas Triton backend, which this jax "
                             f"({jax.__version__}) does not have")
        warnings.warn(f"rk4h.ensemble: this jax ({jax.__version__}) has no Pallas Triton backend; the "
                      f"{platform} batch runs jax's own loops (slower; equal to 1e-13)", RuntimeWarning, stacklevel=3)
        kernel = "xla"
    if not kern.has_scalar():
        raise ValueError(f"backend='jax' needs a force with a straight-line form (at most "
                         f"{kern.MAX_SCALAR_DOF} degrees of freedom), got {kern.n_dof}; use backend='numba'")
    dt = np.dtype(dtype)
    xla = kernel == "xla"
    fn = _runner(tab, kern, dtype, unroll if xla else 1, kernel, 1 if xla else LANES)
    counts = np.diff(np.concatenate([[0], idx])).astype(np.int64)
    out, done, alive = fn(jnp.asarray(fp, dtype=np.float64), jnp.asarray(mass, dtype=np.float64),
                          jnp.asarray(y0, dtype=np.float64), jnp.asarray(bound, dtype=np.float64),
                          jnp.asarray(pending, dtype=np.float64), jnp.asarray(step, dtype=dt), jnp.asarray(counts))
    ys[...] = np.asarray(out)
    return np.asarray(done, dtype=np.int64), np.where(np.asarray(alive), 0, -1).astype(np.int64)
