"""The context of the timed runs: the machine's load while they ran.

Wall times measured on a loaded machine are slower and noisier than the
repeats of one run can show (a rerun under load average 6-9 on 2 cores read
the large-N fit as N^1.48 where an unloaded run read N^1.09, and about 20
time-verdict cells changed). So a report records the load average
(:func:`os.getloadavg`: processes running or waiting for a CPU, averaged over
1, 5 and 15 minutes, machine-wide) and the machine's CPU count just before and
just after its timed runs (:func:`snapshot`, taken by
:mod:`rk4h.validation.engine`), and when the load exceeded the CPUs at either
moment every time verdict between two measured sides is a tie
(:func:`gate_time_verdicts`) and index.md says why (:func:`sentence`,
:func:`environment_lines`). A verdict with one measured side names that side
whatever the load (the other has no run that meets the target: no speed is
compared), and an unmeasured one stays unmeasured.

The load includes the report's own worker processes (at most ``--workers``
of them, one per timed run); a load above the CPU count means some process
waited for a CPU, so a timing may hold time spent waiting. Under Dask the load
is that of the machine running ``run_all.py``, not of the workers. Nothing here
reads or decides timings themselves.
"""
from __future__ import annotations

import math
import os
import time

__all__ = ["snapshot", "load_context", "is_loaded", "gate_time_verdicts", "context_text", "sentence",
           "environment_lines", "findings",
           "TIME_VERDICT_COLUMNS"]

#: The time-verdict columns of ``cheapest.csv`` (rk4h.validation.trust).
TIME_VERDICT_COLUMNS = ("verdict_amortized", "verdict_one_run")


def snapshot() -> dict:
    """``{"load": (1, 5, 15 min) or None, "cpus": os.cpu_count(), "t": time.time()}``;
    ``load`` is None where the platform has no load average."""
    try:
        load = tuple(float(x) for x in os.getloadavg())
    except (AttributeError, OSError):
        load = None
    return {"load": load, "cpus": os.cpu_count() or 1, "t": time.time()}


def load_context(before, after, *, executed_timed: int = 0, resumed_timed: int = 0, where: str = "") -> dict | None:
    """The timing context of a report from the :func:`snapshot` taken before
    and after its timed runs (either None when not taken).

    Returns None when no timed run was executed and none resumed (nothing
    to qualify); else a dict with ``before``, ``after`` (the snapshots),
    ``cpus``, ``executed_timed``, ``resumed_timed``, ``peak`` (the largest
    1-minute load of the two, NaN when unknown), ``loaded`` (``peak >
    cpus``), ``known`` (both loads recorded and no timed record resumed from
    an earlier run, whose load is not known) and ``where``."""
    if not executed_timed and not resumed_timed:
        return None
    snaps = [s for s in (before, after) if s]
    cpus = max((s["cpus"] for s in snaps), default=os.cpu_count() or 1)
    loads = [s["load"][0] for s in snaps if s.get("load")]
    peak = max(loads) if loads else math.nan
    return {"before": before, "after": after, "cpus": cpus, "executed_timed": int(executed_timed),
            "resumed_timed": int(resumed_timed), "peak": peak, "loaded": bool(loads) and peak > cpus,
            "known": len(loads) == 2 and not resumed_timed, "where": where}


def is_loaded(ctx) -> bool:
    """Whether the timed runs ran with the load above the CPU count."""
    return bool(ctx and ctx.get("loaded"))


def _reason(ctx) -> str:
    return (f"load average {ctx['peak']:.2f} exceeded the {ctx['cpus']} CPUs during the timed runs "
            f"(timings include waiting for a CPU)")


