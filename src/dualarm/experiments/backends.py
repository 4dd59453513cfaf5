"""Where the training runs of a comparison execute: local worker processes, or Ray tasks.

A backend takes ``RunTask`` values (one training run each) and hands back ``RunOutcome``
values; the driver in ``dualarm.experiments.compare`` keeps at most ``capacity`` runs in
flight and polls ``wait``. Both backends run ``execute`` on the task:

* ``LocalBackend``: ``spawn``ed worker processes (torch and ``fork`` do not mix), one run
  at a time each; a run that crashes its process (out of memory, a segfault) fails alone.
  Each process limits OpenMP/BLAS to one thread and exits if the driver dies.
* ``RayBackend``: each run is a ``ray.remote(num_cpus=1)`` task on a local Ray instance or
  on a cluster. A task trains in place when its node sees the comparison directory (it
  reads the manifest and finds the comparison's id); otherwise it trains in a node-local
  temporary directory, starting from the run directory the driver shipped as a tar
  archive (partial runs only), and returns the finished (or failed) run directory as a tar
  archive that the driver unpacks into the comparison directory.
"""

from __future__ import annotations

import io
import os
import shutil
import socket
import tarfile
import tempfile
import sys
import threading
import time
import traceback
from dataclasses import dataclass, replace
from pathlib import Path

import yaml

from dualarm.atomic import atomic_open
from dualarm.errors import DualarmError, InputError
from dualarm.training.run_dir import RunPaths

#: Written (atomically) in a run directory once ``Trainer.run()`` has returned.
DONE_MARKER = "done.yaml"
#: The comparison's manifest, in its root directory.
MANIFEST = "comparison.yaml"


@dataclass(frozen=True)
class RunTask:
    """One training run to bring to ``config["episodes"]`` episodes.

    Attributes:
        name: the run's name, e.g. "multi-seed0"; its directory is ``root/runs/name``.
        root: absolute path of the comparison directory, as the driver sees it.
        comparison_id: the manifest's id; a worker that reads it at ``root`` sees the
            comparison directory (shared filesystem or same machine).
        config: the run's ``TrainConfig.to_dict()`` (``episodes`` is the target total).
        constraints: the bytes of the file named by ``config["constraints"]`` (None when the
            run uses no file or the shipped default), recreated at that path on a node that
            does not see it.
    """

    name: str
    root: str
    comparison_id: str
    config: dict
    constraints: bytes | None = None

    @property
    def run_dir(self) -> Path:
        return Path(self.root) / "runs" / self.name


@dataclass
class RunOutcome:
    """How a run ended.

    Attributes:
        name: the run's name.
        episodes: training episodes done at the end (0 if it failed before starting).
        wall_time_s: seconds this task ran, s (start-up included).
        error: "ErrorType: message" if the run failed, else None.
        traceback: the full traceback of an unexpected (non-dualarm) error, else None.
        last_eval: the run's last evaluation (episode, success_rate, return_mean), or None.
        node: host name of the machine that ran it.
        archive: the run directory as an uncompressed tar, when trained off the comparison
            directory (Ray without a shared filesystem); None otherwise.
    """

    name: str
    episodes: int = 0
    wall_time_s: float = 0.0
    error: str | None = None
    traceback: str | None = None
    last_eval: dict | None = None
    node: str = ""
    archive: bytes | None = None

    @property
    def ok(self) -> bool:
        return self.error is None


# ------------------------------------------------------------------ one run
def read_done(run_dir: str | Path) -> dict | None:
    """The done marker of a run directory (episodes, env_steps, wall_time_s, last_eval),
    or None if the run never returned from ``run()`` (or the marker is unreadable)."""
    try:
        data = yaml.safe_load((Path(run_dir) / DONE_MARKER).read_text())
    except (OSError, yaml.YAMLError):
        return None
    return data if isinstance(data, dict) and isinstance(data.get("episodes"), int) else None


