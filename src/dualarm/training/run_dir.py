"""The files of a run directory: CSV logs that survive a kill, and atomic checkpoints.

    DIR/config.yaml                 the resolved TrainConfig
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
        self.checkpoints = self.root / "checkpoints"
        self.latest = self.checkpoints / "latest.pt"
        self.best = self.checkpoints / "best_policy.pt"
        self.curves = self.root / "curves.png"


class CsvLog:
    """An append-only CSV with a fixed header, flushed after every batch of rows.

    ``truncate(n)`` keeps the first n data rows (and drops a half-written last line), so a
    resumed run continues the log exactly where its checkpoint was taken.
    """

    def __init__(self, path: Path, columns: list[str]):
        self.path = path
        self.columns = columns

    def truncate(self, keep: int) -> None:
        """Keep the header and the first ``keep`` complete rows (rewritten atomically)."""
        rows = []
        if self.path.exists():
            with open(self.path, newline="") as f:
                reader = csv.reader(f)
                header = next(reader, None)
                if header is not None and header != self.columns:
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
        text = io.StringIO()
        writer = csv.writer(text, lineterminator="\n")
        writer.writerow(self.columns)
        writer.writerows(rows)
        with atomic_open(self.path) as f:
            f.write(text.getvalue().encode())

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
        raise CheckpointError(f"{path}: the checkpoint is corrupt or truncated and cannot be "
                              f"read ({type(exc).__name__}: {str(exc).splitlines()[0][:200]})") from None
    except Exception as exc:  # torch's unpickler raises its own types for foreign content
        raise CheckpointError(f"{path}: not a checkpoint this version can read "
                              f"({type(exc).__name__})") from None
    if not isinstance(payload, dict) or payload.get("format") != CHECKPOINT_FORMAT:
        raise CheckpointError(f"{path}: not a dualarm DADDPG checkpoint")
    if payload.get("version") != CHECKPOINT_VERSION:
        raise CheckpointError(f"{path}: checkpoint version {payload.get('version')} is not "
                              f"supported (this code reads version {CHECKPOINT_VERSION})")
    return payload
