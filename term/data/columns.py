"""Columns from the packet table: a field's name and unit in the files and on the live channels.

A field ``phi`` whose scaled unit is ``°`` becomes the column ``phi_deg``, its value the raw value times the
table's ``scale`` (``field_column``); with ``si=True`` the unit is SI instead (``phi_rad``, ``sp_radps``,
``sax_mps2``: ``SI_OF``), as Foxglove's panels and the MCAP export carry them. A field without a physical unit
(counters, motor commands, sticks, enumerations) keeps its bare name and raw value; an enumeration gets a
``<name>_name`` beside it. ``json_schema`` describes a packet's messages from the same columns.
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable
from dataclasses import dataclass
from enum import IntEnum, IntFlag
from typing import Any

from term.core import protocol
from term.core.protocol import FieldSpec, PacketSpec

DIGITS = 6  # decimals kept after scaling: below every field's resolution, no float noise in the files

# How a unit is spelled at the end of a column name (ASCII, lower case). Units not named here are no physical
# unit (sticks, 0..1000 motor commands, bits, enumerations): those columns keep the bare field name.
UNIT_SUFFIX = {
    "°": "deg", "°/s": "dps", "g": "g", "m": "m", "m/s": "mps", "V": "v", "°C": "degc", "s": "s", "ms": "ms",
    "µs": "us", "Pa": "pa", "%": "pct", "bytes": "bytes",
    "rad": "rad", "rad/s": "radps", "m/s²": "mps2",
}
# The SI unit of each scaled unit that is not SI (° and g are not), and the factor to it. °C stays: it is SI's own
# derived unit for temperature, and a kelvin reading would serve no one.
G0 = 9.80665  # m/s² per g (standard gravity)
SI_OF = {"°": ("rad", math.pi / 180.0), "°/s": ("rad/s", math.pi / 180.0), "g": ("m/s²", G0), "ms": ("s", 1e-3),
         "µs": ("s", 1e-6)}


@dataclass(frozen=True, slots=True)
class Column:
    """One output column: where it comes from (``field``), its name, the factor to its unit, and that unit."""

    name: str
    field: str
    scale: float
    unit: str
    doc: str = ""
    enum: type[IntEnum] | None = None


def column_name(field: str, unit: str) -> str:
    suffix = UNIT_SUFFIX.get(unit)
    # a field named with its unit already (Profile's mean_us) keeps its name: not mean_us_us (issue 34)
    return f"{field}_{suffix}" if suffix and not field.endswith(f"_{suffix}") else field


def _enum_of(unit: str) -> type[IntEnum] | None:
    cls = getattr(protocol, unit, None) if unit.isidentifier() else None
    if isinstance(cls, type) and issubclass(cls, IntEnum) and not issubclass(cls, IntFlag):
        return cls
    return None


def field_column(fs: FieldSpec, board_units: bool = False, si: bool = False) -> Column:
    """The column of ``fs``: in the table's scaled unit, the board's (``board_units``) or SI (``si``)."""
    if board_units:
        return Column(fs.name, fs.name, 1.0, fs.unit, fs.doc, _enum_of(fs.unit))
    unit, scale = fs.scaled_unit or fs.unit, fs.scale
    if si and unit in SI_OF:
        unit, factor = SI_OF[unit]
        scale *= factor
    return Column(column_name(fs.name, unit), fs.name, scale, unit, fs.doc, _enum_of(fs.unit))


def packet_columns(spec: PacketSpec, board_units: bool = False, si: bool = False) -> list[Column]:
    return [field_column(fs, board_units, si) for fs in spec.fields]


def _value(raw: Any, scale: float) -> Any:
    if isinstance(raw, bytes):
        return raw.hex()
    if scale == 1.0:
        return raw if not isinstance(raw, float) or math.isfinite(raw) else None
    v = round(raw * scale, DIGITS)
    return v if math.isfinite(v) else None


def _enum_name(enum: type[IntEnum], raw: int) -> str:
    try:
        return enum(raw).name
    except ValueError:
        return str(raw)


def packet_record(pkt: Any, columns: list[Column]) -> dict[str, Any]:
    """``pkt`` as a dict of column name to value (scaled), enumerations named beside their number."""
    out: dict[str, Any] = {}
    for col in columns:
        raw = getattr(pkt, col.field)
        out[col.name] = _value(raw, col.scale)
        if col.enum is not None:
            out[f"{col.name}_name"] = _enum_name(col.enum, raw)
    return out


def json_schema(spec: PacketSpec, si: bool = False) -> dict[str, Any]:
    """The JSON schema of a packet's exported messages, generated from its table entry."""
    props: dict[str, Any] = {}
    for fs, col in zip(spec.fields, packet_columns(spec, si=si), strict=True):
        kind = "string" if fs.fmt.endswith("s") else "integer" if col.scale == 1.0 and fs.fmt != "e" else "number"
        desc = f"{fs.doc} ({col.unit})" if fs.doc and col.unit else fs.doc or col.unit
        props[col.name] = {"type": kind, "description": desc}
        if col.enum is not None:
            props[f"{col.name}_name"] = {"type": "string", "enum": [m.name for m in col.enum],
                                         "description": f"{col.enum.__name__} of {col.name}"}
    return {"$schema": "http://json-schema.org/draft-07/schema#", "title": f"quadrupel.{spec.cls.__name__}",
            "description": f"{spec.doc} Direction: {spec.direction}. Rate: {spec.rate}.",
            "type": "object", "properties": props}




def _json_float(x: float) -> str:
    return repr(x) if math.isfinite(x) else "null"


def packet_json(columns: tuple[Column, ...], fmts: tuple[str, ...]) -> Callable[[Any], bytes]:
    """A function giving ``json.dumps(packet_record(pkt, columns))`` as bytes, numerically the same, some five
    times faster (one format string per packet type: the live server and the export write every frame with it).
    ``fmts``: each field's struct format (``e`` a float, ``…s`` bytes)."""
    parts, args = [], []
    env: dict[str, Any] = {"_f": _json_float}
    for i, (col, fmt) in enumerate(zip(columns, fmts, strict=True)):
        key = json.dumps(col.name)
        if fmt.endswith("s"):
            parts.append(f'{key}: "%s"')
            args.append(f"p[{i}].hex()")
        elif fmt == "e":  # a float on the wire: nan and inf are null, as packet_record has them
            parts.append(f"{key}: %s")
            args.append(f"_f(p[{i}] * {col.scale!r})" if col.scale != 1.0 else f"_f(p[{i}])")
        elif col.scale == 1.0:
            parts.append(f"{key}: %d")
            args.append(f"p[{i}]")
        else:
            parts.append(f"{key}: %r")
            args.append(f"round(p[{i}] * {col.scale!r}, {DIGITS})")
        if col.enum is not None:
            names = {int(m): m.name for m in col.enum}
            env[f"_n{i}"] = names
            parts.append(f'{json.dumps(col.name + "_name")}: "%s"')
            args.append(f"(_n{i}.get(p[{i}]) or str(p[{i}]))")
    body = "{" + ", ".join(parts) + "}"
    src = f"def enc(p):\n    return ({body!r} % ({', '.join(args)},)).encode()\n"
    exec(src, env)  # noqa: S102  # the source is built from the packet table above, never from input
    return env["enc"]  # type: ignore[no-any-return]
