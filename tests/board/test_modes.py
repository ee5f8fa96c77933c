"""The mode machine on its own: guards and their NAK reasons, PANIC's profile, calibration, the safety monitor,
and the generated mode doc."""

from __future__ import annotations

import pytest

from fcb_sim.board.modes import (
    FLIGHT_MODES,
    LIFT_ZERO,
    STICK_NEUTRAL,
    TRANSITIONS,
    ModeConfig,
    ModeMachine,
    mermaid,
    modes_doc,
    tilt_cdeg,
)
from term.core.protocol import EventCode, Joystick, Mode, Nak
from tests.support.paths import DOCS

DOC = DOCS / "modes.md"


def machine(**cfg) -> ModeMachine:
    return ModeMachine(ModeConfig(**cfg), calibration_names=("gx", "pressure"))


def calibrate(m: ModeMachine, now: float = 0.0) -> float:
    assert m.request(Mode.CALIBRATION, now) == Nak.OK
    for i in range(60):
        m.calibration_sample({"gx": 10 + (i % 2)})
    m.tick(now + m.config.calibration_s)
    assert m.mode == Mode.SAFE and m.calibrated
    return now + m.config.calibration_s


def test_leaving_safe_needs_zero_lift_then_neutral_sticks() -> None:
    m = machine()
    m.joystick = Joystick(0, 0, 0, LIFT_ZERO + 1, 0)
    assert m.request(Mode.MANUAL, 0.0) == Nak.LIFT_NOT_ZERO
    m.joystick = Joystick(STICK_NEUTRAL + 1, 0, 0, 0, 0)
    assert m.request(Mode.MANUAL, 0.0) == Nak.STICKS_NOT_NEUTRAL
    m.joystick = Joystick(0, 0, -STICK_NEUTRAL - 1, 0, 0)
    assert m.request(Mode.CALIBRATION, 0.0) == Nak.STICKS_NOT_NEUTRAL
    assert m.mode == Mode.SAFE
    m.joystick = Joystick(STICK_NEUTRAL, -STICK_NEUTRAL, 0, LIFT_ZERO, 0)
    assert m.request(Mode.MANUAL, 0.0) == Nak.OK
    assert m.mode == Mode.MANUAL


@pytest.mark.parametrize("axis", ["roll", "pitch", "yaw"])
def test_trims_count_as_stick_when_leaving_safe(axis: str) -> None:
    """Issue 11.3: a roll trim of +8192 with the joystick centred is a roll command, not neutral sticks."""
    m = machine()
    m.adjust_trim(axis, 32)  # 32 key presses: the trim limit, +8192
    assert getattr(m.trims, axis) == 8192
    assert m.request(Mode.MANUAL, 0.0) == Nak.STICKS_NOT_NEUTRAL
    assert m.request(Mode.CALIBRATION, 0.0) == Nak.STICKS_NOT_NEUTRAL
    # the stick held against the trim: what the motors would get is neutral
    m.joystick = Joystick(**{"roll": 0, "pitch": 0, "yaw": 0, "lift": 0, "buttons": 0, axis: -8192 + STICK_NEUTRAL})
    assert m.request(Mode.MANUAL, 0.0) == Nak.OK


def test_lift_trim_counts_as_lift_and_is_zeroed_on_entering_safe() -> None:
    m = machine()
    m.adjust_trim("lift", 3)
    assert m.request(Mode.MANUAL, 0.0) == Nak.LIFT_NOT_ZERO
    m.adjust_trim("lift", -3)
    assert m.request(Mode.MANUAL, 0.0) == Nak.OK
    m.adjust_trim("lift", 5)
    assert m.request(Mode.SAFE, 0.1) == Nak.LIFT_NOT_ZERO  # no cutting the motors in the air with a key
    m.joystick = Joystick(0, 0, 0, 0, 0)
    m.adjust_trim("lift", -5)
    assert m.request(Mode.SAFE, 0.2) == Nak.OK
    m.adjust_trim("lift", 2)
    m.request(Mode.PANIC, 0.3)  # SAFE: stays
    assert m.trims.lift > 0
    m.request(Mode.MANUAL, 0.3)
    assert m.mode == Mode.SAFE


