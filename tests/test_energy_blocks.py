"""A long trajectory's energies are evaluated in blocks of columns
(rk4h.energy.motion_energies): the result equals one call on the whole array to
the bit, in either memory layout, for every kind of model; a model whose energy
is not one number per state is refused, not broadcast."""
import numpy as np
import pytest

import rk4h.energy as EN
from rk4h.validation.execute import problem
from rk4h.validation.scenes import load_scene

#: Scenes of every model kind the energy runs meet: linear chains of 3 and 100 masses, an
#: FPUT chain, the planar network, a symbolic potential, pendulums, a triangle, CO2 and a
#: first-order ODE.
SCENES = ("three_blocks", "lattice100", "energy_fput", "planar4_case1", "energy_henon_heiles", "pendulums_beats",
          "triangle", "co2", "lotka_volterra")


def _trajectory(model, y0, m, seed):
    """``m`` states near ``y0`` (shape (2n, m), C order), a random walk."""
    rng = np.random.default_rng(seed)
    y0 = np.asarray(y0, float)
    scale = np.maximum(np.abs(y0), 1e-3)[:, None]
    return y0[:, None] + scale * 0.1 * np.cumsum(rng.standard_normal((y0.size, m)), axis=1) / np.sqrt(m)


@pytest.mark.parametrize("name", SCENES)
@pytest.mark.parametrize("order", ["C", "F"])
def test_blocks_equal_one_call_to_the_bit(name, order, monkeypatch):
    from pathlib import Path

    scene = load_scene(Path(__file__).resolve().parent.parent / "validation" / "scenes" / f"{name}.toml")
    model, y0 = problem(scene)
    y = np.asarray(_trajectory(model, y0, 5003, seed=len(name)), order=order)
    whole = EN.motion_energies(model, y)  # 5003 columns: one block at the default size
    monkeypatch.setattr(EN, "BLOCK_BYTES", 8 * y.shape[0] * 300)  # 300 columns a block: 17 blocks
    calls = []
    real = EN._motion_energies
    monkeypatch.setattr(EN, "_motion_energies", lambda *a: calls.append(a[1].shape[1]) or real(*a))
    blocked = EN.motion_energies(model, y)
    assert len(calls) == 17 and sum(calls) == 5003
    assert blocked.shape == whole.shape == (5003,)
    assert np.array_equal(blocked, whole)
    assert np.array_equal(EN.relative_energy_error(model, y),
                          (whole - whole[0]) / EN._scale(whole[0]))


def test_block_width_has_a_floor_and_single_states_pass_through(monkeypatch):
    from pathlib import Path

    scene = load_scene(Path(__file__).resolve().parent.parent / "validation" / "scenes" / "three_blocks.toml")
    model, y0 = problem(scene)
    monkeypatch.setattr(EN, "BLOCK_BYTES", 1)  # 256 columns, never fewer
    calls = []
    real = EN._motion_energies
    monkeypatch.setattr(EN, "_motion_energies", lambda *a: calls.append(a[1].shape) or real(*a))
    y = _trajectory(model, y0, 600, seed=1)
    EN.motion_energies(model, y)
    assert [c[1] for c in calls] == [256, 256, 88]
    calls.clear()
    e = EN.motion_energies(model, np.asarray(y0, float))
    assert calls == [(len(y0),)] and np.ndim(e) == 0


class _OneNumber:
    """A model whose energy of many states is one number (a user's mistake)."""
    n_dof = 1
    first_order = False

    def potential(self, q):
        return 0.0

    def energy(self, y):
        return float(np.sum(np.asarray(y) ** 2))


def test_an_energy_that_is_not_one_per_state_is_refused(monkeypatch):
    monkeypatch.setattr(EN, "BLOCK_BYTES", 1)
    with pytest.raises(ValueError, match=r"_OneNumber.energy of 2 x 256 states returned shape \(\)"):
        EN.motion_energies(_OneNumber(), np.ones((2, 1000)))
