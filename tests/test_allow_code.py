"""Code named by a scene runs only when the user says so.

A scene the project does not ship may not start a program (``command``
method) or import a module (``python`` method, ``model = "module:Class"``)
without ``--allow-code`` / ``RK4H_ALLOW_CODE=1`` / ``allow_code=True``; the
refusal comes before anything is imported or started."""
import shutil
import sys

import pytest

from rk4h.models import MODELS
from rk4h.validation import advise
from rk4h.validation.cli import main as rk4h
from rk4h.validation.run_all import main as run_all
from rk4h.validation.scenes import (SCENE_DIR, SceneError, is_shipped, load_scene, load_scenes, scene_from_dict)

BASE = '''
name = "{name}"
model = "{model}"
[params]
masses = [1.0]
springs = [1.0, 1.0]
[initial]
x = [0.01]
[run]
t_end = 1.0
h = [0.1]
solvers = {solvers}
outputs = ["state"]
'''


def _command_scene(tmp_path, sentinel):
    p = tmp_path / "cmd.toml"
    p.write_text(BASE.format(name="cmdtest", model="chain", solvers='["rk4", "fast"]')
                 + f'[methods.fast]\ncommand = ["sh", "-c", "echo PWNED > {sentinel}; exit 1"]\norder = 4\n')
    return p


def _one_line_refusal(err: str, path, key):
    assert "Traceback" not in err and len(err.strip().splitlines()) == 1, err
    assert str(path) in err and f"field `{key}`" in err and "--allow-code" in err, err


def test_a_command_method_of_a_user_scene_is_refused_without_the_flag(tmp_path, capsys, monkeypatch):
    monkeypatch.delenv("RK4H_ALLOW_CODE", raising=False)
    sentinel = tmp_path / "pwned.txt"
    scene = _command_scene(tmp_path, sentinel)
    out = tmp_path / "out"
    assert run_all(["--scene", str(scene), "--out", str(out), "--workers", "1"]) == 2
    _one_line_refusal(capsys.readouterr().err, scene, "methods.fast.command")
    assert not sentinel.exists() and not out.exists()
    assert advise.main([str(scene), "--target", "1e-3"]) == 2
    _one_line_refusal(capsys.readouterr().err, scene, "methods.fast.command")
    for argv in (["run", "--scene", str(scene), "--out", str(out)], ["advise", str(scene), "--target", "1e-3"]):
        assert rk4h(argv) == 2
        _one_line_refusal(capsys.readouterr().err, scene, "methods.fast.command")
    assert not sentinel.exists() and not out.exists()


def test_a_command_method_runs_with_allow_code(tmp_path, capsys, monkeypatch):
    monkeypatch.delenv("RK4H_ALLOW_CODE", raising=False)
    sentinel = tmp_path / "pwned.txt"
    scene = _command_scene(tmp_path, sentinel)
    rc = run_all(["--scene", str(scene), "--out", str(tmp_path / "out"), "--workers", "1", "--repeats", "1",
                  "--no-figures", "--allow-code"])
    assert rc in (0, 1), capsys.readouterr()  # the program exits 1: a failed row, not bad input
    assert sentinel.read_text().strip() == "PWNED"


def test_the_environment_variable_allows_code(tmp_path, monkeypatch):
    sentinel = tmp_path / "pwned.txt"
    scene = _command_scene(tmp_path, sentinel)
    monkeypatch.setenv("RK4H_ALLOW_CODE", "1")
    assert load_scene(scene).method("fast").argv[0] == "sh"
    monkeypatch.setenv("RK4H_ALLOW_CODE", "0")
    with pytest.raises(SceneError) as e:
        load_scene(scene)
    assert e.value.field == "methods.fast.command"
    monkeypatch.setenv("RK4H_ALLOW_CODE", "yes")
    with pytest.raises(SceneError) as e:
        load_scene(scene)
    assert e.value.field == "RK4H_ALLOW_CODE" and "'yes'" in str(e.value)


