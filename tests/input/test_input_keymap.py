"""The key map: the lab's keys, rebinding from the config, clashes refused, the help generated from it."""

import pytest

from term.core.protocol import Mode, Op
from term.input.keymap import (
    DEFAULT_KEYMAP,
    KeymapError,
    action_for_key,
    build_keymap,
    help_markdown,
    help_rows,
)
from tests.support.paths import DOCS

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
    ({"mode_pnic": "x"}, "unknown action 'mode_pnic' in [keys] (did you mean 'mode_panic'?)"),
    ({"lift_up": "z"}, "[keys] lift_up: key 'z' is bound to both lift_up and lift_down"),
    ({"lift_up": []}, "give a key"),
    ({"lift_up": "ctrl+q"}, "[keys] lift_up: key 'ctrl+q' is reserved"),
    ({"lift_up": 5}, "[keys] lift_up: give a key name or a list of key names, got 5"),
    ({"lift_up": [True]}, "give a key name"),
    ({"lift_up": "a,b"}, "unknown key name 'a,b'"),  # Textual would read it as two keys, unchecked
    ({"lift_up": "Escape"}, "unknown key name 'Escape' (did you mean 'escape'?)"),
    ({"lift_up": "ctrl+ctrl+x"}, "unknown key name"),
    ({"lift_up": ["x", "x"]}, "[keys] lift_up: key 'x' is given twice"),
    ({"lift_up": ["tab", "ctrl+i"]}, "key 'ctrl+i' is given twice"),  # Textual's alias of tab
    ({"lift_up": "tab", "yaw_up": "ctrl+i"}, "key 'ctrl+i' (the same key as 'tab') is bound to both"),
    ({"help": "?", "lift_up": "question_mark"}, "bound to both"),
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

    text = (DOCS / "user-guide.md").read_text(encoding="utf-8")
    table = text.split("<!-- keys:begin -->\n", 1)[1].split("\n<!-- keys:end -->", 1)[0]
    assert table == help_markdown(), "regenerate the table: python -c 'from term.input.keymap import help_markdown"


@pytest.mark.parametrize("name, text", [("mode_panic", "PANIC"), ("mode_safe", "SAFE"), ("lift_down", "lift down")])
@pytest.mark.parametrize("keys", [["nosuchkey"], [], "", ["alt+p"], ["shift+f5", "super+x"], ["x", "x"], 5])
def test_the_safety_keys_cannot_be_lost(name: str, text: str, keys: object) -> None:
    """Issue 10: `mode_panic = ["nosuchkey"]` was accepted and PANIC was silently gone."""
    with pytest.raises(KeymapError) as exc:
        build_keymap({name: keys})  # type: ignore[dict-item]
    assert str(exc.value).startswith(f"[keys] {name}: "), exc.value
    km = build_keymap({name: ["alt+p", "space"]})  # a modifier key beside a plain one is fine
    assert action_for_key(km, "space").name == name and action_for_key(km, "alt+p").name == name


def test_key_names_are_textuals() -> None:
    km = build_keymap({"lift_up": "+", "lift_down": "minus", "mode_panic": ["escape", "A", "f20", "ctrl+x"]})
    assert action_for_key(km, "plus").name == "lift_up"  # a punctuation character becomes Textual's name for it
    assert action_for_key(km, "minus").name == "lift_down"
    assert action_for_key(km, "A").name == "mode_panic" and action_for_key(km, "a") is None  # case matters
    assert [b.keys for b in km if b.action.name == "mode_panic"] == [("escape", "A", "f20", "ctrl+x")]