def test_controlled_modes_need_calibration_and_refusals_emit_events() -> None:
    m = machine()
    for mode in (Mode.YAW, Mode.FULL, Mode.RAW):
        assert m.request(mode, 0.0) == Nak.NOT_CALIBRATED
    refused = [e for e in m.drain_events() if e[0] == EventCode.REFUSED]
    assert [(arg >> 8, arg & 0xFF) for _, arg, _ in refused] == [
        (Nak.NOT_CALIBRATED, Mode.YAW), (Nak.NOT_CALIBRATED, Mode.FULL), (Nak.NOT_CALIBRATED, Mode.RAW)]
    t = calibrate(m)
    assert m.request(Mode.FULL, t) == Nak.OK


def test_flight_modes_leave_only_to_safe_or_panic_and_height_returns_to_its_base() -> None:
    m = machine()
    t = calibrate(m)
    m.request(Mode.RAW, t)
    for other in (Mode.MANUAL, Mode.YAW, Mode.FULL, Mode.CALIBRATION):
        assert m.request(other, t) == Nak.INVALID_TRANSITION
    assert m.request(Mode.HEIGHT, t) == Nak.OK
    assert m.request(Mode.FULL, t) == Nak.INVALID_TRANSITION  # entered from RAW
    assert m.request(Mode.RAW, t) == Nak.OK
    assert m.request(Mode.HEIGHT + 0, t) == Nak.OK
    assert m.request(Mode.PANIC, t) == Nak.OK and m.mode == Mode.PANIC


def test_height_cannot_start_from_safe() -> None:
    m = machine()
    calibrate(m)
    assert m.request(Mode.HEIGHT, 2.0) == Nak.INVALID_TRANSITION


def test_bad_and_wireless_arguments() -> None:
    m = machine()
    assert m.request(99, 0.0) == Nak.BAD_ARGUMENT
    assert m.request(Mode.WIRELESS, 0.0) == Nak.BAD_ARGUMENT  # the board routes the handover itself
    assert m.request(Mode.SAFE, 0.0) == Nak.OK


def test_panic_descends_until_the_ground_then_ramps_then_safe_by_itself() -> None:
    m = machine(panic_level=370, panic_ramp_s=1.0)
    m.request(Mode.MANUAL, 0.0)
    m.motor_level = 420
    assert m.request(Mode.PANIC, 10.0) == Nak.OK
    assert m.panic_scale(10.5) == 1.0 and m.panic_motor_level(10.5) == 370  # never above what they ran at
    assert m.request(Mode.SAFE, 10.6) == Nak.PANIC_ACTIVE
    assert m.request(Mode.MANUAL, 10.6) == Nak.PANIC_ACTIVE
    m.tick(60.0)
    assert m.mode == Mode.PANIC and m.panic_scale(60.0) == 1.0  # still coming down: no timer cuts the motors
    m.panic_ground(60.0)  # the flight core sensed the ground
    assert m.panic_scale(60.5) == 0.5 and m.panic_motor_level(60.5) == 185
    m.tick(60.99)
    assert m.mode == Mode.PANIC
    m.tick(61.0)
    assert m.mode == Mode.SAFE
    assert m.panic_motor_level(61.0) == 0
    assert EventCode.PANIC_DONE in [e[0] for e in m.drain_events()]


def test_a_panic_that_never_senses_the_ground_ends_at_its_timeout() -> None:
    m = machine(panic_ramp_s=1.0, panic_timeout_s=100.0)
    m.request(Mode.MANUAL, 0.0)
    m.motor_level = 400
    m.panic(0.0)
    m.tick(99.9)
    assert m.mode == Mode.PANIC and m.panic_scale(99.9) == 1.0
    assert m.panic_scale(100.5) == 0.5
    m.tick(101.0)
    assert m.mode == Mode.SAFE


def test_panic_never_spins_motors_up() -> None:
    m = machine(panic_level=370)
    m.request(Mode.MANUAL, 0.0)
    m.motor_level = 120
    m.panic(1.0)
    assert m.panic_motor_level(1.1) == 120
    m2 = machine()
    m2.request(Mode.CALIBRATION, 0.0)
    m2.panic(0.5)  # motors were off: nothing to descend, SAFE at the next tick
    assert m2.mode == Mode.PANIC and m2.panic_motor_level(0.5) == 0
    m2.tick(0.5)
    assert m2.mode == Mode.SAFE


def test_calibration_left_early_keeps_the_previous_offsets() -> None:
    m = machine()
    t = calibrate(m)
    offsets = dict(m.offsets)
    m.request(Mode.CALIBRATION, t)
    m.calibration_sample({"gx": 1000})
    assert m.request(Mode.SAFE, t + 0.1) == Nak.OK
    assert m.calibrated and m.offsets == offsets and offsets["gx"] in (10, 11)


