"""The model's figures and lines agree with each other (issue 34): merged lines keep the order of their causes, a
refused mode says from which mode, a link timeout in PANIC is not "not flying"."""

from __future__ import annotations

from term.core.events import NotSent
from term.core.protocol import Event, EventCode, Mode
from term.session.model import Model


def test_a_repeat_never_jumps_over_what_the_board_did_after_the_first() -> None:
    m = Model(start=0.0)
    m.note(1.0, "info", "term", "request PANIC")
    m.apply_packet(Event(EventCode.MODE_CHANGED, (Mode.FULL << 8) | Mode.PANIC, 1050), 1.05)
    m.note(1.5, "info", "term", "request PANIC")  # pressed again
    texts = [e.text for e in m.events]
    assert texts.index("request PANIC") < next(i for i, t in enumerate(texts) if "FULL → PANIC" in t)
    assert texts[-1] == "request PANIC" and len(texts) == 3
    # lines of the terminal alone still merge over each other
    m.apply(NotSent("mode YAW", "not connected"), 2.0)
    m.note(2.5, "info", "term", "something else")
    m.apply(NotSent("mode YAW", "not connected"), 3.0)
    assert m.events[-1].count == 2


def test_a_link_timeout_in_panic_is_not_called_not_flying() -> None:
    m = Model(start=0.0)
    m.mode = Mode.PANIC
    m.apply_packet(Event(EventCode.LINK_TIMEOUT, 1760, 5000), 5.0)
    text = m.events[-1].text
    assert "not flying" not in text and "PANIC" in text, text


def test_deadline_misses_say_they_count_the_boards_reports_not_every_miss() -> None:
    m = Model(start=0.0)
    for i in range(3):
        m.apply_packet(Event(EventCode.DEADLINE_MISS, 6034, 1000 + 10_000 * i), 1.0 + 10 * i)
    text = m.events[-1].text
    assert "reported 3 times" in text and "F9 counts them all" in text, text


def test_a_handback_is_not_called_a_restored_link() -> None:
    from term.core.link import LinkLost, LinkRestored
    from term.core.protocol import WirelessState

    m = Model(start=0.0, link_name="serial", radio_name="ble")
    m.radio_up = True
    m.wireless = WirelessState.STARTED
    m.apply(LinkLost(0.6), 10.0)
    m.wireless = WirelessState.DISCONNECTED
    m.apply(LinkRestored(64.1), 74.1)
    text = m.events[-1].text
    assert "link restored" not in text and "handed back after 64.1 s over BLE" in text, text
