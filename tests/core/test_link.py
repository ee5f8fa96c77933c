"""LinkSession on a fake clock: heartbeats, commands (ACK, retry, NAK, failure), joystick policy, statistics,
link loss and the version handshake. No I/O, no sleeps: time is a number passed in."""

from __future__ import annotations

import math

import pytest

from term.core.link import (
    CommandAcked,
    CommandFailed,
    LinkLost,
    LinkRestored,
    LinkSession,
    PacketReceived,
    VersionMismatch,
)
from term.core.protocol import (
    NAK_TEXT,
    PROTOCOL_VERSION,
    Ack,
    Command,
    Decoder,
    Encoder,
    Heartbeat,
    HeartbeatAck,
    Hello,
    Joystick,
    Nak,
    Op,
    Status,
)
from tests.conftest import LinkSim, ScriptedBoard


def packets(data: bytes) -> list:
    dec = Decoder()
    out = dec.feed(data)
    assert dec.stats.frames_bad == 0 and dec.stats.bytes_skipped == 0
    return out


class Board:
    """Just an encoder for frames the board would send."""

    def __init__(self) -> None:
        self.enc = Encoder()

    def __call__(self, *pkts: object) -> bytes:
        return self.enc.encode_many(pkts)


def of(events: list, kind: type) -> list:
    return [e for e in events if type(e) is kind]


# --- handshake and heartbeats -------------------------------------------------------------------------------


def test_hello_is_our_version() -> None:
    s = LinkSession(0.0)
    (hello,) = packets(s.hello())
    assert hello == Hello(PROTOCOL_VERSION, 0, hello.major, hello.minor, 0)
    assert s.stats.tx_bytes == s.encoder.bytes  # the Hello counted as sent


def test_heartbeat_answered_in_the_same_step_ahead_of_everything() -> None:
    s = LinkSession(0.0)
    board = Board()
    s.set_joystick(Joystick(1, 2, 3, 4, 0))
    s.send_command(Op.MODE, 2, 0.0)
    events = s.receive(board(Heartbeat(7, 123456)), 0.01)
    assert of(events, PacketReceived) == [PacketReceived(Heartbeat(7, 123456))]
    out = packets(s.data_to_send(0.01))
    assert out[0] == HeartbeatAck(7, 123456)
    assert [type(p) for p in out] == [HeartbeatAck, Joystick, Command]  # a changed stick goes ahead of a command
    assert s.data_to_send(0.01) == b""  # each thing once


def test_every_heartbeat_in_a_chunk_gets_its_ack_in_order() -> None:
    s = LinkSession(0.0)
    board = Board()
    s.receive(board(Heartbeat(1, 100), Status(0, 0, 0, 0, 0, 0, 0, 0), Heartbeat(2, 200)), 0.2)
    assert packets(s.data_to_send(0.2)) == [HeartbeatAck(1, 100), HeartbeatAck(2, 200)]
    st = s.stats_at(0.5)
    assert st.heartbeats == 2 and st.since_last_heartbeat_s == pytest.approx(0.3)


def test_a_heartbeat_split_across_reads_is_answered_when_whole() -> None:
    s = LinkSession(0.0)
    frame = Board()(Heartbeat(9, 900))
    s.receive(frame[:5], 0.1)
    assert s.data_to_send(0.1) == b""
    s.receive(frame[5:], 0.1)
    assert packets(s.data_to_send(0.1)) == [HeartbeatAck(9, 900)]


# --- commands -----------------------------------------------------------------------------------------------


def test_command_acked_with_value_and_rtt() -> None:
    s = LinkSession(0.0)
    board = Board()
    cmd_id = s.send_command(Op.TRIM_LIFT, 1, 0.5)
    assert packets(s.data_to_send(0.5)) == [Command(cmd_id, Op.TRIM_LIFT, 1)]
    events = s.receive(board(Ack(cmd_id, Op.TRIM_LIFT, Nak.OK, 250)), 0.512)
    assert of(events, CommandAcked) == [CommandAcked(cmd_id, Op.TRIM_LIFT, 1, 250)]
    assert s.stats.rtt_last_ms == pytest.approx(12.0)
    assert s.stats.commands_sent == 1 and s.stats.command_retries == 0


