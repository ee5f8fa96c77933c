"""The phone app's logic (term.session.phone) without any UI: the pad springs back, the lift slider stays, the buttons
ask
for the key map's actions, PANIC lets go of the lift, and the readouts (battery, attitude, links) say what the
model holds."""

from __future__ import annotations

from term.core.link import LinkStats
from term.core.protocol import Attitude, Compact, Joystick, Mode, Op, WirelessState
from term.input.keymap import DEFAULT_KEYMAP, action_by_name
from term.input.mapping import FULL
from term.session.model import Model
from term.session.phone import (
    BUTTONS,
    MODE_BUTTONS,
    PANIC,
    TRIM_BUTTONS,
    Phone,
    Readout,
    RunAction,
    SendCommand,
    SetAxes,
    link_states,
    readout,
)


def test_the_pad_springs_back_and_the_lift_stays() -> None:
    p = Phone()
    assert p.touch(FULL, -FULL // 2) == [SetAxes(roll=FULL, pitch=-FULL // 2)]
    assert p.touch(FULL, -FULL // 2) == []  # no move, no request
    assert p.touch(10 * FULL, -10 * FULL) == [SetAxes(roll=FULL, pitch=-FULL)]  # clipped to full deflection
    assert p.slide(FULL // 3) == [SetAxes(lift=FULL // 3)]
    p.let_go_lift()
    assert p.release() == [SetAxes(roll=0, pitch=0)]  # let go: back to the centre
    assert (p.roll, p.pitch, p.lift) == (0, 0, FULL // 3)  # the lift stays where it was left
    assert p.release() == []  # already centred
    assert p.slide(-5) == [SetAxes(lift=0)] and p.slide(2 * FULL) == [SetAxes(lift=FULL)]


def test_untouched_controls_follow_the_stick_the_terminal_sends() -> None:
    p = Phone()
    p.follow(Joystick(100, -200, 0, 3000, 0))  # a hardware joystick
    assert (p.roll, p.pitch, p.lift) == (100, -200, 3000)
    p.touch(5000, 0)
    p.slide(9000)
    p.follow(Joystick(1, 1, 0, 1, 0))  # while touched, the finger wins
    assert (p.roll, p.pitch, p.lift) == (5000, 0, 9000)
    p.release()
    p.let_go_lift()
    p.follow(Joystick(7, 8, 0, 9, 0))
    assert (p.roll, p.pitch, p.lift) == (7, 8, 9)


def test_buttons_are_the_key_maps_actions_and_panic_lets_go_of_the_lift() -> None:
    p = Phone()
    for _, action in (*MODE_BUTTONS, *TRIM_BUTTONS):
        assert p.press(action) == [RunAction(action)]
        assert action_by_name(DEFAULT_KEYMAP, action) is not None  # the same action as its key
    assert p.press("handover") == [SendCommand(Op.WIRELESS, 1)]
    assert p.press("handback") == [SendCommand(Op.WIRELESS, 0)]
    assert p.press("no such button") == []
    p.slide(20000)
    assert p.press(PANIC) == [RunAction(PANIC), SetAxes(lift=0)]
    assert p.lift == 0 and not p.sliding
    assert action_by_name(DEFAULT_KEYMAP, PANIC).arg == Mode.PANIC  # type: ignore[union-attr]
    assert {"handover", "handback", PANIC} <= BUTTONS


def test_the_readout_is_the_phones_telemetry() -> None:
    m = Model(start=0.0, radio_name="ble")
    r = readout(m, 0.0)
    assert r.mode == "—" and not r.battery.known and r.battery_level == "" and not r.attitude[0].known

    def att(r: Readout) -> tuple[float | None, ...]:
        return tuple(a.value for a in r.attitude)

    m.apply_packet(Attitude(Mode.MANUAL, 1000, -500, 9000, 0, 0, 0), 0.1)
    assert att(readout(m, 0.1)) == (10.0, -5.0, 90.0)
    # Over BLE the phone shows its own Compact frames (the freshest attitude).
    m.radio_up = True
    m.apply_packet(Compact(int(Mode.PANIC), int(WirelessState.STARTED), 200, 300, -400, 1040), 0.2)
    r = readout(m, 0.2)
    assert r.mode == "PANIC" and r.panic and r.wireless == "STARTED" and att(r) == (2.0, 3.0, -4.0)
    assert r.attitude[0].source == "Compact" and r.attitude[0].fresh
    assert r.battery.value == 10.4 and r.battery_level == "panic"
    m.apply_packet(Compact(int(Mode.SAFE), int(WirelessState.STARTED), 0, 0, 0, 1100), 0.3)
    assert readout(m, 0.3).battery_level == "warn"
    m.apply_packet(Compact(int(Mode.SAFE), int(WirelessState.STARTED), 0, 0, 0, 1200), 0.4)
    assert readout(m, 0.4).battery_level == "ok"
    later = readout(m, 10.0)  # nothing for ten seconds: the same figures, marked with their age
    assert later.battery.stale and later.battery.mark == "9 s old" and later.attitude[0].stale


def _stats(**kw: object) -> LinkStats:
    base = dict(rtt_last_ms=12.0, rtt_mean_ms=12.0, rtt_p95_ms=15.0, loss_pct=0.0, loss_pct_total=0.0,
                rx_bytes_per_s=0.0, tx_bytes_per_s=0.0, frames_ok=10, frames_bad=0, since_last_frame_s=0.01,
                since_last_heartbeat_s=0.05, heartbeat_delay_ms=None, lost=False, rx_bytes=0, tx_bytes=0,
                commands_sent=0, command_retries=0, commands_failed=0, heartbeats=1, board_version=1)
    base.update(kw)
    return LinkStats(**base)  # type: ignore[arg-type]


def test_link_states_say_which_link_carries_control() -> None:
    m = Model(start=0.0)
    (cable,) = link_states(m)
    assert cable.name == "cable" and cable.carries and cable.level == "warn" and "waiting" in cable.state
    m.link = _stats()
    assert link_states(m)[0].state == "OK, RTT 12 ms"
    m.radio_name = "ble"
    cable, ble = link_states(m)
    assert cable.carries and not ble.carries and ble.state == "not connected" and ble.level == "warn"
    m.radio_up, m.radio = True, _stats(rtt_last_ms=30.0, rtt_mean_ms=30.0)  # (the mean is the one shown)
    m.apply_packet(Compact(int(Mode.SAFE), int(WirelessState.STARTED), 0, 0, 0, 1200), 0.1)
    m.link_lost = True
    cable, ble = link_states(m)
    assert not cable.carries and cable.state == "silent: flying over BLE" and cable.level == "info"
    assert ble.carries and ble.state == "flying over BLE, RTT 30 ms" and ble.level == "active"
    m.radio_lost = True
    assert link_states(m)[1].level == "alarm"
    alone = Model(start=0.0, primary_ble=True)
    assert link_states(alone)[0].name == "ble" and "waiting for the handover" in link_states(alone)[0].state
