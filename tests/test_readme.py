"""The README is what a new user runs: its code blocks run, its scenes load,
its links resolve, and it stays short. The project cites nothing outside the
repository."""
import os
import re
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

from rk4h.validation.scenes import scene_from_dict, scene_points_from_dict

REPO = Path(__file__).resolve().parent.parent
README = REPO / "README.md"


def _blocks(lang):
    """The README's fenced code blocks whose info string is ``lang`` ("" for plain ones)."""
    out, current, info = [], None, None
    for line in README.read_text().splitlines(keepends=True):
        if line.startswith("```"):
            if current is None:
                current, info = [], line[3:].strip()
            else:
                if info == lang:
                    out.append("".join(current))
                current = None
        elif current is not None:
            current.append(line)
    return out


def _env():
    return {**os.environ, "PYTHONPATH": str(REPO), "MPLBACKEND": "Agg"}


def test_readme_is_short_and_opens_with_the_two_commands():
    lines = README.read_text().splitlines()
    assert len(lines) <= 300, f"README has {len(lines)} lines"
    first = "\n".join(lines[:8])
    assert "python validation/run_all.py" in first and "python -m pytest" in first


def test_readme_links_resolve():
    for target in re.findall(r"\]\(([^)#]+)\)", README.read_text()):
        if "://" not in target:
            assert (REPO / target).exists(), target


@pytest.mark.parametrize("i", range(len(_blocks("python"))))
def test_readme_python_blocks_run(i, tmp_path):
    code = _blocks("python")[i]
    proc = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, env=_env(), capture_output=True,
                          text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr[-2000:]


def test_readme_scene_and_fragments_validate():
    docs = [tomllib.loads(b) for b in _blocks("toml")]
    full = [d for d in docs if "name" in d]
    assert full, "the README shows no complete scene"
    base = full[0]
    scene = scene_from_dict(base)
    assert scene.name == base["name"]
    for frag in docs:
        if "methods" in frag:
            doc = {**base, "methods": frag["methods"],
                   "run": {**base["run"], "solvers": base["run"]["solvers"] + list(frag["methods"])}}
            assert set(frag["methods"]) <= set(scene_from_dict(doc).registry)
        if "sweep" in frag:
            points = scene_points_from_dict({**base, "sweep": frag["sweep"]})
            assert len(points) == len(next(iter(frag["sweep"].values())))


def test_readme_advisor_command_runs(capsys):
    cmds = [c for b in _blocks("") for c in b.splitlines() if c.startswith("python validation/advise.py")]
    assert _blocks(""), "no plain code block found"
    assert cmds, "the README shows no advisor command"
    # the command's arguments, run in process (advise.py as a process: tests/test_trust.py)
    from rk4h.validation.advise import main

    python, script, *argv = cmds[0].split()
    assert (python, script) == ("python", "validation/advise.py")
    assert main(argv + ["--json"]) == 0, capsys.readouterr().err[-2000:]
    assert '"method"' in capsys.readouterr().out


def test_nothing_cites_files_outside_the_repository():
    pattern = re.compile(r"DESIGN\.md|\.\./shared")
    hits = []
    for path in REPO.rglob("*"):
        if path.suffix not in {".py", ".md"} or not path.is_file():
            continue
        rel = path.relative_to(REPO)
        if rel.parts[0] in {"reports", ".git"} or rel == Path("tests/test_readme.py"):
            continue
        hits += [f"{rel}:{n}" for n, line in enumerate(path.read_text(errors="replace").splitlines(), 1)
                 if pattern.search(line)]
    assert not hits, hits


def test_readme_python_lotka_volterra_is_the_shipped_scene():
    """The README's Python form of the Lotka-Volterra scene builds the same study: run settings,
    initial state, right-hand side and invariant (the study itself runs in the block test)."""
    import numpy as np

    from rk4h.validation.scenes import SCENE_DIR, load_scene

    block = next(b for b in _blocks("python") if "ode_scene(" in b)
    ns = {}
    exec(block.split("res = study(scene)")[0], ns)  # noqa: S102 - the README's own code
    mine, shipped = ns["scene"], load_scene(SCENE_DIR / "lotka_volterra.toml")
    for field in ("name", "t_end", "h", "tolerances", "solvers", "initial_x"):
        assert getattr(mine, field) == getattr(shipped, field), field
    a, b = mine.build_model(), shipped.build_model()
    assert a.first_order and b.first_order and a.coord_names == b.coord_names
    rng = np.random.default_rng(0)
    for y in rng.uniform(0.2, 5.0, size=(5, 2)):
        np.testing.assert_allclose(a.rhs(0.0, y), b.rhs(0.0, y), rtol=1e-14)
        np.testing.assert_allclose(a.energy(y[:, None]), b.energy(y[:, None]), rtol=1e-14)


def test_readme_own_scene_command_runs(tmp_path, monkeypatch, capsys):
    """The tour's 'your own scene': the README's TOML saved under the name its
    command gives, and that command run (in process, its --out in tmp_path)."""
    from rk4h.validation.run_all import main

    cmds = [c for b in _blocks("") for c in b.splitlines()
            if c.startswith("python validation/run_all.py --scene ") and c.split()[3].endswith(".toml")]
    assert cmds, "the README shows no command running its own scene"
    python, script, *argv = cmds[0].split()
    scene_file = argv[argv.index("--scene") + 1]
    full = [b for b in _blocks("toml") if "name = " in b]
    (tmp_path / scene_file).write_text(full[0], encoding="utf-8")
    argv[argv.index("--out") + 1] = str(tmp_path / "out")
    monkeypatch.chdir(tmp_path)
    assert main(argv) == 0, capsys.readouterr().err[-2000:]
    index = (tmp_path / "out" / "index.md").read_text(encoding="utf-8")
    assert tomllib.loads(full[0])["name"] in index


def test_readme_quick_command_and_count_are_the_code():
    """The tour's quick-run command is one ``run_all.py`` accepts as written
    (its parser, no run), and the number of scenes the README gives for the
    quick set is the number ``--quick`` loads."""
    import shlex

    from rk4h.validation.run_all import _parser
    from rk4h.validation.scenes import load_scenes

    text = README.read_text()
    commands = [line for block in _blocks("") for line in block.splitlines()
                if line.startswith("python validation/run_all.py --quick")]
    assert commands, "the README shows no --quick command"
    for line in commands:
        args = _parser().parse_args(shlex.split(line)[2:])
        assert args.quick and args.out
    said = re.search(r"The quick set \((\d+) scenes\)", text)
    assert said, "the README no longer says how many scenes the quick set has"
    assert int(said.group(1)) == len(load_scenes(None, quick=True))
