"""The channels of a flight as the field's tools read them: ONE description, shared by the live server
(``term.data.foxglove``, Foxglove's WebSocket protocol) and the MCAP export (``term.data.export``).

Contract (docs/recording.md lists the channels with what each holds):

- Every channel has a JSON schema (``ChannelSpec``: topic, schema name and text, message encoding ``json``), so any
  reader finds its schema by id and its messages by a well-known encoding. Decoded packets are on
  ``/<link>/<rx|tx>/<Packet>`` (schema ``quadrupel.<Packet>``, generated from the packet table) in SI units:
  angles in rad, rates in rad/s, accelerations in m/s², heights in m, volts, Pa, °C (``term.data.columns``).
- Foxglove's well-known schemas where one fits: the board's attitude estimate and height as ``foxglove.FrameTransform``
  on ``/<link>/pose`` (frame ``craft`` in ``room``), the simulator's true pose on ``/truth/pose`` (frame ``truth``;
  ``term --sim``, live and recorded), the events panel's lines as ``foxglove.Log`` on ``/events``. The frame
  ``room`` is the pad with x north, y west, z up (the board's NED turned about x, so the 3D panel's z is up); the
  craft's frame is x forward, y left, z up.
- The link statistics on ``/<link>/stats`` (``quadrupel.LinkStats``, times in s), the simulator's truth on
  ``/truth`` (``quadrupel.Truth``).
- Raw link bytes only when asked (``raw_channel``): message encoding ``quadrupel-frames`` with a schema of that
  encoding that says what the bytes are; a reader that does not know the encoding skips the channel. The station's
  records (``/station``, what a replay applies) go with them: an export with them replays as the session did.

``Channels`` turns what a session holds (decoded frames, event lines, link statistics, truth samples, and the
recording's items, the truth among them) into ``(ChannelSpec, log_time_ns, message)``; it keeps the latest height of
each link for the pose. Sans-IO: the writers (a file, a server) encode and send.
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable, Iterable, Iterator, Mapping
from dataclasses import dataclass
from functools import cache
from typing import Any

from term.core.protocol import SPEC_OF, Attitude, Compact, Compact2, Decoder, Height, PacketSpec
from term.data.columns import json_schema, packet_columns, packet_json
from term.data.recording import (
    LEVEL_OF,
    LOG_SCHEMA,
    RAW_ENCODING,
    LinkBytes,
    LoggedEvent,
    StationRecord,
    TruthSample,
)

ROOM, CRAFT, TRUTH = "room", "craft", "truth"  # the 3D panel's frames


@dataclass(frozen=True, slots=True)
class ChannelSpec:
    """One channel: its topic, its schema (name, encoding, text) and its messages' encoding."""

    topic: str
    schema_name: str
    schema: bytes
    schema_encoding: str = "jsonschema"
    message_encoding: str = "json"


Message = tuple[ChannelSpec, int, Any]  # the channel, log_time (Unix ns), the message: a dict, or bytes (encoded)

_TIME = {"type": "object", "title": "time", "properties": {"sec": {"type": "integer", "minimum": 0},
                                                           "nsec": {"type": "integer", "minimum": 0}}}
_VEC3 = {"type": "object", "properties": {k: {"type": "number"} for k in "xyz"}}
_QUAT = {"type": "object", "properties": {k: {"type": "number"} for k in "xyzw"}}
# Foxglove's FrameTransform (https://docs.foxglove.dev/docs/sdk/schemas/frame-transform), in its JSON form.
FRAME_TRANSFORM_SCHEMA = {
    "title": "foxglove.FrameTransform",
    "description": "A transform between two reference frames in 3D space",
    "type": "object",
    "properties": {
        "timestamp": dict(_TIME, description="Timestamp of transform"),
        "parent_frame_id": {"type": "string", "description": "Name of the parent frame"},
        "child_frame_id": {"type": "string", "description": "Name of the child frame"},
        "translation": dict(_VEC3, description="Translation component of the transform (m)"),
        "rotation": dict(_QUAT, description="Rotation component of the transform"),
    },
}
STATS_FIELDS = ("rtt_last_ms", "rtt_mean_ms", "rtt_p95_ms", "loss_pct", "loss_pct_total", "rx_bytes_per_s",
                "tx_bytes_per_s", "frames_ok", "frames_bad", "since_last_frame_s", "since_last_heartbeat_s",
                "heartbeat_delay_ms", "lost", "rx_bytes", "tx_bytes", "commands_sent", "command_retries",
                "commands_failed", "heartbeats")
