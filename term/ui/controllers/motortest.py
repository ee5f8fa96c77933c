"""The terminal's side of the bench motor test (Op.MOTOR_TEST; the board's guards: docs/modes.md, "The motor
test"). The app owns one; the motor test screen asks it to start and stop, the app tells it of every key and of
every render tick.

- ``start(mask, level)`` only in SAFE on a live link (else a reason, said in the events list); one command per
  start: the board runs it for at most MOTOR_TEST_MAX_MS by itself.
- ``stop(why)`` sends level 0 (the board also stops by itself, so a lost stop costs at most its own limits).
- Any key while a test runs stops it (the app calls ``key()`` before anything else sees the key), leaving the screen
  stops it, and a lost link ends it here at once (the board stops after MOTOR_TEST_LINK_MS of silence).
- ``tick(model, now)`` follows the board: its MOTOR_TEST event or flag ends the run here; so does the board's own
  time limit passing (with a margin), whatever was heard.
"""

from __future__ import annotations

from collections.abc import Callable

from term.core.protocol import (
    MOTOR_TEST_MAX_LEVEL,
    MOTOR_TEST_MAX_MS,
    EventCode,
    Flag,
    Mode,
    MotorTestEnd,
    Op,
    motor_test_arg,
)
from term.session.model import Model

END_TEXT = {MotorTestEnd.TIME_UP: f"{MOTOR_TEST_MAX_MS / 1000:g} s up (the board's limit)",
            MotorTestEnd.STOPPED: "stopped", MotorTestEnd.LINK_SILENT: "the board heard nothing from the terminal",
            MotorTestEnd.MODE: "the mode changed", MotorTestEnd.LIFT: "the lift left zero"}
MARGIN_S = 0.5  # past the board's limit, the run is over here too


def end_text(arg: int) -> str:
    try:
        return END_TEXT[MotorTestEnd(arg)]
    except (ValueError, KeyError):
        return f"reason {arg}"


class MotorTestController:
    def __init__(self, send: Callable[[Op, int], int | None], note: Callable[[str, str, str], None],
                 clock: Callable[[], float]) -> None:
        self.send, self.note, self.clock = send, note, clock
        self.running = False
        self.mask = 0
        self.level = 0
        self.started = 0.0
        self.last_end = ""  # why the last run ended, for the screen
        self._event_seen = -1.0  # the time of the board's last MOTOR_TEST event already taken
        self._notes_at_start = 0  # the events list's count when the run was asked for (its refusal comes after)

    def refusal(self, model: Model) -> str | None:
        """Why a test cannot start now (the board would refuse too; said first, with the fix)."""
        if model.link_lost or not model.heard:
            return "no link to the board"
        if model.mode != Mode.SAFE:
            return "only in SAFE (press 0)"
        return None

    def start(self, model: Model, mask: int, level: int) -> bool:
        why = self.refusal(model)
        if why is not None:
            self.note("error", "term", f"motor test not started: {why}")
            return False
        level = max(0, min(MOTOR_TEST_MAX_LEVEL, level))
        if self.send(Op.MOTOR_TEST, motor_test_arg(mask, level)) is None:
            return False
        self.running, self.mask, self.level, self.started = True, mask, level, self.clock()
        self._event_seen = model.event_times.get(EventCode.MOTOR_TEST, -1.0)
        self._notes_at_start = model.notes_written
        self.last_end = ""
        return True

    def stop(self, why: str) -> None:
        if not self.running:
            return
        self.running = False
        self.last_end = why
        self.send(Op.MOTOR_TEST, 0)
        self.note("info", "term", f"motor test stopped: {why}")

    def key(self) -> bool:
        """A key was pressed: a running test stops; whether it did (the key is then spent)."""
        if self.running:
            self.stop("a key was pressed")
            return True
        return False

    def tick(self, model: Model, now: float) -> None:
        if not self.running:
            return
        if model.link_lost:
            self.running = False
            self.last_end = "link lost: the board stops by itself"
            self.note("error", "term", f"motor test: {self.last_end}")
            return
        refused = self._refusal_heard(model)
        t = model.event_times.get(EventCode.MOTOR_TEST, -1.0)
        if refused is not None:  # the board said no (its NAK, in the events list), or the command never got there
            self.running = False
            self.last_end = refused
        elif t > self._event_seen:
            self._event_seen = t
            self.running = False
            self.last_end = end_text(model.event_args.get(EventCode.MOTOR_TEST, 0))
        elif now - self.started > MOTOR_TEST_MAX_MS / 1000 + MARGIN_S:
            self.running = False
            self.last_end = END_TEXT[MotorTestEnd.TIME_UP]

    def _refusal_heard(self, model: Model) -> str | None:
        for e in reversed(model.events):
            if e.seq <= self._notes_at_start:
                return None
            if e.source in ("nak", "link") and "motor test: mask" in e.text:
                return e.text
        return None

    @staticmethod
    def board_running(model: Model) -> bool:
        return bool(model.flags & Flag.MOTOR_TEST)
