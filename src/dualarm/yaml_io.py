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


class _NoAliasLoader(yaml.SafeLoader):
    """YAML's safe loader without aliases (``*name``): the project's files never need them,
    and a few lines of nested aliases expand into billions of values (a "billion laughs"
    file), which every later check would have to walk."""

    def compose_node(self, parent, index):
        if self.check_event(yaml.AliasEvent):
            mark = self.peek_event().start_mark
            raise yaml.composer.ComposerError(
                None, None, "aliases (*name) are not supported: write the value out", mark)
        return super().compose_node(parent, index)


def read_yaml(path: str | os.PathLike, what: str = "file") -> Any:
    """The parsed content of the YAML file ``path``.

    Args:
        what: what the file is, for the message ("constraint file", "run config").

    Raises:
        InputError: with ``source=path``: the file cannot be read, is not UTF-8 text, is
            not valid YAML, or uses an alias (the line and column of the problem named).
    """
    source = str(path)
    try:
        text = Path(path).read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        reason = exc.strerror if isinstance(exc, OSError) and exc.strerror else str(exc)
        raise InputError(f"cannot read {what}: {reason}", source=source) from None
    try:
        return yaml.load(text, Loader=_NoAliasLoader)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f" at line {mark.line + 1}, column {mark.column + 1}" if mark is not None else ""
        problem = getattr(exc, "problem", None) or str(exc).splitlines()[0]
        raise InputError(f"YAML syntax error{where}: {problem}", source=source) from None
