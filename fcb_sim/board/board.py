"""The firmware's main loop as a sans-IO object with a microsecond clock (report Figure 2, sections 4.2 and 5).

Timer interrupts set flags (``fcb_sim.board.scheduler``); the main loop runs the flagged tasks, each a method in the
task table, in the order the scheduler picks (round robin, the report's, or priority, its proposed fix). Tasks
(``TASKS``, the order of the Profile packet's ``task`` ids):

- ``parse``: bytes in the receive queue (UART, or BLE after the handover) through the protocol decoder; a changed
  stick recomputes the motor commands at once in the flight modes (docs/board.md, "Sticks to motors");
- ``sensor``: the IMU read, DMP at 200 Hz (quaternion plus raw words) or RAW at 400 Hz (raw words);
- ``control``: the flight core's control step at the sensor rate, motors to the world;
- ``baro``: the ADC (battery) and barometer at 20 Hz;
- ``telemetry``: Attitude and Motion at 50 Hz (``link.telemetry_hz``), Height at 20 Hz, Status and Gains at 5 Hz
  (over BLE: Compact);
  during a log download, the log chunks instead;
- ``heartbeat``: the Heartbeat at 10 Hz (``link.heartbeat_ms``), and the safety monitor (the link failsafe's two
  stages, battery, tilt -> PANIC; docs/modes.md);
- ``logging``: one flash-log record per control step while logging is on.

The board's clock advances as the real board's would (the Figure 14 cost model, ``fcb_sim/board/timing.py``), and the
world's physics advances with it. Commands are a table (``fcb_sim.board.commands``); the UART is a wire model
(``fcb_sim.board.uart``); the profiling bench is ``fcb_sim.lab.profile``. How the model was derived, what it explains
and what it does not: docs/board.md.

Sans-IO contract: ``uart_receive(data)`` (bytes arrive now), ``advance(until_us)``, ``uart_transmit() -> bytes``
(what has left the UART at the protocol's BAUD_RATE by now); ``next_event_us()`` tells a real-time driver when to
call again.
BLE goes through ``board.wireless`` (a ``fcb_sim.board.wireless.WirelessLink``): every packet the board sends is offered
to it. Without a radio, ``ble_connected()``, ``ble_disconnected()`` and ``ble_receive(data)`` drive the link; with
``wireless.BoardRadio`` its ``on_data`` is ``board.ble_data`` and its ``on_disconnect`` is ``board.ble_lost``
(PANIC if the board was flown over BLE). ``status()`` and ``profile()`` report (``prof`` holds the measurements);
the same loop runs as fast as possible (tests, ``fcb-sim profile``) or paced to the wall clock (fcb_sim/hosts/serve.py).
"""

from __future__ import annotations

import random
from collections.abc import Callable
from typing import Any

from fcb_sim.board import telemetry as tm
from fcb_sim.board.calibration import CALIBRATED_VARS
from fcb_sim.board.commands import CommandDesk
from fcb_sim.board.flash_log import FLASH_US_PER_BYTE, Download, FlashLog, LogVar
from fcb_sim.board.flight import FlightCore
from fcb_sim.board.linktimer import LinkTimer
from fcb_sim.board.modes import FLIGHT_MODES, ModeChange, ModeConfig, ModeMachine
from fcb_sim.board.param_bindings import apply_values
from fcb_sim.board.parts import BoardConfig, BoardParts
from fcb_sim.board.scheduler import (
    PARSE_MAX_BYTES,
    TASKS,
    Scheduler,
    timer_period,
)
from fcb_sim.board.telemetry import Telemetry
from fcb_sim.board.timing import (
    COSTS,
    DOWNLOAD_US_PER_CHUNK,
    PARSE_US_BASE,
    PARSE_US_PER_BYTE,
    RAW_FILTER_EXTRA_US,
    REPORT_RECORD_BYTES,
    RICE_ENCODE_EXTRA_US,
    SENSOR_PERIOD_US,
    Interference,
    Profiler,
)
from fcb_sim.board.transmit import Transmitter
from fcb_sim.board.uart import BleInbox, Uart
from fcb_sim.board.wireless import WirelessLink
from fcb_sim.world.physics import World
from term.core.logformat import SCHEME_RICE
from term.core.protocol import (
    PARAMS,
    PRESETS,
    PROTOCOL_VERSION,
    Button,
    Command,
    Decoder,
    EventCode,
    Heartbeat,
    HeartbeatAck,
    Hello,
    Joystick,
    LogState,
    Mode,
    Param,
    Role,
    Status,
    WirelessState,
)

