"""`term export SESSION|--latest -o flight.tlog`: a session recording as a MAVLink telemetry log, the file
QGroundControl and MAVProxy keep of every flight, which mavlogdump, MAVExplorer and any pymavlink script read.

A .tlog is a run of MAVLink messages, each after its time: 8 bytes, big-endian, µs since the Unix epoch. The
messages are the ones a live ground station gets from ``term --mavlink`` (term/data/mavlink_map.py's ``Telemetry``,
at the same capped rates): what the board sent, decoded from the recording's bytes at the times they crossed the
link, plus HEARTBEAT, SYS_STATUS and BATTERY_STATUS once a second of the recording and a PARAM_VALUE for each of
the board's parameter answers. Only the board's side (rx) is read; term's own lines (the events list) are not
MAVLink's. pymavlink (the ``mavlink`` extra) is needed: TlogError (one line) without it. term/data/export.py reads
the recording and calls ``write_tlog`` (this module imports nothing of it: one way, no cycle).
"""

from __future__ import annotations

import struct
from collections.abc import Iterable
from pathlib import Path
from typing import Any

from term.core.protocol import PARAMS, Decoder, Param, ParamValue
from term.data.mavlink_map import (
    PARAM_NAMES,
    PARAM_ORDER,
    MavlinkMissing,
    Telemetry,
    codec,
    pack,
    param_float,
)
from term.data.recording import Recording

_STAMP = struct.Struct(">Q")
BATCH = 256  # messages joined into one write


class TlogError(ValueError):
    """The log cannot be written (pymavlink missing, the file not writable); the message is one line."""


def write_tlog(items: Iterable[Any], out: Path, info: list[Recording]) -> int:
    """A recording's items (term/data/export.py's reading of it: link bytes as ``(t_ns, link, direction, data)``,
    ``info`` its parts as they are read) to ``out`` as a telemetry log; the number of messages written."""
    try:
        mav = codec()
    except MavlinkMissing as exc:
        raise TlogError(str(exc)) from None
    try:
        out.parent.mkdir(parents=True, exist_ok=True)
        with out.open("wb") as f:
            return _write(items, f, mav, info)
    except OSError as exc:
        raise TlogError(f"cannot write {out}: {exc.strerror or exc}") from None


def _write(items: Any, f: Any, mav: Any, info: list[Recording]) -> int:
    tele = Telemetry(mav)
    decoders: dict[str, Decoder] = {}
    start: int | None = None
    next_periodic = 0.0
    out: list[bytes] = []
    n = 0
    for item in items:
        if type(item) is not tuple or item[2] != "rx":  # the board's bytes only (module docstring)
            continue
        t_ns, link, _, data = item
        dec = decoders.get(link) or decoders.setdefault(link, Decoder())
        pkts = dec.feed(data)
        if not pkts:
            continue
        if start is None:
            start = info[0].start_ns if info and info[0].meta else t_ns
        t = (t_ns - start) / 1e9
        stamp = _STAMP.pack(max(0, t_ns // 1000))
        msgs: list[Any] = []
        for pkt in pkts:
            if type(pkt) is ParamValue:
                msgs += _param(mav, pkt)
            else:
                msgs += tele.packet(pkt, t)
        if t >= next_periodic:  # (after this read's packets: the first heartbeat has the board's mode)
            next_periodic = t + 1.0
            msgs += tele.periodic()
        for msg in msgs:
            out.append(stamp + pack(mav, msg))
        if len(out) >= BATCH:
            f.write(b"".join(out))
            n += len(out)
            out.clear()
    f.write(b"".join(out))
    return n + len(out)


def _param(mav: Any, pkt: ParamValue) -> list[Any]:
    if pkt.param not in PARAM_NAMES:
        return []
    spec = PARAMS[Param(pkt.param)]
    return [mav.param_value_encode(PARAM_NAMES[pkt.param].encode(), param_float(spec, pkt.value),
                                   9, len(PARAM_ORDER), PARAM_ORDER.index(pkt.param))]  # 9: MAV_PARAM_TYPE_REAL32
