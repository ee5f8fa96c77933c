"""Headless scripted flights: ``fcb-sim run --scenario NAME --duration S [--seed N] [--json]``.

Every scenario flies the same firmware path as the board: the World (physics at 1 kHz and the sensors) and the
FlightCore at 400 Hz (IMU every tick, DMP at 100 Hz, barometer at 20 Hz as the report's ADC+Baro task), with a
scripted pilot. The common prologue: 1 s of CALIBRATION on the floor, then the flight mode, and a pilot who knows
the hover stick takes off to 1 m (lift stick on the true height, as a pilot's eyes would) by t = 5 s. The
scenario's action starts at t = 6 s; metrics cover t >= 6 s (``measure_from``).

Metrics: ``attitude_rms_deg``/``attitude_max_deg``: the true tilt error (roll and pitch against the commanded
angles, combined); ``height_rms_m``: true height against the held height (the pilot's 1 m, or HEIGHT's set point);
``settle_time_s``: from the step or push until the response stays within its band (10 % of the step around its
final value, 1 deg of level after a push); ``steady_state_error_*``: final value minus command (the cascade is
P-only, so a steady disturbance such as the drag of fast flight leaves an offset); plus what a scenario adds.
``realtime_factor`` is simulated seconds per wall second.
"""

from __future__ import annotations

import json
import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field

from fcb_sim.board import control as C
from fcb_sim.board.calibration import CalibrationSums
from fcb_sim.board.flight import FlightCore
from fcb_sim.errors import UsageError
from fcb_sim.estimation import BEST, FILTERS, has_fixed_point
from fcb_sim.world import constants as P
from fcb_sim.world.physics import World
from term.core.protocol import STICK_MAX, Mode

CONTROL_HZ = 400.0
BARO_EVERY = 20  # control ticks per barometer read (20 Hz)
CALIBRATE_UNTIL = 1.0
TAKEOFF_HEIGHT = 1.0
ACTION_AT = 6.0
MIN_DURATION = 8.0
MAX_DURATION = 3600.0
DEG = math.pi / 180.0


class Sim:
    """A World and a FlightCore wired like the board's loop, ticked at CONTROL_HZ by a script."""

    def __init__(self, seed: int = 1, *, world: World | None = None, core: FlightCore | None = None,
                 world_kw: dict | None = None, core_kw: dict | None = None) -> None:
        self.world = world if world is not None else World(seed, **(world_kw or {}))
        self.fc = core if core is not None else FlightCore(**(core_kw or {}))
        self.dtc = 1.0 / CONTROL_HZ
        self.k = 0
        self.t = 0.0
        self.mode = int(Mode.SAFE)
        self._entered = self.mode  # the mode the flight core last entered (at the control step after set_mode)
        self.sticks = [0, 0, 0, 0]  # roll, pitch, yaw, lift
        self.pilot_target: float | None = None  # the pilot holds this true height with the lift stick
        self.cal = CalibrationSums()
        self.on_tick: Callable[[Sim], None] | None = None

    def _pilot(self) -> None:
        tr = self.world
        h, vz = -tr.d, -tr.vd
        a = 2.0 * (self.pilot_target - h) - 2.5 * vz  # m/s² the pilot asks for
        a = max(-4.0, min(4.0, a))
        ae = P.AE_HOVER_NOMINAL * P.V_REF / max(tr.volts, 1.0) * math.sqrt(max(0.0, 1.0 + a / P.G))
        self.sticks[3] = max(0, min(STICK_MAX, round(ae * STICK_MAX / C.LIFT_AE_MAX)))

    def set_mode(self, mode: int) -> None:
        mode = int(mode)
        if self.mode == int(Mode.CALIBRATION) and mode != self.mode:
            self.fc.set_calibration(self.cal.result())
        if mode == int(Mode.CALIBRATION):
            self.cal = CalibrationSums()
        self.mode = mode

    def run_until(self, t_end: float) -> None:
        world, fc = self.world, self.fc
        dtc = self.dtc
        baro_dt = BARO_EVERY * dtc
        cal_mode = int(Mode.CALIBRATION)
        raw_mode = int(Mode.RAW)
        k_end = int(t_end / dtc + 1e-9)
        while self.k < k_end:
            self.k += 1
            k = self.k
            t = k * dtc
            self.t = t
            world.advance_to(t)
            imu = world.imu()
            fc.imu_sample(imu[0], imu[1], imu[2], imu[3], imu[4], imu[5], dtc)
            mode = self.mode
            q = world.dmp()
            if q is not None and mode != raw_mode:
                fc.dmp_sample(q[0], q[1], q[2], q[3])
            if k % BARO_EVERY == 0:
                pa = world.baro()[0]
                fc.baro_sample(pa, baro_dt)
                fc.battery_sample(round(world.volts * 100.0))  # the ADC without its noise (no draw from the rng)
                if mode == cal_mode:
                    self.cal.add_baro(pa)
            if mode == cal_mode:
                self.cal.add_imu(*imu)
                if q is not None:
                    self.cal.add_dmp(*q)
            if self.pilot_target is not None and k % 8 == 0:
                self._pilot()
            s = self.sticks
            if mode != self._entered:
                fc.enter_mode(mode, s[3])
                self._entered = mode
            ae = fc.control(mode, s[0], s[1], s[2], s[3], dtc)
            world.set_motors(ae[0], ae[1], ae[2], ae[3])
            if self.on_tick is not None:
                self.on_tick(self)

    def prologue(self, mode: int = Mode.FULL) -> None:
        """Calibrate on the floor for 1 s, then take off in ``mode`` to TAKEOFF_HEIGHT."""
        self.set_mode(Mode.CALIBRATION)
        self.run_until(CALIBRATE_UNTIL)
        self.set_mode(mode)
        self.pilot_target = TAKEOFF_HEIGHT
        self._pilot()


