"""The board through its bytes: NAK reasons, telemetry, a flight, the link timeout, the log download with loss,
floods, the BLE seam, the profile; and a hypothesis state machine over random commands, sticks and silences."""

from __future__ import annotations

import random
from typing import Any

from hypothesis import HealthCheck, event, settings
from hypothesis import strategies as st
from hypothesis.stateful import RuleBasedStateMachine, invariant, rule

from fcb_sim.board.board import Board, BoardConfig
from fcb_sim.board.modes import FLIGHT_MODES, LIFT_ZERO, STICK_NEUTRAL, ModeChange
from fcb_sim.board.scheduler import TASKS
from fcb_sim.board.timing import (
    COSTS,
    PARSE_US_BASE,
    PARSE_US_PER_BYTE,
    SD_ADV_CHUNKS,
    SENSOR_PERIOD_US,
    UART_ISR_US,
    UART_US_PER_BYTE,
    Interference,
    rtc_ticks,
    rtc_us,
)
from term.core.logfile import LogDownload, decode_to_rows
from term.core.logformat import decode_log
from term.core.protocol import (
    Ack,
    Attitude,
    Command,
    Decoder,
    Encoder,
    Event,
    EventCode,
    Flag,
    Gains,
    Heartbeat,
    HeartbeatAck,
    Height,
    Hello,
    Joystick,
    LogChunk,
    LogState,
    LogStatus,
    Mode,
    Motion,
    Nak,
    Op,
    Param,
    Profile,
    Status,
    WirelessState,
    param_arg,
    scaled,
)
from tests.support.board_rig import HOVER_LIFT, Pc


def board_and_pc(**cfg: Any) -> tuple[Board, Pc]:
    b = Board(BoardConfig(**cfg))
    return b, Pc(b)


def calibrate(pc: Pc) -> None:
    assert pc.command(Op.MODE, Mode.CALIBRATION).status == Nak.OK
    pc.run(1.2)
    assert pc.board.mode == Mode.SAFE and pc.board.modes.calibrated


def test_nak_reasons() -> None:
    b, pc = board_and_pc()
    assert pc.command(Op.MODE, Mode.FULL) == Ack(1, Op.MODE, Nak.NOT_CALIBRATED, Mode.SAFE)
    pc.js = Joystick(0, 0, 0, 5000, 0)
    assert pc.command(Op.MODE, Mode.MANUAL).status == Nak.LIFT_NOT_ZERO
    pc.js = Joystick(0, 9000, 0, 0, 0)
    assert pc.command(Op.MODE, Mode.CALIBRATION).status == Nak.STICKS_NOT_NEUTRAL
    pc.js = Joystick(0, 0, 0, 0, 0)
    assert pc.command(99).status == Nak.UNKNOWN_COMMAND
    assert pc.command(Op.MODE, 42).status == Nak.BAD_ARGUMENT
    assert pc.command(Op.SET_PARAM, param_arg(77, 1)).status == Nak.UNKNOWN_PARAM
    assert pc.command(Op.LOG_DOWNLOAD, 0).status == Nak.LOG_EMPTY
    assert pc.command(Op.WIRELESS, 1).status == Nak.NO_BLE_CONNECTION
    assert pc.command(Op.MODE, Mode.WIRELESS).status == Nak.NO_BLE_CONNECTION
    assert pc.command(Op.MODE, Mode.MANUAL).status == Nak.OK
    assert pc.command(Op.MODE, Mode.YAW).status == Nak.INVALID_TRANSITION
    assert pc.command(Op.LOG_DOWNLOAD, 0).status == Nak.NOT_IN_SAFE
    assert pc.command(Op.LOG_RESET).status == Nak.NOT_IN_SAFE
    assert pc.command(Op.WIRELESS, 1).status == Nak.NOT_IN_SAFE
    assert pc.command(Op.MODE, Mode.PANIC) == Ack(pc.cmd_id, Op.MODE, Nak.OK, Mode.PANIC)
    assert pc.command(Op.MODE, Mode.SAFE).status == Nak.PANIC_ACTIVE
    refused = [e for e in pc.of(Event) if e.code == EventCode.REFUSED]
    assert (refused[0].arg >> 8, refused[0].arg & 0xFF) == (Nak.NOT_CALIBRATED, Mode.FULL)


def test_a_roll_trim_is_not_neutral_sticks_for_leaving_safe() -> None:
    """Issue 11.3: 32 presses of roll trim (+8192, the limit) with the joystick centred: MANUAL is refused."""
    b, pc = board_and_pc()
    for _ in range(32):
        pc.command(Op.TRIM_ROLL, 1)
    assert b.modes.trims.roll == 8192
    assert pc.command(Op.MODE, Mode.MANUAL).status == Nak.STICKS_NOT_NEUTRAL
    assert b.mode == Mode.SAFE and b.ae == (0, 0, 0, 0)
    assert pc.command(Op.TRIM_ROLL, -32).value == 0
    assert pc.command(Op.MODE, Mode.MANUAL).status == Nak.OK


