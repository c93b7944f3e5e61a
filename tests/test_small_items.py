"""Small hostile-pass items: a --scene name too long for the filesystem, the
RHS count of a command method whose program is not installed, and a ``fun``
returning an array holding None."""
import math

import numpy as np
import pytest

import rk4h
from rk4h.validation import advise
from rk4h.validation.run_all import main as run_all
from rk4h.validation.scenes import scene_from_dict


@pytest.mark.parametrize("name", ["a" * 300, "a" * 300 + ".toml", "a" * 150 + "@" + "b" * 150,
                                  "x" * 5000], ids=["name", "file", "point", "5000"])
def test_a_scene_name_too_long_is_one_line_exit_2(name, tmp_path, capsys):
    out = tmp_path / "out"
    assert run_all(["--scene", name, "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err and len(err.strip().splitlines()) == 1 and "field `file`" in err, err
    assert not out.exists()
    assert advise.main([name, "--target", "1e-3"]) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err and len(err.strip().splitlines()) == 1 and "field `file`" in err, err


def test_an_unavailable_command_method_shows_no_rhs_count():
    from rk4h.references.solvers.command import run_command_method
    from rk4h.validation import execute as X
    from rk4h.validation import measure as M
    from rk4h.validation import plan as P

    doc = {"name": "unavail", "model": "chain", "params": {"masses": [1.0], "springs": [1.0, 1.0]},
           "initial": {"x": [0.01]},
           "methods": {"prog": {"command": ["no-such-program-rk4h", "{problem}", "{trajectory}"], "order": 4,
                                "nfev_per_step": 4}},
           "run": {"t_end": 1.0, "h": [0.1], "solvers": ["rk4", "prog"], "outputs": ["state", "work_precision"]}}
    scene = scene_from_dict(doc)
    run = run_command_method("prog", ["no-such-program-rk4h", "{problem}", "{trajectory}"], scene.build_model(),
                             scene.y0(), scene.t_eval(), 0.1, nfev_per_step=4)
    assert run.status.value == "unavailable" and run.nfev == 0 and run.extra["nfev_source"] == "not run"
    specs = P.plan(scene, figures=False)
    records = {s.key: X.execute(scene, s) for s in specs}
    res = M.measure(scene, specs, records, figures=False)
    for table in ("accuracy", "work_precision"):
        rows = {r["solver"]: r for r in res.tables[table]}
        assert rows["prog"]["status"] == "unavailable" and math.isnan(rows["prog"]["nfev"]), rows["prog"]
        assert rows["rk4"]["nfev"] == 40  # 10 steps of 4 evaluations: counted as before


@pytest.mark.parametrize("value", [np.array([None]), [None], np.array([None, 1.0], dtype=object)[:1],
                                   np.array(["1.5"], dtype=object)], ids=["array", "list", "slice", "string"])
def test_fun_returning_none_inside_an_array_is_a_value_error(value):
    with pytest.raises(ValueError, match=r"`fun` returned an array holding .* at t = 0\.0; expected an array"):
        rk4h.solve(lambda t, y: value, (0.0, 1.0), [1.0], h=0.1)
    # numbers in an object array are still numbers
    res = rk4h.solve(lambda t, y: np.array([1.0], dtype=object), (0.0, 1.0), [0.0], h=0.1)
    assert res.status == 0 and res.y[0, -1] == pytest.approx(1.0)
