"""The TOML config: defaults, every section, and one clear line for a malformed file."""

from pathlib import Path

import pytest

from term.input.keymap import action_for_key
from term.input.mapping import XBOX, AxisMap, StickMapping
from term.session.config import Config, ConfigError, forced_mapping, load_config, save_joystick_mapping


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
    ("[connection]\nbaud = 'fast'", "[connection] baud: must be an integer between 50 and 4000000 baud, got \"fast\""),
    ("[connection]\nbaud = 100000000000000000000", "got 100000000000000000000"),
    ("[connection]\nbaud = 9600.0", "baud: must be an integer"),
    ("[connection]\nbaud = true", "baud: must be an integer"),
    ("[connection]\nlink_timeout = -1", "link_timeout: must be a number between 0.05 and 60 s, got -1"),
    ("[connection]\nlink_timeout = nan", "link_timeout: must be a number between 0.05 and 60 s, got nan"),
    ("[connection]\nlink_timeout = inf", "got inf"),
    ("[connection]\nlink_timout = 1", "unknown key 'link_timout' in [connection] (did you mean 'link_timeout'?)"),
    ("[connection]\nport = ''", "[connection] port: must be a port name (not empty)"),
    ("[connection]\njoystick = 'sometimes'", "joystick: must be one of: stream, on-change, fixed-rate"),
    ("[keys]\nlift_up = 'z'", "bound to both"),
    ("[keys]\nmode_panic = 5", "[keys] mode_panic: give a key name or a list of key names, got 5"),
    ("[keys]\nmode_panic = ['nosuchkey']", "[keys] mode_panic: unknown key name 'nosuchkey'"),
    ("keys = 3", "[keys]: must be a table"),
    ("[plots]\nseries = ['phi', 'nope']", "[plots] series[1]: must be one of: phi,"),
    ("[plots]\nseries = [{a = 1}]", "[plots] series[0]: must be one of"),
    ("[plots]\nseries = []", "[plots] series: must be a list of 1 to"),
    ("[plots]\nseries = ['phi', 'phi']", "[plots] series: \"phi\" is given twice"),
    ("[plots]\nwindow = nan", "[plots] window: must be a number between 1 and 60 s, got nan"),
    ("[plots]\nwindow = -5", "got -5"),
    ("[joystick]\nmapping = 'xbx'", "neither a preset nor in [joystick.mappings] (did you mean 'xbox'?)"),
    ("[joystick]\nresolution = 0", "[joystick] resolution: must be an integer between 1 and 4096 stick units, got 0"),
    ("[joystick]\nresolution = -64", "got -64"),
    ("[joystick.mappings.x]\nroll = 2", "[joystick.mappings.x] roll: must be a table"),
    ("[joystick.mappings.x]\nmatch = 5", "[joystick.mappings.x] match[0]: must be a string (not empty), got 5"),
    ("[joystick.mappings.x]\nroll = {axis = 0, invert = 'false'}", "roll.invert: must be true or false, got \"false\""),
    ("[joystick.mappings.x]\nroll = {axis = -1}", "roll.axis: must be an integer between 0 and 63, got -1"),
    ("[joystick.mappings.x]\nroll = {axs = 1}",
     "unknown key 'axs' in [joystick.mappings.x] roll (did you mean 'axis'?)"),
    ("[joystick.mappings.x]\nfire = [0, 0]", "fire: 0 is given twice"),
    ('[log]\ndirectory = "a\\u0000b"', "[log] directory: must not hold a NUL character"),
    ("[wat]\nx = 1", "unknown key 'wat'"),
    ("connection = 3", "[connection]: must be a table"),
    ("a = " + "[" * 3000 + "]" * 3000, "nest too deeply"),
])
def test_a_malformed_file_is_one_clear_line(tmp_path: Path, text: str, words: str) -> None:
    path = write(tmp_path, text)
    with pytest.raises(ConfigError) as exc:
        load_config(path)
    msg = str(exc.value)
    assert words in msg and str(path) in msg and "\n" not in msg, msg


@pytest.mark.parametrize("data, words", [
    (b"\xfc\x00\x01binary", "is not UTF-8 text (byte 0xfc at offset 0)"),
    (b"[connection]\nport = '\xff\xfe'\n", "is not UTF-8 text (byte 0xff at offset 21)"),
    (b"x = '\x00'", "not valid TOML"),
])
def test_a_file_that_is_not_utf8_toml_is_one_line(tmp_path: Path, data: bytes, words: str) -> None:
    path = tmp_path / "term.toml"
    path.write_bytes(data)
    with pytest.raises(ConfigError) as exc:
        load_config(path)
    assert words in str(exc.value) and "\n" not in str(exc.value), exc.value


def test_a_directory_or_a_huge_file_is_one_line(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match="config file .* is a directory"):
        load_config(tmp_path)
    with pytest.raises(ConfigError, match="is a device, not a file"):  # refused before a byte is read
        load_config(Path("/dev/zero"))
    huge = tmp_path / "huge.toml"
    huge.write_bytes(b"#" * 1_000_001)
    with pytest.raises(ConfigError, match="larger than 1 MB"):
        load_config(huge)


