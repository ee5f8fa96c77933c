"""The Connection pump running a LinkSession over real transports: a pty with pyserial and a scripted board on
the master side, and the faulty loopback. Waits are on conditions with timeouts, never fixed sleeps."""

from __future__ import annotations

import asyncio
import contextlib
import time
from collections.abc import Callable

import pytest

from term.core.link import CommandAcked, CommandFailed, LinkSession, PacketReceived, VersionMismatch
from term.core.protocol import PROTOCOL_VERSION, Command, Decoder, Encoder, Heartbeat, Hello, Joystick, Nak, Op
from term.session.connection import Connection, TransportFailed
from term.transports.base import TransportError
from term.transports.loopback import loopback_pair
from term.transports.serial import SerialTransport
from tests.conftest import PtyBoard, ScriptedBoard


class Events:
    """Collects a connection's events; ``wait`` for a condition on them."""

    def __init__(self) -> None:
        self.items: list[object] = []
        self._changed = asyncio.Event()

    def __call__(self, ev: object) -> None:
        self.items.append(ev)
        self._changed.set()

    def of(self, kind: type) -> list:
        return [e for e in self.items if type(e) is kind]

    async def wait(self, cond: Callable[[], bool], timeout: float = 5.0) -> None:
        async with asyncio.timeout(timeout):
            while not cond():
                self._changed.clear()
                await self._changed.wait()


async def test_over_a_pty_heartbeats_answered_commands_acked_and_refused(pty_pair: tuple[int, str]) -> None:
    master, path = pty_pair
    refuse = {Op.MODE: Nak.LIFT_NOT_ZERO}
    board = ScriptedBoard(heartbeat_period=0.02, nak=lambda c: refuse.get(c.op, Nak.OK), start=time.monotonic())
    peer = PtyBoard(master, board, time.monotonic)
    await peer.start()
    events = Events()
    conn = Connection(SerialTransport(path), LinkSession(time.monotonic()), on_event=events)
    try:
        await conn.start()
        await peer.wait_for(lambda: len(board.hb_acks) >= 5)
        assert board.hellos and board.hellos[0].protocol == PROTOCOL_VERSION
        first = board.hb_acks[0].counter  # heartbeats sent before the port opened were flushed by the open
        assert [a.counter for a in board.hb_acks[:5]] == list(range(first, first + 5))
        ok = conn.send_command(Op.TRIM_LIFT, 1)
        refused = conn.send_command(Op.MODE, 2)
        await events.wait(lambda: events.of(CommandAcked) and events.of(CommandFailed))
        assert events.of(CommandAcked) == [CommandAcked(ok, Op.TRIM_LIFT, 1, 10)]
        (failed,) = events.of(CommandFailed)
        assert failed.cmd_id == refused and failed.nak is Nak.LIFT_NOT_ZERO and failed.reason == "lift not at zero"
        conn.set_joystick(Joystick(100, -100, 0, 2000, 0))
        await peer.wait_for(lambda: any(j.lift == 2000 for j in board.joysticks))
        st = conn.stats
        assert st.rtt_last_ms is not None and st.rtt_last_ms > 0
        assert st.frames_ok > 0 and st.frames_bad == 0 and not st.lost
        assert any(isinstance(e, PacketReceived) and type(e.packet) is Heartbeat for e in events.items)
    finally:
        await conn.stop()
        await peer.stop()
    assert not events.of(TransportFailed)  # a clean stop reports nothing


async def test_heartbeats_are_answered_with_no_timer_due(pty_pair: tuple[int, str]) -> None:
    master, path = pty_pair
    board = ScriptedBoard(heartbeat_period=None)  # heartbeats sent by hand below
    peer = PtyBoard(master, board, time.monotonic)
    await peer.start()
    session = LinkSession(time.monotonic(), link_timeout=3600.0)  # no timer deadline for an hour
    conn = Connection(SerialTransport(path), session)
    try:
        await conn.start()
        await peer.wait_for(lambda: bool(board.hellos))
        enc = Encoder()
        for k in range(3):
            peer._write(enc.encode(Heartbeat(k, 1000 * k)))
            await peer.wait_for(lambda k=k: len(board.hb_acks) == k + 1, timeout=20.0)
        assert [a.counter for a in board.hb_acks] == [0, 1, 2]
    finally:
        await conn.stop()
        await peer.stop()


