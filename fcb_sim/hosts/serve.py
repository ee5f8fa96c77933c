"""`fcb-sim serve --pty | --tcp [HOST:]PORT`: the board in real time behind a fresh pseudo-terminal, or on a TCP port
for pyserial's ``socket://`` (fcb_sim/hosts/tcp_link.py: where there are no pseudo-terminals, Windows), and
optionally a BLE radio and the instructor channel.

The edge around the sans-IO ``Board``: it owns the wall clock and the file descriptors. The board's clock is
paced to the wall clock: the server sleeps until the board's next timer interrupt (or until bytes arrive), then
advances the board to the present, so every task runs at its board time as soon as the wall clock reaches it.
A pseudo-terminal from ``os.openpty`` (both sides raw at once) is a real serial device: ``term --serial PATH``
or any pyserial program talks to it. The first line on stdout is ``pty: /dev/pts/N`` (flushed), or
``tcp: socket://127.0.0.1:PORT`` for the TCP link. ``BoardServer`` is the loop; ``PtyServer`` and ``TcpServer``
give it the bytes' way in and out.

A starved process (a busy laptop: no CPU for a while) keeps the link's time honest: at each wake-up the board is
told how long it could not run (``Board.starved``), so its link timer does not count the simulator's own stall as
the PC's silence (the PC's frames waited in the pty meanwhile), and it says how far it ran behind real time (event
SIM_LAG, at most once a second); the frames that waited are parsed as soon as the board has caught up. Behind by
more than MAX_LAG_S it slips instead of replaying the stall (the world pauses; ``PacingStats.slips``).

Robustness: reads are bounded per wake-up and the board's receive queue is bounded (a flood is dropped and
counted, never queued without end); garbage and half frames only cost the decoder a resync; a client that stops
reading cannot block the board (writes are non-blocking, and what does not fit waits in a bounded buffer).
SIGTERM and SIGINT end the loop cleanly (exit status 0). POSIX-only modules (termios, tty) are imported where the
pty is made, so serve --tcp runs without them.
"""

from __future__ import annotations

import asyncio
import contextlib
import os
import selectors
import signal
import sys
import threading
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from fcb_sim.board.board import Board, BoardConfig
from fcb_sim.errors import UsageError
from fcb_sim.world.physics import World
from term.core.protocol import LINK_TIMEOUT_RANGE_S, LINK_TIMEOUT_S, ROOM_CEILING_M, ROOM_HALF_M

READ_BYTES = 4096  # per wake-up
PENDING_TX_LIMIT = 16384  # bytes kept for a client that does not read; older ones are dropped
MAX_LAG_S = 0.5  # further behind the wall clock than this (a suspended process): slip instead of catching up
MAX_SLEEP_S = 0.01
PACING_KEEP = 20_000  # control steps kept for bench/pacing.py (its runs are seconds long)
STARVED_S = 0.05  # a wake-up this late: the process was starved (a tenth of the link timeout), not merely woken late


@dataclass(frozen=True)
class ServeScenario:
    doc: str
    world: dict[str, Any] = field(default_factory=dict)
    wind: tuple[float, float, float] = (0.0, 0.0, 0.0)
    gust_std: float = 0.0


SCENARIOS: dict[str, ServeScenario] = {
    "bench": ServeScenario("on the floor, still air, battery charged (default)"),
    "breeze": ServeScenario("a 1.5 m/s breeze from the north with light gusts", wind=(-1.5, 0.0, 0.0),
                            gust_std=0.5),
    "gusty": ServeScenario("3 m/s wind with strong gusts", wind=(-3.0, 1.0, 0.0), gust_std=1.5),
    "low-battery": ServeScenario("a nearly flat battery: it sags under 10.5 V when the motors pull",
                                 world={"soc": 0.06}),
    "no-spikes": ServeScenario("still air and a barometer without pressure spikes", world={"baro_spikes": False}),
}


def check_link_timeout(seconds: float) -> None:
    """--link-timeout within the board's link.timeout_ms range (nan is outside it), else a UsageError."""
    lo, hi = LINK_TIMEOUT_RANGE_S
    if not (lo <= seconds <= hi):
        raise UsageError(f"--link-timeout must be between {lo:g} and {hi:g} s, got {seconds:g}")


