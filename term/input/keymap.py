"""The pilot's key map: one table from keys to actions. It drives the app's bindings and generates the help screen.

Board actions carry the protocol ``Op`` and ``arg`` they send; terminal actions (help, log download, ...) carry a
``local`` name the app dispatches. The lab's map (DESIGN.md) comes first; the extras (height gains, log, profile,
help) use keys the lab left free. A config file may rebind any action by name (``[keys]`` in term.toml), after a
preset (``KEY_PRESETS``: "lab", the default, where ← is "roll up", i.e. banks right, as the lab's terminal did;
"natural", where ← banks left and → right), chosen with ``preset = "natural"`` in ``[keys]``.
"""

from __future__ import annotations

import string
import unicodedata
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, replace
from functools import cache

from term.core.protocol import MODE_TABLE, ModeSpec, Op
from term.core.schema import nearest, shown


@dataclass(frozen=True, slots=True)
class Action:
    """What a key does. Exactly one of ``op`` (a board command) or ``local`` (a terminal action) is set."""

    name: str  # stable id used by the config file and the command palette
    description: str
    group: str
    op: Op | None = None
    arg: int = 0
    local: str | None = None


@dataclass(frozen=True, slots=True)
class KeyBinding:
    keys: tuple[str, ...]  # Textual key names, e.g. "1", "escape", "left", "f2"
    action: Action


def _mode(spec: ModeSpec) -> KeyBinding:
    return KeyBinding(spec.keys, Action(spec.action, spec.help, "Modes", Op.MODE, int(spec.mode)))


def _step(name: str, key: str, text: str, group: str, op: Op, arg: int) -> KeyBinding:
    return KeyBinding((key,), Action(name, text, group, op, arg))


def _local(name: str, keys: tuple[str, ...], text: str, group: str) -> KeyBinding:
    return KeyBinding(keys, Action(name, text, group, local=name))


# Z: the lift trim to zero at once (so many steps down that the board clips it at 0, whatever its step size).
ZERO_TRIM_STEPS = -32767


DEFAULT_KEYMAP: tuple[KeyBinding, ...] = (
    *(_mode(spec) for spec in MODE_TABLE.values() if spec.keys),  # the mode table's keys (protocol/modes.py)
    KeyBinding(("8",), Action("wireless", "WIRELESS handover to BLE (in SAFE)", "Modes", Op.WIRELESS, 1)),
    KeyBinding(("c",), Action("ack_crash", "crash seen: the board may leave SAFE again", "Modes", Op.ACK_CRASH)),
    _step("lift_up", "a", "lift up (1 %; ¼ % near hover)", "Trims", Op.TRIM_LIFT, +1),
    _step("lift_down", "z", "lift down (1 %; ¼ % near hover)", "Trims", Op.TRIM_LIFT, -1),
    _step("lift_zero", "Z", "lift trim to zero (in flight: press twice)", "Trims", Op.TRIM_LIFT, ZERO_TRIM_STEPS),
    _step("roll_up", "left", "roll up (trim +: banks right)", "Trims", Op.TRIM_ROLL, +1),
    _step("roll_down", "right", "roll down (trim −: banks left)", "Trims", Op.TRIM_ROLL, -1),
    _step("pitch_down", "up", "pitch down (nose down)", "Trims", Op.TRIM_PITCH, -1),
    _step("pitch_up", "down", "pitch up (nose up)", "Trims", Op.TRIM_PITCH, +1),
    _step("yaw_down", "q", "yaw down (left)", "Trims", Op.TRIM_YAW, -1),
    _step("yaw_up", "w", "yaw up (right)", "Trims", Op.TRIM_YAW, +1),
    _step("yaw_p_up", "u", "yaw P up", "Gains", Op.GAIN_YAW_P, +1),
    _step("yaw_p_down", "j", "yaw P down", "Gains", Op.GAIN_YAW_P, -1),
    _step("p1_up", "i", "roll/pitch P1 up", "Gains", Op.GAIN_P1, +1),
    _step("p1_down", "k", "roll/pitch P1 down", "Gains", Op.GAIN_P1, -1),
    _step("p2_up", "o", "roll/pitch P2 up", "Gains", Op.GAIN_P2, +1),
    _step("p2_down", "l", "roll/pitch P2 down", "Gains", Op.GAIN_P2, -1),
    _step("height_p_up", "t", "height P up", "Gains", Op.GAIN_HEIGHT_P, +1),
    _step("height_p_down", "g", "height P down", "Gains", Op.GAIN_HEIGHT_P, -1),
    _step("height_d_up", "y", "height D up", "Gains", Op.GAIN_HEIGHT_D, +1),
    _step("height_d_down", "h", "height D down", "Gains", Op.GAIN_HEIGHT_D, -1),
    KeyBinding(("f2",), Action("log_start", "log: start recording", "Log", Op.LOG_START)),
    KeyBinding(("f3",), Action("log_stop", "log: stop recording", "Log", Op.LOG_STOP)),
    _local("log_reset", ("f4",), "log: erase the flash (SAFE only; asks first)", "Log"),
    _local("log_download", ("f5",), "log: download to CSV (SAFE only)", "Log"),
    _local("profile", ("f6",), "profile: ask the board for task timings", "Screen"),
    _local("help", ("f1", "question_mark"), "this help", "Screen"),
    _local("show_flight", ("f7",), "flight panel", "Screen"),
    _local("show_plots", ("f8",), "live plots", "Screen"),
    _local("show_profile", ("f9",), "profiling table", "Screen"),
    _local("show_wireless", ("f10",), "wireless screen: the phone's controls, for the mouse", "Screen"),
    _local("show_params", ("f11",), "parameter screen: the board's parameters, search, edit", "Screen"),
    _local("show_joystick", ("f12",), "joystick screen: live axes, mapping, dead zone, save", "Screen"),
    _local("clear_events", ("ctrl+l",), "clear the events list", "Screen"),
    _local("show_console", ("ctrl+t",), "console: the board's text (printf on the UART, qb_log lines)", "Screen"),
    _local("motor_test", ("ctrl+o",), "motor test: spin a motor on the bench, props off (SAFE only; asks first)",
           "Screen"),
)

