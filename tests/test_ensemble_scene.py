"""The [ensemble] table drawn into a batch; statistics and the stability-map figure."""
import numpy as np
import pytest

import rk4h
from rk4h.validation.ensemble import draw_instances, error_statistics, stability_map_figure

pytest.importorskip("numba", reason="numba is not installed (the fast extra)")

SPRINGS = [41.5, 138.0, 157.8]


def chain():
    return rk4h.make_model("chain", {"masses": [0.815, 3.099], "springs": SPRINGS})


def test_draws_follow_their_distributions_and_the_seed():
    table = {"size": 4000, "seed": 3,
             "initial.x[0]": {"dist": "uniform", "low": -0.01, "high": 0.01},
             "initial.v[1]": {"dist": "normal", "mean": 0.5, "std": 0.1},
             "params.masses[1]": {"dist": "log-uniform", "low": 0.1, "high": 10.0}}
    y0, params = draw_instances(table, chain(), [0.005, 0.005])
    assert y0.shape == (4000, 4)
    assert (np.abs(y0[:, 0]) <= 0.01).all() and abs(np.mean(y0[:, 0])) < 1e-3
    assert (y0[:, 1] == 0.005).all() and (y0[:, 2] == 0.0).all()
    assert abs(np.mean(y0[:, 3]) - 0.5) < 0.01 and abs(np.std(y0[:, 3]) - 0.1) < 0.01
    m1 = params["masses[1]"]
    assert (m1 >= 0.1).all() and (m1 <= 10.0).all() and abs(np.median(np.log10(m1))) < 0.1
    again, _ = draw_instances(table, chain(), [0.005, 0.005])
    assert np.array_equal(again, y0)
    other, _ = draw_instances({**table, "seed": 4}, chain(), [0.005, 0.005])
    assert not np.array_equal(other, y0)


def test_grid_keys_form_a_product():
    table = {"size": 12, "params.masses[1]": {"dist": "grid", "low": 1.0, "high": 3.0, "n": 3},
             "initial.x[0]": {"dist": "grid", "values": [0.001, 0.002]},
             "params.springs[1]": {"dist": "grid", "low": 100.0, "high": 200.0, "n": 1}}
    y0, params = draw_instances({**table, "size": 6}, chain(), [0.005, 0.005])
    assert list(params["masses[1]"]) == [1.0, 1.0, 2.0, 2.0, 3.0, 3.0]
    assert list(y0[:, 0]) == [0.001, 0.002] * 3
    y0, params = draw_instances(table, chain(), [0.005, 0.005])
    assert y0.shape[0] == 12 and list(params["masses[1]"][6:]) == [1.0, 1.0, 2.0, 2.0, 3.0, 3.0]


@pytest.mark.parametrize("table, field", [
    ({"size": 0, "initial.x[0]": {"dist": "uniform", "low": 0, "high": 1}}, "`ensemble.size`"),
    ({"size": 5, "initial.x[0]": {"dist": "grid", "low": 0, "high": 1, "n": 2}}, "`ensemble.size`"),
    ({"size": 5, "initial.x[0]": {"dist": "cauchy"}}, '`ensemble."initial.x[0]".dist`'),
    ({"size": 5, "initial.x[0]": {"dist": "uniform", "low": 1, "high": 0}}, '`ensemble."initial.x[0]".high`'),
    ({"size": 5, "params.masses[1]": {"dist": "log-uniform", "low": -1, "high": 1}},
     '`ensemble."params.masses[1]".low`'),
    ({"size": 5, "params.walls": {"dist": "uniform", "low": 0, "high": 1}}, "not a numeric parameter"),
    ({"size": 5, "initial.x[2]": {"dist": "uniform", "low": 0, "high": 1}}, "has 2 coordinates"),
    ({"size": 5, "seed": -1, "initial.x[0]": {"dist": "uniform", "low": 0, "high": 1}}, "`ensemble.seed`"),
])
def test_bad_tables_name_the_field(table, field):
    with pytest.raises(ValueError) as e:
        draw_instances(table, chain(), [0.005, 0.005])
    assert field in str(e.value) and "\n" not in str(e.value)


def test_error_statistics_against_the_modal_solution():
    table = {"size": 20, "seed": 1, "initial.x[0]": {"dist": "uniform", "low": -0.01, "high": 0.01},
             "params.masses[1]": {"dist": "log-uniform", "low": 1.0, "high": 4.0}}
    y0, params = draw_instances(table, chain(), [0.005, 0.005])
    stats = {}
    for h in (0.01, 0.005):
        res = rk4h.ensemble(chain(), y0, (0.0, 2.0), h=h, params=params, backend="numba")
        stats[h] = error_statistics(chain(), res, y0, params)
    s = stats[0.01]
    assert s["failed"] == 0
    assert s["error"]["median"] <= s["error"]["p95"] <= s["error"]["max"] < 1e-3
    # RK4 is fourth order: halving h divides the error by about 16
    assert 10 < stats[0.01]["error"]["median"] / stats[0.005]["error"]["median"] < 20
    assert 10 < stats[0.01]["energy_error"]["median"] / stats[0.005]["energy_error"]["median"] < 40


def test_stability_map_figure(tmp_path):
    from rk4h.batch.maps import RK4_IMAGINARY_LIMIT, stability_map

    smap = stability_map(chain(), "masses[1]", [1.0, 3.0], np.linspace(0.05, 0.2, 6), y0=[0.005, -0.003, 0, 0],
                         n_steps=200)
    path = stability_map_figure(smap, tmp_path / "map.png", limit=RK4_IMAGINARY_LIMIT, label="m2 (kg)")
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
