"""The bench motor test (Op.MOTOR_TEST): one motor or all at a chosen level for a few seconds, props off, to check
wiring, order and direction before a first flight (Betaflight's Motors tab, QGroundControl's motor test).

The board keeps its own guard, whatever the terminal does (docs/modes.md, "The motor test"):

- refused out of SAFE (NOT_IN_SAFE), with the lift (joystick plus trim) above LIFT_ZERO (LIFT_NOT_ZERO), with a
  crash not acknowledged (CRASHED), a level above MOTOR_TEST_MAX_LEVEL (OUT_OF_RANGE: under hover, so even all
  four with props on cannot lift the craft) or a mask outside the four motors (BAD_ARGUMENT);
- a run lasts at most MOTOR_TEST_MAX_MS from the command that started it (a new command starts a new run);
- it stops by itself, with ``Event(MOTOR_TEST, MotorTestEnd)``, when that time is up, on a MOTOR_TEST with level 0,
  on any mode change, when the lift leaves zero, and after MOTOR_TEST_LINK_MS without a frame from the terminal.

Sans-IO: times in seconds are passed in; the mode machine is passed in (its mode, lift, crash flag, and ``emit``
for the event). The C board's twin is firmware/board/qb_motortest.c.
"""

from __future__ import annotations

from typing import Any

from term.core.protocol import (
    LIFT_ZERO,
    MOTOR_COUNT,
    MOTOR_TEST_LINK_MS,
    MOTOR_TEST_MAX_LEVEL,
    MOTOR_TEST_MAX_MS,
    EventCode,
    Mode,
    MotorTestEnd,
    Nak,
    motor_test_split,
)

ALL_MOTORS = (1 << MOTOR_COUNT) - 1


class MotorTest:
    """One board's motor test (module docstring): ``request`` from the command, ``output`` from the control task."""

    def __init__(self) -> None:
        self.mask = 0
        self.level = 0
        self.until: float | None = None  # s: when the running test stops by itself; None: not running

    @property
    def running(self) -> bool:
        return self.until is not None

    def request(self, modes: Any, arg: int, now: float) -> tuple[Nak, int]:
        """Op.MOTOR_TEST: (Nak, the level now running)."""
        mask, level = motor_test_split(arg)
        if level == 0 or mask == 0:
            if self.running:
                self.stop(modes, MotorTestEnd.STOPPED, now)
            return Nak.OK, 0
        reason = self.refusal(modes, mask, level)
        if reason != Nak.OK:
            return reason, self.level if self.running else 0
        self.mask, self.level, self.until = mask, level, now + MOTOR_TEST_MAX_MS / 1000
        return Nak.OK, level

    @staticmethod
    def refusal(modes: Any, mask: int, level: int) -> Nak:
        if modes.mode != Mode.SAFE:
            return Nak.NOT_IN_SAFE
        if modes.crashed:
            return Nak.CRASHED
        if modes.lift > LIFT_ZERO:
            return Nak.LIFT_NOT_ZERO
        if mask & ~ALL_MOTORS:
            return Nak.BAD_ARGUMENT
        if level > MOTOR_TEST_MAX_LEVEL:
            return Nak.OUT_OF_RANGE
        return Nak.OK

    def output(self, modes: Any, now: float, link_silent_s: float) -> tuple[int, int, int, int] | None:
        """The motor commands while a test runs (None: not running, the board's own apply); stops it first when
        one of its limits is reached."""
        if self.until is None:
            return None
        reason = (MotorTestEnd.MODE if modes.mode != Mode.SAFE else
                  MotorTestEnd.LIFT if modes.lift > LIFT_ZERO else
                  MotorTestEnd.LINK_SILENT if link_silent_s * 1000 >= MOTOR_TEST_LINK_MS else
                  MotorTestEnd.TIME_UP if now >= self.until else None)
        if reason is not None:
            self.stop(modes, reason, now)
            return None
        lv, m = self.level, self.mask
        return (lv if m & 1 else 0, lv if m & 2 else 0, lv if m & 4 else 0, lv if m & 8 else 0)

    def stop(self, modes: Any, reason: MotorTestEnd, now: float) -> None:
        self.mask = self.level = 0
        self.until = None
        modes.emit(EventCode.MOTOR_TEST, int(reason), now)
