"""The phone app's logic (the report's Android port, Appendix A), headless: what its controls do and what its screen
says, with no UI. The wireless screen (``term.ui.screens.wireless``) is one view of it; a test drives it directly.

Controls (each returns the requests it makes, in order; the front end carries them out as the keys would):

- the **stick pad**: ``touch(roll, pitch)`` while a finger is on it, ``release()`` when it is let go: it springs
  back to the centre, as the phone's did (roll and pitch zero);
- the **lift slider**: ``slide(lift)``, and it stays where it is left (``let_go_lift()`` ends the drag);
- **buttons** (``press(name)``): the mode buttons and the trims are the key map's own actions (``RunAction``), so a
  click flies exactly what the key would; "handover" and "handback" ask the board to hand control to BLE or
  back to the cable (``SendCommand``); PANIC is the key's PANIC and lets go of the lift at once (lift zero);
- while nothing is touched, the pad and the slider follow the stick the terminal sends (``follow``: a hardware
  joystick's too), so they never show a stick that is not being flown.

Readouts (pure functions of the ``Model`` and the time): ``readout`` gives the phone's telemetry (mode, the
handover state, battery with its level, attitude: each a ``Reading`` with its age, from the phone's own Compact
frames while flying over BLE), and
``link_states`` says which link carries control and how each one is (the link panel shows them too).
Requests are ``SetAxes`` (change some stick axes, keep the others), ``RunAction`` (a key-map action by name) and
``SendCommand`` (an op and its argument).
"""

from __future__ import annotations

from dataclasses import dataclass

from term.core.freshness import Reading
from term.core.protocol import MODE_TABLE, Joystick, Mode, Op, WirelessState
from term.input.mapping import FULL
from term.session.model import Model
from term.session.texts import battery_level, mode_name, rtt_text


@dataclass(frozen=True, slots=True)
class SetAxes:
    """Change these axes of the stick (None: keep it)."""

    roll: int | None = None
    pitch: int | None = None
    yaw: int | None = None
    lift: int | None = None


@dataclass(frozen=True, slots=True)
class RunAction:
    """Run the key map's action of this name, as its key would."""

    name: str


@dataclass(frozen=True, slots=True)
class SendCommand:
    op: Op
    arg: int = 0


Request = SetAxes | RunAction | SendCommand

MODE_BUTTONS = tuple((s.label, s.action) for s in MODE_TABLE.values() if s.phone)  # (label, key-map action)
TRIM_BUTTONS = (  # (label, key-map action): the same actions as the keys, so trims step alike
    ("roll ◀", "roll_up"), ("roll ▶", "roll_down"),
    ("pitch ▲", "pitch_down"), ("pitch ▼", "pitch_up"),
    ("yaw ↺", "yaw_down"), ("yaw ↻", "yaw_up"),
    ("lift −", "lift_down"), ("lift +", "lift_up"),
)
PANIC = "mode_panic"
# The buttons that are not key-map actions.
COMMAND_BUTTONS: dict[str, SendCommand] = {
    "handover": SendCommand(Op.WIRELESS, 1),
    "handback": SendCommand(Op.WIRELESS, 0),
}
BUTTONS = frozenset([PANIC, *COMMAND_BUTTONS, *(a for _, a in MODE_BUTTONS), *(a for _, a in TRIM_BUTTONS)])


def _clip(v: int, lo: int, hi: int) -> int:
    return max(lo, min(hi, int(v)))