def sees_comparison(root: str | Path, comparison_id: str) -> bool:
    """Whether this machine sees the comparison directory ``root`` (its manifest has the id)."""
    try:
        data = yaml.safe_load((Path(root) / MANIFEST).read_text())
    except (OSError, yaml.YAMLError):
        return False
    return isinstance(data, dict) and data.get("id") == comparison_id


def train_run(config: dict, run_dir: str | Path) -> RunOutcome:
    """Start the run in ``run_dir`` (if it holds no ``config.yaml``) or resume it with the
    total of ``config["episodes"]``; write ``curves.png`` and the done marker at the end.

    Failures are returned, not raised: ``error`` holds the error's type and message.
    """
    from dualarm.training import Trainer, TrainConfig
    from dualarm.training.plots import plot_run

    run_dir = Path(run_dir)
    paths = RunPaths(run_dir)
    name = run_dir.name
    started = time.perf_counter()
    node = socket.gethostname()
    try:
        config = TrainConfig.from_dict(config, where=f"run {name}", base=TrainConfig.paper())
        if paths.config.exists():     # never shorten a run that went further
            episodes = max(config.episodes, TrainConfig.load_saved(paths.config).episodes)
            trainer = Trainer.resume(run_dir, episodes=episodes, progress=False)
        else:
            trainer = Trainer.start(config, run_dir, progress=False)
        result = trainer.run()
        plot_run(run_dir, paths.curves)
        done = {"episodes": result.episodes, "env_steps": result.env_steps,
                "wall_time_s": round(result.wall_time_s, 3), "last_eval": result.last_eval,
                "stopped": result.stopped}
        with atomic_open(run_dir / DONE_MARKER) as f:
            f.write(yaml.safe_dump(done, sort_keys=False).encode())
        return RunOutcome(name, result.episodes, time.perf_counter() - started,
                          last_eval=result.last_eval, node=node)
    except Exception as exc:  # reported by the driver; the other runs go on
        tb = None if isinstance(exc, DualarmError) else traceback.format_exc()
        message = str(exc).splitlines()[0] if str(exc) else ""
        return RunOutcome(name, episodes=logged_episodes(run_dir),
                          wall_time_s=time.perf_counter() - started,
                          error=f"{type(exc).__name__}: {message}", traceback=tb, node=node)


def logged_episodes(run_dir: str | Path) -> int:
    """Rows of the run's ``metrics.csv`` (episodes logged so far; 0 if there is none)."""
    try:
        with open(RunPaths(run_dir).metrics, "rb") as f:
            return max(0, f.read().count(b"\n") - 1)
    except OSError:
        return 0


def execute(task: RunTask, in_place: bool | None = None, snapshot: bytes | None = None) -> RunOutcome:
    """Run one task where this process runs.

    Args:
        task: the run.
        in_place: train in ``task.run_dir``; False trains in a temporary directory and
            returns it as ``archive``; None decides by ``sees_comparison``.
        snapshot: the run directory as a tar (a partial run), unpacked before an off-place
            run resumes; ignored in place.
    """
    if in_place is None:
        in_place = sees_comparison(task.root, task.comparison_id)
    if in_place:
        return train_run(task.config, task.run_dir)
    scratch = Path(tempfile.mkdtemp(prefix="dualarm-compare-"))
    try:
        run_dir = scratch / task.name
        if snapshot:
            unpack_run(snapshot, run_dir)
        try:
            _materialise_constraints(task)
        except InputError as exc:
            return RunOutcome(task.name, error=f"InputError: {exc}", node=socket.gethostname())
        outcome = train_run(task.config, run_dir)
        if run_dir.exists():
            outcome.archive = pack_run(run_dir)
        return outcome
    finally:
        shutil.rmtree(scratch, ignore_errors=True)


