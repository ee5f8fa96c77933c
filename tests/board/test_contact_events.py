"""Both boards, the Python one and the C one, fly into the lab's 3 m ceiling and land (issue 35): each sends
EventCode.CONTACT (the ceiling, then the ground) the pilot sees, its height estimate at the ceiling within 0.3 m of
the truth with the speed near zero (rms), and after the landing the height within 0.1 m."""

from __future__ import annotations

import math
import shutil
from typing import Any

import pytest

from fcb_sim.board import control as C
from fcb_sim.board.board import Board
from fcb_sim.board.parts import BoardConfig
from fcb_sim.world import constants as P
from fcb_sim.world.physics import World
from term.core.protocol import (
    Command,
    ContactKind,
    Decoder,
    Event,
    EventCode,
    Height,
    Joystick,
    Mode,
    Op,
    encode,
)

PILOT_US = 20_000


def _lift(world: World, target_m: float) -> int:
    tr = world.truth
    a = max(-4.0, min(4.0, 2.0 * (target_m - tr.h) + 2.5 * tr.vd))
    ae = P.AE_HOVER_NOMINAL * P.V_REF / max(tr.volts, 1.0) * math.sqrt(max(0.0, 1.0 + a / P.G))
    return max(0, min(32767, round(ae * 32767 / C.LIFT_AE_MAX)))


def _fly(kind: str) -> dict[str, Any]:
    world = World(3, room=(3.0, 3.0))
    cfg = BoardConfig(seed=3)
    if kind == "python":
        board: Any = Board(cfg, world=world)
    else:
        from fcb_sim.hosts.cboard import CBoard

        board = CBoard(cfg, world=world)
    dec = Decoder()
    contacts: list[tuple[float, int, int]] = []
    at_ceiling: list[tuple[float, float]] = []
    after_landing: list[float] = []
    target: float | None = None
    for t in range(PILOT_US, 16_000_000 + 1, PILOT_US):
        board.advance(t)
        for pkt in dec.feed(board.uart_transmit()):
            if isinstance(pkt, Event) and pkt.code == EventCode.CONTACT:
                contacts.append((t / 1e6, pkt.arg >> 16, pkt.arg & 0xFFFF))
            elif isinstance(pkt, Height):
                tr = world.truth
                if world.contact == "ceiling" and t > 8_000_000:
                    at_ceiling.append((pkt.height / 100 - tr.h, pkt.vz / 100))
                if 13_000_000 < t and world.contact == "ground":
                    after_landing.append(pkt.height / 100 - tr.h)
        if t == 500_000:
            board.uart_receive(encode(Command(1, Op.MODE, int(Mode.CALIBRATION))))
        elif t == 2_000_000:
            board.uart_receive(encode(Command(2, Op.MODE, int(Mode.FULL))))
            target = 1.0
        elif t == 5_000_000:
            target = 3.6  # into the ceiling
        elif t == 10_000_000:
            target = -0.5  # down, and onto the floor with the motors running
        elif t == 13_000_000:
            target = None  # lift to zero: the motors idle
        lift = _lift(world, target) if target is not None else 0
        board.uart_receive(encode(Joystick(0, 0, 0, lift, 0)))
    return {"contacts": contacts, "ceiling": at_ceiling, "landed": after_landing, "world": world}


@pytest.mark.parametrize("kind", ["python", "c"])
def test_the_ceiling_and_the_landing_are_seen_and_followed(kind: str) -> None:
    if kind == "c" and (shutil.which("cc") is None or shutil.which("make") is None):
        pytest.skip("no C compiler (cc) or make")
    r = _fly(kind)
    kinds = [k for _t, k, _v in r["contacts"]]
    assert kinds[:2] == [ContactKind.CEILING, ContactKind.GROUND], r["contacts"]
    assert [c.where for c in r["world"].contacts] == ["ceiling", "ground"]
    ceiling = r["ceiling"][10:]  # from half a second after the hit on
    assert len(ceiling) > 20
    assert max(abs(e) for e, _vz in ceiling) < 0.3
    assert math.sqrt(sum(vz * vz for _e, vz in ceiling) / len(ceiling)) < 0.25  # not the climb's 0.5 m/s
    assert r["landed"] and max(abs(e) for e in r["landed"]) <= 0.1
