"""The app's test rig: the app and a scripted board on a loopback pair, waits on the app's own events, the commands
a board executed (and before a marker), seeded flights for snapshots."""

from __future__ import annotations

import asyncio
import contextlib
from collections.abc import AsyncIterator, Callable
from contextlib import asynccontextmanager
from functools import partial

from term.core.link import LinkSession
from term.core.protocol import (
    PARAMS,
    Attitude,
    Joystick,
    Mode,
    Op,
    Param,
    scaled,
)
from term.session.config import Config
from term.session.model import Model
from term.session.sim import SimBoard
from term.transports.base import TransportClosed, TransportError
from term.transports.loopback import loopback_pair
from term.transports.serial import SerialTransport
from term.ui.app import TermApp
from tests.support.waits import until


def seeded_handover(seed: int = 1, seconds: float = 3.0) -> Model:
    """The sans-IO board with a cable session and a radio session on a simulated clock: connect the radio at
    0.2 s, key 8 over the cable at 0.5 s, the radio answers and carries control (STARTED), MANUAL over BLE at
    1.2 s, then lift with a little roll. Returns the model the screen renders."""
    from fcb_sim.board.board import Board, BoardConfig
    from fcb_sim.world.physics import World
    from term.session.station import RADIO_SESSION

    board = Board(BoardConfig(seed=seed), world=World(seed))
    cable = LinkSession(0.0)
    phone = LinkSession(0.0, **RADIO_SESSION)  # type: ignore[arg-type]
    model = Model(start=0.0)
    model.link_name = "seeded board (simulated clock)"
    model.radio_name = "BLE F0:5A:00:00:00:01 (simulated clock)"
    board.uart_receive(cable.hello())
    js = Joystick(0, 0, 0, 0, 0)
    cable.set_joystick(js)
    phone.set_joystick(js)
    t_us = 0
    while t_us < seconds * 1e6:
        t_us += 1000
        t = t_us / 1e6
        if t_us == 200_000:
            board.ble_connected()
            model.radio_up = True
        elif t_us == 500_000:
            cable.send_command(Op.WIRELESS, 1, t)
        elif t_us == 1_200_000:
            phone.send_command(Op.MODE, Mode.MANUAL, t)
        elif t_us >= 1_500_000 and t_us % 100_000 == 0:
            js = Joystick(3000, -1500, 0, min(12000, 1000 * (t_us - 1_400_000) // 100_000), 0)
            cable.set_joystick(js)
            phone.set_joystick(js)
        board.advance(t_us)
        for ev in cable.receive(board.uart_transmit(), t) + cable.poll(t):
            model.apply(ev, t)
        notes = board.wireless.notifications()
        assert all(len(n) <= 20 for n in notes)
        for ev in phone.receive(b"".join(notes), t) + phone.poll(t):
            model.radio_event(ev, t)
        board.uart_receive(cable.data_to_send(t))
        if model.radio_up:
            board.ble_receive(phone.data_to_send(t))
    model.set_stick(js)
    model.set_link_stats(cable.stats_at(t), t)
    model.set_radio_stats(phone.stats_at(t), t)
    return model


SIZE = (120, 44)


def seeded_flight(seed: int = 1, seconds: float = 5.0) -> tuple[Model, float]:
    """Fly the seeded board through a LinkSession on a simulated clock: calibrate, FULL, lift off with some
    roll, one refused command; returns the model the screen renders and the end time."""
    from fcb_sim.board.board import Board, BoardConfig
    from fcb_sim.world.physics import World

    board = Board(BoardConfig(seed=seed), world=World(seed))
    session = LinkSession(0.0)
    model = Model(start=0.0)
    model.link_name = "seeded board (simulated clock)"
    board.uart_receive(session.hello())
    script: list[tuple[float, Callable[[float], None]]] = [
        (0.3, lambda t: session.send_command(Op.MODE, Mode.FULL, t)),  # refused: not calibrated
        (0.5, lambda t: session.send_command(Op.MODE, Mode.CALIBRATION, t)),
        (2.0, lambda t: session.send_command(Op.MODE, Mode.FULL, t)),
        (2.2, lambda t: session.send_command(Op.LOG_START, 0, t)),
        (4.2, lambda t: session.send_command(Op.GAIN_P2, 1, t)),
        (4.6, lambda t: session.send_command(Op.PROFILE, 0, t)),
    ]
    # From 2.5 s the pilot holds 0.5 m with the lift stick (as tests/ui/test_app_flight.py does), 20 times a second,
    # with a little right roll and nose down from 4 s.
    base = 15000.0
    next_pilot = 2.5
    session.set_joystick(Joystick(0, 0, 0, 0, 0))
    step_us = 1000
    t_us = 0
    while t_us < seconds * 1e6:
        t_us += step_us
        t = t_us / 1e6
        while script and script[0][0] <= t:
            script.pop(0)[1](t)
        if t >= next_pilot and model.height is not None:
            next_pilot += 0.05
            h, vz = scaled(model.height, "height"), scaled(model.height, "vz")
            base += 40 * (0.5 - h)
            lift = max(0, min(32767, int(base + 4000 * (0.5 - h) - 3000 * vz)))
            session.set_joystick(Joystick(2500, -1500, 0, lift, 0) if t >= 4.0 else Joystick(0, 0, 0, lift, 0))
        board.advance(t_us)
        for ev in session.receive(board.uart_transmit(), t) + session.poll(t):
            model.apply(ev, t)
        board.uart_receive(session.data_to_send(t))
    model.set_stick(session._js or Joystick(0, 0, 0, 0, 0))
    model.set_link_stats(session.stats_at(t_us / 1e6), t_us / 1e6)
    return model, t_us / 1e6


def app_for(flight: tuple[Model, float]) -> TermApp:
    model, end = flight
    app = TermApp(joystick=False, clock=lambda: end)
    app.model = model
    return app


@asynccontextmanager
async def served(config: Config | None = None, preset: str | None = None) -> AsyncIterator[tuple[TermApp, object,
                                                                                                Callable]]:
    sim = SimBoard(seed=2, extra=["--preset", preset] if preset else [])
    port = sim.start()
    try:
        app = TermApp(SerialTransport(port), joystick=False, config=config)
        async with app.run_test(size=(120, 44)) as pilot:

            await until(pilot, lambda: len(app.model.params) == len(PARAMS))  # listed when the board said Hello
            yield app, pilot, partial(until, pilot)  # the one wait, stepping this app (Pilot.pause)
    finally:
        sim.stop()


async def type_into(app: TermApp, text: str) -> None:
    edit = app.screen.query_one("#param-edit")
    edit.value = text  # type: ignore[attr-defined]
    edit.cursor_position = len(text)  # type: ignore[attr-defined]


def attitude(mode: Mode) -> Attitude:
    return Attitude(int(mode), 0, 0, 0, 0, 0, 0)


class LoopBoard:
    """Runs a ScriptedBoard on the board's end of a loopback pair (reads, replies, heartbeats)."""

    def __init__(self, transport, board, clock: Callable[[], float]) -> None:  # noqa: ANN001
        self.t, self.board, self.clock = transport, board, clock
        self.tasks: list[asyncio.Task[None]] = []

    async def start(self) -> None:
        await self.t.open()
        self.tasks = [asyncio.create_task(self._read()), asyncio.create_task(self._tick())]

    async def _read(self) -> None:
        while True:  # like a board's UART: the terminal's end closing and opening again does not stop it
            try:
                data = await self.t.read()
                reply = self.board.receive(data, self.clock())
                if reply:
                    await self.t.write(reply)
            except TransportClosed:
                return
            except TransportError:
                await asyncio.sleep(0.01)

    async def _tick(self) -> None:
        while True:
            out = self.board.tick(self.clock())
            if out:
                with contextlib.suppress(TransportError):
                    await self.t.write(out)
            await asyncio.sleep(max(0.001, self.board.next_deadline() - self.clock()))

    async def send(self, *pkts: object) -> None:
        await self.t.write(self.board.encoder.encode_many(pkts))

    async def write(self, raw: bytes) -> None:
        """Any bytes on the board's side of the wire: text between frames, damaged frames."""
        await self.t.write(raw)

    async def stop(self) -> None:
        for t in self.tasks:
            t.cancel()
        for t in self.tasks:
            with contextlib.suppress(asyncio.CancelledError):
                await t


@contextlib.asynccontextmanager
async def flying(scripted_board, size=(120, 44), link_timeout: float = 3.0, **board_kw):  # noqa: ANN001, ANN201
    """The app and the scripted board on one loopback pair, on the test's one loop. A stall of that loop (a busy
    machine, Textual's first layout) stalls the board too, so a short link timeout would see a silence that never
    was: the tests of silence ask for the report's 0.5 s themselves."""
    import time

    pair = loopback_pair()
    board = scripted_board(start=time.monotonic(), **board_kw)
    peer = LoopBoard(pair.b, board, time.monotonic)
    await peer.start()
    app = TermApp(pair.a, joystick=False, session_options={"link_timeout": link_timeout})
    try:
        async with app.run_test(size=size) as pilot:
            await until(pilot, lambda: board.hellos)
            yield app, pilot, board, peer
    finally:
        await peer.stop()


def sent(board) -> list[tuple[int, int]]:  # noqa: ANN001
    """The commands the board executed, but the parameter list the app asks for when the board says Hello."""
    return [(c.op, c.arg) for c in board.executed if c.op != Op.PARAM_LIST]


MARKER = (Op.PARAM_GET, int(Param.P1))  # a harmless request: the board answers with one parameter's value


async def sent_before_marker(pilot, app, board) -> list[tuple[int, int]]:  # noqa: ANN001
    """The commands the board had executed before a marker sent now. The link keeps order, so once the marker has
    arrived, anything the app sent before it has too: a check that something was NOT sent waits on this, never on
    a pause (which passes when the command is merely slow)."""
    app.send(*MARKER)
    await until(pilot, lambda: MARKER in sent(board))
    out = sent(board)
    return out[: len(out) - 1 - out[::-1].index(MARKER)]
