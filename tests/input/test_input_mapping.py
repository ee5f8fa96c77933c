"""Joystick mapping as pure logic (plain numbers in, Joystick packets out), and pygame with the dummy driver."""

import os
import subprocess
import sys

import pytest

from term.core.protocol import Button, Joystick, Mode
from term.input.mapping import (
    FULL,
    LAB,
    PLAYSTATION,
    XBOX,
    AxisMap,
    MappingError,
    StickState,
    choose_mapping,
    leave_safe_refusal,
    mapping_from_dict,
)

# The lab's stick at rest: centred, throttle lever pulled back (+1 on axis 3 = no lift).
REST = [0.0, 0.0, 0.0, 1.0]


def test_lab_axes_and_fire() -> None:
    js = LAB.to_packet([1.0, -1.0, 0.5, -1.0], [True])
    assert js.roll == FULL and js.pitch == -FULL and js.lift == FULL
    assert 0 < js.yaw < FULL // 2 + 1
    assert js.buttons == Button.FIRE
    assert LAB.to_packet(REST, [False]) == Joystick(0, 0, 0, 0, 0)


def test_deadzone_cuts_jitter_and_keeps_the_range() -> None:
    ax = AxisMap(0, deadzone=0.1)
    assert ax.value([0.09]) == 0 and ax.value([-0.09]) == 0
    assert 0 < ax.value([0.11]) < 500  # no jump at the edge of the deadzone
    assert ax.value([1.0]) == FULL and ax.value([-1.0]) == -FULL
    assert ax.value([2.0]) == FULL  # clipped


