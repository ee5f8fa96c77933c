"""The link on its own thread (term/session/link_thread.py) under the station: a display that blocks its loop does
not starve the board (heartbeat answers keep going and nothing is declared lost), a display frozen past the
watchdog's bound stops the answers on purpose and says so afterwards, an exception in the link path on that
thread is LINK LOST with its cause and a reconnect, and events reach the model in order on the display's thread.

The board is the scripted board of conftest.py on a real pseudo-terminal, run on a thread of its own (a
``LinkThread`` hosting its loop), so blocking the test's loop blocks only the display. Waits are on conditions,
with generous bounds; the watchdog's clock is injected."""

from __future__ import annotations

import asyncio
import threading
import time
from collections.abc import AsyncIterator, Callable
from contextlib import asynccontextmanager

import pytest

from term.core.events import LinkDown, StationEvent
from term.core.link import LinkLost
from term.core.protocol import Attitude, Mode, Op
from term.session.link_thread import FrontDoor, LinkThread, movable
from term.session.model import Model
from term.session.station import Station
from term.transports.loopback import FaultyTransport, loopback_pair
from term.transports.serial import SerialTransport
from tests.conftest import PtyBoard
from tests.support.waits import until


@asynccontextmanager
async def linked(pty_pair, scripted_board, runner: LinkThread,  # noqa: ANN001
                 on_event: Callable[[StationEvent], None] | None = None,
                 opened_first: bool = False) -> AsyncIterator[tuple[Station, object]]:
    master, path = pty_pair
    board_thread = LinkThread(name="test board")  # the board's own loop, apart from the display's
    board_thread.start()
    board = scripted_board(start=time.monotonic())
    peer = PtyBoard(master, board, time.monotonic)
    await board_thread.run(peer.start())
    cable = SerialTransport(path)
    if opened_first:  # as term's command line does, to fail in one line before the screen starts
        await cable.open()
    st = Station(Model(start=time.monotonic()), cable=cable,
                 cable_session={"link_timeout": 0.5}, on_event=on_event, runner=runner)

    async def render_tick() -> None:  # the display's sign of life, as the app's render tick
        while True:
            st.sample()
            await asyncio.sleep(0.08)

    ticking = asyncio.create_task(render_tick()) if runner.clock is time.monotonic else None
    try:
        await st.start()
        await until(lambda: board.hellos and len(board.hb_acks) >= 2)
        yield st, board
    finally:
        if ticking is not None:
            ticking.cancel()
        await st.shutdown()
        await board_thread.run(peer.stop())
        board_thread.stop()


@pytest.mark.parametrize("opened_first", [False, True])
async def test_a_blocked_display_does_not_starve_the_board(pty_pair, scripted_board, opened_first: bool) -> None:  # noqa: ANN001
    """``opened_first``: the cable was opened on the display's loop (term's command line checks it before the
    screen starts); its reader then handed the bytes to the display's loop, which a blocked display never ran."""
    async with linked(pty_pair, scripted_board, LinkThread(), opened_first=opened_first) as (st, board):
        n = len(board.hb_acks)
        time.sleep(1.0)  # the display's loop is busy (a slow widget, a big export): it does nothing else meanwhile
        assert len(board.hb_acks) >= n + 3  # the board heard its heartbeats answered all the while (every 0.1 s)
        await until(lambda: len(board.hb_acks) >= n + 12)
        assert not any(type(e.event) is LinkLost for e in st.model.events if hasattr(e, "event"))
        assert not st.model.link_lost
        assert not any(e.text.startswith("LINK LOST") for e in st.model.events)


async def test_events_reach_the_model_on_the_displays_thread_in_order(pty_pair, scripted_board) -> None:  # noqa: ANN001
    seen: list[tuple[str, bool]] = []
    display = threading.current_thread()

    def front_end(ev: StationEvent) -> None:
        seen.append((type(ev).__name__, threading.current_thread() is display))

    async with linked(pty_pair, scripted_board, LinkThread(), front_end) as (st, board):
        assert st.send(Op.PARAM_LIST) is not None  # from the display's thread, into the link's session
        await until(lambda: any(c.op == Op.PARAM_LIST for c in board.executed))
        await until(lambda: any(name == "FromLink" for name, _ in seen[3:]))
    assert all(here for _, here in seen)
    assert seen[0][0] == "LinkUp"


