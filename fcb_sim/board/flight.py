"""The firmware's control step: calibrated sensor samples and sticks in, motor commands out.

``FlightCore`` is sans-IO and clock-free: the caller passes samples and time steps. The board's tasks call it
(fcb_sim/board/board.py); the headless scenarios call it directly (fcb_sim/lab/scenarios.py).

API for the board::

    fc = FlightCore(filter_name=None, fixed_point=False)    # RAW filter: estimation.BEST unless named
    fc.set_calibration(cal)                                  # a Calibration (means from CALIBRATION mode)
    fc.imu_sample(gx, gy, gz, ax, ay, az, dt)                # raw int16 chip words, every IMU read (400 Hz)
    fc.dmp_sample(w, x, y, z)                                # each new DMP quaternion (World.dmp() not None)
    fc.baro_sample(pressure_pa, dt)                          # each barometer read, dt since the previous one
    ae1, ae2, ae3, ae4 = fc.control(mode, roll, pitch, yaw, lift, dt)   # sticks + trims, int16 / 0..32767
    fc.panic_scale = s                                       # PANIC: the mode machine ramps 1 -> 0 over time
    kind, speed_mm_s = fc.pending_contact() or (0, 0)        # a hard stop felt since the last call: EventCode.CONTACT

The core keeps no mode of its own: whoever keeps the mode (the board's mode machine, a scenario's ``Sim``)
calls ``enter_mode(mode, lift)`` when it changes and passes it to every ``control``. HEIGHT captures its set point
and the lift stick at entry, PANIC restarts at its full descent level. Gains: ``fc.gains``
(constants.Gains), ``adjust_gain(name, steps)``. Telemetry reads ``phi, theta, psi``, ``sp, sq, sr``, ``sax, say,
saz``, ``height``, ``vz``, ``setpoint``, ``ae`` and ``attitude_centideg()``. What each mode does, the gains and the
outputs in full: docs/board.md, "The flight core".

Chip-to-body mapping is done here, once, where samples enter (docs/architecture.md): ``p = gx, q = -gy,
r = -gz``; the z-up estimators' angles become ``phi = roll, theta = -pitch, psi = -yaw``. control.py explains
why this removes the sign puzzle of the report's Table 1.
"""

from __future__ import annotations

from dataclasses import replace

from fcb_sim.board import control as C
from fcb_sim.board.calibration import Calibration
from fcb_sim.estimation import BEST, HeightEstimator, make_filter, quaternion_to_euler
from fcb_sim.estimation.heading import HeadingHold
from fcb_sim.estimation.height import HEIGHT_BEST, STOP_UP, V_REF, HeightKalman, make_height_estimator
from fcb_sim.world import constants as P
from term.core.protocol import PARAMS, STICK_MAX, ContactKind, Mode, Param

HEIGHT_STICK_RATE = 0.5  # m/s of set-point change at full lift deflection away from the entry position
HEIGHT_STICK_DEADBAND = 1500  # stick units around the entry position that leave the set point alone
# Height integral gain, ae² per (mm s): 1.0 N per m s, an integral time of 4 s beside P 400 (constants.Gains). It
# takes out the battery's sag (the hover thrust of the lift captured at entry falls as the pack discharges), which
# grows with the flight: over 120 s of HEIGHT on the true height P 400 / D 400 alone hold 4.4 cm rms, with this
# integral 0.3 cm; on the estimator, seeds 1-6, 0.097 -> 0.087 m rms (worst 0.17 -> 0.13). Over 30 s, where the
# sag is small, it costs a little (seeds 1-12: 0.073 -> 0.077 m).
HEIGHT_I = float(PARAMS[Param.HEIGHT_I].default)  # 100: the protocol's parameter table (ctrl.height_i)