def test_throttle_kinds() -> None:
    lever = AxisMap(0, invert=True, deadzone=0.0, kind="throttle")
    assert lever.value([1.0]) == 0 and lever.value([-1.0]) == FULL and abs(lever.value([0.0]) - FULL // 2) <= 1
    half = AxisMap(0, deadzone=0.0, kind="half")
    assert half.value([0.5]) == 0 and half.value([-1.0]) == FULL


def test_a_missing_axis_reads_as_centred_and_never_as_lift() -> None:
    js = LAB.to_packet([0.3], [])  # a stick with one axis under the lab's mapping
    assert js.roll > 0 and js.lift == 0 and js.pitch == 0


@pytest.mark.parametrize("name, mapping", [
    ("Logitech Logitech Extreme 3D", LAB),
    ("Xbox 360 Controller", XBOX),
    ("Sony Interactive Entertainment Wireless Controller", PLAYSTATION),
    ("PS5 Controller", PLAYSTATION),
    ("Some Unknown Stick", LAB),
])
def test_presets_are_matched_by_name(name: str, mapping) -> None:  # noqa: ANN001
    assert choose_mapping(name) is mapping


def test_a_custom_mapping_wins_over_the_presets() -> None:
    mine = mapping_from_dict("mine", {"match": ["xbox"], "lift": {"axis": 5, "kind": "throttle"}, "fire": [1, 2]})
    assert choose_mapping("Xbox One pad", [mine]) is mine
    assert mine.lift.index == 5 and mine.roll == LAB.roll
    assert mine.to_packet([0, 0, 0, 0, 0, 0], [False, False, True]).buttons == Button.FIRE


@pytest.mark.parametrize("d, words", [
    ({"roll": 3}, "[joystick.mappings.bad] roll: must be a table"),
    ({"lift": {"axis": 1, "kind": "slider"}}, "lift.kind: must be one of: center, throttle, half, got \"slider\""),
    ({"yaw": {"axis": 2, "deadzone": 1.5}}, "yaw.deadzone: must be a number between 0 and 0.9, got 1.5"),
    ({"yaw": {"axis": 2, "deadzone": float("nan")}}, "got nan"),
    ({"fire": "trigger"}, "fire: must be a list of at most 64 items, each an integer between 0 and 127, got"),
    ({"fire": [-1]}, "fire[0]: must be an integer between 0 and 127, got -1"),
    ({"match": 5}, "match[0]: must be a string (not empty), got 5"),
    ({"match": []}, "match: must be a list of 1 to"),
    ({"roll": {"axis": 2.0}}, "roll.axis: must be an integer"),
    ({"roll": {"axis": True}}, "roll.axis: must be an integer"),
    ({"roll": {"axis": 1, "invert": "false"}}, "roll.invert: must be true or false, got \"false\""),
    ({"roll": {"axis": 1, "invrt": True}}, "unknown key 'invrt' in [joystick.mappings.bad] roll (did you mean"),
    ({"rol": {"axis": 1}}, "unknown key 'rol' in [joystick.mappings.bad] (did you mean 'roll'?)"),
])
def test_bad_mappings_are_refused(d: dict, words: str) -> None:
    with pytest.raises(MappingError) as exc:
        mapping_from_dict("bad", d)
    assert words in str(exc.value) and "\n" not in str(exc.value), exc.value


def test_invert_false_is_not_inverted() -> None:
    """Issue 11: `invert = "false"` (a string) was taken as true; a real false keeps the axis as it is."""
    m = mapping_from_dict("m", {"roll": {"axis": 0, "invert": False}, "pitch": {"axis": 1, "invert": True}})
    js = m.to_packet([1.0, 1.0, 0.0, 1.0], [])
    assert js.roll == FULL and js.pitch == -FULL


@pytest.mark.parametrize("resolution", [0, -64, 1.5, True, 5000])
def test_a_resolution_that_cannot_quantise_is_refused(resolution: object) -> None:
    """Issue 11: resolution 0 raised ZeroDivisionError when the stick moved."""
    with pytest.raises(ValueError, match="resolution must be an integer between 1 and 4096"):
        StickState(LAB, resolution=resolution)  # type: ignore[arg-type]


def test_change_detection() -> None:
    st = StickState(LAB, resolution=64)
    assert st.update(REST, [False]) is None  # neutral at start: nothing new
    first = st.update([0.5, 0, 0, 1.0], [False])
    assert first is not None and first.roll > 0
    assert st.update([0.5001, 0, 0, 1.0], [False]) is None  # jitter below the resolution
    assert st.update([0.6, 0, 0, 1.0], [False]) is not None
    back = st.update(REST, [False])
    assert back == Joystick(0, 0, 0, 0, 0)  # back to exactly zero always goes out
    assert st.update(REST, [True]).buttons == Button.FIRE


def test_refuse_to_leave_safe_with_throttle_up() -> None:
    up = Joystick(0, 0, 0, FULL // 2, 0)
    why = leave_safe_refusal(Mode.SAFE, Mode.MANUAL, up)
    assert why is not None and "throttle is up" in why and "50 %" in why
    assert leave_safe_refusal(Mode.SAFE, Mode.PANIC, up) is None  # PANIC and SAFE are always allowed
    assert leave_safe_refusal(Mode.SAFE, Mode.SAFE, up) is None
    assert leave_safe_refusal(Mode.FULL, Mode.HEIGHT, up) is None  # not leaving SAFE: the board decides
    assert leave_safe_refusal(Mode.SAFE, Mode.FULL, Joystick(0, 0, 0, 0, 0)) is None


def test_pygame_dummy_driver_starts_silently_without_a_stick() -> None:
    """In a fresh process (pygame initialises once): no window, no banner on stdout, no stick, no error."""
    code = (
        "from term.input.joystick import JoystickPoller\n"
        "p = JoystickPoller(); msgs = p.start(); r = p.poll()\n"
        "assert not p.connected and r.packet is None and not r.messages, (msgs, r)\n"
        "print('ok', p.error)\n"
        "p.close()\n"
    )
    env = dict(os.environ)
    env.pop("SDL_VIDEODRIVER", None)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=60)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "ok None"  # pygame's "Hello from the pygame community" is not there
    assert out.stderr == ""