def test_retried_on_timeout_then_failed_with_reason() -> None:
    s = LinkSession(0.0, command_timeout=0.25, command_retries=3, link_timeout=10.0)
    cmd_id = s.send_command(Op.MODE, 2, 0.0)
    sent_at = []
    events: list = []
    t = 0.0
    while t < 2.0:  # 1 ms steps: retries must come exactly at the timeouts, not earlier
        events += s.poll(t)
        for p in packets(s.data_to_send(t)):
            assert p == Command(cmd_id, Op.MODE, 2)
            sent_at.append(t)
        t = round(t + 0.001, 6)
    assert sent_at == pytest.approx([0.0, 0.25, 0.5, 0.75])
    (failed,) = of(events, CommandFailed)
    assert failed.cmd_id == cmd_id and failed.op == Op.MODE and failed.arg == 2 and failed.nak is None
    assert "no answer from the board after 4 tries" in failed.reason
    assert s.stats.command_retries == 3 and s.stats.commands_failed == 1
    assert s.next_deadline() == 10.0  # only the link timeout is left


def test_failure_time_follows_next_deadline() -> None:
    s = LinkSession(0.0, command_timeout=0.1, command_retries=1, link_timeout=10.0)
    s.send_command(Op.LOG_STATUS, 0, 0.0)
    s.data_to_send(0.0)
    assert s.next_deadline() == pytest.approx(0.1)
    assert s.poll(0.0999) == [] and s.data_to_send(0.0999) == b""
    assert packets(s.data_to_send(0.1))  # the retry
    assert s.next_deadline() == pytest.approx(0.2)
    assert of(s.poll(0.2), CommandFailed)


def test_nak_reason_reaches_the_caller() -> None:
    s = LinkSession(0.0)
    board = Board()
    cmd_id = s.send_command(Op.MODE, 4, 0.0)
    s.data_to_send(0.0)
    events = s.receive(board(Ack(cmd_id, Op.MODE, Nak.NOT_CALIBRATED, 0)), 0.01)
    (failed,) = of(events, CommandFailed)
    assert failed.nak is Nak.NOT_CALIBRATED
    assert failed.reason == NAK_TEXT[Nak.NOT_CALIBRATED]
    assert s.stats.commands_failed == 0  # the link delivered it: a refusal is not a link failure
    assert s.stats.rtt_last_ms == pytest.approx(10.0)  # a NAK is a round trip too


def test_unknown_nak_code_still_gives_a_reason() -> None:
    s = LinkSession(0.0)
    cmd_id = s.send_command(Op.MODE, 4, 0.0)
    s.data_to_send(0.0)
    (failed,) = of(s.receive(Board()(Ack(cmd_id, Op.MODE, 200, 0)), 0.01), CommandFailed)
    assert failed.nak is None and "200" in failed.reason


def test_late_ack_after_a_retry_is_accepted_once_and_gives_no_rtt_sample() -> None:
    s = LinkSession(0.0, link_timeout=10.0)
    board = Board()
    cmd_id = s.send_command(Op.GAIN_P1, 1, 0.0)
    s.data_to_send(0.0)
    s.data_to_send(0.25)  # the retry
    ack = Ack(cmd_id, Op.GAIN_P1, Nak.OK, 5)
    assert of(s.receive(board(ack), 0.26), CommandAcked) == [CommandAcked(cmd_id, Op.GAIN_P1, 1, 5)]
    assert of(s.receive(board(ack), 0.27), CommandAcked) == []  # the board's answer to the retry: ignored
    assert s.stats.rtt_last_ms is None  # Karn: which attempt was answered is unknown
    assert not of(s.poll(5.0), CommandFailed)  # answered: no retries run out later


def test_ack_for_another_op_does_not_match() -> None:
    s = LinkSession(0.0, link_timeout=10.0)
    cmd_id = s.send_command(Op.MODE, 2, 0.0)
    s.data_to_send(0.0)
    assert not of(s.receive(Board()(Ack(cmd_id, Op.TRIM_LIFT, Nak.OK, 0)), 0.01), CommandAcked)