BOARD_VERSION = (0, 1)


def _default(param: Param) -> Any:
    return PARAMS[param].default


def _parts(cfg: BoardConfig, world: World | None, core: FlightCore | None, wireless: WirelessLink | None,
           log_vars: tuple[LogVar, ...] | None) -> tuple[World, FlightCore, WirelessLink, ModeMachine, FlashLog]:
    """The board's parts: the world, flight core and BLE link it is given, or its own built from the config and
    the parameter table's defaults; its mode machine and flash log (in this order: the world draws first)."""
    if world is None:
        world = World(cfg.seed)
    if core is None:
        core = FlightCore(fixed_point=cfg.fixed_point, filter_name=_default(Param.ATTITUDE_FILTER),
                          height_name=_default(Param.HEIGHT_ESTIMATOR))
    if wireless is None:
        wireless = WirelessLink()
    mc = ModeConfig(link_timeout_s=cfg.link_timeout_s, link_failsafe_s=cfg.link_failsafe_s, panic_level=core.panic_ae)
    modes = ModeMachine(mc, calibration_names=CALIBRATED_VARS)
    log = FlashLog(size=cfg.log_bytes, scheme=cfg.log_scheme, **({} if log_vars is None else {"variables": log_vars}))
    return world, core, wireless, modes, log


def _slack_budget(name: str) -> int:
    """The slack rule's estimate of a task's duration (µs): its 99.9th percentile."""
    return int(COSTS[name].figure[3])


def _sensor_path(setting: str, modes: ModeMachine) -> str:
    """The sensor path to run: the setting (Param.SENSOR_PATH), or for "auto" RAW in RAW mode (and HEIGHT from
    RAW), else DMP."""
    if setting != "auto":
        return setting
    m = modes.mode
    if m == Mode.RAW or (m == Mode.HEIGHT and modes.height_base == Mode.RAW):
        return "raw"
    return "dmp"


# A log download rides the telemetry task (in SAFE only) at this period whatever link.telemetry_hz says: the
# report preset's 1.9 s telemetry period paced a download to 0.3 kB/s and a Status to one every 19 s.
DOWNLOAD_PERIOD_US = 20_000