def test_a_retried_command_is_answered_again_but_done_once() -> None:
    b, pc = board_and_pc()
    pc.send(Command(7, Op.TRIM_ROLL, 1))
    pc.run(0.02)
    pc.send(Command(7, Op.TRIM_ROLL, 1))  # the Ack was lost: the link retries with the same id
    pc.run(0.02)
    acks = [p for p in pc.of(Ack) if p.cmd_id == 7]
    assert len(acks) == 2 and acks[0] == acks[1] and b.modes.trims.roll == acks[0].value == 256
    pc.send(Command(8, Op.TRIM_ROLL, 1))
    pc.run(0.02)
    assert b.modes.trims.roll == 512


def test_a_new_terminal_is_not_taken_for_a_retry() -> None:
    b, pc = board_and_pc()
    pc.send(Command(1, Op.TRIM_ROLL, 1))
    pc.run(0.02)
    pc.send(Hello(1, 0, 0, 1, 0))  # the terminal restarted: its cmd_ids begin again at 1
    pc.send(Command(1, Op.TRIM_ROLL, 1))
    pc.run(0.02)
    assert b.modes.trims.roll == 512


def test_heartbeats_carry_the_measured_round_trip() -> None:
    b, pc = board_and_pc()
    pc.run(0.55)  # answered within the same 10 ms step: a round trip under 10 ms
    rtts = [hb.rtt for hb in pc.of(Heartbeat)]
    assert rtts[0] == 0  # nothing measured before the first answer
    assert all(0 < r <= 100 for r in rtts[1:]) and len(rtts) >= 5
    before = len(pc.packets)
    pc.read(answer=False)  # stop answering: the next heartbeat has no fresh measurement
    b.advance(b.now + 250_000)
    pc.read(answer=False)
    late = [hb.rtt for hb in pc.packets[before:] if type(hb) is Heartbeat]
    assert late and late[-1] == 0


def test_gains_and_hello() -> None:
    b, pc = board_and_pc()
    p1 = b.core.gains.p1
    ack = pc.command(Op.GAIN_P1, 2)
    assert ack.status == Nak.OK and abs(ack.value / 1000 - b.core.gains.p1) < 1e-9 and b.core.gains.p1 > p1
    pc.send(Hello(1, 0, 0, 1, 0))
    pc.run(0.05)
    hellos = pc.of(Hello)
    assert len(hellos) == 2 and hellos[-1].role == 1  # one at boot, one answering ours


def test_telemetry_at_rest() -> None:
    b, pc = board_and_pc()
    pc.run(2.0)
    att, mot, hgt, sts, gns = (pc.of(k) for k in (Attitude, Motion, Height, Status, Gains))
    assert 90 <= len(att) <= 110 and 90 <= len(mot) <= 110  # 50 Hz
    assert 35 <= len(hgt) <= 45 and 8 <= len(sts) <= 12 and 8 <= len(gns) <= 12
    assert 18 <= len(pc.of(Heartbeat)) <= 21  # 10 Hz
    a, m, h, s = att[-1], mot[-1], hgt[-1], sts[-1]
    assert a.mode == Mode.SAFE and abs(a.phi) < 300 and abs(a.theta) < 300
    assert -17500 < m.saz < -15300 and (m.ae1, m.ae2, m.ae3, m.ae4) == (0, 0, 0, 0)
    assert abs(h.pressure - 101325) < 300 and 1000 < h.battery < 1300 and h.temperature == 2500
    assert not s.flags & Flag.ARMED and not s.flags & Flag.CALIBRATED and 0 < s.cpu_load < 100
    assert gns[-1].p2 == b.core.gains.p2


def test_fly_full_through_bytes_then_land() -> None:
    b, pc = board_and_pc()
    calibrate(pc)
    assert pc.command(Op.MODE, Mode.FULL).status == Nak.OK
    assert pc.of(Status)[-1].flags & Flag.CALIBRATED
    pc.js = Joystick(0, 0, 0, int(HOVER_LIFT * 1.1), 0)
    pc.run(1.5)
    assert b.world.truth.h > 0.5 and pc.of(Status)[-1].flags & Flag.ARMED
    assert max(scaled(p, "height") for p in pc.of(Height)) > 0.3
    assert abs(b.world.truth.phi) < 0.15 and abs(b.world.truth.theta) < 0.15
    pc.js = Joystick(0, 0, 0, int(HOVER_LIFT * 0.8), 0)
    pc.run(4.0)
    assert b.world.truth.on_ground
    pc.js = Joystick(0, 0, 0, 0, 0)
    assert pc.command(Op.MODE, Mode.SAFE).status == Nak.OK
    pc.run(0.05)
    assert b.ae == (0, 0, 0, 0) and b.world.cmd == [0, 0, 0, 0]


