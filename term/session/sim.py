"""The simulated board as a child process: ``SimBoard`` runs ``fcb-sim serve --pty`` (or ``--tcp 127.0.0.1:0``: the
link) and, if asked, its BLE radio and its instructor channel in a child, reads the port and the radio's and
instructor's addresses from the child's first lines, and stops it in order.

The link: a pseudo-terminal where there are pseudo-terminals (``pty_missing()`` is None), else a loopback TCP port
that term opens as pyserial's ``socket://`` URL with the same serial transport and codec (Windows, or a Python
without termios); ``link="tcp"`` asks for the port anywhere (``term --sim --sim-link tcp``).

``start()`` returns the port (a pty path or a socket:// URL) or raises ``UsageError`` with the child's last words
(one line); ``stop()`` ends the child (SIGTERM, then SIGKILL). ``transport(baud)`` is term's transport to it, which
names the child's death when the link fails because the child died (its exit status and the last line of its log),
never "check the cable" (issue 36). On Linux the child also dies with term, even when term is killed
(``PR_SET_PDEATHSIG``), and runs in its own session, so the terminal's Ctrl+C and SIGHUP go to term, which stops
it. The child's stdout is drained once it has spoken; its stderr goes to ``fcb-sim.log`` in term's log directory
(``log=True``) or to a temporary file. ``term --sim`` uses it (term/cli/main.py), and so do the tests and benches that
need a real board behind a real pty.
"""

from __future__ import annotations

import contextlib
import os
import signal
import subprocess
import sys
import tempfile
import threading
from collections.abc import Sequence
from typing import IO, Any

from term.core.errors import UsageError
from term.transports.base import Transport, TransportClosed, TransportError

__all__ = ["LINKS", "SIM_START_TIMEOUT", "SimBoard", "SimTransport", "pty_missing"]

SIM_START_TIMEOUT = 15.0  # s for the child board to print its pty
DEATH_WAIT_S = 1.0  # a link that failed: how long the child may take to be seen dead (its pty closes first)
LINKS = ("pty", "tcp")


def pty_missing() -> str | None:
    """Why the simulator cannot serve a pseudo-terminal here (one phrase), or None where it can."""
    if sys.platform == "win32":
        return "Windows has no pseudo-terminals"
    if not hasattr(os, "openpty"):
        return f"{sys.platform} has no os.openpty"
    try:
        import termios  # noqa: F401
        import tty  # noqa: F401
    except ImportError as exc:
        return f"this Python has no {exc.name or 'termios'}"
    return None


def _die_with_parent() -> None:
    """In the child, before exec: ask Linux to SIGTERM it when term dies, even by SIGKILL."""
    try:
        import ctypes

        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(1, signal.SIGTERM)  # PR_SET_PDEATHSIG
    except Exception:
        pass
    os.setsid()  # its own session: the terminal's Ctrl+C or SIGHUP goes to term, which stops it in order


def c_board_problem() -> str | None:
    """Why ``--board c`` cannot fly here, in one line (no C compiler, no sources), or None once it is built. This
    module is the one seam between the programs: no other module of term imports fcb_sim."""
    from fcb_sim.hosts.cboard import CBoardUnavailable, library_path

    try:
        library_path()
    except CBoardUnavailable as exc:
        return str(exc)
    return None


