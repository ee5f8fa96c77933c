"""The board's console, sans-IO: the text a board prints between frames (printf on the UART) and its own debug lines
(Text packets, ``qb_log``) as lines, each with a level, under a rate limit.

- ``Console.feed_bytes(data, now)``: text bytes from a decoder with ``keep_text`` (term.core.protocol.Decoder); a
  line ends at LF (CR is dropped); a line longer than ``max_line`` is cut there and marked ``cut``.
- ``Console.feed_packet(pkt, now)``: a ``Text`` packet; pieces with ``TEXT_MORE`` are joined until the last.
- Both give ``ConsoleLine``s. Level: a Text packet's own; a printed line's from its words (``level_of``: assert,
  fault, panic, error ... error; warn ... warning; debug ... debug; else info).
- Rate limit: a token bucket (``rate`` lines a second, bursts of ``burst``) over both sources together: a board
  spewing text cannot flood the screen, the events list or an export. What it drops is counted (``dropped``), said
  at once by a ``ConsoleDropped`` at the end of the feed that dropped it (a board that spews then falls silent has
  no next line to say it), and the next line that passes says how many went before it (``ConsoleLine.dropped``).
- Text from the board is hostile until read: bytes are decoded with replacement, control characters (escape
  sequences) become spaces, so nothing the board prints can drive the terminal.

Nothing here reads a clock: ``now`` is the caller's, in seconds.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

from term.core.protocol import LEVEL_DEBUG, LEVEL_ERROR, LEVEL_INFO, LEVEL_WARNING, TEXT_LEVEL_MASK, TEXT_MORE, Text

CONSOLE_RATE = 20.0  # lines a second, on average
CONSOLE_BURST = 50  # lines at once (a board's boot banner)
CONSOLE_MAX_LINE = 200  # characters; a longer line is cut
UART, BOARD = "uart", "board"  # the sources: printed between frames, Text packets

_ERROR = re.compile(r"\b(assert\w*|fault|hard ?fault|panic|error|err|fail\w*|abort\w*|fatal)\b|^\s*(E|\[E\])[:\] ]",
                    re.IGNORECASE)
_WARNING = re.compile(r"\b(warn\w*)\b|^\s*(W|\[W\])[:\] ]", re.IGNORECASE)
_DEBUG = re.compile(r"\b(debug|dbg|trace)\b|^\s*(D|\[D\])[:\] ]", re.IGNORECASE)
_CONTROL = re.compile(r"[\x00-\x08\x0a-\x1f\x7f-\x9f]")


@dataclass(frozen=True, slots=True)
class ConsoleLine:
    """One line of the board's text: ``source`` UART (printed between frames) or BOARD (Text packets)."""

    text: str
    level: int  # 1 debug .. 5 fatal (foxglove.Log's levels)
    source: str
    dropped: int = 0  # lines the rate limit dropped just before this one
    cut: bool = False  # longer than the console keeps: the rest was dropped


@dataclass(frozen=True, slots=True)
class ConsoleDropped:
    """Lines one feed dropped by the rate limit (``count``), from ``source``."""

    count: int
    source: str


ConsoleEvent = ConsoleLine | ConsoleDropped


def level_of(text: str) -> int:
    """A printed line's level, from its words."""
    if _ERROR.search(text):
        return LEVEL_ERROR
    if _WARNING.search(text):
        return LEVEL_WARNING
    if _DEBUG.search(text):
        return LEVEL_DEBUG
    return LEVEL_INFO


def clean(text: str) -> str:
    """Control characters (escape sequences, bells, NULs) as spaces; tabs kept."""
    return _CONTROL.sub(" ", text)


class Console:
    """Lines from one link's text, rate-limited (module docstring)."""

    def __init__(self, rate: float = CONSOLE_RATE, burst: int = CONSOLE_BURST,
                 max_line: int = CONSOLE_MAX_LINE) -> None:
        self.rate, self.burst, self.max_line = rate, burst, max_line
        self.lines = 0  # passed the limit
        self.dropped = 0  # dropped by it, since the start
        self._tokens = float(burst)
        self._at: float | None = None
        self._since_pass = 0  # dropped since the last line that passed
        self._uart = bytearray()
        self._uart_cut = False  # the line being collected was cut: the rest up to its LF is dropped
        self._board = bytearray()
        self._board_level = LEVEL_INFO

    def feed_bytes(self, data: bytes, now: float) -> list[ConsoleEvent]:
        out: list[ConsoleEvent] = []
        before = self.dropped
        buf = self._uart
        for part in re.split(rb"(\n)", data):
            if part == b"\n":
                if not self._uart_cut:
                    self._line(bytes(buf), None, UART, now, out, False)
                buf.clear()
                self._uart_cut = False
                continue
            if self._uart_cut:
                continue
            buf += part.replace(b"\r", b"")
            if len(buf) > self.max_line:
                self._line(bytes(buf[: self.max_line]), None, UART, now, out, True)
                buf.clear()
                self._uart_cut = True
        return self._said_drops(out, before, UART)

    def feed_packet(self, pkt: Text, now: float) -> list[ConsoleEvent]:
        out: list[ConsoleEvent] = []
        before = self.dropped
        if not self._board:
            self._board_level = pkt.info & TEXT_LEVEL_MASK or LEVEL_INFO
        self._board += pkt.text.rstrip(b"\x00")
        cut = len(self._board) > self.max_line * 4  # UTF-8: at most four bytes a character
        if not pkt.info & TEXT_MORE or cut:
            self._line(bytes(self._board), self._board_level, BOARD, now, out, cut)
            self._board.clear()
        return self._said_drops(out, before, BOARD)

    def _said_drops(self, out: list[ConsoleEvent], before: int, source: str) -> list[ConsoleEvent]:
        if self.dropped > before:
            out.append(ConsoleDropped(self.dropped - before, source))
        return out

    def _line(self, raw: bytes, level: int | None, source: str, now: float, out: list[ConsoleEvent],
              cut: bool) -> None:
        text = clean(raw.decode("utf-8", "replace")).rstrip()
        if len(text) > self.max_line:
            text, cut = text[: self.max_line], True
        if not self._take(now):
            self.dropped += 1
            self._since_pass += 1
            return
        self.lines += 1
        out.append(ConsoleLine(text, level_of(text) if level is None else level, source, self._since_pass, cut))
        self._since_pass = 0

    def _take(self, now: float) -> bool:
        """A token from the bucket, refilled at ``rate`` a second since the last call."""
        if self._at is not None and now > self._at:
            self._tokens = min(float(self.burst), self._tokens + (now - self._at) * self.rate)
        if self._at is None or now > self._at:
            self._at = now
        if self._tokens >= 1.0:
            self._tokens -= 1.0
            return True
        return False
