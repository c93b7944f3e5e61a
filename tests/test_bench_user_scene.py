"""benchmarks/bench_user_scene.py: the scene it times is the README's own scene, as the
scene loader reads it; its arguments are checked. Timings are not asserted."""
import pathlib
import subprocess
import sys

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))

import bench_user_scene  # noqa: E402


def test_the_timed_scene_is_the_readme_chain_with_default_outputs(tmp_path):
    from rk4h.validation.scenes import load_scene

    text = bench_user_scene.readme_scene()
    assert text in (ROOT / "README.md").read_text(encoding="utf-8")
    path = tmp_path / "my_chain.toml"
    path.write_text(text, encoding="utf-8")
    scene = load_scene(path)
    assert scene.model == "chain" and len(scene.params["masses"]) == 3
    assert "outputs" not in text  # the default outputs: every one that applies


def test_zero_rounds_is_refused_in_one_line():
    proc = subprocess.run([sys.executable, str(ROOT / "benchmarks" / "bench_user_scene.py"), "--rounds", "0"],
                          capture_output=True, text=True, timeout=60)
    assert proc.returncode == 2 and "--rounds: must be at least 1, got 0" in proc.stderr


def test_the_uniform_benchmark_scene_loads_with_the_wave_packets():
    from rk4h.validation.scenes import load_scene

    scene = load_scene(ROOT / "benchmarks" / "scenes" / "uniform_chain3.toml")
    assert scene.model == "chain" and len(set(scene.params["masses"])) == 1
    assert "dispersion" in scene.outputs  # a default output here: the chain is uniform