@pytest.fixture
def evil_modules(tmp_path, monkeypatch):
    """Two modules that write a file when imported: a python stepper and a model."""
    monkeypatch.delenv("RK4H_ALLOW_CODE", raising=False)
    pkg = tmp_path / "mods"
    pkg.mkdir()
    step_sentinel, model_sentinel = tmp_path / "imported-step", tmp_path / "imported-model"
    (pkg / "rk4h_evil_step.py").write_text(
        f"open({str(step_sentinel)!r}, 'w').write('imported')\n"
        "from rk4h.steppers import rk4_step\n")
    (pkg / "rk4h_evil_model.py").write_text(
        f"open({str(model_sentinel)!r}, 'w').write('imported')\n"
        "from rk4h.models import Chain\n"
        "class EvilChain(Chain):\n    name = 'evil-chain-test'\n")
    monkeypatch.syspath_prepend(str(pkg))
    yield step_sentinel, model_sentinel
    for mod in ("rk4h_evil_step", "rk4h_evil_model"):
        sys.modules.pop(mod, None)
    MODELS.pop("evil-chain-test", None)


def _python_scene(tmp_path):
    p = tmp_path / "py.toml"
    p.write_text(BASE.format(name="pytest-step", model="chain", solvers='["rk4", "mine"]')
                 + '[methods.mine]\npython = "rk4h_evil_step:rk4_step"\norder = 4\n')
    return p


def _model_scene(tmp_path):
    p = tmp_path / "model.toml"
    p.write_text(BASE.format(name="pytest-model", model="rk4h_evil_model:EvilChain", solvers='["rk4"]'))
    return p


@pytest.mark.parametrize("kind", ["python", "model"])
def test_a_module_a_user_scene_names_is_never_imported_without_the_flag(kind, tmp_path, evil_modules, capsys):
    step_sentinel, model_sentinel = evil_modules
    scene, module, sentinel, key = {
        "python": (_python_scene(tmp_path), "rk4h_evil_step", step_sentinel, "methods.mine.python"),
        "model": (_model_scene(tmp_path), "rk4h_evil_model", model_sentinel, "model"),
    }[kind]
    with pytest.raises(SceneError) as e:
        load_scene(scene)
    assert e.value.field == key
    with pytest.raises(SceneError):
        load_scenes([scene])
    assert run_all(["--scene", str(scene), "--out", str(tmp_path / "out")]) == 2
    _one_line_refusal(capsys.readouterr().err, scene, key)
    assert advise.main([str(scene), "--target", "1e-3"]) == 2
    _one_line_refusal(capsys.readouterr().err, scene, key)
    assert module not in sys.modules and not sentinel.exists()
    # with the user's word, the same file loads: the module is imported
    loaded = load_scene(scene, allow_code=True)
    assert module in sys.modules and sentinel.read_text() == "imported"
    assert loaded.build_model().n_dof == 1


def test_shipped_scenes_with_code_load_and_a_copy_does_not(tmp_path, monkeypatch):
    monkeypatch.delenv("RK4H_ALLOW_CODE", raising=False)
    for name, key in (("methods_2dof.toml", "python"), ("thesis_code03_case2.toml", "command")):
        shipped = SCENE_DIR / name
        assert is_shipped(shipped) and any(key in t for t in load_scene(shipped).methods.values())
        copy = tmp_path / name
        shutil.copy(shipped, copy)
        assert not is_shipped(copy)
        with pytest.raises(SceneError) as e:
            load_scene(copy)
        assert e.value.field.startswith("methods.") and e.value.field.endswith(f".{key}")
        link = tmp_path / f"link-{name}"
        link.symlink_to(shipped)  # a link to the shipped file is the shipped file
        assert is_shipped(link)
    outside = tmp_path / "outside.toml"
    outside.write_text((SCENE_DIR / "methods_2dof.toml").read_text())
    assert not is_shipped(outside)  # same content, not the shipped file
    assert not is_shipped(SCENE_DIR / "no_such_scene_rk4h.toml")


def test_a_document_built_in_python_is_the_callers_code(tmp_path):
    doc = {"name": "dict-step", "model": "chain", "params": {"masses": [1.0], "springs": [1.0, 1.0]},
           "initial": {"x": [0.01]}, "methods": {"mine": {"python": "rk4h.steppers:rk4_step", "order": 4}},
           "run": {"t_end": 1.0, "h": [0.1], "solvers": ["rk4", "mine"], "outputs": ["state"]}}
    assert scene_from_dict(doc).method("mine").target == "rk4h.steppers:rk4_step"
    with pytest.raises(SceneError) as e:
        scene_from_dict(doc, allow_code=False)
    assert e.value.field == "methods.mine.python"
