"""The mode table: one row per board mode, the one place a mode's face is written.

The board's behaviour in a mode lives with the board (fcb_sim/board/modes.py and flight.py, their C twins); what
everything else shows or binds is read from here: the key map (term/input/keymap.py), the footer (term/ui/app.py),
the phone's buttons (term/session/phone.py), the mode banner's colour (term/ui/widgets/mode.py), FLIGHT_MODES (the
board, the generated C header) and docs/architecture.md's walk-through of adding a mode.

A row: the lab's keys (Textual key names; none for a mode entered by its own command, as WIRELESS is), the short
label of the footer and the phone, the help line of the key map, the banner's Rich style, whether the phone has a
button for it, whether the flight core drives the motors in it, and what entering it needs (the board's guards,
in words, for the docs and the help).
"""

from __future__ import annotations

from dataclasses import dataclass

from term.core.protocol.facts import Mode


@dataclass(frozen=True, slots=True)
class ModeSpec:
    mode: Mode
    keys: tuple[str, ...]  # the lab's keys (DESIGN.md); () when another command enters it
    label: str  # the footer's and the phone's word
    help: str  # the key map's line (F1)
    style: str  # the mode banner's Rich style
    phone: bool  # a button on the phone (F10)
    flight: bool  # the flight core drives the motors (FLIGHT_MODES)
    needs: str  # what entering it needs, in words (the board's guards say it exactly)

    @property
    def action(self) -> str:
        """The key map's action name: ``mode_safe``, ``mode_full``, ..."""
        return f"mode_{self.mode.name.lower()}"


_NEUTRAL = "SAFE, lift and sticks neutral, no crash unacknowledged, battery fine"

MODE_TABLE: dict[Mode, ModeSpec] = {s.mode: s for s in (
    ModeSpec(Mode.SAFE, ("0",), "SAFE", "SAFE: motors off", "bold black on green", True, False,
             "lift at zero from a flight mode; always from CALIBRATION"),
    ModeSpec(Mode.PANIC, ("1", "escape"), "PANIC", "PANIC: controlled descent, then SAFE", "bold blink white on red",
             False, False, "a flight mode or CALIBRATION (keys 1, Esc, the fire button), or a safety monitor"),
    ModeSpec(Mode.MANUAL, ("2",), "MANUAL", "MANUAL: sticks straight to the motors", "bold black on yellow", True,
             True, _NEUTRAL),
    ModeSpec(Mode.CALIBRATION, ("3",), "CALIB", "CALIBRATION: zero the sensors (board level, still)",
             "bold black on cyan", True, False, "SAFE, lift and sticks neutral, no crash unacknowledged"),
    ModeSpec(Mode.YAW, ("4",), "YAW", "YAW control", "bold white on blue", True, True, _NEUTRAL + ", calibrated"),
    ModeSpec(Mode.FULL, ("5",), "FULL", "FULL control (roll, pitch, yaw)", "bold white on blue", True, True,
             _NEUTRAL + ", calibrated"),
    ModeSpec(Mode.RAW, ("6",), "RAW", "RAW: unfiltered sensors, on-board filter", "bold white on magenta", True,
             True, _NEUTRAL + ", calibrated"),
    ModeSpec(Mode.HEIGHT, ("7",), "HEIGHT", "HEIGHT hold", "bold white on dark_blue", True, True,
             "FULL or RAW (back to where it came from)"),
    ModeSpec(Mode.WIRELESS, (), "WIRELESS", "WIRELESS handover to BLE (key 8, in SAFE)", "bold black on bright_cyan",
             False, False, "SAFE, the key 8, then data over BLE (the report's rule)"),
)}

# Modes in which the motors may turn under the flight core (PANIC drives them too, from its own profile).
FLIGHT_MODES: frozenset[Mode] = frozenset(m for m, s in MODE_TABLE.items() if s.flight)
