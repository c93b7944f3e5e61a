"""Two array-loop designs tried against ``rk4h.fast.codegen.array_source``
for the cold start of issue 29, kept so that their figures in
docs/performance.md ("Eighteenth round") can be reproduced with
``benchmarks/bench_compile_options.py METHOD N one_call_site | as_data |
as_data_inline``. Neither is used by the package: both keep the numbers bit
for bit, and both slow the loops down (see there).

* :func:`one_call_site_source` -- one text per (method, force structure), as
  now, with the stages in a run-time loop so that the slope is inlined once;
* :func:`as_data_source` -- one text per force structure: the method is
  data (:func:`plan_data`), the combinations run-time loops over its terms.
"""
from __future__ import annotations

import numpy as np

from rk4h.fast.codegen import (_ARRAY_OUTPUT_START, _ARRAY_STEP_END, _HEADER, _Plan, _array_close, _array_head,
                               _array_new_state, _array_output_rest, _array_stage_parts, _dependencies_digest,
                               _slope_copy, _start_slope,
                               _rhs_lines)


def one_call_site_source(tab, kern) -> str:
    """The array loop of ``rk4h.fast.codegen.array_source`` with its stages
    in a run-time loop over the stage index: each stage's combination is
    still written out with its coefficients, but the force is called (and
    numba inlines the slope) at one place in the step, plus one for the
    dense output and one for a FSAL method's first evaluation, instead of
    once per stage. Same arguments, same numbers bit for bit."""
    plan = _Plan(tab)
    ns = plan.ns
    L = _array_head(plan, kern)
    L += [f"        for s in range({ns}):"]
    post = []
    for i in range(ns):
        body, ev, src, after = _array_stage_parts(plan, i, "                ")
        L += [f"            {'if' if i == 0 else 'elif'} s == {i}:"] + (body or ["                pass"])
        L += [f"                ev = {ev}", f"                src = {src}"]
        if after:
            post += [f"            {'if' if not post else 'elif'} s == {i}:"] + after
    # The one place the step calls the force (numba inlines a chain's fused
    # slope here: once, not once per stage).
    L += ["            if ev:", "                rhs(fp, ip, mass, src, k, s, nq, w)"] + post
    L += _array_new_state(plan)
    # Dense-output slopes at both ends of the step: from the stages when the
    # method has them (a copy), else one force call each -- through one call
    # site when both ends need one.
    start, start_array = _start_slope(plan)
    ends = [start, _slope_copy(plan, plan.fsal[1], "y_new", "f1") if plan.fsal else None]
    pad = "                    "
    call = ["rhs(fp, ip, mass, src, dst, 0, nq, w)", "n_extra += 1"]
    if ends[0] is None and ends[1] is None:
        dense = [pad + "for e in range(2):", pad + "    src = y if e == 0 else y_new",
                 pad + "    dst = f0 if e == 0 else f1"] + [pad + "    " + c for c in call]
    else:
        dense = []
        for (state, arr), lines in zip((("y", "f0"), ("y_new", "f1")), ends):
            if lines is None:
                dense += [pad + f"src = {state}", pad + f"dst = {arr}"] + [pad + c for c in call]
            else:
                dense += [pad + c for c in lines]
    return "\n".join(L + _ARRAY_STEP_END + dense + _array_output_rest(start_array) + _array_close(plan))


#: Layout of the integer plan of :func:`plan_data`: a header of ``_HEAD``
#: entries, then ``_PER_STAGE`` entries per stage.
_HEAD, _PER_STAGE = 9, 8


