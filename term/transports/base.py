"""The one small interface every byte pipe offers: open, close, write bytes, read the next chunk.

Transports move bytes and know nothing of packets or widgets. Every failure reaches the caller as one
``TransportError`` whose message is a single line a pilot can act on ("serial port /dev/ttyUSB0 not found: ...").
"""

from __future__ import annotations

import abc
from collections.abc import AsyncIterator


class TransportError(Exception):
    """The link cannot be opened or has died. ``str(exc)`` is one clear line: what happened and what to do."""


class TransportClosed(TransportError):
    """Raised by ``read``/``write`` after this side called ``close()``: a deliberate stop, not a failure."""


class Transport(abc.ABC):
    """A bidirectional byte pipe. Methods are coroutines; none of them blocks the event loop.

    What a transport can do is said by its attributes, never guessed from its class: ``movable`` (it may be opened
    and used on whichever event loop calls it, so the link's own thread can own it: serial and BLE; a loopback
    pair shares queues with its peer on the caller's loop and may not), ``is_open``, ``address`` (what the user
    named: the port, the BLE address) and ``inner`` (a wrapper's transport: a recording tap, a fault proxy;
    ``innermost`` follows them to the pipe itself)."""

    name: str = "transport"
    address: str = ""
    movable: bool = False
    inner: Transport | None = None

    @property
    def is_open(self) -> bool:
        """Whether ``open()`` succeeded and the link has not been closed since."""
        return False

    @property
    def innermost(self) -> Transport:
        """The byte pipe under every wrapper (this transport itself when it wraps none)."""
        t: Transport = self
        while t.inner is not None:
            t = t.inner
        return t

    @abc.abstractmethod
    async def open(self) -> None:
        """Open the link; raises TransportError if it cannot."""

    @abc.abstractmethod
    async def close(self) -> None:
        """Close the link. Idempotent and prompt: a pending ``read`` ends with TransportClosed."""

    @abc.abstractmethod
    async def write(self, data: bytes) -> None:
        """Send ``data``; raises TransportError if the link died."""

    @abc.abstractmethod
    async def read(self) -> bytes:
        """The next non-empty chunk of received bytes; raises TransportError when the link dies."""

    async def __aenter__(self) -> Transport:
        await self.open()
        return self

    async def __aexit__(self, *exc: object) -> None:
        await self.close()

    async def chunks(self) -> AsyncIterator[bytes]:
        """The received bytes as an async stream; ends quietly when this side closes."""
        while True:
            try:
                yield await self.read()
            except TransportClosed:
                return
