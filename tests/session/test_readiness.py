"""The readiness checks (term/session/readiness.py), each driven true and false from the packets the board sends; every
refusal reason mapped to its check; refusals said once; repeated events merged; deadline misses summarised; the
log keys' reports; the alarms' rising edges (term/session/alarms.py)."""

from __future__ import annotations

import pytest

from term.core.events import NotSent, Requested
from term.core.link import CommandAcked, CommandFailed, LinkLost, LinkStats
from term.core.protocol import (
    LIFT_ZERO,
    NAK_TEXT,
    STICK_NEUTRAL,
    Attitude,
    Event,
    EventCode,
    Flag,
    Height,
    Joystick,
    LogState,
    LogStatus,
    Mode,
    Nak,
    Op,
    Status,
    WirelessState,
    field_scale,
)
from term.input.keymap import KEY_PRESETS, build_keymap
from term.session.alarms import Alarms
from term.session.model import Model
from term.session.readiness import ITEMS, NAK_ITEM, checks, next_step, ready

KEYMAP = build_keymap()
NOW = 10.0


def status(flags: Flag = Flag.CALIBRATED, trims: tuple[int, int, int, int] = (0, 0, 0, 0), log_fill: int = 0,
           wireless: int = 0) -> Status:
    return Status(int(flags), *trims, 20, log_fill, wireless)


def volts(v: float) -> int:
    return round(v / field_scale(Height, "battery"))


def good_model(**status_kw: object) -> Model:
    """A board that is ready to fly: link up, calibrated, sticks and lift at zero, a full battery."""
    m = Model(start=0.0)
    m.apply_packet(Attitude(Mode.SAFE, 0, 0, 0, 0, 0, 0), NOW)
    m.apply_packet(status(**status_kw), NOW)  # type: ignore[arg-type]
    m.apply_packet(Height(101325, 0, 0, 0, volts(12.4), 2500), NOW)
    m.set_link_stats(link_stats(), NOW)
    return m


def link_stats() -> LinkStats:
    return LinkStats(rtt_last_ms=4.0, rtt_mean_ms=4.0, rtt_p95_ms=5.0, loss_pct=0.0, loss_pct_total=0.0,
                     rx_bytes_per_s=2000.0, tx_bytes_per_s=1000.0, frames_ok=100, frames_bad=0,
                     since_last_frame_s=0.01, since_last_heartbeat_s=0.05, heartbeat_delay_ms=1.0, lost=False,
                     rx_bytes=20000, tx_bytes=10000, commands_sent=0, command_retries=0, commands_failed=0,
                     heartbeats=10, board_version=2)


def by_item(m: Model, **kw: object) -> dict:
    return {c.item: c for c in checks(m, NOW, KEYMAP, **kw)}  # type: ignore[arg-type]


def test_a_ready_board_is_all_green() -> None:
    found = checks(good_model(), NOW, KEYMAP)
    assert [c.item for c in found] == list(ITEMS)
    assert all(c.state == "ok" for c in found), found
    assert ready(found) and next_step(found) is None


def test_nothing_known_is_waiting_not_green() -> None:
    found = {c.item: c for c in checks(Model(start=0.0), NOW, KEYMAP)}
    assert found["link"].state == "wait" and found["calibrated"].state == "wait"
    assert found["battery"].state == "wait" and found["log"].state == "wait"
    assert not ready(list(found.values()))


def test_calibrated_false_says_which_key() -> None:
    c = by_item(good_model(flags=Flag(0)))["calibrated"]
    assert c.state == "todo" and c.text.startswith("press 3")
    assert next_step(checks(good_model(flags=Flag(0)), NOW, KEYMAP)).step.startswith("calibrate — press 3")
    m = good_model()
    m.apply_packet(Attitude(Mode.CALIBRATION, 0, 0, 0, 0, 0, 0), NOW)
    assert by_item(m)["calibrated"].state == "wait"  # calibrating now