def plan_data(tab):
    """The array loop's reading of ``tab`` (:class:`_Plan`) as data:
    ``(pi, pj, pc)``, int64, int64 and float64 arrays.

    ``pj[t]``, ``pc[t]`` are term ``t``: slope ``j`` and its coefficient
    (``a_ij``, ``b_i``: the loop forms ``h * pc[t]`` once per run, as the
    straight-line loop forms ``h a_ij``); a combination is the terms
    ``t0 <= t < t1``, in ``rk_step``'s order (``j`` ascending, zero
    coefficients left out). ``pi`` holds ``ns``, partitioned, the FSAL pair
    (``i0, i_last``; -1 when none), the dense output's start stage (-1 when
    none) and the new state's position and velocity term ranges; then per
    stage: evaluated, velocity first, its position and velocity term ranges,
    the term of its diagonal velocity coefficient (-1 when none) and whether
    it copies its velocity into its slope before calling the force."""
    plan = _Plan(tab)
    ns = plan.ns
    pj, pc = [], []

    def terms(row, upto):
        t0 = len(pj)
        for j in range(upto):
            if row[j] != 0.0:
                pj.append(j)
                pc.append(float(row[j]))
        return t0, len(pj)

    head = [ns, int(plan.partitioned), plan.fsal[0] if plan.fsal else -1, plan.fsal[1] if plan.fsal else -1,
            -1 if plan.start is None else plan.start]
    if plan.partitioned:
        head += [*terms(plan.b, ns), *terms(plan.b_v, ns)]
    else:
        head += [*terms(plan.b, ns), 0, 0]
    stages = []
    for i in range(ns):
        ev = plan.evaluate[i]
        if not plan.partitioned:
            q = terms(plan.A[i], i)
            stages += [int(ev), 0, *q, 0, 0, -1, 0]
        elif plan.v_first[i]:
            v = terms(plan.A_v[i], i)
            q = terms(plan.A[i], i + 1)
            stages += [int(ev), 1, *q, *v, -1, int(plan.A[i, i] != 0.0 or not ev)]
        else:  # position first; the velocity's own term (a_v ii != 0) after the force
            q = terms(plan.A[i], i)
            v = terms(plan.A_v[i], i)
            diag = len(pj)  # a_v ii != 0: not velocity first
            pj.append(i)
            pc.append(float(plan.A_v[i, i]))
            stages += [int(ev), 0, *q, *v, diag, 1]
    pi = np.array(head + stages, dtype=np.int64)
    assert pi.shape[0] == _HEAD + _PER_STAGE * ns
    return pi, np.array(pj, dtype=np.int64), np.array(pc, dtype=float)


