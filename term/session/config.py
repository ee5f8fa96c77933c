"""The terminal's TOML config file, in the platform's config directory (platformdirs).

Everything is optional; a missing file means the defaults. Every value is checked where it is read, against one
schema (``CONFIG_SCHEMA``: section, key, type, range): a wrong type, nan or inf, a number out of range, an unknown
section or key (with the nearest known one), bad UTF-8 or bad TOML is a ``ConfigError`` of one line naming the
file, the key and what is allowed, e.g. ``config file term.toml: [connection] link_timeout: must be a number
between 0.05 and 60 s, got nan``. The key map refuses unknown key names, and PANIC, SAFE and lift down always
keep a key (term/input/keymap.py). An example::

    [connection]
    port = "/dev/ttyUSB0"      # used when neither --serial nor --sim is given
    baud = 115200
    link_timeout = 0.5         # seconds without a frame before the terminal shows LINK LOST
    joystick = "stream"        # or "on-change", "fixed-rate" (see JOYSTICK_POLICIES below)

    [keys]                     # rebind any action by name (see the help screen, F1)
    preset = "lab"             # or "natural": ← banks left, → banks right (the lab's map banks right on ←)
    mode_panic = ["1", "escape"]

    [alarms]
    bell = true                # the terminal's bell on LINK LOST, PANIC, low battery and a crash

    [params]
    file = "~/quadrupel/my-board.toml"   # a set saved with 'term params save' (or the parameter screen)
    apply_on_connect = false   # true: sent to the board each time it says Hello (docs/parameters.md)

    [joystick]
    mapping = ""               # force a mapping by name; empty: pick by the stick's name
    resolution = 64            # stick units below which a change is jitter

    [joystick.mappings.my_stick]
    match = ["Thrustmaster"]
    roll = { axis = 0 }
    lift = { axis = 2, invert = true, kind = "throttle" }
    fire = [0]

    [plots]
    series = ["phi", "theta", "psi", "height"]
    window = 10.0              # seconds shown

    [log]
    directory = "~/quadrupel-logs"
"""

from __future__ import annotations

import os
import tomllib
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from term.core.logfile import check_directory
from term.core.protocol import BAUD_RATE, LINK_TIMEOUT_RANGE_S, LINK_TIMEOUT_S
from term.core.schema import Flag, ListOf, Number, OneOf, SchemaError, Table, TableOf, Text, nearest, one_line, shown
from term.core.userfile import UserFileError, read_user_text, read_user_toml
from term.input.keymap import KeyBinding, KeymapError, build_keymap
from term.input.mapping import (
    LAB,
    MAPPING_TABLE,
    PLAYSTATION,
    PRESETS,
    RESOLUTION_RANGE,
    XBOX,
    StickMapping,
    mapping_from_dict,
)

APP_NAME = "quadrupel"
FILE_NAME = "term.toml"
CONFIG_MAX_BYTES = 1_000_000  # a config is a few hundred bytes; this keeps `--config /dev/zero` from eating memory

# Telemetry series the plots can show: name -> (label, unit).
PLOT_SERIES: dict[str, tuple[str, str]] = {
    "phi": ("roll φ", "°"),
    "theta": ("pitch θ", "°"),
    "psi": ("yaw ψ", "°"),
    "sp": ("roll rate p", "°/s"),
    "sq": ("pitch rate q", "°/s"),
    "sr": ("yaw rate r", "°/s"),
    "ae1": ("motor 1", ""),
    "ae2": ("motor 2", ""),
    "ae3": ("motor 3", ""),
    "ae4": ("motor 4", ""),
    "height": ("height", "m"),
    "setpoint": ("height set point", "m"),
    "vz": ("vertical speed", "m/s"),
    "pressure": ("pressure", "Pa"),
    "battery": ("battery", "V"),
    "rtt": ("link RTT", "ms"),
}


