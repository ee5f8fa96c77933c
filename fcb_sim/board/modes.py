"""The board's mode state machine: a table of transitions with guards, and tables of enter and leave actions.

The report (3.2) kept two arrays of function pointers, one called when a mode is left and one when a mode is
entered, and a check that decides whether a transition is valid. Here the same three things are data:

- ``TRANSITIONS``: one row per allowed (source, target) pair, with the guards that must all pass and what
  triggers it (a pilot's request, or the machine itself: a timer, a safety monitor);
- ``ENTER`` and ``LEAVE``: per mode, the action run on entering and on leaving it.

The mode diagram in docs/modes.md is generated from these tables (``mermaid()``), so it cannot drift.

Safety rules (DESIGN.md): leaving SAFE needs neutral sticks and zero lift (joystick plus trims); modes 4 and up
need a finished calibration; from a flight mode the way out is SAFE (with the lift at zero) or PANIC; PANIC is
reachable from every mode that can turn the motors, holds a level just under hover for a few seconds, ramps the
motors to zero and then returns to SAFE by itself; link silence, a low battery while flying and excessive tilt
mean PANIC; the motors are zero in SAFE and CALIBRATION. Every refused request returns a ``Nak`` reason.

Sans-IO: time (``now``, seconds) is passed in; the machine reads no clock. Pilot inputs (joystick, trims),
the battery and the motor level are pushed in by the board; events for the PC come out of ``events``.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field

from fcb_sim.board.calibration import CalibrationSums
from fcb_sim.board.motortest import MotorTest
from fcb_sim.world import constants as P
from term.core.protocol import (
    BATTERY_LOW,
    FLIGHT_MODES,
    HEIGHT_KEY_STEP_MM,
    HEIGHT_SETPOINT_MAX_MM,
    HEIGHT_SETPOINT_MIN_MM,
    LIFT_ZERO,
    LOW_BATTERY_HOLD_S,
    MOTOR_TEST_LINK_MS,
    MOTOR_TEST_MAX_LEVEL,
    MOTOR_TEST_MAX_MS,
    PARAMS,
    STICK_MAX,
    STICK_NEUTRAL,
    EventCode,
    Joystick,
    Mode,
    MotorTestEnd,
    Nak,
    Param,
    lift_trim_after,
)

# FLIGHT_MODES (the motors may turn under the flight core), LIFT_ZERO and STICK_NEUTRAL (the guards for leaving
# SAFE) and the battery threshold are protocol facts: the terminal checks the same numbers.
MOTORS_OFF_MODES = frozenset({Mode.SAFE, Mode.CALIBRATION})
TRIM_LIMIT = 8192  # roll/pitch/yaw trims stay within a quarter of full deflection


@dataclass
class ModeConfig:
    """Tunables of the machine; the defaults are the team's safety decisions."""

    link_timeout_s: float = PARAMS[Param.LINK_TIMEOUT_MS].default / 1000  # silence before stage 1 (or PANIC)
    link_failsafe_s: float = PARAMS[Param.LINK_FAILSAFE_MS].default / 1000  # stage 1's guard; 0: PANIC at once
    panic_level: int = 350  # PANIC's reference level: just under hover (about 400); the descent loop trims it
    panic_ramp_s: float = 1.5  # motors to zero over this once the ground is sensed
    panic_timeout_s: float = 300.0  # the ground not sensed by then (CEILING_M at 1-3 m/s): ramp to zero anyway
    # CALIBRATION averages this long, then returns to SAFE by itself; 0: for as long as the pilot holds it (report)
    calibration_s: float = PARAMS[Param.CALIBRATION_MS].default / 1000
    # PANIC: 0 descends at a bounded rate until the ground; else the report's countdown: a level this long, then off
    panic_countdown_s: float = PARAMS[Param.PANIC_COUNTDOWN_MS].default / 1000
    calibration_min_samples: int = 50
    tilt_limit_cdeg: int = 5000  # 50°
    low_battery: int = BATTERY_LOW  # 10 mV units: 10.5 V
    trim_step: int = int(PARAMS[Param.TRIM_STEP].default)  # roll, pitch, yaw trim per key press (stick units)
    lift_step: int = int(PARAMS[Param.LIFT_STEP].default)  # lift trim per key press (1 %; finer near hover)


@dataclass
class Trims:
    """Keyboard trims: they add to the joystick (which is absolute)."""

    roll: int = 0
    pitch: int = 0
    yaw: int = 0
    lift: int = 0