def test_link_silence_while_flying_panics_then_safe() -> None:
    # the report's one stage (tests/board/test_failsafe.py)
    b, pc = board_and_pc(link_timeout_s=0.3, link_failsafe_s=0.0)
    calibrate(pc)
    pc.command(Op.MODE, Mode.FULL)
    pc.js = Joystick(0, 0, 0, HOVER_LIFT, 0)
    pc.run(1.0)
    last = b.last_frame_us
    b.advance(b.now + 500_000)  # the PC goes silent
    panic = [c for c in b.modes.changes if c.new == Mode.PANIC][-1]
    assert panic.reason == "panic:link"
    assert 0.3 < panic.now - last / 1e6 <= 0.3 + 0.1 + 0.01  # within the timeout plus one heartbeat
    b.advance(b.now + 8_000_000)  # PANIC's descent to the floor, the ground sensed, the motors ramped off
    assert b.mode == Mode.SAFE and b.ae == (0, 0, 0, 0)
    pc.read()
    assert EventCode.LINK_TIMEOUT in [e.code for e in pc.of(Event)]


def test_joystick_fire_is_panic() -> None:
    b, pc = board_and_pc()
    pc.command(Op.MODE, Mode.MANUAL)
    pc.js = Joystick(0, 0, 0, 6000, 0)
    pc.run(0.2)
    pc.js = Joystick(0, 0, 0, 6000, 1)
    pc.run(0.05)
    assert b.mode == Mode.PANIC


def test_log_flight_and_download_with_loss() -> None:
    b, pc = board_and_pc()
    calibrate(pc)
    assert pc.command(Op.LOG_START).status == Nak.OK
    pc.command(Op.MODE, Mode.FULL)
    pc.js = Joystick(0, 0, 0, HOVER_LIFT, 0)
    pc.run(1.0)
    assert pc.command(Op.LOG_DOWNLOAD, 0).status == Nak.NOT_IN_SAFE
    pc.js = Joystick(0, 0, 0, 0, 0)
    pc.run(0.3)
    pc.command(Op.MODE, Mode.PANIC)
    pc.run(4.0)
    assert pc.command(Op.LOG_DOWNLOAD, 0).status == Nak.LOG_BUSY
    pc.command(Op.LOG_STOP)
    assert pc.command(Op.LOG_STATUS).status == Nak.OK
    status = pc.of(LogStatus)[-1]
    assert status.state == LogState.IDLE and status.used == b.log.used and status.records == b.log.records
    download = LogDownload(started=0.0)
    download.feed(status, 0.0)
    pc.drop_chunks = 0.3
    first: int | None = 0
    for _ in range(10):
        ack = pc.command(Op.LOG_DOWNLOAD, first)
        assert ack.status == Nak.OK and ack.value == download.total_chunks
        pc.run(3.0)
        for c in pc.of(LogChunk):
            download.feed(c, 0.0)
        first = download.missing()
        if first is None:
            break
    assert first is None and EventCode.LOG_DONE in [e.code for e in pc.of(Event)]
    assert download.verify() is None
    seg = decode_log(download.data())[0]
    assert len(seg.rows) == status.records > 400  # the DMP path logs at 200 Hz, for about 5 s here
    modes = {r[seg.names.index("mode")] for r in seg.rows}
    assert {Mode.FULL, Mode.PANIC, Mode.SAFE} <= modes
    t = [r[0] for r in seg.rows]
    assert all(b > a for a, b in zip(t, t[1:], strict=False))
    header, rows = decode_to_rows(download.data())
    assert header == ["segment", *seg.names] and len(rows) == len(seg.rows)


def test_floods_garbage_and_half_frames_do_not_stop_the_board() -> None:
    b, pc = board_and_pc()
    rng = random.Random(3)
    for _ in range(20):
        b.uart_receive(bytes(rng.randrange(256) for _ in range(5000)))
        b.uart_receive(pc.enc.encode(Command(1, Op.MODE, 2))[:7])  # half a frame
        b.advance(b.now + 1000)
    assert b.rx_overflow > 50_000
    pc.run(0.2)
    assert pc.command(Op.TRIM_YAW, 1).status == Nak.OK  # still answering
    assert EventCode.OVERFLOW in [e.code for e in pc.of(Event)]
    assert len(pc.of(Heartbeat)) >= 2