def test_commands_go_one_at_a_time_in_order() -> None:
    s = LinkSession(0.0, link_timeout=100.0)
    board = Board()
    ops = (Op.TRIM_ROLL, Op.TRIM_PITCH, Op.TRIM_ROLL)  # no two alike in a row: those would merge
    ids = [s.send_command(op, k, 0.0) for k, op in enumerate(ops)]
    assert len(set(ids)) == 3
    assert packets(s.data_to_send(0.0)) == [Command(ids[0], Op.TRIM_ROLL, 0)]  # the others wait their turn
    assert s.next_deadline() == pytest.approx(0.25)  # only the retry timer: waiting commands are not due
    s.receive(board(Ack(ids[0], Op.TRIM_ROLL, 0, 0)), 0.01)
    assert packets(s.data_to_send(0.01)) == [Command(ids[1], Op.TRIM_PITCH, 1)]
    s.receive(board(Ack(ids[1], Op.TRIM_PITCH, Nak.BAD_ARGUMENT, 0)), 0.02)  # a NAK settles it too
    assert packets(s.data_to_send(0.02)) == [Command(ids[2], Op.TRIM_ROLL, 2)]


def test_a_failed_command_lets_the_next_one_go() -> None:
    s = LinkSession(0.0, link_timeout=100.0, command_timeout=0.1, command_retries=0)
    a = s.send_command(Op.MODE, 2, 0.0)
    b = s.send_command(Op.MODE, 0, 0.0)
    assert packets(s.data_to_send(0.0)) == [Command(a, Op.MODE, 2)]
    assert [e.cmd_id for e in of(s.poll(0.1), CommandFailed)] == [a]
    assert s.next_deadline() == -math.inf
    assert packets(s.data_to_send(0.1)) == [Command(b, Op.MODE, 0)]


def test_waiting_commands_are_bounded() -> None:
    s = LinkSession(0.0, link_timeout=100.0, max_queued=32)
    ids = [s.send_command(Op.PROFILE, 0, 0.0) for _ in range(40)]  # not a stepping op: nothing merges
    assert len(set(ids)) == 40 and all(0 <= i < 256 for i in ids)
    failed = of(s.poll(0.0), CommandFailed)
    assert [f.cmd_id for f in failed] == ids[32:] and "too many commands" in failed[0].reason


def test_panic_jumps_the_queue_and_cancels_what_waits() -> None:
    s = LinkSession(0.0, link_timeout=100.0)
    stuck = s.send_command(Op.MODE, 2, 0.0)
    s.data_to_send(0.0)
    waiting = s.send_command(Op.TRIM_LIFT, 1, 0.05)
    panic = s.send_command(Op.MODE, 1, 0.06)  # Mode.PANIC
    cancelled = of(s.poll(0.06), CommandFailed)
    assert [c.cmd_id for c in cancelled] == [stuck, waiting]
    assert all(c.reason == "cancelled: PANIC requested" for c in cancelled)
    assert packets(s.data_to_send(0.06)) == [Command(panic, Op.MODE, 1)]
    assert packets(s.data_to_send(0.31)) == [Command(panic, Op.MODE, 1)]  # only PANIC is retried


def test_ids_wrap_modulo_256() -> None:
    s = LinkSession(0.0, link_timeout=1000.0)
    board = Board()
    seen = []
    for k in range(300):
        cmd_id = s.send_command(Op.TRIM_YAW, 1, k)
        s.data_to_send(k)
        seen.append(cmd_id)
        assert of(s.receive(board(Ack(cmd_id, Op.TRIM_YAW, 0, 0)), k + 0.001), CommandAcked)
    assert seen[:256] == list(range(256)) and seen[256:] == list(range(44))


# --- joystick -----------------------------------------------------------------------------------------------


def test_joystick_latest_wins_at_most_rate() -> None:
    s = LinkSession(0.0, joystick_rate=100.0, link_timeout=100.0)
    sent: list[tuple[float, Joystick]] = []
    latest = None
    for ms in range(1000):  # 1 s of 1 kHz stick updates, the session asked every ms
        t = ms / 1000
        latest = Joystick(ms, -ms, 0, ms % 32767, 0)
        s.set_joystick(latest)
        for p in packets(s.data_to_send(t)):
            assert p == latest  # never a stale value
            sent.append((t, p))
    assert len(sent) == 100
    gaps = [b[0] - a[0] for a, b in zip(sent, sent[1:], strict=False)]
    assert min(gaps) >= 0.01 - 1e-9


