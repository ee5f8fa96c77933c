"""Handing control back to the cable (issue 36): the board's Ack of WIRELESS 0 over BLE is its word that it is back on
the cable, so the radio's silence that follows is the handover's, not a BLE LINK LOST on the link in control.

How the soak's LINK LOST in control came about: the board acks WIRELESS 0 over BLE, goes DISCONNECTED and writes
only to the cable from then on; the terminal kept BLE in control until the cable (2 % of its bytes damaged) brought
a Status (5 Hz) or the WIRELESS_STATE event, a median 0.2 s later in the soak (``handback_cable_news``), and when
none of those came through within the 0.5 s link timeout, the radio's silence was declared BLE LINK LOST while BLE
still carried control."""

from __future__ import annotations

from term.core.events import CABLE, RADIO, FromLink, LinkUp
from term.core.link import CommandAcked, CommandFailed, LinkLost, PacketReceived
from term.core.protocol import Compact, Event, EventCode, Mode, Nak, Op, WirelessState
from term.session.model import Model


def _over_ble() -> Model:
    m = Model(start=0.0, link_name="serial", radio_name="ble")
    m.apply(LinkUp(RADIO, "ble", False), 1.0)
    m.apply(FromLink(RADIO, PacketReceived(Compact(int(Mode.SAFE), int(WirelessState.STARTED), 0, 0, 0, 1160))), 2.0)
    assert m.over_ble
    return m


def test_the_acked_handback_puts_control_on_the_cable_before_the_cable_says_so() -> None:
    m = _over_ble()
    m.apply(FromLink(RADIO, CommandAcked(7, Op.WIRELESS, 0, 0)), 3.0)
    assert m.wireless == WirelessState.DISCONNECTED and not m.over_ble
    m.apply(FromLink(RADIO, LinkLost(0.5)), 3.5)  # the board writes only to the cable now
    assert not m.radio_lost and not m.control_lost
    assert not any("LINK LOST" in e.text for e in m.events), [e.text for e in m.events]


def test_a_refused_or_undelivered_handback_leaves_control_on_ble() -> None:
    m = _over_ble()
    m.apply(FromLink(RADIO, CommandFailed(7, Op.WIRELESS, 0, "busy", Nak.LOG_BUSY)), 3.0)
    m.apply(FromLink(RADIO, CommandFailed(8, Op.WIRELESS, 0, "no answer from the board after 4 tries", None)), 3.1)
    m.apply(FromLink(RADIO, CommandAcked(9, Op.WIRELESS, 1, 0)), 3.2)  # (a handover asked again: no change)
    assert m.over_ble
    m.apply(FromLink(RADIO, LinkLost(0.5)), 3.6)
    assert m.radio_lost and m.control_lost


def test_the_cables_news_after_the_ack_changes_nothing() -> None:
    m = _over_ble()
    m.apply(FromLink(RADIO, CommandAcked(7, Op.WIRELESS, 0, 0)), 3.0)
    said = Event(EventCode.WIRELESS_STATE, int(WirelessState.DISCONNECTED), 3100)
    m.apply(FromLink(CABLE, PacketReceived(said)), 3.2)
    assert m.wireless == WirelessState.DISCONNECTED and not m.over_ble
