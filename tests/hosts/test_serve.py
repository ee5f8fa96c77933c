"""`fcb-sim serve --pty` for real: a plain pyserial client flies the board over the pseudo-terminal with bytes
built by term.core.protocol; signals end it cleanly; floods and garbage do not stop it; bad options are one line."""

from __future__ import annotations

import os
import random
import signal
import subprocess
import sys
import time
from collections.abc import Callable
from typing import Any

import pytest
import serial

from fcb_sim.board import control as C
from fcb_sim.hosts.serve import ThreadedServer, make_board
from term.core.protocol import (
    PROTOCOL_VERSION,
    Ack,
    Attitude,
    Command,
    Compact,
    Decoder,
    Encoder,
    Heartbeat,
    HeartbeatAck,
    Height,
    Hello,
    Joystick,
    Mode,
    Motion,
    Nak,
    Op,
    Status,
    WirelessState,
)

HOVER_LIFT = C.z_to_lift(-4.0 * 400**2)
SERVE = [sys.executable, "-m", "fcb_sim.cli", "serve"]


class Client:
    """A pilot in a dozen lines of pyserial: joystick at 50 Hz, heartbeats answered, packets kept."""

    def __init__(self, path: str) -> None:
        self.port = serial.Serial(path, 115200, timeout=0)
        self.enc, self.dec = Encoder(), Decoder()
        self.js = Joystick(0, 0, 0, 0, 0)
        self.got: list[Any] = []
        self.cmd_id = 0

    def poll(self) -> None:
        """One round: the joystick out, whatever arrived in, heartbeats answered."""
        self.port.write(self.enc.encode(self.js))
        for pkt in self.dec.feed(self.port.read(8192)):
            self.got.append(pkt)
            if type(pkt) is Heartbeat:
                self.port.write(self.enc.encode(HeartbeatAck(pkt.counter, pkt.board_ms)))

    def pump(self, seconds: float, until: Callable[[], bool] | None = None) -> bool:
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            self.poll()
            if until is not None and until():
                return True
            time.sleep(0.02)
        return until is None

    def command(self, op: int, arg: int = 0) -> Ack:
        self.cmd_id += 1
        cid = self.cmd_id
        self.port.write(self.enc.encode(Command(cid, int(op), arg)))
        assert self.pump(5.0, lambda: any(type(p) is Ack and p.cmd_id == cid for p in self.got)), "no Ack"
        return [p for p in self.got if type(p) is Ack and p.cmd_id == cid][-1]

    def last(self, kind: type) -> Any:
        return next((p for p in reversed(self.got) if type(p) is kind), None)


@pytest.fixture
def served() -> Any:
    # a generous link timeout: a test machine busy with other work must not starve the client into a PANIC
    proc = subprocess.Popen([*SERVE, "--pty", "--scenario", "no-spikes", "--link-timeout", "3"],
                            stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, env=dict(os.environ, PYTHONUNBUFFERED="1"))
    try:
        line = proc.stdout.readline()
        assert line.startswith("pty: /dev/"), line
        yield proc, line.split()[1]
    finally:
        if proc.poll() is None:
            proc.kill()
        proc.wait(5)


def test_a_pyserial_client_flies_the_board_over_the_pty(served: Any) -> None:
    proc, path = served
    c = Client(path)
    c.port.write(c.enc.encode(Hello(PROTOCOL_VERSION, 0, 0, 1, 0)))
    assert c.pump(3.0, lambda: c.last(Hello) is not None)
    assert c.last(Hello).role == 1 and c.last(Hello).protocol == PROTOCOL_VERSION
    assert c.command(Op.MODE, Mode.FULL).status == Nak.NOT_CALIBRATED
    assert c.command(Op.MODE, Mode.CALIBRATION).status == Nak.OK
    assert c.pump(4.0, lambda: (s := c.last(Status)) is not None and s.flags & 1 and
                  c.last(Motion) is not None)
    assert c.command(Op.MODE, Mode.FULL).status == Nak.OK
    c.js = Joystick(0, 0, 0, int(HOVER_LIFT * 1.1), 0)
    assert c.pump(6.0, lambda: (h := c.last(Height)) is not None and h.height > 150), "no lift-off"  # (the 3 m room)
    m = c.last(Motion)
    assert min(m.ae1, m.ae2, m.ae3, m.ae4) > 300
    c.js = Joystick(0, 0, 0, int(HOVER_LIFT * 0.75), 0)
    assert c.pump(8.0, lambda: (h := c.last(Height)) is not None and h.vz > -50 and h.height < 80), "no landing"
    c.js = Joystick(0, 0, 0, 0, 0)
    c.pump(0.1)
    assert c.command(Op.MODE, Mode.SAFE) == Ack(c.cmd_id, Op.MODE, Nak.OK, Mode.SAFE)
    assert c.pump(2.0, lambda: (m := c.last(Motion)) is not None and (m.ae1, m.ae2, m.ae3, m.ae4) == (0, 0, 0, 0))
    c.port.close()
    proc.send_signal(signal.SIGTERM)
    out, err = proc.communicate(timeout=10)
    assert proc.returncode == 0 and "mode SAFE" in out and "Traceback" not in err


