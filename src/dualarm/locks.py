"""One writer per directory: the advisory lock that `train` and `compare` take on theirs.

The lock is ``DIR/.lock``, held with ``flock`` for as long as the writer lives; the
operating system releases it when the process ends, however it ends (even SIGKILL), so
a stale lock never blocks a resume. The file records who holds it, for the message the
second writer prints.
"""

from __future__ import annotations

import contextlib
import os
import socket
import sys
import time
from pathlib import Path

from dualarm.errors import DualarmError

LOCK_NAME = ".lock"


class DirectoryBusy(DualarmError):
    """Another process is writing to the directory (the message names it)."""


class DirectoryLock:
    """An exclusive, non-blocking lock on ``root`` (created if missing).

    Args:
        root: the directory.
        purpose: who takes it, for the other writer's message ("dualarm train").

    Raises:
        DirectoryBusy: another process holds the lock.
    """

    def __init__(self, root: str | os.PathLike, purpose: str):
        self.root = Path(root)
        self.created = not self.root.exists()
        # the folders above root that this lock makes, innermost first (removed with it)
        self.made_parents = [p for p in self.root.parents if not p.exists()]
        self.root.mkdir(parents=True, exist_ok=True)
        self._file = open(self.root / LOCK_NAME, "a+")
        try:
            import fcntl
        except ImportError:                   # no advisory locks on this platform
            return
        try:
            fcntl.flock(self._file, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            self._file.seek(0)
            holder = self._file.read().strip() or "another process"
            self._file.close()
            self._file = None
            raise DirectoryBusy(f"{self.root} is in use by {holder}; wait for it to end or "
                                "stop it (a killed process releases its lock)") from None
        self._file.seek(0)
        self._file.truncate()
        started = time.strftime("%Y-%m-%d %H:%M:%S")
        self._file.write(f"{purpose}, pid {os.getpid()} on {socket.gethostname()}, since {started}\n")
        self._file.flush()

    @property
    def held(self) -> bool:
        return self._file is not None

    def release(self, remove_if_created: bool = False) -> None:
        """Let go of the lock; with ``remove_if_created``, also delete the directory if this
        lock created it and nothing but the lock file is in it (a start that failed), and the
        folders above it that it created, while they are empty."""
        if self._file is None:
            return
        lock_path = self.root / LOCK_NAME
        if remove_if_created and self.created and [p.name for p in self.root.iterdir()] == [LOCK_NAME]:
            lock_path.unlink(missing_ok=True)
            with contextlib.suppress(OSError):
                self.root.rmdir()
                for parent in self.made_parents:      # rmdir refuses a folder that is not empty
                    parent.rmdir()
        self._file.close()                    # closing the descriptor releases flock
        self._file = None

    def __enter__(self) -> "DirectoryLock":
        """``with DirectoryLock(dir, "dualarm compare"):`` holds it for the block (a block that
        fails also removes the directory if the lock made it and nothing else is in it)."""
        return self

    def __exit__(self, *exc) -> None:
        self.release(remove_if_created=exc[0] is not None)

    def __del__(self):                        # a forgotten lock still goes with the object
        if getattr(self, "_file", None) is not None and not sys.is_finalizing():
            self.release()