def test_lift_trim_counts_the_presses_and_offers_zero() -> None:
    m = good_model(trims=(0, 0, 0, 13 * 328))
    c = by_item(m, lift_step=328)["lift"]
    # 13 presses of 328 up: 12 presses of z bring it under the zero guard (500), or Z at once
    assert c.state == "todo" and c.text == "trim 13 %: press z 12 times, or Z", c.text
    assert "press z till 0 %, or Z" in by_item(m)["lift"].text  # the board's step not known
    m.set_stick(Joystick(0, 0, 0, 8000, 0))
    assert "throttle fully down" in by_item(m)["lift"].text


def test_lift_presses_near_hover_count_the_boards_finer_steps() -> None:
    # 40 presses of 1 % and 36 of 0.25 % near hover (the protocol's lift_trim_after): z steps down the same way
    m = good_model(trims=(0, 0, 0, 40 * 328 + 36 * 82))
    c = by_item(m, lift_step=328)["lift"]
    assert c.text == "trim 49 %: press z 75 times, or Z", c.text  # 36 of 0.25 %, then 39 of 1 % under 500
    m.set_stick(Joystick(0, 0, 0, LIFT_ZERO, 0))
    m.apply_packet(status(), NOW)
    assert by_item(m)["lift"].state == "ok"


def test_sticks_and_trims_name_the_axis_and_the_key() -> None:
    m = good_model(trims=(5 * 256, 0, 0, 0))
    c = by_item(m, trim_step=256)["sticks"]
    assert c.state == "todo" and c.text == "roll trim +1280: press → 2 times", c.text  # lab map: → is roll down
    natural = build_keymap(preset="natural")
    assert "press ←" in checks(m, NOW, natural, trim_step=256)[2].text  # natural map: ← is roll down
    m = good_model()
    m.set_stick(Joystick(0, -STICK_NEUTRAL - 1, 0, 0, 0))
    assert by_item(m)["sticks"].text.startswith("centre the pitch stick")
    m.set_stick(Joystick(0, -STICK_NEUTRAL, 0, 0, 0))
    assert by_item(m)["sticks"].state == "ok"


def test_link_lost_and_waiting() -> None:
    m = good_model()
    m.apply(LinkLost(0.7), NOW)
    assert by_item(m)["link"].state == "todo" and "LINK LOST" in by_item(m)["link"].text
    assert next_step(checks(m, NOW, KEYMAP)).item == "link"  # the link before anything else


def test_a_board_that_never_answered_is_named_so() -> None:
    """Issue 21: the start-up grace ran out without one frame: the pilot is told what to check, not 'for 3.0 s'."""
    m = Model(start=0.0)
    m.apply(LinkLost(3.0, never_heard=True), 3.0)
    assert m.link_lost and m.events[-1].severity == "error"
    assert m.events[-1].text == ("LINK LOST: no answer from the board in 3.0 s since the link opened (is it on, and "
                                 "on this port?)")


@pytest.mark.parametrize("v, state", [(12.4, "ok"), (10.9, "info"), (10.3, "todo")])
def test_battery_levels(v: float, state: str) -> None:
    m = good_model()
    m.apply_packet(Height(101325, 0, 0, 0, volts(v), 2500), NOW)
    assert by_item(m)["battery"].state == state


def test_crash_must_be_acknowledged() -> None:
    m = good_model(flags=Flag.CALIBRATED | Flag.CRASHED)
    c = by_item(m)["crash"]
    assert c.state == "todo" and c.text.endswith("press c")
    assert by_item(good_model())["crash"].state == "ok"


def test_wireless_states() -> None:
    m = good_model()
    assert by_item(m)["wireless"].text == "cable"
    m.radio_name, m.radio_up = "ble", True
    assert by_item(m)["wireless"].state == "ok" and "8 hands over" in by_item(m)["wireless"].text
    m.apply_packet(status(wireless=WirelessState.STARTING), NOW)
    assert by_item(m)["wireless"].state == "info"
    m.apply_packet(status(wireless=WirelessState.STARTED), NOW)
    assert by_item(m)["wireless"].text == "flying over BLE"


def test_log_space() -> None:
    assert by_item(good_model(log_fill=12))["log"].text == "88 % free"
    assert by_item(good_model(log_fill=95))["log"].state == "info"
    m = good_model(log_fill=100)
    m.apply_packet(LogStatus(int(LogState.FULL), 131072, 5000, 0), NOW)
    c = by_item(m)["log"]
    assert c.state == "todo" and "F5" in c.text and "F4" in c.text