def test_joystick_rate_holds_when_the_timer_wakes_late() -> None:
    s = LinkSession(0.0, joystick_rate=100.0, link_timeout=100.0)
    s.set_joystick(Joystick(0, 0, 0, 0, 0))
    t, sent = 0.0, []
    while t < 10.0:  # a timer that wakes 0.3 ms after every deadline must not slow the stream down
        if packets(s.data_to_send(t)):
            sent.append(t)
        t = s.next_deadline() + 0.0003
    assert len(sent) == 1000
    gaps = [b - a for a, b in zip(sent, sent[1:], strict=False)]
    assert min(gaps) >= 0.005


def test_joystick_not_sent_before_set_and_streams_unchanged_without_change_only() -> None:
    s = LinkSession(0.0, joystick_rate=50.0, link_timeout=100.0)
    assert s.data_to_send(0.0) == b""
    s.set_joystick(Joystick(0, 0, 0, 0, 0))
    n = sum(len(packets(s.data_to_send(ms / 1000))) for ms in range(1000))
    assert n == 50  # the cable stream repeats the same value: it also keeps the board's link timer alive


def test_change_only_sends_on_change_plus_keepalive() -> None:
    s = LinkSession(0.0, joystick_rate=100.0, change_only=True, keepalive=0.5, link_timeout=100.0)
    s.set_joystick(Joystick(0, 0, 0, 0, 0))
    times = []
    for ms in range(2000):
        t = ms / 1000
        if ms == 1234:
            s.set_joystick(Joystick(0, 0, 0, 1000, 0))
        if ms == 1236:  # changes again within the rate limit: held, then the latest one goes out
            s.set_joystick(Joystick(0, 0, 0, 2000, 0))
        for p in packets(s.data_to_send(t)):
            times.append((ms, p.lift))
    assert times == [(0, 0), (500, 0), (1000, 0), (1234, 1000), (1244, 2000), (1744, 2000)]


def test_a_change_right_after_a_keepalive_goes_at_once() -> None:
    s = LinkSession(0.0, joystick_rate=100.0, change_only=True, keepalive=0.5, link_timeout=100.0)
    s.set_joystick(Joystick(0, 0, 0, 0, 0))
    times = []
    for tenth_ms in range(12_000):  # 1.2 s, asked every 0.1 ms
        t = tenth_ms / 10_000
        if tenth_ms == 5_002:  # 0.2 ms after the keep-alive at 0.5 s
            s.set_joystick(Joystick(0, 0, 0, 1000, 0))
        if tenth_ms == 5_010:  # another change 0.8 ms later: the rate limit holds it until 10 ms after the first
            s.set_joystick(Joystick(0, 0, 0, 2000, 0))
        for p in packets(s.data_to_send(t)):
            times.append((tenth_ms, p.lift))
    assert times == [(0, 0), (5_000, 0), (5_002, 1000), (5_102, 2000), (10_102, 2000)]
    # the deadline says so too: after a keep-alive, a change is due now
    s = LinkSession(0.0, joystick_rate=100.0, change_only=True, keepalive=0.5, link_timeout=100.0)
    s.set_joystick(Joystick(0, 0, 0, 0, 0))
    s.data_to_send(0.0)
    s.data_to_send(0.5)  # the keep-alive
    s.set_joystick(Joystick(1, 0, 0, 0, 0))
    assert s.next_deadline() <= 0.5


def test_joystick_deadline_drives_the_timer() -> None:
    s = LinkSession(0.0, joystick_rate=100.0, change_only=True, keepalive=0.5, link_timeout=100.0)
    assert s.next_deadline() == 100.0  # only the link timeout
    s.set_joystick(Joystick(0, 0, 0, 0, 0))
    assert s.next_deadline() == -math.inf  # never sent: due now
    s.data_to_send(1.0)
    assert s.next_deadline() == pytest.approx(1.5)  # keep-alive
    s.set_joystick(Joystick(1, 0, 0, 0, 0))
    assert s.next_deadline() == pytest.approx(1.01)  # the change, at the rate limit


# --- statistics ---------------------------------------------------------------------------------------------