@dataclass(frozen=True)
class Guard:
    """A transition condition: ``check(machine)`` returns Nak.OK or the reason the transition is refused."""

    label: str
    check: Callable[[ModeMachine], Nak]


@dataclass(frozen=True)
class Transition:
    source: Mode
    target: Mode
    guards: tuple[Guard, ...] = ()
    trigger: str = "request"  # "request": the pilot asks; "auto": the machine takes it by itself
    note: str = ""


@dataclass
class ModeChange:
    old: Mode
    new: Mode
    now: float
    reason: str  # "request", "panic:<why>", "auto"


# --- guards -------------------------------------------------------------------------------------------------


def _zero_lift(m: ModeMachine) -> Nak:
    return Nak.OK if m.lift <= LIFT_ZERO else Nak.LIFT_NOT_ZERO


def _neutral_sticks(m: ModeMachine) -> Nak:
    # What the motors would get: joystick plus trims (a trimmed-in roll is a roll command like the stick's).
    roll, pitch, yaw, _ = m.sticks()
    ok = abs(roll) <= STICK_NEUTRAL and abs(pitch) <= STICK_NEUTRAL and abs(yaw) <= STICK_NEUTRAL
    return Nak.OK if ok else Nak.STICKS_NOT_NEUTRAL


def _calibrated(m: ModeMachine) -> Nak:
    return Nak.OK if m.calibrated else Nak.NOT_CALIBRATED


def _battery_ok(m: ModeMachine) -> Nak:
    if m.battery_low_latched:
        return Nak.BATTERY_LOW  # a pack that sagged under load once recovers at rest: it is still flat
    return Nak.OK if m.battery is None or m.battery >= m.config.low_battery else Nak.BATTERY_LOW


def _no_crash(m: ModeMachine) -> Nak:
    return Nak.CRASHED if m.crashed else Nak.OK


def _from_base(m: ModeMachine) -> Nak:
    # HEIGHT flies on top of FULL or RAW; it may only fall back to the one it was entered from.
    return Nak.OK if m.height_base == m.pending_target else Nak.INVALID_TRANSITION


def _panic_done(m: ModeMachine) -> Nak:
    return Nak.OK if m.panic_finished() else Nak.PANIC_ACTIVE


def _calibration_time_up(m: ModeMachine) -> Nak:
    limit = m.config.calibration_s  # 0: no timer, the pilot ends it (the report's)
    return Nak.OK if limit > 0 and m.calibration_elapsed() >= limit else Nak.BUSY


ZERO_LIFT = Guard("lift + trim zero", _zero_lift)
NEUTRAL = Guard("sticks + trims neutral", _neutral_sticks)
CALIBRATED = Guard("calibrated", _calibrated)
BATTERY = Guard("battery ok", _battery_ok)
FROM_BASE = Guard("entered from it", _from_base)
PANIC_DONE = Guard("motors ramped to zero", _panic_done)
NO_CRASH = Guard("no crash unacknowledged", _no_crash)
CAL_TIME = Guard("averaging time up", _calibration_time_up)

_ARM = (ZERO_LIFT, NEUTRAL, NO_CRASH, BATTERY)

TRANSITIONS: tuple[Transition, ...] = (
    Transition(Mode.SAFE, Mode.MANUAL, _ARM),
    Transition(Mode.SAFE, Mode.CALIBRATION, (ZERO_LIFT, NEUTRAL, NO_CRASH)),
    Transition(Mode.SAFE, Mode.YAW, (*_ARM, CALIBRATED)),
    Transition(Mode.SAFE, Mode.FULL, (*_ARM, CALIBRATED)),
    Transition(Mode.SAFE, Mode.RAW, (*_ARM, CALIBRATED)),
    Transition(Mode.CALIBRATION, Mode.SAFE, (CAL_TIME,), "auto", "means taken"),
    Transition(Mode.CALIBRATION, Mode.SAFE, (), "request", "means taken"),
    Transition(Mode.FULL, Mode.HEIGHT, (), "request", "hold the current height"),
    Transition(Mode.RAW, Mode.HEIGHT, (), "request", "hold the current height"),
    Transition(Mode.HEIGHT, Mode.FULL, (FROM_BASE,)),
    Transition(Mode.HEIGHT, Mode.RAW, (FROM_BASE,)),
    *(Transition(m, Mode.SAFE, (ZERO_LIFT,)) for m in sorted(FLIGHT_MODES)),
    *(Transition(m, Mode.PANIC, (), "request", "key 1, ESC, fire; or safety")
      for m in sorted(FLIGHT_MODES | {Mode.CALIBRATION})),
    Transition(Mode.PANIC, Mode.SAFE, (PANIC_DONE,), "auto"),
    *(Transition(m, Mode.SAFE, (), "crash", "impact: motors off, event CRASH")
      for m in sorted(FLIGHT_MODES | {Mode.CALIBRATION, Mode.PANIC})),
)

