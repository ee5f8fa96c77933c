"""What the screen says for the board's contact and heading events (issue 35)."""

from __future__ import annotations

from term.core.protocol import ContactKind, EventCode
from term.session.texts import event_text


def test_contact_events_say_what_stopped_the_craft() -> None:
    assert event_text(EventCode.CONTACT, ContactKind.CEILING << 16 | 512) == ("warning", "hit the ceiling at 0.51 m/s")
    assert event_text(EventCode.CONTACT, ContactKind.GROUND << 16 | 300) == ("info", "touched down at 0.30 m/s")
    severity, text = event_text(EventCode.CONTACT, ContactKind.WALL << 16)
    assert severity == "warning" and "sideways" in text


def test_the_heading_drift_says_the_heading_is_relative() -> None:
    severity, text = event_text(EventCode.HEADING_DRIFT, -1234)
    assert severity == "info" and "-12.3°" in text and "no compass" in text
