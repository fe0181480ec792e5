"""One validator for the fields of the TOML files the tool reads.

Every reader (sequence, profile, truth, result, gimbal, requirements) asks
the same questions of a parsed table: is this key a number, finite, in
range; is that one a boolean, a string, a table; is this a key we know, or
a near miss of one ("``rate_dsp``: did you mean ``rate_dps``?"); was the
file written by a newer version of the tool. They ask them here, so every
refusal reads the same: what, where (file and key), how to fix.
"""

from __future__ import annotations

import difflib
import math
import reprlib
from collections.abc import Iterable
from typing import Literal, overload

from calib.errors import CalibError

from .files import toml_number

_MISSING = object()
# The keywords of Fields.number, which Fields.numbers passes on to each item.
_NUMBER_CHECKS = frozenset({"low", "high", "positive", "finite", "unit", "fix"})
REQUIRED = _MISSING  # "no default": a missing key is refused

# The first format version of each file kind; files written before versions existed
# carry no ``format_version`` and mean what version 1 means.
FORMAT_VERSION = 1


class Fields:
    """Typed access to one TOML table, with refusals that name the file and key.

    Parameters
    ----------
    table : dict
        The parsed table.
    where : str
        The file (and table) it came from, for messages.
    """

    def __init__(self, table, where: str):
        if not isinstance(table, dict):
            raise CalibError("must be a table", where)
        self.table = table
        self.where = where

    def here(self, key: str) -> str:
        return f"{self.where}: key '{key}'"

    def number(
        self,
        key: str,
        default=_MISSING,
        *,
        low: float | None = None,
        high: float | None = None,
        positive: bool = False,
        finite: bool = True,
        unit: str = "",
        fix: str | None = None,
    ) -> float:
        """A number, refused with the key's name unless it is finite and within the bounds.

        ``fix`` is the advice every refusal of this key carries (e.g. the unit expected).
        """
        if key not in self.table:
            if default is _MISSING:
                raise CalibError(f"missing key '{key}'", self.where, fix or f"add '{key} = <number>'")
            return default
        raw = self.table[key]
        value = toml_number(raw)
        if value is None:
            raise CalibError(f"'{key}' must be a number, got {raw!r}", self.here(key), fix)
        if finite and not math.isfinite(value):
            raise CalibError(f"'{key}' must be finite, got {value}", self.here(key), fix)
        if positive and not value > 0:
            raise CalibError(f"'{key}' must be > 0, got {value}", self.here(key), fix)
        if (low is not None and value < low) or (high is not None and value > high):
            span = f"[{'-inf' if low is None else f'{low:g}'}, {'inf' if high is None else f'{high:g}'}]"
            raise CalibError(f"'{key}' = {value:g}{unit} is outside {span}{unit}", self.here(key), fix)
        return value

    def numbers(self, key: str, default=_MISSING, *, length: int | None = None, **checks) -> list[float]:
        """An array of numbers, each checked as :meth:`number` checks one.

        ``length`` (when given) is the array's required size. ``checks`` are
        :meth:`number`'s keywords (``low``, ``high``, ``positive``, ``finite``,
        ``unit``, ``fix``), applied to each item; a refused item is named by its
        index, ``key[i]``; ``fix`` is the advice every refusal carries.
        """
        if unknown := set(checks) - _NUMBER_CHECKS:  # a misspelt check would otherwise be ignored
            raise TypeError(
                f"numbers() got unknown checks {sorted(unknown)}; number() takes {sorted(_NUMBER_CHECKS)}"
            )
        fix = checks.get("fix")
        if key not in self.table:
            if default is _MISSING:
                raise CalibError(f"missing key '{key}'", self.where, fix or f"add '{key} = [<number>, ...]'")
            return default
        raw = self.table[key]
        if not isinstance(raw, list) or (length is not None and len(raw) != length):
            size = "numbers" if length is None else f"{length} numbers"
            raise CalibError(
                f"'{key}' must be an array of {size}, got {reprlib.repr(raw)}", self.here(key), fix
            )
        items = Fields({f"{key}[{i}]": item for i, item in enumerate(raw)}, self.where)
        return [items.number(name, **checks) for name in items.table]

    def integer(self, key: str, default=_MISSING, *, low: int | None = None) -> int:
        """A whole number (booleans refused)."""
        if key not in self.table:
            if default is _MISSING:
                raise CalibError(f"missing key '{key}'", self.where, f"add '{key} = <integer>'")
            return default
        raw = self.table[key]
        if isinstance(raw, bool) or not isinstance(raw, int) or (low is not None and raw < low):
            bound = f" >= {low}" if low is not None else ""
            raise CalibError(f"'{key}' must be an integer{bound}, got {raw!r}", self.here(key))
        return raw

    def boolean(self, key: str, default=_MISSING) -> bool:
        if key not in self.table:
            if default is _MISSING:
                raise CalibError(f"missing key '{key}'", self.where, f"add '{key} = true|false'")
            return default
        raw = self.table[key]
        if not isinstance(raw, bool):
            raise CalibError(f"'{key}' must be true or false, got {raw!r}", self.here(key))
        return raw

    def string(self, key: str, default=_MISSING, *, choices: Iterable[str] | None = None) -> str:
        if key not in self.table:
            if default is _MISSING:
                raise CalibError(f"missing key '{key}'", self.where, f"add '{key} = \"...\"'")
            return default
        raw = self.table[key]
        if not isinstance(raw, str):
            raise CalibError(f"'{key}' must be a string, got {raw!r}", self.here(key))
        if choices is not None and raw not in choices:
            raise CalibError(f"'{key}' = {raw!r} is not one of {', '.join(choices)}", self.here(key))
        return raw

    @overload
    def sub(self, key: str, required: Literal[True]) -> Fields: ...

    @overload
    def sub(self, key: str, required: bool = False) -> Fields | None: ...

    def sub(self, key: str, required: bool = False) -> Fields | None:
        """The sub-table ``[key]`` (None when absent and not required)."""
        if key not in self.table:
            if required:
                raise CalibError(f"missing table [{key}]", self.where)
            return None
        return Fields(self.table[key], f"{self.where}: [{key}]")

    def check_keys(self, known: Iterable[str], kind: str) -> list[str]:
        """Refuse a near miss of a known key; return a warning for every other unknown key.

        The files' contract lets a file carry more keys than the tool reads, so
        an unknown key is not refused; but a typo of a known one would
        silently fall back to a default, so it is.
        """
        known = list(known)
        warnings = []
        for key in self.table:
            if key in known:
                continue
            # 0.8: one letter off in four ('sgxx'), a unit left off ('dwell'), two swapped
            # ('rate_dsp'); not two of four ('site' is no typo of 'step').
            close = difflib.get_close_matches(key, known, n=1, cutoff=0.8)
            if close:
                raise CalibError(
                    f"unknown key '{key}': did you mean '{close[0]}'?",
                    self.here(key),
                    f"rename it to '{close[0]}' (the {kind} keys are: {', '.join(known)})",
                )
            warnings.append(f"{self.where}: key '{key}' is not a {kind} key; it is ignored")
        return warnings


def check_format_version(table: dict, kind: str, where: str) -> int:
    """The file's ``format_version`` (1 when absent); refuse one newer than this tool reads."""
    version = Fields(table, where).integer("format_version", FORMAT_VERSION, low=1)
    if version > FORMAT_VERSION:
        raise CalibError(
            f"{kind} format_version {version} is newer than this tool reads ({FORMAT_VERSION})",
            f"{where}: key 'format_version'",
            "upgrade seqdesign",
        )
    return version
