"""benchmarks/_child.py: the timing of one child process that four benchmarks share."""
import importlib.util
import pathlib
import sys

ROOT = pathlib.Path(__file__).resolve().parents[1]


def _child():
    spec = importlib.util.spec_from_file_location("_bench_child", ROOT / "benchmarks" / "_child.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_timed_run_counts_the_childs_cpu_and_keeps_its_output():
    busy = "import time\nt = time.process_time()\nwhile time.process_time() - t < 0.3: pass\nprint('done')"
    proc, wall, cpu, load = _child().timed_run([sys.executable, "-c", busy])
    assert proc.returncode == 0 and proc.stdout == "done\n"
    assert cpu >= 0.3 and wall >= 0.3 and load >= 0.0


def test_timed_run_passes_its_keywords_on(tmp_path):
    proc, *_ = _child().timed_run([sys.executable, "-c", "import os; print(os.getcwd())"], cwd=tmp_path)
    assert pathlib.Path(proc.stdout.strip()).resolve() == tmp_path.resolve()
