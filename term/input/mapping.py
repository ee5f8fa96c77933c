"""Joystick mapping, pure logic: raw axis values (-1..1) and buttons in, a protocol ``Joystick`` packet out.

No pygame here, so every rule is testable with plain numbers. The lab's stick (Logitech Extreme 3D Pro): axis 0
roll, 1 pitch, 2 yaw (twist), 3 throttle; the fire button (0) is PANIC. Other sticks get name-matched presets
(as MAVProxy and cfclient do), and a config file may add its own mappings, which win over the presets.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

from term.core.protocol import (  # LIFT_ZERO: the board's guard, checked here first
    LIFT_ZERO,
    STICK_MAX,
    Button,
    Joystick,
)
from term.core.schema import Flag, ListOf, Number, OneOf, SchemaError, Table, Text

FULL = STICK_MAX  # full deflection, stick units


@dataclass(frozen=True, slots=True)
class AxisMap:
    """One logical axis from one raw axis.

    ``kind`` "center": a self-centring axis, -1..1 → -32767..32767. "throttle": a lever whose whole travel is
    lift, -1..1 → 0..32767 (with ``invert`` the lab's lever: -1 pushed forward is full lift). "half": a
    self-centring stick used as throttle, only its upper half gives lift (pushed up, -1, is full lift).
    """

    index: int
    invert: bool = False
    deadzone: float = 0.05
    kind: str = "center"

    def value(self, axes: Sequence[float]) -> int:
        if not 0 <= self.index < len(axes):
            return 0  # a stick without this axis: centred, and never lift
        raw = float(axes[self.index])
        raw = max(-1.0, min(1.0, -raw if self.invert else raw))
        if self.kind == "throttle":
            return round(_dead((raw + 1.0) / 2.0, self.deadzone) * FULL)
        if self.kind == "half":
            return round(_dead(max(0.0, -raw), self.deadzone) * FULL)
        mag = _dead(abs(raw), self.deadzone)
        return round(mag * FULL) if raw >= 0 else -round(mag * FULL)


END_SNAP = 0.002  # SDL's axes end at 32767/32768: the last 0.2 % of travel is full deflection


def _dead(x: float, dz: float) -> float:
    """Deadzone on a magnitude 0..1, rescaled so the output still spans 0..1 without a jump at the edge."""
    if x <= dz:
        return 0.0
    if x >= 1.0 - END_SNAP:
        return 1.0
    return min(1.0, (x - dz) / (1.0 - dz)) if dz < 1.0 else 0.0


@dataclass(frozen=True, slots=True)
class StickMapping:
    name: str
    match: tuple[str, ...]  # case-insensitive substrings of the joystick's name; empty matches nothing
    roll: AxisMap
    pitch: AxisMap
    yaw: AxisMap
    lift: AxisMap
    fire: tuple[int, ...] = (0,)

    def to_packet(self, axes: Sequence[float], buttons: Sequence[bool]) -> Joystick:
        fire = any(0 <= b < len(buttons) and buttons[b] for b in self.fire)
        return Joystick(
            roll=self.roll.value(axes),
            pitch=self.pitch.value(axes),
            yaw=self.yaw.value(axes),
            lift=self.lift.value(axes),
            buttons=int(Button.FIRE) if fire else 0,
        )


LAB = StickMapping(
    "lab (Logitech Extreme 3D Pro)",
    ("extreme 3d", "logitech attack"),
    roll=AxisMap(0),
    pitch=AxisMap(1),
    yaw=AxisMap(2, deadzone=0.08),
    lift=AxisMap(3, invert=True, deadzone=0.02, kind="throttle"),
    fire=(0,),
)

# Game pads as SDL exposes them on Linux (axes 0 LX, 1 LY, 2 LT, 3 RX, 4 RY, 5 RT); "mode 2": left stick
# yaw and lift, right stick roll and pitch; A/cross is fire.
_PAD = dict(
    roll=AxisMap(3, deadzone=0.08),
    pitch=AxisMap(4, deadzone=0.08),
    yaw=AxisMap(0, deadzone=0.1),
    lift=AxisMap(1, deadzone=0.05, kind="half"),
    fire=(0,),
)
XBOX = StickMapping("Xbox pad (mode 2)", ("xbox", "x-box", "xinput", "microsoft x"), **_PAD)  # type: ignore[arg-type]
PLAYSTATION = StickMapping(
    "PlayStation pad (mode 2)", ("playstation", "dualshock", "dualsense", "ps4", "ps5", "wireless controller"),
    **_PAD,  # type: ignore[arg-type]
)

PRESETS: tuple[StickMapping, ...] = (LAB, XBOX, PLAYSTATION)


def choose_mapping(name: str, custom: Iterable[StickMapping] = ()) -> StickMapping:
    """The mapping for a joystick called ``name``: a custom one that matches, else a preset, else the lab's."""
    low = name.lower()
    for m in (*custom, *PRESETS):
        if any(s.lower() in low for s in m.match if s):
            return m
    return LAB


class MappingError(SchemaError):
    """A joystick mapping from the config that cannot be used; the message is one line."""


AXIS_MAX = 63  # raw axis numbers SDL may report; a stick has at most a handful
BUTTON_MAX = 127
DEADZONE_MAX = 0.9  # of the travel: a wider dead zone leaves the pilot no stick
RESOLUTION_RANGE = (1, 4096)  # stick units of change detection (StickState); 0 would divide by zero

# One [joystick.mappings.NAME] table: its keys, their types and ranges. Missing axes keep the lab's.
AXIS_TABLE = Table({
    "axis": Number(0, AXIS_MAX, integer=True),
    "invert": Flag(),
    "deadzone": Number(0, DEADZONE_MAX),
    "kind": OneOf(("center", "throttle", "half")),
})
MAPPING_TABLE = Table({
    "match": ListOf(Text(nonempty=True), min_len=1, one_ok=True),
    "roll": AXIS_TABLE, "pitch": AXIS_TABLE, "yaw": AXIS_TABLE, "lift": AXIS_TABLE,
    "fire": ListOf(Number(0, BUTTON_MAX, integer=True), unique=True),
}, section=True)


def mapping_from_dict(name: str, d: Mapping[str, Any]) -> StickMapping:
    """A mapping from its TOML table: ``match = [...]``, ``roll = {axis = 0, invert = false, deadzone = 0.05}``,
    ``lift = {axis = 3, invert = true, kind = "throttle"}``, ``fire = [0]``. Missing axes default to the lab's;
    a wrong type, a value out of range or an unknown key is a ``MappingError`` naming the table and key."""
    try:
        v = MAPPING_TABLE.check(d, f"[joystick.mappings.{name}]")
    except SchemaError as exc:
        raise MappingError(str(exc)) from None

    def axis(key: str, default: AxisMap) -> AxisMap:
        t = v.get(key, {})
        return AxisMap(t.get("axis", default.index), t.get("invert", default.invert),
                       t.get("deadzone", default.deadzone), t.get("kind", default.kind))

    return StickMapping(
        name, tuple(v.get("match", [name])),
        roll=axis("roll", LAB.roll), pitch=axis("pitch", LAB.pitch), yaw=axis("yaw", LAB.yaw),
        lift=axis("lift", LAB.lift), fire=tuple(v.get("fire", [0])),
    )


NEUTRAL = Joystick(0, 0, 0, 0, 0)


@dataclass
class StickState:
    """Change detection: ``update`` returns the new packet only when the mapped value changed.

    Values are quantised to ``resolution`` stick units first, so sensor jitter below that is not a change.
    """

    mapping: StickMapping = LAB
    resolution: int = 64
    current: Joystick = NEUTRAL
    _last_key: tuple[int, ...] = field(default=(0, 0, 0, 0, 0), repr=False)

    def __post_init__(self) -> None:
        lo, hi = RESOLUTION_RANGE
        if isinstance(self.resolution, bool) or not isinstance(self.resolution, int) or not lo <= self.resolution <= hi:
            raise ValueError(f"resolution must be an integer between {lo} and {hi}, got {self.resolution!r}")

    def update(self, axes: Sequence[float], buttons: Sequence[bool]) -> Joystick | None:
        pkt = self.mapping.to_packet(axes, buttons)
        r = self.resolution
        key = (pkt.roll // r, pkt.pitch // r, pkt.yaw // r, pkt.lift // r, pkt.buttons)
        if pkt == self.current:
            return None
        # Within one quantum it is jitter, unless a value just reached zero or full deflection: those matter to
        # the guards and the pilot, so they always go out.
        if key == self._last_key and not any(
            a != b and b in _EDGES for a, b in zip(self.current, pkt, strict=True)
        ):
            return None
        self._last_key = key
        self.current = pkt
        return pkt

    def reset(self) -> None:
        self.current = NEUTRAL
        self._last_key = (0, 0, 0, 0, 0)


_EDGES = (0, FULL, -FULL)




def leave_safe_refusal(current_mode: int, requested_mode: int, stick: Joystick) -> str | None:
    """Why the terminal refuses to ask the board to leave SAFE now, or None. The board guards too; this one
    answers at once and names the fix."""
    from term.core.protocol import Mode

    leaving_safe = current_mode == Mode.SAFE and requested_mode not in (Mode.SAFE, Mode.PANIC, Mode.WIRELESS)
    if leaving_safe and stick.lift > LIFT_ZERO:
        pct = round(100 * stick.lift / FULL)
        return f"throttle is up ({pct} %): pull it fully down before leaving SAFE"
    return None
