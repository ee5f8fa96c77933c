"""`term export SESSION|--latest -o flight.tlog`: a session recording as a MAVLink telemetry log, the file
QGroundControl and MAVProxy keep of every flight, which mavlogdump, MAVExplorer and any pymavlink script read.

A .tlog is a run of MAVLink messages, each after its time: 8 bytes, big-endian, µs since the Unix epoch. The
messages are the ones a live ground station gets from ``term --mavlink`` (term/data/mavlink_map.py's ``Telemetry``,
at the same capped rates): what the board sent, decoded from the recording's bytes at the times they crossed the
link, plus HEARTBEAT, SYS_STATUS and BATTERY_STATUS once a second of the recording and a PARAM_VALUE for each of
the board's parameter answers. Only the board's side (rx) is read; term's own lines (the events list) are not
MAVLink's. pymavlink (the ``mavlink`` extra) is needed: ExportError (one line) without it.
"""

from __future__ import annotations

import struct
from pathlib import Path
from typing import Any

from term.core.protocol import PARAMS, Decoder, Param, ParamValue
from term.data.export import ExportError, ExportResult, Progress, _counted, _session_items, kind_of
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


def export_tlog(src: Path, out: Path, progress: Progress | None = None, *, board_units: bool = False,
                raw: bool = False) -> ExportResult:
    """Write the session recording ``src`` to ``out`` as a telemetry log; ExportError (one line) on trouble."""
    if board_units or raw:
        raise ExportError("--board-units and --raw are for CSV and MCAP: a telemetry log carries MAVLink's units")
    if kind_of(src) != "session":
        raise ExportError(f"{src} is a flash-log CSV: a telemetry log is written from a session recording")
    if out.exists() and out.resolve() == src.resolve():
        raise ExportError(f"{out} is the input: choose another output")
    try:
        mav = codec()
    except MavlinkMissing as exc:
        raise ExportError(str(exc)) from None
    try:
        out.parent.mkdir(parents=True, exist_ok=True)
        with out.open("wb") as f:
            info: list[Recording] = []
            n = _write(_counted(_session_items(src, info), src, progress), f, mav, info)
    except OSError as exc:
        raise ExportError(f"cannot write {out}: {exc.strerror or exc}") from None
    return ExportResult("session", n, all(r.complete for r in info))


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
        if t >= next_periodic:
            next_periodic = t + 1.0
            msgs += tele.periodic()
        for pkt in pkts:
            if type(pkt) is ParamValue:
                msgs += _param(mav, pkt)
            else:
                msgs += tele.packet(pkt, t)
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
