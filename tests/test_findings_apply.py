"""Findings only where they apply: the FPUT recurrence finding needs a nonlinear
model with at least two modes; thesis figure labels only on the scenes that
reproduce a thesis figure (the scene's `thesis_figures`)."""
import pytest

from rk4h.models import Chain
from rk4h.validation import run_all
from rk4h.validation.measure import recurrence_applies
from rk4h.validation.scenes import SCENE_DIR, load_scenes

CHAIN3 = """
name = "{name}"
model = "chain"
[params]
masses = 1.0
springs = 1.0
n = 3
walls = "both"
alpha = {alpha}
[initial]
x = [0.5, 0.0, 0.0]            # all three modes excited (mode 1 about 73%)
v = [0.0, 0.0, 0.0]
[run]
t_end = 60.0
output_dt = 1.0
h = [0.1]
tolerances = [1e-10]
solvers = ["rk4", "dop853"]    # DOP853's modal shares wander at its error level: a minimum inside the run
outputs = ["modal_energy"]
"""


@pytest.fixture
def tmp_cache(tmp_path, monkeypatch):
    monkeypatch.setenv("RK4H_CACHE", str(tmp_path / "cache"))


def _findings(tmp_path, capsys, name, alpha):
    scene = tmp_path / f"{name}.toml"
    scene.write_text(CHAIN3.format(name=name, alpha=alpha))
    out = tmp_path / name
    rc = run_all.main(["--scene", str(scene), "--out", str(out), "--repeats", "1", "--no-figures", "--workers", "1"])
    cap = capsys.readouterr()
    assert rc == 0, cap.out + cap.err
    index = (out / "index.md").read_text()
    findings = index[index.index("## Main findings"):]
    findings = findings[:findings.index("\n## ", 3)]  # up to the next section (the tables' descriptions)
    return findings, (out / "modal_energy.csv").read_text()


def test_a_linear_chain_has_no_recurrence_finding(tmp_path, tmp_cache, capsys):
    findings, table = _findings(tmp_path, capsys, "linear-chain3", 0.0)
    assert "linear-chain3,rk4" in table and "linear-chain3,dop853" in table  # the table is there, not the finding
    assert "recurrence" not in findings.lower()
    assert "returns to" not in findings


@pytest.mark.slow
def test_a_nonlinear_chain_keeps_its_recurrence_finding(tmp_path, tmp_cache, capsys):
    findings, _ = _findings(tmp_path, capsys, "fput-chain3", 0.5)
    assert "(FPUT recurrence)" in findings


def test_recurrence_applies_to_nonlinear_models_with_two_modes():
    assert not recurrence_applies(Chain(1.0, 1.0, n=3), 3)
    assert recurrence_applies(Chain(1.0, 1.0, n=3, alpha=0.25), 3)
    assert not recurrence_applies(Chain(1.0, 1.0, n=1, beta=1.0), 1)


def test_thesis_figure_labels_only_on_scenes_that_reproduce_them():
    scenes = {s.name: s for s in load_scenes(sorted(SCENE_DIR.glob("*.toml")))}
    labelled = {n for n, s in scenes.items() if s.thesis_figures}
    assert {"thesis-2dof-case1", "planar4-case1", "oscillator-iso-delta0"} <= labelled
    for name in ("co2", "three-blocks", "chain10-mode2", "fput-alpha", "lattice100", "henon-heiles"):
        if name in scenes:
            assert not scenes[name].thesis_figures, name
    assert scenes["thesis-2dof-case3"].thesis_figures == "Figs 4.5-4.6"
