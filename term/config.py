"""The terminal's TOML config file, in the platform's config directory (platformdirs).

Everything is optional; a missing file means the defaults. A malformed file is reported in one line (``ConfigError``)
naming the file and the problem. Example (``term --print-config`` prints the defaults in this form)::

    [connection]
    port = "/dev/ttyUSB0"      # used when neither --serial nor --sim is given
    baud = 115200
    link_timeout = 0.5         # seconds without a frame before the terminal shows LINK LOST
    joystick = "stream"        # or "on-change", "fixed-rate" (see JOYSTICK_POLICIES below)

    [keys]                     # rebind any action by name (see the help screen, F1)
    mode_panic = ["1", "escape"]

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

import tomllib
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from term.input.keymap import KeyBinding, KeymapError, build_keymap
from term.input.mapping import MappingError, StickMapping, mapping_from_dict

APP_NAME = "quadrupel"
FILE_NAME = "term.toml"

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


class ConfigError(ValueError):
    """The config file cannot be used; the message is one line naming the file."""


@dataclass
class Config:
    port: str | None = None
    baud: int = 115200
    link_timeout: float = 0.5  # as the board's: LINK LOST shows no later than the board's own PANIC
    joystick_policy: str = "stream"
    keymap: tuple[KeyBinding, ...] = field(default_factory=build_keymap)
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
    user named (``required``) is an error."""
    path = path or default_path()
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        if required:
            raise ConfigError(f"config file {path} not found") from None
        return Config()
    except OSError as exc:
        raise ConfigError(f"cannot read config file {path}: {exc.strerror}") from None
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"config file {path} is not valid TOML: {exc}") from None
    try:
        cfg = config_from_dict(data)
    except (ConfigError, KeymapError, MappingError) as exc:
        raise ConfigError(f"config file {path}: {exc}") from None
    cfg.source = path
    return cfg


def _table(data: Mapping[str, Any], name: str) -> Mapping[str, Any]:
    t = data.get(name, {})
    if not isinstance(t, Mapping):
        raise ConfigError(f"[{name}] must be a table")
    return t


def _get(t: Mapping[str, Any], section: str, key: str, kind: type | tuple[type, ...], default: Any) -> Any:
    v = t.get(key, default)
    if v is not default and (not isinstance(v, kind) or isinstance(v, bool) and bool not in _as_tuple(kind)):
        names = "/".join(k.__name__ for k in _as_tuple(kind))
        raise ConfigError(f"[{section}] {key} must be {names}, not {v!r}")
    return v


def _as_tuple(kind: type | tuple[type, ...]) -> tuple[type, ...]:
    return kind if isinstance(kind, tuple) else (kind,)


def config_from_dict(data: Mapping[str, Any]) -> Config:
    known = {"connection", "keys", "joystick", "plots", "log"}
    for k in data:
        if k not in known:
            raise ConfigError(f"unknown section [{k}]; known: {', '.join(sorted(known))}")
    cfg = Config()
    conn = _table(data, "connection")
    cfg.port = _get(conn, "connection", "port", str, None)
    cfg.baud = _get(conn, "connection", "baud", int, cfg.baud)
    cfg.link_timeout = float(_get(conn, "connection", "link_timeout", (int, float), cfg.link_timeout))
    if cfg.baud <= 0 or cfg.link_timeout <= 0:
        raise ConfigError("[connection] baud and link_timeout must be positive")
    cfg.joystick_policy = _get(conn, "connection", "joystick", str, cfg.joystick_policy)
    if cfg.joystick_policy not in JOYSTICK_POLICIES:
        raise ConfigError(f"[connection] joystick must be one of: {', '.join(JOYSTICK_POLICIES)}")

    keys = _table(data, "keys")
    cfg.keymap = build_keymap(dict(keys))

    js = _table(data, "joystick")
    cfg.joystick_mapping = _get(js, "joystick", "mapping", str, "")
    cfg.joystick_resolution = _get(js, "joystick", "resolution", int, cfg.joystick_resolution)
    maps = _get(js, "joystick", "mappings", dict, {})
    cfg.joystick_mappings = tuple(mapping_from_dict(name, m) for name, m in maps.items() if isinstance(m, dict))
    if cfg.joystick_mapping:
        from term.input.mapping import PRESETS

        names = {m.name for m in (*cfg.joystick_mappings, *PRESETS)} | {"lab", "xbox", "playstation"}
        if cfg.joystick_mapping not in names:
            raise ConfigError(f"[joystick] mapping {cfg.joystick_mapping!r} is neither a preset nor in "
                              "[joystick.mappings]")

    plots = _table(data, "plots")
    series = _get(plots, "plots", "series", list, list(cfg.plot_series))
    bad = [s for s in series if s not in PLOT_SERIES]
    if bad:
        raise ConfigError(f"[plots] unknown series {bad[0]!r}; known: {', '.join(PLOT_SERIES)}")
    cfg.plot_series = tuple(series)
    cfg.plot_window = float(_get(plots, "plots", "window", (int, float), cfg.plot_window))

    log = _table(data, "log")
    directory = _get(log, "log", "directory", str, None)
    if directory:
        cfg.log_directory = Path(directory).expanduser()
    return cfg


def forced_mapping(cfg: Config) -> StickMapping | None:
    """The mapping the config forces by name, if any."""
    if not cfg.joystick_mapping:
        return None
    from term.input.mapping import LAB, PLAYSTATION, PRESETS, XBOX

    short = {"lab": LAB, "xbox": XBOX, "playstation": PLAYSTATION}
    if cfg.joystick_mapping in short:
        return short[cfg.joystick_mapping]
    for m in (*cfg.joystick_mappings, *PRESETS):
        if m.name == cfg.joystick_mapping:
            return m
    return None