def test_rtt_last_mean_p95() -> None:
    s = LinkSession(0.0, link_timeout=1000.0)
    board = Board()
    t = 0.0
    for k in range(1, 21):  # RTTs of 1..20 ms
        cmd_id = s.send_command(Op.TRIM_YAW, 1, t)
        s.data_to_send(t)
        s.receive(board(Ack(cmd_id, Op.TRIM_YAW, 0, 0)), t + k / 1000)
        t += 1.0
    st = s.stats
    assert st.rtt_last_ms == pytest.approx(20.0)
    assert st.rtt_mean_ms == pytest.approx(10.5)
    assert st.rtt_p95_ms == pytest.approx(19.0)  # nearest rank: the 19th of 20


def test_loss_from_sequence_gaps_windowed_and_total() -> None:
    s = LinkSession(0.0, link_timeout=1000.0, stats_window=2.0)
    board = Board()
    for k in range(1000):  # 10 s at 100 Hz; every 10th frame lost in the first 5 s only
        frame = board(Status(0, k, 0, 0, 0, 0, 0, 0))
        if k < 500 and k % 10 == 5:
            continue
        s.receive(frame, k / 100)
    st = s.stats_at(9.995)
    assert st.loss_pct == 0.0  # the last 2 s were clean
    assert st.loss_pct_total == pytest.approx(5.0)  # 50 of 1000
    assert st.frames_ok == 950
    s2 = LinkSession(0.0, link_timeout=1000.0, stats_window=2.0)
    board2 = Board()
    for k in range(400):
        frame = board2(Status(0, k, 0, 0, 0, 0, 0, 0))
        if k % 4 != 0:
            s2.receive(frame, k / 100)
    assert s2.stats_at(3.995).loss_pct == pytest.approx(25.0, abs=1.0)


def test_corrupted_frames_are_counted_bad_and_as_loss() -> None:
    s = LinkSession(0.0, link_timeout=1000.0)
    board = Board()
    data = bytearray(board(*(Status(0, k, 0, 0, 0, 0, 0, 0) for k in range(10))))
    data[25] ^= 0x40  # inside the second frame (frames are 19 bytes)
    s.receive(bytes(data), 0.1)
    st = s.stats
    assert st.frames_ok == 9 and st.frames_bad == 1 and st.loss_pct_total == pytest.approx(10.0)


def test_bytes_per_second_each_way() -> None:
    s = LinkSession(0.0, joystick_rate=100.0, link_timeout=1000.0, stats_window=2.0)
    board = Board()
    s.set_joystick(Joystick(0, 0, 0, 0, 0))
    rx = 0
    for ms in range(0, 4000, 10):
        t = ms / 1000
        frame = board(Status(0, 0, 0, 0, 0, 0, 0, 0))
        rx += len(frame)
        s.receive(frame, t)
        s.data_to_send(t)
    st = s.stats_at(3.99)
    js_frame = len(Encoder().encode(Joystick(0, 0, 0, 0, 0)))
    assert st.tx_bytes_per_s == pytest.approx(100 * js_frame, rel=0.02)
    assert st.rx_bytes_per_s == pytest.approx(100 * len(frame), rel=0.02)
    assert st.rx_bytes == rx


def test_heartbeat_delay_is_relative_to_the_fastest() -> None:
    s = LinkSession(0.0, link_timeout=1000.0)
    board = Board()
    offset = 123.0  # the board booted long before us: the offset must cancel
    for k, extra_ms in enumerate([5, 1, 3, 40, 2]):
        board_t = k * 0.1
        s.receive(board(Heartbeat(k, int((board_t + offset) * 1000))), board_t + extra_ms / 1000)
        s.data_to_send(board_t)
    assert s.stats.heartbeat_delay_ms == pytest.approx(1.0, abs=1e-6)  # 2 ms against the best 1 ms
    assert s.stats.rtt_last_ms is None  # heartbeats without the board's measurement give no RTT


def test_board_measured_heartbeat_rtt_joins_the_rtt_series() -> None:
    s = LinkSession(0.0, link_timeout=1000.0)
    board = Board()
    for k, rtt in enumerate([0, 25, 0, 41]):  # 0: the board has no measurement for that heartbeat
        s.receive(board(Heartbeat(k, k * 100, rtt)), k * 0.1)
    st = s.stats
    assert st.rtt_last_ms == pytest.approx(4.1)
    assert st.rtt_mean_ms == pytest.approx(3.3)