# How the joystick goes out over the cable (LinkSession options; bench/latency.py measures each):
# - "stream" (default): a change goes out at once (at most one frame per ms), and the latest value is resent
#   every 10 ms while nothing changes, so the board hears the stick at >= 100 Hz and a lost frame is repaired
#   within 10 ms; the joystick poller makes at most 100 changes a second, so the cable carries <= 200 frames/s;
# - "on-change": a change at once, otherwise a keep-alive every 0.1 s (less traffic, slower repair);
# - "fixed-rate": the latest value in fixed 100 Hz slots (a change waits for the next slot: +5 ms on average).
JOYSTICK_POLICIES: dict[str, dict[str, float | bool]] = {
    "stream": {"change_only": True, "joystick_rate": 1000.0, "keepalive": 0.01},
    "on-change": {"change_only": True, "joystick_rate": 1000.0, "keepalive": 0.1},
    "fixed-rate": {"joystick_rate": 100.0},
}


# Ranges of the numbers a user may set (the config file and the same options on the command line).
BAUD = Number(50, 4_000_000, integer=True, unit="baud")  # up to Linux's highest standard rate, B4000000
LINK_TIMEOUT = Number(*LINK_TIMEOUT_RANGE_S, unit="s")  # the board's link.timeout_ms range: nan would never time out
PLOT_WINDOW = Number(1.0, 60.0, unit="s")  # the model keeps 60 s of each series (term/session/model.py HISTORY)


class ConfigError(ValueError):
    """The config file cannot be used; the message is one line naming the file."""


@dataclass
class Config:
    port: str | None = None
    baud: int = BAUD_RATE
    link_timeout: float = LINK_TIMEOUT_S  # the board's default: LINK LOST shows no later than its own stage 1
    joystick_policy: str = "stream"
    keymap: tuple[KeyBinding, ...] = field(default_factory=build_keymap)
    key_preset: str = "lab"
    bell: bool = True  # the terminal's bell on an alarm (term/session/alarms.py)
    params_file: Path | None = None  # a parameter set (term/session/param_client.py) ...
    params_apply: bool = False  # ... sent to the board when it says Hello
    joystick_mapping: str = ""
    joystick_resolution: int = 64
    joystick_mappings: tuple[StickMapping, ...] = ()
    plot_series: tuple[str, ...] = ("phi", "theta", "psi", "height")
    plot_window: float = 10.0
    log_directory: Path = field(default_factory=lambda: Path.home() / "quadrupel-logs")
    source: Path | None = None  # the file these came from, if any


def default_path() -> Path:
    from platformdirs import user_config_path

    return user_config_path(APP_NAME, appauthor=False) / FILE_NAME


def load_config(path: Path | None = None, *, required: bool = False) -> Config:
    """Read ``path`` (default: the platform's config file). A missing default file is fine; a missing file the
    user named (``required``) is an error. Every problem is a ``ConfigError`` of one line naming the file."""
    path = path or default_path()
    if not required and not os.path.lexists(path):
        return Config()
    try:
        data = read_user_toml(path, CONFIG_MAX_BYTES, "config file")
    except UserFileError as exc:
        if required and not os.path.lexists(path):
            raise ConfigError(f"config file {path} not found") from None
        raise ConfigError(one_line(str(exc))) from None
    try:
        cfg = config_from_dict(data)
    except (SchemaError, KeymapError) as exc:
        raise ConfigError(one_line(f"config file {path}: {exc}")) from None
    cfg.source = path
    return cfg


class _KeysSpec:
    """[keys]: the key map checks its own rules (known actions and key names, clashes, safety keys)."""

    section = True

    def describe(self) -> str:
        return "a table of action = key names"

    def check(self, value: Any, where: str) -> tuple[tuple[KeyBinding, ...], str]:
        if not isinstance(value, Mapping):
            raise SchemaError(f"{where}: must be {self.describe()}, got {shown(value)}")
        overrides = dict(value)
        preset = overrides.pop("preset", "lab")
        return build_keymap(overrides, preset), preset