_ROWS: dict[tuple[Mode, Mode, str], Transition] = {(t.source, t.target, t.trigger): t for t in TRANSITIONS}


# --- enter and leave actions --------------------------------------------------------------------------------


def _enter_safe(m: ModeMachine, now: float) -> None:
    # Lift trim is a flying set point: a fresh flight starts from zero (the report zeroed it on leaving SAFE).
    m.trims.lift = 0


def _enter_calibration(m: ModeMachine, now: float) -> None:
    m.calibration.reset()
    m.calibration_started = now


def _leave_calibration(m: ModeMachine, now: float) -> None:
    n = m.calibration.count
    if n >= m.config.calibration_min_samples:
        m.offsets = m.calibration.means()
        m.calibrated = True
        m.emit(EventCode.CALIBRATION_DONE, n, now)
    # Too few samples (left at once, or a PANIC): the previous calibration, if any, stays in force.


def _enter_panic(m: ModeMachine, now: float) -> None:
    m.panic_started = now
    m.panic_landed_at = None
    # Never spin motors up to enter PANIC: the descent starts from what they ran at (none: nothing to do).
    m.panic_start_level = min(m.config.panic_level, max(0, m.motor_level))


def _leave_panic(m: ModeMachine, now: float) -> None:
    m.emit(EventCode.PANIC_DONE, 0, now)


def _enter_height(m: ModeMachine, now: float) -> None:
    m.height_base = m.previous


def _nothing(m: ModeMachine, now: float) -> None:
    pass


ENTER: dict[Mode, Callable[[ModeMachine, float], None]] = {
    Mode.SAFE: _enter_safe,
    Mode.PANIC: _enter_panic,
    Mode.MANUAL: _nothing,
    Mode.CALIBRATION: _enter_calibration,
    Mode.YAW: _nothing,
    Mode.FULL: _nothing,
    Mode.RAW: _nothing,
    Mode.HEIGHT: _enter_height,
}

LEAVE: dict[Mode, Callable[[ModeMachine, float], None]] = {
    Mode.SAFE: _nothing,
    Mode.PANIC: _leave_panic,
    Mode.MANUAL: _nothing,
    Mode.CALIBRATION: _leave_calibration,
    Mode.YAW: _nothing,
    Mode.FULL: _nothing,
    Mode.RAW: _nothing,
    Mode.HEIGHT: _nothing,
}


# --- the machine --------------------------------------------------------------------------------------------