class Phone:
    """The phone's controls: the pad (springs back), the lift slider (stays), the buttons."""

    def __init__(self) -> None:
        self.roll = 0
        self.pitch = 0
        self.lift = 0
        self.touching = False  # a finger (the mouse) on the pad
        self.sliding = False  # ... on the lift slider

    def follow(self, stick: Joystick) -> None:
        """The stick the terminal sends; shown by whatever is not being touched."""
        if not self.touching:
            self.roll, self.pitch = stick.roll, stick.pitch
        if not self.sliding:
            self.lift = _clip(stick.lift, 0, FULL)

    def touch(self, roll: int, pitch: int) -> list[Request]:
        """A finger on the pad at (roll, pitch), each clipped to full deflection."""
        self.touching = True
        roll, pitch = _clip(roll, -FULL, FULL), _clip(pitch, -FULL, FULL)
        if (roll, pitch) == (self.roll, self.pitch):
            return []
        self.roll, self.pitch = roll, pitch
        return [SetAxes(roll=roll, pitch=pitch)]

    def release(self) -> list[Request]:
        """The finger is lifted: the pad springs back to the centre."""
        self.touching = False
        if (self.roll, self.pitch) == (0, 0):
            return []
        self.roll = self.pitch = 0
        return [SetAxes(roll=0, pitch=0)]

    def slide(self, lift: int) -> list[Request]:
        """The lift slider moved to ``lift`` (clipped to 0..full); it stays there."""
        self.sliding = True
        lift = _clip(lift, 0, FULL)
        if lift == self.lift:
            return []
        self.lift = lift
        return [SetAxes(lift=lift)]

    def let_go_lift(self) -> None:
        self.sliding = False

    def press(self, button: str) -> list[Request]:
        """A button by name (``BUTTONS``): what it asks for, in order. Unknown names ask for nothing."""
        if button in COMMAND_BUTTONS:
            return [COMMAND_BUTTONS[button]]
        if button not in BUTTONS:
            return []
        if button == PANIC:  # as the phone's: PANIC lets go of the lift too
            self.lift = 0
            self.sliding = False
            return [RunAction(PANIC), SetAxes(lift=0)]
        return [RunAction(button)]


# --- what the phone's screen says --------------------------------------------------------------------------------


@dataclass(frozen=True, slots=True)
class Readout:
    mode: str
    panic: bool
    wireless: str  # the handover state's name
    battery: Reading  # V, with its age (term.core.freshness)
    battery_level: str  # "panic", "warn", "ok" ("" without a reading shown)
    attitude: tuple[Reading, Reading, Reading]  # roll, pitch, yaw in degrees


def readout(model: Model, now: float) -> Readout:
    """The phone's telemetry, each figure from its freshest source (over BLE the phone's own Compact frames, on
    the cable Attitude and Height), with its age."""
    try:
        ws = WirelessState(model.wireless).name
    except ValueError:
        ws = str(model.wireless)
    bat = model.reading("battery", now)
    level = battery_level(bat.value) if bat.shown and bat.value is not None else ""
    att = (model.reading("phi", now), model.reading("theta", now), model.reading("psi", now))
    return Readout(mode_name(model.mode), model.mode == Mode.PANIC, ws, bat, level, att)


@dataclass(frozen=True, slots=True)
class LinkState:
    name: str  # "cable" or "ble"
    state: str  # in words
    level: str  # "ok", "active" (flying over it), "info", "warn", "alarm"
    carries: bool  # this link carries control


def link_states(model: Model) -> list[LinkState]:
    """Which link carries control, and each link's health: the board's link, then the radio (if any)."""
    s = model.link
    over_ble = model.over_ble
    if model.primary_ble and not model.heard:
        state, level = "connected: waiting for the handover (8 on the cable terminal)", "warn"
    elif s is None or s.since_last_frame_s is None:
        state, level = "waiting for the board…", "warn"
    elif model.link_lost and model.radio_name and over_ble:
        state, level = "silent: flying over BLE", "info"
    elif model.link_lost:
        state, level = "LINK LOST", "alarm"
    else:
        rtt = rtt_text(s)
        state, level = f"OK{', ' + rtt if rtt else ''}", "ok"
    out = [LinkState("ble" if model.primary_ble else "cable", state, level,
                     carries=not model.radio_name or not over_ble)]
    if not model.radio_name:
        return out
    r = model.radio
    if not model.radio_up:
        state, level = model.radio_note or "not connected", "warn"
    elif model.radio_lost:
        state, level = "BLE LINK LOST", "alarm"
    elif model.wireless == WirelessState.STARTED:
        rtt = rtt_text(r)
        state, level = f"flying over BLE{', ' + rtt if rtt else ''}", "active"
    elif model.wireless == WirelessState.STARTING:
        state, level = "STARTING: answering the board's heartbeats", "warn"
    else:
        state, level = "connected, idle (8 in SAFE hands over)", "ok"
    out.append(LinkState("ble", state, level, carries=over_ble))
    return out
