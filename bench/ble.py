"""BLE link figures: notification fill and airtime at telemetry load (with and without Compact2, the flight
screen's second frame), and the PC's writes per second with the stick still and moving (change-only joystick sends,
report section 3.9).

Two measurements:

- **simulated** (exact, deterministic): the board's ``WirelessLink`` (STARTED) and the PC's ``LinkSession``
  (``change_only=True``) exchange bytes on a 1 ms simulated clock for ``--seconds``: the board sends a 10 Hz
  heartbeat, Compact telemetry (asked at every 50 Hz telemetry tick: 40 Hz; and 10 Hz for comparison), Compact2
  once per heartbeat (or not, for comparison) and an Ack per command; the pilot presses a key every 2 s; the
  stick is still, or moving (a slow sweep sampled at 100 Hz, as the joystick poller does); the PC's output is cut
  into ATT writes of at most 20 bytes, as ``BleTransport`` does. Per case: the notification fill, notifications
  and payload bytes per second, and their airtime (``airtime_us``).
- **radio** (real time, real stack): the same board stand-in behind the bumble radio (``start_radio`` with the
  phone-side controller on 127.0.0.1) and the terminal's ``Connection(BleTransport(..., hci=...),
  LinkSession(change_only=True))`` through our bleak backend: writes per second still and moving, notification
  fill and size as received, heartbeat round trip.
- **board** (real time): the real ``fcb_sim.board.board.Board`` paced to the wall clock behind the radio, the
  terminal's ``Connection`` in front: the board's own fill and airtime with Compact2 and without it, and the
  stick-to-motor latency over BLE in MANUAL.
- **app** (real time): the same board, but in front of it term's own app (``TermApp``, Textual running
  headless and rendering) with its cable (a loopback pair to the board's UART) and its radio, as ``term --sim``
  wires them: key 8 over the cable, MANUAL over BLE once the app routes there, then the stick-to-motor latency
  from ``app.set_stick`` (what the joystick poller and the wireless screen's pad call) to the board's motors.

``python -m bench.ble [--seconds 20] [--radio-seconds 1.5] [--no-radio]``; one JSON object on the last line.
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import json
import math
import statistics
import time
from dataclasses import dataclass, field

from fcb_sim.board.wireless import NOTIFY_PAYLOAD, WirelessLink
from fcb_sim.hosts.radio import start_radio
from term.core.link import LinkSession
from term.core.protocol import (
    Ack,
    Command,
    Compact,
    Compact2,
    Decoder,
    Heartbeat,
    HeartbeatAck,
    Joystick,
    Mode,
    Op,
    WirelessState,
)

HEARTBEAT_HZ = 10.0
TELEMETRY_HZ = 50.0  # the board's telemetry timer; over BLE it asks compact_due() at each tick
KEY_EVERY_S = 2.0
STICK_HZ = 100.0  # the joystick poller's rate
# Airtime on the LE 1M PHY (1 µs a bit), Bluetooth Core Specification 4.2: a notification of n value bytes is an LL
# data PDU of n + 17 bytes (preamble 1, access address 4, LL header 2, CRC 3: Vol 6 Part B 2.1 and 2.4; L2CAP
# header 4: Vol 3 Part A 3.1; ATT opcode and handle 3: Vol 3 Part F 3.4.7.1), answered by the central's empty PDU
# (10 bytes), with T_IFS = 150 µs before each (Vol 6 Part B 4.1). No encryption (no MIC), no retransmissions.
PDU_OVERHEAD_BYTES = 17
EMPTY_PDU_US = 80
T_IFS_US = 150


def airtime_us(notifications: int, payload_bytes: int) -> int:
    """The radio's busy time for ``notifications`` carrying ``payload_bytes`` in all (see PDU_OVERHEAD_BYTES)."""
    return 8 * (payload_bytes + PDU_OVERHEAD_BYTES * notifications) + (EMPTY_PDU_US + 2 * T_IFS_US) * notifications