@dataclass
class ModeMachine:
    """The mode state machine with the pilot inputs it guards on. Drive it with ``request``, ``tick`` and
    ``supervise``; read ``mode``, ``motors_enabled``, ``panic_motor_level``, ``offsets``; drain ``events``."""

    config: ModeConfig = field(default_factory=ModeConfig)
    calibration_names: Sequence[str] = ()
    mode: Mode = Mode.SAFE
    previous: Mode = Mode.SAFE
    calibrated: bool = False
    offsets: dict[str, int] = field(default_factory=dict)
    joystick: Joystick = Joystick(0, 0, 0, 0, 0)
    trims: Trims = field(default_factory=Trims)
    battery: int | None = None  # 10 mV units, from the ADC task
    motor_level: int = 0  # mean motor command, from the control task
    height_base: Mode = Mode.FULL
    events: list[tuple[EventCode, int, float]] = field(default_factory=list)
    changes: list[ModeChange] = field(default_factory=list)  # every change, for the board's listeners and tests
    link_timed_out: bool = False
    link_hold: bool = False  # the failsafe's stage 1: level, the lift it had, until the link is back or stage 2
    battery_low_latched: bool = False  # set by a low-battery PANIC; only a new battery (a reboot) clears it
    crashed: bool = False  # an impact the pilot has not acknowledged (Op.ACK_CRASH): no leaving SAFE
    motor_test: MotorTest = field(default_factory=MotorTest)  # the bench test (SAFE only; fcb_sim/board/motortest.py)

    def __post_init__(self) -> None:
        self.calibration = CalibrationSums(self.calibration_names)
        self.calibration_started = 0.0
        self.panic_started = 0.0
        self.panic_start_level = 0
        self.panic_landed_at: float | None = None
        self.pending_target: Mode | None = None
        self._low_battery_since: float | None = None
        self.listeners: list[Callable[[ModeChange], None]] = []
        self._now = 0.0
        self._hold_lift = 0  # the lift stage 1 holds
        self._hold_since = 0.0

    # --- inputs -------------------------------------------------------------------------------------------

    @property
    def lift(self) -> int:
        """Effective lift: joystick plus lift trim."""
        return max(0, min(STICK_MAX, self.joystick.lift + self.trims.lift))

    def sticks(self) -> tuple[int, int, int, int]:
        """Effective (roll, pitch, yaw, lift): joystick plus trims, clipped to the stick range; in the failsafe's
        stage 1, level with the lift it had."""
        if self.link_hold:
            return 0, 0, 0, self._hold_lift
        js, t = self.joystick, self.trims

        def clip(v: int) -> int:
            return max(-STICK_MAX, min(STICK_MAX, v))

        return clip(js.roll + t.roll), clip(js.pitch + t.pitch), clip(js.yaw + t.yaw), self.lift

    def adjust_trim(self, axis: str, steps: int) -> int:
        """Move one trim by ``steps`` key presses; returns the new value."""
        if axis == "lift":  # finer near hover: the protocol's rule (lift_trim_after)
            self.trims.lift = lift_trim_after(self.trims.lift, steps, self.config.lift_step, self.joystick.lift)
            return self.trims.lift
        value = getattr(self.trims, axis) + steps * self.config.trim_step
        value = max(-TRIM_LIMIT, min(TRIM_LIMIT, value))
        setattr(self.trims, axis, value)
        return value

    @property
    def motors_enabled(self) -> bool:
        return self.mode not in MOTORS_OFF_MODES

    @property
    def flying(self) -> bool:
        return self.mode in FLIGHT_MODES

    def emit(self, code: EventCode, arg: int, now: float) -> None:
        self.events.append((code, int(arg), now))

    # --- transitions --------------------------------------------------------------------------------------

    def check(self, target: Mode, trigger: str = "request") -> Nak:
        """Would a transition to ``target`` be allowed now? Nak.OK or the first failing guard's reason."""
        if target == self.mode:
            return Nak.OK
        if self.mode == Mode.PANIC and trigger == "request":
            return Nak.PANIC_ACTIVE
        row = _ROWS.get((self.mode, target, trigger))
        if row is None:
            return Nak.INVALID_TRANSITION
        self.pending_target = target
        try:
            for guard in row.guards:
                reason = guard.check(self)
                if reason != Nak.OK:
                    return reason
        finally:
            self.pending_target = None
        return Nak.OK

    def request(self, target: int, now: float) -> Nak:
        """The pilot asks for a mode. Returns Nak.OK (done, or already there) or the reason it is refused;
        a refusal also emits an ``EventCode.REFUSED`` event."""
        try:
            target = Mode(target)
        except ValueError:
            return Nak.BAD_ARGUMENT
        if target == Mode.WIRELESS:
            return Nak.BAD_ARGUMENT  # a handover, not a mode: the board routes Op.WIRELESS itself
        if target == Mode.PANIC and self.mode in (Mode.SAFE, Mode.PANIC):
            return Nak.OK  # already safe (motors off) or already descending
        if target == self.mode:  # already there: no re-entry (HEIGHT would forget its base), no event
            if target == Mode.SAFE:
                _enter_safe(self, now)  # but 0 in SAFE still zeroes the lift trim
            return Nak.OK
        reason = self.check(target)
        if reason != Nak.OK:
            self.emit(EventCode.REFUSED, (int(reason) << 8) | int(target), now)
            return reason
        self._change(target, now, "request")
        return Nak.OK

    def panic(self, now: float, why: str = "request") -> bool:
        """Enter PANIC if the motors may turn; returns whether the machine is now in PANIC."""
        if self.mode in FLIGHT_MODES or self.mode == Mode.CALIBRATION:
            self._change(Mode.PANIC, now, f"panic:{why}")
        return self.mode == Mode.PANIC

    def crash(self, now: float, speed_mm_s: int) -> None:
        """The craft hit the ground (or the ceiling) too hard: event CRASH, motors off (SAFE), and SAFE is kept
        until the pilot acknowledges it."""
        self.crashed = True
        self.emit(EventCode.CRASH, speed_mm_s, now)
        if self.mode != Mode.SAFE:
            self._change(Mode.SAFE, now, "crash")

    def acknowledge_crash(self) -> Nak:
        """The pilot has seen the crash (``Op.ACK_CRASH``): only in SAFE."""
        if self.mode != Mode.SAFE:
            return Nak.NOT_IN_SAFE
        self.crashed = False
        return Nak.OK

    def _change(self, target: Mode, now: float, reason: str) -> None:
        old = self.mode
        self.link_hold = False  # a new mode (PANIC, a crash's SAFE) ends stage 1
        LEAVE[old](self, now)
        self.previous = old
        self.mode = target
        ENTER[target](self, now)
        change = ModeChange(old, target, now, reason)
        self.changes.append(change)
        self.emit(EventCode.MODE_CHANGED, (int(old) << 8) | int(target), now)
        for listener in self.listeners:
            listener(change)

    # --- timers and safety --------------------------------------------------------------------------------

    def calibration_elapsed(self) -> float:
        return self._now - self.calibration_started

    def panic_elapsed(self) -> float:
        return self._now - self.panic_started

    def panic_ground(self, now: float) -> None:
        """The flight core sensed the ground during PANIC's descent: the motors ramp to zero from now."""
        if self.mode == Mode.PANIC and self.panic_landed_at is None:
            self.panic_landed_at = now

    def _ramp_from(self) -> float | None:
        countdown = self.config.panic_countdown_s
        if countdown > 0:  # the report's: when the countdown ends the motors stop (a ramp of no length)
            return self.panic_started + countdown if self._now >= self.panic_started + countdown else None
        if self.panic_landed_at is not None:
            return self.panic_landed_at
        timeout = self.panic_started + self.config.panic_timeout_s
        return timeout if self._now >= timeout else None

    def _ramp_s(self) -> float:
        return 0.0 if self.config.panic_countdown_s > 0 else self.config.panic_ramp_s

    def panic_finished(self) -> bool:
        if self.panic_start_level == 0:
            return True
        t0 = self._ramp_from()
        return t0 is not None and self._now >= t0 + self._ramp_s()

    def panic_scale(self, now: float) -> float:
        """What PANIC's descent is multiplied by at ``now``: 1 until the ground is sensed (or the timeout), then
        a linear ramp to 0 over ``panic_ramp_s``."""
        if self.mode != Mode.PANIC:
            return 0.0
        self._now = max(self._now, now)
        t0 = self._ramp_from()
        if t0 is None:
            return 1.0
        ramp = self._ramp_s()
        return 0.0 if ramp <= 0 else max(0.0, 1.0 - (now - t0) / ramp)

    def panic_motor_level(self, now: float) -> int:
        """PANIC's reference level scaled as ``panic_scale`` says (the descent loop works around it)."""
        return int(self.panic_start_level * self.panic_scale(now))

    def tick(self, now: float) -> None:
        """Take the automatic transitions whose guards pass (PANIC done, calibration time up)."""
        self._now = now
        if (self.mode, Mode.SAFE, "auto") in _ROWS and self.check(Mode.SAFE, "auto") == Nak.OK:
            self._change(Mode.SAFE, now, "auto")

    def calibration_sample(self, values: Mapping[str, int]) -> None:
        """Add one sensor sample (some or all of the calibrated variables) to the sums (only in CALIBRATION)."""
        if self.mode == Mode.CALIBRATION:
            self.calibration.add(values)

    def link_back(self, now: float) -> None:
        """A valid frame from the PC: stage 1 of the failsafe ends, control is the pilot's again."""
        if self.link_hold:
            self.link_hold = False
            self.emit(EventCode.LINK_REGAINED, round((now - self._hold_since) * 1000), now)

    def _link(self, now: float, silent: float) -> bool:
        """The two-stage link failsafe (docs/modes.md); returns whether it is time for the PANIC."""
        cfg = self.config
        timed_out = silent > cfg.link_timeout_s
        flying = self.mode in FLIGHT_MODES
        if not timed_out:
            self.link_back(now)
        elif flying and silent <= cfg.link_timeout_s + cfg.link_failsafe_s:
            if not self.link_hold:  # stage 1: level, the lift it had
                self._hold_lift, self._hold_since, self.link_hold = self.lift, now, True
                self.emit(EventCode.LINK_LOST, int(silent * 1000), now)
            timed_out = False  # the guard runs: the timeout proper (PANIC) is stage 2's
        elif not self.link_timed_out or self.link_hold:  # the timeout proper: said once (stage 2, or not flying)
            self.emit(EventCode.LINK_TIMEOUT, int(silent * 1000), now)
        self.link_timed_out = timed_out or self.link_hold
        return timed_out and flying

    def supervise(self, now: float, *, link_silent_s: float, battery: int | None = None,
                  phi_cdeg: int = 0, theta_cdeg: int = 0) -> EventCode | None:
        """The safety monitor: the link failsafe's two stages, PANIC on a low battery while flying or excessive
        tilt. Returns the cause if it triggered PANIC."""
        self._now = now
        cfg = self.config
        if battery is not None:
            self.battery = battery
        timed_out = self._link(now, link_silent_s)
        if self.battery is not None and self.battery < cfg.low_battery:
            if self._low_battery_since is None:
                self._low_battery_since = now
        else:
            self._low_battery_since = None
        if self.mode not in FLIGHT_MODES:
            return None
        if timed_out:
            self.panic(now, "link")
            return EventCode.LINK_TIMEOUT
        if self._low_battery_since is not None and now - self._low_battery_since >= LOW_BATTERY_HOLD_S:
            self.emit(EventCode.LOW_BATTERY, self.battery or 0, now)
            self.battery_low_latched = True
            self.panic(now, "battery")
            return EventCode.LOW_BATTERY
        tilt = tilt_cdeg(phi_cdeg, theta_cdeg)
        if tilt > cfg.tilt_limit_cdeg:
            self.emit(EventCode.TILT_LIMIT, tilt, now)
            self.panic(now, "tilt")
            return EventCode.TILT_LIMIT
        return None

    def drain_events(self) -> list[tuple[EventCode, int, float]]:
        out, self.events = self.events, []
        return out


