"""The endpoint's socket and its edges without a board: the address a user types (loopback unless
``--mavlink-public``), TCP to a ground station listening (pymavlink's ``tcpin``) and back after it went away, and
what a hostile ground station sends (garbage, NaN, a flood) costing only its own messages."""

from __future__ import annotations

import math
import socket
import time

import pytest

pytest.importorskip("pymavlink", reason="the mavlink extra (pymavlink) is not installed")

from term.data.mavlink import DISPLAY_QUEUE_MAX, MavlinkEndpoint  # noqa: E402
from term.data.mavlink_socket import MavlinkError, parse_address  # noqa: E402
from tests.support.mavlink_gcs import Gcs  # noqa: E402


def wait_for(cond: object, timeout: float = 10.0) -> None:
    deadline = time.monotonic() + timeout
    while not cond():  # type: ignore[operator]
        assert time.monotonic() < deadline, "timed out"
        time.sleep(0.01)


def test_the_address_is_loopback_unless_public_and_bad_ones_are_one_line() -> None:
    assert parse_address("127.0.0.1:14550") == ("udp", "127.0.0.1", 14550)
    assert parse_address("tcp:localhost:5760") == ("tcp", "localhost", 5760)
    assert parse_address("14551") == ("udp", "127.0.0.1", 14551)
    assert parse_address("udp:[::1]:14550") == ("udp", "::1", 14550)
    for bad in ("udp:127.0.0.1:0", "127.0.0.1:99999", "127.0.0.1:port", "x" * 400, "tcp:", ":14550\0"):
        with pytest.raises(MavlinkError) as exc:
            parse_address(bad)
        assert "\n" not in str(exc.value) and len(str(exc.value)) < 200
    with pytest.raises(MavlinkError, match="--mavlink-public"):
        parse_address("192.0.2.7:14550")
    assert parse_address("192.0.2.7:14550", public=True) == ("udp", "192.0.2.7", 14550)


def test_over_tcp_the_ground_station_gets_the_heartbeat_and_again_after_it_went_away() -> None:
    from pymavlink import mavutil  # (here: its every dialect takes 0.7 s to import, on each worker)

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    first = mavutil.mavlink_connection(f"tcpin:127.0.0.1:{port}", source_system=255)
    ep = MavlinkEndpoint(f"tcp:127.0.0.1:{port}")
    ep.start()
    try:
        assert first.wait_heartbeat(timeout=10) is not None
        assert first.messages["HEARTBEAT"].type == 2
        first.close()  # the ground station goes; another comes on the same port
        wait_for(lambda: not ep.socket.connected)
        second = mavutil.mavlink_connection(f"tcpin:127.0.0.1:{port}", source_system=255)
        try:
            assert second.wait_heartbeat(timeout=10) is not None
        finally:
            second.close()
    finally:
        ep.close()


def test_a_hostile_ground_station_costs_only_its_own_messages() -> None:
    gcs = Gcs()
    ep = MavlinkEndpoint(gcs.address)
    posted: list[object] = []
    ep._post = lambda fn, *args: posted.append((fn, args))  # a display that is not drawing: nothing runs
    ep.start()
    try:
        wait_for(lambda: gcs.last("HEARTBEAT") is not None)
        gcs.conn.write(bytes(range(256)) * 8 + b"\xfd\xff\xff" * 100)  # garbage
        gcs.mav.param_set_send(1, 1, b"CTRL_P1", math.nan, 9)
        gcs.mav.param_set_send(1, 1, b"\xff\xfe\x00bad", 1.0, 9)
        wait_for(lambda: any("CTRL_P1 not set: not a number" in t for t in gcs.texts()))
        wait_for(lambda: any("no parameter" in t for t in gcs.texts()))
        assert all(t.isascii() for t in gcs.texts()), gcs.texts()  # (the mode's "—" spelled "-")
        # A flood of commands while the display is held: at most DISPLAY_QUEUE_MAX wait on it, the rest are
        # dropped; a flood of sticks is one call (latest wins) once handed over.
        for i in range(500):
            gcs.mav.command_long_send(1, 1, 400, 0, math.nan, 0, 0, 0, 0, 0, 0)
            if i % 50 == 49:
                time.sleep(0.02)  # (the kernel's receive buffer drops a burst's rest: the flood is paced a little)
        wait_for(lambda: ep.received.get("COMMAND_LONG", 0) > DISPLAY_QUEUE_MAX + 100)
        n = ep.received["COMMAND_LONG"]
        wait_for(lambda: ep.dropped_in == n - DISPLAY_QUEUE_MAX or ep.received["COMMAND_LONG"] != n)
        assert len(posted) == DISPLAY_QUEUE_MAX and ep.dropped_in == ep.received["COMMAND_LONG"] - DISPLAY_QUEUE_MAX
        ep.state = "offered"
        for i in range(300):
            gcs.mav.manual_control_send(1, 0, 0, i, 0, 0)
            if i % 50 == 49:
                time.sleep(0.02)
        wait_for(lambda: ep.received.get("MANUAL_CONTROL", 0) >= 100 and ep._stick is not None
                 and ep._stick.lift == round(299 * 32767 / 1000))  # the last one came: it is the stick
        assert len(posted) == DISPLAY_QUEUE_MAX  # (the queue is full: the stick's call was dropped, its value kept)
        for fn, args in posted:  # the display draws again: what waited runs (each NaN costs itself)
            fn(*args)  # type: ignore[operator]
        posted.clear()
        gcs.mav.manual_control_send(1, 0, 0, 500, 0, 0)  # the next stick reaches the display again
        wait_for(lambda: len(posted) == 1)
        assert ep.socket.connected and gcs.last("HEARTBEAT") is not None
    finally:
        ep.close()
        gcs.close()


def test_term_refuses_a_bad_or_public_address_in_one_line_before_anything_starts(
        capsys: pytest.CaptureFixture[str]) -> None:
    from term.cli.main import main

    assert main(["--sim", "--mavlink", "192.0.2.7:14550"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("term: --mavlink") and "--mavlink-public" in err and "\n" not in err
    assert main(["--sim", "--mavlink", "udp:127.0.0.1:nope"]) == 2
    assert "[udp:|tcp:]HOST:PORT" in capsys.readouterr().err
    assert main(["--sim", "--mavlink-public"]) == 2
    assert "--mavlink-public needs --mavlink" in capsys.readouterr().err
