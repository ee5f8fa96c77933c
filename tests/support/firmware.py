"""The C side under test: build firmware/ once per test session, drive the C codec runner over pipes, run the
reference board on a pseudo-terminal. Used by tests/test_firmware*.py.

``build()`` runs `make -C firmware BUILD=<temporary dir> all` once (cached): the library, the reference board and
the codec runner, each compiled twice with `-std=c99 -Wall -Wextra -Werror` (plain -O2, and ASan + UBSan with
every finding fatal). Under pytest the folder is the run's (tests/conftest.py makes it and removes it), so the
workers of ``make test`` build once between them. Without a C compiler every test that needs it is skipped, all
with the same one line.
"""

from __future__ import annotations

import atexit
import contextlib
import functools
import os
import select
import shutil
import signal
import subprocess
import tempfile
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest

from fcb_sim import cbuild
from term.core import protocol as p

ROOT = Path(__file__).resolve().parents[2]
FIRMWARE = ROOT / "firmware"
NO_CC = "no C compiler (cc) or make: the firmware tests are skipped"
NO_ARM = "arm-none-eabi-gcc not installed: the Cortex-M0 build is skipped (apt-get install gcc-arm-none-eabi)"
# Sanitizer findings end the process with an error (UBSan too: -fno-sanitize-recover=all in the Makefile).
SAN_ENV = {**os.environ, "ASAN_OPTIONS": "abort_on_error=0:exitcode=86", "UBSAN_OPTIONS": "print_stacktrace=1"}


@dataclass(frozen=True)
class Build:
    dir: Path

    def path(self, name: str, sanitized: bool = True) -> Path:
        return self.dir / "san" / name if sanitized else self.dir / name


SHARED_BUILD_ENV = "QUADRUPEL_TEST_FIRMWARE_BUILD"  # the run's build folder, shared by its workers (conftest.py)


@functools.cache
def _build() -> Build | str:
    if shutil.which("cc") is None or shutil.which("make") is None:
        return NO_CC
    shared = os.environ.get(SHARED_BUILD_ENV)
    if shared:  # one build for the run: the first worker builds under the lock, make finds the rest up to date
        out = Path(shared)
    else:
        out = Path(tempfile.mkdtemp(prefix="qp-firmware-"))
        atexit.register(shutil.rmtree, out, True)
    jobs = f"-j{min(4, os.cpu_count() or 1)}"
    with cbuild.file_lock(out / ".lock"):
        proc = subprocess.run(["make", "-s", jobs, "-C", str(FIRMWARE), f"BUILD={out}", "all"], capture_output=True,
                              text=True)
    if proc.returncode != 0:
        raise AssertionError(f"the firmware does not build:\n{proc.stdout}\n{proc.stderr}")
    return Build(out)


def build() -> Build:
    """The session's build; skips the calling test (one reason for all) where there is no C compiler."""
    result = _build()
    if isinstance(result, str):
        pytest.skip(result)
    return result


# --- the codec runner (firmware/test/qp_runner.c) ------------------------------------------------------------


class Runner:
    """The C codec behind qp_runner's line protocol: one process for many commands."""

    def __init__(self, exe: Path) -> None:
        self.proc = subprocess.Popen([str(exe)], stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                     stderr=subprocess.PIPE, text=True, env=SAN_ENV)

    def ask(self, line: str) -> list[str]:
        """Send one command; the answer's lines up to and including its last (any line not starting "pkt ")."""
        assert self.proc.stdin is not None and self.proc.stdout is not None
        self.proc.stdin.write(line + "\n")
        self.proc.stdin.flush()
        out = []
        while True:
            got = self.proc.stdout.readline()
            if not got:
                raise AssertionError(f"qp_runner died (status {self.proc.wait()}):\n{self.proc.stderr.read()}")
            out.append(got.rstrip("\n"))
            if not got.startswith("pkt "):
                return out

    def feed(self, data: bytes, by_byte: bool = False) -> tuple[list[dict[str, Any]], tuple[int, ...]]:
        """Decode a slice: (the packets as field dicts with their seq, the decoder's stats after it)."""
        lines = self.ask(("bytes " if by_byte else "feed ") + data.hex())
        packets = [parse_packet_line(line) for line in lines[:-1]]
        end = lines[-1].split()
        assert end[0] == "end", lines
        return packets, tuple(int(v) for v in end[1:])

    def reset(self) -> None:
        assert self.ask("reset") == ["ok"]

    def encode(self, pkt: Any, seq: int) -> bytes:
        values = []
        for fs in p.SPEC_OF[type(pkt)].fields:
            v = getattr(pkt, fs.name)
            values.append(v.hex() if isinstance(v, bytes) else str(half_bits(v) if fs.fmt == "e" else int(v)))
        (line,) = self.ask(f"encode {seq} {type(pkt).__name__} {' '.join(values)}")
        assert line.startswith("frame "), line
        return bytes.fromhex(line[6:])

    def close(self) -> None:
        with contextlib.suppress(OSError):
            self.proc.stdin.close()  # type: ignore[union-attr]
        status = self.proc.wait(10)
        err = self.proc.stderr.read()  # type: ignore[union-attr]
        assert status == 0, f"qp_runner exit {status}:\n{err}"