@dataclass
class Recorder:
    """Samples the truth at 100 Hz from ``start`` on; ``phi_sp``/``theta_sp`` (rad) are the commanded angles."""

    start: float
    phi_sp: float = 0.0
    theta_sp: float = 0.0
    h_ref: float = TAKEOFF_HEIGHT
    t: list[float] = field(default_factory=list)
    tilt_err: list[float] = field(default_factory=list)
    phi: list[float] = field(default_factory=list)
    r: list[float] = field(default_factory=list)
    h_err: list[float] = field(default_factory=list)

    def __call__(self, sim: Sim) -> None:
        if sim.k % 4 or sim.t < self.start:
            return
        tr = sim.world.truth
        self.t.append(tr.t)
        self.tilt_err.append(math.hypot(tr.phi - self.phi_sp, tr.theta - self.theta_sp))
        self.phi.append(tr.phi)
        self.r.append(tr.r)
        self.h_err.append(tr.h - self.h_ref)

    def metrics(self) -> dict[str, float]:
        n = max(1, len(self.t))
        return {
            "attitude_rms_deg": math.sqrt(sum(e * e for e in self.tilt_err) / n) / DEG,
            "attitude_max_deg": max(self.tilt_err, default=0.0) / DEG,
            "height_rms_m": math.sqrt(sum(e * e for e in self.h_err) / n),
        }


def settle_time(ts: list[float], values: list[float], band: float, t0: float,
                target: float | None = None) -> float | None:
    """Seconds from ``t0`` until ``values`` stay within ``band`` of ``target``, by default of their final value
    (the mean of the last second: a P-only loop settles with an offset under a steady disturbance, which
    ``steady_state_error`` reports); None if they are still outside during the last half second."""
    if not ts:
        return None
    if target is None:
        tail = [v for t, v in zip(ts, values, strict=True) if t >= ts[-1] - 1.0]
        target = sum(tail) / len(tail)
    last_out = None
    for t, v in zip(ts, values, strict=True):
        if t >= t0 and abs(v - target) > band:
            last_out = t
    if ts[-1] - (last_out or t0) < 0.5:
        return None
    return (last_out if last_out is not None else t0) - t0


def final_value(ts: list[float], values: list[float]) -> float:
    """Mean over the last second."""
    tail = [v for t, v in zip(ts, values, strict=True) if t >= ts[-1] - 1.0] if ts else []
    return sum(tail) / len(tail) if tail else float("nan")


def _roll_stick(angle_rad: float) -> int:
    return round(angle_rad * C.ANGLE_LSB_PER_RAD) << C.STICK_ANGLE_SHIFT