def make_board(seed: int = 1, scenario: str = "bench", link_timeout: float = LINK_TIMEOUT_S, board: str = "python",
               **config: Any) -> Board:
    """A board in its world for a serve scenario; UsageError for an unknown scenario or a bad timeout. ``board``
    "c" is the C board (firmware/board/, fcb_sim/hosts/cboard.py) in the same world."""
    sc = SCENARIOS.get(scenario)
    if sc is None:
        raise UsageError(f"unknown scenario {scenario!r}; choose one of: {', '.join(SCENARIOS)}")
    check_link_timeout(link_timeout)
    world = World(seed, room=(ROOM_HALF_M, ROOM_CEILING_M), **sc.world)  # the lab's walls, as term --sim draws them
    if sc.wind != (0.0, 0.0, 0.0) or sc.gust_std:
        world.set_wind(*sc.wind, gust_std=sc.gust_std)
    if board == "c":
        from fcb_sim.hosts.cboard import CBoard

        return CBoard(BoardConfig(seed=seed, link_timeout_s=link_timeout, **config), world=world)  # type: ignore
    return Board(BoardConfig(seed=seed, link_timeout_s=link_timeout, **config), world=world)


def open_pty() -> tuple[int, int, str]:
    """A fresh pseudo-terminal, both sides raw at once; the master non-blocking. Returns (master, slave, path).
    The slave stays open here so the master never sees a hang-up between clients. UsageError (one line) where
    there are no pseudo-terminals."""
    try:
        if not hasattr(os, "openpty"):
            raise ImportError("os.openpty")
        import termios
        import tty
    except ImportError:
        raise UsageError(f"serve --pty needs pseudo-terminals, which {sys.platform} has not: serve the board with "
                         "--tcp 127.0.0.1:PORT and fly it with term --serial socket://127.0.0.1:PORT") from None
    master, slave = os.openpty()
    for fd in (master, slave):
        tty.setraw(fd, termios.TCSANOW)
    os.set_blocking(master, False)
    return master, slave, os.ttyname(slave)


@dataclass
class PacingStats:
    """How late each control step ran against the wall clock (for bench/pacing.py): the latest ``PACING_KEEP``
    steps (100 s), so a long flight's memory stays flat (200,000 of each grew 9 MB over 17 minutes, issue 36)."""

    lateness_us: deque[float] = field(default_factory=lambda: deque(maxlen=PACING_KEEP))
    wall_periods_us: deque[float] = field(default_factory=lambda: deque(maxlen=PACING_KEEP))
    slips: int = 0
    wakeups: int = 0
    _last_wall: float | None = None

    def control_ran(self, board_start_us: int, wall_us: float) -> None:
        self.lateness_us.append(wall_us - board_start_us)
        if self._last_wall is not None:
            self.wall_periods_us.append(wall_us - self._last_wall)
        self._last_wall = wall_us


