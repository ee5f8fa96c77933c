"""The board's two-stage link-loss failsafe (issue 21) and the rule that in flight the link timeouts only shrink.

Stage 1: after link.timeout_ms of silence in a flight mode the board holds level with the lift it had and says
LINK_LOST; a frame within link.failsafe_ms gives control back (LINK_REGAINED, no PANIC). Stage 2: the PANIC
descent (LINK_TIMEOUT). The report's preset keeps the report's immediate PANIC. Board time is the clock: no sleeps.
"""

from __future__ import annotations

from fcb_sim.board.board import Board, BoardConfig
from fcb_sim.board.modes import ModeConfig, ModeMachine
from fcb_sim.board.param_bindings import get_raw
from term.core.protocol import PARAMS, Event, EventCode, Joystick, Mode, Nak, Op, Param, nak_text, param_arg
from tests.support.board_rig import HOVER_LIFT, Pc


def flying(**cfg: object) -> tuple[Board, Pc]:
    b = Board(BoardConfig(seed=1, **cfg))  # type: ignore[arg-type]
    pc = Pc(b)
    assert pc.command(Op.MODE, Mode.CALIBRATION).status == Nak.OK
    pc.run(1.2)
    pc.command(Op.MODE, Mode.SAFE)  # the report's board calibrates until the pilot leaves CALIBRATION
    assert b.mode == Mode.SAFE and b.modes.calibrated
    assert pc.command(Op.MODE, Mode.FULL).status == Nak.OK
    pc.js = Joystick(0, 0, 0, HOVER_LIFT, 0)
    pc.run(1.0)
    return b, pc


def events(pc: Pc, code: EventCode) -> list[Event]:
    pc.read()
    return [e for e in pc.of(Event) if e.code == code]


def set_param(pc: Pc, param: Param, value: int) -> Nak:
    return Nak(pc.command(Op.SET_PARAM, param_arg(param, PARAMS[param].to_raw(value))).status)


def test_in_flight_the_link_timeouts_only_shrink() -> None:
    b, pc = flying()
    assert set_param(pc, Param.LINK_TIMEOUT_MS, 60000) == Nak.ONLY_SHORTER_IN_FLIGHT  # the fault: PANIC off in flight
    assert set_param(pc, Param.LINK_FAILSAFE_MS, 10000) == Nak.ONLY_SHORTER_IN_FLIGHT
    assert get_raw(b.parts, Param.LINK_TIMEOUT_MS) == 500 and get_raw(b.parts, Param.LINK_FAILSAFE_MS) == 1000
    assert set_param(pc, Param.LINK_TIMEOUT_MS, 300) == Nak.OK and b.modes.config.link_timeout_s == 0.3
    assert set_param(pc, Param.LINK_FAILSAFE_MS, 0) == Nak.OK and b.modes.config.link_failsafe_s == 0.0
    assert "shorter" in nak_text(Nak.ONLY_SHORTER_IN_FLIGHT)
    pc.js = Joystick(0, 0, 0, 0, 0)
    assert pc.command(Op.MODE, Mode.SAFE).status == Nak.OK
    assert set_param(pc, Param.LINK_TIMEOUT_MS, 60000) == Nak.OK  # on the ground: any length
    assert set_param(pc, Param.LINK_FAILSAFE_MS, 10000) == Nak.OK


def test_stage_one_holds_level_and_gives_control_back_without_a_panic() -> None:
    b, pc = flying()
    pc.js = Joystick(6000, 0, 0, HOVER_LIFT + 500, 0)  # a roll in, then the link goes quiet
    pc.run(0.05)
    b.advance(b.now + 800_000)  # 0.8 s of silence: past the 0.5 s timeout, inside the 1 s guard
    assert b.modes.link_hold and b.mode == Mode.FULL
    assert b.modes.sticks() == (0, 0, 0, HOVER_LIFT + 500)  # level, with the lift it had
    (lost,) = events(pc, EventCode.LINK_LOST)
    assert 500 <= lost.arg <= 600  # the timeout plus at most one heartbeat period
    assert not events(pc, EventCode.LINK_TIMEOUT)
    pc.run(0.3)  # the link is back
    assert not b.modes.link_hold and b.mode == Mode.FULL
    assert b.modes.sticks()[0] == 6000  # the pilot's stick again
    (back,) = events(pc, EventCode.LINK_REGAINED)
    assert 0 < back.arg <= 500
    assert not [c for c in b.modes.changes if c.new == Mode.PANIC]


