"""One check of every settings dataclass against its declared field types.

Config files are YAML, where ``2.5``, ``"ten"`` and ``true`` all parse, and a number in
the wrong place would otherwise surface later as a confusing error deep in the code (or,
for ``episodes: true``, as a run of one episode). Each settings dataclass calls
``check_field_types(self)`` first thing in ``__post_init__``, so whatever built it (a
file, the command line, code) meets the same rule: ints are ints (not bools, not
2.5), floats are finite numbers, bools are bools, tuples have their declared length, and
the error names the field.
"""

from __future__ import annotations

import dataclasses
import math
import numbers
import types
import typing
from collections.abc import Mapping
from functools import cache

import numpy as np

from dualarm.errors import InputError


@cache
def _hints(cls: type) -> dict[str, object]:
    return typing.get_type_hints(cls)


def describe(tp) -> str:
    """A reader's name for a declared type: "an integer", "true or false", ..."""
    origin, args = typing.get_origin(tp), typing.get_args(tp)
    if origin in (typing.Union, types.UnionType):
        return " or ".join("null" if a is type(None) else describe(a) for a in args)
    if origin is tuple:
        item = describe(args[0]).removeprefix("an ").removeprefix("a ")
        count = "" if len(args) == 2 and args[1] is Ellipsis else f"{len(args)} "
        return f"a list of {count}{item}s"
    return {bool: "true or false", int: "an integer", float: "a number", str: "a string",
            dict: "a mapping"}.get(tp, getattr(tp, "__name__", str(tp)))


class _Mismatch(Exception):
    pass


def conform(value, tp):
    """``value`` as the declared type ``tp`` (lists become tuples, ints become floats where
    a float is declared); raises ``_Mismatch`` if it is not one."""
    origin, args = typing.get_origin(tp), typing.get_args(tp)
    if origin in (typing.Union, types.UnionType):
        if value is None and type(None) in args:
            return None
        for option in args:
            if option is type(None):
                continue
            try:
                return conform(value, option)
            except _Mismatch:
                pass
        raise _Mismatch
    if tp is bool:
        if isinstance(value, (bool, np.bool_)):
            return bool(value)
        raise _Mismatch
    if tp is int:
        if isinstance(value, numbers.Integral) and not isinstance(value, bool):
            return int(value)
        raise _Mismatch
    if tp is float:
        if (isinstance(value, numbers.Real) and not isinstance(value, bool)
                and math.isfinite(float(value))):
            return float(value)
        raise _Mismatch
    if tp is str:
        if isinstance(value, str):
            return value
        raise _Mismatch
    if tp is dict or origin is dict:
        if isinstance(value, Mapping):
            return value
        raise _Mismatch
    if origin is tuple:
        if isinstance(value, (str, bytes)) or not isinstance(value, (list, tuple)):
            raise _Mismatch
        if len(args) == 2 and args[1] is Ellipsis:
            kinds = [args[0]] * len(value)
        elif len(args) == len(value):
            kinds = list(args)
        else:
            raise _Mismatch
        return tuple(conform(v, k) for v, k in zip(value, kinds))
    if isinstance(tp, type):
        if isinstance(value, tp):
            return value
        raise _Mismatch
    return value                      # an annotation this check does not know: left alone


def check_field_types(obj) -> None:
    """Check (and normalise) every field of the dataclass instance ``obj`` against its
    declared type.

    Raises:
        InputError: naming the first field whose value is not of its type, the type
            expected and the value given ("episodes: expected an integer, got 2.5").
    """
    hints = _hints(type(obj))
    for f in dataclasses.fields(obj):
        value = getattr(obj, f.name)
        try:
            fixed = conform(value, hints[f.name])
        except _Mismatch:
            shown = repr(value) if not isinstance(value, bool) else str(value).lower()
            raise InputError(f"{f.name}: expected {describe(hints[f.name])}, got {shown[:80]}"
                             f" ({type(value).__name__})") from None
        if fixed is not value:
            object.__setattr__(obj, f.name, fixed)


#: A removed option's value that is today's behaviour, or ``ANY`` where every value is (an
#: option that only mattered beside another removed one).
ANY = object()


def drop_removed_fields(d: dict, removed: Mapping, where: str) -> dict:
    """``d`` without the options that left a settings dataclass: each may still be given with
    the one value that is today's behaviour (so old run directories and files keep loading);
    any other value is refused, naming the field.

    Args:
        d: the settings as read from a file.
        removed: field name -> its value today (``ANY``: every value), e.g. the dataclass's
            ``REMOVED_FIELDS``.
        where: prefixes the error (the file and section).
    """
    d = dict(d)
    for name, value in removed.items():
        if name not in d:
            continue
        given = d.pop(name)
        same = given is value if value is None else \
            isinstance(given, bool) == isinstance(value, bool) and given == value
        if value is not ANY and not same:
            raise InputError(f"{where}: {name}: {given!r} is no longer an option (only "
                             f"{value!r}; docs/learning-runs.md names the commit that had it)"[:300])
    return d


def plain(value):
    """A settings value as YAML writes it: tuples as lists, a settings group as its mapping."""
    if isinstance(value, Settings):
        return value.to_dict()
    if isinstance(value, tuple):
        return [plain(v) for v in value]
    return value


class Settings:
    """What every frozen settings dataclass read from YAML shares: ``to_dict``, ``from_dict``
    on top of a base (a file says only what it changes), ``with_``. A subclass names itself in
    errors with ``LABEL`` and may list ``REMOVED`` options (``drop_removed_fields``); its
    ``__post_init__`` calls ``check_field_types`` and checks its own values, in one place."""

    LABEL = "settings"
    REMOVED: Mapping = {}
    #: Older names ``upgrade`` turns into fields.
    OLD_NAMES: tuple[str, ...] = ()

    @classmethod
    def check_names(cls, d: Mapping, where: str) -> None:
        """Refuse a name that is neither a field, a removed option nor an old name."""
        known = {f.name for f in dataclasses.fields(cls)}
        unknown = sorted(set(d) - known - set(cls.REMOVED) - set(cls.OLD_NAMES), key=str)
        if unknown:
            raise InputError(f"{where}: unknown {cls.LABEL} field(s) {unknown}; known: {sorted(known)}")

    @classmethod
    def upgrade(cls, d: dict, where: str) -> dict:
        """``d`` of an older layout in today's (here: removed options dropped)."""
        return drop_removed_fields(d, cls.REMOVED, where)

    def to_dict(self) -> dict:
        return {f.name: plain(getattr(self, f.name)) for f in dataclasses.fields(self)}

    @classmethod
    def from_dict(cls, d, where: str = "config", base=None):
        """Build from a mapping, naming unknown fields (``where`` prefixes every message); the
        fields it leaves out take ``base``'s values (default: the class's defaults)."""
        if not isinstance(d, Mapping):
            raise InputError(f"{where}: expected a mapping of {cls.LABEL} settings, got {d!r}"[:160])
        cls.check_names(d, where)
        d = cls.upgrade(dict(d), where)
        if base is not None:
            d = {**base.to_dict(), **d}
        try:
            return cls(**d)
        except InputError as exc:
            raise InputError(f"{where}: {exc}") from None

    def with_(self, **changes):
        """A copy with some fields changed (checked as a new one is)."""
        return dataclasses.replace(self, **changes)