# PANIC's descent (issue 10.4: from about 100 m the old fixed level for 3.5 s, then motors off, hit the ground at
# 23.5 m/s). A vertical-speed PI loop on the height estimate; ae per (m/s) and per m.
PANIC_DESCENT_M_S = (1.0, 3.0)  # the rate at or below PANIC_SLOW_BELOW_M, and at or above PANIC_FAST_ABOVE_M
PANIC_SLOW_BELOW_M = 10.0
PANIC_FAST_ABOVE_M = 40.0
PANIC_KP = 60.0
PANIC_KI = 60.0
PANIC_MAX_AE = 700  # enough to stop a fall on a sagging battery
PANIC_MIN_FRAC = 0.4  # of panic_ae, in the air: the attitude loops keep some thrust to work with
PANIC_LAND_FRAC = 0.6  # the ground: the loop asks for less than this share of panic_ae ...
PANIC_LAND_VZ = 0.3  # ... and the craft does not move (m/s) ...
PANIC_LAND_S = 0.5  # ... for this long
# The height estimator's ground test: motors below this cannot lift the craft (thrust goes with ae², so 0.7 of the
# hover level is half the weight: in the air the accelerometer would read half a g, on the legs it reads one).
GROUND_AE = int(0.7 * P.AE_HOVER_NOMINAL)
# A wall: the body's x/y specific force (thrust is along body z, so only drag and contact show there) beyond this
# many m/s² for WALL_SAMPLES samples in a row; one event per WALL_REPEAT_S.
WALL_ACC = 6.9
WALL_SAMPLES = 2
WALL_REPEAT_S = 0.5
# Still (the heading's drift is learnt, estimation/heading.py): on the ground by the height estimator's test and every
# gyro axis under STILL_LSB (1.5 °/s after calibration's offsets) for STILL_S. The headings are corrected at 100 Hz.
STILL_LSB = 1.5 * P.GYRO_LSB_PER_DPS
STILL_S = 1.0
HEADING_EVERY = 4  # IMU samples
HEADING_REPORT_CDEG = 200  # a drift this far from the last reported one is reported again (EventCode.HEADING_DRIFT)
HEADING_LIFTOFF_CDEG = 50  # ... and at a lift-off, one at least this large


def panic_descent_rate(height_m: float) -> float:
    """PANIC's descent rate (m/s, positive) at an estimated height: slow near the ground, faster high up."""
    slow, fast = PANIC_DESCENT_M_S
    f = (height_m - PANIC_SLOW_BELOW_M) / (PANIC_FAST_ABOVE_M - PANIC_SLOW_BELOW_M)
    return slow + (fast - slow) * max(0.0, min(1.0, f))

_SAFE, _PANIC, _MANUAL, _CAL = int(Mode.SAFE), int(Mode.PANIC), int(Mode.MANUAL), int(Mode.CALIBRATION)
_YAW, _FULL, _RAW, _HEIGHT = int(Mode.YAW), int(Mode.FULL), int(Mode.RAW), int(Mode.HEIGHT)
_ANGLE = C.ANGLE_LSB_PER_RAD
_SHIFT = C.STICK_ANGLE_SHIFT
_YSHIFT = C.STICK_YAW_SHIFT
_mix = C.mix
_RAD_S_PER_LSB = 1.0 / P.RATE_LSB_PER_RAD_S
_MS2_PER_LSB = 1.0 / P.ACC_LSB_PER_MS2
_lift_to_z = C.lift_to_z


def default_height_estimator() -> HeightEstimator | HeightKalman:
    """The board's height estimator: the robust Kalman filter (estimation/height.py, HEIGHT_BEST), which skips the
    barometer's spikes against the accelerometer-predicted height (HEIGHT hold 0.167 -> 0.077 m rms, seeds 1-12).

    The report's Figure 10 stays available as ``make_height_estimator("complementary")``: as HEIGHT flew it,
    WITHOUT the 0.1 Hz high-pass on the barometer (a high-passed height forgets any steady height within ~1.6 s,
    so a PD holding it at the set point makes the true height ramp away: 0.6-2.9 m rms over 12-40 s of HEIGHT;
    the accelerometer keeps its high-pass) and without the median-of-3 (at 20 Hz it cannot remove spikes that
    last several samples, and its extra sample of delay made the hold worse: 0.164 against 0.18 m rms)."""
    return make_height_estimator(HEIGHT_BEST)


