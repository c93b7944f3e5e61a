"""Outputs as units (rk4h.validation.outputs): the registry is discovered from the
package's modules, the schema, the defaults, the scene reference and the
report's tables are derived from it, a new output registered from one file
runs through the pipeline, and the ``trajectory`` output's netCDF file holds
the runs' arrays."""
import ast
import importlib.util
import json
import re
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from rk4h.validation import columns, execute, outputs, plan, run_all, scene_schema, tables
from rk4h.validation.scenes import load_scene_points

from _scenes import one_mass

REPO = Path(__file__).resolve().parent.parent
PACKAGE = REPO / "validation" / "outputs"


def _module_outputs() -> dict:
    """output name -> module file, read from the package's source (not the registry)."""
    found = {}
    for path in sorted(PACKAGE.glob("*.py")):
        if path.name.startswith("_"):
            continue
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.keyword) and node.arg == "name" and isinstance(node.value, ast.Constant):
                found[node.value.value] = path.name
                break
    return found


def test_the_registry_is_the_package_modules():
    mods = _module_outputs()
    assert len(mods) >= 12 and "trajectory" in mods
    assert set(outputs.names()) == set(mods)
    assert list(outputs.names()) == sorted(outputs.names(), key=lambda n: outputs.get(n).rank)


def test_the_schema_and_reference_come_from_the_registry():
    schema = scene_schema.json_schema()
    enums = []

    def walk(x):
        if isinstance(x, dict):
            if x.get("enum") and "state" in x["enum"]:
                enums.append(x["enum"])
            for v in x.values():
                walk(v)
        elif isinstance(x, list):
            for v in x:
                walk(v)

    walk(schema)
    assert enums and all(e == list(outputs.names()) for e in enums)
    ref = scene_schema.reference_markdown()
    for name, o in outputs.OUTPUTS.items():
        assert f"| `{name}` | {o.when} | {o.what} |" in ref


def test_every_table_belongs_to_an_output_or_the_scene():
    owned = set(outputs.table_names()) | set(tables.SCENE_TABLES)
    assert set(tables.COLUMNS) == owned
    assert set(tables._BUILTIN) == owned - {t for t in owned if outputs.own_table(t) is not None}
    for name in owned:
        assert columns.table_columns(name)  # every column declared (strict)
        assert tables.DESCRIPTIONS.get(name), name


def test_a_model_output_that_applies_is_a_default():
    from rk4h.validation.scenes import default_outputs
    import rk4h

    chain = rk4h.make_model("chain", {"masses": [1.0, 1.0, 1.0], "springs": [2.0] * 4})
    facts = outputs.ModelFacts(chain)
    assert default_outputs(chain) == [n for n, o in outputs.OUTPUTS.items() if o.applies(facts)]
    assert "trajectory" not in default_outputs(chain) and "thesis_code" not in default_outputs(chain)


def test_register_refuses_a_duplicate_and_a_non_output():
    with pytest.raises(ValueError, match="already registered"):
        outputs.register(outputs.get("state"))
    with pytest.raises(TypeError):
        outputs.register("state")


# -- a new output in one file -------------------------------------------------------------
def _docs_example() -> str:
    """The one-file output of docs/outputs.md (so the example there is what runs here)."""
    text = (REPO / "docs" / "outputs.md").read_text(encoding="utf-8")
    blocks = re.findall(r"```python\n(.*?)```", text, re.S)
    return next(b for b in blocks if "OUTPUT = register(" in b)


NEW_OUTPUT = _docs_example()