def stick_at(t: float, moving: bool) -> Joystick:
    """Neutral, or a slow sweep of roll and pitch (a pilot flying gentle circles), quantised like pygame's."""
    if not moving:
        return Joystick(0, 0, 0, 8000, 0)
    return Joystick(int(9000 * math.sin(1.3 * t)), int(9000 * math.cos(1.3 * t)), 0, 8000, 0)


class BoardStandIn:
    """The BLE half of the board: the WirelessLink handed over and STARTED, a heartbeat and Compact schedule,
    an Ack for every command. Enough to load the link as the board will; not the firmware."""

    def __init__(self, link: WirelessLink, telemetry_hz: float, phase: float = 0.0137) -> None:
        # Compact2 at a telemetry tick as the board sends it (link.compact2_per_heartbeat: 0 turns it off)
        self.link = link
        self.compact_period = 1.0 / telemetry_hz
        self.decoder = Decoder()
        self.next_hb = 0.0
        self.next_compact = phase  # the telemetry and heartbeat timers have unrelated phases, as on the board
        self.hb_counter = 0
        self.hb_sent: dict[int, float] = {}
        self.hb_rtt: list[float] = []
        self.joysticks = 0
        self.commands = 0

    def tick(self, now: float) -> None:
        # At every telemetry tick a Compact if the link wants one (COMPACT_PER_HEARTBEAT per period), as the board does.
        while now >= self.next_compact - 1e-9:
            t = self.next_compact
            if self.link.compact_due():
                self.link.send(Compact(Mode.SAFE, self.link.state, int(500 * math.sin(t)), 0, 0, 1150))
            if self.link.compact2_due():
                self.link.send(Compact2(100, 101, 99, 100, int(100 * math.sin(t)), 100, 0, 0x1B, 0))
            self.next_compact += self.compact_period
        while now >= self.next_hb - 1e-9:
            self.hb_counter = (self.hb_counter + 1) & 0xFFFF
            self.hb_sent[self.hb_counter] = now
            self.link.send(Heartbeat(self.hb_counter, int(now * 1000)))
            self.next_hb += 1.0 / HEARTBEAT_HZ

    def receive(self, data: bytes, now: float) -> None:
        for pkt in self.decoder.feed(self.link.ble_receive(data)):
            kind = type(pkt)
            if kind is HeartbeatAck:
                sent = self.hb_sent.pop(pkt.counter, None)
                if sent is not None:
                    self.hb_rtt.append(now - sent)
            elif kind is Joystick:
                self.joysticks += 1
            elif kind is Command:
                self.commands += 1
                self.link.send(Ack(pkt.cmd_id, pkt.op, 0, pkt.arg))


def started_link(compact2: bool = True) -> WirelessLink:
    link = WirelessLink(compact2_per_heartbeat=1 if compact2 else 0)
    link.connected()
    link.request_start()
    link.ble_receive(b"\x00")  # the phone's first bytes: STARTED
    return link