class SimBoard:
    """`fcb-sim serve --pty` (or ``--tcp``: ``link``, None for the platform's choice) in a child process;
    ``start()`` returns the pty path (the socket:// URL) it printed first. With
    ``radio`` the board's BLE radio is on the air too (``--ble-hci`` on a free local port): ``ble_address`` and
    ``ble_hci`` (the ``--hci`` to reach it) come from the child's second line. With ``log`` the child's stderr
    is appended to ``fcb-sim.log`` in term's log directory and kept (else a temporary file, gone at exit)."""

    def __init__(self, *, seed: int = 1, scenario: str | None = None, link_timeout: float | None = None,
                 extra: Sequence[str] = (), radio: bool = False, log: bool = False, instructor: bool = False,
                 link: str | None = None) -> None:
        if link is None:
            link = "tcp" if pty_missing() else "pty"
        if link not in LINKS:
            raise UsageError(f"--sim-link {link!r}: choose {' or '.join(LINKS)}")
        if link == "pty" and (why := pty_missing()):
            raise UsageError(f"--sim-link pty: {why}; use --sim-link tcp (the board on a loopback TCP port)")
        self.link = link
        # fcb-sim's entry, ended without the interpreter's teardown (fcb_sim/__main__.py): stop() waits for it
        self.cmd = [sys.executable, "-m", "fcb_sim",
                    "serve", *(["--pty"] if link == "pty" else ["--tcp", "127.0.0.1:0"]), "--seed", str(seed)]
        if scenario:
            self.cmd += ["--scenario", scenario]
        if link_timeout is not None:
            self.cmd += ["--link-timeout", str(link_timeout)]
        if radio:
            self.cmd += ["--ble-hci", "tcp-server:127.0.0.1:0"]
        if instructor:  # the truth and the lessons' situations (fcb_sim/hosts/instructor.py, lessons/instructor.py)
            self.cmd += ["--instructor", "tcp-server:127.0.0.1:0"]
        self.instructor = instructor
        self.instructor_address = ""
        self.cmd += list(extra)
        self.radio = radio
        self.port = ""
        self.ble_name = self.ble_address = self.ble_hci = ""
        self.proc: subprocess.Popen[bytes] | None = None
        self._stderr: IO[bytes] | None = None
        self._stderr_start = 0  # where this run's stderr begins in the file
        self.log = log

    def launch(self) -> None:
        """Start the child without waiting for it: the caller's own set-up runs while the board boots (on the
        other core); ``start`` then waits for its first lines."""
        self._stderr, self._stderr_start = None, 0
        if self.log:
            from term.session.applog import child_log

            self._stderr, self._stderr_start = child_log("fcb-sim.log")
        if self._stderr is None:
            self._stderr = tempfile.TemporaryFile()
        env = dict(os.environ, PYTHONUNBUFFERED="1")
        self.proc = subprocess.Popen(
            self.cmd, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE, stderr=self._stderr, env=env,
            preexec_fn=_die_with_parent if sys.platform.startswith("linux") else None,
        )

    def start(self, timeout: float = SIM_START_TIMEOUT) -> str:
        """The pty path, once the child has said it (launched here unless ``launch`` was called)."""
        if self.proc is None:
            self.launch()
        assert self.proc is not None
        line = _readline_with_timeout(self.proc, timeout)
        if not line.startswith(f"{self.link}: "):
            if not line:  # its stdout closed: let it exit, so its last words on stderr can be read
                # (generous: only this error path waits, and a loaded machine can take seconds to tear down)
                with contextlib.suppress(subprocess.TimeoutExpired):
                    self.proc.wait(15.0)
            why = self._child_error() or (line.strip() or "no output")
            self.stop()
            raise UsageError(f"the simulated board did not start: {why}")
        if self.radio:  # "ble: Quadrupel 1 F0:5A:00:00:00:01 hci tcp-client:127.0.0.1:PORT"
            words = _readline_with_timeout(self.proc, timeout).split()
            if len(words) < 6 or words[0] != "ble:" or words[-2] != "hci":
                why = self._child_error() or " ".join(words) or "no output"
                self.stop()
                raise UsageError(f"the simulated board's radio did not start: {why}")
            self.ble_name, self.ble_address, self.ble_hci = " ".join(words[1:-3]), words[-3], words[-1]
        if self.instructor:  # "instructor: tcp-client:127.0.0.1:PORT"
            words = _readline_with_timeout(self.proc, timeout).split()
            if len(words) != 2 or words[0] != "instructor:":
                why = self._child_error() or " ".join(words) or "no output"
                self.stop()
                raise UsageError(f"the simulated board's instructor channel did not start: {why}")
            self.instructor_address = words[1]
        self.port = line[len(f"{self.link}: "):].strip()
        # Drain its stdout from now on, so a chatty child never blocks on a full pipe.
        threading.Thread(target=_drain, args=(self.proc.stdout,), daemon=True).start()
        return self.port

    def transport(self, baud: int) -> SimTransport:
        """term's transport to the started board: the serial one over its pty or socket:// URL, naming the child's
        death (``SimTransport``)."""
        from term.session.links import LinkSpec, open_link

        return SimTransport(open_link(LinkSpec(port=self.port, baud=baud)), self)

    def death(self, wait: float = DEATH_WAIT_S) -> str | None:
        """One line if the child has died (waiting up to ``wait`` s for it): its exit status and the last line of
        its log; None while it runs."""
        proc = self.proc
        if proc is None:
            return None
        try:
            status = proc.wait(wait)
        except subprocess.TimeoutExpired:
            return None
        if status < 0:
            try:
                how = f"killed by {signal.Signals(-status).name}"
            except ValueError:
                how = f"killed by signal {-status}"
        else:
            how = f"exit status {status}"
        last = self._child_error()
        said = f"; its log's last line: {last}" if last else "; its log says nothing"
        return f"the simulated board stopped ({how}){said}; start term --sim again"

    def _child_error(self) -> str:
        if self._stderr is None:
            return ""
        with contextlib.suppress(Exception):
            if self.proc is not None and self.proc.poll() is None:
                return ""
            self._stderr.seek(self._stderr_start)
            lines = [ln for ln in self._stderr.read().decode(errors="replace").splitlines() if ln.strip()]
            last = lines[-1].strip() if lines else ""
            return last.removeprefix("fcb-sim: ")
        return ""

    def stop(self) -> None:
        proc = self.proc
        if proc is None:
            return
        if proc.poll() is None:
            proc.terminate()
            try:
                proc.wait(3.0)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait(3.0)
        if proc.stdout is not None:
            with contextlib.suppress(Exception):
                proc.stdout.close()
        if self._stderr is not None:
            self._stderr.close()
            self._stderr = None
        self.proc = None


