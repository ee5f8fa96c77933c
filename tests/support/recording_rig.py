"""Recordings for the tests: a session recorded to a folder, the flash log's CSV, a live session replayed into a
model, a RAW flight's log."""

from __future__ import annotations

import math
from pathlib import Path

from fcb_sim.board.flash_log import LOG_VARS, encode_log
from term.core.events import (
    CABLE,
    FromLink,
    LinkDown,
    LinkUp,
    Note,
    Requested,
    StatsSample,
    StickSet,
)
from term.core.link import (
    CommandAcked,
    LinkLost,
    LinkRestored,
    LinkStats,
    PacketReceived,
)
from term.core.logfile import decode_to_rows, write_csv
from term.core.protocol import (
    Attitude,
    Compact,
    Encoder,
    Event,
    EventCode,
    Height,
    Joystick,
    Mode,
    Op,
    Status,
)
from term.data.recording import (
    SessionRecorder,
)
from term.session.model import Model


def _raw_flight_log(tmp_path: Path, seconds: float = 12.0,
                    fixed: bool = False) -> tuple[Path, list[tuple[int, ...]]]:
    """A RAW-mode flight in the simulator, logged as the board's logging task does every control period from the
    end of CALIBRATION on (the on-board filter restarts there too), encoded into flash, downloaded and written as
    term writes it (decode_to_rows, write_csv); the board's filter in fixed point with ``fixed``."""
    from fcb_sim.board.flash_log import encode_log
    from fcb_sim.lab.scenarios import Sim, _roll_stick
    from term.core.logfile import decode_to_rows, write_csv
    from term.core.protocol import Mode

    sim = Sim(3, core_kw={"fixed_point": fixed})
    rows: list[tuple[int, ...]] = []

    def log(s: Sim) -> None:
        if s.t <= 1.0:
            return
        fc = s.fc
        phi, theta, psi = fc.attitude_centideg()
        rows.append((round(s.t * 1e6), s.mode, phi, theta, psi, round(fc.sp), round(fc.sq), round(fc.sr),
                     round(fc.sax), round(fc.say), round(fc.saz), *fc.ae, round(fc.height * 100), 101325, 1200))

    sim.on_tick = log
    sim.prologue(Mode.RAW)
    sim.run_until(6.0)
    for k in range(int((seconds - 6.0) / 0.5)):  # the roll stick thrown side to side every half second
        sim.sticks[0] = _roll_stick(math.radians(15.0 if k % 2 else -15.0))
        sim.run_until(6.0 + 0.5 * (k + 1))
    path = tmp_path / "flight.csv"
    write_csv(encode_log(rows, "rice"), path, decode_to_rows)
    return path, rows


STATS = LinkStats(1.5, 2.0, 3.25, 0.0, 0.5, 1200.0, 300.0, 42, 1, 0.01, 0.05, 0.7, False, 5000, 900, 3, 1, 0, 10, 1)


def live_session(rec: SessionRecorder, model: Model, t0: float) -> None:
    """What the station does in a short flight, applied to ``model`` and recorded as the app records it."""
    board = Encoder()

    def emit(ev: object, now: float) -> None:
        model.apply(ev, now)
        rec.station_event(ev, now)

    emit(LinkUp(CABLE, "/dev/pts/7", False), t0)
    emit(Note("info", "term", "hello pilot"), t0 + 0.01)
    for i in range(400):
        now = t0 + 0.05 + i * 0.01
        pkts = [Attitude(int(Mode.MANUAL if i > 100 else Mode.SAFE), 10 * i, -20 * i, 7, 16 * i, 0, -16)]
        if i % 4 == 0:
            pkts.append(Height(101300, 10 * i, 0, 5, 1160 - i // 10, 2100))
        if i % 20 == 0:
            pkts.append(Status(1, 0, 0, 0, 0, 30, 2, 0))
        data = b"".join(board.encode(p) for p in pkts)
        rec.received(CABLE, data, now)  # the tap records the bytes before the session decodes them
        for p in pkts:
            model.apply(FromLink(CABLE, PacketReceived(p)), now)  # (the recorder skips these: bytes carry them)
            rec.station_event(FromLink(CABLE, PacketReceived(p)), now)
        if i == 100:
            emit(Requested(int(Op.MODE), int(Mode.MANUAL), CABLE), now)
            emit(FromLink(CABLE, CommandAcked(1, Op.MODE, 2, 2)), now)
        if i % 10 == 0:
            emit(StatsSample(CABLE, STATS), now)
            emit(StickSet(Joystick(i, 0, 0, 1000 + i, 0)), now)
        if i == 300:
            emit(FromLink(CABLE, LinkLost(0.5)), now)
        if i == 320:
            emit(FromLink(CABLE, LinkRestored(0.2)), now)


WALL = 1_700_000_000_000_000_000


def record(directory: Path, *, close: bool = True) -> tuple[SessionRecorder, list]:
    """A short session on an injected clock: telemetry in over the cable and the radio, sticks out, events."""
    rec = SessionRecorder(directory, 10.0, wall_ns=WALL)
    cable, radio, out = Encoder(), Encoder(), Encoder()
    sent = []
    for i in range(300):
        now = 10.0 + i * 0.01
        pkts = [Attitude(int(Mode.MANUAL), 1234 + i, -500, 9000, 164, -328, 0)]
        if i % 5 == 0:
            pkts.append(Height(101325 - i, 150 + i, 100, -2, 1168, 2150))  # cm (protocol 2)
        data = b"".join(cable.encode(p) for p in pkts)
        rec.received("serial", data[:7], now)  # split mid-frame, as a UART read may
        rec.received("serial", data[7:], now + 0.0005)
        sent += [("serial", "rx", p) for p in pkts]
        if i % 3 == 0:
            c = Compact(int(Mode.MANUAL), 2, 1234 + i, -500, 9000, 1168)
            rec.received("ble", radio.encode(c), now + 0.001)
            sent.append(("ble", "rx", c))
        js = Joystick(i, -i, 0, 2000, 0)
        rec.sent("serial", out.encode(js), now + 0.001)
        sent.append(("serial", "tx", js))
        if i == 150:
            rec.event(now + 0.001, "error", "link", "LINK LOST: nothing from the board for 0.5 s")
            rec.station_event(LinkDown("cable", "cable pulled"), now + 0.001)  # for a replay, not for the tables
            ev = Event(int(EventCode.LOW_BATTERY), 1040, 123456)
            rec.received("serial", cable.encode(ev), now + 0.001)
            sent.append(("serial", "rx", ev))
        rec.poll(now)
    if close:
        rec.close()
    return rec, sent


def flash_log_csv(path: Path) -> list[tuple[int, ...]]:
    rows = [(i * 2500, int(Mode.FULL), 100 + i, -50, 9000, 16, -16, 0, 0, 0, -16384, 400, 410, 400, 390, 1000 + i,
             101300, 1160) for i in range(200)]
    data = encode_log(rows, "rice", LOG_VARS)
    write_csv(data, path, decode_to_rows)
    return rows
