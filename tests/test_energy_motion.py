"""The energy error is relative to the energy of the motion, E_motion = E0 - V(q*):
adding a constant to the potential changes E0 but neither the trajectory nor the
reported energy drift."""
import math

import numpy as np
import pytest

from rk4h.energy import energy_scale, motion_energy, rest_energy
from rk4h.models import Network
from rk4h.validation import execute as X
from rk4h.validation import metrics
from rk4h.validation.plan import plan
from rk4h.validation.scenes import load_scene

DUFFING = """
name = "duffing{tag}"
model = "potential"
[params]
coordinates = ["x"]
masses = 1.0
potential = "{offset}x^2/2 + x^4/4"
[initial]
x = [1.0]
v = [0.0]
[run]
t_end = 20.0
h = [0.2, 0.1]
tolerances = [1e-8]
solvers = ["rk4", "dop853"]
outputs = ["state", "energy"]
"""


@pytest.fixture
def tmp_cache(tmp_path, monkeypatch):
    """An empty truth cache (``tmp_path/cache/truth``): the truths here are
    computed, not read from the user's. Only the truth's: the compiled loops of
    the two potentials keep the user's cache (a fresh ``RK4H_CACHE`` compiled
    both numba loops cold in every run, most of the test's 7 s)."""
    from rk4h.references import truth as T

    real = T.cache_dir
    fresh = tmp_path / "cache" / "truth"
    monkeypatch.setattr(T, "cache_dir", lambda path=None: real(path if path is not None else fresh))
    return tmp_path / "cache"


def _records(tmp_path, offset, tag):
    path = tmp_path / f"duffing{tag}.toml"
    path.write_text(DUFFING.format(offset=offset, tag=tag))
    scene = load_scene(path)
    X.clear_problems()
    runs = [s for s in plan(scene) if s.purpose == "run"]
    return scene, {(s.solver, s.setting): X.execute(scene, s).values for s in runs}


def test_energy_drift_is_invariant_when_a_constant_is_added_to_the_potential(tmp_path, tmp_cache):
    scene0, plain = _records(tmp_path, "", "")
    scene1, shifted = _records(tmp_path, "1000 + ", "-shifted")
    model0, model1 = scene0.build_model(), scene1.build_model()
    assert rest_energy(model0) == 0.0 and rest_energy(model1) == 1000.0
    y0 = np.asarray(scene0.y0(), float)
    assert motion_energy(model0, model0.energy(y0)) == pytest.approx(0.75, rel=1e-15)
    assert motion_energy(model1, model1.energy(y0)) == pytest.approx(0.75, rel=1e-12)
    assert plain.keys() == shifted.keys() and len(plain) == 3
    for key, v in plain.items():
        w = shifted[key]
        # identical trajectories: the errors against the truth are the same numbers
        assert w["error_max"] == v["error_max"], key
        assert v["energy_drift_max"] > 1e-8, key
        assert w["energy_drift_max"] == pytest.approx(v["energy_drift_max"], rel=1e-9, abs=0), key
        assert w["drift_per_time"] == pytest.approx(v["drift_per_time"], rel=1e-9, abs=0), key


def test_pre_tension_is_not_motion():
    # one mass between two walls 2 m apart on springs of rest length 0.5 m: each spring
    # is stretched by 0.5 m at equilibrium and stores k 0.5^2 / 2 J there
    k = 100.0
    net = Network(dim=1, masses=[1.0], positions=[1.0], anchors=[0.0, 2.0],
                  springs=[[0, 1, k, 0.5], [0, 2, k, 0.5]])
    assert rest_energy(net) == pytest.approx(2 * k * 0.25 / 2)
    y0 = np.array([0.01, 0.0])
    E0 = float(net.energy(y0))
    assert energy_scale(net, E0) == pytest.approx(k * 0.01 ** 2, rel=1e-9)  # 2 springs, k x^2 / 2 each
    t = np.linspace(0.0, 2.0, 201)
    from rk4h.references.solvers import integrate

    run = integrate("rk4", net, y0, t, 0.05)
    drift = metrics.energy_drift_max(net, run.y)
    E = net.energy(run.y)
    assert drift == pytest.approx(np.max(np.abs(E - E0)) / (E0 - rest_energy(net)), rel=1e-12)
    assert drift > 100 * np.max(np.abs(E - E0)) / abs(E0)