def tilt_cdeg(phi_cdeg: int, theta_cdeg: int) -> int:
    """Angle between the body z axis and the vertical, from roll and pitch (centidegrees)."""
    phi, theta = math.radians(phi_cdeg / 100), math.radians(theta_cdeg / 100)
    c = max(-1.0, min(1.0, math.cos(phi) * math.cos(theta)))
    return round(math.degrees(math.acos(c)) * 100)


# --- the diagram, generated from the tables -----------------------------------------------------------------


def mermaid() -> str:
    """The mode diagram as a Mermaid stateDiagram, from ``TRANSITIONS``."""
    lines = ["stateDiagram-v2", "    [*] --> SAFE"]
    for t in TRANSITIONS:
        label = [g.label for g in t.guards]
        if t.trigger == "auto":
            label.insert(0, "auto")
        if t.note:
            label.append(t.note)
        text = ": " + ", ".join(label) if label else ""
        lines.append(f"    {t.source.name} --> {t.target.name}{text}")
    lines.append("    SAFE --> SAFE: 8 BLE handover (stays SAFE)")
    return "\n".join(lines)


def transition_table_markdown() -> str:
    """The same table as Markdown, for readers without a Mermaid renderer."""
    lines = ["| from | to | trigger | guards (all must pass) | note |", "|---|---|---|---|---|"]
    for t in TRANSITIONS:
        guards = ", ".join(g.label for g in t.guards) or "none"
        lines.append(f"| {t.source.name} | {t.target.name} | {t.trigger} | {guards} | {t.note} |")
    return "\n".join(lines)


