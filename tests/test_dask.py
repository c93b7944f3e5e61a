"""The same plan on a real Dask cluster: a scheduler and two workers started as
separate processes on 127.0.0.1 give the deterministic columns of a local run,
bit for bit."""
import importlib.util
import os
import shutil
import socket
import subprocess
import sys
import time
from pathlib import Path

import pandas as pd
import pytest

from rk4h.validation.plan import code_digest
from rk4h.validation.trust import TIMING_COLUMNS as TRUST_TIMING

from _scenes import one_mass

# found, not imported: importing distributed here (about 1 s) would cost every worker that collects this file
if importlib.util.find_spec("distributed") is None:
    pytest.skip("could not import 'distributed': the cluster extra is not installed", allow_module_level=True)

REPO = Path(__file__).resolve().parent.parent
TIMING_COLUMNS = {"wall_s", "compile_s", "wall_min", "wall_max"} | TRUST_TIMING


def _free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _env(path=REPO):
    return {**os.environ, "PYTHONPATH": str(path) + os.pathsep + os.environ.get("PYTHONPATH", ""),
            "MPLBACKEND": "Agg"}


class _Cluster:
    """A Dask scheduler on 127.0.0.1 and the workers added to it, each a
    separate process; ``close()`` ends them all."""

    def __init__(self, tmp_path):
        self.tmp, self.port = tmp_path, _free_port()
        self.address = f"tcp://127.0.0.1:{self.port}"
        self.procs, self.logs = [], []
        self._start("scheduler", [sys.executable, "-m", "distributed.cli.dask_scheduler", "--host", "127.0.0.1",
                                  "--port", str(self.port), "--no-dashboard"], REPO)

    def _start(self, name, cmd, code):
        self.logs.append(open(self.tmp / f"{name}.log", "w"))
        self.procs.append(subprocess.Popen(cmd, cwd=code, env=_env(code), stdout=self.logs[-1],
                                           stderr=subprocess.STDOUT))
        return self.procs[-1]

    def add_worker(self, extra=(), code=REPO):
        """Start a worker importing the packages from ``code`` (a directory)."""
        i = len(self.procs)
        return self._start(f"w{i}", [sys.executable, "-m", "distributed.cli.dask_worker", self.address,
                                     "--nthreads", "1", "--nworkers", "1", "--no-dashboard", "--host", "127.0.0.1",
                                     "--local-directory", str(self.tmp / f"w{i}"), *extra], code)

    def wait(self, n_workers):
        """The workers' addresses, once the scheduler has ``n_workers``."""
        from distributed import Client

        deadline = time.monotonic() + 90
        while True:
            try:
                with Client(self.address, timeout="5s") as c:
                    workers = c.scheduler_info(n_workers=-1)["workers"]
                    if len(workers) == n_workers:
                        return sorted(workers)
            except OSError:
                pass
            if time.monotonic() > deadline:
                pytest.fail("the Dask cluster did not start: " + (self.tmp / "scheduler.log").read_text()[-2000:])
            time.sleep(0.5)

    def close(self):
        for p in self.procs[::-1]:
            p.terminate()
        for p in self.procs:
            try:
                p.wait(timeout=3)  # a worker's graceful close waits for its nanny: not what is tested
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait(timeout=20)
        for f in self.logs:
            f.close()


@pytest.fixture
def cluster(tmp_path):
    c = _Cluster(tmp_path)
    try:
        c.add_worker(["--resources", "timing=1"])
        c.add_worker()
        c.wait(2)
        yield c.address
    finally:
        c.close()


def _drop_timing(df):
    return df[[c for c in df.columns if c not in TIMING_COLUMNS]]


@pytest.mark.slow
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


@pytest.mark.process
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


