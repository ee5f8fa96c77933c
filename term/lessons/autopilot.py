"""The autopilot: a scripted pilot that flies through the same keys and sticks a person uses.

It is the demo (``term --sim --demo``), a lesson's "show me", and the pilot of the lesson tests. Sans-IO: every
``update(ns, truth, now)`` (about 50 times a second) returns what to do now: ``Press(action)`` (a key map action,
performed exactly as the key would be) and ``Stick(joystick)`` (the stick it holds). Its eyes are the
simulator's truth (as a pilot's eyes see the craft: ``term.lessons.instructor.Truth``) and the lesson variables
(term/lessons/observe.py) for its waits; it never touches the board any other way.

A script is a list of maneuvers (``term.lessons.spec.Maneuver``, from a lesson's ``[[show]]`` or demo.toml):
``press`` an action; ``wait`` until an expression holds; ``hover`` at [north, east, height] (going there at
``speed`` m/s; done when there and still, or by ``until``/``for``), with ``yaw_rate`` (°/s) or a ``heading``;
``land`` (at most ``rate`` m/s, slower near the floor) and cut the lift on the floor; ``sticks`` (raw stick values
held, the flying off, until the next ``hover`` or ``land``: the lessons' failing pilots); ``pause``; ``say`` (a
caption). Any maneuver may end by ``until`` or after ``for`` seconds, and fails the script after ``timeout``
seconds (``state`` FAILED, ``why`` says where). ``press`` also takes the palette's commands that have no key
(``spec.COMMANDS``: ``handback``).

How it flies (module ``_Flight``): the lift stick on a PID of the true height (it learns the hover stick as a
pilot does, starting from a guess); in FULL, RAW and HEIGHT the roll and pitch sticks ask for the tilt that
accelerates it towards the target (a position PID, leaning into the wind), the yaw stick for a turn rate; in
MANUAL (and YAW) the sticks are moments, so it closes the attitude loops itself on the true angles and rates, as
a MANUAL pilot must. In HEIGHT it keeps the lift stick where it was when HEIGHT was engaged, and nudges it (which
moves the held height) when the true height wanders off, as a pilot watching the craft would. Gains are a pilot's
feel, not the board's parameters: docs/lessons.md.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from term.core.protocol import STICK_MAX, Joystick
from term.lessons.instructor import Truth
from term.lessons.spec import COMMANDS, Maneuver

FLYING, DONE, FAILED = "flying", "done", "failed"
G = 9.81

# A pilot's feel for the sticks (docs/board.md, "Sticks to motors"): in FULL a full roll or pitch stick tilts
# the craft about 22.5° (so about 83000 per radian), a full yaw twist turns it at about 125°/s.
ANGLE_STICK = 83440.0  # stick per rad of tilt asked for (FULL, RAW, HEIGHT)
YAW_STICK = 15034.0  # stick per rad/s of turn asked for
# MANUAL: the sticks are moments. Gains of the pilot's own attitude loop (stick per rad, per rad/s).
MANUAL_ANGLE = 105000.0
MANUAL_RATE = 21000.0
MANUAL_YAW_RATE = 60000.0
# Height: the lift stick from the true height (stick per m, per m/s, per m s); the hover stick is learnt.
LIFT_GUESS = 14000.0
LIFT_KP, LIFT_KD, LIFT_KI = 4000.0, 3000.0, 800.0
TAKEOFF_RAMP = 3000.0  # stick per s while still on the floor with somewhere to go
# HEIGHT: beyond HEIGHT_NUDGE_FROM m off, the lift stick is moved this much per m (at most _MAX, past the board's
# dead band of 1500) and the held height follows at up to 0.5 m/s per full stick.
HEIGHT_NUDGE_FROM, HEIGHT_NUDGE, HEIGHT_NUDGE_MAX = 0.06, 40000.0, 10000.0
LAND_SLOW, LAND_SLOW_PER_M = 0.12, 0.5  # landing: at most this descent rate (m/s) plus this per m of height
# Position: m/s² asked for per m, per m/s and per m s, at most POS_ACC; tilt at most TILT_MAX.
POS_KP, POS_KD, POS_KI = 2.0, 2.4, 0.5
POS_ACC = 2.5
POS_I_MAX = 1.5  # m/s² the integral may lean into a wind
TILT_MAX = 0.26  # rad (15°)
HEADING_KP = 1.2  # rad/s of turn per rad of heading error
TURN_MAX = 1.0  # rad/s
THERE_M = 0.12  # a hover is done when within this of its target and slower than THERE_M_S
THERE_M_S = 0.15
GROUND_H = 0.03  # m: below this the craft is on its feet as far as the flying goes

_FLIGHT = frozenset(("MANUAL", "YAW", "FULL", "RAW", "HEIGHT"))


@dataclass(frozen=True, slots=True)
class Press:
    action: str


@dataclass(frozen=True, slots=True)
class Stick:
    js: Joystick


Act = Press | Stick
__all__ = ["COMMANDS", "DONE", "FAILED", "FLYING", "Act", "Autopilot", "Press", "Stick"]


def _clip(v: float, lim: float) -> float:
    return -lim if v < -lim else lim if v > lim else v


def _stick(v: float) -> int:
    return int(round(_clip(v, STICK_MAX)))


class _Flight:
    """Sticks from the truth: the height, position and heading loops (module docstring)."""

    def __init__(self) -> None:
        self.target: tuple[float, float, float] | None = None  # where it is going now (moves towards goal)
        self.goal: tuple[float, float, float] | None = None
        self.speed = 0.5
        self.heading: float | None = None  # rad; None: hold the heading it has
        self.yaw_rate: float | None = None  # rad/s; overrides the heading
        self.base = LIFT_GUESS
        self.i_n = self.i_e = 0.0
        self.height_lift: int | None = None  # the lift stick HEIGHT was engaged with
        self._last_lift = 0
        self.land_rate: float | None = None
        self._mode: str | None = None

    def set_goal(self, goal: tuple[float, float, float], truth: Truth | None, speed: float) -> None:
        if self.target is None or (truth is not None and truth.on_ground):
            self.target = (truth.n, truth.e, truth.h) if truth is not None else goal
        self.goal, self.speed, self.land_rate = goal, speed, None

    def land(self, truth: Truth | None, rate: float) -> None:
        if self.target is None and truth is not None:
            self.target = (truth.n, truth.e, truth.h)
        self.land_rate = rate

    def sticks(self, mode: str | None, truth: Truth | None, dt: float) -> Joystick:
        if mode != self._mode:
            if mode == "HEIGHT":
                self.height_lift = self._last_lift  # the stick the board took as HEIGHT's neutral
            self._mode = mode
        if mode not in _FLIGHT or truth is None:
            self.base, self.i_n, self.i_e = LIFT_GUESS, 0.0, 0.0
            self.target = None if mode in ("SAFE", "CALIBRATION", None) else self.target
            return Joystick(0, 0, 0, 0, 0)
        s = truth
        tn, te, th, vz_ref = self._advance_target(s, dt)
        airborne = not s.on_ground
        lift = self._lift(mode, s, th, vz_ref, dt, airborne)
        r_sp = self._yaw_rate_setpoint(s)
        if not airborne:
            self.i_n = self.i_e = 0.0
            return Joystick(0, 0, 0, _stick(max(0.0, lift)), 0)
        roll, pitch, yaw = self._attitude_sticks(mode, s, tn, te, r_sp, dt)
        return Joystick(_stick(roll), _stick(pitch), _stick(yaw), _stick(max(0.0, lift)), 0)

    def _advance_target(self, s: Truth, dt: float) -> tuple[float, float, float, float]:
        """Moves the target one step toward the goal (or down while landing): its north, east, height and climb rate."""
        if self.target is None:
            self.target = (s.n, s.e, s.h)
        tn, te, th = self.target
        vz_ref = 0.0  # the target's own climb rate: the lift follows it instead of lagging behind
        if self.land_rate is not None:
            # slower as the floor comes near (a pilot's flare): touch down at about 0.15 m/s
            vz_ref = -min(self.land_rate, LAND_SLOW + LAND_SLOW_PER_M * max(0.0, s.h))
            th = max(-0.5, min(th, s.h + 0.2) + vz_ref * dt)
        elif self.goal is not None:
            gn, ge, gh = self.goal
            dn, de, dh = gn - tn, ge - te, gh - th
            dist = math.sqrt(dn * dn + de * de + dh * dh)
            step = self.speed * dt
            if dist <= step:
                tn, te, th = gn, ge, gh
            else:
                tn, te, th = tn + dn * step / dist, te + de * step / dist, th + dh * step / dist
                vz_ref = self.speed * dh / dist
        self.target = (tn, te, th)
        return tn, te, th, vz_ref

    def _lift(self, mode: str, s: Truth, th: float, vz_ref: float, dt: float, airborne: bool) -> float:
        """The lift stick that holds the target height (HEIGHT mode: the held stick plus a pilot's nudge)."""
        err = th - s.h
        if not airborne and th > GROUND_H:
            self.base += TAKEOFF_RAMP * dt  # winding up to the hover stick it does not know yet
        elif airborne:
            self.base = _clip(self.base + LIFT_KI * err * dt, STICK_MAX)
        lift = self.base + LIFT_KP * err - LIFT_KD * (s.vz - vz_ref)
        if not airborne and th <= GROUND_H:
            lift = 0.0  # on the floor with nowhere to go: hands off the lift
        if mode == "HEIGHT":
            # The board holds its estimate of the height it had: the stick stays where it was, but when the true
            # height wanders (the barometer's error) a pilot nudges it, which moves the held height.
            if self.height_lift is None:
                self.height_lift = _stick(max(0.0, lift))
            nudge = 0.0 if abs(err) < HEIGHT_NUDGE_FROM else _clip(HEIGHT_NUDGE * err, HEIGHT_NUDGE_MAX)
            lift = self.height_lift + nudge
        self._last_lift = _stick(max(0.0, lift))
        return lift

    def _yaw_rate_setpoint(self, s: Truth) -> float:
        """The yaw rate asked for: the scripted turn, or back to the heading held."""
        if self.yaw_rate is not None:
            self.heading = None
            return self.yaw_rate
        if self.heading is None:
            self.heading = s.psi
        d = (self.heading - s.psi + math.pi) % (2 * math.pi) - math.pi
        return _clip(HEADING_KP * d, TURN_MAX)

    def _attitude_sticks(
        self, mode: str, s: Truth, tn: float, te: float, r_sp: float, dt: float
    ) -> tuple[float, float, float]:
        """Roll, pitch and yaw sticks: the acceleration toward the target, then the tilt that gives it."""
        self.i_n = _clip(self.i_n + POS_KI * (tn - s.n) * dt, POS_I_MAX)
        self.i_e = _clip(self.i_e + POS_KI * (te - s.e) * dt, POS_I_MAX)
        an = _clip(POS_KP * (tn - s.n) - POS_KD * s.vn + self.i_n, POS_ACC)
        ae = _clip(POS_KP * (te - s.e) - POS_KD * s.ve + self.i_e, POS_ACC)
        c, sn = math.cos(s.psi), math.sin(s.psi)
        fwd, right = an * c + ae * sn, -an * sn + ae * c
        theta_sp = _clip(-fwd / G, TILT_MAX)
        phi_sp = _clip(right / G, TILT_MAX)
        if mode in ("MANUAL", "YAW"):
            roll = MANUAL_ANGLE * (phi_sp - s.phi) - MANUAL_RATE * s.p
            pitch = MANUAL_ANGLE * (theta_sp - s.theta) - MANUAL_RATE * s.q
            yaw = MANUAL_YAW_RATE * (r_sp - s.r) if mode == "MANUAL" else r_sp * YAW_STICK
            return roll, pitch, yaw
        return phi_sp * ANGLE_STICK, theta_sp * ANGLE_STICK, r_sp * YAW_STICK


class Autopilot:
    """Flies a script (module docstring)."""

    def __init__(self, script: tuple[Maneuver, ...], now: float, title: str = "autopilot") -> None:
        self.script = script
        self.title = title
        self.state = FLYING
        self.why = ""
        self.caption = ""
        self.index = -1
        self.flight = _Flight()
        self._started = now
        self._last: float | None = None
        self._raw: Joystick | None = None  # a `sticks` maneuver's values
        self._landed_at: float | None = None

    @property
    def maneuver(self) -> Maneuver | None:
        return self.script[self.index] if 0 <= self.index < len(self.script) else None

    def _next(self, now: float, truth: Truth | None) -> list[Act]:
        """Start the next maneuver; a press (or a caption) acts at once and moves on."""
        out: list[Act] = []
        while True:
            self.index += 1
            m = self.maneuver
            if m is None:
                self.state = DONE
                self.caption = f"{self.title}: done"
                return out
            self._started = now
            self._landed_at = None
            if m.say:
                self.caption = m.say
            f = self.flight
            if m.verb == "press":
                out.append(Press(m.arg))
                continue
            if m.verb == "say":
                continue
            if m.verb in ("hover", "land"):
                self._raw = None  # flying again: the raw sticks are let go
            if m.verb == "hover":
                f.set_goal(m.arg, truth, m.options.get("speed") or 0.5)
                yr = m.options.get("yaw_rate")
                f.yaw_rate = math.radians(yr) if yr is not None else None
                hd = m.options.get("heading")
                if hd is not None:
                    f.heading = math.radians(hd)
            elif m.verb == "land":
                f.land(truth, m.arg)
                f.yaw_rate = None
            elif m.verb == "sticks":
                self._raw = Joystick(m.arg["roll"], m.arg["pitch"], m.arg["yaw"], m.arg["lift"], 0)
            return out

    def stop(self, why: str) -> None:
        if self.state == FLYING:
            self.state, self.why = FAILED, why

    def update(self, ns: dict[str, Any], truth: Truth | None, now: float) -> list[Act]:
        """One tick: what to press and the stick to hold."""
        if self.state != FLYING:
            return []
        dt = 0.02 if self._last is None else max(0.0, min(0.2, now - self._last))
        self._last = now
        out: list[Act] = []
        if self.index < 0:
            out += self._next(now, truth)
            if self.state != FLYING:
                return out
        m = self.maneuver
        assert m is not None
        elapsed = now - self._started
        if self._over(m, ns, truth, now, elapsed):
            out += self._next(now, truth)
            m = self.maneuver
            if m is None:
                return out + [Stick(self._hold(ns, truth, dt))]
        elif elapsed >= m.timeout:
            self.state = FAILED
            what = m.until.text if m.until is not None else m.arg.text if m.verb == "wait" else m.verb
            self.why = f"gave up on step {self.index + 1} ({m.verb}: {what}) after {m.timeout:g} s"
            return out
        out.append(Stick(self._hold(ns, truth, dt)))
        return out

    def _hold(self, ns: dict[str, Any], truth: Truth | None, dt: float) -> Joystick:
        if self._raw is not None:
            return self._raw
        return self.flight.sticks(ns.get("mode"), truth, dt)

    def _over(self, m: Maneuver, ns: dict[str, Any], truth: Truth | None, now: float, elapsed: float) -> bool:
        if m.until is not None and m.until.true(ns):
            return True
        if m.seconds is not None:
            return elapsed >= m.seconds
        if m.until is not None:
            return False
        if m.verb == "wait":
            return bool(m.arg(ns))
        if m.verb == "pause":
            return elapsed >= (m.arg or 0.0)
        if m.verb == "hover":
            f = self.flight
            if truth is None or f.target != f.goal:
                return False
            gn, ge, gh = m.arg
            d = math.sqrt((truth.n - gn) ** 2 + (truth.e - ge) ** 2 + (truth.h - gh) ** 2)
            return d < THERE_M and math.sqrt(truth.speed ** 2 + truth.vz ** 2) < THERE_M_S
        if m.verb == "land":
            if truth is not None and truth.on_ground:
                self._landed_at = self._landed_at if self._landed_at is not None else now
                return now - self._landed_at >= 0.5
            self._landed_at = None
            return False
        return True