_DOC_HEAD = """# Board modes

Generated by `python -m fcb_sim.board.modes` from the tables in `fcb_sim/board/modes.py` (`TRANSITIONS`, `ENTER`,
`LEAVE`); a test fails if this file is out of date. Do not edit by hand.

The machine follows the report's design (section 3.2): a check decides whether a transition is valid (the
guards below, each refusal answered by a NAK with its reason), then the leave action of the old mode and the
enter action of the new one run. The motors are zero in SAFE and CALIBRATION; they may turn in every other mode.

- Leaving SAFE needs the sticks neutral and the lift at zero, both read as the motors would get them, joystick
  plus trim on every axis: |roll|, |pitch|, |yaw| each <= {neutral} (a roll trim of +8192 with the joystick centred
  is a roll command, not neutral sticks) and lift + lift trim <= {lift}; YAW, FULL and RAW also need a finished
  calibration, and no flight mode starts on a low battery (< {battery} V, or after a low-battery PANIC: the pack
  recovers at rest but is still flat).
- From a flight mode the way out is SAFE (only with the lift at zero, so a key press cannot cut the motors in the
  air) or PANIC. HEIGHT is entered from FULL or RAW (it holds the height it had) and falls back to the one it
  came from.
- In HEIGHT the lift keys (a / z) move the height set point, {height_step:g} m a press (kept within
  {sp_lo:g}..{sp_hi:g} m), and the board says the new set point (event HEIGHT_SETPOINT); they leave the lift trim
  as it was. Why the set point and not a trim: HEIGHT holds a height, so a lift trim there is taken back by the
  controller and changes nothing the pilot sees, until HEIGHT is left and the changed trim drops (or lifts) the
  craft; a press that moves what HEIGHT holds is seen at once, and leaving HEIGHT gives back the lift the craft
  hovered on when it entered. The lift stick moves the set point too (beyond a dead band, at up to
  {stick_rate:g} m/s).
- PANIC is reachable from every mode that can turn the motors (a PANIC request in SAFE is accepted and changes
  nothing: the motors are already off). It descends at a bounded rate (1 m/s below 10 m of estimated height, up
  to 3 m/s above 40 m) from the motor level it found (never spinning them up; levelled by the attitude loops when
  calibrated) until the flight core senses the ground (little thrust, no vertical speed for 0.5 s), then ramps
  the motors to zero over {ramp} s and returns to SAFE by itself; safe from any height the simulator allows
  (its sky ends at {ceiling:g} m). If the ground is not sensed within {panic_timeout:g} s the ramp starts anyway.
  With `mode.panic_countdown_ms` set (the `report` preset: the report's countdown, section 3.2) PANIC instead holds
  the level it found (at most the panic level, levelled when calibrated) for that long, then the motors stop and
  the board is in SAFE: from high up that is a fall, which is why ours descends until it senses the ground.
- A crash (an impact faster than {crash_speed:g} m/s, or a touch-down tilted past {crash_tilt:g}°) turns the
  motors off from any mode (SAFE), is reported (event CRASH with the speed, Status flag CRASHED), and SAFE is
  kept until the pilot acknowledges it (`Op.ACK_CRASH`, SAFE only).
- The safety monitor (checked at the heartbeat rate, 10 Hz) enters PANIC from a flight mode on a battery under
  {battery} V for {bat_hold} s, or a tilt past {tilt}°; link silence fails safe in two stages. Stage 1: silence
  longer than `link.timeout_ms` (default {timeout} s) in a flight mode holds level (roll, pitch and yaw sticks
  neutral) with the lift it had, in the same mode, says so (event LINK_LOST, Status flag LINK_TIMEOUT), and the
  first valid frame back within `link.failsafe_ms` (default {failsafe} s) gives control back without a PANIC
  (event LINK_REGAINED). Stage 2: silence past both is the PANIC descent (event LINK_TIMEOUT). Outside SAFE both
  times can only be made shorter (`Nak.ONLY_SHORTER_IN_FLIGHT`), never longer or off.
- Why two stages where the report has one: the report's board PANICs as soon as the link times out (the `report`
  preset keeps that: `link.failsafe_ms` 0). A pilot's laptop is never idle, and a terminal stalled for half a
  second by its own machine (issue 21: 506-534 ms of silence ended eight flights in one sitting, in FULL, HEIGHT
  and MANUAL) is not a lost link; Betaflight (stage 1 holds for a guard time, stage 2 lands) and ArduPilot's GCS
  failsafe (waits seconds) do the same. A link that stays away still ends in the PANIC descent, {failsafe} s
  later.
- CALIBRATION sums the sensor samples in unbounded integers for {cal} s (`mode.calibration_ms`) with the board
  still, then returns to SAFE by itself (with 0, the report's, section 3.6: for as long as the pilot holds it,
  until 0); leaving it (by itself or on request) takes the means, which are subtracted from every later
  sample. Leaving with fewer than {cal_min} samples keeps the previous calibration.
- Key 8 (`Op.WIRELESS`, arg 1) is a BLE handover, not a mode: accepted only in SAFE, the board stays in SAFE and
  `Status.wireless` moves DISCONNECTED -> STARTING -> STARTED (see docs/wireless.md).

## The motor test

A bench check of wiring, order and direction before a first flight, props off (`Op.MOTOR_TEST`, arg
`motor_test_arg(motors, level)`: a mask of the motors, bit 0 ae1 front .. bit 3 ae4 left, and a level). Not a
mode: the board stays in SAFE while the motors in the mask turn at the level. Its guards are the board's own,
whatever the terminal does (fcb_sim/board/motortest.py; the C board's firmware/board/qb_console.c):

| refused with | when |
|---|---|
{mt_refusals}

| the test stops by itself (event MOTOR_TEST, arg) | when |
|---|---|
{mt_stops}

The level is capped at {mt_level} (hover is about 400): even all four motors with props on cannot lift the craft.
Each run is at most {mt_ms} ms from the command that started it; a new command starts a new run. While a test
runs, Status has the flag MOTOR_TEST and Motion carries the motor commands. The board says each start on its
console (`qb_log`: "motor test: mask 2 at 200 for {mt_ms} ms"). The terminal's motor test screen (Ctrl+O)
asks "props off?" first, sends one command per start, and a stop (level 0) on any key and on leaving the screen.

## Diagram

```mermaid
{diagram}
```

## Transitions

{table}

## Enter and leave actions

| mode | on enter | on leave |
|---|---|---|
{actions}
"""


