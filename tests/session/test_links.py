"""One opener for every link a user names (term/session/links.py): flying, term params and the simulated board's
links get their transports from ``open_link``, which says what each can do."""

from __future__ import annotations

import os

import pytest

from term.core.errors import UsageError
from term.session.links import LinkSpec, open_link
from term.transports.ble import BleTransport
from term.transports.serial import SerialTransport


async def test_a_port_is_the_serial_transport_and_it_opens() -> None:
    master, slave = os.openpty()
    try:
        t = open_link(LinkSpec(port=os.ttyname(slave), baud=115200))
        assert isinstance(t, SerialTransport) and t.address == os.ttyname(slave) and t.baud == 115200
        assert t.movable and not t.is_open
        await t.open()
        assert t.is_open and t.innermost is t
        await t.close()
        assert not t.is_open
    finally:
        os.close(master)
        os.close(slave)


def test_a_url_is_serial_too_and_ble_alone_is_ble() -> None:
    assert isinstance(open_link(LinkSpec(port="socket://127.0.0.1:5760")), SerialTransport)
    t = open_link(LinkSpec(ble="F0:5A:00:00:00:01", hci="tcp-client:127.0.0.1:9", ble_timeout=2.0))
    assert isinstance(t, BleTransport) and t.movable and t.address == "F0:5A:00:00:00:01"
    assert t.hci == "tcp-client:127.0.0.1:9" and t.timeout == 2.0


def test_a_cable_with_a_radio_beside_it_splits_in_two() -> None:
    spec = LinkSpec(port="/dev/ttyUSB0", baud=9600, ble="F0:5A:00:00:00:01", hci="tcp-client:h:1")
    assert spec.cable == LinkSpec(port="/dev/ttyUSB0", baud=9600)
    assert spec.radio == LinkSpec(ble="F0:5A:00:00:00:01", hci="tcp-client:h:1")
    assert isinstance(open_link(spec), SerialTransport)  # the cable first: the radio is opened beside it
    assert LinkSpec(ble="x").cable is None and LinkSpec(port="p").radio is None


def test_naming_no_board_is_one_line() -> None:
    with pytest.raises(UsageError, match="no board given"):
        open_link(LinkSpec())
