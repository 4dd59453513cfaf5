"""Error types raised where bad input enters the pipeline."""

from __future__ import annotations


class DualarmError(Exception):
    """Base class of every error the project raises on purpose.

    The command line prints ``str(error)`` as one line on stderr and exits with
    status 2, so the message must name the file, row, column or field at fault.
    """


class InputError(DualarmError, ValueError):
    """Bad user input: a file, column, row, field or option value.

    Args:
        message: what is wrong, in one line.
        source: the file (or other origin) the bad value came from, if known.
        row: 1-based data row (header excluded) in ``source``, if known.
        column: the column or field name, if known.
    """

    def __init__(self, message: str, *, source: str | None = None,
                 row: int | None = None, column: str | None = None):
        self.source = source
        self.row = row
        self.column = column
        where = []
        if source is not None:
            where.append(str(source))
        if row is not None:
            where.append(f"row {row}")
        if column is not None:
            where.append(f"column '{column}'")
        prefix = ", ".join(where)
        super().__init__(f"{prefix}: {message}" if prefix else message)


class WriteError(DualarmError, OSError):
    """A file could not be written (a full disk, a file-size limit, a read-only folder); the
    message names the file, and its previous version, if any, is kept."""


def require_file(path, what: str = "file") -> None:
    """Refuse a ``path`` that does not exist or is a directory, naming it (``what``: the kind
    of file, for the message, e.g. "labels file")."""
    from pathlib import Path

    p = Path(path)
    if not p.exists():
        raise InputError(f"{what} not found", source=str(path))
    if p.is_dir():
        raise InputError(f"is a directory, not a {what}", source=str(path))