def modes_doc() -> str:
    """The whole of docs/modes.md."""
    from fcb_sim.board.flight import HEIGHT_STICK_RATE  # (the flight core's; only the doc needs it)

    cfg = ModeConfig()
    actions = []
    for mode in ENTER:
        enter = (ENTER[mode].__name__.lstrip("_").replace("_", " ") if ENTER[mode] is not _nothing else "-")
        leave = (LEAVE[mode].__name__.lstrip("_").replace("_", " ") if LEAVE[mode] is not _nothing else "-")
        enter_doc = _ACTION_TEXT.get(ENTER[mode], enter)
        leave_doc = _ACTION_TEXT.get(LEAVE[mode], leave)
        actions.append(f"| {mode.name} | {enter_doc} | {leave_doc} |")
    return _DOC_HEAD.format(
        neutral=STICK_NEUTRAL, lift=LIFT_ZERO, battery=cfg.low_battery / 100, panic=cfg.panic_level,
        ramp=cfg.panic_ramp_s, panic_timeout=cfg.panic_timeout_s, ceiling=P.CEILING_M,
        crash_speed=P.CRASH_SPEED_M_S, crash_tilt=P.CRASH_TILT_DEG, timeout=cfg.link_timeout_s,
        failsafe=cfg.link_failsafe_s,
        bat_hold=LOW_BATTERY_HOLD_S,
        tilt=cfg.tilt_limit_cdeg / 100, cal=cfg.calibration_s, cal_min=cfg.calibration_min_samples,
        diagram=mermaid(), table=transition_table_markdown(), actions="\n".join(actions),
        mt_level=MOTOR_TEST_MAX_LEVEL, mt_ms=MOTOR_TEST_MAX_MS, **_motor_test_rows(),
        height_step=HEIGHT_KEY_STEP_MM / 1000, sp_lo=HEIGHT_SETPOINT_MIN_MM / 1000, sp_hi=HEIGHT_SETPOINT_MAX_MM / 1000,
        stick_rate=HEIGHT_STICK_RATE,
    )