class FlightCore:
    """One control step per call, per mode, in the firmware's units (module docstring)."""

    def __init__(self, *, gains: P.Gains | None = None, filter_name: str | None = None,
                 fixed_point: bool = False,
                 height_estimator: HeightEstimator | HeightKalman | None = None,
                 height_name: str = HEIGHT_BEST) -> None:
        self.gains = gains if gains is not None else P.Gains()
        self.filter_name = filter_name or BEST
        self.fixed_point = fixed_point
        self.k_gyro = float(PARAMS[Param.K_GYRO].default)  # the complementary filter's, when it is the one named
        self.filter = make_filter(self.filter_name, fixed_point=fixed_point)
        # the height estimator and its name in the parameter table (est.height)
        self.height_est = height_estimator if height_estimator is not None else make_height_estimator(height_name)
        self.height_name = height_name
        self.run_filter = True  # the RAW filter runs on every IMU sample (it must be converged on entering RAW)
        self.run_height = True  # so does the height estimator
        self.panic_ae = P.PANIC_AE
        self.panic_scale = 1.0
        self.panic_landed = False  # PANIC sensed the ground (the board then ramps panic_scale to 0)
        self.panic_hold = False  # the report's PANIC: hold the level it found (at most panic_ae), no descent loop
        self._panic_i = 0.0
        self.panic_level = 0.0
        self._panic_start = 0.0
        self._land_s = 0.0
        self.calibration = Calibration()
        self.calibrated = False
        # calibrated samples, body FRD: rates in gyro LSB, accelerations in accel LSB
        self.sp = self.sq = self.sr = 0.0
        self.sax = self.say = 0.0
        self.saz = -P.ACC_LSB_PER_G
        # attitude of both paths, rad FRD
        self.dmp_phi = self.dmp_theta = self.dmp_psi = 0.0
        self._n_imu = 0
        self.phi = self.theta = 0.0  # of the path the last control step used; psi is a property
        self._psi_src = _FULL
        self._q = (1.0, 0.0, 0.0, 0.0)  # latest attitude quaternion for the height estimator (z up)
        self._have_dmp = False
        self.height = 0.0
        self.vz = 0.0
        self.setpoint = 0.0
        self._z_base = 0.0
        self._z_int = 0.0  # height integral (ae², more lift positive)
        self._sp_from_est = False  # HEIGHT's set point follows the estimator's captured height
        self._sp_cap0 = 0.0  # the captured height at entry
        self._sp_base = 0.0  # the height at entry
        self._sp_offset = 0.0  # moved by the lift stick
        self.height_i = HEIGHT_I  # not a protocol gain (the Gains packet has P and D only); settable here
        self._lift_entry = 0
        self._on_filter = False  # the law last entered flies on the on-board filter (RAW, HEIGHT entered from RAW)
        self.ae = (0, 0, 0, 0)
        self._g_off = (0.0, 0.0, 0.0)
        self._a_off = (0.0, 0.0, 0.0)
        self._stops_seen = 0  # the height estimator's hard stops already reported
        self._wall_n = 0  # samples in a row of a sideways jolt
        self._wall_quiet = 0.0  # s until a new wall contact may be reported
        self._walls = 0  # wall contacts not yet reported
        # the headings without a compass: relative to calibration, their drift learnt while still
        self.heading_dmp = HeadingHold()
        self.heading_raw = HeadingHold()
        self.psi_dmp = self.psi_raw = 0.0  # corrected (rad, FRD)
        self._still_s = 0.0
        self.still = False
        self._n_head = 0
        self._head_dt = 0.0
        self._drift_reported = 0  # cdeg

    # ---- configuration ---------------------------------------------------------------------------------------
    def set_calibration(self, cal: Calibration) -> None:
        """Apply calibration means: gyro offsets, accelerometer offsets (gravity kept on z), DMP angle offsets,
        the pressure reference of the height estimator. Restarts the estimators."""
        self.calibration = cal
        self._g_off = cal.gyro
        self._a_off = (cal.accel[0], cal.accel[1], cal.accel[2] - P.ACC_LSB_PER_G)
        self.calibrated = True
        self.filter.reset()
        self.height_est.reset(cal.pressure)
        self.height = self.vz = 0.0
        self.heading_dmp.reset()
        self.heading_raw.reset()
        self._drift_reported = 0

    def adjust_gain(self, name: str, steps: int) -> float:
        """Change a gain by ``steps`` key presses (constants.GAIN_STEPS) inside the parameter table's range (as the
        board's gain keys and SET_PARAM); returns the new value."""
        step = P.GAIN_STEPS[name]
        spec = PARAMS[P.GAIN_PARAMS[name]]
        value = min(spec.hi, max(spec.lo, getattr(self.gains, name) + steps * step))
        setattr(self.gains, name, value)
        return value

    # ---- samples ---------------------------------------------------------------------------------------------
    def imu_sample(self, gx: int, gy: int, gz: int, ax: int, ay: int, az: int, dt: float) -> None:
        """A raw MPU6050 sample (chip words) and the time since the previous one (s)."""
        go, ao = self._g_off, self._a_off
        cgx, cgy, cgz = gx - go[0], gy - go[1], gz - go[2]
        cax, cay, caz = ax - ao[0], ay - ao[1], az - ao[2]
        self.sp, self.sq, self.sr = cgx, -cgy, -cgz
        self.sax, self.say, self.saz = cax, -cay, -caz
        if dt <= 0.0:
            return
        s = _MS2_PER_LSB
        axs, ays, azs = cax * s, cay * s, caz * s
        # a sideways jolt: a wall (or a hand) stopped the craft
        self._wall_quiet -= dt
        self._wall_n = self._wall_n + 1 if axs * axs + ays * ays > WALL_ACC * WALL_ACC else 0
        if self._wall_n >= WALL_SAMPLES and self._wall_quiet <= 0.0:
            self._walls += 1
            self._wall_quiet = WALL_REPEAT_S
        if self.run_filter:
            k = _RAD_S_PER_LSB
            f = self.filter
            f.update(cgx * k, cgy * k, cgz * k, axs, ays, azs, dt)
            # no DMP (RAW mode): the height estimator takes the filter's attitude at 100 Hz, as fast as the DMP's
            self._n_imu += 1
            if not self._have_dmp and not self._n_imu & 3:
                self._q = f.quaternion()
        if self.run_height:
            qw, qx, qy, qz = self._q
            h = self.height_est
            h.update_imu(axs, ays, azs, qw, qx, qy, qz, dt)
            self.height, self.vz = h.height, h.vz
        self._heading(cgx, cgy, cgz, dt)

    def _heading(self, cgx: float, cgy: float, cgz: float, dt: float) -> None:
        """Both paths' headings corrected for their drift (estimation/heading.py), at 100 Hz."""
        quiet = -STILL_LSB < cgx < STILL_LSB and -STILL_LSB < cgy < STILL_LSB and -STILL_LSB < cgz < STILL_LSB
        self._still_s = self._still_s + dt if quiet and getattr(self.height_est, "on_ground", False) else 0.0
        self._head_dt += dt
        self._n_head += 1
        if self._n_head < HEADING_EVERY:
            return
        still = self._still_s >= STILL_S
        if self.still and not still and abs(self.heading_drift_cdeg() - self._drift_reported) >= HEADING_LIFTOFF_CDEG:
            self._drift_reported = -1 << 30  # leaving the pad: report the drift
        self.still = still
        t = self._head_dt
        self._n_head = 0
        self._head_dt = 0.0
        self.psi_dmp = self.heading_dmp.update(self.dmp_psi, still, t)
        self.psi_raw = self.heading_raw.update(-self.filter.yaw, still, t)

    def dmp_sample(self, w: float, x: float, y: float, z: float) -> None:
        """A new DMP quaternion (body-to-earth, earth z up)."""
        roll, pitch, yaw = quaternion_to_euler(w, x, y, z)
        cal = self.calibration
        self.dmp_phi = roll - cal.dmp_phi
        self.dmp_theta = -pitch - cal.dmp_theta
        self.dmp_psi = -yaw
        self._q = (w, x, y, z)
        self._have_dmp = True

    def baro_sample(self, pressure_pa: float, dt: float, battery_10mv: int | None = None) -> None:
        """A barometer reading (Pa) and the time since the previous one (s); the battery's, read with it (10 mV)."""
        if self.run_height:
            self.height_est.update_baro(pressure_pa, dt)
        if battery_10mv is not None:
            self.battery_sample(battery_10mv)

    def battery_sample(self, volts_10mv: int) -> None:
        """A battery reading (10 mV): the height estimator's thrust model scales the motors' commands by its square."""
        if hasattr(self.height_est, "supply_sq"):
            sv = volts_10mv * 0.01 / V_REF
            self.height_est.supply_sq = sv * sv

    # ---- modes and control -----------------------------------------------------------------------------------
    def move_setpoint(self, dm: float, lo: float, hi: float) -> float:
        """HEIGHT: the set point moved by ``dm`` metres (the lift keys), kept in ``lo``..``hi``; the new one. A press
        never moves it against its own direction (a craft held above ``hi`` is not pulled down by a press up)."""
        sp = self.setpoint + dm
        sp = min(sp, max(hi, self.setpoint)) if dm > 0 else max(sp, min(lo, self.setpoint))
        self._sp_offset += sp - self.setpoint
        self.setpoint = sp
        return sp

    def enter_mode(self, mode: int, lift: int = 0) -> None:
        """Mode entry actions of the control law (the board's mode machine decides whether it may).

        HEIGHT captures the height set point and the lift stick, and flies on the attitude source of the mode it
        was entered from (RAW: the on-board filter; otherwise the DMP). CALIBRATION clears the DMP angle offsets
        so that ``dmp_phi``/``dmp_theta`` read uncorrected angles while the means are collected. PANIC restarts
        at the full descent level."""
        mode = int(mode)
        if mode == _HEIGHT:
            # The set point is the height at entry, refined by what later readings reveal about that instant (the
            # estimator's captured height, when it has one), plus the stick's offset.
            capture = getattr(self.height_est, "capture", None)
            self._sp_from_est = capture is not None
            self._sp_cap0 = capture() if capture is not None else 0.0
            self._sp_base = self.height
            self._sp_offset = 0.0
            self.setpoint = self._sp_base
            self._lift_entry = lift
            self._z_base = C.lift_to_z(lift)
            self._z_int = 0.0
        elif mode == _PANIC:
            # the descent starts from the level the motors ran at: PANIC never spins them up by itself
            self.panic_scale = 1.0
            self.panic_landed = False
            self._land_s = 0.0
            self._panic_start = self.panic_level = sum(self.ae) / 4.0
            self._panic_i = self._panic_start - self.panic_ae
        elif mode == _CAL:
            self.calibration = replace(self.calibration, dmp_phi=0.0, dmp_theta=0.0)
        if mode == _RAW:
            # the DMP is off in RAW mode: the height estimator follows the on-board filter
            self._have_dmp = False
        # HEIGHT flies on the source of the mode it was entered from; RAW on the filter; the rest on the DMP
        if mode != _HEIGHT:
            self._on_filter = mode == _RAW

    def panic_motors(self, scale: float = 1.0, dt: float = 0.0) -> tuple[int, int, int, int]:
        """PANIC: the descent loop's level (module docstring) times ``scale`` (0..1; the board ramps it down once
        ``panic_landed``); ``dt`` 0 (a recompute between control steps) moves no state."""
        if self.panic_hold:
            self.panic_level = min(float(self.panic_ae), self._panic_start)
        elif not self.panic_landed and dt > 0.0:
            err = -panic_descent_rate(self.height) - self.vz
            self._panic_i = max(-self.panic_ae, min(float(PANIC_MAX_AE), self._panic_i + PANIC_KI * err * dt))
            floor = min(PANIC_MIN_FRAC * self.panic_ae, self._panic_start)
            level = max(floor, min(float(PANIC_MAX_AE), self.panic_ae + PANIC_KP * err + self._panic_i))
            still = level < PANIC_LAND_FRAC * self.panic_ae and abs(self.vz) < PANIC_LAND_VZ
            self._land_s = self._land_s + dt if still else 0.0
            self.panic_landed = self._land_s >= PANIC_LAND_S
            self.panic_level = level
        level = int(self.panic_level * max(0.0, min(1.0, scale)))
        if self.calibrated and level > 0:
            g = self.gains
            phi, theta = self.dmp_phi, self.dmp_theta  # PANIC's sensor path is the DMP's
            a = C.ANGLE_LSB_PER_RAD
            lm = C.cascade(0.0, phi * a, self.sp, g.p1, g.p2)
            mm = C.cascade(0.0, theta * a, self.sq, g.p1, g.p2)
            nm = C.yaw_rate(0.0, self.sr, g.yaw_p)
            return C.mix(-4 * level * level, lm, mm, nm, armed=False)
        return level, level, level, level

    def control(self, mode: int, roll: int, pitch: int, yaw: int, lift: int,
                dt: float = 0.0025) -> tuple[int, int, int, int]:
        """The control law of ``mode`` for these sticks (trims included); returns ae1..ae4 and keeps them in
        ``self.ae``. ``dt`` is the control period (s), used by HEIGHT's moving set point. ``mode`` is entered already
        (``enter_mode``)."""
        mode = int(mode)
        g = self.gains
        if mode == _FULL or mode == _HEIGHT or mode == _RAW:
            if mode == _RAW or (mode == _HEIGHT and self._on_filter):
                f = self.filter
                phi = f.roll
                theta = -f.pitch
                self.phi, self.theta, self._psi_src = phi, theta, _RAW
            else:
                phi, theta = self.dmp_phi, self.dmp_theta
                self.phi, self.theta, self._psi_src = phi, theta, _FULL
            lm = C.cascade(roll >> _SHIFT, phi * _ANGLE, self.sp, g.p1, g.p2)
            mm = C.cascade(pitch >> _SHIFT, theta * _ANGLE, self.sq, g.p1, g.p2)
            nm = C.yaw_rate(yaw >> _YSHIFT, self.sr, g.yaw_p)
            if mode == _HEIGHT:
                d = lift - self._lift_entry
                if d > HEIGHT_STICK_DEADBAND or d < -HEIGHT_STICK_DEADBAND:
                    self._sp_offset += d / STICK_MAX * HEIGHT_STICK_RATE * dt
                sp = self._sp_base + self._sp_offset
                if self._sp_from_est:
                    sp += self.height_est.captured_height - self._sp_cap0
                self.setpoint = sp
                sp_mm, h_mm = self.setpoint * 1000.0, self.height * 1000.0
                z = C.height_pd(self._z_base, sp_mm, h_mm, self.vz * 1000.0, g.height_p, g.height_d) - self._z_int
                sat = z > 0.0
                if sat:
                    z = 0.0
                if self.height_i > 0.0:
                    # saturated = asking for less than no lift: only unwinding steps count (anti-windup)
                    self._z_int = C.height_integral(self._z_int, sp_mm, h_mm, self.height_i, dt, saturated=sat)
            else:
                z = _lift_to_z(lift)
            out = _mix(z, lm, mm, nm)
        elif mode == _MANUAL or mode == _YAW:
            self.phi, self.theta, self._psi_src = self.dmp_phi, self.dmp_theta, _FULL
            lm = roll * C.MANUAL_LM_GAIN
            mm = pitch * C.MANUAL_LM_GAIN
            if mode == _YAW:
                nm = C.yaw_rate(yaw >> C.STICK_YAW_SHIFT, self.sr, g.yaw_p)
            else:
                nm = yaw * C.MANUAL_N_GAIN
            out = C.mix(C.lift_to_z(lift), lm, mm, nm)
        elif mode == _PANIC:
            self._follow_sensors()
            out = self.panic_motors(self.panic_scale, dt)
        else:  # SAFE, CALIBRATION, WIRELESS: motors off
            self._follow_sensors()
            out = (0, 0, 0, 0)
        self.ae = out
        # its on-the-ground test: no motor could lift the craft
        self.height_est.motors_off = max(out) < GROUND_AE
        # the thrust model's hint: the sum of ae², scaled by the pack (the ESCs' speed follows its voltage)
        self.height_est.thrust_hint = (float(out[0] * out[0] + out[1] * out[1] + out[2] * out[2] + out[3] * out[3])
                                       * getattr(self.height_est, "supply_sq", 1.0))
        return out

    def pending_contact(self) -> tuple[int, int] | None:
        """A hard stop felt since the last call (the board sends it as EventCode.CONTACT): (ContactKind, the
        estimated speed into the surface in mm/s; 0 for a wall), or None. One per call."""
        h = self.height_est
        stops = getattr(h, "stops", 0)
        if stops != self._stops_seen:
            self._stops_seen = stops
            kind = ContactKind.CEILING if h.stop_kind == STOP_UP else ContactKind.GROUND
            return int(kind), min(0xFFFF, round(h.stop_speed * 1000.0))
        if self._walls:
            self._walls = 0
            return int(ContactKind.WALL), 0
        return None

    @property
    def height_unsure(self) -> bool:
        """The height estimate is unsure (telemetry's HEIGHT_UNSURE flag)."""
        return bool(getattr(self.height_est, "unsure", False))

    def _follow_sensors(self) -> None:
        # No attitude loop runs (PANIC levels on the DMP itself): the angles shown follow the sensor path that runs,
        # the DMP's or, without it (RAW's path), the filter's, so a flight that ended tilted is not shown tilted on
        # the pad (issue 22).
        if self._have_dmp:
            self.phi, self.theta, self._psi_src = self.dmp_phi, self.dmp_theta, _FULL
        else:
            f = self.filter
            self.phi, self.theta, self._psi_src = f.roll, -f.pitch, _RAW

    # ---- telemetry helpers -----------------------------------------------------------------------------------
    @property
    def raw_psi(self) -> float:
        """Yaw of the on-board filter (rad, FRD: nose right positive), its drift learnt at rest taken out."""
        return self.psi_raw

    @property
    def psi(self) -> float:
        """Yaw (rad, FRD) of the path the last control step used, relative to calibration and its drift learnt
        while still taken out (estimation/heading.py)."""
        return self.psi_raw if self._psi_src == _RAW else self.psi_dmp

    def heading_drift_cdeg(self) -> int:
        """How far the heading in use has drifted since calibration (0.01°, what was taken out)."""
        hold = self.heading_raw if self._psi_src == _RAW else self.heading_dmp
        return round(hold.offset * 18000.0 / 3.141592653589793)

    def pending_heading_drift(self) -> int | None:
        """The drift to report (EventCode.HEADING_DRIFT, 0.01°) when the craft leaves the pad or it moved by
        HEADING_REPORT_CDEG since the last report; else None."""
        d = self.heading_drift_cdeg()
        if abs(d - self._drift_reported) < HEADING_REPORT_CDEG:
            return None
        self._drift_reported = d
        return d

    def attitude_centideg(self) -> tuple[int, int, int]:
        """phi, theta, psi in 0.01 deg (the Attitude packet's unit)."""
        k = 18000.0 / 3.141592653589793
        return round(self.phi * k), round(self.theta * k), round(self.psi * k)