# Keys Textual itself gives meaning to; shown in the help table, not rebound.
APP_KEYS: tuple[tuple[str, str], ...] = (
    ("ctrl+p", "command palette: every action by name"),
    ("ctrl+q", "quit (while the motors run it asks first, and sends PANIC before it goes)"),
)

# Key presets: action name -> keys, applied to the default map before the config's own [keys].
KEY_PRESETS: dict[str, dict[str, tuple[str, ...]]] = {
    "lab": {},  # the lab's map, the default: ← is "roll up" (a positive roll trim banks right)
    "natural": {"roll_down": ("left",), "roll_up": ("right",)},  # ← banks left, → banks right
}
PRESET_TEXT = {"lab": "the lab's map (default): ← rolls right, → rolls left",
               "natural": "natural arrows: ← banks left, → banks right"}

JOYSTICK_HELP: tuple[tuple[str, str], ...] = (
    ("joystick fire", "PANIC"),
    ("joystick axes", "0 roll, 1 pitch, 2 yaw (twist), 3 throttle (lift); trims add to them"),
)


class KeymapError(ValueError):
    """A key map from the config that cannot be used; the message is one line."""


# The pilot's way out: each of these keeps at least one key every terminal sends, whatever the config says.
SAFETY_ACTIONS: dict[str, str] = {"mode_panic": "PANIC", "mode_safe": "SAFE", "lift_down": "lift down"}
MODIFIERS = ("ctrl", "alt", "shift", "meta", "super", "hyper")  # Textual's order in a combined key name


@cache
def _key_names() -> tuple[frozenset[str], dict[str, str]]:
    """Every key name Textual reports without the kitty keyboard protocol (its ``Keys`` plus the name of each
    printable character: "a", "A", "1", "question_mark", "plus", ...), and its aliases (ctrl+i is tab)."""
    from textual.keys import KEY_ALIASES, KEY_NAME_REPLACEMENTS, Keys

    names = {k.value for k in Keys if not k.value.startswith("<") and k.value != "ctrl-at"}
    for c in string.printable:
        if c.isspace() and c != " ":
            continue  # tab and enter are in Keys; the other control characters are no keys
        name = c if c.isalnum() else unicodedata.name(c).lower().replace("-", "_").replace(" ", "_")
        names.add(KEY_NAME_REPLACEMENTS.get(name, name))
    canonical = {alias: key for key, aliases in KEY_ALIASES.items() for alias in aliases}
    return frozenset(names), canonical


def normalise_key(key: str, where: str) -> str:
    """A key name from the config as Textual names it ("?" -> "question_mark"); an unknown name is refused.

    Plain names are what every terminal sends; a modifier on top ("alt+x", "shift+f5") is accepted too, for
    terminals that speak the kitty keyboard protocol."""
    names, _ = _key_names()
    if len(key) == 1 and not key.isalnum():
        key = unicodedata.name(key, key).lower().replace("-", "_").replace(" ", "_")
        from textual.keys import KEY_NAME_REPLACEMENTS

        key = KEY_NAME_REPLACEMENTS.get(key, key)
    if key in names:
        return key
    *mods, base = key.split("+")
    if base in names and mods and len(set(mods)) == len(mods) and all(m in MODIFIERS for m in mods):
        return key
    raise KeymapError(f"{where}: unknown key name {key!r}{nearest(key, names)}; keys are named as Textual names "
                      "them: a, A, 1, escape, space, enter, up, f5, ctrl+x, question_mark, ...")


@cache
def _character_keys() -> frozenset[str]:
    """The key names of printable characters ("a", "1", "slash", "space", ...): what a text box takes as text."""
    from textual.keys import KEY_NAME_REPLACEMENTS

    names = set()
    for c in string.printable:
        if c.isspace() and c != " ":
            continue
        name = c if c.isalnum() else unicodedata.name(c).lower().replace("-", "_").replace(" ", "_")
        names.add(KEY_NAME_REPLACEMENTS.get(name, name))
    return frozenset(names)


