"""An in-process transport pair with fault injection: loss, corruption, delay and baud-rate pacing.

The faults live in a sans-IO core, ``FaultyChannel``: bytes go in with the time they were sent, and come out
at their delivery times, so tests drive it with a fake clock and get exact, seeded results. ``loopback_pair``
wraps two channels (one per direction) in two asyncio ``Transport``s on the real clock, for the link session,
the app and the benchmarks. ``FaultyTransport`` is a byte proxy: it puts a channel in each direction of another
transport (a real serial port, say), for loss and damage without delay or pacing (the real link has its own).

Fault model, applied in this order to what one side writes:

1. pacing: at ``baud`` the wire carries one byte per 10 bit times (8N1); bytes queue behind each other, so a
   burst arrives spread out and a busy wire delays what follows; ``baud=None`` means an infinitely fast wire;
2. loss: each frame (the bytes up to and including a 0x00 delimiter; ``drop_unit="byte"`` for single bytes) is
   dropped with probability ``drop``; it still took its time on the wire;
3. corruption: each delivered byte has one random bit flipped with probability ``corrupt``;
4. delay: every byte arrives ``delay`` seconds (plus a uniform ``jitter``, never reordering) after it left the
   wire;
5. a frame filter (``drop_frame``, optional): a predicate on each frame's bytes as sent (up to and including its
   0x00); a frame it is true for is dropped whole. The channel still knows nothing of packets: the caller's
   predicate does (a test drops every frame of one packet type). With a filter, a frame's bytes are held until
   its delimiter has been sent, so none of them arrives before the whole frame has left the wire.
"""

from __future__ import annotations

import asyncio
import math
import random
import time
from collections import deque
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field

from term.transports.base import Transport, TransportClosed, TransportError

BITS_PER_BYTE = 10  # start bit, 8 data bits, stop bit


@dataclass(frozen=True, slots=True)
class Faults:
    """The faults of one direction of a link."""

    drop: float = 0.0
    corrupt: float = 0.0
    delay: float = 0.0
    jitter: float = 0.0
    baud: float | None = None
    drop_unit: str = "frame"  # "frame" (up to a 0x00) or "byte"
    drop_frame: Callable[[bytes], bool] | None = field(default=None, compare=False)  # True: drop this frame

    def __post_init__(self) -> None:
        if not (0.0 <= self.drop <= 1.0 and 0.0 <= self.corrupt <= 1.0):
            raise ValueError("drop and corrupt are probabilities in [0, 1]")
        if self.delay < 0 or self.jitter < 0 or (self.baud is not None and self.baud <= 0):
            raise ValueError("delay and jitter must be >= 0 and baud > 0")
        if self.drop_unit not in ("frame", "byte"):
            raise ValueError("drop_unit is 'frame' or 'byte'")


@dataclass
class ChannelStats:
    bytes_in: int = 0
    bytes_out: int = 0
    bytes_dropped: int = 0
    bytes_corrupted: int = 0
    frames_in: int = 0  # delimiters seen
    frames_dropped: int = 0
    frames_filtered: int = 0  # dropped by the frame filter


class FaultyChannel:
    """One direction of a faulty link, sans-IO: ``send(data, now)``, then ``receive(now)`` what has arrived.

    Deterministic for a given ``seed`` and sequence of calls.
    """

    def __init__(self, faults: Faults | None = None, *, seed: int | None = 0, **kwargs: float | str | None) -> None:
        self.faults = faults if faults is not None else Faults(**kwargs)  # type: ignore[arg-type]
        self.stats = ChannelStats()
        self._rng = random.Random(seed)
        self._wire_free = -math.inf  # when the wire finishes the last byte sent
        self._last_arrival = -math.inf  # keeps jittered bytes in order
        self._queue: deque[tuple[float, int]] = deque()  # (arrival time, byte)
        self._dropping: bool | None = None  # the current frame's fate; None until its first byte
        self._frame = bytearray()  # with a frame filter: the current frame as sent
        self._held: list[tuple[float, int]] = []  # with a frame filter: its bytes that will arrive, held to its end

    def send(self, data: bytes, now: float) -> None:
        """Put ``data`` on the wire at ``now``."""
        f = self.faults
        st = self.stats
        st.bytes_in += len(data)
        byte_time = BITS_PER_BYTE / f.baud if f.baud else 0.0
        t = max(now, self._wire_free)
        rng = self._rng
        by_frame = f.drop_unit == "frame"
        q = self._queue
        flt = f.drop_frame
        for b in data:
            t += byte_time  # the byte has left the wire
            sent = b
            if by_frame:
                if self._dropping is None:  # a frame's first byte: decide its fate once
                    self._dropping = bool(f.drop) and rng.random() < f.drop
                dropped = self._dropping
                if b == 0:
                    st.frames_in += 1
                    st.frames_dropped += dropped
                    self._dropping = None
            else:
                dropped = bool(f.drop) and rng.random() < f.drop
                if b == 0:
                    st.frames_in += 1
            if dropped:
                st.bytes_dropped += 1
            else:
                if f.corrupt and rng.random() < f.corrupt:
                    b ^= 1 << rng.randrange(8)
                    st.bytes_corrupted += 1
                arrival = t + f.delay + (rng.uniform(0.0, f.jitter) if f.jitter else 0.0)
                arrival = max(arrival, self._last_arrival)
                self._last_arrival = arrival
                if flt is None:
                    q.append((arrival, b))
                else:
                    self._held.append((arrival, b))
            if flt is not None:
                self._frame.append(sent)
                if sent == 0:
                    self._frame_end(flt)
        self._wire_free = t

    def _frame_end(self, flt: Callable[[bytes], bool]) -> None:
        """A frame's delimiter has left the wire: its held bytes go on their way, or all of them are dropped."""
        if flt(bytes(self._frame)):
            self.stats.frames_filtered += 1
            self.stats.bytes_dropped += len(self._held)
        else:
            self._queue.extend(self._held)
        self._frame.clear()
        self._held.clear()

    def receive(self, now: float) -> bytes:
        """The bytes that have arrived by ``now`` (possibly a partial frame, as a real UART read gives)."""
        q = self._queue
        out = bytearray()
        while q and q[0][0] <= now:
            out.append(q.popleft()[1])
        self.stats.bytes_out += len(out)
        return bytes(out)

    def next_arrival(self) -> float | None:
        """When the next byte arrives, or None if nothing is on its way."""
        return self._queue[0][0] if self._queue else None

    @property
    def in_flight(self) -> int:
        return len(self._queue)