async def test_board_going_away_is_one_transport_failed_event(pty_pair: tuple[int, str]) -> None:
    master, path = pty_pair
    board = ScriptedBoard(heartbeat_period=0.02, start=time.monotonic())
    peer = PtyBoard(master, board, time.monotonic)
    await peer.start()
    events = Events()
    conn = Connection(SerialTransport(path), LinkSession(time.monotonic()), on_event=events)
    await conn.start()
    await peer.wait_for(lambda: len(board.hb_acks) >= 2)
    await peer.stop(close_fd=True)  # the board's end of the cable is gone
    await events.wait(lambda: bool(events.of(TransportFailed)))
    (failed,) = events.of(TransportFailed)
    assert failed.message.startswith(f"serial port {path} lost") and "\n" not in failed.message
    with pytest.raises(TransportError, match="lost"):
        await asyncio.wait_for(conn.wait_closed(), 2.0)
    assert not conn.running
    await conn.stop()  # idempotent after a failure
    assert len(events.of(TransportFailed)) == 1


async def test_open_failure_raises_the_transport_error() -> None:
    conn = Connection(SerialTransport("/dev/ttyNOSUCHPORT9"), LinkSession(0.0))
    with pytest.raises(TransportError, match="not found"):
        await conn.start()


async def test_version_mismatch_reaches_the_app(pty_pair: tuple[int, str]) -> None:
    master, path = pty_pair
    board = ScriptedBoard(heartbeat_period=0.05, protocol=PROTOCOL_VERSION + 1, start=time.monotonic())
    peer = PtyBoard(master, board, time.monotonic)
    await peer.start()
    conn = Connection(SerialTransport(path), LinkSession(time.monotonic()))  # events into conn.events
    try:
        await conn.start()
        async with asyncio.timeout(5):
            while not isinstance(ev := await conn.events.get(), VersionMismatch):
                pass
        assert ev == VersionMismatch(PROTOCOL_VERSION + 1, PROTOCOL_VERSION)
    finally:
        await conn.stop()
        await peer.stop()


async def test_over_the_faulty_loopback_commands_survive_loss() -> None:
    loop = asyncio.get_running_loop()
    pair = loopback_pair(drop=0.2, delay=0.002, seed=4, clock=loop.time)
    board = ScriptedBoard(heartbeat_period=0.02, start=loop.time())
    enc_dec = board  # the board end is driven by hand: read, answer, tick
    events = Events()
    conn = Connection(pair.a, LinkSession(loop.time(), command_timeout=0.03, command_retries=8),
                      clock=loop.time, on_event=events)

    async def board_loop() -> None:
        await pair.b.open()
        while True:
            data = b""
            with contextlib.suppress(TimeoutError):
                async with asyncio.timeout(0.01):
                    data = await pair.b.read()
            out = (enc_dec.receive(data, loop.time()) if data else b"") + enc_dec.tick(loop.time())
            if out:
                await pair.b.write(out)

    task = asyncio.create_task(board_loop())
    try:
        await conn.start()
        # Alternating ops: two presses of one trim in a row would merge into one command (STEP_OPS).
        ids = [conn.send_command((Op.TRIM_PITCH, Op.TRIM_ROLL)[k % 2], 1) for k in range(10)]
        await events.wait(lambda: len(events.of(CommandAcked)) + len(events.of(CommandFailed)) == 10)
        assert {e.cmd_id for e in events.of(CommandAcked)} == set(ids)
        assert len(board.executed) == 10
        assert pair.a_to_b.stats.frames_dropped > 0  # the faults were on
    finally:
        task.cancel()
        await conn.stop()


async def test_callback_bug_stops_the_connection_and_is_raised(pty_pair: tuple[int, str]) -> None:
    master, path = pty_pair
    board = ScriptedBoard(heartbeat_period=0.02, start=time.monotonic())
    peer = PtyBoard(master, board, time.monotonic)
    await peer.start()

    def broken(ev: object) -> None:
        raise RuntimeError("bug in the app")

    conn = Connection(SerialTransport(path), LinkSession(time.monotonic()), on_event=broken)
    try:
        await conn.start()
        with pytest.raises(RuntimeError, match="bug in the app"):
            await asyncio.wait_for(conn.wait_closed(), 5.0)
    finally:
        await conn.stop()
        await peer.stop()