def _yaw_stick(rate_rad_s: float) -> int:
    return round(rate_rad_s * C.RATE_LSB_PER_RAD_S) << C.STICK_YAW_SHIFT


# ---- scenarios: each flies ``duration`` simulated seconds and returns its metrics --------------------------------

def _take_off(sim: Sim, mode: int = Mode.FULL) -> tuple[Sim, Recorder]:
    """Record ``sim`` from now on and fly its prologue (calibrate, arm, take off in ``mode``)."""
    rec = Recorder(ACTION_AT)
    sim.on_tick = rec
    sim.prologue(mode)
    return sim, rec


def _hover(seed: int, duration: float, mode: int = Mode.FULL, **core_kw: object) -> dict:
    sim, rec = _take_off(Sim(seed, core_kw=core_kw), mode)
    sim.run_until(duration)
    return rec.metrics()


def fly_core(seed: int, duration: float, core: FlightCore, mode: int = Mode.FULL) -> dict:
    """The flight of ``hover`` (``raw_hover`` with ``mode`` RAW) on a prepared flight core: another preset's
    (fcb_sim.board.param_bindings.preset_core), for bench.flight's report-against-default figures."""
    sim, rec = _take_off(Sim(seed, core=core), mode)
    sim.run_until(duration)
    return rec.metrics()


def hover(seed: int, duration: float) -> dict:
    """FULL mode (DMP path), still air, the pilot holding 1 m."""
    return _hover(seed, duration)


def raw_hover(seed: int, duration: float, filter_name: str | None = None, fixed_point: bool = False) -> dict:
    """RAW mode hover on the on-board filter (--filter, default the best; --fixed-point).

    The same flight as ``hover`` with the angles from the firmware's filter instead of the DMP."""
    return _hover(seed, duration, Mode.RAW, filter_name=filter_name, fixed_point=fixed_point)


def step_roll(seed: int, duration: float) -> dict:
    """FULL mode: a 10 deg roll step on the stick at t = 6 s, held; settle = within 1 deg (10 %)."""
    sim, rec = _take_off(Sim(seed))
    sim.run_until(ACTION_AT)
    step = 10.0 * DEG
    sim.sticks[0] = _roll_stick(step)
    rec.phi_sp = sim.sticks[0] / (1 << C.STICK_ANGLE_SHIFT) / C.ANGLE_LSB_PER_RAD
    sim.run_until(duration)
    m = rec.metrics()
    st = settle_time(rec.t, rec.phi, 0.1 * step, ACTION_AT)
    m["settle_time_s"] = st if st is not None else float("nan")
    m["final_roll_deg"] = final_value(rec.t, rec.phi) / DEG
    m["steady_state_error_deg"] = m["final_roll_deg"] - rec.phi_sp / DEG
    return m


def step_yaw(seed: int, duration: float) -> dict:
    """FULL mode: a 45 deg/s yaw-rate step on the twist at t = 6 s; settle = within 10 % of the rate."""
    sim, rec = _take_off(Sim(seed))
    sim.run_until(ACTION_AT)
    sim.sticks[2] = _yaw_stick(45.0 * DEG)
    target = sim.sticks[2] / (1 << C.STICK_YAW_SHIFT) / C.RATE_LSB_PER_RAD_S
    sim.run_until(duration)
    m = rec.metrics()
    st = settle_time(rec.t, rec.r, 0.1 * target, ACTION_AT)
    m["settle_time_s"] = st if st is not None else float("nan")
    m["final_yaw_rate_dps"] = final_value(rec.t, rec.r) / DEG
    m["steady_state_error_dps"] = m["final_yaw_rate_dps"] - target / DEG
    return m


def height_hold(seed: int, duration: float, sim: Sim | None = None) -> dict:
    """HEIGHT mode from t = 5 s with the noisy, spiky barometer; the pilot lets go of the lift stick.
    ``sim``: a prepared simulator (another estimator, other gains or world) instead of ``Sim(seed)``."""
    sim, rec = _take_off(sim or Sim(seed))
    sim.run_until(5.0)
    sim.pilot_target = None
    rec.h_ref = -sim.world.d  # HEIGHT holds the height it was entered at
    sim.set_mode(Mode.HEIGHT)
    sim.run_until(duration)
    m = rec.metrics()
    m["baro_spikes"] = sim.world.baro_model.spike_count
    m["estimate_error_m"] = sim.fc.height - sim.fc.setpoint - (-sim.world.d - rec.h_ref)
    return m


