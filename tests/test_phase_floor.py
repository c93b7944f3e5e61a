"""The phase error's bar (``energy_time.PHASE_RESOLVED_AMPLITUDE``) sits
above round-off: on shipped scenes where RK4 damps a mode away, a mode's
measured angle is on RK4's exact lag (1e-6 rad) at every amplitude down to
well below the bar, so no mode the bar keeps carries round-off.
``benchmarks/phase_floor.py`` prints the same figures."""
import pathlib
import subprocess
import sys

import numpy as np
import pytest

from rk4h.validation import energy_time as et

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))

import phase_floor  # noqa: E402

pytest.importorskip("numba")


@pytest.mark.parametrize("scene", ["co2", "thesis-2dof-case2"])
def test_modes_leave_rk4s_lag_only_far_below_the_bar(scene):
    m = phase_floor.measure(scene, 0.1)
    off = np.abs(m["angle"] - m["lag"]) > phase_floor.TOL
    assert off.any()  # the case exercises the bar: a mode is damped into round-off
    first = np.argmax(off, axis=1)
    for k in np.where(off.any(axis=1))[0]:
        # a mode leaves its lag only at amplitudes at least 10x below the bar
        assert m["amplitude"][k, first[k]] < 0.1 * et.PHASE_RESOLVED_AMPLITUDE, (scene, k)
    np.testing.assert_allclose(m["angle"][~off.any(axis=1)], m["lag"][~off.any(axis=1)], atol=phase_floor.TOL)


def test_bad_case_exits_2_with_one_line():
    proc = subprocess.run([sys.executable, str(ROOT / "benchmarks" / "phase_floor.py"), "co2:h"], cwd=ROOT,
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2 and "H must be a step" in proc.stderr and "Traceback" not in proc.stderr
