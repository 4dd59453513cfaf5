"""`dualarm compare` on a real Ray cluster on this machine: a head and a second node started
with `ray start`, the second on its own loopback address. The second node's raylet is killed
(SIGKILL) while it trains runs; the sweep must finish, every run identical to a local run
of the same seeds (wall time aside), none lost, none logged twice."""

from __future__ import annotations

import os
import secrets
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import pytest
import yaml

pytest.importorskip("ray")
pytestmark = pytest.mark.slow(minutes=1)      # the sweep; the other test takes seconds

from dualarm.cli.main import main  # noqa: E402

EPISODES = 150
CONFIG = {"extends": "paper", "num_envs": 2, "eval_every": 50, "eval_episodes": 2, "checkpoint_every": 10,
          "algo": {"hidden": [32, 32], "batch_size": 32, "warmup_steps": 0, "buffer_size": 5000},
          "task": {"max_episode_steps": 20}}
SECOND_NODE_IP = "127.0.0.2"


def rows(path: Path) -> list[list[str]]:
    """A CSV's rows without its wall-time column."""
    lines = [line.split(",") for line in path.read_text().splitlines()]
    drop = lines[0].index("wall_time_s")
    return [r[:drop] + r[drop + 1:] for r in lines]


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def ray_processes(marker: str) -> list[int]:
    """Pids of processes whose command line contains ``marker``."""
    pids = []
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit() or int(entry.name) == os.getpid():
            continue
        try:
            args = (entry / "cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace")
        except OSError:
            continue
        if marker in args:
            pids.append(int(entry.name))
    return pids


@pytest.fixture
def cluster():
    """(address, environment) of a two-node cluster; torn down by killing its processes only
    (`ray stop` would stop every Ray instance of the user)."""
    ray = shutil.which("ray") or str(Path(sys.executable).parent / "ray")
    port = free_port()
    env = {**os.environ, "RAY_AUTH_MODE": "token", "RAY_AUTH_TOKEN": secrets.token_hex(32),
           "RAY_USAGE_STATS_ENABLED": "0"}
    temp = tempfile.mkdtemp(prefix="rt", dir="/tmp")        # short: Ray's socket paths must fit
    try:
        subprocess.run([ray, "start", "--head", f"--port={port}", "--num-cpus=1", "--include-dashboard=false",
                        f"--temp-dir={temp}", "--disable-usage-stats"], env=env, check=True,
                       capture_output=True, timeout=180)
        subprocess.run([ray, "start", f"--address=127.0.0.1:{port}", f"--node-ip-address={SECOND_NODE_IP}",
                        "--num-cpus=2", "--disable-usage-stats"], env=env, check=True,
                       capture_output=True, timeout=180)
        yield f"127.0.0.1:{port}", env
    finally:
        for pid in set(ray_processes(f":{port}")) | set(ray_processes(temp)):
            try:
                os.kill(pid, signal.SIGKILL)
            except OSError:
                pass
        shutil.rmtree(temp, ignore_errors=True)


def second_raylet() -> int:
    pids = [p for p in ray_processes(f"node_ip_address={SECOND_NODE_IP}") if "raylet/raylet" in
            Path(f"/proc/{p}/cmdline").read_bytes().decode(errors="replace")]
    assert len(pids) == 1, pids
    return pids[0]


def parent(pid: int) -> int:
    try:
        return int(Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[1])
    except (OSError, IndexError, ValueError):
        return 0


def trains_under(run: Path, ancestor: int) -> bool:
    """Whether the process holding the run's lock descends from process ``ancestor``."""
    try:
        pid = int((run / ".lock").read_text().split("pid ", 1)[1].split()[0])
    except (OSError, IndexError, ValueError):
        return False
    while pid > 1:
        if pid == ancestor:
            return True
        pid = parent(pid)
    return False


def logged(run: Path) -> int:
    metrics = run / "metrics.csv"
    return max(0, len(metrics.read_text().splitlines()) - 1) if metrics.exists() else 0


def test_a_sweep_survives_losing_a_node(cluster, tmp_path):
    address, env = cluster
    config = tmp_path / "tiny.yaml"
    config.write_text(yaml.safe_dump(CONFIG))
    grid = ["--conditions", "none,multi", "--seeds", "0,1", "--episodes", str(EPISODES),
            "--config", str(config), "--poll", "0.2"]
    assert main(["compare", *grid, "--workers", "2", "-o", str(tmp_path / "local")]) == 0

    out = tmp_path / "ray"
    log = (tmp_path / "ray.log").open("w")
    sweep = subprocess.Popen([sys.executable, "-m", "dualarm.cli.main", "compare", "--backend", "ray",
                              "--ray-address", address, *grid, "-o", str(out)],
                             env=env, stdout=log, stderr=subprocess.STDOUT)
    # 4 runs on 3 CPUs (1 on the head, 2 on the second node). Once the second node's workers
    # (its raylet's children) hold runs that have logged episodes, kill its raylet.
    deadline = time.monotonic() + 900
    raylet = second_raylet()
    while True:
        assert sweep.poll() is None and time.monotonic() < deadline, (tmp_path / "ray.log").read_text()
        runs = sorted((out / "runs").glob("*")) if (out / "runs").exists() else []
        there = [r.name for r in runs if 0 < logged(r) < EPISODES and trains_under(r, raylet)]
        if len(there) >= 2 or (there and time.monotonic() > deadline - 600):
            os.kill(raylet, signal.SIGKILL)
            break
        time.sleep(0.1)
    assert sweep.wait(timeout=900) == 0, (tmp_path / "ray.log").read_text()
    text = (tmp_path / "ray.log").read_text()
    assert "FAILED" not in text and text.count(f"done, {EPISODES} episodes") == 4, text
    assert "the node it was running on is dead" in text, text       # Ray retried the lost runs
    for name in ("none-seed0", "none-seed1", "multi-seed0", "multi-seed1"):
        mine, local = out / "runs" / name, tmp_path / "local" / "runs" / name
        episodes = [int(r[0]) for r in rows(mine / "metrics.csv")[1:]]
        assert episodes == list(range(1, EPISODES + 1)), name      # none lost, none twice
        assert rows(mine / "metrics.csv") == rows(local / "metrics.csv"), name
        assert rows(mine / "eval.csv") == rows(local / "eval.csv"), name
        assert yaml.safe_load((mine / "done.yaml").read_text())["episodes"] == EPISODES


def test_an_address_that_is_not_a_ray_cluster_fails_fast_and_writes_nothing(tmp_path):
    """Something answers at the address, but not Ray: one line within 15 s, nothing written."""
    with socket.socket() as server:
        server.bind(("127.0.0.1", 0))
        server.listen()
        port = server.getsockname()[1]
        out = tmp_path / "cmp"
        start = time.monotonic()
        done = subprocess.run([sys.executable, "-m", "dualarm.cli.main", "compare", "--backend", "ray",
                               "--ray-address", f"127.0.0.1:{port}", "--conditions", "none", "--seeds", "0",
                               "--episodes", "1", "-o", str(out)], capture_output=True, text=True, timeout=120)
        took = time.monotonic() - start
    assert done.returncode == 2, done.stderr
    assert took < 15, took
    assert len(done.stderr.strip().splitlines()) == 1 and "--ray-address" in done.stderr
    assert not out.exists()