def gusts(seed: int, duration: float) -> dict:
    """FULL mode hover in wind: 2 m/s from the north plus gusts of 1.5 m/s rms (0.5 s) from t = 5 s."""
    sim, rec = _take_off(Sim(seed))
    sim.run_until(5.0)
    sim.world.set_wind(2.0, 0.0, 0.0, gust_std=1.5, gust_tau=0.5)
    sim.run_until(duration)
    return rec.metrics()


def push(seed: int, duration: float) -> dict:
    """FULL mode hover, a shove at t = 6 s (0.3 N m roll and 3 N sideways for 0.1 s).

    settle_time_s: until the tilt stays within 1 deg of level."""
    sim, rec = _take_off(Sim(seed))
    sim.run_until(ACTION_AT)
    sim.world.push(0.0, 3.0, 0.0, 0.1, tx=0.3)
    sim.run_until(duration)
    m = rec.metrics()
    st = settle_time(rec.t, rec.tilt_err, 1.0 * DEG, ACTION_AT, target=0.0)
    m["settle_time_s"] = st if st is not None else float("nan")
    return m


def motor_stuck(seed: int, duration: float) -> dict:
    """FULL mode hover, then the back motor (ae3) is stuck at 330 or below from t = 6 s.

    The attitude loops trade the other motors against it (watch the tilt and the yaw rate)."""
    sim, rec = _take_off(Sim(seed))
    sim.run_until(ACTION_AT)
    sim.world.stick_motor(3, 330)
    sim.run_until(duration)
    m = rec.metrics()
    m["final_yaw_rate_dps"] = final_value(rec.t, rec.r) / DEG
    m["landed"] = float(sim.world.on_ground)
    return m


def _panic_until_safe(sim: Sim, until: float, ramp: float = 1.5) -> None:
    """PANIC as the board flies it: the flight core descends until it senses the ground, then the motors ramp to
    zero over ``ramp`` s, then SAFE (or ``until`` comes first)."""
    sim.pilot_target = None
    sim.set_mode(Mode.PANIC)
    landed_at = None
    while sim.t < until:
        if landed_at is None and sim.fc.panic_landed:
            landed_at = sim.t
        if landed_at is not None:
            sim.fc.panic_scale = max(0.0, 1.0 - (sim.t - landed_at) / ramp)
            if sim.t >= landed_at + ramp:
                sim.set_mode(Mode.SAFE)
                break
        sim.run_until(min(until, sim.t + 0.01))
    sim.run_until(until)


def panic(seed: int, duration: float) -> dict:
    """FULL mode hover at 1 m, then PANIC at t = 6 s: the descent to the floor, the motors ramped off, SAFE.

    Reports the touch-down speed and whether it was a crash."""
    sim, rec = _take_off(Sim(seed))
    sim.run_until(ACTION_AT)
    _panic_until_safe(sim, duration)
    m = rec.metrics()
    lands = [v for t, v in sim.world.landings if t >= ACTION_AT]
    m["landing_speed_m_s"] = lands[0] if lands else float("nan")
    m["landed"] = float(sim.world.on_ground)
    m["crashes"] = float(len(sim.world.crashes))
    return m


def panic_high(seed: int, duration: float, height: float = 100.0) -> dict:
    """FULL mode: climb to ``height`` (100 m), PANIC there (issue 10.4): the bounded-rate descent, the touch-down
    speed, crashes (none wanted) and how long it took; ``duration`` is how long it may take at most."""
    sim = Sim(seed)
    sim.prologue(Mode.FULL)
    sim.pilot_target = height
    give_up = sim.t + 120.0
    while (abs(-sim.world.d - height) > 0.5 or abs(sim.world.vd) > 0.3) and sim.t < give_up:
        sim.run_until(sim.t + 0.1)
    start = sim.t
    _panic_until_safe(sim, start + max(duration, height / 0.9 + 30.0))
    lands = [v for t, v in sim.world.landings if t >= start]
    return {"panic_height_m": height, "landing_speed_m_s": lands[0] if lands else float("nan"),
            "crashes": float(len(sim.world.crashes)), "landed": float(sim.world.on_ground),
            "descent_s": (sim.world.landings[-1][0] - start) if lands else float("nan"),
            "motors_off": float(sim.fc.ae == (0, 0, 0, 0))}


