"""Checks at the edge: small declarative specs for what a user hands term (the config file, a joystick mapping,
command-line numbers), and one walk over them that refuses a bad value in one line.

A spec says what a value may be: ``Number(lo, hi, integer=...)`` (finite, inside the closed range; a TOML bool
is not a number), ``Text`` (no NUL, optionally not empty), ``Flag`` (a real ``true``/``false``: the string
"false" is not false), ``OneOf`` (a name from a list, with the nearest one suggested), ``ListOf`` and ``Table``
(known keys only: a typo is refused and the nearest key named). ``spec.check(value, where)`` returns the value
(ints as int, numbers as float) or raises ``SchemaError`` whose message is one line::

    [connection] link_timeout: must be a number between 0.05 and 60 s, got nan

``where`` names the place in the file (``[section] key``, ``[joystick.mappings.x] roll.invert``) or the option
(``--baud``); the caller puts the file name in front. Pure: standard library only.
"""

from __future__ import annotations

import difflib
import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from typing import Any, Protocol

SHOWN_MAX = 40  # characters of a bad value quoted back in a message


class SchemaError(ValueError):
    """A value that does not fit its spec; the message is one line: where, what is allowed, what was given."""


class Spec(Protocol):
    def check(self, value: Any, where: str) -> Any: ...

    def describe(self) -> str: ...


def shown(value: Any) -> str:
    """A value as the user wrote it (TOML spelling where it differs from Python's), short and on one line."""
    if isinstance(value, bool):
        text = "true" if value else "false"
    elif isinstance(value, str):
        text = '"' + value.encode("unicode_escape").decode("ascii").replace('"', '\\"') + '"'
    elif isinstance(value, float):
        text = repr(value)  # nan, inf, -inf as TOML spells them
    elif isinstance(value, int) and abs(value) >= 10**SHOWN_MAX:
        text = f"{'-' if value < 0 else ''}a {len(str(abs(value)))}-digit integer"  # never thousands of digits
    elif isinstance(value, Mapping):
        text = "{" + ", ".join(f"{k} = {shown(v)}" for k, v in list(value.items())[:4]) + "}"
    elif isinstance(value, list | tuple):
        text = "[" + ", ".join(shown(v) for v in list(value)[:6]) + "]"
    else:
        text = str(value)
    text = " ".join(text.split())  # one line, whatever a datetime or nested value looked like
    return text if len(text) <= SHOWN_MAX else text[: SHOWN_MAX - 1] + "…"


def nearest(word: str, choices: Iterable[str]) -> str:
    """' (did you mean X?)' for a near miss, else ''."""
    close = difflib.get_close_matches(word, list(choices), n=1, cutoff=0.6)
    return f" (did you mean {close[0]!r}?)" if close else ""


def _fail(where: str, spec: Spec, value: Any) -> SchemaError:
    prefix = f"{where}: " if where else ""
    return SchemaError(f"{prefix}must be {spec.describe()}, got {shown(value)}")


def _g(x: float) -> str:
    return f"{x:g}" if abs(x) < 1e6 or x != int(x) else str(int(x))


@dataclass(frozen=True)
class Number:
    """A finite number in [lo, hi]; ``integer``: an int (a float like 3.0 is refused: the file says 3)."""

    lo: float
    hi: float
    integer: bool = False
    unit: str = ""

    def describe(self) -> str:
        kind = "an integer" if self.integer else "a number"
        unit = f" {self.unit}" if self.unit else ""
        return f"{kind} between {_g(self.lo)} and {_g(self.hi)}{unit}"

    def check(self, value: Any, where: str) -> Any:
        types: tuple[type, ...] = (int,) if self.integer else (int, float)
        if isinstance(value, bool) or not isinstance(value, types):
            raise _fail(where, self, value)
        if isinstance(value, float) and not math.isfinite(value) or not self.lo <= value <= self.hi:
            raise _fail(where, self, value)
        return int(value) if self.integer else float(value)


@dataclass(frozen=True)
class Text:
    """A string without NUL (it cannot name a file or a port); ``nonempty``: not blank."""

    nonempty: bool = False
    what: str = "a string"

    def describe(self) -> str:
        return f"{self.what} (not empty)" if self.nonempty else self.what

    def check(self, value: Any, where: str) -> Any:
        if not isinstance(value, str) or self.nonempty and not value.strip():
            raise _fail(where, self, value)
        if "\0" in value:
            raise SchemaError(f"{where}: must not hold a NUL character, got {shown(value)}")
        return value


