"""The link session over a faulty loopback on a fake clock: retries carry commands through loss and corruption,
the loss figure matches the injected loss, and a dead link is declared and recovered."""

from __future__ import annotations

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from term.core.link import CommandAcked, CommandFailed, LinkLost, LinkRestored, LinkSession
from term.core.protocol import Joystick, Op
from term.transports.loopback import Faults, FaultyChannel
from tests.conftest import LinkSim, ScriptedBoard


def test_commands_get_through_loss_and_corruption_by_retry() -> None:
    session = LinkSession(0.0, command_timeout=0.05, command_retries=5)
    board = ScriptedBoard(heartbeat_period=0.1, filler_period=0.01)
    up = FaultyChannel(Faults(drop=0.15, corrupt=0.002, baud=115200, delay=0.002), seed=11)
    down = FaultyChannel(Faults(drop=0.15, corrupt=0.002, baud=115200, delay=0.002), seed=12)
    sim = LinkSim(session, board, up, down)
    session.set_joystick(Joystick(0, 0, 0, 0, 0))
    sent = []
    for k in range(60):  # a key press every 100 ms for 6 s
        sim.run_until(0.1 * (k + 1))
        sent.append(session.send_command(Op.TRIM_ROLL, 1 if k % 2 else -1, sim.now))
    sim.run_until(8.0)
    acked = {e.cmd_id for e in sim.of_type(CommandAcked)}
    assert not sim.of_type(CommandFailed)
    assert acked == set(sent)
    assert session.stats.command_retries > 10  # the loss was real and the retries did the work
    # Each command took effect exactly once on the board, although many arrived twice or more.
    assert len(board.executed) == 60
    assert len(board.commands) > 60
    assert not sim.of_type(LinkLost)


def test_loss_figure_matches_the_injected_drop_rate() -> None:
    session = LinkSession(0.0, stats_window=5.0)
    board = ScriptedBoard(heartbeat_period=0.1, filler_period=0.005)
    down = FaultyChannel(Faults(drop=0.08), seed=5)
    sim = LinkSim(session, board, FaultyChannel(), down)
    sim.run_until(20.0)
    st = session.stats
    injected = 100.0 * down.stats.frames_dropped / down.stats.frames_in
    assert 6.0 < injected < 10.0
    assert st.loss_pct_total == pytest.approx(injected, abs=0.3)  # counted from the sequence numbers
    assert st.loss_pct == pytest.approx(8.0, abs=2.5)  # the last 5 s
    assert st.frames_bad == 0


def test_corruption_shows_as_bad_frames_and_loss() -> None:
    session = LinkSession(0.0)
    board = ScriptedBoard(heartbeat_period=0.1, filler_period=0.005)
    down = FaultyChannel(Faults(corrupt=0.002), seed=6)
    sim = LinkSim(session, board, FaultyChannel(), down)
    sim.run_until(10.0)
    st = session.stats
    assert st.frames_bad > 0
    assert 0.5 < st.loss_pct_total < 10.0


def test_board_hang_is_a_lost_link_and_its_return_restores_it() -> None:
    session = LinkSession(0.0, link_timeout=0.5)
    board = ScriptedBoard(heartbeat_period=0.1)
    sim = LinkSim(session, board)
    sim.run_until(1.0)
    board.silent = True
    sim.run_until(1.45)
    assert not sim.of_type(LinkLost)
    sim.run_until(1.6)
    (lost,) = sim.of_type(LinkLost)
    assert session.stats.lost
    cmd = session.send_command(Op.MODE, 2, sim.now)
    sim.run_until(1.7)
    (failed,) = sim.of_type(CommandFailed)
    assert failed.cmd_id == cmd and failed.reason.startswith("link lost")
    board.silent = False
    sim.run_until(3.0)
    assert len(sim.of_type(LinkRestored)) == 1 and not session.stats.lost
    assert len(board.hellos) == 2  # the handshake was repeated after the outage


@settings(max_examples=25, deadline=None)
@given(
    seed=st.integers(0, 10_000),
    drop=st.floats(0.0, 0.4),
    corrupt=st.floats(0.0, 0.01),
    presses=st.lists(st.floats(0.0, 3.0), min_size=1, max_size=15),
)
def test_every_command_has_exactly_one_outcome_and_runs_at_most_once(
    seed: int, drop: float, corrupt: float, presses: list[float]
) -> None:
    session = LinkSession(0.0, command_timeout=0.05, command_retries=3)
    board = ScriptedBoard(heartbeat_period=0.05)
    faults = Faults(drop=drop, corrupt=corrupt, baud=115200, delay=0.001)
    sim = LinkSim(session, board, FaultyChannel(faults, seed=seed), FaultyChannel(faults, seed=seed + 1))
    ids: list[tuple[int, int]] = []
    for k, t in enumerate(sorted(presses)):
        sim.run_until(t)
        # Powers of two: presses merged into one command (STEP_OPS) still give an arg no other command has.
        ids.append((session.send_command(Op.TRIM_YAW, 1 << k, sim.now), 1 << k))
    sim.run_until(6.0)
    outcomes = [e.cmd_id for e in sim.events if isinstance(e, CommandAcked | CommandFailed)]
    assert sorted(outcomes) == sorted({i for i, _ in ids})  # one each: no command forgotten or doubled
    acked_args = {e.arg for e in sim.of_type(CommandAcked)}
    done = [c.arg for c in board.executed]
    assert len(done) == len(set(done))  # a retried command never ran twice
    assert acked_args <= set(done)  # an acknowledged command really ran