def test_every_nak_reason_maps_to_an_item() -> None:
    assert set(NAK_ITEM) == set(Nak) and set(NAK_TEXT) == set(Nak)
    assert {v for v in NAK_ITEM.values() if v is not None} <= set(ITEMS)


@pytest.mark.parametrize("nak, item", [(n, i) for n, i in NAK_ITEM.items() if i is not None])
def test_a_refusal_marks_its_item_until_fixed(nak: Nak, item: str) -> None:
    broken = {"calibrated": {"flags": Flag(0)}, "lift": {"trims": (0, 0, 0, 2000)},
              "sticks": {"trims": (0, 2000, 0, 0)}, "crash": {"flags": Flag.CALIBRATED | Flag.CRASHED},
              "log": {"log_fill": 100}}
    m = good_model(**broken.get(item, {}))  # type: ignore[arg-type]
    if item == "battery":
        m.apply_packet(Height(101325, 0, 0, 0, volts(10.2), 2500), NOW)
    if item == "wireless":
        m.radio_name = "ble"  # a radio, not connected
    assert by_item(m)[item].state != "ok"
    m.apply(CommandFailed(1, Op.MODE, Mode.FULL, NAK_TEXT[nak], nak), NOW)
    c = by_item(m)[item]
    assert c.refused.startswith("NAK mode FULL") and c.state == "todo"
    assert sum(e.source == "nak" for e in m.events) == 1


def test_a_refused_mode_is_said_once() -> None:
    """The board answers a refused mode twice: its Ack's NAK and a REFUSED event. One line in the list."""
    m = good_model(flags=Flag(0))
    m.apply(CommandFailed(1, Op.MODE, Mode.FULL, NAK_TEXT[Nak.NOT_CALIBRATED], Nak.NOT_CALIBRATED), NOW)
    m.apply_packet(Event(EventCode.REFUSED, (int(Nak.NOT_CALIBRATED) << 8) | Mode.FULL, 9000), NOW + 0.01)
    assert len(m.events) == 1 and m.events[0].source == "nak"
    # a second request later is said again (merged into one line with a count)
    m.apply(CommandFailed(2, Op.MODE, Mode.FULL, NAK_TEXT[Nak.NOT_CALIBRATED], Nak.NOT_CALIBRATED), NOW + 5)
    assert len(m.events) == 1 and m.events[0].count == 2


def test_repeated_events_merge_with_a_count() -> None:
    m = Model(start=0.0)
    for i in range(5):
        m.apply(NotSent("mode YAW", "not connected"), 1.0 + i)
    assert len(m.events) == 1 and m.events[0].count == 5 and m.events[0].t == 5.0
    m.note(6.0, "info", "term", "something else")
    m.apply(NotSent("mode YAW", "not connected"), 7.0)  # still among the last lines: moved to the end, counted
    assert [e.count for e in m.events] == [1, 6] and m.events[-1].text.startswith("not sent")
    m.apply(NotSent("mode YAW", "not connected"), 200.0)  # long after: a new line
    assert [e.count for e in m.events] == [1, 6, 1]
    seqs = [e.seq for e in m.events]
    assert seqs == sorted(seqs) and len(set(seqs)) == 3  # each written line has its own place in the order


def test_board_events_merge_despite_their_time_stamps() -> None:
    m = Model(start=0.0)
    for i in range(3):
        m.apply_packet(Event(EventCode.OVERFLOW, 12, 1000 + 100 * i), 1.0 + i)
    assert len(m.events) == 1 and m.events[0].count == 3 and m.events[0].text.startswith("[1.200]")


def test_deadline_misses_are_one_line() -> None:
    m = Model(start=0.0)
    m.apply_packet(Event(EventCode.DEADLINE_MISS, 2600, 1000), 1.0)
    m.note(2.0, "info", "term", "between")
    for i, period in enumerate((2700, 3100, 2650)):
        m.apply_packet(Event(EventCode.DEADLINE_MISS, period, 11000 + 10000 * i), 11.0 + 10 * i)
    misses = [e for e in m.events if "deadline" in e.text]
    assert len(misses) == 1 and misses[0].text.startswith("deadline misses reported 4 times since 1 s (longest "
                                                          "period 3100 µs; at most one report per 10 s")
    assert m.events[-1] is misses[0]


