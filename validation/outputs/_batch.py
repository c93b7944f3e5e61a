"""What the batch outputs (``ensemble``, ``stability_map``,
``amplitude_ensemble``) share: the solvers they run, the words of their
statistics, their records (a failed one as a failed check)."""
from __future__ import annotations

#: Each statistic over a batch's instances: its column suffix and its words.
STAT_WORDS = (("median", "median"), ("p95", "95th percentile"), ("max", "maximum"))


def tableau_solvers(scene) -> list:
    """The scene's fixed-step solvers a batch can run (a tableau or a built-in name)."""
    return [s for s in scene.fixed_solvers if scene.method(s).tableau is not None]


def one_solver(scene) -> str:
    """The method under test (:data:`rk4h.references.registry.UNDER_TEST`)
    when the scene runs it, else its first solver a batch can run (else the
    method under test)."""
    from rk4h.references.registry import UNDER_TEST

    fixed = tableau_solvers(scene)
    return UNDER_TEST if UNDER_TEST in fixed else (fixed[0] if fixed else UNDER_TEST)


def ok_records(m, purpose: str, what):
    """``(spec, record)`` of every spec of ``purpose`` of the scene being
    measured whose record is ok; each other one files a failed check named
    ``what(spec)`` with the line ``SCENE: WHAT: MESSAGE`` and is left out.

    Parameters
    ----------
    m : rk4h.validation.outputs.Measuring
        The measurement in progress (its ``specs``, ``records``, ``res``).
    purpose : str
        The specs' purpose.
    what : str or callable(spec) -> str
        The check's name, also the line's label.
    """
    for spec in m.specs(purpose):
        rec = m.records[spec.key]
        if rec.ok:
            yield spec, rec
            continue
        name = what(spec) if callable(what) else what
        m.res.check(name, False, f"{m.scene.name}: {name}: {rec.message}")
