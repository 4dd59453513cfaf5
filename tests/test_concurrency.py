"""Two writers on one directory, as real processes: one proceeds, the other exits 2 naming
the holder, and the logs stay intact; a killed writer's lock goes with it."""

from __future__ import annotations

import csv
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

TINY = ("extends: paper\nnum_envs: 2\nepisodes: 400\neval_every: 0\ncheckpoint_minutes: 0.01\n"
        "algo: {hidden: [16, 16], batch_size: 16, warmup_steps: 0, buffer_size: 5000}\n"
        "task: {max_episode_steps: 5}\n")


def dualarm(*args: str, cwd: Path) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "dualarm.cli.main", *args], cwd=cwd,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def wait_until_training(run: Path, proc: subprocess.Popen, timeout: float = 120.0) -> None:
    """Until ``proc`` holds the run's lock and has logged an episode."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        metrics = run / "metrics.csv"
        if metrics.exists() and len(metrics.read_text().splitlines()) > 1:
            return
        assert proc.poll() is None, proc.communicate()
        time.sleep(0.2)
    raise AssertionError("the first trainer never started")


def episodes(run: Path) -> list[int]:
    with open(run / "metrics.csv", newline="") as f:
        return [int(r["episode"]) for r in csv.DictReader(f)]


def stop(proc: subprocess.Popen) -> None:
    proc.send_signal(signal.SIGKILL)
    proc.wait(timeout=30)


@pytest.fixture
def folder(tmp_path):
    (tmp_path / "tiny.yaml").write_text(TINY)
    return tmp_path


@pytest.mark.parametrize("second", [
    ("train", "--config", "tiny.yaml", "--condition", "none", "--out", "run"),   # a second trainer
    ("train", "--resume", "run"),                                                # a resume while live
    ("train", "--resume", "run", "--episodes", "500"),
])
def test_a_second_writer_of_a_live_run_exits_2_naming_the_holder(folder, second):
    first = dualarm("train", "--config", "tiny.yaml", "--condition", "none", "--out", "run", cwd=folder)
    try:
        wait_until_training(folder / "run", first)
        config = (folder / "run" / "config.yaml").read_bytes()
        other = dualarm(*second, cwd=folder)
        _, err = other.communicate(timeout=120)
        assert other.returncode == 2, err
        assert f"in use by dualarm train, pid {first.pid}" in err and "Traceback" not in err
        assert (folder / "run" / "config.yaml").read_bytes() == config
        assert first.poll() is None                         # the holder goes on
    finally:
        stop(first)
    # the killed holder released its lock: the run resumes and its log reads 1..N in order
    done = dualarm("train", "--resume", "run", "--episodes", str(max(episodes(folder / "run")) + 4),
                   cwd=folder)
    _, err = done.communicate(timeout=300)
    assert done.returncode == 0, err
    logged = episodes(folder / "run")
    assert logged == list(range(1, len(logged) + 1))


def test_a_second_comparison_of_a_live_one_exits_2(folder):
    args = ("compare", "--conditions", "none", "--seeds", "0", "--episodes", "400", "--config",
            "tiny.yaml", "--workers", "1", "-o", "cmp")
    first = dualarm(*args, cwd=folder)
    try:
        wait_until_training(folder / "cmp" / "runs" / "none-seed0", first)
        other = dualarm(*args, cwd=folder)
        _, err = other.communicate(timeout=120)
        assert other.returncode == 2, err
        assert f"in use by dualarm compare, pid {first.pid}" in err
    finally:
        stop(first)
    # the killed driver's worker goes with it: the run's lock is free and its log stops growing
    from dualarm.locks import DirectoryLock, DirectoryBusy

    run = folder / "cmp" / "runs" / "none-seed0"
    for _ in range(100):
        try:
            DirectoryLock(run, "test").release()
            break
        except DirectoryBusy:
            time.sleep(0.1)
    else:
        raise AssertionError("the comparison's worker outlived its driver")
    logged = len(episodes(run))
    time.sleep(1.0)
    assert len(episodes(run)) == logged
