"""How term ends when it is told to from outside: a signal (SIGTERM, SIGHUP, SIGINT, Windows' SIGBREAK) or its
terminal going away. Both take Ctrl+Q's path while the motors run (PANIC first, then quit) with 128 + the signal's
number (SIGINT 130; a hang-up 129), through the running app's event loop (``_running``, set by term/cli/main.py);
a watchdog ends the process if that orderly exit hangs. The terminal watcher uses what each platform really reports
(``_hangup_check``: never POLLNVAL read as a hang-up; macOS's poll() cannot watch terminals)."""

from __future__ import annotations

import contextlib
import os
import select
import signal
import sys
import threading
from collections.abc import Callable
from typing import IO, TYPE_CHECKING, Any

if TYPE_CHECKING:
    import asyncio

# The app while it runs, and its loop: a signal asks it to exit through the loop.
_running: list[tuple[Any, asyncio.AbstractEventLoop]] = []
_watchdogs: list[threading.Timer] = []  # one a signal, cancelled once the orderly exit is done
SIGNAL_EXIT_GRACE_S = 5.0  # after a signal, the longest an orderly exit may take before term ends itself
# Windows' console events that end the process once the handlers return: CTRL_CLOSE_EVENT, LOGOFF, SHUTDOWN
CONSOLE_ENDS = (2, 5, 6)
CONSOLE_GRACE_S = 4.0  # the system ends the process 5 s after CTRL_CLOSE_EVENT (HandlerRoutine's documentation)
_exited = threading.Event()  # set once the orderly exit is done (a console handler waits for it)


@contextlib.contextmanager
def _terminate_on_signals() -> Any:
    """SIGTERM, SIGHUP (terminal closed), SIGINT and Windows' SIGBREAK end term in order, as Ctrl+Q does: PANIC
    first while the motors run, then quit with 128 + the signal's number (SIGINT 130), the child board stopped on
    the way out (issue 34: a signal in flight used to end term without the PANIC, and SIGINT with 0).

    While the app runs, the signal asks it to exit through its event loop (``_quit_in_order``): unwinding with
    SystemExit from inside the loop would skip Textual's own shutdown and leave its input thread spinning on a dead
    terminal, keeping the process alive. A watchdog ends the process if the orderly exit hangs (the child board
    then gets its own SIGTERM from the kernel, PR_SET_PDEATHSIG). Before the app runs (the board starting), SIGINT
    is KeyboardInterrupt (main's 130) and the others SystemExit."""
    def raise_exit(signum: int, frame: object) -> None:
        if not _request_exit(128 + signum):
            if signum == signal.SIGINT:
                raise KeyboardInterrupt
            raise SystemExit(128 + signum)

    old = {}
    # getattr: Windows has no SIGHUP (its console's close is _console_handler's) but has SIGBREAK (Ctrl+Break)
    names = ("SIGTERM", "SIGHUP", "SIGINT", "SIGBREAK")
    for sig in (getattr(signal, name) for name in names if hasattr(signal, name)):
        with contextlib.suppress(ValueError, OSError):
            old[sig] = signal.signal(sig, raise_exit)
    _exited.clear()
    console = _console_handler() if sys.platform == "win32" else None
    try:
        yield
    finally:
        _exited.set()
        if console is not None:
            console.remove()
        for sig, handler in old.items():
            with contextlib.suppress(ValueError, OSError, TypeError):
                signal.signal(sig, handler)
        for watchdog in _watchdogs:  # the orderly exit is done: nothing left to end
            watchdog.cancel()
        _watchdogs.clear()


class _ConsoleHandler:
    """Windows: the console window closed (or logoff, shutdown) takes the same orderly path as a hang-up (PANIC first
    in flight, 129). Python's signal module has no signal for these events: the C runtime maps them to SIGBREAK but
    only sets a flag, and the system ends the process when the handlers return (python/cpython #85470, #96289). So
    a console control handler asks the app to quit and holds the system's thread until the orderly exit is done, or
    CONSOLE_GRACE_S (inside the 5 s the system allows). Ctrl+C and Ctrl+Break go on to Python's own handler (SIGINT,
    SIGBREAK). ``kernel32`` is the Windows DLL (a stand-in in the tests)."""

    def __init__(self, kernel32: Any) -> None:
        import ctypes
        from ctypes import wintypes

        factory = getattr(ctypes, "WINFUNCTYPE", ctypes.CFUNCTYPE)
        prototype = factory(wintypes.BOOL, wintypes.DWORD)
        self.kernel32 = kernel32
        self.routine = prototype(self.handle)  # kept referenced: the system calls it from its own thread
        setter = kernel32.SetConsoleCtrlHandler
        setter.argtypes = (prototype, wintypes.BOOL)  # (a 64-bit pointer: without argtypes ctypes would cut it)
        setter.restype = wintypes.BOOL
        self.installed = bool(setter(self.routine, True))

    def handle(self, event: int) -> bool:
        if event not in CONSOLE_ENDS:
            return False  # the next handler's (Python's own, for Ctrl+C and Ctrl+Break)
        if _request_exit(128 + 1):  # as a hang-up
            _exited.wait(CONSOLE_GRACE_S)
        return True

    def remove(self) -> None:
        if self.installed:
            with contextlib.suppress(Exception):
                self.kernel32.SetConsoleCtrlHandler(self.routine, False)
            self.installed = False


