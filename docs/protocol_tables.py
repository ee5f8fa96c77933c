"""The protocol's tables as Markdown: the generated parts of docs/protocol.md and docs/parameters.md.

Written from the packet, enumeration, parameter and preset tables in term.core.protocol, the one source of truth;
docs/gen_protocol.py and docs/gen_parameters.py put them into the documents.
"""

from __future__ import annotations

import struct

from term.core.protocol import (
    ACC_LSB_PER_G,
    BATTERY_FULL,
    BATTERY_LOW,
    BATTERY_WARN,
    BOARD_NAME_PREFIX,
    EVENT_ARG_SCALE,
    FLIGHT_MODES,
    GYRO_LSB_PER_DPS,
    LIFT_ZERO,
    LOW_BATTERY_HOLD_S,
    NAK_TEXT,
    NUS_RX,
    NUS_SERVICE,
    NUS_TX,
    PACKETS,
    PARAMS,
    PRESETS,
    STICK_MAX,
    STICK_NEUTRAL,
    Button,
    EventCode,
    Flag,
    LogState,
    Mode,
    Nak,
    Op,
    Param,
    Role,
    WirelessState,
    preset_values,
)


def spec_markdown() -> str:
    """The packet table as Markdown: the generated part of docs/protocol.md."""
    lines: list[str] = []
    for spec in sorted(PACKETS.values(), key=lambda s: s.type_id):
        name = spec.cls.__name__
        lines.append(f"### `{spec.type_id:#04x}` {name}")
        lines.append("")
        lines.append(f"{spec.doc} Direction: {spec.direction}. Rate: {spec.rate}. "
                     f"Body {spec.body_size} bytes, frame {spec.frame_size} bytes.")
        lines.append("")
        lines.append("| offset | field | type | unit | shown as | meaning |")
        lines.append("|---|---|---|---|---|---|")
        offset = 0
        for fs in spec.fields:
            size = struct.calcsize("<" + fs.fmt)
            shown = f"× {fs.scale:.6g} {fs.scaled_unit}" if fs.scale != 1.0 else ""
            lines.append(f"| {offset} | `{fs.name}` | {_C_TYPE.get(fs.fmt, fs.fmt)} | {fs.unit} | {shown} "
                         f"| {fs.doc} |")
            offset += size
        lines.append("")
    return "\n".join(lines)


_C_TYPE = {
    "B": "uint8",
    "b": "int8",
    "H": "uint16",
    "h": "int16",
    "I": "uint32",
    "i": "int32",
    "e": "float16 (IEEE 754 half)",
    "f": "float32",
    "12s": "uint8[12]",
}


def enum_markdown() -> str:
    """The enumerations as Markdown tables."""
    lines: list[str] = []
    for enum in (Mode, Op, Nak, EventCode, WirelessState, LogState, Flag, Button, Role, Param):
        lines.append(f"### {enum.__name__}")
        lines.append("")
        lines.append("| value | name |" + (" text |" if enum is Nak else ""))
        lines.append("|---|---|" + ("---|" if enum is Nak else ""))
        for member in enum:
            extra = f" {NAK_TEXT[member]} |" if enum is Nak else ""
            lines.append(f"| {int(member)} | {member.name} |{extra}")
        lines.append("")
    return "\n".join(lines)



def params_markdown() -> str:
    """The parameter table as Markdown (docs/protocol.md and docs/parameters.md): one row per parameter, by name."""
    lines = ["| id | name | type | unit | range | default | raw = value / | in flight | meaning |",
             "|---|---|---|---|---|---|---|---|---|"]
    for ps in sorted(PARAMS.values(), key=lambda p: p.name):
        raw = f"{ps.scale:g}" if ps.kind == "float" else ("choice" if ps.kind == "enum" else "")
        if ps.kind == "enum":
            raw = ", ".join(f"{ps.base + i} {c}" for i, c in enumerate(ps.choices))
        lines.append(f"| {int(ps.param)} | `{ps.name}` | {ps.kind} | {ps.unit} | {ps.limits_text()} | "
                     f"{ps.text(ps.default)} | {raw} | {'yes' if ps.in_flight else 'SAFE only'} | {ps.doc} |")
    return "\n".join(lines) + "\n"


def presets_markdown() -> str:
    """The presets as Markdown: each preset's values where they differ from the defaults."""
    names = list(PRESETS)
    changed = sorted({p for values in PRESETS.values() for p in values}, key=lambda p: PARAMS[p].name)
    lines = ["| parameter | " + " | ".join(f"`{n}`" for n in names) + " |", "|---|" + "---|" * len(names)]
    for p in changed:
        spec = PARAMS[p]
        cells = [spec.text(preset_values(n)[p]) for n in names]
        lines.append(f"| `{spec.name}` | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def facts_markdown() -> str:
    """The facts both ends share, as Markdown."""
    modes = ", ".join(m.name for m in sorted(FLIGHT_MODES))
    events = ", ".join(f"{c.name} × {k:g} {u}" for c, (k, u) in EVENT_ARG_SCALE.items())
    rows = [
        ("NUS service", f"`{NUS_SERVICE}`"),
        ("NUS RX (terminal writes; write, write without response)", f"`{NUS_RX}`"),
        ("NUS TX (board notifies; notify only)", f"`{NUS_TX}`"),
        ("board name", f"`{BOARD_NAME_PREFIX} <board id>`"),
        ("flight modes (motors under the flight core)", modes),
        ("stick range", f"±{STICK_MAX} (lift 0..{STICK_MAX})"),
        ("zero lift (leaving SAFE, going back to SAFE)", f"joystick lift + lift trim ≤ {LIFT_ZERO}"),
        ("neutral sticks (leaving SAFE)", f"joystick + trim within ±{STICK_NEUTRAL} on roll, pitch and yaw each"),
        ("battery: PANIC while flying", f"< {BATTERY_LOW} (× 10 mV) for {LOW_BATTERY_HOLD_S:g} s"),
        ("battery: time to land / full", f"< {BATTERY_WARN} / {BATTERY_FULL} (× 10 mV)"),
        ("gyro / accelerometer words", f"{GYRO_LSB_PER_DPS:g} LSB per °/s, {ACC_LSB_PER_G} LSB per g"),
        ("event arguments with a unit", events),
    ]
    lines = ["| fact | value |", "|---|---|", *(f"| {k} | {v} |" for k, v in rows)]
    return "\n".join(lines) + "\n"