@pytest.mark.parametrize("mode", sorted(FLIGHT_MODES - {Mode.HEIGHT}))
def test_link_silence_battery_and_tilt_panic_only_when_flying(mode: Mode) -> None:
    m = machine(link_timeout_s=0.5, link_failsafe_s=0.0)  # the report's one stage (tests/board/test_failsafe.py)
    assert m.supervise(0.0, link_silent_s=5.0) is None and m.mode == Mode.SAFE and m.link_timed_out
    t = calibrate(m, 1.0)
    assert m.request(mode, t) == Nak.OK
    assert m.supervise(t, link_silent_s=0.5) is None
    assert m.supervise(t, link_silent_s=0.51) == EventCode.LINK_TIMEOUT and m.mode == Mode.PANIC

    m = machine()
    t = calibrate(m)
    m.request(mode, t)
    assert m.supervise(t, link_silent_s=0.0, battery=1049) is None  # a sag, not yet a flat battery
    assert m.supervise(t + 0.25, link_silent_s=0.0, battery=1049) == EventCode.LOW_BATTERY
    assert m.mode == Mode.PANIC

    m = machine(tilt_limit_cdeg=5000)
    t = calibrate(m)
    m.request(mode, t)
    assert m.supervise(t, link_silent_s=0.0, phi_cdeg=3000, theta_cdeg=3000) is None
    assert m.supervise(t, link_silent_s=0.0, phi_cdeg=4000, theta_cdeg=3500) == EventCode.TILT_LIMIT


def test_low_battery_refuses_takeoff() -> None:
    m = machine()
    m.battery = 1000
    assert m.request(Mode.MANUAL, 0.0) == Nak.BATTERY_LOW


def test_tilt() -> None:
    assert tilt_cdeg(0, 0) == 0
    assert tilt_cdeg(3000, 0) == 3000
    assert 4000 < tilt_cdeg(3000, 3000) < 4300


def test_every_flight_mode_has_a_way_to_panic_and_to_safe() -> None:
    pairs = {(t.source, t.target) for t in TRANSITIONS}
    for mode in FLIGHT_MODES | {Mode.CALIBRATION}:
        assert (mode, Mode.PANIC) in pairs and (mode, Mode.SAFE) in pairs
    assert (Mode.PANIC, Mode.SAFE) in pairs
    assert not any(t.source == Mode.PANIC and t.target != Mode.SAFE for t in TRANSITIONS)


def test_mode_doc_is_generated_from_the_table() -> None:
    assert DOC.read_text() == modes_doc(), "docs/modes.md is stale: run python -m fcb_sim.board.modes"
    for t in TRANSITIONS:
        assert f"{t.source.name} --> {t.target.name}" in mermaid()


def test_a_low_battery_panic_latches() -> None:
    m = machine()
    m.request(Mode.MANUAL, 0.0)
    m.motor_level = 400
    m.supervise(0.0, link_silent_s=0.0, battery=1040)
    m.supervise(0.3, link_silent_s=0.0, battery=1040)
    assert m.mode == Mode.PANIC and m.battery_low_latched
    m.panic_ground(8.0)
    m.tick(10.0)
    m.supervise(10.0, link_silent_s=0.0, battery=1090)  # recovered at rest
    assert m.mode == Mode.SAFE and m.request(Mode.MANUAL, 10.1) == Nak.BATTERY_LOW


def test_asking_for_the_current_mode_changes_nothing() -> None:
    # Pressing 0 in SAFE or 7 in HEIGHT logged "mode SAFE → SAFE" and re-ran the enter action: HEIGHT took
    # itself as the mode to return to, and a second 3 restarted a calibration under way.
    m = machine()
    m.adjust_trim("lift", 2)
    assert m.request(Mode.SAFE, 0.0) == Nak.OK
    assert m.trims.lift == 0  # 0 in SAFE still zeroes the lift trim, as entering SAFE does
    t = calibrate(m)
    m.drain_events()
    assert m.request(Mode.RAW, t) == Nak.OK and m.request(Mode.HEIGHT, t) == Nak.OK
    changes = len(m.changes)
    assert m.request(Mode.HEIGHT, t) == Nak.OK
    assert len(m.changes) == changes
    assert [e for e in m.drain_events() if e[0] == EventCode.MODE_CHANGED][-1][1] == (Mode.RAW << 8) | Mode.HEIGHT
    assert m.request(Mode.RAW, t) == Nak.OK and m.mode == Mode.RAW  # HEIGHT still returns to RAW