def _materialise_constraints(task: RunTask) -> None:
    """Recreate the run's constraints file at its path on a node that does not see it.

    Raises:
        InputError: the path cannot be written, or holds a different file on this node.
    """
    path = task.config.get("constraints")
    if not path or task.constraints is None:
        return
    path = Path(path)
    try:
        if path.exists():
            if path.read_bytes() != task.constraints:
                raise InputError(f"{path}: a different file is at this path on node "
                                 f"{socket.gethostname()}; the comparison's constraints cannot "
                                 "be recreated there")
            return
        with atomic_open(path) as f:
            f.write(task.constraints)
    except OSError as exc:
        raise InputError(f"{path}: cannot recreate the constraints file on node "
                         f"{socket.gethostname()} ({exc.strerror or exc})") from None


def pack_run(run_dir: str | Path) -> bytes:
    """The run directory as an uncompressed tar (members relative to it)."""
    buffer = io.BytesIO()
    with tarfile.open(fileobj=buffer, mode="w") as tar:
        tar.add(str(run_dir), arcname=".")
    return buffer.getvalue()


def unpack_run(archive: bytes, run_dir: str | Path) -> None:
    """Replace ``run_dir`` by the contents of ``archive`` (from ``pack_run``).

    The archive is unpacked beside ``run_dir`` and swapped in with two renames, so a crash
    leaves either the old directory or the new one (and a hidden leftover to delete).
    """
    run_dir = Path(run_dir)
    run_dir.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{run_dir.name}.new-", dir=run_dir.parent))
    try:
        with tarfile.open(fileobj=io.BytesIO(archive), mode="r:") as tar:
            if hasattr(tarfile, "data_filter"):
                tar.extractall(tmp, filter="data")
            else:                     # Python < 3.11.4: refuse what the "data" filter refuses
                for member in tar.getmembers():
                    if (not (member.isfile() or member.isdir()) or member.name.startswith("/")
                            or ".." in Path(member.name).parts):
                        raise ValueError(f"unsafe member {member.name!r} in a run archive")
                tar.extractall(tmp)
        old = None
        if run_dir.exists():
            old = run_dir.with_name(f".{run_dir.name}.old-{os.getpid()}-{time.time_ns()}")
            os.replace(run_dir, old)
        os.replace(tmp, run_dir)
        if old is not None:
            shutil.rmtree(old, ignore_errors=True)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


# ------------------------------------------------------------ local backend
def _exit_when_orphaned(parent: int, every_s: float = 1.0) -> None:
    """End this process once its parent is gone (a killed driver must not leave runs
    writing into the comparison directory behind the next one)."""
    while True:
        time.sleep(every_s)
        if os.getppid() != parent:
            os._exit(3)


def _die_with_parent() -> None:
    """Ask Linux to SIGKILL this process the moment its parent ends (prctl PR_SET_PDEATHSIG);
    elsewhere ``_exit_when_orphaned`` notices within a second."""
    if not sys.platform.startswith("linux"):
        return
    import ctypes
    import signal

    try:
        ctypes.CDLL(None, use_errno=True).prctl(1, int(signal.SIGKILL), 0, 0, 0)
    except (OSError, AttributeError):
        pass


def _local_worker(conn) -> None:
    """Body of a local worker process: receive tasks, send back their outcomes, until None."""
    for var in ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS"):
        os.environ[var] = "1"
    parent = os.getppid()
    _die_with_parent()
    if os.getppid() != parent:        # the driver died before the request took effect
        os._exit(3)
    threading.Thread(target=_exit_when_orphaned, args=(parent,), daemon=True).start()
    try:
        while True:
            try:
                task = conn.recv()
            except EOFError:
                return
            if task is None:
                return
            conn.send(execute(task, in_place=True))
    except KeyboardInterrupt:      # Ctrl-C reaches the workers too; the driver reports it
        return


@dataclass
class _Worker:
    process: object
    conn: object
    task: RunTask | None = None


