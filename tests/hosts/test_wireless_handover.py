"""The handover end to end with the real board: the cable (a LinkSession on the board's UART), the terminal's
BLE path (Connection over BleTransport over our bleak backend over the bumble radio), the board paced to the
wall clock as ``fcb-sim serve`` runs it. Cable -> STARTING -> STARTED -> fly over BLE -> connection lost ->
DISCONNECTED, PANIC, and the UART resumes."""

from __future__ import annotations

import asyncio
import time

import pytest

from fcb_sim.board.board import Board, BoardConfig
from fcb_sim.hosts.radio import start_radio
from term.core.link import LinkSession, PacketReceived
from term.core.protocol import Ack, Attitude, Compact, Joystick, Mode, Op, WirelessState
from term.session.connection import Connection
from term.transports.ble import BleTransport
from tests.support.waits import until

S = WirelessState


class Bench:
    """The board on the wall clock with its cable to a PC session, as fcb-sim serve and term would run it."""

    def __init__(self) -> None:
        self.board = Board(BoardConfig(seed=3, link_timeout_s=0.5, board_id=4))
        self.cable = LinkSession(time.monotonic())
        self.cable_packets: list = []
        self.t0 = time.monotonic()
        self._task: asyncio.Task[None] | None = None

    def start(self) -> None:
        self._task = asyncio.create_task(self._run())

    async def _run(self) -> None:
        board, cable = self.board, self.cable
        while True:
            now = time.monotonic()
            board.advance(int((now - self.t0) * 1e6))
            out = board.uart_transmit()
            events = cable.receive(out, now) if out else cable.poll(now)
            self.cable_packets += [ev.packet for ev in events if isinstance(ev, PacketReceived)]
            data = cable.data_to_send(now)
            if data:
                board.uart_receive(data)
            await asyncio.sleep(0.001)

    async def stop(self) -> None:
        if self._task is not None:
            self._task.cancel()
            with pytest.raises(asyncio.CancelledError):
                await self._task


async def test_handover_fly_and_lose_the_connection() -> None:
    bench = Bench()
    board = bench.board
    radio = await start_radio(board.wireless, board=board, board_id=4, hci="tcp-server:127.0.0.1:0")
    bench.start()
    ble_packets: list = []
    transport = BleTransport(radio.address, hci=radio.hci.client_spec, timeout=5.0)
    phone = Connection(
        transport,
        LinkSession(time.monotonic(), change_only=True),
        on_event=lambda ev: ble_packets.append(ev.packet) if isinstance(ev, PacketReceived) else None,
    )
    try:
        await phone.start()
        await until(lambda: board.wireless.is_connected)
        await asyncio.sleep(0.15)
        assert board.wireless.state is S.DISCONNECTED  # a connection alone changes nothing
        assert board.mode is Mode.SAFE

        # Key 8 on the cable: STARTING; the phone answers the BLE heartbeat: STARTED.
        cmd = bench.cable.send_command(Op.WIRELESS, 1, time.monotonic())
        await until(lambda: board.wireless.state is S.STARTED)
        assert any(type(p) is Ack and p.cmd_id == cmd and p.status == 0 for p in bench.cable_packets)
        await until(lambda: any(type(p) is Compact and p.wireless == S.STARTED for p in ble_packets))
        assert not any(type(p) is Attitude for p in ble_packets)  # the full telemetry stays on the cable

        # The UART falls silent: the cable sees no new telemetry.
        await asyncio.sleep(0.05)
        seen = len(bench.cable_packets)
        await asyncio.sleep(0.3)
        assert len(bench.cable_packets) == seen

        # Fly over BLE: MANUAL, then lift.
        phone.send_command(Op.MODE, Mode.MANUAL)
        await until(lambda: board.mode is Mode.MANUAL)
        phone.set_joystick(Joystick(0, 0, 0, 14000, 0))
        await until(lambda: min(board.ae) > 0)
        assert board.modes.flying

        # The phone is gone: DISCONNECTED, PANIC, and the UART resumes.
        await phone.stop()
        await until(lambda: board.wireless.state is S.DISCONNECTED)
        assert board.mode is Mode.PANIC
        assert max(board.ae) > 0  # PANIC holds a descent level before stopping the motors
        seen = len(bench.cable_packets)
        await until(lambda: any(type(p) is Attitude and p.mode == Mode.PANIC for p in bench.cable_packets[seen:]))
        assert board.wireless.stats.largest <= 20
    finally:
        await phone.stop()
        await bench.stop()
        await radio.close()
