"""`term --foxglove [HOST:]PORT`: the session served live over Foxglove's WebSocket protocol (the `foxglove-sdk`
package, the optional extra ``foxglove``), on the channels ``term export`` writes (term/data/channels.py).

Contract:

- ``LiveServer(host, port, t0=, start_ns=)`` starts the SDK's server (loopback unless a host is given) in a context
  of its own. It is fed on the link's thread as the link works, never through the display (so a slow screen
  delays nothing served): ``link_packet`` (each packet a link received, as its session decoded it: the station's
  ``on_packet``), ``received``/``sent`` (a link's bytes and the caller's monotonic ``now``, tapped at the
  transports by ``RecordingTransport``: a read only stamps the time of the packets decoded from it, a write's
  bytes are decoded here; ``thread_safe`` tells ``post_taps`` to call them on the link's thread). From the
  display's thread: ``packet`` (a replay's decoded packets), ``event`` (an events-panel line), ``station_event``
  (the link statistics), ``truth`` (the simulator's). Each call converts (``Channels``) on the caller's thread
  what a client subscribed to (and the parameters, always), and hands each message to the SDK's ``log``, which
  never blocks: the SDK's own thread sends it, and a slow client loses its oldest messages (the SDK's backlog),
  never the flight's. No hop through a thread of our own: a hop is a wake-up that a busy machine delays by tens
  of ms (bench.foxglove), and the link's thread is awake with the packets already. A conversion that fails costs
  that message (``errors`` counts), never the link.
- Times: ``log_time`` is the time the bytes crossed the link, on the recording's clock (``start_ns`` plus the
  monotonic time since ``t0``, µs resolution, as ``SessionRecorder`` stamps them): a live message and the same
  message in the recording carry the same time.
- Nothing is sent on a channel no client subscribes to. The board's parameters (from its ParamValue answers,
  F11's list) are the server's parameters, published as they change, read-only: a client's set is answered with
  the values as they are (a change goes through F11 and its guards).
- Clients pass a door first (term/data/foxglove_front.py, ``guard`` its caps): the SDK keeps every connection it
  accepts, so it listens on loopback at a port of its own and the door, on the address asked for, lets through
  only connections that send their WebSocket upgrade in time, and at most so many clients: a flood of idle
  connections costs the flight nothing.
- ``close()`` stops the server (taps after it are ignored). ``port`` is the port bound (``0`` asks for any free one).
"""

from __future__ import annotations

import asyncio
import contextlib
import dataclasses
import json
import os
import threading
import time
from typing import Any

from term.core.protocol import Decoder
from term.core.protocol.params import PARAMS, Param
from term.data.channels import Channels, ChannelSpec, console_message
from term.data.export import DecodedFrame
from term.data.foxglove_front import Front
from term.data.recording import LoggedEvent

UPSTREAM_HOST = "127.0.0.1"  # the SDK's own server, behind the front (term/data/foxglove_front.py)
DEFAULT_HOST = "127.0.0.1"  # loopback: a flight's data leaves the machine only when the pilot names a host
# The SDK's runtime (tokio) starts a worker thread per core; one is plenty for a few hundred small messages a second,
# and two waking each other for every message cost more than the sending (bench.foxglove: 2.0 -> 1.2 % of a core).
SDK_WORKER_THREADS = "1"
INSTALL_HINT = "live Foxglove needs the SDK: pip install 'quadrupel[foxglove]' (or: pip install foxglove-sdk)"


class FoxgloveError(ValueError):
    """The server cannot start; the message is one line."""


def is_loopback(host: str) -> bool:
    """Whether ``host`` is this machine alone (a name other than localhost counts as beyond it)."""
    import ipaddress

    if host.lower() == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