def test_stage_two_is_the_panic_descent_after_the_guard_time() -> None:
    b, pc = flying()
    last = b.last_frame_us
    b.advance(b.now + 2_000_000)
    panic = [c for c in b.modes.changes if c.new == Mode.PANIC][-1]
    assert panic.reason == "panic:link"
    assert 1.5 < panic.now - last / 1e6 <= 1.5 + 0.1 + 0.01  # timeout + guard, within one heartbeat
    assert [e.code for e in pc.dec.feed(b.uart_transmit()) if type(e) is Event
            and e.code in (EventCode.LINK_LOST, EventCode.LINK_TIMEOUT)] == [EventCode.LINK_LOST,
                                                                            EventCode.LINK_TIMEOUT]
    assert not b.modes.link_hold
    pc.run(0.3)  # the link back after the PANIC: the descent goes on
    assert b.mode == Mode.PANIC


def test_the_report_preset_panics_at_once() -> None:
    b, pc = flying(preset="report")
    last = b.last_frame_us
    b.advance(b.now + 1_000_000)
    panic = [c for c in b.modes.changes if c.new == Mode.PANIC][-1]
    assert 0.5 < panic.now - last / 1e6 <= 0.5 + 0.325 + 0.01  # within one of the report's heartbeat periods
    pc.read()
    assert not events(pc, EventCode.LINK_LOST) and events(pc, EventCode.LINK_TIMEOUT)


def test_the_machine_alone() -> None:
    m = ModeMachine(ModeConfig(link_timeout_s=0.5, link_failsafe_s=1.0))
    m.calibrated = True
    assert m.request(Mode.MANUAL, 0.0) == Nak.OK
    assert m.supervise(1.0, link_silent_s=0.6) is None and m.link_hold
    assert m.supervise(1.5, link_silent_s=1.5) is None and m.link_hold  # at the guard's end: still holding
    assert m.supervise(1.6, link_silent_s=1.6) == EventCode.LINK_TIMEOUT and m.mode == Mode.PANIC
    codes = [c for c, _arg, _t in m.drain_events()]
    assert codes.index(EventCode.LINK_LOST) < codes.index(EventCode.LINK_TIMEOUT)
    m = ModeMachine(ModeConfig(link_timeout_s=0.5, link_failsafe_s=1.0))
    assert m.supervise(1.0, link_silent_s=5.0) is None and m.mode == Mode.SAFE and not m.link_hold  # not flying


def test_the_terminal_says_what_the_board_does() -> None:
    from term.session.texts import event_text

    assert event_text(EventCode.LINK_LOST, 600) == ("error", "LINK LOST: board holds level (600 ms silent); "
                                                              "PANIC if it stays")
    assert event_text(EventCode.LINK_REGAINED, 300)[1].startswith("board has the link back after 300 ms")
    assert "250 ms behind real time" in event_text(EventCode.SIM_LAG, 250)[1]


# --- a starved simulator keeps the link's time honest (fcb_sim/hosts/serve.py) ----------------------------------------


def test_a_starved_simulator_does_not_count_its_own_stall_as_link_silence() -> None:
    """The server's process gets no CPU for 0.4 s while the PC keeps sending: the frames wait in the pty. When it
    runs again the board must not call that link silence (no LINK_LOST, no PANIC on the report's board), and it
    says how far it ran behind real time (SIM_LAG). The wall clock is injected: no sleeps."""
    import os
    import select

    from fcb_sim.hosts.serve import PtyServer
    from term.core.protocol import Decoder, Encoder

    b, pc = flying(preset="report", link_timeout_s=0.2)  # the report's board: 0.2 s of silence is PANIC at once
    now = [1000.0]
    server = PtyServer(b, clock=lambda: now[0])
    os.set_blocking(server.slave, False)
    enc, dec, got = Encoder(), Decoder(), []

    def wall_step(seconds: float, *, runs: bool = True) -> None:
        end = now[0] + seconds
        while now[0] < end - 1e-9:
            now[0] += 0.01
            os.write(server.slave, enc.encode(pc.js))  # the PC streams its sticks at 100 Hz
            if runs:
                select.select([server.master], [], [], 5.0)  # the pty hands the bytes over (an event, not a pause)
                server._on_readable()
                server._step()
                try:
                    got.extend(dec.feed(os.read(server.slave, 65536)))
                except BlockingIOError:
                    pass

    wall_step(0.2)
    wall_step(0.4, runs=False)  # starved: nothing runs, the bytes wait
    select.select([server.master], [], [], 5.0)
    wall_step(0.3)
    try:
        got.extend(dec.feed(os.read(server.slave, 65536)))
    except BlockingIOError:
        pass
    server.close()
    assert b.mode == Mode.FULL and not b.modes.link_hold
    codes = [e.code for e in got if type(e) is Event]
    assert EventCode.LINK_LOST not in codes and EventCode.LINK_TIMEOUT not in codes
    (lag,) = [e for e in got if type(e) is Event and e.code == EventCode.SIM_LAG]
    assert 380 <= lag.arg <= 420  # ms behind real time when it ran again
    assert b.now >= server._wall_us() - 20_000 and server.pacing.slips == 0  # caught up, not slipped