TRUTH_FIELDS = {"n": "m", "e": "m", "h": "m", "vn": "m/s", "ve": "m/s", "vd": "m/s", "phi": "rad", "theta": "rad",
                "psi": "rad", "p": "rad/s", "q": "rad/s", "r": "rad/s", "volts": "V", "wind_n": "m/s",
                "wind_e": "m/s"}


def _schema(d: dict[str, Any]) -> bytes:
    return json.dumps(d, ensure_ascii=False).encode()


def _stat_name(name: str) -> str:
    return name[:-3] + "_s" if name.endswith("_ms") else name  # SI: the link's times in s


def _number_schema(title: str, doc: str, props: dict[str, tuple[str, str]]) -> bytes:
    return _schema({"$schema": "http://json-schema.org/draft-07/schema#", "title": title, "description": doc,
                    "type": "object",
                    "properties": {k: {"type": t, "description": d} for k, (t, d) in props.items()}})


EVENTS = ChannelSpec("/events", "foxglove.Log", _schema(LOG_SCHEMA))
TRUTH_POSE = ChannelSpec("/truth/pose", "foxglove.FrameTransform", _schema(FRAME_TRANSFORM_SCHEMA))
TRUTH_CHANNEL = ChannelSpec("/truth", "quadrupel.Truth", _number_schema(
    "quadrupel.Truth", "The simulator's truth: earth NED from the pad, body FRD, SI units (term --sim)",
    {**{k: ("number", u) for k, u in TRUTH_FIELDS.items()}, "on_ground": ("boolean", ""), "crashes": ("integer", "")}))
CONSOLE = ChannelSpec("/console", "foxglove.Log", _schema(LOG_SCHEMA))  # the board's text (term.core.console)
STATION = ChannelSpec("/station", "quadrupel.StationRecord", _schema(
    {"title": "quadrupel.StationRecord", "type": "object",
     "description": "a station event by class ('~') and field (term/core/events.py): what a replay applies"}))


@cache
def packet_channel(link: str, direction: str, spec: PacketSpec) -> tuple[ChannelSpec, Callable[[Any], bytes]]:
    """The channel of ``spec``'s packets over ``link`` in ``direction``, and the function that writes a packet as
    its message (JSON, SI: ``packet_record`` of its SI columns)."""
    enc = packet_json(tuple(packet_columns(spec, si=True)), tuple(f.fmt for f in spec.fields))
    return (ChannelSpec(f"/{link}/{direction}/{spec.cls.__name__}", f"quadrupel.{spec.cls.__name__}",
                        _schema(json_schema(spec, si=True))), enc)


@cache
def pose_channel(link: str) -> ChannelSpec:
    return ChannelSpec(f"/{link}/pose", "foxglove.FrameTransform", _schema(FRAME_TRANSFORM_SCHEMA))


@cache
def stats_channel(link: str) -> ChannelSpec:
    props = {_stat_name(k): ("boolean" if k == "lost" else "number", "") for k in STATS_FIELDS}
    return ChannelSpec(f"/{link}/stats", "quadrupel.LinkStats", _number_schema(
        "quadrupel.LinkStats", f"the {link} link's health (term/core/link.py LinkStats; times in s)", props))


@cache
def raw_channel(link: str, direction: str) -> ChannelSpec:
    doc = (b"The bytes exactly as read from or written to the link: COBS frames, each ended by 0x00, with a CRC-16 "
           b"(docs/protocol.md). Not JSON: skip this channel unless you decode the quadrupel protocol.")
    return ChannelSpec(f"/{link}/{direction}", RAW_ENCODING, doc, RAW_ENCODING, RAW_ENCODING)