@pytest.mark.process
def test_bad_scheduler_address_is_exit_2(tmp_path):
    p = tmp_path / "s.toml"
    p.write_text(one_mass("dask-bad"))
    r = subprocess.run([sys.executable, "validation/run_all.py", "--scene", str(p), "--out", str(tmp_path / "o"),
                        "--scheduler", "not an address"], cwd=REPO, capture_output=True, text=True, timeout=120)
    assert r.returncode == 2 and "--scheduler" in r.stderr and r.stderr.count("\n") == 1


#: RK4H_SCHEDULER_TIMEOUT of the tests below (s): a run that has reached
#: the scheduler ends within it + 10 s (counted from that contact: the
#: imports and planning before it take a loaded test machine ~10 s alone)
TIMEOUT = 2.0


def _contacts(log: Path, since: float) -> list:
    """When (``time.time()``) the scheduler logging to ``log`` received a
    client after ``since``."""
    from datetime import datetime

    out = []
    for line in log.read_text().splitlines():
        if "Receive client connection" in line:
            t = datetime.strptime(line[:23], "%Y-%m-%d %H:%M:%S,%f").timestamp()
            if t >= since:
                out.append(t)
    return out


def _run_all(scene, out, address, **popen):
    cmd = [sys.executable, "validation/run_all.py", "--scene", str(scene), "--out", str(out), "--repeats", "1",
           "--no-figures", "--scheduler", address]
    env = {**os.environ, "MPLBACKEND": "Agg", "RK4H_SCHEDULER_TIMEOUT": f"{TIMEOUT:g}"}
    if popen:
        return subprocess.Popen(cmd, cwd=REPO, env=env, text=True, **popen)
    r = subprocess.run(cmd, cwd=REPO, env=env, capture_output=True, text=True, timeout=120)
    return r, time.time()


@pytest.mark.process
def test_an_endpoint_that_accepts_and_never_answers_is_exit_3_within_the_timeout(tmp_path):
    import threading

    scene = tmp_path / "s.toml"
    scene.write_text(one_mass("dask-silent"))
    server = socket.socket()
    server.bind(("127.0.0.1", 0))
    server.listen(16)
    accepted = []

    def accept():
        try:
            while True:
                accepted.append((server.accept()[0], time.time()))  # held open, never read or written
        except OSError:
            pass

    threading.Thread(target=accept, daemon=True).start()
    try:
        r, end = _run_all(scene, tmp_path / "o", f"tcp://127.0.0.1:{server.getsockname()[1]}")
    finally:
        server.close()
        for conn, _ in accepted:
            conn.close()
    assert accepted, "run_all never connected"
    assert r.returncode == 3, r.stderr
    assert end - accepted[0][1] < TIMEOUT + 10, end - accepted[0][1]
    assert r.stderr.count("\n") == 1 and "cannot reach the Dask scheduler" in r.stderr, r.stderr
    assert not (tmp_path / "o").exists()


@pytest.mark.process
def test_a_scheduler_without_workers_is_exit_3_within_the_timeout(tmp_path):
    scene = tmp_path / "s.toml"
    scene.write_text(one_mass("dask-empty"))
    c = _Cluster(tmp_path)
    try:
        c.wait(0)
        start = time.time()
        r, end = _run_all(scene, tmp_path / "o", c.address)
    finally:
        c.close()
    assert r.returncode == 3, r.stderr
    [contact] = _contacts(tmp_path / "scheduler.log", start)
    assert end - contact < TIMEOUT + 10, end - contact
    assert r.stderr.count("\n") == 1 and "has no workers" in r.stderr, r.stderr
    assert not (tmp_path / "o").exists()