@pytest.fixture
def new_output(tmp_path):
    path = tmp_path / "initial_energy.py"
    path.write_text(NEW_OUTPUT, encoding="utf-8")
    spec = importlib.util.spec_from_file_location("initial_energy_output", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    yield module.OUTPUT
    outputs.unregister("initial_energy")
    assert "initial_energy" not in tables.COLUMNS and "initial_energy" not in outputs.names()


def _scene(tmp_path, name, outs, **kw):
    path = tmp_path / f"{name}.toml"
    path.write_text(one_mass(name, outputs=json.dumps(outs), **kw), encoding="utf-8")
    return path


def test_a_new_output_in_one_file_runs_through_the_pipeline(tmp_path, new_output):
    assert "initial_energy" in outputs.names()
    assert "initial_energy" in json.dumps(scene_schema.json_schema())
    assert "initial_energy" in scene_schema.reference_markdown()
    scene = load_scene_points(_scene(tmp_path, "new-output", ["state", "initial_energy"]))[0]
    assert [s.purpose for s in plan.plan(scene, figures=False)].count("initial_energy") == 1
    out = tmp_path / "out"
    out.mkdir()
    _, failures = run_all.run([scene], out, repeats=1, figures=False, workers=1)
    assert not failures, failures
    df = pd.read_csv(out / "initial_energy.csv")
    # one mass, x0 = 0.01 m between two springs of 2 N/m: E = (2 + 2) x0^2 / 2
    assert df["energy_j"].tolist() == pytest.approx([0.5 * 4.0 * 0.01 ** 2], rel=1e-12)
    described = json.loads((out / "columns.json").read_text())["tables"]["initial_energy"]
    assert [c["name"] for c in described["columns"]] == ["scene", "energy_j"]
    assert described["columns"][1]["unit"] == "J"
    assert "initial_energy.csv" in (out / "index.md").read_text()


def test_an_unknown_output_is_still_refused(tmp_path):
    from rk4h.validation.scenes import SceneError

    with pytest.raises(SceneError) as info:
        load_scene_points(_scene(tmp_path, "unknown", ["state", "initial_energy"]))
    assert info.value.field == "run.outputs[1]" and "'initial_energy'" in str(info.value)


# -- trajectory: netCDF through xarray ------------------------------------------------------
def test_trajectory_netcdf_holds_the_records_arrays(tmp_path):
    xr = pytest.importorskip("xarray")
    scene = load_scene_points(_scene(tmp_path, "traj", ["state", "trajectory"], t_end=1.0,
                                     solvers='["rk4", "dop853"]'))[0]
    out = tmp_path / "out"
    out.mkdir()
    _, failures = run_all.run([scene], out, repeats=1, figures=False, workers=1)
    assert not failures, failures
    path = out / "trajectory-traj.nc"
    listed = pd.read_csv(out / "trajectory.csv")
    assert set(listed["file"]) == {path.name}
    runs = [s for s in plan.plan(scene, figures=False) if s.purpose == "run"]
    assert len(runs) == len(listed) == 4
    with xr.open_dataset(path, engine="scipy") as ds:
        assert ds.attrs["scene"] == "traj" and "energy: J" in ds.attrs["units"]
        assert ds["time"].attrs["units"] == "s" and ds["energy"].attrs["units"] == "J"
        assert ds.sizes["run"] == 4 and ds.sizes["component"] == 2
        assert [str(c) for c in ds["component"].values] == ["x1", "dx1/dt"]
        for i, spec in enumerate(runs):
            rec = execute.execute(scene, spec)  # the run again: fixed steps and DOP853 repeat exactly
            one = ds.isel(run=i)
            assert str(one["solver"].values) == spec.solver
            assert float(one["setting"]) == spec.setting
            if spec.solver == "rk4":
                assert float(one["h"]) == spec.setting and np.isnan(float(one["rtol"]))
            else:
                assert float(one["rtol"]) == spec.setting and np.isnan(float(one["h"]))
            np.testing.assert_array_equal(ds["time"].values, rec.arrays["trajectory_t"])
            np.testing.assert_array_equal(one["y"].values, rec.arrays["trajectory_y"].T)
            np.testing.assert_array_equal(one["energy"].values, rec.arrays["trajectory_energy"])
        # energy is the model's: (k1 + k2) x^2 / 2 + m v^2 / 2 of the state read back
        y = ds["y"].values[0]
        np.testing.assert_allclose(ds["energy"].values[0], 2.0 * y[:, 0] ** 2 + 0.5 * y[:, 1] ** 2, rtol=1e-12)


def test_no_trajectory_is_kept_unless_asked():
    scene = next(s for s in load_scene_points(REPO / "validation/scenes/thesis_2dof_case1.toml"))
    assert "trajectory" not in scene.outputs
    assert all("trajectory" not in s.keep for s in plan.plan(scene) if s.purpose == "run")


def test_the_wave_packet_spec_names_the_method_that_integrates_it():
    """The packet is integrated by RK4 (rk4h.references.wavepacket, the
    registry's UNDER_TEST) whatever the scene lists first: its spec, so its
    record and its row, name that method, not another."""
    from rk4h.references.registry import UNDER_TEST
    from rk4h.validation.scenes import scene_from_dict

    doc = {"name": "lattice", "model": "chain", "params": {"masses": 1.0, "springs": 1.0, "n": 4},
           "initial": {"x": [0.01, 0.0, 0.0, 0.0]},
           "run": {"t_end": 1.0, "h": [0.1], "tolerances": [1e-6], "solvers": ["stormer-verlet", "dop853"],
                   "outputs": ["dispersion"]}}
    packets = [s for s in plan.plan(scene_from_dict(doc, "lattice.toml"), figures=False) if s.purpose == "packet"]
    assert packets and {s.solver for s in packets} == {UNDER_TEST}