def test_log_keys_say_what_they_did() -> None:
    m = good_model()
    m.apply(CommandAcked(1, Op.LOG_START, 0, 2400), NOW)
    assert m.events[-1].text.startswith("log recording started (2.4 kB")
    m.apply(CommandAcked(2, Op.LOG_STOP, 0, 52000), NOW)
    assert "stopped (52.0 kB" in m.events[-1].text
    m.apply_packet(LogStatus(int(LogState.IDLE), 52000, 1234, 0), NOW)
    m.apply(Requested(Op.LOG_RESET, 0, "cable"), NOW)
    m.apply(CommandAcked(3, Op.LOG_RESET, 0, 0), NOW)
    assert m.events[-1].text == "log erased: 1234 records gone"


def test_alarms_ring_once_on_each_rising_edge() -> None:
    m = good_model()
    a = Alarms()
    assert a.update(m, NOW) == []
    m.apply_packet(Attitude(Mode.PANIC, 0, 0, 0, 0, 0, 0), NOW)
    assert a.update(m, NOW) == ["PANIC"] and a.update(m, NOW) == []
    m.apply(LinkLost(0.6), NOW)
    m.apply_packet(status(Flag.CALIBRATED | Flag.LOW_BATTERY | Flag.CRASHED), NOW)
    assert a.update(m, NOW) == ["LINK LOST", "low battery", "crash"]
    m.apply_packet(Attitude(Mode.SAFE, 0, 0, 0, 0, 0, 0), NOW)
    a.update(m, NOW)
    m.apply_packet(Attitude(Mode.PANIC, 0, 0, 0, 0, 0, 0), NOW)
    assert a.update(m, NOW) == ["PANIC"]  # a new PANIC rings again


def test_a_crash_event_alone_is_an_alarm() -> None:
    """Over BLE no Status comes: the board's CRASH event rings the bell by itself."""
    m = Model(start=0.0)
    a = Alarms()
    a.update(m, NOW)
    m.apply_packet(Event(EventCode.CRASH, 3500, 1000), NOW)
    assert a.update(m, NOW) == ["crash"]


def test_the_natural_preset_swaps_the_roll_arrows_only() -> None:
    lab, natural = build_keymap(), build_keymap(preset="natural")
    changed = {b.action.name for b, c in zip(lab, natural, strict=True) if b.keys != c.keys}
    assert changed == set(KEY_PRESETS["natural"]) == {"roll_up", "roll_down"}
    assert [b.keys for b in natural if b.action.name == "roll_down"] == [("left",)]


def test_over_ble_the_log_space_is_not_a_wait_and_an_empty_log_is_no_fault() -> None:
    # Seen flying over BLE: the panel's top line said "waiting for the board…" with every check green but the log,
    # whose fill only the cable carries; then F5 on an empty log (NAK log empty) made "next: the log — not known
    # yet" the pilot's next step, though an empty log stops nothing.
    m = good_model(log_fill=12)
    m.radio_name, m.radio_up = "ble", True
    m.apply_packet(status(log_fill=12, wireless=WirelessState.STARTED), NOW)
    later = NOW + 30.0  # the cable's Status is long stale; BLE carries no log fill
    m.apply_packet(Attitude(Mode.SAFE, 0, 0, 0, 0, 0, 0), later)
    m.apply_packet(Height(101325, 0, 0, 0, volts(12.4), 2500), later)
    m.set_link_stats(link_stats(), later)
    log = {c.item: c for c in checks(m, later, KEYMAP)}["log"]
    assert log.state == "info" and "not over BLE" in log.text
    m.apply(CommandFailed(1, Op.LOG_DOWNLOAD, 0, NAK_TEXT[Nak.LOG_EMPTY], Nak.LOG_EMPTY), later)
    found = checks(m, later, KEYMAP)
    assert next_step(found) is None or next_step(found).item != "log"
    assert NAK_ITEM[Nak.LOG_EMPTY] is None