def _console_handler() -> _ConsoleHandler | None:
    """The console handler installed (Windows), or None where it cannot be."""
    try:
        import ctypes

        return _ConsoleHandler(ctypes.windll.kernel32)  # type: ignore[attr-defined]
    except (ImportError, AttributeError, OSError):
        return None


def _end_now(code: int) -> None:
    """The watchdog's end: no clean-up left to wait for (a test replaces it, to see it was not needed)."""
    os._exit(code)


def _request_exit(code: int) -> bool:
    """Ask the running app to quit in order with ``code`` (False if none runs); end the process if that hangs."""
    if not _running:
        return False
    app, loop = _running[0]
    watchdog = threading.Timer(SIGNAL_EXIT_GRACE_S, _end_now, (code,))
    watchdog.daemon = True
    watchdog.start()
    _watchdogs.append(watchdog)
    # Through the app's own message queue, so the quitting runs in the app's context (its timers need it): a
    # signal's or a console handler's thread has none, and the loop's callbacks run in the caller's.
    loop.call_soon_threadsafe(app.call_later, _quit_in_order, app, code)
    return True


def _quit_in_order(app: Any, code: int) -> None:
    """Ctrl+Q's path without its question (term/ui/app.py, action_quit): in a flight mode PANIC goes first, is said
    in the events and on stderr after the screen, and has QUIT_PANIC_WAIT_S to reach the board; then the exit."""
    from term.core.protocol import FLIGHT_MODES, Mode, Op
    from term.ui.controllers.dialogs import QUIT_PANIC_WAIT_S

    if app.replay is None and app.model.mode in FLIGHT_MODES and app.control_connection() is not None:
        app.send(Op.MODE, Mode.PANIC)
        app.exit_message = "PANIC sent before quitting: the board descends and lands by itself"
        app.station.note("error", "term", app.exit_message)
        app.set_timer(QUIT_PANIC_WAIT_S, lambda: app.exit(return_code=code))
    else:
        app.exit(return_code=code)


async def _exit_on_hangup(stream: IO[str], period: float = 0.5) -> None:
    """Exit when the terminal goes away. Closing a terminal does not always signal us (a session leader that
    ignores SIGHUP does not pass it on), and Textual reads a hung-up terminal's EOF as piped input and keeps
    running. Where a terminal sends SIGHUP, ``_terminate_on_signals`` takes it; this watcher covers the rest with
    what each platform really reports (``_hangup_check``), looking every ``period`` seconds without taking input."""
    import asyncio  # (not at the top: 'term params --sim' starts its board before this)

    try:
        fd = stream.fileno()
    except (AttributeError, OSError, ValueError):
        return
    gone = _hangup_check(fd)
    if gone is None:
        return
    while True:
        await asyncio.sleep(period)
        if gone():
            _request_exit(128 + 1)  # as SIGHUP (1 on every POSIX system; Windows has none)
            return


def _hangup_check(fd: int) -> Callable[[], bool] | None:
    """A check that answers True once the terminal on ``fd`` has hung up; None where there is nothing to watch.

    - Linux, the BSDs: poll() reports POLLHUP (with POLLERR) for a hung-up tty, without taking any input.
    - macOS: poll() does not support devices and answers POLLNVAL for every terminal, healthy or not (poll(2)
      BUGS; termbox2 #31, fzf #4653, console-rs/console #169), and dirge-code/dirge #731 is this very watchdog
      ending every session with 129. So poll() is not used there, and POLLNVAL is never read as a hang-up
      anywhere: a kernel that answers it for this descriptor (macOS's, or one like it) is not polled again.
    - Everywhere with termios: a hung-up line fails the window-size ioctl with EIO (ENXIO for a device gone),
      which is what macOS reports where poll() cannot (dirge-code/dirge #731's probe; Linux: hung_up_tty_ioctl).
    - Windows: no tty and no termios: None. Closing the console window ends the process itself (the system's
      CTRL_CLOSE_EVENT); Ctrl+Break arrives as SIGBREAK (``_terminate_on_signals``)."""
    import errno

    try:
        import fcntl
        import termios
    except ImportError:
        return None
    if not os.isatty(fd):
        return None
    poller = None
    if sys.platform != "darwin" and hasattr(select, "poll"):
        poller = select.poll()
        poller.register(fd, 0)  # POLLHUP and POLLERR are reported whatever is asked for

    def gone() -> bool:
        nonlocal poller
        if poller is not None:
            events = [ev for _, ev in poller.poll(0)]
            if any(ev & (select.POLLHUP | select.POLLERR) for ev in events):
                return True
            if any(ev & select.POLLNVAL for ev in events):
                poller = None  # this kernel cannot poll the device (or the fd was closed): the ioctl alone
        try:
            fcntl.ioctl(fd, termios.TIOCGWINSZ, bytes(8))
        except OSError as exc:
            return exc.errno in (errno.EIO, errno.ENXIO)
        return False

    return gone
