"""Numbers from outside, parsed once and strictly: the one place every surface (the command line, parameter and
config files, the parameter screen, the simulator's instructor channel) turns what a user gave into a number.

- ``parse_number(text, name, lo, hi, ...)``: typed text. ASCII only (a full-width ``１`` or an Arabic-Indic digit is
  not a digit here), no ``_`` separators, no hex, no ``nan``/``inf``, at most ``TEXT_MAX`` characters; spaces
  around it are allowed, any other whitespace or control character is not;
- ``check_number(value, name, lo, hi, ...)``: a value a parser already made (TOML, JSON): a real int or float, not
  a bool, finite, inside ``lo..hi`` compared exactly (a 400-digit integer is out of range, never an OverflowError).

Both check the range BEFORE any scaling, so nothing huge ever reaches ``round`` or ``int``; both raise
``NumberError`` whose message is one line naming the field: ``ctrl.p1 must be a number from 0 to 10, got 1e308``.
Standard library only (``fcb_sim`` uses it for the instructor's numbers).
"""

from __future__ import annotations

import argparse
import math
import re
from typing import Any

TEXT_MAX = 40  # characters of typed number: more is not a number a pilot means
SHOWN_MAX = 40
_NUMBER = re.compile(r"[+-]?(?:[0-9]+(?:\.[0-9]*)?|\.[0-9]+)(?:[eE][+-]?[0-9]{1,4})?", re.ASCII)
_INTEGER = re.compile(r"[+-]?[0-9]+", re.ASCII)


class NumberError(ValueError):
    """A number that cannot be used; the message is one line naming the field."""


def shown_text(value: Any) -> str:
    """``value`` quoted back on one line, short, control characters escaped."""
    if isinstance(value, str):
        text = '"' + value.encode("unicode_escape").decode("ascii") + '"'
    elif isinstance(value, bool):
        text = "true" if value else "false"
    elif isinstance(value, int) and abs(value) >= 10**SHOWN_MAX:
        text = ("-" if value < 0 else "") + f"a {len(str(abs(value)))}-digit integer"
    else:
        text = repr(value)
    text = " ".join(text.split())
    return text if len(text) <= SHOWN_MAX else text[: SHOWN_MAX - 1] + "…"


def finite(value: Any) -> bool:
    """A real number (an int of any size, a float), not a bool, not nan or inf; never raises."""
    if isinstance(value, bool) or not isinstance(value, int | float):
        return False
    return isinstance(value, int) or math.isfinite(value)


def _fmt(x: float) -> str:
    if not math.isfinite(x) or abs(x) < 1e6 or x != int(x):
        return f"{x:g}"
    return str(int(x))


def allowed(lo: float, hi: float, integer: bool = False, unit: str = "") -> str:
    kind = "a whole number" if integer else "a number"
    return f"{kind} from {_fmt(lo)} to {_fmt(hi)}" + (f" {unit}" if unit else "")


def check_number(value: Any, name: str, lo: float, hi: float, *, integer: bool = False, unit: str = "",
                 what: str | None = None) -> int | float:
    """``value`` (an int or float from a parser) if it is finite and inside ``lo..hi``; else NumberError.
    ``integer``: a float with a fraction is refused (3.0 is 3). ``what``: how the refusal shows what was given."""
    given = what if what is not None else shown_text(value)
    refusal = NumberError(f"{name} must be {allowed(lo, hi, integer, unit)}, got {given}")
    if not finite(value):
        raise refusal
    if not lo <= value <= hi:  # exact for ints of any size: no float conversion before the range
        raise refusal
    if integer:
        if isinstance(value, float) and not value.is_integer():
            raise refusal
        return int(value)
    return float(value)


def parse_number(text: str, name: str, lo: float, hi: float, *, integer: bool = False,
                 unit: str = "") -> int | float:
    """Typed ``text`` as a number inside ``lo..hi`` (module docstring); else NumberError of one line."""
    given = shown_text(text)
    if not isinstance(text, str):
        raise NumberError(f"{name} must be {allowed(lo, hi, integer, unit)}, got {given}")
    t = text.strip(" ")
    if len(t) > TEXT_MAX or not _NUMBER.fullmatch(t):
        raise NumberError(f"{name} must be {allowed(lo, hi, integer, unit)}, got {given}")
    value: int | float = int(t) if _INTEGER.fullmatch(t) else float(t)
    return check_number(value, name, lo, hi, integer=integer, unit=unit, what=given)


# --- command-line options ----------------------------------------------------------------------------------------
# argparse types: the syntax only (the range is the option's own check, with its own message); "nan" and "inf"
# pass as words so that check names them.
_WORD = re.compile(r"[+-]?(nan|inf|infinity)", re.ASCII | re.IGNORECASE)


def cli_float(text: str) -> float:
    """``type=`` for a number option: ASCII digits, no ``_``, no full-width or other scripts' digits."""
    t = text.strip(" ")
    if len(t) > TEXT_MAX or not (_NUMBER.fullmatch(t) or _WORD.fullmatch(t)):
        raise argparse.ArgumentTypeError(f"invalid float value: {_cli_shown(text)} (ASCII digits, like 0.5 or 2e-3)")
    return float(t)


def cli_int(text: str) -> int:
    """``type=`` for a whole-number option: ASCII digits only (``1_0`` and ``１`` are not 10 and 1)."""
    t = text.strip(" ")
    if len(t) > TEXT_MAX or not _INTEGER.fullmatch(t):
        raise argparse.ArgumentTypeError(f"invalid int value: {_cli_shown(text)} (ASCII digits only)")
    return int(t)


def _cli_shown(text: str) -> str:
    """As argparse quotes a value (``'abc'``), short and on one line."""
    shown = repr(text)  # escaped: a control character or another script's digit is seen as what it is
    return shown if len(shown) <= SHOWN_MAX else shown[: SHOWN_MAX - 1] + "…"