def test_time_since_last_frame() -> None:
    s = LinkSession(0.0)
    assert s.stats_at(0.3).since_last_frame_s is None
    s.receive(Board()(Status(0, 0, 0, 0, 0, 0, 0, 0)), 0.4)
    assert s.stats_at(0.7).since_last_frame_s == pytest.approx(0.3)
    assert s.stats_at(0.7).since_last_heartbeat_s is None


# --- link lost and restored ---------------------------------------------------------------------------------


def test_link_lost_after_timeout_then_restored() -> None:
    s = LinkSession(0.0, link_timeout=1.0)
    board = Board()
    s.receive(board(Heartbeat(0, 0)), 0.5)
    s.data_to_send(0.5)
    assert s.next_deadline() == pytest.approx(1.5)
    assert s.poll(1.49) == []
    events = s.poll(1.5)
    assert events == [LinkLost(pytest.approx(1.0))]
    assert s.stats.lost and s.poll(3.0) == []  # reported once
    events = s.receive(board(Heartbeat(1, 100)), 4.0)
    assert events[0] == LinkRestored(pytest.approx(3.5))
    assert not s.stats.lost
    out = packets(s.data_to_send(4.0))
    assert [type(p) for p in out] == [Hello, HeartbeatAck]  # handshake again: the board may have restarted


def test_no_board_at_all_is_a_lost_link() -> None:
    """A board that never answers is lost once the start-up grace is over, and the event says it never spoke."""
    s = LinkSession(10.0, link_timeout=1.0, connect_timeout=3.0)
    assert s.next_deadline() == pytest.approx(13.0)
    assert s.poll(12.99) == []
    assert of(s.poll(13.0), LinkLost) == [LinkLost(pytest.approx(3.0), never_heard=True)]


def test_the_loss_clock_starts_at_the_boards_first_frame() -> None:
    """Issue 21: term --sim on a busy machine said LINK LOST 0.8 s into start-up, while the simulator's own process
    got no CPU (its first frame came late). Before the board's first frame the link is still being made: the
    start-up grace (``connect_timeout``) applies; from that frame on the link timeout does, as before."""
    s = LinkSession(0.0, link_timeout=0.5, connect_timeout=3.0)
    assert s.poll(0.8) == []
    s.receive(Board()(Heartbeat(0, 0)), 0.8)
    s.data_to_send(0.8)
    assert s.next_deadline() == pytest.approx(1.3)
    assert s.poll(1.29) == []
    assert of(s.poll(1.3), LinkLost) == [LinkLost(pytest.approx(0.5))]


def test_the_start_up_grace_is_never_shorter_than_the_link_timeout() -> None:
    s = LinkSession(0.0, link_timeout=5.0, connect_timeout=3.0)
    assert s.poll(4.99) == []
    assert of(s.poll(5.0), LinkLost)


@pytest.mark.parametrize("option", ["link_timeout", "connect_timeout", "command_timeout", "joystick_rate", "keepalive",
                                    "stats_window"])
@pytest.mark.parametrize("value", [math.nan, math.inf, -math.inf, 0.0, -1.0, "1", None, True])
def test_a_timer_option_that_is_not_a_finite_positive_number_is_refused_in_one_line(option: str, value: object) -> None:
    # nan passed the old "<= 0" test: a link timeout that never fires, and the terminal spun on it
    with pytest.raises(ValueError) as err:
        LinkSession(0.0, **{option: value})  # type: ignore[arg-type]
    assert str(err.value) == f"{option} must be a finite number above 0, got {value!r}"


@pytest.mark.parametrize("value", [-1, 1.5, math.nan, True, "3"])
def test_command_retries_must_be_a_whole_number(value: object) -> None:
    with pytest.raises(ValueError, match="command_retries must be a whole number >= 0"):
        LinkSession(0.0, command_retries=value)  # type: ignore[arg-type]


def test_the_smallest_and_largest_sane_options_are_accepted() -> None:
    s = LinkSession(0.0, link_timeout=0.05, command_timeout=1e-3, joystick_rate=1e4, keepalive=3600.0,
                    stats_window=86400.0, command_retries=0)
    assert s.link_timeout == 0.05 and s.joystick_interval == pytest.approx(1e-4)