class BoardServer:
    """Serves one ``Board`` in real time over a byte link a subclass gives: ``_link_start``/``_link_stop`` (the
    loop's readers), ``_recv`` (bytes that arrived, or None) and ``_send`` (how many bytes the link took)."""

    path = ""  # what a client opens: the pty's path, or the socket:// URL

    def __init__(self, board: Board, *, clock: Callable[[], float] = time.monotonic) -> None:
        self.board = board
        self.clock = clock
        self.pacing = PacingStats()
        self.tx_dropped = 0
        self.bytes_in = 0
        self.bytes_out = 0
        self._pending = bytearray()
        self._waiter: asyncio.Future[None] | None = None
        self._batch: list[int] = []  # control steps run by the current advance
        self._stop: asyncio.Event | None = None
        self._t0 = clock() - board.now / 1e6
        self.closed = False
        self.cable_open: Callable[[], bool] | None = None  # the instructor's cable cuts (fcb_sim/hosts/instructor.py)

    # --- the loop -----------------------------------------------------------------------------------------

    async def serve(self, stop: asyncio.Event | None = None) -> None:
        """Run until ``stop`` is set (or ``request_stop()``)."""
        loop = asyncio.get_running_loop()
        self._stop = stop or asyncio.Event()
        board = self.board
        board.on_task = self._on_task
        self._t0 = self.clock() - board.now / 1e6
        self._link_start(loop)
        stop_waiter = asyncio.ensure_future(self._stop.wait())
        stop_waiter.add_done_callback(lambda _f: self._wake_up())
        try:
            while not self._stop.is_set():
                self._step()
                # sleep until the board's next timer interrupt (bytes arriving wake us earlier)
                wait = (board.next_event_us() - self._wall_us()) / 1e6
                if self._pending:
                    wait = min(wait, 0.002)
                wait = min(MAX_SLEEP_S, wait)
                if wait > 0:
                    fut = loop.create_future()
                    self._waiter = fut
                    handle = loop.call_later(wait, self._wake_up)
                    await fut
                    handle.cancel()
                    self._waiter = None
                else:
                    await asyncio.sleep(0)
        finally:
            stop_waiter.cancel()
            self._link_stop(loop)
            board.on_task = None

    def _wake_up(self) -> None:
        fut = self._waiter
        if fut is not None and not fut.done():
            fut.set_result(None)

    def _on_task(self, name: str, start: int, dur: int) -> None:
        if name == "control":
            self._batch.append(start)

    def request_stop(self) -> None:
        if self._stop is not None:
            self._stop.set()

    def _wall_us(self) -> float:
        return (self.clock() - self._t0) * 1e6

    def _catch_up(self) -> None:
        """Bring the board to the wall clock's present; a starved wake-up is not link silence (module docstring)."""
        board = self.board
        # the C board (fcb_sim/hosts/cboard.py) has no link-timer credit yet: it counts a stall as silence, unreported
        starved = getattr(board, "starved", None)
        wall = self._wall_us()
        if wall - board.now > MAX_LAG_S * 1e6:
            self.pacing.slips += 1  # we were not scheduled for a long time: do not replay it in a burst
            if starved is not None:
                starved(int(wall), slip=True)  # said as SIM_LAG; the stall's board time never passes
            self._t0 = self.clock() - board.now / 1e6
            wall = float(board.now)
        elif wall - board.now > STARVED_S * 1e6 and starved is not None:
            starved(int(wall))
        board.advance(int(wall))

    def _step(self) -> None:
        board = self.board
        self.pacing.wakeups += 1
        self._catch_up()
        done = self._wall_us()
        for start in self._batch:
            self.pacing.control_ran(start, done)
        self._batch.clear()
        out = board.uart_transmit()
        if self.cable_open is not None and not self.cable_open():
            out = b""  # the instructor cut the cable: what the board sent is lost
        self._write(out)

    # --- the link (a subclass's) ---------------------------------------------------------------------------

    def _link_start(self, loop: asyncio.AbstractEventLoop) -> None:
        raise NotImplementedError

    def _link_stop(self, loop: asyncio.AbstractEventLoop) -> None:
        raise NotImplementedError

    def _recv(self) -> bytes | None:
        raise NotImplementedError

    def _send(self, data: bytes | bytearray) -> int:
        raise NotImplementedError

    def _on_readable(self) -> None:
        data = self._recv()
        if data:
            if self.cable_open is not None and not self.cable_open():
                return  # the instructor cut the cable: the bytes are lost
            self.bytes_in += len(data)
            # bytes arrive at the present: bring the board up to now first, so they are not dated in the past
            self._catch_up()
            self.board.uart_receive(data)
            self._wake_up()

    def _write(self, data: bytes) -> None:
        if data:
            self._pending += data
        if not self._pending:
            return
        n = self._send(self._pending)
        self.bytes_out += n
        del self._pending[:n]
        if len(self._pending) > PENDING_TX_LIMIT:
            drop = len(self._pending) - PENDING_TX_LIMIT
            del self._pending[:drop]
            self.tx_dropped += drop

    def close(self) -> None:
        self.closed = True