# Height profile (issue 10.3): the pilot's targets (m) and how long each is held (s) once reached, then a landing.
PROFILE_LEVELS = ((2.0, 8.0), (10.0, 8.0), (30.0, 8.0))
PROFILE_GROUND_S = 30.0  # on the ground, motors off, after the landing
PROFILE_SETTLE_S = 5.0  # touch-down errors count from this long after the touch-down


def height_profile(seed: int, duration: float = 0.0) -> dict:
    """FULL mode: climb to 2, 10 and 30 m (holding each), descend, land, motors off, 30 s on the ground; the
    board's height estimate against the true height.

    ``height_flight_rms_m``: estimate error from take-off to touch-down; ``height_touchdown_err_m``: the largest
    error from 5 s after touch-down on; ``height_ground_drift_m``: how far the estimate moves over the time on
    the ground from then on (the truth does not move). ``duration`` (s) only lengthens the time on the ground."""
    sim = Sim(seed)
    errors: list[tuple[float, float, bool]] = []  # (t, estimate - truth, on the ground)

    def record(s: Sim) -> None:
        if s.k % 4 == 0:
            errors.append((s.t, s.fc.height - (-s.world.d), s.world.on_ground))

    sim.on_tick = record
    sim.prologue(Mode.FULL)
    sim.run_until(ACTION_AT)
    for level, hold in PROFILE_LEVELS:
        sim.pilot_target = level
        give_up = sim.t + 60.0
        while (abs(-sim.world.d - level) > 0.2 or abs(sim.world.vd) > 0.2) and sim.t < give_up:
            sim.run_until(sim.t + 0.1)
        sim.run_until(sim.t + hold)
    sim.pilot_target = -0.5  # down to the floor, gently (the pilot's loop slows the descent near the ground)
    give_up = sim.t + 120.0
    while not sim.world.on_ground and sim.t < give_up:
        sim.run_until(sim.t + 0.05)
    touchdown = sim.t
    sim.pilot_target = None
    sim.sticks[3] = 0
    sim.set_mode(Mode.SAFE)
    sim.run_until(max(duration, touchdown + PROFILE_SETTLE_S + PROFILE_GROUND_S))
    flight = [e for t, e, _g in errors if ACTION_AT - 1.0 <= t < touchdown]
    settled = [(t, e) for t, e, _g in errors if t >= touchdown + PROFILE_SETTLE_S]
    est0 = settled[0][1] if settled else 0.0
    return {
        "height_flight_rms_m": math.sqrt(sum(e * e for e in flight) / max(1, len(flight))),
        "height_touchdown_err_m": max((abs(e) for _t, e in settled), default=float("nan")),
        "height_ground_drift_m": max((abs(e - est0) for _t, e in settled), default=float("nan")),
        "touchdown_s": touchdown,
        "landing_speed_m_s": sim.world.landings[-1][1] if sim.world.landings else float("nan"),
    }


# Stick thrown side to side (issue 12): the roll set point reverses between +-THROW_DEG every THROW_HALF_S.
THROW_DEG = 20.0
THROW_HALF_S = 0.6


def _throw(seed: int, duration: float, mode: int, **core_kw: object) -> dict:
    sim, rec = _take_off(Sim(seed, core_kw=core_kw), mode)
    est: list[float] = []
    speed = [0.0]
    record = sim.on_tick

    def tick(s: Sim) -> None:
        record(s)
        if s.k % 4 == 0 and s.t >= ACTION_AT:
            tr = s.world.truth
            est.append(math.hypot(s.fc.phi - tr.phi, s.fc.theta - tr.theta))
            speed[0] = max(speed[0], math.hypot(tr.vn, tr.ve))

    sim.on_tick = tick
    sim.run_until(ACTION_AT)
    k = 0
    while sim.t < duration - 1e-9:
        sim.sticks[0] = _roll_stick((THROW_DEG if k % 2 else -THROW_DEG) * DEG)
        sim.run_until(min(duration, ACTION_AT + THROW_HALF_S * (k + 1)))
        k += 1
    m = rec.metrics()  # attitude_*: the true tilt from level (the set point swings, so this is the swing itself)
    m["estimate_rms_deg"] = math.sqrt(sum(e * e for e in est) / max(1, len(est))) / DEG
    m["estimate_max_deg"] = max(est, default=0.0) / DEG
    m["max_speed_m_s"] = speed[0]
    return m