def test_ble_handover_seam() -> None:
    b, pc = board_and_pc()
    phone_enc, phone_dec = Encoder(), Decoder()
    b.ble_connected()
    ack = pc.command(Op.WIRELESS, 1)
    assert ack.status == Nak.OK and ack.value == WirelessState.STARTING
    pc.run(0.25)
    heard = phone_dec.feed(b"".join(b.wireless.notifications()))
    assert any(type(p) is Heartbeat for p in heard)  # STARTING: heartbeats over BLE too
    b.ble_receive(phone_enc.encode(HeartbeatAck(1, 0)))  # the phone answers: STARTED
    assert b.wireless.state is WirelessState.STARTED
    b.ble_receive(phone_enc.encode(Command(9, Op.MODE, Mode.MANUAL)))
    b.advance(b.now + 50_000)
    heard = phone_dec.feed(b"".join(b.wireless.notifications()))
    assert Ack(9, Op.MODE, Nak.OK, Mode.MANUAL) in heard and b.mode == Mode.MANUAL
    pc.read()
    assert not [p for p in pc.of(Ack) if p.cmd_id == 9]  # the reply went where the command came from
    b.ble_disconnected()  # lost while flown over BLE
    assert b.mode == Mode.PANIC and b.wireless.state is WirelessState.DISCONNECTED


def test_profile_packets_and_figures() -> None:
    b, pc = board_and_pc()
    pc.run(1.0)
    assert pc.command(Op.PROFILE).value == len(TASKS)
    pc.run(0.05)
    prof = pc.of(Profile)
    assert [p.task for p in prof] == list(range(len(TASKS)))
    sensor = prof[TASKS.index("sensor")]
    assert 1800 < sensor.mean_us < 2200 and 4900 < sensor.period_us < 5100  # DMP in SAFE, report: 1983/4949


def test_the_cost_table_holds_figure_14() -> None:
    # Every fitted duration has the report's mean and sigma, and its p99 and p99.9 within 0.15 sigma or 10 %
    # (telemetry: nine samples, a plain log-normal on mean and sigma only). The right tails are real: a normal
    # with that sigma falls short of them.
    for name, c in COSTS.items():
        mean, sd, p99, p999 = c.figure
        assert abs(c.mean() - mean) <= 0.02 * mean and abs(c.sd() - sd) <= 0.05 * sd, name
        if name != "telemetry":
            for q, want in ((0.99, p99), (0.999, p999)):
                assert abs(c.quantile(q) - want) <= max(0.15 * sd, 0.1 * want), (name, q)
    sensor = COSTS["sensor_dmp"]
    assert sensor.quantile(0.99) > sensor.mean() + 4 * sensor.sd()  # a normal would put it at + 2.3 sigma


