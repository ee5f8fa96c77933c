"""The demo (term --sim --demo) end to end on the simulated clock: the autopilot flies the whole tour through the
terminal's station and the board's own link, as the app does (bench/lessons.py's rig), and every feature it
claims happens on the board: calibration, FULL, HEIGHT, the handover to BLE, a PANIC, soft landings, the log
download, byte-identical to the board's flash. `make demo` runs the same tour in the real app under tmux; the app's
own start of it is in tests/lessons/test_lesson_app.py."""

from __future__ import annotations

from fcb_sim.board.modes import Mode
from term.core.protocol import WirelessState
from tests.support.lessons_rig import Rig


def test_the_demo_flies_the_whole_tour() -> None:
    rig = Rig(seed=2)
    rig.run(0.5)
    assert rig.fly_demo() == "done", rig.captions[-3:]
    board, counts = rig.board, rig.driver.observer.counts
    visited = {c.new for c in board.modes.changes}
    assert {Mode.CALIBRATION, Mode.FULL, Mode.HEIGHT, Mode.PANIC} <= visited
    assert counts["calibrations"] == 1 and counts["handovers"] == 1 and counts["panics"] == 1
    assert counts["refusals"] == 0 and counts["board_panics"] == 0
    world = board.world
    # its own landing soft; PANIC's at the board's 1 m/s descent; no crash
    assert not world.crashes and len(world.landings) >= 2 and world.landings[0][1] < 0.3
    assert all(v < 1.5 for _, v in world.landings)
    assert max(h for _, h in rig.heights) > 1.8  # HEIGHT was flown at 2 m
    assert board.mode == Mode.SAFE and board.wireless.state == WirelessState.DISCONNECTED  # back on the cable
    assert rig.saved is not None and rig.saved == board.log.contents()[: board.log.used] and len(rig.saved) > 1000
    # a caption for each thing it does, saying what and why, in the order it does them
    said = " | ".join(rig.captions)
    for words in ("F2", "3: CALIBRATION", "5: FULL", "7: HEIGHT", "8: the handover", "PANIC", "F5", "your turn"):
        assert words in said, words
    assert said.index("7: HEIGHT") < said.index("8: the handover") < said.index("PANIC") < said.index("F5")