def throw(seed: int, duration: float) -> dict:
    """FULL mode, the roll stick thrown side to side (+-20 deg, reversing every 0.6 s) from t = 6 s.

    ``estimate_rms_deg``: the attitude the control loop flies on (here the DMP's) against the truth."""
    return _throw(seed, duration, Mode.FULL)


def raw_throw(seed: int, duration: float, filter_name: str | None = None, fixed_point: bool = False) -> dict:
    """RAW mode, the roll stick thrown side to side (as ``throw``): the on-board filter under hard sideways
    acceleration (--filter, --fixed-point). ``estimate_rms_deg``: the filter's attitude against the truth."""
    return _throw(seed, duration, Mode.RAW, filter_name=filter_name, fixed_point=fixed_point)


SCENARIOS: dict[str, Callable[[int, float], dict]] = {
    "hover": hover,
    "raw-hover": raw_hover,
    "step-roll": step_roll,
    "step-yaw": step_yaw,
    "height-hold": height_hold,
    "gusts": gusts,
    "push": push,
    "motor-stuck": motor_stuck,
    "panic": panic,
    "panic-high": panic_high,
    "height-profile": height_profile,
    "throw": throw,
    "raw-throw": raw_throw,
}


RAW_SCENARIOS = ("raw-hover", "raw-throw")


def run_scenario(name: str, duration: float = 10.0, seed: int = 1, *, filter_name: str | None = None,
                 fixed_point: bool = False) -> dict:
    """Fly a scenario and return its metrics (with sim_seconds, wall_seconds, realtime_factor)."""
    if name not in SCENARIOS:
        raise UsageError(f"unknown scenario {name!r}; try one of: {', '.join(SCENARIOS)} (see --list)")
    if not (math.isfinite(duration) and MIN_DURATION <= duration <= MAX_DURATION):
        raise UsageError(f"--duration must be between {MIN_DURATION:g} and {MAX_DURATION:g} s, got {duration:g}")
    opts: dict = {}
    if filter_name is not None or fixed_point:
        if name not in RAW_SCENARIOS:
            raise UsageError(f"--filter and --fixed-point apply to the RAW-mode scenarios: {', '.join(RAW_SCENARIOS)}")
        fname = filter_name or BEST
        if fname not in FILTERS:
            raise UsageError(f"unknown filter {fname!r}; known: {', '.join(FILTERS)}")
        if fixed_point and not has_fixed_point(fname):
            raise UsageError(f"filter {fname!r} has no fixed-point variant; try --filter complementary")
        opts = {"filter_name": fname, "fixed_point": fixed_point}
    t0 = time.perf_counter()
    metrics = SCENARIOS[name](seed, duration, **opts)
    wall = time.perf_counter() - t0
    out = {"scenario": name, "seed": seed, "sim_seconds": duration, "wall_seconds": wall,
           "realtime_factor": duration / wall if wall > 0 else float("inf")}
    if opts:
        out["filter"] = opts["filter_name"] + (" (Q16.16)" if fixed_point else "")
    out.update(metrics)
    return out


def _json_value(v: object) -> object:
    if isinstance(v, float) and not math.isfinite(v):
        return None
    return v


def cmd_run(args) -> int:
    """``fcb-sim run``."""
    if args.list:
        for name, fn in SCENARIOS.items():
            print(f"{name:16s} {(fn.__doc__ or '').splitlines()[0]}")
        return 0
    m = run_scenario(args.scenario, args.duration, args.seed, filter_name=getattr(args, "filter", None),
                     fixed_point=getattr(args, "fixed_point", False))
    for key, value in m.items():
        if isinstance(value, float):
            print(f"{key}: {value:.4g}")
        else:
            print(f"{key}: {value}")
    if args.json:
        print(json.dumps({k: _json_value(v) for k, v in m.items()}))
    return 0
