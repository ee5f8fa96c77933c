"""The simulator tells term each time the craft touches the ceiling or a wall (issue 35): the truth counts the
touches, however short (a bounce between two truths too), with the last one's surface and speed, and term says
each one once in the events list."""

from __future__ import annotations

from fcb_sim.board.board import Board, BoardConfig
from fcb_sim.hosts.instructor import Instructor
from fcb_sim.world.physics import World
from term.lessons.instructor import Truth, parse_line


def _truths(world: World, seconds: float, every: float = 0.05) -> list[Truth]:
    inst = Instructor(Board(BoardConfig(seed=1), world=world))
    out = []
    for i in range(1, int(seconds / every) + 1):
        world.advance_to(i * every)
        t = parse_line(inst.truth_line(world.t))
        assert isinstance(t, Truth)
        out.append(t)
    return out


def test_a_climb_into_the_ceiling_is_one_touch_with_its_speed() -> None:
    w = World(1, height=2.8, airborne=True, room=(3.0, 3.0))
    w.set_motors(450, 450, 450, 450)  # a little over hover: it climbs and stays pressed on the ceiling
    truths = _truths(w, 2.0)
    assert [c.where for c in w.contacts] == ["ceiling"]
    assert truths[0].touches == 0 and truths[0].touched == ""
    assert truths[-1].touches == 1 and truths[-1].touched == "ceiling"
    assert abs(truths[-1].touch_speed - round(w.contacts[0].speed, 4)) < 1e-3


def test_a_wall_touched_between_two_truths_is_counted() -> None:
    w = World(2, height=1.0, airborne=True, room=(0.1, 3.0))
    w.vn = 0.5  # into the wall 0.1 m away, motors off: it falls to the floor after (the floor is no touch here)
    w.set_motors(0, 0, 0, 0)
    truths = _truths(w, 1.0, every=0.25)  # a truth every 250 ms: the touch is long over at the next one
    assert "wall" in [c.where for c in w.contacts] and truths[-1].contact == "ground"
    assert truths[-1].touches == 1 and truths[-1].touched == "wall"