def public_refusal(host: str, public: bool) -> str:
    """Why ``--foxglove HOST:PORT`` is refused ("" if it is not): an address beyond this machine serves the whole
    flight to the network, so it needs ``--foxglove-public`` (as the instructor's channel needs its own)."""
    if public or is_loopback(host):
        return ""
    return (f"--foxglove on {_shown(host, quoted=False)} serves the whole flight to every machine that reaches it; "
            "add --foxglove-public to mean it (or leave the host out: loopback)")


def parse_address(text: str) -> tuple[str, int]:
    """``[HOST:]PORT`` to (host, port); host defaults to loopback. FoxgloveError with one line if malformed."""
    host, sep, port_text = text.rpartition(":")
    host = host.strip("[]") if sep else DEFAULT_HOST
    shown = _shown(text)
    try:
        port = int(port_text)
    except ValueError:
        raise FoxgloveError(f"--foxglove takes [HOST:]PORT, e.g. 8765 or 0.0.0.0:8765; got {shown}") from None
    if not 0 <= port <= 65535 or not host:
        raise FoxgloveError(f"--foxglove: port 0..65535 and a host, e.g. 127.0.0.1:8765; got {shown}")
    return host, port


def _shown(text: str, quoted: bool = True) -> str:
    """``text`` for an error line (``quoted``: as its repr), or, if long (a hostile address), its first 40
    characters and its length: the message stays one short line."""
    if len(text) > 60:
        text, more = text[:40], f"... ({len(text)} characters)"
    else:
        more = ""
    return (repr(text) if quoted else text) + more


class _Params:
    """The board's parameters as the server's, read-only (the SDK calls these from its own threads). The SDK's
    ServerListener's other callbacks are given by ``_listener``."""

    def __init__(self) -> None:
        self.values: dict[str, float | str | bool] = {}

    def parameters(self, names: list[str] | None = None) -> list[Any]:
        import foxglove

        values = dict(self.values)
        return [foxglove.Parameter(k, value=v) for k, v in sorted(values.items()) if not names or k in names]

    def on_get_parameters(self, client: Any, param_names: list[str], request_id: str | None = None) -> list[Any]:
        return self.parameters(param_names)

    def on_set_parameters(self, client: Any, parameters: list[Any], request_id: str | None = None) -> list[Any]:
        return self.parameters([p.name for p in parameters])  # unchanged: writes go through F11's guards


def _listener(params: type, base: type) -> type:
    """``params`` with the SDK's ServerListener's do-nothing callbacks for the rest (subscribe, unsubscribe, ...)."""
    return type("ParamsListener", (params, base), {})


