"""A macOS-shaped Python on Linux (tests/platform): put this folder first on PYTHONPATH of a child process.

What it changes, as macOS has it: ``sys.platform`` is "darwin", and ``select.poll()`` answers POLLNVAL for a
terminal device at once, whatever it is asked (macOS poll(2), BUGS: "The poll() system call currently does not
support devices"; seen by termbox2 #31, fzf #4653, console-rs/console #169). Every other descriptor is polled for
real. Each look at the terminal on stdin (a poll() that had it, an ioctl TIOCGWINSZ on it) adds a dot to the
file named by $SHAPE_PROBES, so a test can wait for a number of looks instead of for a time.

What it cannot show: the rest of macOS (its kqueue, its pty driver, its signals, CoreBluetooth, its paths beyond
what platformdirs derives from sys.platform); the kernel below is still Linux's.
"""

import os
import select
import sys

_PROBES = os.environ.get("SHAPE_PROBES")


def _looked() -> None:
    if _PROBES:
        with open(_PROBES, "a") as f:
            f.write(".")


class _MacPoll:
    """select.poll as macOS's: terminals (a tty when registered) answer POLLNVAL at once."""

    def __init__(self) -> None:
        self._real = _real_poll()
        self._ttys: set[int] = set()

    def register(self, fd: object, mask: int = select.POLLIN | select.POLLPRI | select.POLLOUT) -> None:
        n = fd if isinstance(fd, int) else fd.fileno()  # type: ignore[attr-defined]
        if os.isatty(n):
            self._ttys.add(n)
        else:
            self._real.register(n, mask)

    def modify(self, fd: object, mask: int) -> None:
        n = fd if isinstance(fd, int) else fd.fileno()  # type: ignore[attr-defined]
        if n not in self._ttys:
            self._real.modify(n, mask)

    def unregister(self, fd: object) -> None:
        n = fd if isinstance(fd, int) else fd.fileno()  # type: ignore[attr-defined]
        if n in self._ttys:
            self._ttys.discard(n)
        else:
            self._real.unregister(n)

    def poll(self, timeout: float | None = None) -> list[tuple[int, int]]:
        if self._ttys:
            if 0 in self._ttys:
                _looked()
            return [(n, select.POLLNVAL) for n in sorted(self._ttys)] + self._real.poll(0)
        return self._real.poll(timeout)


_real_poll = select.poll
select.poll = _MacPoll  # type: ignore[assignment,misc]

import fcntl  # noqa: E402  (after the poll: this file is the whole shape)
import termios  # noqa: E402

_real_ioctl = fcntl.ioctl


def _ioctl(fd: object, request: int, *args: object) -> object:
    if request == termios.TIOCGWINSZ and fd == 0:
        _looked()
    return _real_ioctl(fd, request, *args)  # type: ignore[arg-type]


fcntl.ioctl = _ioctl  # type: ignore[assignment]
sys.platform = "darwin"