# The file's format in one place: section -> key -> type and range (the defaults are Config's).
CONFIG_SCHEMA = Table({
    "connection": Table({
        "port": Text(nonempty=True, what="a port name"),
        "baud": BAUD,
        "link_timeout": LINK_TIMEOUT,
        "joystick": OneOf(tuple(JOYSTICK_POLICIES)),
    }, section=True),
    "keys": _KeysSpec(),
    "joystick": Table({
        "mapping": Text(),
        "resolution": Number(*RESOLUTION_RANGE, integer=True, unit="stick units"),
        "mappings": TableOf(MAPPING_TABLE),
    }, section=True),
    "plots": Table({
        "series": ListOf(OneOf(tuple(PLOT_SERIES)), min_len=1, max_len=len(PLOT_SERIES), unique=True),
        "window": PLOT_WINDOW,
    }, section=True),
    "log": Table({"directory": Text(nonempty=True, what="a directory")}, section=True),
    "alarms": Table({"bell": Flag()}, section=True),
    "params": Table({"file": Text(nonempty=True, what="a parameter file"), "apply_on_connect": Flag()}, section=True),
})


def config_from_dict(data: Mapping[str, Any]) -> Config:
    """A ``Config`` from parsed TOML, every value checked against ``CONFIG_SCHEMA`` (``SchemaError`` or
    ``KeymapError``, one line naming the section and key)."""
    v = CONFIG_SCHEMA.check(data, "")
    cfg = Config()
    conn = v.get("connection", {})
    cfg.port = conn.get("port", cfg.port)
    cfg.baud = conn.get("baud", cfg.baud)
    cfg.link_timeout = conn.get("link_timeout", cfg.link_timeout)
    cfg.joystick_policy = conn.get("joystick", cfg.joystick_policy)
    if "keys" in v:
        cfg.keymap, cfg.key_preset = v["keys"]
    cfg.bell = v.get("alarms", {}).get("bell", cfg.bell)
    params = v.get("params", {})
    if "file" in params:
        cfg.params_file = Path(params["file"]).expanduser()
    cfg.params_apply = params.get("apply_on_connect", cfg.params_apply)
    if cfg.params_apply and cfg.params_file is None:
        raise SchemaError("[params] apply_on_connect: needs [params] file, the set to apply")

    js = v.get("joystick", {})
    cfg.joystick_resolution = js.get("resolution", cfg.joystick_resolution)
    cfg.joystick_mappings = tuple(mapping_from_dict(name, m) for name, m in (js.get("mappings") or {}).items())
    cfg.joystick_mapping = js.get("mapping", "")
    if cfg.joystick_mapping and forced_mapping(cfg) is None:
        names = [*SHORT_NAMES, *(m.name for m in cfg.joystick_mappings)]
        raise SchemaError(f"[joystick] mapping: {shown(cfg.joystick_mapping)} is neither a preset nor in "
                          f"[joystick.mappings]{nearest(cfg.joystick_mapping, names)}; known: {', '.join(names)}")

    plots = v.get("plots", {})
    cfg.plot_series = tuple(plots.get("series", cfg.plot_series))
    cfg.plot_window = plots.get("window", cfg.plot_window)

    directory = v.get("log", {}).get("directory")
    if directory:
        why = check_directory(Path(directory))
        if why:
            raise SchemaError(f"[log] directory: {why}")
        cfg.log_directory = Path(directory).expanduser()
    return cfg


SHORT_NAMES = ("lab", "xbox", "playstation")


def forced_mapping(cfg: Config) -> StickMapping | None:
    """The mapping the config forces by name, if any."""
    if not cfg.joystick_mapping:
        return None
    short = dict(zip(SHORT_NAMES, (LAB, XBOX, PLAYSTATION), strict=True))
    if cfg.joystick_mapping in short:
        return short[cfg.joystick_mapping]
    for m in (*cfg.joystick_mappings, *PRESETS):
        if m.name == cfg.joystick_mapping:
            return m
    return None


def mapping_table_name(device: str) -> str:
    """A TOML bare key for a device's own mapping ("Logitech Extreme 3D" -> "logitech_extreme_3d")."""
    import re

    return (re.sub(r"[^a-z0-9_-]+", "_", device.lower()).strip("_") or "my_stick")[:40]


def mapping_table(mapping: StickMapping, device: str) -> Any:
    """One ``[joystick.mappings.NAME]`` table for ``mapping`` (a tomlkit table), matching ``device`` by its name."""
    import tomlkit

    table = tomlkit.table()
    table["match"] = [device]
    for key in ("roll", "pitch", "yaw", "lift"):
        a = getattr(mapping, key)
        axis = tomlkit.inline_table()
        axis.update({"axis": a.index, "invert": a.invert, "deadzone": round(a.deadzone, 3), "kind": a.kind})
        table[key] = axis
    table["fire"] = list(mapping.fire)
    return table


