"""The phase error's bar (``energy_time.PHASE_RESOLUTION``) sits above
round-off: on shipped scenes where RK4 damps a mode away, a mode's measured
angle leaves RK4's exact lag (by 1e-6 rad) only where its rounding estimate is
well above the bar, so no sample the report reads carries round-off; and an
uncoupled mode, whose angle round-off never reaches, is never cut.
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


@pytest.mark.parametrize("scene", ["co2", "thesis-2dof-case2", "three-blocks"])
def test_modes_leave_rk4s_lag_only_far_above_the_bar(scene):
    m = phase_floor.measure(scene, 0.1)
    off = np.abs(m["angle"] - m["lag"]) > phase_floor.TOL
    assert off.any() and m["unresolved"] >= 1  # the case exercises the bar: a mode is damped into round-off
    assert m["rounding"][off].min() >= 5 * et.PHASE_RESOLUTION
    resolved = np.logical_and.accumulate(m["rounding"] <= et.PHASE_RESOLUTION, axis=1)
    np.testing.assert_allclose(m["angle"][resolved], m["lag"][resolved], atol=phase_floor.TOL)


def test_an_uncoupled_mode_is_never_cut():
    # the anisotropic oscillator's x and y are its modes: RK4 at h = 0.1 s damps
    # the fast one to 1e-135 of the motion, and its angle stays on the lag
    m = phase_floor.measure("oscillator-aniso-2", 0.1)
    np.testing.assert_allclose(m["angle"], m["lag"], atol=phase_floor.TOL)
    assert m["unresolved"] == 0 and m["rounding"].max() <= et.PHASE_RESOLUTION


def test_bad_case_exits_2_with_one_line():
    proc = subprocess.run([sys.executable, str(ROOT / "benchmarks" / "phase_floor.py"), "co2:h"], cwd=ROOT,
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2 and "H must be a step" in proc.stderr and "Traceback" not in proc.stderr
