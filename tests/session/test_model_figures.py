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
