"""The key map: the lab's keys, rebinding from the config, clashes refused, the help generated from it."""

import pytest

from term.input.keymap import (
    DEFAULT_KEYMAP,
    KeymapError,
    action_for_key,
    build_keymap,
    help_markdown,
    help_rows,
)
from term.protocol import Mode, Op

# DESIGN.md's table, key by key.
LAB = {
    "0": (Op.MODE, Mode.SAFE), "1": (Op.MODE, Mode.PANIC), "escape": (Op.MODE, Mode.PANIC),
    "2": (Op.MODE, Mode.MANUAL), "3": (Op.MODE, Mode.CALIBRATION), "4": (Op.MODE, Mode.YAW),
    "5": (Op.MODE, Mode.FULL), "6": (Op.MODE, Mode.RAW), "7": (Op.MODE, Mode.HEIGHT), "8": (Op.WIRELESS, 1),
    "a": (Op.TRIM_LIFT, 1), "z": (Op.TRIM_LIFT, -1),
    "left": (Op.TRIM_ROLL, 1), "right": (Op.TRIM_ROLL, -1),
    "up": (Op.TRIM_PITCH, -1), "down": (Op.TRIM_PITCH, 1),
    "q": (Op.TRIM_YAW, -1), "w": (Op.TRIM_YAW, 1),
    "u": (Op.GAIN_YAW_P, 1), "j": (Op.GAIN_YAW_P, -1),
    "i": (Op.GAIN_P1, 1), "k": (Op.GAIN_P1, -1),
    "o": (Op.GAIN_P2, 1), "l": (Op.GAIN_P2, -1),
}


@pytest.mark.parametrize("key", sorted(LAB))
def test_the_labs_keys(key: str) -> None:
    action = action_for_key(DEFAULT_KEYMAP, key)
    assert action is not None and (action.op, action.arg) == LAB[key]


def test_every_action_has_one_kind_and_unique_keys() -> None:
    keys = [k for b in DEFAULT_KEYMAP for k in b.keys]
    assert len(keys) == len(set(keys))
    for b in DEFAULT_KEYMAP:
        assert (b.action.op is None) != (b.action.local is None)
    assert len({b.action.name for b in DEFAULT_KEYMAP}) == len(DEFAULT_KEYMAP)


def test_rebinding_from_the_config() -> None:
    km = build_keymap({"mode_panic": ["space", "escape"], "lift_up": "plus"})
    assert action_for_key(km, "space").name == "mode_panic"
    assert action_for_key(km, "1") is None  # the old key is free now
    assert action_for_key(km, "plus").name == "lift_up"


@pytest.mark.parametrize("overrides, words", [
    ({"no_such": "x"}, "unknown action"),
    ({"lift_up": "z"}, "bound to both"),
    ({"lift_up": []}, "give a key"),
    ({"lift_up": "ctrl+q"}, "reserved"),
])
def test_bad_rebindings_are_one_clear_line(overrides: dict, words: str) -> None:
    with pytest.raises(KeymapError) as exc:
        build_keymap(overrides)
    assert words in str(exc.value) and "\n" not in str(exc.value)


def test_help_is_generated_from_the_map() -> None:
    rows = help_rows(DEFAULT_KEYMAP)
    assert ("Modes", "1, ESC", "PANIC: controlled descent, then SAFE") in rows
    assert any(r[0] == "Joystick" and "PANIC" in r[2] for r in rows)
    md = help_markdown()
    for b in DEFAULT_KEYMAP:
        assert b.action.description in md


def test_the_user_guide_carries_the_generated_key_table() -> None:
    from pathlib import Path

    text = (Path(__file__).parent.parent / "docs" / "user-guide.md").read_text(encoding="utf-8")
    table = text.split("<!-- keys:begin -->\n", 1)[1].split("\n<!-- keys:end -->", 1)[0]
    assert table == help_markdown(), "regenerate the table: python -c 'from term.input.keymap import help_markdown"