def test_commands_in_flight_fail_when_the_link_is_lost_and_new_ones_fail_fast() -> None:
    s = LinkSession(0.0, link_timeout=1.0, command_timeout=0.4, command_retries=5)
    s.receive(Board()(Heartbeat(0, 0)), 0.0)
    a = s.send_command(Op.MODE, 2, 0.5)
    s.data_to_send(0.5)
    events = s.poll(1.0)
    assert [type(e) for e in events] == [LinkLost, CommandFailed]
    assert events[1].cmd_id == a and events[1].reason.startswith("link lost")
    b = s.send_command(Op.MODE, 0, 1.2)
    assert s.data_to_send(1.2) == b""  # nothing sent to a lost link
    assert s.next_deadline() == -math.inf  # the failure is due at once
    (failed,) = s.poll(1.2)
    assert failed.cmd_id == b and failed.reason == "link lost: nothing from the board for 1.2 s"


def test_silence_then_data_reports_lost_and_restored_in_order() -> None:
    s = LinkSession(0.0, link_timeout=1.0)
    events = s.receive(Board()(Status(0, 0, 0, 0, 0, 0, 0, 0)), 5.0)  # nobody polled in between
    assert [type(e) for e in events] == [LinkLost, LinkRestored, PacketReceived]


def test_sequence_jump_across_an_outage_is_not_counted_as_loss() -> None:
    s = LinkSession(0.0, link_timeout=1.0)
    board = Board()
    s.receive(board(Status(0, 0, 0, 0, 0, 0, 0, 0)), 0.0)
    for _ in range(100):
        board(Status(0, 0, 0, 0, 0, 0, 0, 0))  # sent while the cable was out
    s.poll(2.0)
    s.receive(board(Status(0, 0, 0, 0, 0, 0, 0, 0)), 3.0)
    assert s.stats.loss_pct_total == 0.0


# --- version handshake --------------------------------------------------------------------------------------


def test_version_mismatch_is_reported_and_stops_commands_and_sticks() -> None:
    s = LinkSession(0.0)
    s.set_joystick(Joystick(0, 0, 0, 0, 0))
    waiting = s.send_command(Op.MODE, 2, 0.0)
    events = s.receive(Board()(Hello(PROTOCOL_VERSION + 1, 1, 2, 0, 7)), 0.01)
    assert VersionMismatch(PROTOCOL_VERSION + 1, PROTOCOL_VERSION) in events
    (failed,) = of(events, CommandFailed)
    assert failed.cmd_id == waiting and f"v{PROTOCOL_VERSION + 1}" in failed.reason
    assert s.data_to_send(0.02) == b""  # neither the command nor the stick goes to a board that may misread
    s.send_command(Op.MODE, 0, 0.03)
    (again,) = s.poll(0.03)
    assert "protocol" in again.reason
    assert s.stats.board_version == PROTOCOL_VERSION + 1


def test_matching_hello_is_quiet() -> None:
    s = LinkSession(0.0)
    events = s.receive(Board()(Hello(PROTOCOL_VERSION, 1, 0, 1, 7)), 0.01)
    assert [type(e) for e in events] == [PacketReceived]
    assert s.board_hello == Hello(PROTOCOL_VERSION, 1, 0, 1, 7)


# --- the whole loop against a scripted board ----------------------------------------------------------------


def test_session_against_scripted_board_keeps_the_link_and_answers_every_heartbeat() -> None:
    s = LinkSession(0.0)
    board = ScriptedBoard(heartbeat_period=0.1)
    sim = LinkSim(s, board)
    s.set_joystick(Joystick(0, 0, 0, 0, 0))
    sim.run_until(0.5)
    cmd = s.send_command(Op.MODE, 2, sim.now)
    sim.run_until(9.95)
    assert not sim.of_type(LinkLost)
    assert board.hellos and s.board_hello is not None
    assert [a.counter for a in board.hb_acks] == list(range(len(board.hb_acks)))
    assert len(board.hb_acks) == 100  # heartbeats at 0.0 .. 9.9
    assert sim.of_type(CommandAcked) == [CommandAcked(cmd, Op.MODE, 2, 20)]
    assert 990 <= len(board.joysticks) <= 1000
    assert s.stats.loss_pct_total == 0.0 and s.stats.frames_bad == 0