@dataclass(frozen=True)
class Flag:
    def describe(self) -> str:
        return "true or false"

    def check(self, value: Any, where: str) -> Any:
        if not isinstance(value, bool):
            raise _fail(where, self, value)
        return value


@dataclass(frozen=True)
class OneOf:
    choices: tuple[str, ...]

    def describe(self) -> str:
        return "one of: " + ", ".join(self.choices)

    def check(self, value: Any, where: str) -> Any:
        if not isinstance(value, str) or value not in self.choices:
            hint = nearest(value, self.choices) if isinstance(value, str) else ""
            raise SchemaError(f"{_fail(where, self, value)}{hint}")
        return value


@dataclass(frozen=True)
class ListOf:
    """A list of ``item``; ``one_ok``: a single item may stand for a list of one (``match = "pad"``)."""

    item: Spec
    min_len: int = 0
    max_len: int = 64
    unique: bool = False
    one_ok: bool = False

    def describe(self) -> str:
        size = f"{self.min_len} to {self.max_len}" if self.min_len else f"at most {self.max_len}"
        return f"a list of {size} items, each {self.item.describe()}"

    def check(self, value: Any, where: str) -> Any:
        if self.one_ok and not isinstance(value, list):
            value = [value]
        if not isinstance(value, list) or not self.min_len <= len(value) <= self.max_len:
            raise _fail(where, self, value)
        out = [self.item.check(v, f"{where}[{i}]") for i, v in enumerate(value)]
        if self.unique:
            seen = set()
            for v in out:
                if v in seen:
                    raise SchemaError(f"{where}: {shown(v)} is given twice")
                seen.add(v)
        return out


def child_where(where: str, key: str, section: bool) -> str:
    """``[a]`` + b -> ``[a] b``; ``[a] b`` + c -> ``[a] b.c``; a section: ``[a]`` + b -> ``[a.b]``."""
    if section:
        head = where[1:-1] if where.startswith("[") and where.endswith("]") else where
        return f"[{head}.{key}]" if head else f"[{key}]"
    if not where:
        return key
    return f"{where} {key}" if where.endswith("]") else f"{where}.{key}"


@dataclass(frozen=True)
class Table:
    """A TOML table with known keys, each checked by its spec; an unknown key is refused (typos must not pass
    silently). ``section``: written as ``[name]`` in the file, so places inside read ``[name] key``."""

    fields: Mapping[str, Spec]
    section: bool = False

    def describe(self) -> str:
        return "a table" + (f" with keys {', '.join(self.fields)}" if len(self.fields) <= 6 else "")

    def check(self, value: Any, where: str) -> dict[str, Any]:
        if not isinstance(value, Mapping):
            raise _fail(where, self, value)
        for key in value:
            if key not in self.fields:
                place = f" in {where}" if where else ""
                raise SchemaError(f"unknown key {str(key)!r}{place}{nearest(str(key), self.fields)}; known: "
                                  f"{', '.join(self.fields)}")
        return {k: spec.check(value[k], child_where(where, k, _is_section(spec))) for k, spec in self.fields.items()
                if k in value}


@dataclass(frozen=True)
class TableOf:
    """A table of tables whose names the user picks (``[joystick.mappings.NAME]``), each checked by ``item``."""

    item: Spec
    section: bool = True
    max_len: int = 64

    def describe(self) -> str:
        return f"a table of at most {self.max_len} named tables"

    def check(self, value: Any, where: str) -> dict[str, Any]:
        if not isinstance(value, Mapping) or len(value) > self.max_len:
            raise _fail(where, self, value)
        return {k: self.item.check(v, child_where(where, k, _is_section(self.item))) for k, v in value.items()}


def _is_section(spec: Spec) -> bool:
    return bool(getattr(spec, "section", False))


def one_line(text: str, limit: int = 300) -> str:
    """Any message made safe to print as one line (library messages may carry newlines or control bytes)."""
    flat = " ".join(str(text).split())
    return flat if len(flat) <= limit else flat[: limit - 1] + "…"
