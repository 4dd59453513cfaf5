"""Atomic file writes: a temporary file beside the target, then a rename onto it.

A reader (or a run killed mid-write) never sees half a file: the target is either the old
file or the complete new one. The temporary file keeps the target's suffix (writers that
pick a format by extension see the right one), is created exclusively with mode 0o666 so
the user's umask applies (``mkstemp`` would leave it 0600), and is removed on any failure.
"""

from __future__ import annotations

import contextlib
import os
import re
import secrets
from collections.abc import Iterator
from pathlib import Path
from typing import BinaryIO

from dualarm.errors import WriteError


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike) -> Iterator[Path]:
    """Yield a fresh empty temporary path to write; on success it replaces ``path``.

    The parent folder of ``path`` is created if missing. A write that fails (a full disk, a
    file-size limit: an ``OSError``, or the ``RuntimeError`` torch's writer turns it into)
    raises ``WriteError`` naming ``path``; the file it would have replaced is left as it was.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.stem}.{secrets.token_hex(6)}.tmp{path.suffix}")
    os.close(os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666))
    try:
        yield tmp
        os.replace(tmp, path)
    except (OSError, RuntimeError) as exc:
        tmp.unlink(missing_ok=True)
        if isinstance(exc, WriteError):
            raise
        reason = (exc.strerror if isinstance(exc, OSError) and exc.strerror
                  else "the writer stopped part-way")
        raise WriteError(f"{path}: could not be written ({reason}; is the disk full or a "
                         "file-size limit set?); its previous version, if any, is kept") from exc
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


#: ``atomic_path``'s temporary names: ``.<stem>.<12 hex>.tmp<suffix>``.
_TEMPORARY = re.compile(r"^\..+\.[0-9a-f]{12}\.tmp(\..*)?$")


def leftover_temporaries(folder: str | os.PathLike) -> list[Path]:
    """The temporary files ``atomic_path`` left in ``folder`` when its process was killed
    mid-write. Only a caller that owns the folder (holds its lock) may remove them: another
    writer's may be in use."""
    folder = Path(folder)
    if not folder.is_dir():
        return []
    return sorted(p for p in folder.iterdir() if _TEMPORARY.match(p.name) and p.is_file())


@contextlib.contextmanager
def atomic_open(path: str | os.PathLike) -> Iterator[BinaryIO]:
    """Yield a binary file to write; on success it is flushed to disk and replaces ``path``."""
    with atomic_path(path) as tmp, open(tmp, "wb") as out:
        yield out
        out.flush()
        os.fsync(out.fileno())


def atomic_copy(source: str | os.PathLike, target: str | os.PathLike) -> None:
    """Copy the bytes of ``source`` to ``target`` atomically (``atomic_open``)."""
    data = Path(source).read_bytes()
    with atomic_open(target) as out:
        out.write(data)