class LocalBackend:
    """Runs on this machine, ``workers`` runs at a time, in spawned worker processes.

    A worker process trains one run at a time and is reused for the next; one that dies
    (killed, out of memory) fails only its own run and is replaced.

    Args:
        workers: processes at most (>= 1); each trains with the run's ``torch_threads``
            (1 by default) and one OpenMP/BLAS thread.
    """

    def __init__(self, workers: int):
        import multiprocessing

        if workers < 1:
            raise InputError(f"--workers must be at least 1, got {workers}")
        self.capacity = workers
        self._ctx = multiprocessing.get_context("spawn")
        self._workers: list[_Worker] = []

    def start(self) -> None:
        """Nothing to start: worker processes are spawned as runs are submitted."""

    def describe(self) -> str:
        return f"local, up to {self.capacity} worker process(es)"

    @property
    def running(self) -> int:
        return sum(w.task is not None for w in self._workers)

    def submit(self, task: RunTask) -> None:
        """Hand ``task`` to an idle worker (spawning one if fewer than ``capacity`` exist)."""
        self._workers = [w for w in self._workers if w.task is not None or w.process.is_alive()]
        idle = [w for w in self._workers if w.task is None]
        if idle:
            worker = idle[0]
        elif len(self._workers) < self.capacity:
            conn, child = self._ctx.Pipe()
            proc = self._ctx.Process(target=_local_worker, args=(child,), daemon=True,
                                     name="dualarm-compare-worker")
            proc.start()
            child.close()
            worker = _Worker(proc, conn)
            self._workers.append(worker)
        else:
            raise RuntimeError("every worker is busy: wait for one before submitting")
        worker.task = task
        try:
            worker.conn.send(task)
        except (BrokenPipeError, OSError):
            pass          # the worker died while idle: wait() reports it as this run's failure

    def wait(self, timeout: float) -> list[RunOutcome]:
        """Outcomes of the runs that ended within ``timeout`` seconds (maybe none)."""
        from multiprocessing.connection import wait

        busy = [w for w in self._workers if w.task is not None]
        if not busy:
            return []
        ready = set(wait([w.conn for w in busy] + [w.process.sentinel for w in busy], timeout))
        outcomes = []
        for w in busy:
            if w.conn not in ready and w.process.sentinel not in ready:
                continue
            outcome = None
            try:
                if w.conn.poll():
                    outcome = w.conn.recv()
            except (EOFError, OSError):
                pass
            if outcome is None and w.process.is_alive():
                continue                    # woke up before the whole message arrived
            if outcome is None:
                w.process.join()
                w.conn.close()
                self._workers.remove(w)
                outcome = RunOutcome(w.task.name, episodes=logged_episodes(w.task.run_dir),
                                     error=f"WorkerDied: the run's process ended with exit code "
                                           f"{w.process.exitcode} (killed, or out of memory?)")
            w.task = None
            outcomes.append(outcome)
        return outcomes

    def close(self) -> None:
        """Stop the worker processes; runs still going are killed (their last checkpoints
        remain, so the next invocation resumes them)."""
        for w in self._workers:
            if w.task is None:
                try:
                    w.conn.send(None)
                except OSError:
                    pass
            else:
                w.process.terminate()
        for w in self._workers:
            w.process.join(10)
            if w.process.is_alive():
                w.process.kill()
                w.process.join()
            w.conn.close()
        self._workers.clear()


# -------------------------------------------------------------- Ray backend
def _import_ray():
    try:
        import ray
    except ImportError:
        raise InputError("--backend ray needs Ray: pip install 'dualarm[ray]'") from None
    return ray


def _ray_execute(task: RunTask, in_place: bool | None, snapshot_ref: list) -> RunOutcome:
    """Body of a Ray task: fetch the shipped snapshot only when training off-place."""
    if in_place is None:
        in_place = sees_comparison(task.root, task.comparison_id)
    snapshot = None
    if not in_place and snapshot_ref:
        import ray
        snapshot = ray.get(snapshot_ref[0])
    return execute(task, in_place=in_place, snapshot=snapshot)