def test_timers_tick_on_the_rtc_and_slide_past_each_other() -> None:
    # Whole 30.5 µs ticks: 2.5 ms is 2502.4 µs, and the 50 Hz telemetry timer (655 ticks) is not a multiple of the
    # sensor's (82 or 164): its tick meets the sensor period at every phase in turn, not at one phase for ever.
    assert rtc_ticks(2500) == 82 and abs(rtc_us(82 * 1000) / 1000 - 2502.4) < 0.1
    b, pc = board_and_pc(seed=3)
    starts: dict[str, list[int]] = {"sensor": [], "telemetry": []}
    b.on_task = lambda name, start, dur: starts[name].append(start) if name in starts else None
    pc.run(4.0)
    sensor = starts["sensor"]
    period = SENSOR_PERIOD_US["dmp"]
    phases = set()
    for t in starts["telemetry"]:
        before = [s for s in sensor if s <= t]
        if before:
            phases.add(min(9, (t - before[-1]) * 10 // period))
    assert len(phases) >= 6  # locked timers would give one or two (the DMP read fills the first 2 ms)


def test_an_interrupt_in_progress_holds_back_an_idle_start() -> None:
    irq = Interference(random.Random(1), first_adv_us=10_000)
    # the SoftDevice's post-processing (200 µs) and its priority-2 work (270) back to back: 470 µs of CPU
    post = 10_000 + SD_ADV_CHUNKS[4][0]
    assert irq.free_at(post + 50) == post + 470
    assert irq.free_at(post + 2000) == post + 2000  # nothing then
    irq.rx(20_000, 3)  # three bytes arriving, an interrupt each
    assert irq.free_at(20_000 + 90) == 20_000 + 87 + UART_ISR_US
    assert irq.free_at(20_000 + 87 + UART_ISR_US + 1) == 20_000 + 87 + UART_ISR_US + 1


# --- properties over random sequences ----------------------------------------------------------------------

AXIS = st.sampled_from([0, 0, 0, 400, -900, 2500, -20000, 32767])
LIFT = st.sampled_from([0, 0, 0, 300, 3000, HOVER_LIFT, 30000])
PANIC_MAX_S = 30.0  # the highest a random flight gets, at PANIC's 1 m/s, plus sensing the ground and the ramp


# CALIBRATION as short as the board allows with its minimum of samples (Param.CALIBRATION_MS, as a pilot sets it):
# the properties are the mode machine's, and a second of averaging per calibration was half the test's time.
PROPERTY_CALIBRATION_MS = 300


class BoardProperties(RuleBasedStateMachine):
    def __init__(self) -> None:
        super().__init__()
        self.board, self.pc = board_and_pc(seed=4, link_timeout_s=0.5)
        assert self.pc.command(Op.SET_PARAM, param_arg(Param.CALIBRATION_MS, PROPERTY_CALIBRATION_MS)).status == Nak.OK
        self.leaves: list[tuple[ModeChange, Joystick, int]] = []
        self.board.modes.listeners.append(self._on_change)

    def _on_change(self, ch: ModeChange) -> None:
        if ch.old == Mode.SAFE and ch.new != Mode.SAFE:
            self.leaves.append((ch, self.board.modes.sticks(), self.board.modes.lift))

    @rule(roll=AXIS, pitch=AXIS, yaw=AXIS, lift=LIFT)
    def sticks(self, roll: int, pitch: int, yaw: int, lift: int) -> None:
        self.pc.js = Joystick(roll, pitch, yaw, lift, 0)
        self.pc.run(0.02)

    @rule(mode=st.integers(0, 9))
    def press_mode(self, mode: int) -> None:
        self.pc.send(self.pc.js)
        self.pc.send(Command(1, Op.MODE, mode))
        self.pc.run(0.03)

    @rule(op=st.sampled_from([Op.TRIM_LIFT, Op.TRIM_ROLL, Op.TRIM_PITCH, Op.TRIM_YAW]), steps=st.integers(-3, 3))
    def trim(self, op: Op, steps: int) -> None:
        self.pc.send(Command(2, op, steps))
        self.pc.run(0.02)

    @rule()
    def calibrate(self) -> None:
        self.pc.js = Joystick(0, 0, 0, 0, 0)
        self.pc.send(Command(3, Op.MODE, Mode.CALIBRATION))
        self.pc.run(PROPERTY_CALIBRATION_MS / 1000 + 0.1)

    @rule(mode=st.sampled_from([Mode.MANUAL, Mode.YAW, Mode.FULL, Mode.RAW]), lift=LIFT, cal=st.booleans())
    def take_off(self, mode: Mode, lift: int, cal: bool) -> None:
        """A pilot's way up (random sequences alone seldom line up neutral sticks, zero lift and a key)."""
        if cal and not self.board.modes.calibrated:
            self.calibrate()
        self.pc.js = Joystick(0, 0, 0, 0, 0)
        self.pc.send(self.pc.js)
        self.pc.send(Command(5, Op.MODE, mode))
        self.pc.run(0.02)
        self.pc.js = Joystick(0, 0, 0, lift, 0)
        self.pc.run(0.3)

    @rule(seconds=st.floats(0.01, 0.8))
    def fly(self, seconds: float) -> None:
        self.pc.run(seconds)
        event(f"flew in {self.board.mode.name}")

    @rule(fire=st.booleans())
    def panic(self, fire: bool) -> None:
        b = self.board
        before = b.mode
        if fire:
            self.pc.send(self.pc.js._replace(buttons=1))
        else:
            self.pc.send(Command(4, Op.MODE, Mode.PANIC))
        self.pc.run(0.01, joystick=False)
        if before in FLIGHT_MODES or before == Mode.CALIBRATION:
            assert b.mode in (Mode.PANIC, Mode.SAFE)
            event(f"panic from {before.name}")
        else:
            assert b.mode in (Mode.SAFE, Mode.PANIC)
        for _ in range(int(PANIC_MAX_S / 0.5)):  # the PC keeps talking: PANIC comes down and ends by itself
            if b.mode == Mode.SAFE:
                break
            self.pc.run(0.5)
        self.pc.run(0.05)
        assert b.mode == Mode.SAFE and b.ae == (0, 0, 0, 0) and b.world.cmd == [0, 0, 0, 0]

    @rule(seconds=st.floats(0.0, 2.0))
    def silence(self, seconds: float) -> None:
        b = self.board
        b.advance(b.now + 2000)  # bytes already queued (heartbeat answers) are parsed: they are not silence
        flying = b.modes.flying
        n_changes = len(b.modes.changes)
        last = b.last_frame_us
        b.advance(b.now + int(seconds * 1e6))
        cfg = b.modes.config
        timeout = cfg.link_timeout_s + cfg.link_failsafe_s  # the failsafe's stage 2 (docs/modes.md)
        if flying and last is not None and (b.now - last) / 1e6 > cfg.link_timeout_s + 0.1 + 0.01:
            assert b.modes.link_hold or not b.modes.flying  # stage 1 at least
        if flying and last is not None and (b.now - last) / 1e6 > timeout + 0.1 + 0.01:
            assert not b.modes.flying
            # PANIC by the deadline; or the flight ended before it by itself: a crash (the lift was cut, the craft
            # fell), motors off and SAFE, which needs no PANIC (found by this property: MANUAL to SAFE, "crash")
            ends = [c for c in b.modes.changes[n_changes:] if c.new == Mode.PANIC or c.reason == "crash"]
            assert ends and ends[0].now - last / 1e6 <= timeout + 0.1 + 0.01, ends
            event("link silence while flying")
        self.pc.read(answer=False)  # the PC was away: it does not answer heartbeats it never saw

    @invariant()
    def safe_is_never_left_off_neutral(self) -> None:
        for change, (roll, pitch, yaw, _), lift in self.leaves:  # joystick plus trims, as the motors get them
            if change.new == Mode.PANIC:
                continue
            assert abs(roll) <= STICK_NEUTRAL and abs(pitch) <= STICK_NEUTRAL
            assert abs(yaw) <= STICK_NEUTRAL and lift <= LIFT_ZERO, change

    @invariant()
    def motors_zero_when_off(self) -> None:
        b = self.board
        if b.mode in (Mode.SAFE, Mode.CALIBRATION) and b.prof.stats["control"].n:
            assert b.ae == (0, 0, 0, 0) and b.world.cmd == [0, 0, 0, 0]


BoardProperties.TestCase.settings = settings(
    max_examples=25, stateful_step_count=20, deadline=None, suppress_health_check=[HealthCheck.too_slow])
TestBoardProperties = BoardProperties.TestCase


def test_the_terminals_link_session_flies_the_board() -> None:
    """Both sides sans-IO on one clock: term.core.link.LinkSession (the PC) and the Board, with a UART between."""
    from term.core.link import CommandAcked, CommandFailed, LinkLost, LinkSession, VersionMismatch

    b = Board(BoardConfig(seed=6))
    s = LinkSession(0.0)
    b.uart_receive(s.hello())
    events: list[Any] = []

    def run(seconds: float) -> None:
        end = b.now + int(seconds * 1e6)
        while b.now < end:
            t = b.now / 1e6
            b.uart_receive(s.data_to_send(t))
            b.advance(b.now + 2000)
            t = b.now / 1e6
            events.extend(s.receive(b.uart_transmit(), t))
            events.extend(s.poll(t))

    def acked(cmd_id: int) -> Any:
        run(0.3)
        found = [e for e in events if isinstance(e, CommandAcked | CommandFailed) and e.cmd_id == cmd_id]
        assert found, f"no answer to command {cmd_id}"
        return found[-1]

    run(0.3)
    assert s.board_hello is not None and s.board_hello.role == 1
    failed = acked(s.send_command(Op.MODE, Mode.FULL, b.now / 1e6))
    assert isinstance(failed, CommandFailed) and failed.nak == Nak.NOT_CALIBRATED
    assert isinstance(acked(s.send_command(Op.MODE, Mode.CALIBRATION, b.now / 1e6)), CommandAcked)
    run(1.2)
    assert isinstance(acked(s.send_command(Op.MODE, Mode.FULL, b.now / 1e6)), CommandAcked)
    s.set_joystick(Joystick(0, 0, 0, int(HOVER_LIFT * 1.1), 0))
    run(1.5)
    assert b.mode == Mode.FULL and b.world.truth.h > 0.4
    assert not [e for e in events if isinstance(e, LinkLost | VersionMismatch)]
    assert s.stats.rtt_last_ms is not None and s.stats.rtt_last_ms < 20


def test_a_flat_battery_sags_under_load_and_panics() -> None:
    from fcb_sim.hosts.serve import make_board

    b = make_board(seed=3, scenario="low-battery")
    pc = Pc(b)
    pc.run(0.3)
    assert b.battery >= 1050  # at rest it still reads above 10.5 V: take-off is allowed
    assert pc.command(Op.MODE, Mode.MANUAL).status == Nak.OK
    pc.js = Joystick(0, 0, 0, HOVER_LIFT, 0)
    pc.run(2.0)
    assert [c.reason for c in b.modes.changes if c.new == Mode.PANIC] == ["panic:battery"]
    assert EventCode.LOW_BATTERY in [e.code for e in pc.of(Event)]
    pc.js = Joystick(0, 0, 0, 0, 0)
    pc.run(4.0)
    assert b.mode == Mode.SAFE and b.battery >= 1050  # at rest again it reads fine ...
    assert pc.of(Status)[-1].flags & Flag.LOW_BATTERY
    assert pc.command(Op.MODE, Mode.MANUAL).status == Nak.BATTERY_LOW  # ... but it is still flat


# --- sticks to motors: a changed stick moves the motors in the parse task that decodes it -------------------------

FRAME_WIRE_US = 15 * UART_US_PER_BYTE  # a Joystick frame on the UART at BAUD_RATE


class Runs:
    """Every task run the board reports, with the motor commands and the time they took effect after it."""

    def __init__(self, board: Board) -> None:
        self.board = board
        self.runs: list[tuple[str, int, int, tuple[int, ...], int, int]] = []
        board.on_task = self

    def __call__(self, name: str, start: int, dur: int) -> None:
        b = self.board
        self.runs.append((name, start, dur, b.ae, b.motors_at_us, b.prof.reactions.n))

    def first_change(self, since: int, ae: tuple[int, ...]) -> tuple[str, int, int, tuple[int, ...], int, int]:
        return next(r for r in self.runs if r[1] >= since and r[3] != ae)


def manual(**cfg: Any) -> tuple[Board, Pc]:
    b, pc = board_and_pc(**cfg)
    assert pc.command(Op.MODE, Mode.MANUAL).status == Nak.OK
    pc.js = Joystick(0, 0, 0, 8000, 0)
    pc.run(0.1)
    b.advance(b.now + 5000)  # what the PC sent last (a heartbeat's answer) is in and parsed
    assert b.ae != (0, 0, 0, 0)
    return b, pc


def stick_latencies(b: Board, pc: Pc, n: int) -> tuple[list[int], list[str]]:
    """Send n lift changes at random phases; the board time from each frame reaching the UART to the motors
    changing, and the task that changed them."""
    rng = random.Random(5)
    runs = Runs(b)
    lat, by = [], []
    for i in range(n):
        t = b.now + rng.randrange(10_000)
        b.advance(t)
        ae = b.ae
        pc.send(Joystick(0, 0, 0, (8000, 12000)[i % 2 == 0], 0))
        b.advance(t + 12_000)
        name, start, dur, _ae, at, _n = runs.first_change(t, ae)
        lat.append(at - t)
        by.append(name)
    b.on_task = None
    return lat, by


def test_a_changed_stick_moves_the_motors_in_the_parse_run_that_decodes_it() -> None:
    b, pc = manual()
    runs = Runs(b)
    for i in range(30):  # at many phases against the control step (the board's own clock: deterministic)
        t = b.now + 1000 * i % 5000
        b.advance(t)
        ae = b.ae
        pc.send(Joystick(0, 0, 0, 9000 + 1000 * (i % 2), 0))
        b.advance(t + 12_000)
        name, start, dur, new, at, _n = runs.first_change(t, ae)
        assert name == "parse" and at == start + dur  # at the end of that parse run: decode, then recompute
        # the first parse after the frame's last byte came in (not before: the wire takes 1.3 ms)
        assert start == next(r[1] for r in runs.runs if r[0] == "parse" and r[1] >= t + FRAME_WIRE_US)
        # the control step computes the same from these sticks: the motors stay where the parse put them
        after = [r for r in runs.runs if r[0] == "control" and r[1] > at]
        assert after and after[0][3] == new


def test_the_recompute_takes_the_stick_delay_from_the_control_period_to_the_wire() -> None:
    lat, by = stick_latencies(*manual(), 60)
    assert set(by) == {"parse"}
    assert min(lat) >= FRAME_WIRE_US and sum(lat) / len(lat) < FRAME_WIRE_US + 800
    old, by_old = stick_latencies(*manual(stick_reaction=False), 60)  # the report's firmware: control steps only
    assert set(by_old) == {"control"} and sum(old) / len(old) > FRAME_WIRE_US + 2000


def test_an_unchanged_stick_does_nothing_more_than_its_decode() -> None:
    b, pc = manual()
    runs = Runs(b)
    n0, ae = b.prof.reactions.n, b.ae
    for _ in range(50):  # the same value again and again: the stream's keep-alives
        pc.send(pc.js)
        b.advance(b.now + 10_000)
    parses = [r for r in runs.runs if r[0] == "parse"]
    assert len(parses) == 50 and all(r[2] == PARSE_US_BASE + PARSE_US_PER_BYTE * 15 for r in parses)
    assert b.prof.reactions.n == n0 and b.ae == ae
    pc.send(Command(99, Op.TRIM_ROLL, 4))  # a trim moves the effective stick: that is a change too
    b.advance(b.now + 10_000)
    assert b.prof.reactions.n == n0 + 1 and b.ae[3] > b.ae[1]  # roll right: the left motor up, the right one down


def test_safe_panic_and_fire_still_force_the_motors() -> None:
    b, pc = board_and_pc()
    pc.run(0.1)
    for js in (Joystick(4000, 0, 0, 0, 0), Joystick(0, 0, 0, 9000, 0)):  # SAFE: motors off whatever the sticks
        pc.send(js)
        b.advance(b.now + 10_000)
        assert b.ae == (0, 0, 0, 0) and b.world.cmd == [0, 0, 0, 0] and b.prof.reactions.n == 0
    b, pc = manual()
    n0 = b.prof.reactions.n
    pc.send(Joystick(0, 0, 0, 20_000, 1))  # fire with the lift up in the same frame: PANIC, not more lift
    b.advance(b.now + 10_000)
    assert b.mode == Mode.PANIC and b.prof.reactions.n == n0
    level = b.ae[0]
    assert b.ae == (level,) * 4 and level == int(b.core.panic_level)  # PANIC's descent loop drives them
    for lift in (30_000, 0, 15_000):  # sticks in PANIC move nothing: the motors are the descent loop's
        pc.send(Joystick(3000, -3000, 2000, lift, 0))
        b.advance(b.now + 10_000)
        assert b.ae == (int(b.core.panic_level),) * 4 and b.prof.reactions.n == n0


def test_the_recompute_in_height_steps_no_integral_filter_or_set_point() -> None:
    b, pc = board_and_pc()
    calibrate(pc)
    assert pc.command(Op.MODE, Mode.FULL).status == Nak.OK
    pc.js = Joystick(0, 0, 0, int(HOVER_LIFT * 1.05), 0)
    pc.run(1.0)
    assert pc.command(Op.MODE, Mode.HEIGHT).status == Nak.OK
    pc.run(1.0)
    fc = b.core

    def state() -> tuple[Any, ...]:
        h = fc.height_est
        return (fc._z_int, fc._sp_offset, fc.setpoint, fc.height, fc.vz, h.height, h.vz, fc.filter.quaternion(),
                fc.dmp_phi, fc.sp, b.world.t)

    seen: list[tuple[str, int, tuple[Any, ...]]] = []
    b.on_task = lambda name, start, dur: seen.append((name, b.prof.reactions.n, state()))
    n0 = b.prof.reactions.n
    for i in range(20):  # roll and a lift far past HEIGHT's deadband: with a time step both would move things
        pc.send(Joystick(600 * (i % 3 - 1), 0, 0, int(HOVER_LIFT * (1.05 + 0.3 * (i % 2))), 0))
        b.advance(b.now + 7_000)
    b.on_task = None
    assert b.mode == Mode.HEIGHT and b.prof.reactions.n >= n0 + 15
    reacted = [i for i in range(1, len(seen)) if seen[i][1] > seen[i - 1][1]]
    assert reacted and all(seen[i][0] == "parse" for i in reacted)
    for i in reacted:
        before, after = seen[i - 1][2], seen[i][2]
        assert after[:10] == before[:10]  # no estimator, filter, integral or set-point step
        assert after[10] >= before[10]  # only the world ran on to the moment the motors changed


def test_under_the_priority_scheduler_a_recompute_waits_if_it_might_not_fit_before_the_tick() -> None:
    b, pc = manual(scheduler="priority")
    rng = random.Random(2)
    checked = skipped = 0

    def check(name: str, start: int, dur: int) -> None:
        nonlocal checked, skipped
        if name != "parse":
            return
        if b.motors_at_us == start + dur:  # this parse run recomputed
            cost = b.prof.reactions.last_us
            assert b.motors_at_us - cost + COSTS[f"control_{b.path}"].figure[3] <= b.sched.next["sensor"]
            checked += 1
        elif b.modes.sticks() != b._sticks_used:
            skipped += 1  # left to the control step at the tick, which runs first

    b.on_task = check
    for _ in range(300):
        pc.send(Joystick(rng.randint(-2000, 2000), 0, 0, rng.randint(6000, 12_000), 0))
        b.advance(b.now + rng.randrange(2000, 6000))
    assert checked > 150 and skipped > 0


def test_a_burst_is_on_the_wire_while_a_task_runs_past_the_present() -> None:
    b, pc = manual()
    runs = Runs(b)
    start = None
    while start is None:  # stop the world just after a DMP read began (the read lasts about 2 ms)
        b.advance(b.now + 100)
        start = next((r[1] for r in runs.runs if r[0] == "sensor" and r[1] < b.now - 1500), None)
    t = start + 10
    runs.runs.clear()
    b.advance(t)
    assert b.now > t + FRAME_WIRE_US  # the loop is inside the read, well past the present
    ae, read_end = b.ae, b.now
    pc.send(Joystick(0, 0, 0, 11_000, 0))
    b.advance(t + 10_000)
    name, s, d, _new, at, _n = runs.first_change(t, ae)
    # the frame arrived during the read: parsed right after it (and the control step), not 1.3 ms after it
    assert name == "parse" and at < read_end + FRAME_WIRE_US
