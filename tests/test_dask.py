"""The same plan on a real Dask cluster: a scheduler and two workers started as
separate processes on 127.0.0.1 give the deterministic columns of a local run,
bit for bit."""
import os
import socket
import subprocess
import sys
import time
from pathlib import Path

import pandas as pd
import pytest

from validation.trust import TIMING_COLUMNS as TRUST_TIMING

from _scenes import one_mass

pytest.importorskip("distributed")

REPO = Path(__file__).resolve().parent.parent
TIMING_COLUMNS = {"wall_s", "compile_s", "wall_min", "wall_max"} | TRUST_TIMING


def _free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.fixture
def cluster(tmp_path):
    port = _free_port()
    env = {**os.environ, "PYTHONPATH": str(REPO) + os.pathsep + os.environ.get("PYTHONPATH", ""),
           "MPLBACKEND": "Agg"}
    dask = [sys.executable, "-m", "distributed.cli.dask_scheduler"]
    worker = [sys.executable, "-m", "distributed.cli.dask_worker"]
    address = f"tcp://127.0.0.1:{port}"
    logs = [open(tmp_path / f"{n}.log", "w") for n in ("scheduler", "w1", "w2")]
    procs = [subprocess.Popen(dask + ["--host", "127.0.0.1", "--port", str(port), "--no-dashboard"],
                              cwd=REPO, env=env, stdout=logs[0], stderr=subprocess.STDOUT)]
    for i, extra in enumerate((["--resources", "timing=1"], [])):
        procs.append(subprocess.Popen(worker + [address, "--nthreads", "1", "--nworkers", "1", "--no-dashboard",
                                                "--host", "127.0.0.1", "--local-directory", str(tmp_path / f"w{i}")]
                                      + extra, cwd=REPO, env=env, stdout=logs[i + 1], stderr=subprocess.STDOUT))
    try:
        from distributed import Client

        deadline = time.monotonic() + 90
        while True:
            try:
                with Client(address, timeout="5s") as c:
                    if len(c.scheduler_info()["workers"]) == 2:
                        break
            except OSError:
                pass
            if time.monotonic() > deadline:
                pytest.fail("the Dask cluster did not start: " + (tmp_path / "scheduler.log").read_text()[-2000:])
            time.sleep(0.5)
        yield address
    finally:
        for p in procs[::-1]:
            p.terminate()
        for p in procs:
            try:
                p.wait(timeout=3)  # a worker's graceful close waits for its nanny: not what is tested
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait(timeout=20)
        for f in logs:
            f.close()



def _drop_timing(df):
    return df[[c for c in df.columns if c not in TIMING_COLUMNS]]


def test_scheduler_run_equals_local_run(cluster, tmp_path):
    scenes = []
    for i, extra in enumerate(('["state", "energy", "work_precision", "convergence", "modes"]',
                               '["state", "work_precision", "modes"]')):
        p = tmp_path / f"s{i}.toml"
        p.write_text(one_mass(f"dask-{i}", t_end=5.0 + i, h="[0.1, 0.05, 0.02]", tolerances="[1e-6, 1e-9]",
                              solvers='["rk4", "dop853", "cvode-adams"]', outputs=extra))
        scenes += ["--scene", str(p)]
    env = {**os.environ, "MPLBACKEND": "Agg"}
    common = [sys.executable, "validation/run_all.py", *scenes, "--no-figures", "--repeats", "1"]
    remote = subprocess.run(common + ["--out", str(tmp_path / "remote"), "--scheduler", cluster], cwd=REPO,
                            env=env, capture_output=True, text=True, timeout=300)
    assert remote.returncode == 0, remote.stderr
    assert "Dask at" in remote.stdout
    local = subprocess.run(common + ["--out", str(tmp_path / "local"), "--workers", "1"], cwd=REPO, env=env,
                           capture_output=True, text=True, timeout=300)
    assert local.returncode == 0, local.stderr
    a, b = (tmp_path / "remote"), (tmp_path / "local")
    names = sorted(p.name for p in a.glob("*.csv"))
    assert names == sorted(p.name for p in b.glob("*.csv")) and "accuracy.csv" in names
    for name in names:
        pd.testing.assert_frame_equal(_drop_timing(pd.read_csv(a / name)), _drop_timing(pd.read_csv(b / name)),
                                      check_exact=True, obj=name)


def test_unreachable_scheduler_is_one_line_exit_3(tmp_path):
    p = tmp_path / "s.toml"
    p.write_text(one_mass("dask-none"))
    port = _free_port()
    r = subprocess.run([sys.executable, "validation/run_all.py", "--scene", str(p), "--out", str(tmp_path / "o"),
                        "--scheduler", f"tcp://127.0.0.1:{port}"], cwd=REPO, capture_output=True, text=True,
                       timeout=120, env={**os.environ, "RK4H_SCHEDULER_TIMEOUT": "2"})
    assert r.returncode == 3, r.stderr
    assert r.stderr.count("\n") == 1 and "Dask scheduler" in r.stderr
    assert not (tmp_path / "o").exists()


def test_bad_scheduler_address_is_exit_2(tmp_path):
    p = tmp_path / "s.toml"
    p.write_text(one_mass("dask-bad"))
    r = subprocess.run([sys.executable, "validation/run_all.py", "--scene", str(p), "--out", str(tmp_path / "o"),
                        "--scheduler", "not an address"], cwd=REPO, capture_output=True, text=True, timeout=120)
    assert r.returncode == 2 and "--scheduler" in r.stderr and r.stderr.count("\n") == 1