def parse_packet_line(line: str) -> dict[str, Any]:
    """``pkt SEQ Name a=1 b=2`` -> {"seq": SEQ, "type": Name, "a": 1, ...} (byte strings stay hex)."""
    _, seq, name, *fields = line.split()
    out: dict[str, Any] = {"seq": int(seq), "type": name}
    for f in fields:
        key, value = f.split("=", 1)
        out[key] = value if _is_bytes_field(name, key) else int(value)
    return out


def _is_bytes_field(type_name: str, field: str) -> bool:
    for spec in p.PACKETS.values():
        if spec.cls.__name__ == type_name:
            return any(fs.name == field and fs.fmt.endswith("s") for fs in spec.fields)
    return False


def half_bits(x: float) -> int:
    import struct

    return struct.unpack("<H", struct.pack("<e", x))[0]


def python_fields(pkt: Any) -> dict[str, Any]:
    """A Python packet in the runner's notation: half floats as raw bits, byte strings in hex."""
    out: dict[str, Any] = {"type": type(pkt).__name__}
    for fs in p.SPEC_OF[type(pkt)].fields:
        v = getattr(pkt, fs.name)
        out[fs.name] = v.hex() if isinstance(v, bytes) else half_bits(v) if fs.fmt == "e" else int(v)
    return out


def python_stats(dec: p.Decoder) -> tuple[int, ...]:
    s = dec.stats
    return (s.frames_ok, s.crc_errors, s.malformed, s.bytes_skipped, s.seq_gaps, s.bytes_in)


@contextlib.contextmanager
def runner(sanitized: bool = True) -> Iterator[Runner]:
    r = Runner(build().path("qp_runner", sanitized))
    try:
        yield r
    finally:
        r.close()


# --- the reference board on a pseudo-terminal -----------------------------------------------------------------


class HostBoard:
    """`host_board --pty` in a child process; ``path`` is its pseudo-terminal (open it like a serial port)."""

    def __init__(self, sanitized: bool = True) -> None:
        exe = build().path("host_board", sanitized)
        self.proc = subprocess.Popen([str(exe), "--pty"], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                     text=True, env=SAN_ENV)
        assert self.proc.stdout is not None
        first = self.proc.stdout.readline()
        assert first.startswith("pty: "), (first, self.proc.stderr.read() if self.proc.stderr else "")
        self.path = first[5:].strip()

    def terminate(self, timeout: float = 10.0) -> tuple[int, str, str]:
        """SIGTERM; (exit status, the rest of stdout, stderr)."""
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGTERM)
        out, err = self.proc.communicate(timeout=timeout)
        return self.proc.returncode, out, err

    def kill(self) -> None:
        if self.proc.poll() is None:
            self.proc.kill()
        self.proc.communicate(timeout=10)


class PtyPeer:
    """The terminal's end of the board's pty in plain Python: our Encoder and Decoder over os.read/os.write."""

    def __init__(self, path: str) -> None:
        self.fd = os.open(path, os.O_RDWR | os.O_NOCTTY)  # the board made it raw already
        self.enc = p.Encoder()
        self.dec = p.Decoder()
        self.received: list[Any] = []
        self.ack_heartbeats = True

    def send(self, *pkts: Any) -> None:
        os.write(self.fd, self.enc.encode_many(pkts))

    def write(self, data: bytes) -> None:
        os.write(self.fd, data)

    def pump(self, seconds: float) -> None:
        """Read for ``seconds``, answering heartbeats (unless ``ack_heartbeats`` is off, as a silent terminal)."""
        end = time.monotonic() + seconds
        while (left := end - time.monotonic()) > 0:
            ready, _, _ = select.select([self.fd], [], [], min(left, 0.05))
            if ready:
                self._read()

    def until(self, cond: Any, timeout: float = 5.0) -> None:
        """Read until ``cond()`` holds; fails after ``timeout`` seconds."""
        end = time.monotonic() + timeout
        while not cond():
            left = end - time.monotonic()
            if left <= 0:
                raise AssertionError(f"timed out; received: {self.received[-12:]}")
            ready, _, _ = select.select([self.fd], [], [], min(left, 0.05))
            if ready:
                self._read()

    def _read(self) -> None:
        for pkt in self.dec.feed(os.read(self.fd, 4096)):
            self.received.append(pkt)
            if type(pkt) is p.Heartbeat and self.ack_heartbeats:
                self.send(p.HeartbeatAck(pkt.counter, pkt.board_ms))

    def of(self, kind: type) -> list[Any]:
        return [x for x in self.received if type(x) is kind]

    def events(self, code: int) -> list[Any]:
        return [e for e in self.of(p.Event) if e.code == code]

    def close(self) -> None:
        with contextlib.suppress(OSError):
            os.close(self.fd)