class RayBackend:
    """Runs each training run as a Ray task (``num_cpus=1``).

    Args:
        address: a Ray cluster ("auto", "ray://host:10001", "host:6379"); None connects to
            the Ray instance this process already started, or starts a local one (no
            dashboard) and shuts it down on ``close``.
        workers: runs in flight at most (None: all; Ray queues them by free CPUs).
        shared_fs: True: every node sees the comparison directory (train in place); False:
            none does (train in node-local directories and ship run directories as tar);
            None: each task checks (``sees_comparison``). With a cluster address and not
            True, the driver also ships each partial run's directory with its task, so a
            node that does not see the directory can resume it.
    """

    def __init__(self, address: str | None = None, workers: int | None = None,
                 shared_fs: bool | None = None):
        if workers is not None and workers < 1:
            raise InputError(f"--workers must be at least 1, got {workers}")
        _import_ray()                  # fail before anything is written if Ray is missing
        self.address = address
        self.capacity = workers if workers is not None else 1 << 30
        self.shared_fs = shared_fs
        self._ray = None
        self._started = False
        self._remote = None
        self._running: dict = {}     # ObjectRef -> task

    def describe(self) -> str:
        where = self.address or "local Ray instance"
        cpus = self._ray.cluster_resources().get("CPU", 0) if self._ray else 0
        return f"ray ({where}, {cpus:g} CPUs)"

    def start(self) -> None:
        """Connect to (or start) Ray."""
        ray = _import_ray()
        self._ray = ray
        if not ray.is_initialized():
            if self.address:
                try:
                    ray.init(address=self.address)
                except (ConnectionError, ValueError, RuntimeError) as exc:
                    raise InputError(f"--ray-address {self.address}: cannot connect to the Ray "
                                     f"cluster ({str(exc).splitlines()[0][:300]})") from None
            else:
                ray.init(include_dashboard=False)
            self._started = True
        self._remote = ray.remote(num_cpus=1)(_ray_execute)

    @property
    def running(self) -> int:
        return len(self._running)

    def submit(self, task: RunTask) -> None:
        if self._ray is None:
            self.start()
        ship = self.shared_fs is False or (self.shared_fs is None and self.address is not None)
        snapshot = []
        if ship and RunPaths(task.run_dir).config.exists():
            snapshot = [self._ray.put(pack_run(task.run_dir))]
        ref = self._remote.remote(task, self.shared_fs, snapshot)
        self._running[ref] = task

    def wait(self, timeout: float) -> list[RunOutcome]:
        """Outcomes of the tasks that ended within ``timeout`` seconds; shipped run
        directories are unpacked into the comparison directory before they are returned."""
        if not self._running:
            return []
        ray = self._ray
        refs = list(self._running)
        ready, _ = ray.wait(refs, num_returns=1, timeout=timeout)
        if ready:
            ready, _ = ray.wait(refs, num_returns=len(refs), timeout=0)
        outcomes = []
        for ref in ready:
            task = self._running.pop(ref)
            try:
                outcome = ray.get(ref)
            except Exception as exc:    # the worker or its node died, or the task was cancelled
                outcome = RunOutcome(task.name, episodes=logged_episodes(task.run_dir),
                                     error=f"{type(exc).__name__}: {str(exc).splitlines()[0][:300]}")
            if outcome.archive is not None:
                unpack_run(outcome.archive, task.run_dir)
                outcome = replace(outcome, archive=None)
            outcomes.append(outcome)
        return outcomes

    def close(self) -> None:
        """Cancel the tasks still going; shut Ray down if this backend started it."""
        if self._ray is None:
            return
        for ref in list(self._running):
            try:
                self._ray.cancel(ref, force=True)
            except Exception:
                pass
        self._running.clear()
        if self._started:
            self._ray.shutdown()
            self._started = False