class PtyServer(BoardServer):
    """Serves one ``Board`` on a fresh pseudo-terminal in real time (``path``: its slave side)."""

    def __init__(self, board: Board, *, clock: Callable[[], float] = time.monotonic) -> None:
        super().__init__(board, clock=clock)
        self.master, self.slave, self.path = open_pty()

    def _link_start(self, loop: asyncio.AbstractEventLoop) -> None:
        loop.add_reader(self.master, self._on_readable)

    def _link_stop(self, loop: asyncio.AbstractEventLoop) -> None:
        loop.remove_reader(self.master)

    def _recv(self) -> bytes | None:
        try:
            return os.read(self.master, READ_BYTES)
        except (BlockingIOError, InterruptedError):
            return None
        except OSError:
            return None  # EIO: no client at the moment

    def _send(self, data: bytes | bytearray) -> int:
        try:
            return os.write(self.master, data)
        except (BlockingIOError, InterruptedError):
            return 0
        except OSError:
            return len(data)  # nobody there: the bytes are gone, as on a real unplugged UART

    def close(self) -> None:
        if self.closed:
            return
        self.closed = True
        for fd in (self.master, self.slave):
            with contextlib.suppress(OSError):
                os.close(fd)


class TcpServer(BoardServer):
    """Serves one ``Board`` on a TCP port in real time for pyserial's socket:// (fcb_sim/hosts/tcp_link.py: one
    client at a time, loopback unless ``public``); ``path`` is the URL, ``refused`` the connections closed at once."""

    def __init__(self, board: Board, host: str = "127.0.0.1", port: int = 0, *, public: bool = False,
                 clock: Callable[[], float] = time.monotonic) -> None:
        from fcb_sim.hosts.tcp_link import TcpLink

        super().__init__(board, clock=clock)
        self.link = TcpLink(host, port, public=public, read_bytes=READ_BYTES)
        self.path = self.link.path

    @property
    def client(self) -> object:
        return self.link.client

    @property
    def refused(self) -> int:
        return self.link.refused

    def _link_start(self, loop: asyncio.AbstractEventLoop) -> None:
        self.link.start(loop, self._on_readable, self._pending.clear)  # a new client: nothing stale for it

    def _link_stop(self, loop: asyncio.AbstractEventLoop) -> None:
        self.link.stop(loop)

    def _recv(self) -> bytes | None:
        return self.link.recv()

    def _send(self, data: bytes | bytearray) -> int:
        return self.link.send(data)

    def close(self) -> None:
        self.closed = True
        self.link.close()


def event_loop() -> asyncio.AbstractEventLoop:
    """An event loop whose sleeps have microsecond resolution: epoll rounds every timeout up to a whole
    millisecond, select() does not, and the board's tasks are due every 2.5 ms. select() is also the one that
    watches a pty on macOS (its poll() does not support devices, and kqueue took terminals only recently) and
    sockets on Windows. Its price: descriptors at or above FD_SETSIZE cannot be watched, so no server here ever
    registers one (fcb_sim/hosts/tcp_link.py refuses such a connection)."""
    return asyncio.SelectorEventLoop(selectors.SelectSelector())


class ThreadedServer:
    """A ``PtyServer`` (or, with ``link="tcp"``, a ``TcpServer`` on a free loopback port) on its own thread and
    event loop (tests, benchmarks): ``start()`` returns the pty path (the socket:// URL), ``stop()`` ends it."""

    def __init__(self, board: Board, *, link: str = "pty") -> None:
        self.server: BoardServer = TcpServer(board) if link == "tcp" else PtyServer(board)
        self._loop: asyncio.AbstractEventLoop | None = None
        self._stop: asyncio.Event | None = None
        self._thread: threading.Thread | None = None
        self._ready = threading.Event()
        self.error: BaseException | None = None

    @property
    def path(self) -> str:
        return self.server.path

    def start(self) -> str:
        self._thread = threading.Thread(target=self._run, name="fcb-sim serve", daemon=True)
        self._thread.start()
        self._ready.wait(5.0)
        return self.server.path

    def _run(self) -> None:
        async def main() -> None:
            self._loop = asyncio.get_running_loop()
            self._stop = asyncio.Event()
            self._ready.set()
            await self.server.serve(self._stop)

        try:
            with asyncio.Runner(loop_factory=event_loop) as runner:
                runner.run(main())
        except BaseException as exc:  # surfaced to the test through .error
            self.error = exc

    def stop(self) -> None:
        if self._loop is not None and self._stop is not None:
            with contextlib.suppress(RuntimeError):
                self._loop.call_soon_threadsafe(self._stop.set)
        if self._thread is not None:
            self._thread.join(5.0)
        self.server.close()