def test_command_frames_are_what_the_board_decodes() -> None:
    # The bytes the pump writes are the session's own: one encoder, in order.
    s = LinkSession(0.0)
    cmd = s.send_command(Op.LOG_START, 0, 0.0)
    assert Decoder().feed(s.hello() + s.data_to_send(0.0)) == [
        Hello(PROTOCOL_VERSION, 0, 0, 1, 0),
        Command(cmd, Op.LOG_START, 0),
    ]


async def test_transport_closed_under_the_connection_is_reported_once() -> None:
    loop = asyncio.get_running_loop()
    pair = loopback_pair(clock=loop.time)
    await pair.b.open()
    events = Events()
    conn = Connection(pair.a, LinkSession(loop.time()), clock=loop.time, on_event=events)
    await conn.start()
    await pair.a.close()  # someone else closed the transport: not a clean stop of the connection
    await events.wait(lambda: bool(events.of(TransportFailed)))
    assert "closed" in events.of(TransportFailed)[0].message
    with pytest.raises(TransportError):
        await conn.wait_closed()


async def test_clean_stop_emits_nothing_and_wait_closed_returns() -> None:
    loop = asyncio.get_running_loop()
    pair = loopback_pair(clock=loop.time)
    await pair.b.open()
    events = Events()
    async with Connection(pair.a, LinkSession(loop.time()), clock=loop.time, on_event=events) as conn:
        assert conn.running
        assert await pair.b.read()  # our Hello
    await asyncio.wait_for(conn.wait_closed(), 1.0)
    assert not events.of(TransportFailed) and not conn.running


async def test_a_simulator_starved_at_start_up_is_no_lost_link() -> None:
    """Issue 21 (make test-busy: test_app_flight said LINK LOST 0.8 s into start-up while the simulator's child got
    no CPU). The child is held by SIGSTOP for a bounded 1.2 s while the terminal connects (a starved process, not
    hoped-for load): the board's first frame comes late, and that is the link still being made, not a lost link.
    The terminal's own loop keeps running meanwhile, so nothing here is the terminal's own starvation."""
    import os
    import signal

    from term.core.link import LinkLost
    from term.session.sim import SimBoard

    sim = SimBoard(seed=3)
    sim.start()
    assert sim.proc is not None
    events = Events()
    conn = Connection(SerialTransport(sim.port), LinkSession(time.monotonic(), link_timeout=0.5), on_event=events)
    os.kill(sim.proc.pid, signal.SIGSTOP)
    try:
        await conn.start()
        await asyncio.sleep(1.2)  # the stall itself: the child cannot run, however fast the machine
        os.kill(sim.proc.pid, signal.SIGCONT)
        await events.wait(lambda: any(type(getattr(e, "packet", None)) is Heartbeat for e in events.items), 20.0)
        assert not events.of(LinkLost)
    finally:
        os.kill(sim.proc.pid, signal.SIGCONT)
        await conn.stop()
        sim.stop()


async def test_a_stall_of_the_terminal_is_left_out_whole(pty_pair: tuple[int, str]) -> None:
    """Issue 21 (bench.contention at 4 busy processes per core: LINK LOST from the terminal while frames waited in the
    OS). The terminal's process gets no CPU for 0.7 s: its clock jumps while its loop does not run. The whole stall
    is the terminal's own, not the board's silence, whichever task runs first afterwards (the reader, with the
    frames that waited): the timer used to count only the part past its own deadline, and the reader none."""
    master, path = pty_pair
    board = ScriptedBoard(heartbeat_period=0.02, start=time.monotonic())
    peer = PtyBoard(master, board, time.monotonic)
    await peer.start()
    offset = [0.0]

    def clock() -> float:
        return time.monotonic() + offset[0]

    events = Events()
    # the radio's policy: no stick, so no timer deadline but the loss's while frames keep coming
    session = LinkSession(clock(), link_timeout=0.5, change_only=True)
    conn = Connection(SerialTransport(path), session, clock, on_event=events)
    try:
        await conn.start()
        await peer.wait_for(lambda: len(board.hb_acks) >= 3)
        offset[0] += 0.7  # the stall, as the terminal's clock sees it
        acked = len(board.hb_acks)
        await peer.wait_for(lambda: len(board.hb_acks) >= acked + 5)
        from term.core.link import LinkLost

        assert not events.of(LinkLost)
        assert not conn.stats.lost
    finally:
        await conn.stop()
        await peer.stop()