def is_character_key(key: str) -> bool:
    """A key that types a character (a letter, digit, punctuation, space; any one character, umlauts too)."""
    return key in _character_keys() or len(key) == 1


# Out of SAFE these act whatever has the focus, a text box included: they are never text while the craft can fly.
PRIORITY_IN_FLIGHT = frozenset({"mode_panic", "mode_safe"})


def _plain(key: str) -> bool:
    return key in _key_names()[0]


def _canonical(key: str) -> str:
    return _key_names()[1].get(key, key)


def build_keymap(overrides: Mapping[str, Sequence[str] | str] | None = None,
                 preset: str = "lab") -> tuple[KeyBinding, ...]:
    """The default map with the ``preset`` (``KEY_PRESETS``) and then ``overrides`` (action name -> key or keys)
    applied.

    Refused, in one line: an unknown action, a value that is not a key name or a list of them, an unknown key
    name, a key given twice, an empty list, a key bound to two actions (aliases count: ctrl+i is tab), a key
    Textual keeps for itself, and a safety action (PANIC, SAFE, lift down) left without a plain key."""
    if preset not in KEY_PRESETS:
        raise KeymapError(f"[keys] preset: {shown(preset)} is not a key preset{nearest(str(preset), KEY_PRESETS)}; "
                          f"known: {', '.join(KEY_PRESETS)}")
    table = list(DEFAULT_KEYMAP)
    by_name = {b.action.name: i for i, b in enumerate(table)}
    for name, keys in KEY_PRESETS[preset].items():
        table[by_name[name]] = replace(table[by_name[name]], keys=keys)
    if overrides is not None and not isinstance(overrides, Mapping):
        raise KeymapError(f"[keys]: must be a table of action = key names, got {shown(overrides)}")
    for name, keys in (overrides or {}).items():
        if name not in by_name:
            raise KeymapError(f"unknown action {name!r} in [keys]{nearest(name, by_name)}; known: "
                              f"{', '.join(sorted(by_name))}")
        where = f"[keys] {name}"
        keys_t = [keys] if isinstance(keys, str) else keys
        if not isinstance(keys_t, list | tuple) or not keys_t or not all(isinstance(k, str) and k for k in keys_t):
            raise KeymapError(f"{where}: give a key name or a list of key names, got {shown(keys)}")
        normal = [normalise_key(k, where) for k in keys_t]
        for i, k in enumerate(normal):
            if _canonical(k) in map(_canonical, normal[:i]):
                raise KeymapError(f"{where}: key {k!r} is given twice")
        if name in SAFETY_ACTIONS and not any(_plain(k) for k in normal):
            raise KeymapError(f"{where}: {SAFETY_ACTIONS[name]} needs at least one key every terminal sends "
                              f"(a letter, digit, escape, f1..f12, ...), not only {', '.join(normal)}")
        table[by_name[name]] = replace(table[by_name[name]], keys=tuple(normal))
    seen: dict[str, tuple[str, str]] = {}  # canonical key -> (action, the key as written)
    for b in table:
        for k in b.keys:
            c = _canonical(k)
            if c in seen:
                other, written = seen[c]
                where = next((f"[keys] {n}: " for n in (b.action.name, other) if n in (overrides or {})), "")
                same = f" (the same key as {written!r})" if written != k else ""
                raise KeymapError(f"{where}key {k!r}{same} is bound to both {other} and {b.action.name}")
            seen[c] = (b.action.name, k)
    for k, text in APP_KEYS:
        if k in seen:
            raise KeymapError(f"[keys] {seen[k][0]}: key {k!r} is reserved ({text})")
    return tuple(table)


def action_for_key(keymap: Iterable[KeyBinding], key: str) -> Action | None:
    for b in keymap:
        if key in b.keys:
            return b.action
    return None


def action_by_name(keymap: Iterable[KeyBinding], name: str) -> Action | None:
    for b in keymap:
        if b.action.name == name:
            return b.action
    return None


_PRETTY = {"escape": "ESC", "left": "←", "right": "→", "up": "↑", "down": "↓", "question_mark": "?"}


def pretty_key(key: str) -> str:
    return _PRETTY.get(key, key.upper() if key.startswith("f") and key[1:].isdigit() else key)


def help_rows(keymap: Iterable[KeyBinding]) -> list[tuple[str, str, str]]:
    """(group, keys, description) rows for the help screen and the user guide, in table order."""
    rows = [(b.action.group, ", ".join(pretty_key(k) for k in b.keys), b.action.description) for b in keymap]
    rows += [("Joystick", k, d) for k, d in JOYSTICK_HELP]
    rows += [("App", pretty_key(k), d) for k, d in APP_KEYS]
    return rows


def help_markdown(keymap: Iterable[KeyBinding] = DEFAULT_KEYMAP) -> str:
    """The key table as Markdown (docs/user-guide.md carries it; a test keeps the two in sync)."""
    lines = ["| group | key | action |", "|---|---|---|"]
    for group, keys, text in help_rows(keymap):
        cell = keys.replace("|", "\\|")
        lines.append(f"| {group} | {cell} | {text} |")
    return "\n".join(lines)