@pytest.mark.slow
def test_a_worker_running_other_code_is_refused_and_named(tmp_path):
    """A worker importing a copy of the packages with one file changed (as a
    worker with rk4 swapped for the 3/8 rule would) reports another code
    digest: alone, the run ends with exit 3 naming it; beside a worker with
    this code, it is refused and named, and the run uses the other one."""
    other = tmp_path / "other"
    # the installed layout: rk4core/ is rk4h/, holding references/ and validation/
    for pkg, dest in (("rk4core", "rk4h"), ("references", "rk4h/references"), ("validation", "rk4h/validation")):
        shutil.copytree(REPO / pkg, other / dest, ignore=shutil.ignore_patterns("__pycache__"))
    with open(other / "rk4h" / "__init__.py", "a") as f:
        f.write("# another version of the code\n")
    scene = tmp_path / "s.toml"
    scene.write_text(one_mass("dask-digest"))
    c = _Cluster(tmp_path)
    try:
        c.add_worker(code=other)
        [bad] = c.wait(1)
        start = time.time()
        r, end = _run_all(scene, tmp_path / "o", c.address)
        assert r.returncode == 3, r.stderr
        [contact] = _contacts(tmp_path / "scheduler.log", start)
        assert end - contact < 2 * TIMEOUT + 10, end - contact  # the code check has a timeout of its own
        assert f"Dask worker {bad} refused: it runs other code" in r.stderr, r.stderr
        assert "no worker of the Dask scheduler" in r.stderr and bad in r.stderr.splitlines()[-1], r.stderr
        assert not (tmp_path / "o").exists()
        c.add_worker()
        assert bad in c.wait(2)
        r, _ = _run_all(scene, tmp_path / "o", c.address)
    finally:
        c.close()
    assert r.returncode == 0, r.stderr
    assert r.stderr.splitlines() == [f"run_all: Dask worker {bad} refused: it runs other code: code digest "
                                     f"{r.stderr.split('code digest ')[1].split(',')[0]}, ours "
                                     f"'{code_digest()}'"], r.stderr
    assert "all expectations held" in r.stdout


@pytest.mark.slow
@pytest.mark.parametrize("how", ["killed", "frozen"])
def test_a_scheduler_lost_mid_run_is_exit_3_with_the_records_kept_and_the_report_untouched(tmp_path, how):
    """The scheduler is killed (kill -9) or frozen (SIGSTOP: it still
    accepts connections, and answers nothing) after the first record."""
    import signal

    scene = tmp_path / "s.toml"
    scene.write_text(one_mass("dask-lost", t_end=60.0, h="[0.1, 0.05, 0.02, 0.01, 0.005]",
                              tolerances="[1e-6, 1e-8, 1e-10]", solvers='["rk4", "dop853", "cvode-adams"]',
                              outputs='["state", "work_precision", "convergence"]'))
    out = tmp_path / "o"
    prev = subprocess.run([sys.executable, "validation/run_all.py", "--scene", str(scene), "--out", str(out),
                           "--repeats", "1", "--no-figures", "--workers", "1"], cwd=REPO, capture_output=True,
                          text=True, timeout=300, env={**os.environ, "MPLBACKEND": "Agg"})
    assert prev.returncode == 0, prev.stderr
    before = {p.name: p.read_bytes() for p in out.iterdir()}
    c = _Cluster(tmp_path)
    try:
        c.add_worker()
        c.wait(1)
        p = _run_all(scene, out, c.address, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
        first = p.stdout.readline()
        assert first.startswith("[1/"), first + p.stderr.read()
        c.procs[0].send_signal(signal.SIGKILL if how == "killed" else signal.SIGSTOP)  # the scheduler
        t0 = time.monotonic()
        stdout, stderr = p.communicate(timeout=120)
        seconds = time.monotonic() - t0
    finally:
        if p.poll() is None:
            p.kill()
        c.procs[0].send_signal(signal.SIGCONT)
        c.close()
    assert p.returncode == 3, stderr
    # no record for TIMEOUT s: the scheduler is asked, and has TIMEOUT s (+ 1) to answer
    assert seconds < 2 * TIMEOUT + 1 + 10, seconds
    print(f"scheduler {how}: exit 3 after {seconds:.1f} s")
    assert "Cancelled" not in stdout + stderr and "Traceback" not in stderr, stderr
    assert "the Dask scheduler" in stderr and "rerun with --resume" in stderr, stderr
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before
    assert any((tmp_path / f".{out.name}.records").glob("*.json"))