def test_the_panic_key_cannot_be_lost(tmp_path: Path) -> None:
    """Issue 10: `mode_panic = ["nosuchkey"]` was accepted and PANIC had no key left."""
    for bad in ('["nosuchkey"]', "[]", '""', '["alt+p"]', '["1", "1"]'):
        with pytest.raises(ConfigError, match=r"\[keys\] mode_panic"):
            load_config(write(tmp_path, f"[keys]\nmode_panic = {bad}\n"))
    cfg = load_config(write(tmp_path, '[keys]\nmode_panic = ["space", "alt+p"]\nhelp = ["f1", "?"]\n'))
    assert action_for_key(cfg.keymap, "space").name == "mode_panic"
    assert action_for_key(cfg.keymap, "question_mark").name == "help"  # "?" is Textual's question_mark


# --- the joystick mapping's save (the F12 screen): the user's file kept as written ----------------------------

COMMENTED = """\
# my settings, by hand
[connection]   # the cable
port = "/dev/ttyUSB0"  # the lab's
baud = 115200

# the stick
[joystick]
mapping = ""   # pick by name
resolution = 64

[joystick.mappings.old_pad]  # my old pad
match = ["Old"]
roll = { axis = 0 }
pitch = { axis = 1 }
yaw = { axis = 2 }
lift = { axis = 3, invert = true, kind = "throttle" }
# said after the old pad

# the plots, next
[plots]
window = 20.0 # seconds
# the end
"""


def _pad(lift_deadzone: float = 0.08) -> StickMapping:
    return StickMapping("x", ("Pad",), AxisMap(0), AxisMap(1, True), AxisMap(2),
                        AxisMap(3, True, lift_deadzone, "throttle"), (0, 1))


def _table_span(text: str, header: str) -> tuple[int, int]:
    """Where the table ``header`` starts and where its keys end (the line after its last key)."""
    start = text.index(header)
    end = start
    for line in text[start:].splitlines(keepends=True)[1:]:
        if not line.strip() or line.lstrip().startswith(("#", "[")):
            break
        end += len(line)
    return start, end + len(text[start:].splitlines(keepends=True)[0])


JOYSTICK_FIRST = "# mine\n[joystick]  # the stick\nmapping = \"\"\n\n# the plots\n[plots]\nwindow = 5.0\n"


@pytest.mark.parametrize("original", [COMMENTED, JOYSTICK_FIRST, "", "# only a comment\n"])
def test_a_saved_mapping_keeps_the_rest_of_a_commented_file_byte_for_byte(tmp_path: Path, original: str) -> None:
    """Issue 25: the save edited the file line by line and could lose comments near the table it replaced."""
    path = write(tmp_path, original)
    assert save_joystick_mapping(path, _pad(), "Virtual Joystick") == "virtual_joystick"
    text = path.read_text(encoding="utf-8")
    start, end = _table_span(text, "[joystick.mappings.virtual_joystick]")
    head, tail = text[:start], text[end:]  # a new table (with a blank line on one side), and nothing else changed
    assert original in (head + tail, head + tail.removeprefix("\n"), head.removesuffix("\n") + tail), text
    mine = next(m for m in load_config(path, required=True).joystick_mappings if m.name == "virtual_joystick")
    assert mine.match == ("Virtual Joystick",) and mine.lift.deadzone == 0.08 and mine.fire == (0, 1)

    before = text
    save_joystick_mapping(path, _pad(0.12), "Virtual Joystick")  # again: the same table, replaced in place
    text = path.read_text(encoding="utf-8")
    assert text.count("[joystick.mappings.virtual_joystick]") == 1
    old_start, old_end = _table_span(before, "[joystick.mappings.virtual_joystick]")
    new_start, new_end = _table_span(text, "[joystick.mappings.virtual_joystick]")
    assert text[:new_start] == before[:old_start] and text[new_end:] == before[old_end:]
    assert "deadzone = 0.12" in text[new_start:new_end]


def test_replacing_a_mapping_keeps_its_comments(tmp_path: Path) -> None:
    path = write(tmp_path, COMMENTED)
    save_joystick_mapping(path, _pad(), "Old Pad")
    text = path.read_text(encoding="utf-8")
    start, end = _table_span(text, "[joystick.mappings.old_pad]")
    old_start, old_end = _table_span(COMMENTED, "[joystick.mappings.old_pad]")
    assert text[:start] == COMMENTED[:old_start] and text[end:] == COMMENTED[old_end:]
    assert "[joystick.mappings.old_pad]  # my old pad\n" in text and '"Old Pad"' in text


@pytest.mark.parametrize("text, words", [
    ("[joystick\n", "not saved, it does not read as a config"),
    ("joystick = 3\n", "not saved"),
    ("[keys]\nmode_panic = ['nosuchkey']\n", "not saved, it would not load"),
])
def test_a_file_that_cannot_take_the_mapping_is_left_alone(tmp_path: Path, text: str, words: str) -> None:
    path = write(tmp_path, text)
    with pytest.raises(ConfigError, match=words):
        save_joystick_mapping(path, _pad(), "Virtual Joystick")
    assert path.read_text(encoding="utf-8") == text
