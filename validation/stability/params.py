"""The ``[stability]`` table of a scene: keys, defaults and validation."""
from __future__ import annotations

import math

from rk4core.validate import float_list, positive

__all__ = ["STUDIES", "DEFAULTS", "validate_params"]

STUDIES = ("boundary", "stiffness", "mass_ratio", "long_horizon", "roundoff", "large_n",
           "amplitude", "singular")

#: Every key and its default; ``*_quick`` values replace the plain ones in --quick runs.
DEFAULTS = {
    "studies": None,                      # required: list of STUDIES
    "bisection_rtol": 1e-4,               # relative precision of the boundary bisection
    "growth_theta": [0.25, 0.5, 1.0, 1.5, 1.9, 2.2, 2.6, 2.9, 3.2],
    "target_error": 1e-6,                 # stiffness: error every solver must reach
    "stiffness_ratios": [1.0, 1e2, 1e4, 1e6, 1e8],
    "stiffness_ratios_quick": [1.0, 1e4, 1e8],
    "mu": [1e-6, 1e-4, 1e-2, 1.0, 1e2, 1e4, 1e6],
    "mu_quick": [1e-2, 1.0, 1e2],
    "long_theta": 0.2,                    # omega_max * h of the long RK4 run
    "long_periods": 1e6,                  # periods of the slowest mode
    "long_periods_quick": 1e3,
    "reference_periods": 1e4,             # CVODE / heyoka on the long run (fewer if slow)
    "reference_periods_quick": 1e2,
    "drift_theta": [0.05, 0.1, 0.2, 0.3, 0.4, 0.5],
    "roundoff_theta": [0.5, 0.2, 0.1, 0.05, 0.02, 1e-2, 5e-3, 2e-3, 1e-3, 5e-4, 2e-4],
    "roundoff_theta_quick": [0.5, 0.2, 0.1, 0.05, 0.02, 1e-2, 5e-3, 2e-3, 1e-3],
    "n_values": [3e3, 1e4, 3e4, 1e5],     # fits start above the cache-resident sizes
    "n_values_quick": [3e3, 1e4, 3e4],
    "amplitudes": [1e-6, 1e-5, 1e-4, 1e-3, 1e-2, 3e-2, 0.1, 0.3, 1.0, 2.0, 3.0],
    "singular_offset": 1e-9,              # m: y offset of the mass aimed at the anchor
}

_LISTS = {"growth_theta", "stiffness_ratios", "stiffness_ratios_quick", "mu", "mu_quick",
          "drift_theta", "roundoff_theta", "roundoff_theta_quick", "n_values", "n_values_quick",
          "amplitudes"}


def validate_params(params, where: str = "stability") -> dict:
    """Check a scene's ``[stability]`` table and fill in defaults.

    Raises ``ValueError`` with one line naming the field (``where.key``) and
    the value. Unknown keys and unknown study names are refused.
    """
    if not isinstance(params, dict):
        raise ValueError(f"`{where}` must be a table, got {params!r}")
    unknown = sorted(set(params) - set(DEFAULTS))
    if unknown:
        raise ValueError(f"`{where}.{unknown[0]}` is not a known key (known: {', '.join(DEFAULTS)})")
    if "studies" not in params:
        raise ValueError(f"`{where}.studies` is required (a list out of {list(STUDIES)})")
    out = dict(DEFAULTS)
    studies = params["studies"]
    if isinstance(studies, str) or not isinstance(studies, list) or not studies:
        raise ValueError(f"`{where}.studies` must be a non-empty list, got {studies!r}")
    for s in studies:
        if s not in STUDIES:
            raise ValueError(f"`{where}.studies` entries must be among {list(STUDIES)}, got {s!r}")
    out["studies"] = list(studies)
    for key, value in params.items():
        if key == "studies":
            continue
        name = f"{where}.{key}"
        if key in _LISTS:
            out[key] = float_list(name, value, positive_items=True).tolist()
        else:
            out[key] = positive(name, value)
    if not out["bisection_rtol"] < 0.1:
        raise ValueError(f"`{where}.bisection_rtol` must be < 0.1, got {out['bisection_rtol']!r}")
    if not out["target_error"] < 1:
        raise ValueError(f"`{where}.target_error` must be < 1, got {out['target_error']!r}")
    for key in ("n_values", "n_values_quick"):
        if any(v != math.floor(v) or v < 2 for v in out[key]):
            raise ValueError(f"`{where}.{key}` must hold whole numbers >= 2, got {out[key]!r}")
    return out


def pick(params: dict, key: str, quick: bool):
    """The ``key_quick`` value in quick mode when there is one, else ``key``."""
    return params.get(f"{key}_quick", params[key]) if quick else params[key]
