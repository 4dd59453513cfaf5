"""Reading the project's YAML files (configs, constraints, manifests) with one kind of error.

Whatever is wrong with the file (missing, unreadable, not UTF-8, not YAML), the caller
gets an ``InputError`` that names it and, for a syntax error, the line and column.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import yaml

from dualarm.errors import InputError


def read_yaml(path: str | os.PathLike, what: str = "file") -> Any:
    """The parsed content of the YAML file ``path``.

    Args:
        what: what the file is, for the message ("constraint file", "run config").

    Raises:
        InputError: with ``source=path``: the file cannot be read, is not UTF-8 text, or is
            not valid YAML (the line and column of the problem named).
    """
    source = str(path)
    try:
        text = Path(path).read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        reason = exc.strerror if isinstance(exc, OSError) and exc.strerror else str(exc)
        raise InputError(f"cannot read {what}: {reason}", source=source) from None
    try:
        return yaml.safe_load(text)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f" at line {mark.line + 1}, column {mark.column + 1}" if mark is not None else ""
        problem = getattr(exc, "problem", None) or str(exc).splitlines()[0]
        raise InputError(f"YAML syntax error{where}: {problem}", source=source) from None