def as_data_source(kern, inline_comb: bool = False) -> str:
    """Python source of the array loop of force kernel ``kern`` (any size),
    for any tableau: the method is data (:func:`plan_data`), not text, so one
    compiled loop serves every method on one force structure.
    ``integrate(pi, pj, pc, fp, ip, mass, w, y0, t0, step, n, idx, theta, ys,
    bound, pending, y_fail) -> (n_done, n_out, status, n_extra)``.

    The arithmetic is :func:`source`'s: ``h a_ij`` and ``h b_i`` formed
    once (``step * coefficient``), each combination ``y + (h a_i0) k_0 +
    ...`` summed left to right over the nonzero terms (one pass per term,
    ``out = y + c k_j`` then ``out = out + c k_j``: the same roundings),
    the same stages evaluated and reused, the new state with the instability
    test, the state arrays swapped instead of copied; the same numbers bit
    for bit. The force is called at one place in the step (numba inlines a
    chain's fused slope there), so the compile does not grow with the
    number of stages. ``inline_comb``: numba inlines the combination
    helper at each of its seven calls (else LLVM decides)."""
    L = [
        "# Generated by rk4h.fast.codegen: an array loop, the method as data; do not edit.",
        f"# depends on: {_dependencies_digest()}",
    ] + _HEADER + _rhs_lines(kern) + [
        "@njit(inline=\"always\", error_model=\"numpy\")" if inline_comb else "@njit(error_model=\"numpy\")",
        "def comb(out, y, k, pj, hc, t0, t1, lo, hi):",
        "    # out[lo:hi] = y + hc[t0] k[pj[t0]] + ... left to right",
        "    if t1 == t0:",
        "        for p in range(lo, hi):",
        "            out[p] = y[p]",
        "        return",
        "    c = hc[t0]",
        "    j = pj[t0]",
        "    for p in range(lo, hi):",
        "        out[p] = y[p] + c * k[j, p]",
        "    for t in range(t0 + 1, t1):",
        "        c = hc[t]",
        "        j = pj[t]",
        "        for p in range(lo, hi):",
        "            out[p] = out[p] + c * k[j, p]",
        "",
        "",
        "@njit(error_model=\"numpy\", nogil=True)",
        "def integrate(pi, pj, pc, fp, ip, mass, w, y_start, t0, step, n, idx, theta, ys, bound, pending, y_fail):",
        "    dim = y_start.shape[0]",
        "    nq = dim // 2",
        "    ns = pi[0]",
        "    part = pi[1] != 0",
        "    i0 = pi[2]",
        "    i_last = pi[3]",
        "    start = pi[4]",
        "    k = np.empty((ns, dim))",
        "    yi = np.empty(dim)",
        "    f0 = np.empty((1, dim))",
        "    f1 = np.empty((1, dim))",
        "    y = y_start.copy()",
        "    y_new = np.empty(dim)",
        "    hc = np.empty(pc.shape[0])",
        "    for t in range(pc.shape[0]):",
        "        hc[t] = step * pc[t]",
        "    if i0 >= 0:  # the first step's evaluation of the reused stage, at y_start",
        "        rhs(fp, ip, mass, y, k, i0, nq, w)",
        "    qhi = nq if part else dim",
    ] + _ARRAY_OUTPUT_START + [
        f"        for s in range(ns):",
        f"            b = {_HEAD} + {_PER_STAGE} * s",
        "            ev = pi[b] != 0",
        "            if not part:  # a classical method: one pass over the whole state",
        "                if ev:",
        "                    comb(yi, y, k, pj, hc, pi[b + 2], pi[b + 3], 0, dim)",
        "            elif pi[b + 1] != 0:  # V_s from earlier accelerations, then Q_s (which may use V_s)",
        "                comb(yi, y, k, pj, hc, pi[b + 4], pi[b + 5], nq, dim)",
        "                if pi[b + 7] != 0:  # q' = v: the stage's velocity (rhs writes it when called)",
        "                    for p in range(nq):",
        "                        k[s, p] = yi[nq + p]",
        "                if ev:",
        "                    comb(yi, y, k, pj, hc, pi[b + 2], pi[b + 3], 0, nq)",
        "            else:  # Q_s first, its acceleration, then V_s with it",
        "                comb(yi, y, k, pj, hc, pi[b + 2], pi[b + 3], 0, nq)",
        "                comb(yi, y, k, pj, hc, pi[b + 4], pi[b + 5], nq, dim)",
        "            if ev:",
        "                rhs(fp, ip, mass, yi, k, s, nq, w)",
        "            if part and pi[b + 1] == 0:",
        "                c = hc[pi[b + 6]]",
        "                for p in range(nq, dim):",
        "                    yi[p] = yi[p] + c * k[s, p]",
        "                for p in range(nq):",
        "                    k[s, p] = yi[nq + p]",
        "        comb(y_new, y, k, pj, hc, pi[5], pi[6], 0, qhi)",
        "        if part:",
        "            comb(y_new, y, k, pj, hc, pi[7], pi[8], nq, dim)",
        "        # the instability test NOT(|y_p| <= bound_p), without a short circuit",
        "        accept = True",
        "        for p in range(dim):",
        "            accept &= abs(y_new[p]) <= bound[p]",
    ] + _ARRAY_STEP_END + [
        "                    for e in range(2):",
        "                        # from the stages when the method has them, else one force call each",
        "                        src = y if e == 0 else y_new",
        "                        dst = f0 if e == 0 else f1",
        "                        r = start if e == 0 else (i_last if i0 >= 0 else -1)",
        "                        if r < 0:",
        "                            rhs(fp, ip, mass, src, dst, 0, nq, w)",
        "                            n_extra += 1",
        "                        elif not part:",
        "                            for p in range(dim):",
        "                                dst[0, p] = k[r, p]",
        "                        else:",
        "                            for p in range(nq):",
        "                                dst[0, p] = src[nq + p]",
        "                                dst[0, nq + p] = k[r, nq + p]",
    ] + _array_output_rest("f0") + [
        "        if i0 >= 0:  # first same as last: the next step's stage i0 is this step's last",
        "            for p in range(nq if part else 0, dim):",
        "                k[i0, p] = k[i_last, p]",
        "        y, y_new = y_new, y",
        "    return n, ptr, K.STATUS_OK, n_extra",
        "",
    ]
    return "\n".join(L)