class SimTransport(Transport):
    """The simulated board's link (``inner``, a SerialTransport) whose failures name the child's death: a read,
    write or open that fails while the child has exited raises ``SimBoard.death``'s line instead of the port's
    ("... lost: the device disconnected; check the cable"), so LINK LOST says what happened. Everything else is
    the inner transport's (taps and the link thread follow ``inner``)."""

    def __init__(self, inner: Transport, sim: SimBoard) -> None:
        self.inner = inner
        self.sim = sim

    @property
    def name(self) -> str:  # type: ignore[override]
        return self.inner.name

    def __getattr__(self, name: str) -> Any:
        return getattr(self.inner, name)

    async def _named(self, exc: TransportError) -> TransportError:
        import asyncio

        why = await asyncio.to_thread(self.sim.death)
        return TransportError(why) if why else exc

    async def open(self) -> None:
        try:
            await self.inner.open()
        except TransportClosed:
            raise
        except TransportError as exc:
            raise await self._named(exc) from None

    async def close(self) -> None:
        await self.inner.close()

    async def read(self) -> bytes:
        try:
            return await self.inner.read()
        except TransportClosed:
            raise
        except TransportError as exc:
            raise await self._named(exc) from None

    async def write(self, data: bytes) -> None:
        try:
            await self.inner.write(data)
        except TransportClosed:
            raise
        except TransportError as exc:
            raise await self._named(exc) from None


def _readline_with_timeout(proc: subprocess.Popen[bytes], timeout: float) -> str:
    result: list[bytes] = []

    def read() -> None:
        assert proc.stdout is not None
        result.append(proc.stdout.readline())

    t = threading.Thread(target=read, daemon=True)
    t.start()
    t.join(timeout)
    if not result:
        return ""
    return result[0].decode(errors="replace")


def _drain(stream: IO[bytes] | None) -> None:
    if stream is None:
        return
    with contextlib.suppress(Exception):
        while stream.read(4096):
            pass
