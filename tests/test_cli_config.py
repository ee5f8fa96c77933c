"""The TOML config: defaults, every section, and one clear line for a malformed file."""

from pathlib import Path

import pytest

from term.config import Config, ConfigError, forced_mapping, load_config
from term.input.keymap import action_for_key
from term.input.mapping import XBOX


def write(tmp_path: Path, text: str) -> Path:
    p = tmp_path / "term.toml"
    p.write_text(text, encoding="utf-8")
    return p


def test_missing_default_file_means_defaults(tmp_path: Path) -> None:
    cfg = load_config(tmp_path / "absent.toml")
    assert cfg == Config(log_directory=cfg.log_directory)
    with pytest.raises(ConfigError, match="not found"):
        load_config(tmp_path / "absent.toml", required=True)


def test_every_section(tmp_path: Path) -> None:
    cfg = load_config(write(tmp_path, """
[connection]
port = "/dev/ttyUSB1"
baud = 57600
link_timeout = 0.5
joystick = "on-change"
[keys]
mode_panic = ["space", "escape"]
[joystick]
mapping = "xbox"
resolution = 128
[joystick.mappings.thrust]
match = ["Thrustmaster"]
lift = { axis = 2, invert = true, kind = "throttle" }
[plots]
series = ["height", "setpoint", "vz"]
window = 20
[log]
directory = "~/logs-here"
"""))
    assert (cfg.port, cfg.baud, cfg.link_timeout) == ("/dev/ttyUSB1", 57600, 0.5)
    assert cfg.joystick_policy == "on-change"
    assert action_for_key(cfg.keymap, "space").name == "mode_panic"
    assert forced_mapping(cfg) is XBOX and cfg.joystick_resolution == 128
    assert cfg.joystick_mappings[0].name == "thrust" and cfg.joystick_mappings[0].lift.index == 2
    assert cfg.plot_series == ("height", "setpoint", "vz") and cfg.plot_window == 20.0
    assert cfg.log_directory == Path.home() / "logs-here"


@pytest.mark.parametrize("text, words", [
    ("[connection\nport = 1", "not valid TOML"),
    ("[connection]\nbaud = 'fast'", "baud must be int"),
    ("[connection]\nlink_timeout = -1", "must be positive"),
    ("[connection]\njoystick = 'sometimes'", "joystick must be one of: stream, on-change, fixed-rate"),
    ("[keys]\nlift_up = 'z'", "bound to both"),
    ("[plots]\nseries = ['phi', 'nope']", "unknown series 'nope'"),
    ("[joystick]\nmapping = 'mystery'", "neither a preset"),
    ("[joystick.mappings.x]\nroll = 2", "roll needs"),
    ("[wat]\nx = 1", "unknown section"),
    ("connection = 3", "must be a table"),
])
def test_a_malformed_file_is_one_clear_line(tmp_path: Path, text: str, words: str) -> None:
    path = write(tmp_path, text)
    with pytest.raises(ConfigError) as exc:
        load_config(path)
    msg = str(exc.value)
    assert words in msg and str(path) in msg and "\n" not in msg
