"""What the batch outputs (``ensemble``, ``stability_map``,
``amplitude_ensemble``) share: their records, a failed one as a failed check."""
from __future__ import annotations


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