def _last_table(table: Any) -> Any:
    """The table drawn last in ``table``'s family (itself or its last sub-table, down), or None."""
    from tomlkit.items import Table

    if not isinstance(table, Table):
        return None
    keyed = [item for key, item in table.value.body if key is not None]
    if keyed and isinstance(keyed[-1], Table):
        return _last_table(keyed[-1])
    return table


def _take_introduction(table: Any) -> list[Any]:
    """The comment lines after ``table``'s last blank line, taken out of it: tomlkit counts them as the table's,
    but they introduce the table below (``# the plots`` above ``[plots]``), where they must stay."""
    from tomlkit.items import Whitespace

    body = table.value.body
    keys = [i for i, (key, _) in enumerate(body) if key is not None]
    blanks = [i for i, (key, item) in enumerate(body) if key is None and isinstance(item, Whitespace)
              and i > (keys[-1] if keys else -1)]
    if not blanks or blanks[-1] == len(body) - 1:
        return []
    taken = [item for _, item in body[blanks[-1] + 1:]]
    del body[blanks[-1]:]  # (the blank line too: tomlkit puts one before the new table's header)
    return taken


def _with_trivia_of(old: Any, new: Any) -> Any:
    """``new`` with what the user wrote around ``old`` (the header's comment, the comments and blank lines after
    its last key, which tomlkit counts as the table's): only the keys change. A new table ends in a blank line."""
    import tomlkit
    from tomlkit.items import Table

    if not isinstance(old, Table):
        new.add(tomlkit.nl())
        return new
    new.trivia.comment_ws, new.trivia.comment = old.trivia.comment_ws, old.trivia.comment
    body = old.value.body
    last_key = max((i for i, (key, _) in enumerate(body) if key is not None), default=-1)
    for _, item in body[last_key + 1:]:
        new.add(item)
    return new


def save_joystick_mapping(path: Path, mapping: StickMapping, device: str) -> str:
    """Write ``mapping`` into the config file at ``path`` as the device's own mapping (replacing an earlier one of
    the same name) and return the table's name. tomlkit edits the document in place: every comment, blank line
    and key outside that one table stays byte for byte as the user wrote it. The new file is checked as the
    terminal will read it before it is written; trouble is a ``ConfigError`` of one line."""
    import tomlkit
    from tomlkit.exceptions import TOMLKitError

    name = mapping_table_name(device)
    try:
        old = read_user_text(path, CONFIG_MAX_BYTES, "config file") if os.path.lexists(path) else ""
    except UserFileError as exc:
        raise ConfigError(one_line(str(exc))) from None
    try:
        doc = tomlkit.parse(old)
        old_mappings = doc.get("joystick", {}).get("mappings", {})
        # A new table goes after the joystick's last one, and the comments that introduce the table below move
        # down with it; a table saved before is replaced where it is.
        before = None if name in old_mappings else _last_table(doc.get("joystick"))
        introduction = _take_introduction(before) if before is not None else []
        joystick = doc.setdefault("joystick", tomlkit.table(is_super_table=True))
        mappings = joystick.setdefault("mappings", tomlkit.table(is_super_table=True))
        mappings[name] = _with_trivia_of(mappings.get(name), mapping_table(mapping, device))
        for item in introduction:
            mappings[name].add(item)
        text = tomlkit.dumps(doc)
        if text.endswith("\n\n") and not old.endswith("\n\n"):  # (a new table at the end: no blank line after)
            text = text[:-1]
    except (TOMLKitError, AttributeError, TypeError) as exc:  # not TOML, or [joystick] is not a table
        raise ConfigError(one_line(f"config file {path}: not saved, it does not read as a config: {exc}")) from None
    try:
        config_from_dict(tomllib.loads(text))
    except (tomllib.TOMLDecodeError, SchemaError, KeymapError) as exc:
        raise ConfigError(one_line(f"config file {path}: not saved, it would not load: {exc}")) from None
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text, encoding="utf-8")
    except OSError as exc:
        raise ConfigError(f"cannot write config file {path}: {exc.strerror or exc}") from None
    return name