class Board:
    """The simulated flight-control board (module docstring)."""

    def __init__(self, config: BoardConfig | None = None, *, world: World | None = None,
                 core: FlightCore | None = None, wireless: WirelessLink | None = None,
                 log_vars: tuple[LogVar, ...] | None = None) -> None:
        self.config = cfg = config or BoardConfig()
        self.world, self.core, self.wireless, self.modes, log = _parts(cfg, world, core, wireless, log_vars)
        self.modes.listeners.append(self._on_mode_change)
        self.download = Download()
        self.desk = CommandDesk()
        self.rng = random.Random(cfg.seed ^ 0x5EED)
        self._cost = {name: c.sampler(self.rng) for name, c in COSTS.items()}
        self.now = 0  # µs since boot
        self._present = 0  # the outside world's present: the latest time ``advance`` was asked to reach
        self.decoder = Decoder()
        self.ble_decoder = Decoder()
        self.uart = Uart()
        self.tx = Transmitter(self.uart, self.wireless)
        self.ble_rx = BleInbox()
        self.rx_ignored = 0  # UART bytes while the parser reads BLE
        self.link = LinkTimer()  # the PC's silence, honest about a starved simulator
        self.rtt_us: int | None = None  # the last heartbeat round trip (Heartbeat → HeartbeatAck)
        self._hb_sent: tuple[int, int] | None = None  # (counter, time) of the last heartbeat sent
        self._hb_rtt_fresh = False  # whether rtt_us answers the last heartbeat (it is reported in the next)
        self.prof = Profiler(TASKS)
        self.misses_reported_at = -10**9
        self._path = _sensor_path(cfg.sensor_path, self.modes)
        self.sched = Scheduler(self.rng, self._period, priority=cfg.scheduler == "priority")
        self.irq = Interference(random.Random(cfg.seed ^ 0x150), softdevice=cfg.softdevice)
        self._residual_rng = random.Random(cfg.seed ^ 0x7E5)
        self._idle = True  # the loop is waiting (no task ran since the last wait)
        self._tasks: dict[str, Callable[[], int]] = {
            "parse": self._task_parse, "sensor": self._task_sensor, "control": self._task_control,
            "baro": self._task_baro, "telemetry": self._task_telemetry, "heartbeat": self._task_heartbeat,
            "logging": self._task_logging}
        self._sample_t: float | None = None  # time of the previous sensor read, for dt
        self._baro_t: int | None = None
        self.telemetry = Telemetry()
        self.heartbeats = 0
        self.battery = self.world.battery()
        self.pressure, self.temperature = self.world.baro()
        self.ae = (0, 0, 0, 0)
        self.motors_at_us = 0  # board time at which ``ae`` took effect
        self._sticks_used: tuple[int, int, int, int] | None = None  # what the motors were last computed from
        self._crashes_seen = len(self.world.crashes)
        self.on_task: Any = None  # optional callback(name, start_us, duration_us) after every task run
        # what the handlers act on (fcb_sim/board/parts.py): commands, parameters, telemetry
        self.parts = BoardParts(cfg, self.core, self.modes, log, self.download, self.tx, self.wireless, self.prof,
                                self.sched, self.uart, lambda: self.now)
        self.event = self.parts.event
        self.parts.apply_queue_rule()
        apply_values(self.parts, PRESETS[cfg.preset])  # the preset over the defaults (fcb_sim/board/param_bindings.py)
        if cfg.boot_hello:
            self._hello()
            self.event(EventCode.BOOT, PROTOCOL_VERSION)

    # --- the outside world's calls ------------------------------------------------------------------------

    def uart_receive(self, data: bytes) -> None:
        """Bytes from the PC, reaching the UART at the present: the time ``advance`` was last asked to reach
        (the loop may have run a task past it; the wire does not wait for the task). The UART interrupt queues
        them; a full queue drops and counts."""
        at = min(self.now, self._present)
        taken = self.uart.receive(data, at)
        if taken:
            self.irq.rx(at, taken)

    def uart_transmit(self) -> bytes:
        """What has left the UART by now: BAUD_RATE, 8N1."""
        return self.tx.transmit(self.now)

    @property
    def rx_overflow(self) -> int:
        """Bytes dropped from a full receive queue (UART and BLE)."""
        return self.uart.rx_overflow + self.ble_rx.overflow

    @property
    def download_next(self) -> int | None:
        """The next log chunk to send, or None when no download runs."""
        return self.download.next

    def ble_connected(self) -> None:
        self.wireless.connected()

    def ble_disconnected(self) -> None:
        """The phone went away: a board flown over BLE must PANIC."""
        self.ble_lost(self.wireless.disconnected())

    def ble_receive(self, data: bytes) -> None:
        """What the phone wrote (through the WirelessLink: ignored before the handover)."""
        self.ble_data(self.wireless.ble_receive(data))

    # The radio (fcb_sim.board.wireless.BoardRadio) drives the WirelessLink itself and calls these two:

    def ble_data(self, data: bytes) -> None:
        """Parser bytes from BLE that already went through ``wireless.ble_receive`` (the radio's ``on_data``)."""
        self.ble_rx.put(data)
        self.wireless_events()

    def ble_lost(self, was_started: bool) -> None:
        """The radio lost its phone after calling ``wireless.disconnected()`` (the radio's ``on_disconnect``)."""
        self.ble_rx.queue.clear()
        if was_started and self.modes.flying:
            self.modes.panic(self.now / 1e6, "ble")
        self.wireless_events()

    def starved(self, until_us: int, *, slip: bool = False) -> None:
        """The real-time driver could not run the board from now until ``until_us``: not the PC's silence, and
        said as SIM_LAG (fcb_sim/board/linktimer.py)."""
        lag_ms = self.link.starved(self.now, until_us, slip=slip)
        if lag_ms is not None:
            self.event(EventCode.SIM_LAG, lag_ms)

    @property
    def last_frame_us(self) -> int | None:
        """The last valid frame from the PC (board time)."""
        return self.link.last_frame_us

    def next_tick_us(self) -> int:
        """The board time of the next timer interrupt, or of the last byte of a burst on the receive line."""
        t = self.sched.next_tick_us()
        wire = self.uart.next_arrival_us()
        return t if wire is None else min(t, wire)

    def next_event_us(self) -> int:
        """When a real-time driver should next call ``advance``: now if a task is ready to run (the one that
        just ran ends at ``now``), else at the next timer interrupt or the end of a burst still arriving."""
        self._fire_timers()
        ready = self._pick() is not None if self.sched.priority else any(self.sched.flags.values())
        self.sched.parse_limit = PARSE_MAX_BYTES
        return self.now if ready else self.next_tick_us()

    @property
    def mode(self) -> Mode:
        return self.modes.mode

    @property
    def path(self) -> str:
        return self._path

    @property
    def log(self) -> FlashLog:
        """The flash log (a parameter change may replace it: the parts hold the one in force)."""
        return self.parts.log

    def reset_profile(self) -> None:
        self.prof.reset(self.now)

    # --- the main loop ------------------------------------------------------------------------------------

    def advance(self, until_us: int) -> None:
        """Run the loop until the board clock reaches ``until_us`` (a task running then finishes first)."""
        if until_us > self._present:
            self._present = until_us
        sched = self.sched
        while self.now < until_us:
            self._fire_timers()
            task = self._pick()
            if task is None:
                nxt = self.next_tick_us()
                self.now = min(max(nxt, self.now + 1), until_us) if self.now < nxt else self.now + 1
                self._idle = True
                continue
            if self._idle:
                # The loop was waiting: the flag is seen only once the interrupts in progress are over (those that
                # hit a running task are in its measured duration already).
                self._idle = False
                free = self.irq.free_at(self.now, sched.timer_isr_end, *self.tx.wire(self.now), self.ae)
                if self.config.residual_jitter_us > 0:
                    free += int(self._residual_rng.expovariate(1.0 / self.config.residual_jitter_us))
                if free > self.now:
                    self.now = free
                    continue
            start = self.now
            sched.flags[task] = False
            dur = max(1, int(self._tasks[task]()))
            self.now = start + dur
            period = self.prof.ran(task, start, dur)
            if task == "control" and period is not None and self.prof.control_period(self._path, period):
                self._deadline_missed(period)
            if self.on_task is not None:
                self.on_task(task, start, dur)

    def _fire_timers(self) -> None:
        if self.download.active and self.sched.next["telemetry"] - self.now > DOWNLOAD_PERIOD_US:
            self.sched.restart("telemetry", self.now)  # a download began under a slower telemetry rate
        self.sched.fire(self.now)
        if self.ble_rx.queue or self.uart.arrived(self.now):
            self.sched.flags["parse"] = True

    def _pick(self) -> str | None:
        return self.sched.pick(self.now, _slack_budget)

    def _period(self, name: str) -> int:
        if name == "telemetry" and self.download.active:
            return DOWNLOAD_PERIOD_US
        return timer_period(name, self._path, self.config.telemetry_hz, self.config.heartbeat_ms * 1000)

    def _deadline_missed(self, period: int) -> None:
        """A control period at least WCET99: reported while flying, at most every 10 s."""
        if self.now - self.misses_reported_at >= 10_000_000 and self.modes.flying:
            self.misses_reported_at = self.now
            self.event(EventCode.DEADLINE_MISS, period)

    # --- tasks: each returns its duration in µs -----------------------------------------------------------

    def _task_parse(self) -> int:
        limit = self.sched.parse_limit
        self.sched.parse_limit = PARSE_MAX_BYTES
        if self.wireless.reads_uart:
            chunk, decoder = self.uart.take(min(limit, self.uart.arrived(self.now))), self.decoder
        else:
            self.rx_ignored += self.uart.discard_rx()
            chunk, decoder = self.ble_rx.take(limit), self.ble_decoder
        self.parts.report_overflow(self.rx_overflow)
        cost = PARSE_US_BASE + PARSE_US_PER_BYTE * len(chunk)
        for pkt in decoder.feed(chunk):
            self.link.heard(self.now)
            if self.modes.link_hold:
                self.modes.link_back(self.now / 1e6)  # the failsafe's stage 1 ends with the first frame back
                self._drain_mode_events()
            self._handle(pkt)
        if self.config.stick_reaction and self._sticks_used is not None and self.modes.sticks() != self._sticks_used:
            cost += self._react(self.now + cost)
        return cost

    def _react(self, at: int) -> int:
        """The sticks changed (decoded by board time ``at``): the motor commands now, as the control step would
        compute them but without a time step (docs/board.md, "Sticks to motors"); returns the cost (µs)."""
        m, fc = self.modes, self.core
        mode = m.mode
        if mode not in FLIGHT_MODES:
            return 0  # motors off (SAFE, CALIBRATION) or forced (PANIC)
        path = self._path
        if self.sched.priority and at + COSTS[f"control_{path}"].figure[3] > self.sched.next["sensor"]:
            return 0  # the slack rule: it might not end before the tick; the control step at the tick does it
        cost = self._cost[f"control_{path}"]()
        sticks = m.sticks()
        self._set_motors(fc.control(int(mode), *sticks, 0.0), at + cost)
        self._sticks_used = sticks
        self.prof.reactions.add(at, cost)
        return cost

    def _set_motors(self, ae: tuple[int, int, int, int], at: int) -> None:
        """The motor commands take effect at board time ``at``."""
        self.ae = ae
        self.motors_at_us = at
        self.modes.motor_level = sum(ae) // 4
        self.world.advance_to(at / 1e6)
        self.world.set_motors(*ae)

    def _task_sensor(self) -> int:
        t = self.now / 1e6
        w = self.world
        w.advance_to(t)
        gx, gy, gz, ax, ay, az = w.imu()
        dt = SENSOR_PERIOD_US[self._path] / 1e6 if self._sample_t is None else t - self._sample_t
        self._sample_t = t
        fc = self.core
        fc.imu_sample(gx, gy, gz, ax, ay, az, dt)
        sums = self.modes.calibration if self.modes.mode == Mode.CALIBRATION else None
        if sums is not None:
            sums.add_imu(gx, gy, gz, ax, ay, az)
        if self._path == "dmp":
            q = w.dmp()
            if q is not None:
                fc.dmp_sample(*q)
                if sums is not None:
                    sums.add_dmp(*q)
            cost = self._cost["sensor_dmp"]()
        else:
            cost = self._cost["sensor_raw_fixed" if self.config.fixed_point else "sensor_raw"]()
            cost += RAW_FILTER_EXTRA_US[(fc.filter_name, fc.fixed_point)]  # the filter running now, beyond the report's
        if not self.sched.priority:
            self.sched.flags["control"] = True  # data ready: control follows
        return cost

    def _task_control(self) -> int:
        m = self.modes
        now_s = self.now / 1e6
        crashes = self.world.crashes
        while self._crashes_seen < len(crashes):  # the impact the accelerometer would feel
            m.crash(now_s, round(crashes[self._crashes_seen].speed * 1000))
            self._crashes_seen += 1
        m.tick(now_s)
        mode = m.mode
        fc = self.core
        if mode == Mode.PANIC:
            if fc.panic_landed:
                m.panic_ground(now_s)
            fc.panic_scale = m.panic_scale(now_s)
        sticks = m.sticks()
        ae = fc.control(int(mode), *sticks, SENSOR_PERIOD_US[self._path] / 1e6)
        if not m.motors_enabled:
            ae = (0, 0, 0, 0)
        contact = fc.pending_contact()
        if contact is not None:  # a hard stop the accelerometer felt: the pilot sees it
            m.emit(EventCode.CONTACT, contact[0] << 16 | contact[1], now_s)
        drift = fc.pending_heading_drift()
        if drift is not None:  # the heading is relative: how far it drifted since calibration
            m.emit(EventCode.HEADING_DRIFT, drift, now_s)
        ae = m.motor_test.output(m, now_s, self.link.silent_us(self.now) / 1e6) or ae  # the bench test (SAFE)
        self._sticks_used = sticks
        self._set_motors(ae, self.now)
        if self.log.recording:
            self.sched.flags["logging"] = True
        want = _sensor_path(self.config.sensor_path, self.modes)
        if want != self._path:
            self._path = want
            self.sched.restart("sensor", self.now)
            self._sample_t = None
        flying = mode in FLIGHT_MODES
        path = self._path
        return self._cost[f"control_{path}" if flying or mode == Mode.PANIC else f"control_{path}_safe"]()

    def _task_logging(self) -> int:
        written = self.log.append(tm.log_row(self.parts, self.readings()))
        if self.log.state == LogState.FULL and not self.parts.log_full_reported:
            self.parts.log_full_reported = True
            self.event(EventCode.LOG_FULL, self.log.used)
        base = self._cost["logging"]() - FLASH_US_PER_BYTE * REPORT_RECORD_BYTES
        if self.log.scheme == SCHEME_RICE:
            base += RICE_ENCODE_EXTRA_US
        return max(5, base) + FLASH_US_PER_BYTE * written

    def _task_baro(self) -> int:
        self.world.advance_to(self.now / 1e6)
        self.pressure, self.temperature = self.world.baro()
        self.battery = self.world.battery()
        dt = 0.05 if self._baro_t is None else (self.now - self._baro_t) / 1e6
        self._baro_t = self.now
        self.core.baro_sample(self.pressure, dt, self.battery)
        self.modes.battery = self.battery
        if self.modes.mode == Mode.CALIBRATION:
            self.modes.calibration_sample({"pressure": self.pressure})
        return self._cost["baro"]()

    def _task_heartbeat(self) -> int:
        self.heartbeats += 1
        # The previous heartbeat's round trip rides on this one (0.1 ms units; 0 when its ACK did not come back).
        rtt = min(0xFFFF, max(1, (self.rtt_us or 0) // 100)) if self._hb_rtt_fresh else 0
        counter = self.heartbeats & 0xFFFF
        self.send(Heartbeat(counter, (self.now // 1000) & 0xFFFFFFFF, rtt))
        self._hb_sent, self._hb_rtt_fresh = (counter, self.now), False
        silent = self.link.silent_us(self.now) / 1e6
        phi, theta, _ = self.core.attitude_centideg()
        self.modes.supervise(self.now / 1e6, link_silent_s=silent, battery=self.battery,
                             phi_cdeg=phi, theta_cdeg=theta)
        self._drain_mode_events()
        return self._cost["heartbeat"]()

    def _task_telemetry(self) -> int:
        self.telemetry.runs += 1
        self._drain_mode_events()
        if self.download.active:
            return self._download_step()
        if self.wireless.state is WirelessState.STARTED:
            if self.wireless.compact_due():  # as many as fill the notifications between two heartbeats
                self.send(tm.compact(self.parts, self.readings()))
            if self.wireless.compact2_due():  # the rest of the flight screen, once per heartbeat period
                self.send(tm.compact2(self.parts, self.readings()))
        else:
            for pkt in self.telemetry.packets(self.parts, self.readings()):
                self.tx.telemetry(pkt, self.now)
        return self._cost["telemetry"]()

    def _download_step(self) -> int:
        """Log chunks instead of telemetry: as many as the transmit buffer takes (the wire paces the download);
        a Status every tenth run."""
        chunks, done = self.download.step(self.log, lambda: self.tx.bulk_room(self.now), self.send)
        if done:
            self._end_download()
        if self.telemetry.runs % 10 == 0:
            self.send(self.status())
        return max(chunks * DOWNLOAD_US_PER_CHUNK, 20)

    def _end_download(self) -> None:
        self.download.end(self.log, self.send)
        self.event(EventCode.LOG_DONE, self.download.sent)

    # --- telemetry and packets ----------------------------------------------------------------------------

    def readings(self) -> tm.Readings:
        """What the tasks last measured and commanded, for the telemetry builders."""
        return tm.Readings(self.ae, self.pressure, self.temperature, self.battery, self._path)

    def status(self) -> Status:
        return tm.status(self.parts, self.readings())

    def send(self, pkt: Any) -> None:
        """A packet to the PC, through the transmit side (fcb_sim/board/transmit.py)."""
        self.tx.send(pkt, self.now)

    def _hello(self) -> None:
        self.send(Hello(PROTOCOL_VERSION, Role.BOARD, BOARD_VERSION[0], BOARD_VERSION[1], self.config.board_id))

    def _drain_mode_events(self) -> None:
        for code, arg, _t in self.modes.drain_events():
            self.event(code, arg)

    def wireless_events(self) -> None:
        """Report the handover's state changes (Event WIRELESS_STATE)."""
        self.parts.wireless_events()

    def _on_mode_change(self, change: ModeChange) -> None:
        if change.old == Mode.CALIBRATION and self.modes.calibrated:
            self.core.set_calibration(self.modes.calibration.result(self.pressure))
        if change.new != Mode.SAFE and self.download.active:
            self._end_download()
        self.core.enter_mode(int(change.new), self.modes.lift)

    # --- packets from the PC ------------------------------------------------------------------------------

    def _handle(self, pkt: Any) -> None:
        kind = type(pkt)
        if kind is Joystick:
            self.modes.joystick = pkt
            if pkt.buttons & Button.FIRE:
                self.modes.panic(self.now / 1e6, "fire")
                self._drain_mode_events()
        elif kind is Command:
            answer = self.desk.answer(self.parts, pkt)
            if answer is None:
                return  # shed: no room for its Ack; the terminal retries
            ack, after, retry = answer
            self.send(ack)
            if not retry:
                self._drain_mode_events()
                if after is not None:
                    after()
        elif kind is HeartbeatAck:
            if self._hb_sent is not None and pkt.counter == self._hb_sent[0]:
                self.rtt_us, self._hb_rtt_fresh = self.now - self._hb_sent[1], True
        elif kind is Hello:
            # A terminal (re)connected: its cmd_ids and sequence numbers start afresh, so a first command equal to
            # the last one seen is not a retry, and its sequence jump is not loss.
            self.desk.forget()
            self.decoder.reset_sequence()
            self.ble_decoder.reset_sequence()
            self._hello()

    # --- the profile --------------------------------------------------------------------------------------

    def profile(self) -> dict[str, Any]:
        """The board's own profile: per task figures beside the report's (Figure 14), and the control deadline
        misses (periods between control starts at least WCET99, and WCET99.9)."""
        return self.prof.summary(self.now, self._path, self.config.scheduler, self.config.fixed_point,
                                 self.sched.ticks_lost, self.irq)