def gate_time_verdicts(rows, ctx) -> list[dict]:
    """``cheapest.csv`` rows with their timing context in ``time_context``
    (a timing column: the loads and CPUs, :func:`context_text`) and, when
    the timed runs ran under load (:func:`is_loaded`), every time verdict of
    a row whose two sides were both measured (``confirmed`` and
    ``alt_confirmed``) :data:`rk4h.validation.trust.TIE`, the reason in
    ``time_context``. A row with one measured side keeps its verdicts: they
    name the only side with a run at the target, not the faster one. The
    RHS-call verdict is deterministic and kept, and so is ``note``.
    Returns new dicts; ``ctx`` None (no timed run) leaves the rows as they
    are."""
    from .trust import TIE, is_confirmed

    rows = [dict(r) for r in (rows or [])]
    if ctx is None:
        return rows
    text = context_text(ctx)
    for r in rows:
        if any(c in r for c in TIME_VERDICT_COLUMNS):
            if is_loaded(ctx) and is_confirmed(r.get("confirmed")) and is_confirmed(r.get("alt_confirmed")):
                for c in TIME_VERDICT_COLUMNS:
                    if c in r:
                        r[c] = TIE
            r["time_context"] = text
    return rows


def context_text(ctx) -> str:
    """The context in one cell: ``"load 1.20 -> 1.50 (1 min, before -> after
    the timed runs) on 2 CPUs"``, and when loaded ``"; time verdicts are
    ties: load average 6.30 exceeded the 2 CPUs ..."``."""
    text = f"load {_fmt1(ctx['before'])} -> {_fmt1(ctx['after'])} (1 min, before -> after the timed runs) " \
           f"on {ctx['cpus']} CPUs"
    if ctx["resumed_timed"]:
        text += f"; {ctx['resumed_timed']} timed record(s) resumed, load not known"
    if is_loaded(ctx):
        text += f"; time verdicts between two measured sides are ties: {_reason(ctx)}"
    return text


def findings(ctx) -> list[str]:
    """A finding for index.md when the timed runs ran under load: the time
    verdicts are ties and the timed fits (the large-N time slopes, the
    cost sweeps' wall times) are no evidence of speed; empty otherwise."""
    if not is_loaded(ctx):
        return []
    return [f"Timed under load: {_reason(ctx)}; every time verdict between two measured sides is `tie`, and "
            f"the wall times and the fits "
            f"made from them (large-N time per step ~ N^p, the cost sweeps' time panels) describe this load, "
            f"not the methods."]


def _fmt(snap) -> str:
    if not snap or not snap.get("load"):
        return "not recorded"
    return ", ".join(f"{x:.2f}" for x in snap["load"])


def sentence(ctx) -> str:
    """One sentence for index.md's header: the load around the timed runs and
    what it means for the time verdicts."""
    if ctx is None:
        return "No timed run was executed or resumed, so no timing context applies."
    bits = [f"Load average (1 min) {_fmt1(ctx['before'])} before the timed runs and {_fmt1(ctx['after'])} "
            f"after them, on {ctx['cpus']} CPUs{(' (' + ctx['where'] + ')') if ctx['where'] else ''}"]
    if ctx["resumed_timed"]:
        bits.append(f"{ctx['resumed_timed']} timed record(s) were resumed from an earlier run, whose load is not "
                    f"known")
    if is_loaded(ctx):
        bits.append(f"the load exceeded the CPUs, so the runs waited for CPUs: every time verdict between two "
                    f"measured sides is `tie` and the timings and time fits (wall_s, the large-N time slopes) are "
                    f"not evidence of speed")
    elif not ctx["known"]:
        bits.append("the load during every timed run is not known: read the time verdicts with that in mind")
    return "; ".join(bits) + "."


def _fmt1(snap) -> str:
    if not snap or not snap.get("load"):
        return "(not recorded)"
    return f"{snap['load'][0]:.2f}"


def environment_lines(ctx) -> list[str]:
    """Lines for index.md's environment section."""
    if ctx is None:
        return ["- load average: not recorded (no timed run)"]
    return [f"- load average (1, 5, 15 min) before the timed runs: {_fmt(ctx['before'])}; after: "
            f"{_fmt(ctx['after'])}",
            f"- CPUs: {ctx['cpus']} (os.cpu_count); timed runs executed {ctx['executed_timed']}, resumed "
            f"{ctx['resumed_timed']}; time verdicts: "
            + ("ties (load above the CPUs)" if is_loaded(ctx) else "as measured (load within the CPUs)"
               if ctx["known"] else "as measured, load not known for every timed run")]
