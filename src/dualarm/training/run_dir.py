"""The files of a run directory: CSV logs that survive a kill, and atomic checkpoints.

    DIR/config.yaml                 the resolved TrainConfig
    DIR/constraints.yaml            a copy of the constraints of a guided run (so that the
                                    directory resumes anywhere, moved or copied)
    DIR/.lock                       held by the process training the run (one writer)
    DIR/metrics.csv                 one row per training episode
    DIR/eval.csv                    one row per evaluation
    DIR/events/                     TensorBoard event files
    DIR/checkpoints/latest.pt       everything needed to continue exactly
    DIR/checkpoints/best_policy.pt  actors + normaliser of the best evaluation
    DIR/curves.png                  learning curves, drawn when a run ends
"""

from __future__ import annotations

import csv
import io
import os
import zipfile
from pathlib import Path

import torch

from dualarm.atomic import atomic_open
from dualarm.errors import DualarmError

CHECKPOINT_FORMAT = "dualarm-daddpg-checkpoint"
CHECKPOINT_VERSION = 1
#: Columns of eval.csv, one row per evaluation, as the trainer writes them.
EVAL_COLUMNS = ("episode", "env_steps", "wall_time_s", "success_rate", "return_mean", "steps_mean")
#: Columns eval.csv adds with ``algo.policy_average`` (the averaged actors, evaluated beside).
AVERAGE_EVAL_COLUMNS = ("average_success_rate", "average_return_mean")


class CheckpointError(DualarmError):
    """A checkpoint that cannot be used: missing, corrupt, or from an incompatible run."""


class RunPaths:
    """Where each file of a run directory lives."""

    def __init__(self, root: str | Path):
        self.root = Path(root)
        self.config = self.root / "config.yaml"
        self.metrics = self.root / "metrics.csv"
        self.eval = self.root / "eval.csv"
        self.events = self.root / "events"
        self.constraints = self.root / "constraints.yaml"
        self.checkpoints = self.root / "checkpoints"
        self.latest = self.checkpoints / "latest.pt"
        self.best = self.checkpoints / "best_policy.pt"
        self.curves = self.root / "curves.png"


class CsvLog:
    """An append-only CSV with a fixed header, flushed after every batch of rows.

    A resumed run continues the log exactly where its checkpoint was taken: ``verified(n)``
    reads the first n data rows and checks them (header, complete rows, the ``episode``
    column in order), without writing; ``rewrite(rows)`` then keeps just those (and so
    drops the rows of episodes the checkpoint does not hold, and a half-written last line).

    Args:
        path: the CSV file.
        columns: its header.
        consecutive: the ``episode`` column must read 1, 2, 3, ... (a training log);
            otherwise it must only increase (an evaluation log).
    """

    def __init__(self, path: Path, columns: list[str], consecutive: bool = True):
        self.path = path
        self.columns = columns
        self.consecutive = consecutive

    def verified(self, keep: int) -> list[list[str]]:
        """The first ``keep`` data rows, checked; raises ``CheckpointError`` naming the file
        and the row if the log is missing, short, of other columns or out of order."""
        if keep == 0:
            return []
        if not self.path.exists():
            raise CheckpointError(f"{self.path} is missing, but the checkpoint was taken after "
                                  f"{keep} rows of it: restore the file, or start a new run")
        rows: list[list[str]] = []
        with open(self.path, newline="", errors="replace") as f:
            reader = csv.reader(f)
            header = next(reader, None)
            if header != self.columns:
                raise CheckpointError(f"{self.path}: its columns {header} differ from this "
                                      f"run's {self.columns}")
            for row in reader:
                if len(rows) >= keep:
                    break
                if len(row) == len(self.columns):
                    rows.append(row)
        if len(rows) < keep:
            raise CheckpointError(f"{self.path} has {len(rows)} complete rows, but the "
                                  f"checkpoint was taken after {keep}: the log was edited "
                                  "or belongs to another run")
        if "episode" in self.columns:
            self._check_order(rows, self.columns.index("episode"))
        return rows

    def _check_order(self, rows: list[list[str]], where: int) -> None:
        """Column ``where`` of ``rows`` reads 1, 2, 3, ... (or only increases)."""
        last = 0
        for k, row in enumerate(rows, start=1):
            try:
                episode = int(row[where])
            except ValueError:
                episode = None
            ok = episode is not None and (episode == k if self.consecutive else episode > last)
            if not ok:
                raise CheckpointError(f"{self.path}, row {k}, column 'episode': "
                                      f"{row[where]!r} out of order (two writers, or an edited "
                                      "log); the run cannot continue this log")
            last = episode

    def rewrite(self, rows: list[list[str]]) -> None:
        """Replace the file (atomically) by the header and ``rows``."""
        text = io.StringIO()
        writer = csv.writer(text, lineterminator="\n")
        writer.writerow(self.columns)
        writer.writerows(rows)
        with atomic_open(self.path) as f:
            f.write(text.getvalue().encode())

    def truncate(self, keep: int) -> None:
        """Keep the header and the first ``keep`` complete rows (checked, rewritten atomically)."""
        self.rewrite(self.verified(keep))

    def append(self, rows: list[dict]) -> None:
        if not rows:
            return
        with open(self.path, "a", newline="") as f:
            writer = csv.DictWriter(f, self.columns, lineterminator="\n")
            writer.writerows(rows)
            f.flush()
            os.fsync(f.fileno())


def save_checkpoint(path: Path, payload: dict) -> None:
    """Write ``payload`` (tensors and plain values) atomically with a format tag."""
    payload = {"format": CHECKPOINT_FORMAT, "version": CHECKPOINT_VERSION, **payload}
    with atomic_open(path) as f:
        torch.save(payload, f)


def load_checkpoint(path: Path) -> dict:
    """Read a checkpoint written by ``save_checkpoint``.

    Raises:
        CheckpointError: the file is missing, truncated or corrupt, or not a dualarm
            checkpoint of a version this code reads; the message names the file.
    """
    path = Path(path)
    if not path.exists():
        raise CheckpointError(f"{path}: no checkpoint there")
    try:
        payload = torch.load(path, map_location="cpu", weights_only=True)
    except (RuntimeError, EOFError, zipfile.BadZipFile, OSError, ValueError, KeyError,
            AttributeError, IndexError, TypeError) as exc:
        detail = (str(exc).splitlines() or [""])[0][:200]
        size = path.stat().st_size if path.is_file() else None
        raise CheckpointError(f"{path}: the checkpoint is corrupt or truncated and cannot be read "
                              + ("(0 bytes)" if size == 0 else f"({type(exc).__name__}: {detail})")
                              ) from None
    except Exception as exc:  # torch's unpickler raises its own types for foreign content
        raise CheckpointError(f"{path}: not a checkpoint this version can read "
                              f"({type(exc).__name__})") from None
    if not isinstance(payload, dict) or payload.get("format") != CHECKPOINT_FORMAT:
        raise CheckpointError(f"{path}: not a dualarm DADDPG checkpoint")
    if payload.get("version") != CHECKPOINT_VERSION:
        raise CheckpointError(f"{path}: checkpoint version {payload.get('version')} is not "
                              f"supported (this code reads version {CHECKPOINT_VERSION})")
    return payload