def stamp(t_ns: int) -> dict[str, int]:
    return {"sec": t_ns // 1_000_000_000, "nsec": t_ns % 1_000_000_000}


def quaternion(roll: float, pitch: float, yaw: float) -> dict[str, float]:
    """The rotation of Z-Y-X Euler angles (rad) as a quaternion."""
    cr, sr = math.cos(roll / 2), math.sin(roll / 2)
    cp, sp = math.cos(pitch / 2), math.sin(pitch / 2)
    cy, sy = math.cos(yaw / 2), math.sin(yaw / 2)
    return {"x": sr * cp * cy - cr * sp * sy, "y": cr * sp * cy + sr * cp * sy,
            "z": cr * cp * sy - sr * sp * cy, "w": cr * cp * cy + sr * sp * sy}


def frame_transform(t_ns: int, child: str, xyz: tuple[float, float, float], phi: float, theta: float,
                    psi: float) -> dict[str, Any]:
    """A foxglove.FrameTransform of ``child`` in ``room`` from a NED position and FRD Euler angles (rad): turned
    about x into the room's z-up frame (y and z negated), so roll stays and pitch and yaw change sign."""
    n, e, up = xyz
    return {"timestamp": stamp(t_ns), "parent_frame_id": ROOM, "child_frame_id": child,
            "translation": {"x": n + 0.0, "y": 0.0 - e, "z": up + 0.0},  # (+ 0.0: never a -0.0 in the JSON)
            "rotation": quaternion(phi, -theta, -psi)}


_CDEG = math.pi / 18000.0  # rad per 0.01° (the attitude's unit on the wire)
# frame_transform's JSON for the estimate, as one format string (a pose goes with every attitude: the hot path)
_POSE = ('{"timestamp": {"sec": %d, "nsec": %d}, "parent_frame_id": "' + ROOM + '", "child_frame_id": "' + CRAFT
         + '", "translation": {"x": 0.0, "y": 0.0, "z": %r}, "rotation": {"x": %r, "y": %r, "z": %r, "w": %r}}')


def craft_pose(t_ns: int, up: float, phi: float, theta: float, psi: float) -> bytes:
    """``json.dumps(frame_transform(t_ns, CRAFT, (0, 0, up), phi, theta, psi))``, numerically, as bytes."""
    q = quaternion(phi, -theta, -psi)
    return (_POSE % (t_ns // 1_000_000_000, t_ns % 1_000_000_000, up, q["x"], q["y"], q["z"], q["w"])).encode()


class Channels:
    """What a session holds, as messages on the channels above (the module docstring)."""

    def __init__(self, raw: bool = False) -> None:
        self.raw = raw  # the link bytes and the station's records too (an export that replays)
        self._height: dict[str, float] = {}
        self._decoders: dict[tuple[str, str], Decoder] = {}
        self._packet_channels: dict[tuple[str, str, type], tuple[ChannelSpec, Callable[[Any], bytes]]] = {}

    def frame(self, t_ns: int, link: str, direction: str, pkt: Any,
              want: Callable[[ChannelSpec], bool] | None = None) -> list[Message]:
        """A packet decoded from ``link``'s bytes in ``direction`` at ``t_ns``: its channel, and the pose; only the
        channels ``want`` says yes to (all without it: the live server converts nothing no client asked for)."""
        kind = type(pkt)
        key = (link, direction, kind)
        found = self._packet_channels.get(key)  # (a PacketSpec's own hash is slow: it hashes every field's spec)
        if found is None:
            found = self._packet_channels[key] = packet_channel(link, direction, SPEC_OF[kind])
        ch, enc = found
        out: list[Message] = [(ch, t_ns, enc(pkt))] if want is None or want(ch) else []
        if direction != "rx":
            return out
        if kind is Attitude or kind is Compact:
            pose = pose_channel(link)
            if want is None or want(pose):
                up = self._height.get(link, 0.0)
                out.append((pose, t_ns, craft_pose(t_ns, up, pkt.phi * _CDEG, pkt.theta * _CDEG, pkt.psi * _CDEG)))
        elif kind is Height or kind is Compact2:
            self._height[link] = pkt.height * 0.01  # cm (the table's Height and Compact2)
        return out

    def log(self, t_ns: int, severity: str, source: str, text: str) -> Message:
        return (EVENTS, t_ns, {"timestamp": stamp(t_ns), "level": LEVEL_OF.get(severity, 2), "message": text,
                               "name": source, "file": "", "line": 0})

    def stats(self, t_ns: int, link: str, fields: dict[str, Any]) -> Message:
        """A link's statistics (LinkStats' fields by name) in SI."""
        out: dict[str, Any] = {}
        for k in STATS_FIELDS:
            v = fields.get(k)
            if k.endswith("_ms") and isinstance(v, (int, float)):
                v = v / 1000.0
            out[_stat_name(k)] = v
        return (stats_channel(link), t_ns, out)

    def truth(self, t_ns: int, truth: Mapping[str, Any]) -> list[Message]:
        """A sample of the simulator's truth (``term.lessons.instructor.Truth``'s fields by name, live or from a
        recording): its channel and the pose; none if a field is missing or not a finite number (a hostile file)."""
        rec: dict[str, Any] = {}
        for k in TRUTH_FIELDS:
            v = truth.get(k)
            if type(v) not in (int, float) or not math.isfinite(v):
                return []
            rec[k] = float(v)
        crashes = truth.get("crashes", 0)
        rec["on_ground"], rec["crashes"] = truth.get("on_ground") is True, crashes if type(crashes) is int else 0
        pose = frame_transform(t_ns, TRUTH, (rec["n"], rec["e"], rec["h"]), rec["phi"], rec["theta"], rec["psi"])
        return [(TRUTH_CHANNEL, t_ns, rec), (TRUTH_POSE, t_ns, pose)]

    def item(self, item: Any) -> Iterator[Message]:
        """One item of a recording (``term.data.recording``): link bytes decoded with today's codec, an event
        line, a station record (the link statistics in it; itself only with ``raw``)."""
        kind = type(item)
        if kind is LinkBytes:
            if self.raw:
                yield (raw_channel(item.link, item.direction), item.t_ns, item.data)
            key = (item.link, item.direction)
            dec = self._decoders.get(key) or self._decoders.setdefault(key, Decoder(keep_text=True))
            for pkt in dec.feed(item.data):
                yield from self.frame(item.t_ns, item.link, item.direction, pkt)
        elif kind is LoggedEvent:
            yield self.log(item.t_ns, item.severity, item.source, item.text)
        elif kind is TruthSample:
            yield from self.truth(item.t_ns, item.data)
        elif kind is StationRecord:
            if self.raw:
                yield (STATION, item.t_ns, item.data)
            d = item.data
            if isinstance(d, dict) and d.get("~") == "StatsSample" and isinstance(d.get("stats"), dict):
                yield self.stats(item.t_ns, str(d.get("link", "")), d["stats"])
            line = console_line(d)
            if line is not None:
                yield console_message(item.t_ns, *line)

    def items(self, items: Iterable[Any]) -> Iterator[Message]:
        for it in items:
            yield from self.item(it)


def console_line(d: Any) -> tuple[str, str, int, str] | None:
    """(link, source, level, text) of a recorded station record that is one of the board's console lines
    (``FromLink(link, ConsoleLine)``, as ``term.data.recording.encode_event`` keeps it), else None."""
    if not isinstance(d, dict) or d.get("~") != "FromLink":
        return None
    ev = d.get("event")
    if not isinstance(ev, dict) or ev.get("~") != "ConsoleLine":
        return None
    level = ev.get("level")
    text = ev.get("text")
    if not isinstance(text, str) or not isinstance(level, int) or isinstance(level, bool):
        return None
    dropped = ev.get("dropped")
    if isinstance(dropped, int) and not isinstance(dropped, bool) and dropped > 0:
        text = f"[{dropped} dropped] {text}"
    return str(d.get("link", "")), str(ev.get("source", "")), min(5, max(1, level)), text


def console_message(t_ns: int, link: str, source: str, level: int, text: str) -> Message:
    """A console line as foxglove.Log on /console; its name says the link and the source ("cable/uart")."""
    return (CONSOLE, t_ns, {"timestamp": stamp(t_ns), "level": level, "message": text, "name": f"{link}/{source}",
                            "file": "", "line": 0})


def all_channels(links: Iterable[str] = ("cable", "radio")) -> list[ChannelSpec]:
    """Every channel a session over ``links`` can have (docs, the layout's check, tests)."""
    from term.core.protocol import PACKETS

    out = [EVENTS, CONSOLE, TRUTH_CHANNEL, TRUTH_POSE]
    for link in links:
        out += [pose_channel(link), stats_channel(link)]
        for spec in sorted(PACKETS.values(), key=lambda s: s.type_id):
            direction = "tx" if spec.direction.startswith("pc") else "rx"
            out.append(packet_channel(link, direction, spec)[0])
    return out
