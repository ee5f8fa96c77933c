"""A PC on a board's UART, for either board (the Python ``Board`` or the C board through ``CBoard``): joystick every
10 ms, heartbeats answered (unless told not to), every packet kept, the terminal's console lines kept too (its
link session's ``Console`` over a decoder that keeps text). ``make_board(kind)`` builds one; a C board without a
compiler skips the test."""

from __future__ import annotations

from typing import Any

import pytest

from fcb_sim.board.board import Board
from fcb_sim.board.parts import BoardConfig
from term.core.console import Console, ConsoleLine
from term.core.protocol import Ack, Command, Decoder, Encoder, Heartbeat, HeartbeatAck, Joystick, Nak, Op, Text

KINDS = ("python", "c")


def make_board(kind: str, **cfg: Any) -> Any:
    if kind == "python":
        return Board(BoardConfig(**cfg))
    from fcb_sim.hosts.cboard import CBoard, CBoardUnavailable

    try:
        return CBoard(BoardConfig(**cfg))
    except CBoardUnavailable as exc:
        pytest.skip(str(exc))


class Pc:
    def __init__(self, board: Any) -> None:
        self.board = board
        self.enc, self.dec = Encoder(), Decoder(keep_text=True)
        self.console = Console()
        self.lines: list[ConsoleLine] = []
        self.js = Joystick(0, 0, 0, 0, 0)
        self.packets: list[Any] = []
        self.cmd_id = 0
        self.answer = True  # answer heartbeats (False: the terminal has gone quiet)
        self.stream = True  # stream the joystick

    def send(self, pkt: Any) -> None:
        self.board.uart_receive(self.enc.encode(pkt))

    def command(self, op: int, arg: int = 0) -> Ack:
        self.cmd_id = (self.cmd_id + 1) & 0xFF
        cid = self.cmd_id
        self.send(self.js)
        self.send(Command(cid, int(op), arg))
        self.run(0.03)
        acks = [p for p in self.packets if type(p) is Ack and p.cmd_id == cid]
        assert acks, f"no Ack for {Op(op).name}"
        return acks[-1]

    def ok(self, op: int, arg: int = 0) -> Ack:
        ack = self.command(op, arg)
        assert ack.status == Nak.OK, Nak(ack.status).name
        return ack

    def run(self, seconds: float) -> None:
        b = self.board
        end = b.now + int(seconds * 1e6)
        while b.now < end:
            if self.stream and self.answer:
                self.send(self.js)
            b.advance(min(end, b.now + 10_000))
            self.read()

    def run_until(self, cond: Any, seconds: float) -> bool:
        """Run in 10 ms steps until ``cond()`` or ``seconds`` of board time; whether it held."""
        end = self.board.now + int(seconds * 1e6)
        while self.board.now < end:
            if cond():
                return True
            self.run(0.01)
        return bool(cond())

    def read(self) -> None:
        data = self.board.uart_transmit()
        pkts = self.dec.feed(data)
        t = self.board.now / 1e6
        self.lines += [ev for ev in self.console.feed_bytes(self.dec.take_text(), t) if type(ev) is ConsoleLine]
        for p in pkts:
            self.packets.append(p)
            if type(p) is Heartbeat and self.answer:
                self.send(HeartbeatAck(p.counter, p.board_ms))
            elif type(p) is Text:
                self.lines += [ev for ev in self.console.feed_packet(p, t) if type(ev) is ConsoleLine]

    def of(self, kind: type) -> list[Any]:
        return [p for p in self.packets if type(p) is kind]