def att_writes(data: bytes) -> int:
    return -(-len(data) // NOTIFY_PAYLOAD)


@dataclass
class SimResult:
    writes: int = 0
    write_bytes: int = 0
    joysticks: int = 0
    fill_pct: float = 0.0
    notifications: int = 0
    payload_bytes: int = 0
    largest: int = 0
    extra: dict = field(default_factory=dict)


def simulate(seconds: float, telemetry_hz: float, moving: bool, compact2: bool = True) -> SimResult:
    """Board and PC on one 1 ms simulated clock; bytes pass at once (the radio's delay does not change counts)."""
    link = started_link(compact2)
    board = BoardStandIn(link, telemetry_hz)
    session = LinkSession(0.0, change_only=True)
    res = SimResult()
    next_stick = 0.0
    next_key = KEY_EVERY_S / 2
    steps = int(seconds * 1000)
    for step in range(steps + 1):
        now = step / 1000.0
        board.tick(now)
        notes = link.notifications()
        if notes:
            session.receive(b"".join(notes), now)
        if now >= next_stick - 1e-9:
            session.set_joystick(stick_at(now, moving))
            next_stick += 1.0 / STICK_HZ
        if now >= next_key - 1e-9:
            session.send_command(Op.TRIM_LIFT, 1, now)
            next_key += KEY_EVERY_S
        session.poll(now)
        out = session.data_to_send(now)
        if out:
            res.writes += att_writes(out)
            res.write_bytes += len(out)
            board.receive(out, now)
    st = link.stats
    res.joysticks = board.joysticks
    res.fill_pct = st.fill_pct
    res.notifications = st.notifications
    res.payload_bytes = st.payload_bytes
    res.largest = st.largest
    return res


async def _wait_for(condition, conn, what: str, timeout: float = 10.0) -> None:
    """Wait for the stack; a benchmark fails with a reason rather than hanging."""
    deadline = time.monotonic() + timeout
    while not condition():
        if time.monotonic() > deadline or (conn.error is not None) or (conn.crash is not None):
            raise RuntimeError(f"{what} (connection error: {conn.error or conn.crash})")
        await asyncio.sleep(0.001)


async def radio_run(seconds: float) -> dict:
    """The same exchange over the bumble radio in real time, through the terminal's own BLE path."""
    from term.session.connection import Connection
    from term.transports.ble import BleTransport

    link = WirelessLink()
    board = BoardStandIn(link, TELEMETRY_HZ)
    clock = time.monotonic
    radio = await start_radio(
        link, board_id=1, hci="tcp-server:127.0.0.1:0", on_data=lambda d: board.receive(d, clock())
    )
    transport = BleTransport(radio.address, hci=radio.hci.client_spec, timeout=5.0)
    session = LinkSession(clock(), change_only=True)
    conn = Connection(transport, session, clock=clock, on_event=lambda ev: None)
    note_sizes: list[int] = []
    try:
        await conn.start()
        await _wait_for(lambda: link.is_connected, conn, "the radio never saw the connection")
        link.request_start()  # the wireless key, as the cable would have delivered it
        t0 = clock()
        board.next_hb = board.next_compact = t0

        async def board_loop() -> None:
            while True:
                board.tick(clock())
                await asyncio.sleep(0.001)

        task = asyncio.create_task(board_loop())
        await _wait_for(lambda: link.state is WirelessState.STARTED, conn, "the handover never reached STARTED")
        results = {}
        for label, moving in (("still", False), ("moving", True)):
            w0, j0, n0, b0 = transport.writes, board.joysticks, transport.notifications, transport.bytes_read
            start = clock()
            next_key = start + KEY_EVERY_S / 2
            while (now := clock()) - start < seconds:
                conn.set_joystick(stick_at(now - t0, moving))
                if now >= next_key:
                    conn.send_command(Op.TRIM_LIFT, 1)
                    next_key += KEY_EVERY_S
                await asyncio.sleep(1.0 / STICK_HZ)
            span = clock() - start
            notes = transport.notifications - n0
            results[label] = {
                "writes_per_s": round((transport.writes - w0) / span, 1),
                "joysticks_per_s": round((board.joysticks - j0) / span, 1),
                "notifications_per_s": round(notes / span, 1),
                "fill_pct": round(100.0 * (transport.bytes_read - b0) / (notes * NOTIFY_PAYLOAD), 1) if notes else 0,
            }
        task.cancel()
        note_sizes.append(link.stats.largest)
        rtt = board.hb_rtt
        return {
            "still": results["still"],
            "moving": results["moving"],
            "largest_notification": max(note_sizes),
            "heartbeat_rtt_ms_median": round(1000 * statistics.median(rtt), 2) if rtt else None,
            "heartbeat_rtt_ms_max": round(1000 * max(rtt), 2) if rtt else None,
            "seconds_each": seconds,
        }
    finally:
        await conn.stop()
        await radio.close()


async def board_run(seconds: float, steps: int = 20) -> dict:
    """The real board (``fcb_sim.board.board``) paced to the wall clock behind the radio, the terminal's BLE path in
    front: handover over the cable, then the board's own BLE output (fill, rates, airtime) with the stick still,
    with Compact2 and then without it, and the stick-to-motor latency over BLE in MANUAL (lift steps; from
    ``set_joystick`` to the board's motor command changing)."""
    from fcb_sim.board.board import Board, BoardConfig
    from term.session.connection import Connection
    from term.transports.ble import BleTransport

    clock = time.monotonic
    board = Board(BoardConfig(seed=1, link_timeout_s=0.5))
    radio = await start_radio(board.wireless, board=board, hci="tcp-server:127.0.0.1:0")
    cable = LinkSession(clock())
    t0 = clock()
    changes: list[float] = []  # wall-clock times at which the motor command changed

    async def pace() -> None:
        last_ae = board.ae
        while True:
            now = clock()
            board.advance(int((now - t0) * 1e6))
            if board.ae != last_ae:
                changes.append(now)
                last_ae = board.ae
            out = board.uart_transmit()
            cable.receive(out, now) if out else cable.poll(now)
            data = cable.data_to_send(now)
            if data:
                board.uart_receive(data)
            await asyncio.sleep(0.0005)

    task = asyncio.create_task(pace())
    transport = BleTransport(radio.address, hci=radio.hci.client_spec, timeout=5.0)
    conn = Connection(transport, LinkSession(clock(), change_only=True), clock=clock, on_event=lambda ev: None)
    try:
        await conn.start()
        await _wait_for(lambda: board.wireless.is_connected, conn, "the board never saw the connection")
        cable.send_command(Op.WIRELESS, 1, clock())
        await _wait_for(lambda: board.wireless.state is WirelessState.STARTED, conn, "no handover")
        st = board.wireless.stats
        output = {}
        for label, per_heartbeat in (("with_compact2", 1), ("without_compact2", 0)):
            board.wireless.compact2_per_heartbeat = per_heartbeat
            await asyncio.sleep(0.2)  # a heartbeat period or two in the new regime before counting
            n0, b0, w0, c0, d0 = st.notifications, st.payload_bytes, transport.writes, st.compacts, st.compact2s
            await asyncio.sleep(seconds)
            output[label] = _link_figures(st.notifications - n0, st.payload_bytes - b0, seconds) | {
                "compact_per_s": round((st.compacts - c0) / seconds, 1),
                "compact2_per_s": round((st.compact2s - d0) / seconds, 1),
                "writes_per_s_still": round((transport.writes - w0) / seconds, 1),
            }
        board.wireless.compact2_per_heartbeat = 1
        conn.send_command(Op.MODE, Mode.MANUAL)
        await _wait_for(lambda: board.mode is Mode.MANUAL, conn, "MANUAL refused")
        latencies = []
        for i in range(steps):
            await asyncio.sleep(0.05 + 0.013 * (i % 5))  # an unrelated phase to the board's control tick
            changes.clear()
            sent = clock()
            conn.set_joystick(Joystick(0, 0, 0, 9000 + 1500 * (i % 2), 0))
            await _wait_for(lambda: bool(changes), conn, "the motors never followed the stick", 2.0)
            latencies.append(changes[0] - sent)
        latencies.sort()
        return {
            **output,
            "largest_notification": st.largest,
            "stick_to_motor_ms_median": round(1000 * statistics.median(latencies), 2),
            "stick_to_motor_ms_p90": round(1000 * latencies[int(0.9 * (len(latencies) - 1))], 2),
            "stick_to_motor_ms_max": round(1000 * latencies[-1], 2),
            "steps": steps,
        }
    finally:
        task.cancel()
        with contextlib.suppress(asyncio.CancelledError):
            await task
        await conn.stop()
        await radio.close()


async def app_run(steps: int = 20) -> dict:
    """Stick-to-motor latency over BLE through term's own app: ``TermApp`` with a cable and a radio to the real
    board (paced to the wall clock in this process), handed over with key 8, flown in MANUAL over BLE."""
    from fcb_sim.board.board import Board, BoardConfig
    from term.transports.ble import BleTransport
    from term.transports.loopback import loopback_pair
    from term.ui.app import TermApp

    clock = time.monotonic
    board = Board(BoardConfig(seed=1, link_timeout_s=0.5))
    radio = await start_radio(board.wireless, board=board, hci="tcp-server:127.0.0.1:0")
    pair = loopback_pair()
    await pair.b.open()
    t0 = clock()
    changes: list[float] = []

    async def pace() -> None:  # the board's UART on the cable's far end
        last_ae = board.ae
        while True:
            board.advance(int((clock() - t0) * 1e6))
            if board.ae != last_ae:
                changes.append(clock())
                last_ae = board.ae
            out = board.uart_transmit()
            if out:
                await pair.b.write(out)
            await asyncio.sleep(0.0005)

    async def uart_rx() -> None:
        while True:
            data = await pair.b.read()
            board.advance(int((clock() - t0) * 1e6))
            board.uart_receive(data)

    tasks = [asyncio.create_task(pace()), asyncio.create_task(uart_rx())]
    app = TermApp(pair.a, joystick=False, radio=BleTransport(radio.address, hci=radio.hci.client_spec, timeout=5.0))
    try:
        async with app.run_test(size=(120, 44)) as pilot:
            m = app.model

            async def until(cond, what: str, timeout: float = 10.0) -> None:  # noqa: ANN001
                try:
                    async with asyncio.timeout(timeout):
                        while not cond():
                            await pilot.pause(0.005)
                except TimeoutError:
                    raise SystemExit(f"bench.ble: {what}") from None

            await until(lambda: m.mode == Mode.SAFE and m.radio_up, "the app never connected both links")
            app.send(Op.WIRELESS, 1)
            await until(lambda: m.over_ble, "no handover")
            app.send(Op.MODE, Mode.MANUAL)
            await until(lambda: board.mode is Mode.MANUAL, "MANUAL refused")
            latencies = []
            for i in range(steps):
                await asyncio.sleep(0.05 + 0.013 * (i % 5))
                changes.clear()
                sent = clock()
                app.set_stick(Joystick(0, 0, 0, 9000 + 1500 * (i % 2), 0))
                await until(lambda: bool(changes), "the motors never followed the stick", 2.0)
                latencies.append(changes[0] - sent)
            latencies.sort()
            over_ble = app.control_connection() is app.radio_connection
    finally:
        for t in tasks:
            t.cancel()
        for t in tasks:
            with contextlib.suppress(asyncio.CancelledError, Exception):  # the app closed the cable under them
                await t
        await radio.close()
    return {
        "stick_to_motor_ms_median": round(1000 * statistics.median(latencies), 2),
        "stick_to_motor_ms_p90": round(1000 * latencies[int(0.9 * (len(latencies) - 1))], 2),
        "stick_to_motor_ms_max": round(1000 * latencies[-1], 2),
        "steps": steps,
        "control_over_ble": over_ble,
    }


def _link_figures(notifications: int, payload_bytes: int, seconds: float) -> dict:
    """Fill, rates and airtime of the board's notifications over ``seconds``."""
    return {
        "fill_pct": round(100.0 * payload_bytes / (notifications * NOTIFY_PAYLOAD), 1) if notifications else 0.0,
        "notifications_per_s": round(notifications / seconds, 1),
        "payload_bytes_per_s": round(payload_bytes / seconds, 1),
        "airtime_ms_per_s": round(airtime_us(notifications, payload_bytes) / 1000 / seconds, 2),
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m bench.ble", description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=20.0, help="simulated seconds per case (default 20)")
    parser.add_argument("--radio-seconds", type=float, default=1.5, help="real seconds per radio case")
    parser.add_argument("--no-radio", action="store_true", help="skip the real-time run over the bumble radio")
    args = parser.parse_args(argv)

    out: dict = {"bench": "ble", "notification_payload": NOTIFY_PAYLOAD, "seconds": args.seconds}
    fill = {}
    cases = (("with_compact2", TELEMETRY_HZ, True), ("without_compact2", TELEMETRY_HZ, False),
             ("compact_1_per_heartbeat", HEARTBEAT_HZ, False))
    for label, hz, compact2 in cases:
        r = simulate(args.seconds, hz, moving=False, compact2=compact2)
        fill[label] = _link_figures(r.notifications, r.payload_bytes, args.seconds) | {"largest": r.largest}
        f = fill[label]
        print(f"notification fill, {label.replace('_', ' ')} + heartbeat 10 Hz + acks: {f['fill_pct']:5.1f} % "
              f"({f['notifications_per_s']:.1f} notifications/s, {f['payload_bytes_per_s']:.0f} B/s, airtime "
              f"{f['airtime_ms_per_s']:.1f} ms/s, largest {r.largest} B)")
    out["fill"] = fill
    out["fill_goal_met"] = fill["with_compact2"]["fill_pct"] >= 90.0
    writes = {}
    for label, moving in (("still", False), ("moving", True)):
        r = simulate(args.seconds, TELEMETRY_HZ, moving)
        writes[label] = {
            "writes_per_s": round(r.writes / args.seconds, 1),
            "joysticks_per_s": round(r.joysticks / args.seconds, 1),
            "bytes_per_s": round(r.write_bytes / args.seconds, 1),
        }
        print(f"PC writes, stick {label:6s}: {r.writes / args.seconds:6.1f} writes/s "
              f"({r.joysticks / args.seconds:.1f} joystick frames/s, {r.write_bytes / args.seconds:.0f} B/s)")
    out["writes_simulated"] = writes
    if not args.no_radio:
        radio = asyncio.run(radio_run(args.radio_seconds))
        out["radio"] = radio
        for label in ("still", "moving"):
            r = radio[label]
            print(f"over the bumble radio, stick {label:6s}: {r['writes_per_s']:6.1f} writes/s, "
                  f"{r['notifications_per_s']:.1f} notifications/s at {r['fill_pct']} % fill")
        print(f"heartbeat round trip over the radio: median {radio['heartbeat_rtt_ms_median']} ms, "
              f"largest notification {radio['largest_notification']} B")
        board = asyncio.run(board_run(args.radio_seconds))
        out["board"] = board
        for label in ("with_compact2", "without_compact2"):
            b = board[label]
            print(f"the real board over the radio, {label.replace('_', ' ')}: Compact {b['compact_per_s']}/s, "
                  f"Compact2 {b['compact2_per_s']}/s, fill {b['fill_pct']} % ({b['notifications_per_s']} "
                  f"notifications/s, {b['payload_bytes_per_s']:.0f} B/s, airtime {b['airtime_ms_per_s']} ms/s), "
                  f"PC writes {b['writes_per_s_still']}/s still")
        print(f"stick-to-motor latency over BLE: median {board['stick_to_motor_ms_median']} ms, "
              f"p90 {board['stick_to_motor_ms_p90']} ms, max {board['stick_to_motor_ms_max']} ms "
              f"({board['steps']} lift steps)")
        app = asyncio.run(app_run())
        out["app"] = app
        print(f"stick-to-motor latency over BLE through term's app (TermApp, cable + radio, handed over): median "
              f"{app['stick_to_motor_ms_median']} ms, p90 {app['stick_to_motor_ms_p90']} ms, "
              f"max {app['stick_to_motor_ms_max']} ms ({app['steps']} lift steps)")
    print(json.dumps(out))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
