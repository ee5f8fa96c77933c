"""The world says when the craft touches the ceiling, a wall or the floor, and the accelerometer feels it: the stop
is a jolt (clipped at 2 g), and a surface the craft is pressed against carries the push (issue 35)."""

from __future__ import annotations

from fcb_sim.world import constants as P
from fcb_sim.world.physics import World


def _climb_into_ceiling(seed: int = 1) -> tuple[World, list[tuple[float, float, str]]]:
    """From 2.8 m under a 3 m ceiling, hover-and-a-bit thrust: it climbs and stays pressed there."""
    w = World(seed, height=2.8, airborne=True, room=(3.0, 3.0))
    w.set_motors(450, 450, 450, 450)
    rows = []
    for i in range(1, 801):
        w.advance_to(i * 0.0025)
        az = w.imu()[5] / P.ACC_LSB_PER_MS2  # chip z up: specific force, m/s²
        rows.append((w.t, az, w.contact))
    return w, rows


def test_a_climb_into_the_ceiling_is_one_contact_felt_as_a_jolt() -> None:
    w, rows = _climb_into_ceiling()
    assert [c.where for c in w.contacts] == ["ceiling"]
    hit = w.contacts[0]
    assert 0.3 < hit.speed < P.CRASH_SPEED_M_S
    assert not w.crashes
    jolt = [az for t, az, _ in rows if hit.t <= t <= hit.t + P.JOLT_S]
    assert min(jolt) < -P.G  # pushed down hard: the accelerometer clips at -2 g
    assert w.contact == "ceiling"
    assert abs(w.truth.h - 3.0) < 1e-9


def test_pressed_on_the_ceiling_the_accelerometer_reads_one_g() -> None:
    """The ceiling carries the thrust beyond the weight: no acceleration is felt (as at hover), not the climb's."""
    w, rows = _climb_into_ceiling()
    pressed = [az for t, az, c in rows if t > w.contacts[0].t + 0.1 and c == "ceiling"]
    assert len(pressed) > 200
    mean = sum(pressed) / len(pressed)
    assert abs(mean - P.G) < 0.3  # before the fix it read the thrust: 450² / 400² g = 1.27 g


def test_a_wall_and_a_landing_are_contacts_too() -> None:
    w = World(2, height=1.0, airborne=True, room=(0.1, 3.0))
    w.vn = 0.5  # drifting north into the wall 0.1 m away, motors off: it falls to the floor too
    w.set_motors(0, 0, 0, 0)
    w.advance_to(1.0)
    kinds = [c.where for c in w.contacts]
    assert kinds[0] == "wall" and "ground" in kinds
    assert w.contact == "ground"


def test_resting_on_the_floor_is_no_new_contact() -> None:
    w = World(3)
    w.advance_to(2.0)
    assert w.contacts == [] and w.contact == "ground"