def test_a_burst_of_key_presses_is_merged_not_refused() -> None:
    # Seen from the outside: 45 presses of 'a' typed at once gave "trim lift +1 failed: too many commands
    # waiting for the board" 12 times; those presses were lost. Presses not sent yet now add up in one command.
    s = LinkSession(0.0, link_timeout=100.0, max_queued=32)
    first = s.send_command(Op.TRIM_LIFT, 1, 0.0)
    s.data_to_send(0.0)  # in flight: not merged into
    ids = [s.send_command(Op.TRIM_LIFT, 1, 0.0) for _ in range(44)]
    mode = s.send_command(Op.MODE, 2, 0.0)
    down = s.send_command(Op.TRIM_LIFT, -1, 0.0)  # after another command: its own, in order
    assert not of(s.poll(0.0), CommandFailed)
    assert len(set(ids)) == 1 and first not in ids
    s.receive(Board()(Ack(first, Op.TRIM_LIFT, Nak.OK, 1)), 0.01)
    assert packets(s.data_to_send(0.01)) == [Command(ids[0], Op.TRIM_LIFT, 44)]
    s.receive(Board()(Ack(ids[0], Op.TRIM_LIFT, Nak.OK, 45)), 0.02)
    assert packets(s.data_to_send(0.02)) == [Command(mode, Op.MODE, 2)]
    s.receive(Board()(Ack(mode, Op.MODE, Nak.OK, 0)), 0.03)
    assert packets(s.data_to_send(0.03)) == [Command(down, Op.TRIM_LIFT, -1)]


def test_time_the_terminal_could_not_listen_is_not_the_boards_silence() -> None:
    """Issue 21: a starved terminal (its process got no CPU for 0.7 s) woke, ran its timer before the bytes that
    waited in the OS, and said LINK LOST with the same millisecond as 'link restored'. The time it could not run
    (``starved``) is left out of the silence; a board that stays silent is still lost, a timeout later."""
    from term.core.link import LinkLost
    from term.core.protocol import Encoder, Heartbeat

    s = LinkSession(0.0, link_timeout=0.5)
    board = Encoder()
    s.receive(board.encode(Heartbeat(0, 0)), 0.1)
    s.starved(0.3, 1.0)  # the terminal's timer, due at 0.3 s, ran at 1.0 s
    assert not any(type(e) is LinkLost for e in s.poll(1.0))
    s.data_to_send(1.0)  # (the heartbeat's answer)
    assert s.next_deadline() == pytest.approx(0.1 + 0.7 + 0.5)
    s.receive(board.encode(Heartbeat(1, 100)), 1.0)  # what waited in the OS meanwhile
    assert not s.lost
    s.starved(1.2, 1.3)
    assert not any(type(e) is LinkLost for e in s.poll(1.55))  # 0.55 s since the frame, 0.1 s of them starved
    lost = [e for e in s.poll(1.65) if type(e) is LinkLost]  # the board really is silent: lost after all
    assert lost and lost[0].silent_s == pytest.approx(0.55)


def test_a_command_leaves_after_the_stick_set_before_it() -> None:
    """Issue 21 (found by test_export once the link had its own thread): the pilot zeroes the lift, then presses
    SAFE; the command left at once while the stick's frame waited out the joystick rate, so the board read SAFE
    with the old lift and refused it ('lift not at zero'). A changed stick now goes ahead of a command."""
    from term.core.protocol import Command, Decoder, Joystick, Mode, Op

    s = LinkSession(0.0, link_timeout=10.0, joystick_rate=50.0)
    dec = Decoder()
    s.set_joystick(Joystick(0, 0, 0, 9000, 0))
    dec.feed(s.data_to_send(0.0))  # (its Hello was sent by the caller; this is the stick at 9000)
    s.set_joystick(Joystick(0, 0, 0, 0, 0))
    s.send_command(Op.MODE, Mode.SAFE, 0.001)  # 1 ms later: the rate would hold the stick for 19 ms
    out = dec.feed(s.data_to_send(0.001))
    assert [type(p).__name__ for p in out] == ["Joystick", "Command"]
    assert out[0].lift == 0 and isinstance(out[1], Command)
    assert not dec.feed(s.data_to_send(0.005))  # and the stick is not sent twice