#: Seconds to wait for a Ray cluster's address to accept a connection before giving up.
CONNECT_TIMEOUT_S = 5.0


def check_reachable(address: str, timeout_s: float = CONNECT_TIMEOUT_S) -> None:
    """Refuse a Ray address ("host:port" or "ray://host:port") that accepts no connection
    within ``timeout_s`` (ray.init would wait minutes). "auto" and addresses without a port
    are left to Ray.

    Raises:
        InputError: naming --ray-address.
    """
    import socket

    target = address.removeprefix("ray://")
    host, _, port = target.rpartition(":")
    if not host or not port.isdigit():
        return
    try:
        socket.create_connection((host, int(port)), timeout=timeout_s).close()
    except (OSError, ValueError) as exc:
        raise InputError(f"--ray-address {address}: nothing answers there within {timeout_s:g} s "
                         f"({exc}); start the cluster (`ray start --head`) or fix the address "
                         "(nothing was written)") from None


#: Seconds a Ray cluster gets to accept a test driver before the address is refused.
PROBE_TIMEOUT_S = 9.0
#: Seconds the address gets to complete a gRPC (HTTP/2) handshake, as Ray's GCS and client
#: server do; a port of anything else (a web server, a database) fails here, fast.
HANDSHAKE_TIMEOUT_S = 3.0


def check_ray_cluster(address: str, timeout_s: float = PROBE_TIMEOUT_S) -> None:
    """Refuse an address where no Ray cluster accepts a driver: first no gRPC handshake within
    ``HANDSHAKE_TIMEOUT_S``, then no test connection (``ray.init(address)`` in a child process,
    killed at ``timeout_s``), since ``ray.init`` waits minutes on a port where something else
    answers.

    Raises:
        InputError: naming --ray-address and Ray's own last line.
    """
    import subprocess

    target = address.removeprefix("ray://")
    if target != "auto" and ":" in target:
        import grpc

        channel = grpc.insecure_channel(target)
        try:
            grpc.channel_ready_future(channel).result(timeout=HANDSHAKE_TIMEOUT_S)
        except grpc.FutureTimeoutError:
            raise InputError(f"--ray-address {address}: something answers there, but not as a Ray "
                             f"cluster (no gRPC handshake within {HANDSHAKE_TIMEOUT_S:g} s); give the "
                             "head's GCS port (`ray start --head --port`, 6379 by default) or "
                             "ray://HOST:10001 (nothing was written)") from None
        finally:
            channel.close()

    code = ("import sys, ray\n"
            "ray.init(address=sys.argv[1], logging_level='ERROR', log_to_driver=False)\n"
            "ray.shutdown()\n")
    try:
        done = subprocess.run([sys.executable, "-c", code, address], capture_output=True, text=True,
                              timeout=timeout_s)
    except subprocess.TimeoutExpired:
        raise InputError(f"--ray-address {address}: no Ray cluster accepted a connection within "
                         f"{timeout_s:g} s (something else answers there?); start the cluster "
                         "(`ray start --head`) or fix the address (nothing was written)") from None
    if done.returncode != 0:
        lines = [line.strip() for line in done.stderr.splitlines() if line.strip()]
        why = next((line for line in reversed(lines) if "Error" in line), lines[-1] if lines else "")
        raise InputError(f"--ray-address {address}: cannot connect to the Ray cluster ({why[:300]}) "
                         "(nothing was written)")


def make_backend(kind: str, workers: int | None = None, address: str | None = None):
    """A backend by name: "local" (``workers`` default: CPU count) or "ray"."""
    if kind == "local":
        if address:
            raise InputError("--ray-address needs --backend ray")
        return LocalBackend(workers or os.cpu_count() or 1)
    if kind == "ray":
        if address:
            check_reachable(address)
            _import_ray()                 # the missing extra's line before a child's traceback
            check_ray_cluster(address)
        return RayBackend(address, workers)
    raise InputError(f"--backend must be local or ray, got {kind!r}")