def _motor_test_rows() -> dict[str, str]:
    """The motor test's guards and stops, for docs/modes.md."""
    refusals = [(Nak.NOT_IN_SAFE, "the board is not in SAFE"),
                (Nak.CRASHED, "a crash is not acknowledged"),
                (Nak.LIFT_NOT_ZERO, f"the lift (joystick plus trim) is above {LIFT_ZERO}"),
                (Nak.BAD_ARGUMENT, "the mask names a motor past the fourth"),
                (Nak.OUT_OF_RANGE, f"the level is above {MOTOR_TEST_MAX_LEVEL}")]
    stops = [(MotorTestEnd.TIME_UP, f"{MOTOR_TEST_MAX_MS} ms have passed since the command"),
             (MotorTestEnd.STOPPED, "a MOTOR_TEST command with level 0 (or mask 0)"),
             (MotorTestEnd.LINK_SILENT, f"nothing from the terminal for {MOTOR_TEST_LINK_MS} ms"),
             (MotorTestEnd.MODE, "any mode change"),
             (MotorTestEnd.LIFT, f"the lift leaves zero (above {LIFT_ZERO})")]
    return {"mt_refusals": "\n".join(f"| `{n.name}` | {t} |" for n, t in refusals),
            "mt_stops": "\n".join(f"| `{e.name}` ({int(e)}) | {t} |" for e, t in stops)}


_ACTION_TEXT: dict[Callable[[ModeMachine, float], None], str] = {
    _nothing: "-",
    _enter_safe: "lift trim to zero",
    _enter_calibration: "sums and count to zero, start the averaging timer",
    _leave_calibration: "means = sums / count (rounded); calibrated; event CALIBRATION_DONE",
    _enter_panic: "start the PANIC timer; descend from min(panic level, current motor level) until the ground",
    _leave_panic: "event PANIC_DONE",
    _enter_height: "remember FULL or RAW as the base; the flight core holds the current height",
}


if __name__ == "__main__":
    import pathlib

    out = pathlib.Path(__file__).resolve().parents[2] / "docs" / "modes.md"
    out.write_text(modes_doc())
    print(f"wrote {out}")
