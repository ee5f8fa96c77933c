"""The simulated board's test rig: a PC end that talks to a Board in its own time, the hover lift."""

from __future__ import annotations

import random
from typing import Any

from fcb_sim.board import control as C
from fcb_sim.board.board import Board
from term.core.protocol import (
    Ack,
    Command,
    Decoder,
    Encoder,
    Heartbeat,
    HeartbeatAck,
    Joystick,
    LogChunk,
    Op,
)

HOVER_LIFT = C.z_to_lift(-4.0 * 400**2)


class Pc:
    """A PC on the board's UART: joystick every 10 ms, heartbeats answered, packets collected."""

    def __init__(self, board: Board) -> None:
        self.board = board
        self.enc, self.dec = Encoder(), Decoder()
        self.js = Joystick(0, 0, 0, 0, 0)
        self.packets: list[Any] = []
        self.cmd_id = 0
        self.drop_chunks = 0.0
        self.rng = random.Random(1)

    def send(self, pkt: Any) -> None:
        self.board.uart_receive(self.enc.encode(pkt))

    def command(self, op: int, arg: int = 0) -> Ack:
        self.cmd_id = (self.cmd_id + 1) & 0xFF
        cid = self.cmd_id
        self.send(self.js)  # the joystick streams all the time: the board knows the sticks before the key
        self.send(Command(cid, int(op), arg))
        self.run(0.03)
        acks = [p for p in self.packets if type(p) is Ack and p.cmd_id == cid]
        assert acks, f"no Ack for {Op(op).name}"
        return acks[-1]

    def run(self, seconds: float, joystick: bool = True) -> None:
        b = self.board
        end = b.now + int(seconds * 1e6)
        while b.now < end:
            if joystick:
                self.send(self.js)
            b.advance(min(end, b.now + 10_000))
            self.read()

    def read(self, answer: bool = True) -> None:
        for p in self.dec.feed(self.board.uart_transmit()):
            if type(p) is LogChunk and self.rng.random() < self.drop_chunks:
                continue
            self.packets.append(p)
            if type(p) is Heartbeat and answer:
                self.send(HeartbeatAck(p.counter, p.board_ms))

    def of(self, kind: type) -> list[Any]:
        return [p for p in self.packets if type(p) is kind]
