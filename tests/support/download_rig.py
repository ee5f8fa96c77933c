"""The log download's rig: the real board and the terminal's side joined by a byte proxy in each direction, on one
simulated clock (bench/download.py describes it; tests/session/test_download.py uses it)."""

from __future__ import annotations

from collections.abc import Callable

from fcb_sim.board.board import Board, BoardConfig
from fcb_sim.world.physics import World
from term.core.link import LinkSession, PacketReceived
from term.core.protocol import SPEC_OF, Joystick, LogChunk, LogStatus, Op, cobs_decode
from term.session.download import RUNNING, LogDownloader
from term.transports.loopback import Faults, FaultyChannel

STEP = 0.001  # s: the rig's time step (the board's UART drains 11.5 bytes per ms)
NEUTRAL = Joystick(0, 0, 0, 0, 0)


def is_type(kind: type) -> Callable[[bytes], bool]:
    """A frame filter for the byte proxy: true for the frames of one packet type (as sent)."""
    type_id = SPEC_OF[kind].type_id

    def pred(frame: bytes) -> bool:
        raw = cobs_decode(frame[:-1])
        return bool(raw) and raw[0] == type_id  # type: ignore[index]

    return pred


class Rig:
    """The terminal's side (a LinkSession and, once started, a LogDownloader, wired as the app wires them) and the
    board, through a byte proxy in each direction, on a simulated clock. The board has ``record_s`` s of log."""

    def __init__(self, seed: int = 1, record_s: float = 1.0) -> None:
        self.board = Board(BoardConfig(seed=seed, log_scheme="rice"), world=World(seed))
        self.session = LinkSession(0.0)
        self.session.set_joystick(NEUTRAL)
        self.up = FaultyChannel(seed=seed * 2)  # terminal -> board
        self.down = FaultyChannel(seed=seed * 2 + 1)  # board -> terminal
        self.now = 0.0
        self.dl: LogDownloader | None = None
        self.events: list[object] = []
        self.up.send(self.session.hello(), 0.0)
        self.run(0.3)
        self.command(Op.LOG_START)
        self.run(record_s)
        self.command(Op.LOG_STOP)
        self.run(0.1)
        assert self.board.log.used > 0 and not self.board.log.recording

    def faults(self, up: Faults, down: Faults) -> None:
        self.up.faults, self.down.faults = up, down

    def command(self, op: Op, arg: int = 0) -> object:
        """Send a command and run until its outcome (CommandAcked or CommandFailed), which is returned."""
        cmd_id = self.session.send_command(op, arg, self.now)
        n = len(self.events)
        self.run(2.0, lambda: any(getattr(e, "cmd_id", None) == cmd_id for e in self.events[n:]))
        return next(e for e in self.events[n:] if getattr(e, "cmd_id", None) == cmd_id)

    def step(self) -> None:
        t = self.now = self.now + STEP
        s, b = self.session, self.board
        b.advance(int(t * 1e6))
        data = self.up.receive(t)
        if data:
            b.uart_receive(data)
        self.down.send(b.uart_transmit(), t)
        data = self.down.receive(t)
        events = (s.receive(data, t) if data else []) + s.poll(t)
        dl = self.dl
        for ev in events:
            self.events.append(ev)
            if dl is None:
                continue
            if type(ev) is PacketReceived and type(ev.packet) in (LogStatus, LogChunk):
                dl.feed(ev.packet, t)  # what the model does with them
            dl.on_event(ev, t)
        if dl is not None:
            req = dl.poll(t)
            if req is not None:
                dl.sent(s.send_command(req.op, req.arg, t), t)
        self.up.send(s.data_to_send(t), t)

    def run(self, seconds: float, stop: Callable[[], bool] | None = None) -> None:
        end = self.now + seconds
        while self.now < end and not (stop is not None and stop()):
            self.step()

    def download(self, limit_s: float = 120.0, dl: LogDownloader | None = None) -> LogDownloader:
        """Run a download (a new one, or ``dl`` resumed by the caller) until it ends or ``limit_s`` passes."""
        self.dl = dl if dl is not None else LogDownloader(started=self.now)
        d = self.dl
        self.run(limit_s, lambda: d.state != RUNNING)
        return d

    def truth(self) -> bytes:
        return self.board.log.contents()[: self.board.log.used]