# --- the asyncio pair -----------------------------------------------------------------------------------------


class LoopbackTransport(Transport):
    """One end of a loopback pair: writes go through ``outgoing`` to the peer, reads come from ``incoming``."""

    def __init__(
        self, name: str, outgoing: FaultyChannel, incoming: FaultyChannel, clock: Callable[[], float]
    ) -> None:
        self.name = name
        self.outgoing = outgoing
        self.incoming = incoming
        self._clock = clock
        self.peer: LoopbackTransport | None = None
        self._wake = asyncio.Event()
        self._opened = False
        self._closed = False

    @property
    def is_open(self) -> bool:
        return self._opened and not self._closed

    async def open(self) -> None:
        self._opened = True
        self._closed = False

    async def close(self) -> None:
        if self._closed:
            return
        self._closed = True
        self._wake.set()
        if self.peer is not None:
            self.peer._wake.set()

    async def write(self, data: bytes) -> None:
        if self._closed:
            raise TransportClosed(f"{self.name} is closed")
        if not self._opened:
            raise TransportError(f"{self.name} is not open")
        peer = self.peer
        if peer is None or peer._closed:
            raise TransportError(f"{self.name}: the other end closed the link")
        self.outgoing.send(data, self._clock())
        peer._wake.set()

    async def read(self) -> bytes:
        while True:
            if self._closed:
                raise TransportClosed(f"{self.name} is closed")
            data = self.incoming.receive(self._clock())
            if data:
                return data
            nxt = self.incoming.next_arrival()
            if nxt is None and self.peer is not None and self.peer._closed:
                raise TransportError(f"{self.name}: the other end closed the link")
            self._wake.clear()
            timeout = None if nxt is None else max(0.0, nxt - self._clock())
            try:
                async with asyncio.timeout(timeout):  # not wait_for: see term.session.connection
                    await self._wake.wait()
            except TimeoutError:
                pass


class LoopbackPair:
    """Two connected ends: ``a`` (the terminal's) and ``b`` (the board's). Unpacks as ``a, b``."""

    def __init__(
        self,
        a_to_b: Faults | None = None,
        b_to_a: Faults | None = None,
        *,
        seed: int | None = 0,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        seed_b = None if seed is None else seed + 1
        self.a_to_b = FaultyChannel(a_to_b or Faults(), seed=seed)
        self.b_to_a = FaultyChannel(b_to_a or Faults(), seed=seed_b)
        self.a = LoopbackTransport("loopback a", self.a_to_b, self.b_to_a, clock)
        self.b = LoopbackTransport("loopback b", self.b_to_a, self.a_to_b, clock)
        self.a.peer, self.b.peer = self.b, self.a

    def __iter__(self) -> Iterator[LoopbackTransport]:
        return iter((self.a, self.b))


def loopback_pair(
    *,
    seed: int | None = 0,
    clock: Callable[[], float] = time.monotonic,
    a_to_b: Faults | None = None,
    b_to_a: Faults | None = None,
    **faults: float | str | None,
) -> LoopbackPair:
    """A connected pair; ``faults`` keywords (drop, corrupt, delay, jitter, baud, drop_unit) apply to both
    directions, ``a_to_b``/``b_to_a`` to one."""
    both = Faults(**faults) if faults else None  # type: ignore[arg-type]
    return LoopbackPair(a_to_b or both, b_to_a or both, seed=seed, clock=clock)


class FaultyTransport(Transport):
    """A byte proxy around ``inner``: what is written passes ``up``'s faults, what is read ``down``'s. Loss,
    corruption and the frame filter only (bytes pass at once: the inner link has its own timing)."""

    def __init__(self, inner: Transport, up: Faults | None = None, down: Faults | None = None, *,
                 seed: int | None = 0, clock: Callable[[], float] = time.monotonic) -> None:
        for f in (up, down):
            if f is not None and (f.delay or f.jitter or f.baud):
                raise ValueError("the byte proxy passes bytes at once: no delay, jitter or baud")
        self.inner = inner
        self.name = inner.name
        self.up = FaultyChannel(up or Faults(), seed=seed)
        self.down = FaultyChannel(down or Faults(), seed=None if seed is None else seed + 1)
        self._clock = clock

    async def open(self) -> None:
        await self.inner.open()

    async def close(self) -> None:
        await self.inner.close()

    async def write(self, data: bytes) -> None:
        now = self._clock()
        self.up.send(data, now)
        out = self.up.receive(now)
        if out:
            await self.inner.write(out)

    async def read(self) -> bytes:
        while True:
            data = await self.inner.read()
            now = self._clock()
            self.down.send(data, now)
            out = self.down.receive(now)
            if out:
                return out