async def test_a_frozen_display_stops_the_answers_on_purpose_and_says_why(pty_pair, scripted_board) -> None:  # noqa: ANN001
    wall = [0.0]
    runner = LinkThread(freeze_s=1.5, clock=lambda: wall[0])
    async with linked(pty_pair, scripted_board, runner) as (st, board):
        st.model.apply_packet(Attitude(int(Mode.FULL), 0, 0, 0, 0, 0, 0), time.monotonic())  # flying: armed
        wall[0] = 1.0
        n = len(board.hb_acks)
        await until(lambda: len(board.hb_acks) >= n + 3)  # the display's loop beats: still fed
        seen: dict[str, int] = {}
        released = threading.Event()

        def meanwhile() -> None:  # on another thread, while the display's loop is frozen below
            wall[0] = 3.0  # 2 s since the display's last beat: the pilot is blind
            time.sleep(0.05)  # (one answer may already be on its way)
            acks, sent = len(board.hb_acks), board._counter
            while board._counter < sent + 5:  # five more heartbeats from the board...
                time.sleep(0.01)
            seen["answered"] = len(board.hb_acks) - acks
            released.set()

        helper = threading.Thread(target=meanwhile)
        helper.start()
        released.wait(30.0)  # the display's loop is frozen until the helper has seen enough
        helper.join()
        assert seen["answered"] <= 1  # ...and none answered
        n = len(board.hb_acks)
        await until(lambda: len(board.hb_acks) > n + 2)  # the display beats again: the board is fed again
        await until(lambda: any("display was frozen for" in e.text for e in st.model.events))


async def test_a_frozen_display_in_safe_keeps_the_board_fed(pty_pair, scripted_board) -> None:  # noqa: ANN001
    """The watchdog acts only while the board flies: in SAFE a silence lands nothing, it would only be a false
    alarm (a start-up's first frames on a busy machine took the display past the bound)."""
    wall = [0.0]
    async with linked(pty_pair, scripted_board, LinkThread(freeze_s=1.5, clock=lambda: wall[0])) as (st, board):
        seen: dict[str, int] = {}
        released = threading.Event()

        def meanwhile() -> None:  # on another thread, while the display's loop is frozen below
            wall[0] = 3.0  # 3 s since the display's last beat, the board in SAFE (it never said otherwise)
            acks, sent = len(board.hb_acks), board._counter
            while board._counter < sent + 5:
                time.sleep(0.01)
            time.sleep(0.05)  # (the last answer on its way)
            seen["answered"] = len(board.hb_acks) - acks
            released.set()

        helper = threading.Thread(target=meanwhile)
        helper.start()
        released.wait(30.0)
        helper.join()
        assert seen["answered"] >= 4
        assert not any("display was frozen" in e.text for e in st.model.events)


async def test_an_exception_on_the_link_thread_is_link_lost_and_the_link_comes_back(
        pty_pair, scripted_board) -> None:  # noqa: ANN001
    seen: list[StationEvent] = []
    async with linked(pty_pair, scripted_board, LinkThread(), seen.append) as (st, board):
        conn = st.cable_connection
        assert conn is not None

        def broken(data: bytes, now: float) -> list:
            raise OverflowError("cannot convert float infinity to integer")

        conn.session.receive = broken  # type: ignore[method-assign]  (the next bytes from the board blow up)
        await until(lambda: any(type(e) is LinkDown for e in seen))
        assert any(e.text.startswith("LINK LOST: link error: OverflowError") for e in st.model.events)
        await until(lambda: st.cable_connection is not None and st.cable_connection is not conn)
        n = len(board.hb_acks)
        await until(lambda: len(board.hb_acks) > n + 2)
        assert any(e.text.startswith("reconnected") for e in st.model.events)


def test_only_real_transports_move_to_the_link_thread() -> None:
    pair = loopback_pair()
    assert not movable(pair.a) and not movable(None)
    assert movable(SerialTransport("/dev/null"))
    assert movable(FaultyTransport(SerialTransport("/dev/null")))


async def test_the_front_door_batches_in_order_and_survives_a_failing_reaction() -> None:
    door = FrontDoor(asyncio.get_running_loop())
    got: list[int] = []

    def take(i: int) -> None:
        if i == 3:
            raise ValueError("a reaction that fails")
        got.append(i)

    t = threading.Thread(target=lambda: [door.post(take, i) for i in range(10)])
    t.start()
    t.join()
    await until(lambda: len(got) == 9)
    assert got == [0, 1, 2, 4, 5, 6, 7, 8, 9]
