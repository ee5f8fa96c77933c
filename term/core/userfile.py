"""The one reader of files a user hands us (config, parameter sets, lessons, joystick mappings, recordings, logs).

Every such file is hostile until read. ``read_user_file(path, limit, kind)`` returns its bytes, or raises
``UserFileError`` whose message is one line naming ``kind`` and the path:

- regular files only: a FIFO, a device (``/dev/zero``, a symlink to it), a socket or a directory is refused from
  ``os.stat`` before it is opened, and the open itself is non-blocking, so a FIFO swapped in never hangs us;
- a size cap (``limit`` bytes): checked on the size the file claims and again on what is read (a file that grows);
- ``read_user_text``: UTF-8 with the offending byte named; ``read_user_toml``: TOML whose nesting is bounded
  (``MAX_DEPTH`` brackets or braces deep; Python's parser would otherwise die with RecursionError), the schema
  check is the caller's (term/core/schema.py, the parameter table, the lesson reader);
- ``open_user_file``: the same checks, then a binary file object for a reader that streams (recordings, logs).

Standard library only; no I/O beyond the one file.
"""

from __future__ import annotations

import io
import os
import stat
import tomllib
from pathlib import Path
from typing import Any, BinaryIO

MAX_DEPTH = 64  # nested [ or { in a TOML file: our files nest 3 deep; Python's parser fails near 1000
RECORDING_MAX_BYTES = 8_000_000_000  # a session recording (MCAP): hours of telemetry; a cap all the same
LOG_MAX_BYTES = 256_000_000  # a flash-log CSV (the board's flash is 128 kB: a few MB of text)


class UserFileError(ValueError):
    """A file we cannot use; the message is one line: what it was for, its path, why."""


def _what(mode: int) -> str:
    if stat.S_ISDIR(mode):
        return "a directory"
    if stat.S_ISFIFO(mode):
        return "a FIFO (named pipe)"
    if stat.S_ISCHR(mode) or stat.S_ISBLK(mode):
        return "a device"
    if stat.S_ISSOCK(mode):
        return "a socket"
    return "not a regular file"


def _kb(limit: int) -> str:
    return f"{limit // 1_000_000} MB" if limit >= 1_000_000 else f"{max(1, limit // 1000)} kB"


def open_user_file(path: Path | str, limit: int, kind: str) -> BinaryIO:
    """``path`` opened for reading if it is a regular file of at most ``limit`` bytes (module docstring)."""
    path = Path(path)
    try:
        st = os.stat(path)
    except OSError as exc:
        raise UserFileError(f"cannot read {kind} {path}: {exc.strerror or exc}") from None
    if not stat.S_ISREG(st.st_mode):
        raise UserFileError(f"{kind} {path} is {_what(st.st_mode)}, not a file")
    if st.st_size > limit:
        raise UserFileError(f"{kind} {path} is larger than {_kb(limit)}")
    # Non-blocking where there is O_NONBLOCK (POSIX): if a FIFO was swapped in since the stat, the open returns at
    # once. Windows has neither O_NONBLOCK nor FIFOs in its file system, and needs O_BINARY (no newline translation).
    flags = os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_NOCTTY", 0) | getattr(os, "O_BINARY", 0)
    try:
        fd = os.open(path, flags)
    except OSError as exc:
        raise UserFileError(f"cannot read {kind} {path}: {exc.strerror or exc}") from None
    try:
        st = os.fstat(fd)
        if not stat.S_ISREG(st.st_mode):
            raise UserFileError(f"{kind} {path} is {_what(st.st_mode)}, not a file")
        if flags & getattr(os, "O_NONBLOCK", 0):
            os.set_blocking(fd, True)
        return io.open(fd, "rb", closefd=True)  # noqa: UP020 (an fd, not a path)
    except BaseException:
        os.close(fd)
        raise


def read_user_file(path: Path | str, limit: int, kind: str) -> bytes:
    """The bytes of ``path`` (a regular file of at most ``limit`` bytes), else one UserFileError line."""
    with open_user_file(path, limit, kind) as f:
        try:
            data = f.read(limit + 1)
        except OSError as exc:
            raise UserFileError(f"cannot read {kind} {path}: {exc.strerror or exc}") from None
    if len(data) > limit:
        raise UserFileError(f"{kind} {path} is larger than {_kb(limit)}")
    return data


def read_user_text(path: Path | str, limit: int, kind: str) -> str:
    """``read_user_file`` as UTF-8 text (a bad byte is named with its offset)."""
    data = read_user_file(path, limit, kind)
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise UserFileError(f"{kind} {path} is not UTF-8 text (byte {data[exc.start]:#04x} at offset "
                            f"{exc.start})") from None


def toml_depth(text: str) -> int:
    """The deepest nesting of ``[`` and ``{`` outside strings and comments (an upper bound is enough: a table
    header's brackets count too)."""
    depth = deepest = 0
    i, n = 0, len(text)
    while i < n:
        c = text[i]
        if c in "\"'":
            triple = text.startswith(c * 3, i)
            end = text.find(c * 3 if triple else c, i + (3 if triple else 1))
            while not triple and c == '"' and end > 0 and _escaped(text, end):
                end = text.find(c, end + 1)
            while triple and c == '"' and end > 0 and _escaped(text, end):
                end = text.find(c * 3, end + 1)
            if end < 0:
                return deepest  # an open string: the parser says so
            i = end + (3 if triple else 1)
            continue
        if c == "#":
            nl = text.find("\n", i)
            i = n if nl < 0 else nl
            continue
        if c in "[{":
            depth += 1
            deepest = max(deepest, depth)
        elif c in "]}":
            depth = max(0, depth - 1)
        i += 1
    return deepest


def _escaped(text: str, at: int) -> bool:
    back = 0
    while at - back - 1 >= 0 and text[at - back - 1] == "\\":
        back += 1
    return back % 2 == 1


def parse_toml(text: str, where: str, max_depth: int = MAX_DEPTH) -> dict[str, Any]:
    """``text`` parsed as TOML if it nests at most ``max_depth`` deep; else one UserFileError line naming
    ``where`` (the kind and the path)."""
    if toml_depth(text) > max_depth:
        raise UserFileError(f"{where} is not usable TOML: its values nest too deeply (over {max_depth} levels)")
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise UserFileError(" ".join(f"{where} is not valid TOML: {exc}".split())) from None
    except (RecursionError, MemoryError):
        raise UserFileError(f"{where} is not usable TOML: its values nest too deeply") from None
    except ValueError:  # an integer of more than 4300 digits: Python refuses to convert it
        raise UserFileError(f"{where} is not usable TOML: a number with thousands of digits") from None


def read_user_toml(path: Path | str, limit: int, kind: str, max_depth: int = MAX_DEPTH) -> dict[str, Any]:
    """A TOML file a user hands us: ``read_user_text`` then ``parse_toml`` (the schema check is the caller's)."""
    return parse_toml(read_user_text(path, limit, kind), f"{kind} {path}", max_depth)
