"""The three extensions a user makes, together: a new output (one file, its
``register``), a new model (one file, its ``register_model``) and a new
method (one ``[methods.NAME]`` table in the scene), and one scene that uses
all three runs through the pipeline with no other edit."""
import importlib.util
import math
import re
from pathlib import Path

import pandas as pd
import pytest

from rk4h.models import MODELS, register_model
from rk4h.validation import outputs, tables
from rk4h.validation.run_all import main
from test_model_declarations import MORSE_FILE

REPO = Path(__file__).resolve().parent.parent

#: The new model, one file: a particle in a Morse well V = D (1 - exp(-a x))^2 (test_model_declarations' file
#: under its own name, so that both tests can register it).
MODEL_FILE = MORSE_FILE.replace('name = "morse-test"', 'name = "morse-extension"')
assert MODEL_FILE != MORSE_FILE


#: The scene: the new model, the new method (the 3/8 rule, one table) and the new output.
SCENE = '''
name = "extension"
model = "morse-extension"
[params]
m = 1.0
D = 2.0
a = 1.5
[initial]
x = [0.2]
[methods.rk38-extension]
c = ["0", "1/3", "2/3", "1"]
A = [["0","0","0","0"], ["1/3","0","0","0"], ["-1/3","1","0","0"], ["1","-1","1","0"]]
b = ["1/8", "3/8", "3/8", "1/8"]
[run]
t_end = 4.0
h = [0.04, 0.02]
tolerances = [1e-8]
solvers = ["rk38-extension", "dop853"]
outputs = ["state", "initial_energy"]
'''


def _load(path: Path, name: str):
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.fixture
def extended(tmp_path):
    """The output of docs/outputs.md and the model above, each from its own
    file and registered by one call; both unregistered afterwards."""
    text = (REPO / "docs" / "outputs.md").read_text(encoding="utf-8")
    example = next(b for b in re.findall(r"```python\n(.*?)```", text, re.S) if "OUTPUT = register(" in b)
    (tmp_path / "initial_energy.py").write_text(example, encoding="utf-8")
    (tmp_path / "morse_extension.py").write_text(MODEL_FILE, encoding="utf-8")
    try:
        _load(tmp_path / "initial_energy.py", "initial_energy_extension")
        register_model(_load(tmp_path / "morse_extension.py", "morse_extension").Morse)
        yield tmp_path
    finally:
        outputs.unregister("initial_energy")
        MODELS.pop("morse-extension", None)
    assert "initial_energy" not in outputs.names() and "initial_energy" not in tables.COLUMNS


def test_a_new_output_model_and_method_run_one_scene(extended, capsys):
    scene = extended / "extension.toml"
    scene.write_text(SCENE, encoding="utf-8")
    out = extended / "out"
    rc = main(["--scene", str(scene), "--out", str(out), "--repeats", "1", "--no-figures", "--workers", "1"])
    assert rc == 0, capsys.readouterr()
    # the output: its table, with the new model's energy at t = 0 (v = 0: the potential at x = 0.2 m)
    energy = pd.read_csv(out / "initial_energy.csv")
    assert energy["scene"].tolist() == ["extension"]
    assert energy["energy_j"].tolist() == pytest.approx([2.0 * (1.0 - math.exp(-1.5 * 0.2)) ** 2], rel=1e-12)
    # the method on the model: measured against the reference, fourth order (halving h: error / ~16)
    acc = pd.read_csv(out / "accuracy.csv")
    assert set(acc["scene"]) == {"extension"} and set(acc["status"]) == {"ok"}
    rk38 = acc[acc.solver == "rk38-extension"].set_index("setting")["error_max"]
    assert sorted(rk38.index) == [0.02, 0.04]
    assert 12 < rk38[0.04] / rk38[0.02] < 20
    assert "initial_energy.csv" in (out / "index.md").read_text(encoding="utf-8")


def test_without_the_registrations_the_scene_is_refused(tmp_path, capsys):
    """The scene above needs the output and the model registered: without
    them it is bad input (exit 2), so the test above did use them."""
    scene = tmp_path / "extension.toml"
    scene.write_text(SCENE, encoding="utf-8")
    assert "initial_energy" not in outputs.names() and "morse-extension" not in MODELS
    rc = main(["--scene", str(scene), "--out", str(tmp_path / "out"), "--repeats", "1", "--no-figures",
               "--workers", "1"])
    assert rc == 2
    err = capsys.readouterr().err
    assert "`run.outputs[1]`" in err and "initial_energy" in err and len(err.splitlines()) == 1
