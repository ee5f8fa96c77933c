"""Regenerate the packet tables in docs/protocol.md and the test vectors in tests/vectors/protocol.json.

Both come from the packet table in term/core/protocol/, the one source of truth; tests/core/test_protocol_docs.py fails
when either file is out of date. Run: `.venv/bin/python docs/gen_protocol.py`.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from docs import protocol_tables as tables  # noqa: E402
from term.core import protocol as p  # noqa: E402

DOC = ROOT / "docs" / "protocol.md"
VECTORS = ROOT / "tests" / "vectors" / "protocol.json"
BEGIN = "<!-- BEGIN GENERATED: python docs/gen_protocol.py -->"
END = "<!-- END GENERATED -->"

# Example packets, at least one per type, with values that exercise signs, zeros (COBS) and extremes.
EXAMPLES: list[tuple[int, Any]] = [
    (0, p.Joystick(roll=0, pitch=0, yaw=0, lift=0, buttons=0)),
    (1, p.Joystick(roll=-32767, pitch=12000, yaw=-5, lift=32767, buttons=int(p.Button.FIRE))),
    (2, p.Command(cmd_id=7, op=p.Op.MODE, arg=p.Mode.FULL)),
    (3, p.Command(cmd_id=8, op=p.Op.TRIM_LIFT, arg=-1)),
    (4, p.HeartbeatAck(counter=513, board_ms=123456)),
    (5, p.Hello(protocol=p.PROTOCOL_VERSION, role=p.Role.TERMINAL, major=0, minor=1, board_id=0)),
    (0, p.Hello(protocol=p.PROTOCOL_VERSION, role=p.Role.BOARD, major=0, minor=1, board_id=4242)),
    (1, p.Heartbeat(counter=513, board_ms=123456, rtt=27)),
    (2, p.Ack(cmd_id=7, op=p.Op.MODE, status=p.Nak.OK, value=p.Mode.FULL)),
    (3, p.Ack(cmd_id=9, op=p.Op.MODE, status=p.Nak.LIFT_NOT_ZERO, value=p.Mode.SAFE)),
    (4, p.Attitude(mode=p.Mode.FULL, phi=-1234, theta=567, psi=17999, sp=-164, sq=0, sr=3280)),
    (5, p.Motion(sax=12, say=-40, saz=-16384, ae1=401, ae2=399, ae3=400, ae4=1000)),
    (6, p.Height(pressure=101325, height=1530, setpoint=1500, vz=-120, battery=1160, temperature=2150)),
    (7, p.Status(flags=int(p.Flag.CALIBRATED | p.Flag.ARMED), trim_roll=0, trim_pitch=-256, trim_yaw=0,
                 trim_lift=1024, cpu_load=87, log_fill=12, wireless=p.WirelessState.DISCONNECTED)),
    (8, p.Gains(yaw_p=-800.0, p1=0.5, p2=111.0, height_p=2.5, height_d=-0.125)),
    (9, p.Event(code=p.EventCode.REFUSED, arg=(p.Nak.NOT_CALIBRATED << 8) | p.Mode.FULL, board_ms=98765)),
    (10, p.Profile(task=3, mean_us=1979, p99_us=2560, p999_us=2820, period_us=4949, misses=12)),
    (11, p.LogStatus(state=p.LogState.RECORDING, used=65536, records=4096, crc32=0xDEADBEEF)),
    (12, p.LogChunk(index=300, data=bytes([0, 1, 2, 0, 0, 255, 254, 128, 0, 7, 8, 0]))),
    (13, p.Compact(mode=p.Mode.HEIGHT, wireless=p.WirelessState.STARTED, phi=100, theta=-100, psi=-17000,
                   battery=1110)),
    (14, p.Command(cmd_id=10, op=p.Op.SET_PARAM, arg=p.param_arg(p.Param.P1, 4500))),
    (15, p.Command(cmd_id=11, op=p.Op.SET_PARAM, arg=p.param_arg(p.Param.K_GYRO, -1))),
    (16, p.Event(code=p.EventCode.PARAM_CHANGED, arg=p.param_arg(p.Param.P1, 4500), board_ms=99000)),
    (17, p.ParamValue(param=p.Param.ATTITUDE_FILTER, value=0, index=11, count=19)),
    (18, p.ParamValue(param=p.Param.K_GYRO, value=99900, index=12, count=19)),
    (19, p.Compact2(ae1=100, ae2=0, ae3=250, ae4=101, height=153, setpoint=150, vz=-12,
                    flags=int(p.Flag.CALIBRATED | p.Flag.ARMED | p.Flag.WIRELESS_ACTIVE), trim_lift=3280)),
    *((20 + i, pkt) for i, pkt in enumerate(p.text_packets("ASSERT qb.c:12 °C", p.LEVEL_ERROR))),
    (22, p.Text(info=p.LEVEL_INFO, text=b"\0" * 13)),
    (23, p.Command(cmd_id=12, op=p.Op.MOTOR_TEST, arg=p.motor_test_arg(0b0001, 200))),
    (24, p.Event(code=p.EventCode.MOTOR_TEST, arg=p.MotorTestEnd.TIME_UP, board_ms=100500)),
]


def vectors() -> list[dict[str, Any]]:
    return [{"hex": p.encode(pkt, seq).hex(), "seq": seq, "packet": p.to_dict(pkt)} for seq, pkt in EXAMPLES]


def vectors_json() -> str:
    return json.dumps(vectors(), indent=1) + "\n"


def generated_markdown() -> str:
    parts = ["## Shared facts", "",
             "The numbers both ends need, from `term/core/protocol/` (the one home of each;",
             "`tests/house/test_house_rules.py` fails on a copy elsewhere).", "", tables.facts_markdown(),
             "## Parameters", "",
             "One table (`PARAMS` in `term/core/protocol/`; with the presets and what each one does in",
             "`docs/parameters.md`). Each parameter has an id (1..127) and a raw value, a signed integer: a number",
             "times its scale is the value in its unit, an enum is its choice's number, a bool 0 or 1.", "",
             "- `Command(op=SET_PARAM, arg=param_arg(id, raw))`: the id in the top 8 bits of `arg`, the raw value as",
             "  a signed 24-bit number in the low 24. The board answers `Ack` with the raw value now in force, or",
             "  refuses: `UNKNOWN_PARAM`, `OUT_OF_RANGE`, `NOT_IN_SAFE` (a parameter that may not change in",
             "  flight), `LOG_BUSY` (the log scheme with a log in the flash), `BAD_ARGUMENT` (a filter without a",
             "  fixed-point twin in fixed point). A change, by `SET_PARAM` or by a gain key, is then reported as",
             "  `Event(PARAM_CHANGED, arg=param_arg(id, raw))`.",
             "- `Command(op=PARAM_GET, arg=id)`: `Ack.value` is the raw value (`UNKNOWN_PARAM` if none).",
             "- `Command(op=PARAM_LIST)`: `Ack.value` is how many; then one `ParamValue` per parameter, `index`",
             "  0..`count`-1 (a lost one is asked again with `PARAM_GET`).", "",
             tables.params_markdown(),
             "## Packets", "",
             "Each field's `unit` is what the wire carries; multiply by the factor under *shown as* to get the unit",
             "the terminal shows (`scaled(pkt, name)`). A signed field at either end of its range, or any field at",
             "its top, is clipped by the board (`saturated(pkt, name)`): the true value may lie beyond.", "",
             tables.spec_markdown(), "## Enumerations", "", tables.enum_markdown(), "## Test vectors", "",
             "Each line: the packet, its sequence number, the whole frame in hex (delimiter included). The same",
             "vectors are in `tests/vectors/protocol.json`.", "", "```"]
    for v in vectors():
        fields = ", ".join(f"{k}={val}" for k, val in v["packet"].items() if k != "type")
        parts.append(f"{v['packet']['type']}({fields}) seq={v['seq']}")
        parts.append(f"  {v['hex']}")
    parts.append("```")
    # The C side's walk-through (written by hand in docs/firmware_side.md) ends the page.
    return "\n".join(parts) + "\n\n" + (ROOT / "docs" / "firmware_side.md").read_text()


def render_doc(current: str) -> str:
    head, _, rest = current.partition(BEGIN)
    _, _, tail = rest.partition(END)
    title, nl, body = head.partition("\n")
    if title.startswith("# "):  # the heading names the version the table speaks, never a stale one
        head = f"# The Quadrupel link protocol (version {p.PROTOCOL_VERSION}){nl}{body}"
    return f"{head}{BEGIN}\n{generated_markdown()}{END}{tail}"


def main() -> None:
    DOC.write_text(render_doc(DOC.read_text()))
    VECTORS.parent.mkdir(parents=True, exist_ok=True)
    VECTORS.write_text(vectors_json())
    print(f"wrote {DOC.relative_to(ROOT)} and {VECTORS.relative_to(ROOT)}")


if __name__ == "__main__":
    main()