class LiveServer:
    """The session's channels served live (see the module docstring)."""

    thread_safe = True  # its taps never block: the link's thread calls them as bytes pass (link_thread.post_taps)

    def __init__(self, host: str, port: int, *, t0: float, start_ns: int, name: str = "quadrupel term",
                 guard: dict[str, Any] | None = None) -> None:
        os.environ.setdefault("TOKIO_WORKER_THREADS", SDK_WORKER_THREADS)  # (read when the SDK's runtime starts)
        try:
            import foxglove
            from foxglove.websocket import Capability
        except ImportError:
            raise FoxgloveError(INSTALL_HINT) from None
        self.t0, self.start_ns = t0, start_ns
        self._foxglove = foxglove
        self._context = foxglove.Context()
        self._params = _listener(_Params, foxglove.websocket.ServerListener)()
        try:  # the door first (it binds the address asked for), the SDK's server behind it on loopback
            self._front = Front(host, port, **(guard or {}))
        except Exception as exc:  # an address in use, a host not here: one line
            line = f"cannot serve Foxglove on {_shown(host, quoted=False)}:{port}: {exc}".splitlines()[0]
            raise FoxgloveError(line[:300]) from None
        try:
            self._server = foxglove.start_server(name=name, host=UPSTREAM_HOST, port=0, context=self._context,
                                                 capabilities=[Capability.Parameters],
                                                 server_listener=self._params)
        except Exception as exc:  # the SDK's own error: one line
            self._front.close()
            line = f"cannot serve Foxglove on {_shown(host, quoted=False)}:{port}: {exc}".splitlines()[0]
            raise FoxgloveError(line[:300]) from None
        self._front.start((UPSTREAM_HOST, self._server.port))
        self.host = host
        self.port = self._front.port
        self._channels: dict[str, tuple[Any, bool]] = {}
        self._decoders: dict[str, Decoder] = {}  # each link's written bytes' (one thread each)
        self._read_at: dict[str, float] = {}  # each link's last read: the time of the packets decoded from it
        self._batch: list[Any] = []  # the link thread's messages of this step of its loop (``_queue``)
        self._flush_due = False
        self._lock = threading.Lock()  # the channels are made once, whichever thread asks first
        self._maker = Channels()  # (its state is per link and direction: each is fed from one thread)
        self.published = 0  # messages handed to the SDK (a client subscribed to their channel; about: not locked)
        self.errors = 0  # items that could not be converted (each lost alone)
        self._closed = False

    @property
    def url(self) -> str:
        host = f"[{self.host}]" if ":" in self.host else self.host  # an IPv6 address in brackets
        return f"ws://{host}:{self.port}"

    # --- fed from any thread ------------------------------------------------------------------------------------

    def t_ns(self, now: float) -> int:
        return self.start_ns + round((now - self.t0) * 1e6) * 1000  # µs resolution, as the recording stamps

    def received(self, link: str, data: bytes, now: float) -> None:
        """A read off ``link``: its time only (its packets come decoded by the link's session: ``link_packet``)."""
        self._read_at[link] = now

    def link_packet(self, link: str, pkt: Any) -> None:
        """A packet ``link``'s session decoded from the last read (the hot path: every packet the board sends)."""
        if self._closed:
            return
        now = self._read_at.get(link)
        try:
            self._queue(self._maker.frame(self.t_ns(time.monotonic() if now is None else now), link, "rx", pkt,
                                          self._wanted))
        except Exception:  # one bad packet costs that packet, never the link
            self.errors += 1

    def sent(self, link: str, data: bytes, now: float) -> None:
        """A write to ``link``: its packets, decoded from the bytes (what left: a write the display's watchdog
        holds back never comes here)."""
        if data and not self._closed:
            self._bytes(link, data, now)

    def packet(self, link: str, direction: str, pkt: Any, now: float) -> None:
        self._serve(DecodedFrame(self.t_ns(now), link, direction, pkt))

    def event(self, now: float, severity: str, source: str, text: str) -> None:
        self._serve(LoggedEvent(self.t_ns(now), severity, source, text))

    def station_event(self, ev: Any, now: float) -> None:
        """The station's events the channels carry: the link statistics."""
        if type(ev).__name__ == "StatsSample":
            self._serve(("stats", self.t_ns(now), ev.link, dataclasses.asdict(ev.stats)))
        elif type(ev).__name__ == "FromLink" and type(ev.event).__name__ == "ConsoleLine":
            self._serve(("console", self.t_ns(now), ev.link, ev.event))  # the board's text on /console

    def truth(self, truth: Any, now: float) -> None:
        self._serve(("truth", self.t_ns(now), truth))

    @property
    def front(self) -> Front:
        """The door clients pass (its caps and counts: term/data/foxglove_front.py)."""
        return self._front

    def close(self) -> None:
        self._closed = True
        self._front.close()
        self._server.stop()

    # --- on the caller's thread ---------------------------------------------------------------------------------

    def _serve(self, item: Any) -> None:
        if self._closed:
            return
        try:
            self._publish(self._messages(item))
        except Exception:  # one bad item costs that item, never the link or the screen
            self.errors += 1

    def _bytes(self, link: str, data: bytes, now: float) -> None:
        """A link's written bytes: decoded, each packet to its channels."""
        t_ns = self.t_ns(now)
        dec = self._decoders.get(link) or self._decoders.setdefault(link, Decoder(keep_text=True))
        frame, want = self._maker.frame, self._wanted
        try:
            for pkt in dec.feed(data):
                self._queue(frame(t_ns, link, "tx", pkt, want))
        except Exception:  # one bad packet costs that chunk's rest, never the link
            self.errors += 1

    def _queue(self, messages: list[Any]) -> None:
        """The link thread's messages, handed to the SDK together at the end of this step of its loop (a read and
        its packets, a write): the SDK wakes its sender once for them all, not once a message, which is most of
        the serving's cost (bench.foxglove). Without a running loop here, at once."""
        if not messages:
            return
        self._batch += messages
        if self._flush_due:
            return
        try:
            asyncio.get_running_loop().call_soon(self._flush)
            self._flush_due = True
        except RuntimeError:  # (no loop: a caller of its own)
            self._flush()

    def _flush(self) -> None:
        self._flush_due = False
        batch, self._batch = self._batch, []
        if self._closed:
            return
        try:
            self._publish(batch, wanted=True)
        except Exception:  # (a bad message costs the rest of its batch: counted)
            self.errors += 1

    def _wanted(self, spec: ChannelSpec) -> bool:
        """Worth converting: a client subscribed to the channel, or it carries the board's parameters."""
        ch, is_param = self._channels.get(spec.topic) or self._channel(spec)
        return is_param or ch.has_sinks()

    def _messages(self, item: Any) -> Any:
        maker = self._maker
        kind = type(item)
        if kind is DecodedFrame:
            return maker.frame(item.t_ns, item.link, item.direction, item.packet)
        if kind is tuple:
            if item[0] == "stats":
                return [maker.stats(item[1], item[2], item[3])]
            if item[0] == "console":
                line = item[3]
                text = f"[{line.dropped} dropped] {line.text}" if line.dropped else line.text
                return [console_message(item[1], item[2], line.source, line.level, text)]
            return maker.truth(item[1], dataclasses.asdict(item[2]))  # (a bad sample: an error counted, not raised)
        return maker.item(item)

    def _param(self, param: int, raw: int) -> None:
        spec = PARAMS.get(Param(param)) if param in Param._value2member_map_ else None
        if spec is None:
            return
        value = spec.from_raw(raw)
        if self._params.values.get(spec.name) != value:
            self._params.values[spec.name] = value
            with contextlib.suppress(Exception):  # to the clients that subscribed to it (Foxglove's panel)
                self._server.publish_parameter_values(self._params.parameters([spec.name]))

    def _publish(self, messages: Any, wanted: bool = False) -> None:
        """``messages`` to the SDK; ``wanted``: only what ``_wanted`` let through (asked once, not again)."""
        channels = self._channels
        for spec, t_ns, msg in messages:
            ch, is_param = channels.get(spec.topic) or self._channel(spec)
            if is_param:
                d = json.loads(msg)
                self._param(d["param"], d["value"])  # (whether or not a client subscribed to the channel)
                if not ch.has_sinks():
                    continue
            elif not wanted and not ch.has_sinks():
                continue
            ch.log(msg if type(msg) is bytes else json.dumps(msg, ensure_ascii=False).encode(), t_ns)
            self.published += 1

    def _channel(self, spec: ChannelSpec) -> tuple[Any, bool]:
        """The SDK's channel of ``spec`` (made on first use), and whether it carries the board's parameters."""
        fg = self._foxglove
        with self._lock:  # (two threads asking at once would advertise the topic twice)
            found = self._channels.get(spec.topic)
            if found is None:
                schema = fg.Schema(name=spec.schema_name, encoding=spec.schema_encoding, data=spec.schema)
                ch = fg.Channel(spec.topic, schema=schema, message_encoding=spec.message_encoding,
                                context=self._context).base
                found = self._channels[spec.topic] = (ch, spec.schema_name == "quadrupel.ParamValue")
        return found