async def _serve_main(args: Any) -> int:
    kind = getattr(args, "board", "python")
    if kind == "c" and getattr(args, "ble_hci", None):
        raise UsageError("the C board has no BLE radio yet: serve it without --ble-hci")
    board = make_board(args.seed, args.scenario, args.link_timeout, board=kind,
                       preset=getattr(args, "preset", "default"))
    server = _link_server(args, board)
    stop = asyncio.Event()
    loop = asyncio.get_running_loop()
    if sys.platform != "win32":  # (Windows' loops have no add_signal_handler: cmd_serve's handlers end us there)
        for sig in (signal.SIGTERM, signal.SIGINT):
            loop.add_signal_handler(sig, stop.set)
    radio = instructor = None
    try:
        print(f"{'pty' if isinstance(server, PtyServer) else 'tcp'}: {server.path}", flush=True)
        if getattr(args, "ble_hci", None):
            from fcb_sim.hosts.radio import start_radio

            radio = await start_radio(board.wireless, board_id=board.config.board_id, hci=args.ble_hci,
                                      on_data=board.ble_data, on_disconnect=board.ble_lost)
            spec = getattr(getattr(radio, "hci", None), "client_spec", None)
            print(f"ble: {radio.name} {radio.address}" + (f" hci {spec}" if spec else ""), flush=True)
        if getattr(args, "instructor", None):  # term --sim's truth and situations (fcb_sim/hosts/instructor.py)
            from fcb_sim.hosts.instructor import Instructor, InstructorServer

            instructor = InstructorServer(Instructor(board), radio=radio)
            address = await instructor.start(args.instructor, public=getattr(args, "instructor_public", False))
            server.cable_open = lambda: instructor.instructor.cable_open(board.now / 1e6)
            print(f"instructor: {address}", flush=True)
        await server.serve(stop)
    finally:
        if instructor is not None:
            with contextlib.suppress(Exception):
                await instructor.close()
        if radio is not None:
            with contextlib.suppress(Exception):
                await radio.close()
        server.close()
    p = server.pacing
    refused = getattr(server, "refused", 0)
    print(f"served {board.now / 1e6:.1f} s: mode {board.mode.name}, {server.bytes_in} bytes in, "
          f"{server.bytes_out} out, {board.rx_overflow} dropped by a full receive queue, {p.slips} slips"
          + (f", {refused} connections refused" if refused else ""), flush=True)
    return 0


def _link_server(args: Any, board: Board) -> BoardServer:
    """The board's UART: a fresh pty (--pty), or a TCP port for socket:// (--tcp, fcb_sim/hosts/tcp_link.py)."""
    if getattr(args, "tcp", None) is not None:
        from fcb_sim.hosts.tcp_link import parse_address

        host, port = parse_address(args.tcp)
        return TcpServer(board, host, port, public=getattr(args, "tcp_public", False))
    return PtyServer(board)


def cmd_serve(args: Any) -> int:
    """``fcb-sim serve --pty|--tcp [HOST:]PORT [--tcp-public] [--seed N] [--scenario NAME] [--link-timeout S]
    [--ble-hci TRANSPORT] [--instructor TRANSPORT [--instructor-public]]``."""
    tcp = getattr(args, "tcp", None)
    if args.pty == (tcp is not None):
        raise UsageError("say where to serve the board: --pty (a fresh pseudo-terminal) or --tcp [HOST:]PORT "
                         "(for pyserial's socket://, where there are no pseudo-terminals)")
    if getattr(args, "tcp_public", False) and tcp is None:
        raise UsageError("--tcp-public needs --tcp [HOST:]PORT")
    if args.scenario not in SCENARIOS:
        raise UsageError(f"unknown scenario {args.scenario!r}; choose one of: {', '.join(SCENARIOS)}")
    check_link_timeout(args.link_timeout)
    # SIGTERM before the loop's own handler is in place (starting the radio, the instructor) ends us as Ctrl+C
    # does: cleanly, status 0; the loop then sets its stop event for either signal.
    previous = signal.signal(signal.SIGTERM, _interrupt)
    try:
        with asyncio.Runner(loop_factory=event_loop) as runner:
            return runner.run(_serve_main(args))
    except KeyboardInterrupt:
        return 0
    finally:
        signal.signal(signal.SIGTERM, previous)
        sys.stdout.flush()


def _interrupt(signum: int, frame: Any) -> None:
    raise KeyboardInterrupt
