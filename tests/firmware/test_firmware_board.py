"""The C reference board (firmware/examples/host_board.c, built with ASan and UBSan) on a real pseudo-terminal,
spoken to by term.core.protocol's own Encoder and Decoder: Hello both ways, heartbeats with their round trip, command
ACK/NAK and retries, joystick frames counted, link silence -> PANIC -> SAFE, garbage on the line, and a clean end
on SIGTERM."""

from __future__ import annotations

import re
import subprocess

import pytest

from term.core import protocol as p
from tests.support.firmware import HostBoard, PtyPeer, build

BOARD_HELLO = p.Hello(p.PROTOCOL_VERSION, p.Role.BOARD, 0, 1, 4242)


@pytest.fixture
def board():  # noqa: ANN201
    b = HostBoard()
    peer = PtyPeer(b.path)
    try:
        yield b, peer
    finally:
        peer.close()
        status, _, err = b.terminate()
        assert status == 0, err  # a sanitizer finding would end it otherwise


def _connect(peer: PtyPeer) -> None:
    peer.send(p.Hello(p.PROTOCOL_VERSION, p.Role.TERMINAL, 0, 1, 0))
    peer.until(lambda: BOARD_HELLO in peer.received)


def _mode_changes(peer: PtyPeer) -> list[tuple[int, int]]:
    return [(e.arg >> 8, e.arg & 0xFF) for e in peer.events(p.EventCode.MODE_CHANGED)]


def test_hello_heartbeats_and_their_round_trip(board) -> None:  # noqa: ANN001
    _, peer = board
    _connect(peer)
    peer.until(lambda: len(peer.of(p.Heartbeat)) >= 4)
    hbs = peer.of(p.Heartbeat)
    assert [h.counter for h in hbs] == list(range(hbs[0].counter, hbs[0].counter + len(hbs)))
    assert all(0 < b.board_ms - a.board_ms < 1000 for a, b in zip(hbs, hbs[1:], strict=False))
    assert any(h.rtt > 0 for h in hbs[1:])  # our HeartbeatAcks came back as the board's round trip
    assert {a.mode for a in peer.of(p.Attitude)} == {p.Mode.SAFE}
    assert peer.dec.stats.frames_bad == 0 and peer.dec.stats.seq_gaps == 0


def test_panic_and_safe_accepted_everything_else_refused(board) -> None:  # noqa: ANN001
    _, peer = board
    _connect(peer)
    peer.send(p.Command(1, p.Op.MODE, p.Mode.MANUAL), p.Command(2, p.Op.TRIM_LIFT, 1),
              p.Command(3, p.Op.MODE, p.Mode.SAFE), p.Command(4, p.Op.MODE, p.Mode.PANIC),
              p.Command(5, p.Op.MODE, p.Mode.SAFE), p.Command(6, 250, 0))
    peer.until(lambda: len(peer.of(p.Ack)) == 6)
    nak = p.Nak.NOT_IMPLEMENTED
    assert [(a.cmd_id, a.status, a.value) for a in peer.of(p.Ack)] == [
        (1, nak, p.Mode.SAFE), (2, nak, p.Mode.SAFE), (3, p.Nak.OK, p.Mode.SAFE), (4, p.Nak.OK, p.Mode.PANIC),
        (5, p.Nak.PANIC_ACTIVE, p.Mode.PANIC), (6, nak, p.Mode.PANIC)]
    assert p.NAK_TEXT[nak] == "not implemented on this board"
    # PANIC ends in SAFE by itself, and says so
    peer.until(lambda: (p.Mode.PANIC, p.Mode.SAFE) in _mode_changes(peer))
    assert _mode_changes(peer) == [(p.Mode.SAFE, p.Mode.PANIC), (p.Mode.PANIC, p.Mode.SAFE)]
    assert len(peer.events(p.EventCode.PANIC_DONE)) == 1


def test_a_retried_command_is_answered_again_not_done_twice(board) -> None:  # noqa: ANN001
    _, peer = board
    _connect(peer)
    cmd = p.Command(9, p.Op.MODE, p.Mode.PANIC)
    peer.send(cmd, cmd)  # the first Ack was lost, as far as the terminal knows
    peer.until(lambda: len(peer.of(p.Ack)) == 2)
    assert peer.of(p.Ack)[0] == peer.of(p.Ack)[1] == p.Ack(9, p.Op.MODE, p.Nak.OK, p.Mode.PANIC)
    peer.pump(0.2)
    assert _mode_changes(peer) == [(p.Mode.SAFE, p.Mode.PANIC)]
    # a terminal that says Hello again starts its command ids afresh: the same command is new again
    peer.until(lambda: (p.Mode.PANIC, p.Mode.SAFE) in _mode_changes(peer))
    _connect(peer)
    peer.send(cmd)
    peer.until(lambda: len(peer.of(p.Ack)) == 3)
    peer.until(lambda: _mode_changes(peer).count((p.Mode.SAFE, p.Mode.PANIC)) == 2)


def test_link_silence_means_panic_then_safe(board) -> None:  # noqa: ANN001
    _, peer = board
    _connect(peer)
    peer.pump(0.3)
    assert not peer.events(p.EventCode.LINK_TIMEOUT)
    peer.ack_heartbeats = False  # the terminal goes quiet
    peer.until(lambda: (p.Mode.PANIC, p.Mode.SAFE) in _mode_changes(peer), timeout=6.0)
    (timeout,) = peer.events(p.EventCode.LINK_TIMEOUT)
    assert timeout.arg >= 500  # ms of silence when the board gave up
    assert _mode_changes(peer) == [(p.Mode.SAFE, p.Mode.PANIC), (p.Mode.PANIC, p.Mode.SAFE)]
    assert len(peer.events(p.EventCode.PANIC_DONE)) == 1


def test_joystick_frames_are_counted_fire_is_panic_and_sigterm_ends_cleanly() -> None:
    b = HostBoard()
    peer = PtyPeer(b.path)
    try:
        _connect(peer)
        peer.send(*[p.Joystick(i, -i, 0, 0, 0) for i in range(40)])
        peer.write(b"\x00\xff\x13\x37" * 30 + b"\x00")  # garbage on the line costs nothing but itself
        peer.send(p.Joystick(0, 0, 0, 0, int(p.Button.FIRE)), p.Joystick(0, 0, 0, 0, int(p.Button.FIRE)))
        peer.until(lambda: _mode_changes(peer) == [(p.Mode.SAFE, p.Mode.PANIC)])
        peer.send(p.Command(1, p.Op.LOG_STATUS, 0))
        peer.until(lambda: peer.of(p.Ack))
    finally:
        peer.close()
        status, out, err = b.terminate()
    assert status == 0, err
    assert "42 joystick frames, 1 commands" in out and out.count("\n") == 1, out
    assert int(re.search(r"(\d+) damaged", out).group(1)) == 30  # the 30 garbage pieces, each dropped alone


def test_usage_errors_are_one_line() -> None:
    exe = build().path("host_board")
    for args in ([], ["--nope"], ["/dev/does-not-exist-42"]):
        proc = subprocess.run([str(exe), *args], capture_output=True, text=True, timeout=10)
        assert proc.returncode in (1, 2) and proc.stderr.count("\n") == 1 and not proc.stdout, (args, proc)
