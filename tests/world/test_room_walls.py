"""The room has the walls and ceiling it names (issue 22: "6 m room", yet the craft flew to 9.07 m and 11.43 m,
drawn clipped): the simulator's world (term --sim, fcb-sim serve) has them as contacts like the floor, and the room
view draws the same room from the same facts (term.core.protocol: ROOM_HALF_M, ROOM_CEILING_M)."""

from __future__ import annotations

import dataclasses

import pytest

from fcb_sim.hosts.serve import make_board
from fcb_sim.world import constants as P
from fcb_sim.world.physics import World
from term.core.protocol import ROOM_CEILING_M, ROOM_HALF_M
from term.lessons.instructor import Truth
from term.lessons.room import Room, SideView, TopView
from term.ui.widgets.room import draw

HOVER = 390  # about the hover command at a full pack


def test_a_full_lift_climb_stops_at_the_rooms_ceiling() -> None:
    w = World(1, height=1.0, airborne=True, room=(ROOM_HALF_M, ROOM_CEILING_M))
    w.set_motors(1000, 1000, 1000, 1000)
    w.advance_to(3.0)
    assert -w.d == pytest.approx(ROOM_CEILING_M) and [c.where for c in w.crashes] == ["ceiling"]


def flying_at(n: float, e: float, vn: float, ve: float, room: tuple[float, float] | None) -> World:
    w = World(1, height=1.5, airborne=True, room=room)
    w.set_motors(HOVER, HOVER, HOVER, HOVER)  # about hover for the second or two the tests fly
    w.n, w.e, w.vn, w.ve = n, e, vn, ve
    w.set_wind(vn, ve)  # carried by the air (drag would stop it within a second in still air)
    return w


def test_a_slow_drift_stops_at_the_wall_without_a_crash() -> None:
    w = flying_at(-2.5, 0.0, -0.5, 0.3, (ROOM_HALF_M, ROOM_CEILING_M))
    w.advance_to(1.5)
    assert w.n == pytest.approx(-ROOM_HALF_M) and w.vn == 0.0  # against the south wall
    assert w.e > 0.3 and not w.crashes  # sliding along it, unhurt


def test_a_fast_hit_on_a_wall_is_a_crash() -> None:
    w = flying_at(0.0, 2.5, 0.0, 4.0, (ROOM_HALF_M, ROOM_CEILING_M))
    w.advance_to(0.5)
    assert w.e == pytest.approx(ROOM_HALF_M) and w.ve <= 0.0
    assert [c.where for c in w.crashes][:1] == ["wall"] and w.crashes[0].speed > P.CRASH_SPEED_M_S


def test_the_open_sky_has_no_walls() -> None:
    w = flying_at(0.0, 2.5, 0.0, 4.0, None)
    w.advance_to(0.5)
    assert w.e > ROOM_HALF_M + 1.0 and not w.crashes


def test_the_simulator_term_flies_is_in_the_room_the_view_draws() -> None:
    board = make_board(1, "bench")
    room = Room()
    assert board.world.room == (room.extent, room.ceiling) == (ROOM_HALF_M, ROOM_CEILING_M)


def truth(n: float, e: float, h: float) -> Truth:
    return Truth(t=1.0, n=n, e=e, h=h, vn=0.0, ve=0.0, vd=0.0, phi=0.0, theta=0.0, psi=0.0, p=0.0, q=0.0, r=0.0,
                 on_ground=False, volts=12.0, soc=1.0, landings=0, touchdown=0.0, crashes=0, cable=True)


def test_the_view_draws_the_ceiling_and_the_craft_under_it() -> None:
    room = Room()
    room.update(truth(0.0, ROOM_HALF_M, ROOM_CEILING_M))  # against the east wall, at the ceiling
    assert (room.extent, room.ceiling) == (ROOM_HALF_M, ROOM_CEILING_M)  # the room does not grow past its walls
    text, top, side = draw(room, 46, 10)
    rows = text.plain.split("\n")
    side_rows = [r[top.cols + 1:] for r in rows[:-1]]
    assert "◆" in side_rows[0]  # at the ceiling: the top row, inside the room
    west, _ = side.cell(-ROOM_HALF_M, ROOM_CEILING_M)
    east, _ = side.cell(ROOM_HALF_M, ROOM_CEILING_M)
    assert " " not in side_rows[0][west:east + 1]  # the ceiling: a line from wall to wall
    assert isinstance(top, TopView) and isinstance(side, SideView)
    cx, _ = top.cell(0.0, ROOM_HALF_M)
    assert cx < top.cols  # the craft at the wall is drawn at the wall, not clipped past it


def test_the_room_is_named_by_its_size() -> None:
    from term.ui.widgets.room import room_name

    assert room_name(Room()) == f"{2 * ROOM_HALF_M:.0f} × {2 * ROOM_HALF_M:.0f} × {ROOM_CEILING_M:.0f} m room"
    assert dataclasses.is_dataclass(Truth)