def test_sigint_ends_it_cleanly(served: Any) -> None:
    proc, _ = served
    proc.send_signal(signal.SIGINT)
    out, err = proc.communicate(timeout=10)
    assert proc.returncode == 0 and out.startswith("served") and "Traceback" not in err


def test_floods_garbage_and_half_frames_never_stall_the_loop() -> None:
    srv = ThreadedServer(make_board(seed=2))
    path = srv.start()
    try:
        c = Client(path)
        rng = random.Random(1)
        half = c.enc.encode(Command(1, Op.MODE, Mode.MANUAL))[:6]
        for _ in range(40):
            c.port.write(bytes(rng.randrange(256) for _ in range(4000)) + half)
            c.poll()
        before = sum(type(p) is Heartbeat for p in c.got)
        assert c.pump(2.0, lambda: sum(type(p) is Heartbeat for p in c.got) >= before + 5)
        assert c.command(Op.TRIM_ROLL, 1) == Ack(c.cmd_id, Op.TRIM_ROLL, Nak.OK, 256)
        board = srv.server.board
        assert board.rx_overflow > 0 or board.decoder.stats.frames_bad > 0
        assert srv.error is None
        c.port.close()
    finally:
        srv.stop()
    assert srv.error is None


@pytest.mark.parametrize(("args", "text"), [
    (["--pty", "--scenario", "mars"], "unknown scenario 'mars'"),
    ([], "--pty"),
    (["--pty", "--link-timeout", "0"], "--link-timeout"),
])
@pytest.mark.parametrize("how", ["entry point", "python -m"])
def test_bad_options_are_one_line(args: list[str], text: str, how: str) -> None:
    # both ways of starting it: the installed entry point, and `python -m fcb_sim.cli` (as term --sim does)
    exe = [os.path.join(os.path.dirname(sys.executable), "fcb-sim")] if how == "entry point" else SERVE[:-1]
    r = subprocess.run([*exe, "serve", *args], capture_output=True, text=True, timeout=20)
    assert r.returncode == 2 and text in r.stderr and len(r.stderr.strip().splitlines()) == 1
    assert r.stdout == ""


async def test_wireless_handover_across_the_served_boards_radio() -> None:
    """The BLE seam end to end: `serve --pty --ble-hci`, the cable hands over with key 8, the phone's first
    answer makes it STARTED, commands then go and come back over BLE, and losing the phone while flying over
    it means PANIC with the cable back in charge."""
    import asyncio

    from term.transports.ble import BleTransport

    exe = os.path.join(os.path.dirname(sys.executable), "fcb-sim")
    proc = await asyncio.create_subprocess_exec(
        exe, "serve", "--pty", "--link-timeout", "3", "--ble-hci", "tcp-server:127.0.0.1:0",
        stdout=asyncio.subprocess.PIPE, stderr=asyncio.subprocess.DEVNULL)
    try:
        path = (await asyncio.wait_for(proc.stdout.readline(), 20)).decode().split()[1]
        ble = (await asyncio.wait_for(proc.stdout.readline(), 20)).decode().split()
        address, spec = ble[3], ble[5]
        cable = Client(path)
        phone = BleTransport(address, hci=spec, timeout=10.0)
        await phone.open()
        phone_enc, phone_dec = Encoder(), Decoder()
        heard: list[Any] = []

        async def listen() -> None:
            while True:
                heard.extend(phone_dec.feed(await phone.read()))

        listener = asyncio.create_task(listen())

        async def until_read(cond: Callable[[], bool], seconds: float = 5.0) -> None:
            async with asyncio.timeout(seconds):
                while not cond():
                    cable.poll()
                    await asyncio.sleep(0.02)

        cable.cmd_id += 1
        cable.port.write(cable.enc.encode(Command(cable.cmd_id, Op.WIRELESS, 1)))
        await until_read(lambda: any(type(p) is Ack and p.op == Op.WIRELESS for p in cable.got))
        assert [p for p in cable.got if type(p) is Ack][-1].status == Nak.OK
        await until_read(lambda: any(type(p) is Heartbeat for p in heard))  # STARTING: heartbeats over BLE too
        hb = next(p for p in heard if type(p) is Heartbeat)
        await phone.write(phone_enc.encode(HeartbeatAck(hb.counter, hb.board_ms)))  # -> STARTED
        # STARTED: the cable falls silent, the phone gets the compact telemetry
        await until_read(lambda: any(type(p) is Compact and p.wireless == WirelessState.STARTED for p in heard))
        await phone.write(phone_enc.encode(Joystick(0, 0, 0, 0, 0)))
        await phone.write(phone_enc.encode(Command(200, Op.MODE, Mode.MANUAL)))
        await until_read(lambda: Ack(200, Op.MODE, Nak.OK, Mode.MANUAL) in heard)
        await phone.write(phone_enc.encode(Joystick(0, 0, 0, 6000, 0)))
        await asyncio.sleep(0.3)
        listener.cancel()
        await phone.close()  # the phone goes away while the board flies over it
        n = len(cable.got)
        await until_read(lambda: any(type(p) is Attitude and p.mode == Mode.PANIC for p in cable.got[n:]), 10.0)
        cable.port.close()
    finally:
        proc.terminate()
        await proc.wait()
