"""The firmware's main loop as a sans-IO object with a microsecond clock (report Figure 2, sections 4.2 and 5).

Timer interrupts set flags; the main loop services them. Tasks (``TASKS``, the order of the Profile packet's
``task`` ids):

- ``parse``: bytes in the receive queue (UART, or BLE after the handover) through the protocol decoder;
- ``sensor``: the IMU read, DMP at 200 Hz (quaternion plus raw words) or RAW at 400 Hz (raw words);
- ``control``: the flight core's control step at the sensor rate, motors to the world;
- ``baro``: the ADC (battery) and barometer at 20 Hz;
- ``telemetry``: Attitude and Motion at 50 Hz, Height at 20 Hz, Status and Gains at 5 Hz (over BLE: Compact);
  during a log download, the log chunks instead;
- ``heartbeat``: the Heartbeat at 10 Hz, and the safety monitor (link silence, battery, tilt -> PANIC);
- ``logging``: one flash-log record per control step while logging is on.

The timing model (``fcb_sim/timing.py``) makes the board's clock advance as the real board's would, and the
world's physics advances with that clock:

- Every run of a task costs a draw from the duration the report measured for it (Figure 14, FULL rows: mean,
  sigma, p99 and p99.9 all held; a log-normal body plus a small share of slow runs, because the rows have long
  right tails, the DMP read's p99 four sigma above its mean). The parse cost is ours: a base plus 4 µs a byte
  (COBS frames with a CRC), and logging charges 15 µs for every byte it programs.
- The periodic tasks run from app timers on the 32768 Hz RTC (report section 2: the nRF SDK's timers), whose
  periods are whole ticks: 2.5 ms is 82 ticks (2502.4 µs), 20 ms is 655. Started at unrelated moments, the
  timers also slide past one another, so a slow task meets the sensor tick at every phase in turn.
- A timer's interrupt only sets a flag; the loop sees it when it next tests it. A tick that comes while its
  flag is still set is lost (``ticks_lost``); ticks are never queued.
- Interrupts that find the loop idle delay the task a tick releases: the SoftDevice's advertising events (every
  40 ms plus 0-10 ms, with or without a phone; Nordic's processing times), one interrupt per UART byte each way,
  the motor PWM timer and the app_timer's own interrupt. Interrupts that hit a running task are already in its
  measured duration.

Two schedulers:

- ``round-robin``: the report's design. Every pass of the loop runs each flagged task once, in a fixed order
  (``ROUND_ROBIN_ORDER``; a flag set during a pass is served when the pass reaches it, or on the next pass);
  the sensor read is followed by control (data ready), then logging. A task running at the sensor tick, a long
  read, or an interrupt delays the control step: the report's deadline misses.
- ``priority``: the report's proposed fix (6.1). Among flagged tasks the most important runs first (control,
  sensor read, logging, parse, heartbeat, barometer, telemetry); control runs first at the tick on the sample
  read in the previous period (a fixed one-period sample delay buys a control period without jitter); and a
  low-priority task starts only if its 99.9th-percentile duration fits before the next sensor tick (telemetry
  in the slack).

Sticks to motors. The report measured 23.4 ms from a stick to the motors; most of it was waiting: for the next
control step, which alone turns sticks into motor commands. Its own design (section 2) serves an immediate need
at once, and a new stick value is one: the motors follow it, nothing else has to happen first. So when the parse
task decodes sticks that differ from those the motor commands were last computed from (joystick plus trims,
``ModeMachine.sticks()``), it recomputes the motor commands then, with the flight core's control law on the
latest estimate (``FlightCore.control(..., dt=0)``), and writes them to the motors:

- only the set points change: no sensor read, no estimator or filter update, and no time step, so nothing that
  integrates over time moves (HEIGHT's integral and its stick-driven set point advance by ``dt`` = 0; the next
  control step integrates over its usual period, as without the recompute);
- only in the flight modes (MANUAL, YAW, FULL, RAW, HEIGHT): SAFE and CALIBRATION keep the motors off and PANIC
  keeps its own descent level (the fire button is PANIC before any recompute); mode changes, PANIC's ramp and the
  safety monitor stay with the control and heartbeat tasks;
- an unchanged joystick (the keep-alives, the same value resent) costs nothing beyond its decode;
- the cost is a draw from the control step's own Figure 14 duration (``control_dmp``/``control_raw``, an upper
  bound: it also pays for work the recompute skips), charged inside the parse run, so the parse row of the
  profile grows (``fcb-sim profile``: with the report's random sticks at 100 Hz, RAW parse 65 -> 171 µs mean, the
  CPU load 61.4 -> 62.9 %, round-robin misses 0.83 -> 0.90 %), and ``profile()["stick_reactions"]`` counts them;
- under the priority scheduler the recompute obeys the slack rule: it is done only if its 99.9th percentile
  ends before the next sensor tick; otherwise the control step at that tick, which runs first, does it.

``BoardConfig(stick_reaction=False)`` is the report's firmware. The motors take the command at the end of the
recompute (``motors_at_us``; the control step's at its start, the model's convention). What the motors do with
it (the ESC's next PWM pulse, up to 2.5 ms later) is the same for both paths and is not part of the figure.

The UART's receive side is timed too: bytes from the PC occupy the wire at 115200 baud, one burst after another
(a 15-byte Joystick frame is 1.30 ms), and a burst can be parsed once its last byte is in. A burst reaches the
UART at the present (the time ``advance`` was last asked for), even when the loop has already run a task past it:
the wire does not wait for the task. The burst is parsed in one run, where the firmware would take its bytes as
they come: the frame is complete at the same moment either way, only its decode (4 µs a byte) is counted after it.
``python -m bench.latency`` measures the whole path through a real pty.

``profile()`` gives per task the duration mean, sigma, p99, p99.9 and the period mean and sigma beside the
report's row, and the share of control periods (start to start) at least WCET99 = 2987 µs and WCET99.9 =
3738 µs (RAW; DMP the same multiples of 5000 µs). What the model gives, and what it does not explain (the
report's sensor read starts with more jitter than any task or interrupt it documents), is in bench/profile.py;
``BoardConfig.residual_jitter_us`` adds that missing start jitter as a diagnostic, never by default.

Sans-IO: ``uart_receive(data)`` (bytes arrive now), ``advance(until_us)``, ``uart_transmit() -> bytes`` (what
has left the UART at 115200 baud by now); ``next_event_us()`` tells a real-time driver when to call again.
BLE goes through ``board.wireless`` (a ``fcb_sim.wireless.WirelessLink``): every packet the board sends is
offered to it (``send``: heartbeats from STARTING, everything but the UART telemetry once STARTED, when the
UART falls silent and the parser reads BLE only). Without a radio, ``ble_connected()``, ``ble_disconnected()``
and ``ble_receive(data)`` drive the link; with ``wireless.BoardRadio`` (which drives the link itself) its
``on_data`` is ``board.ble_data`` and its ``on_disconnect`` is ``board.ble_lost`` (PANIC if the board was flown
over BLE). The same loop runs as fast as possible (tests, ``fcb-sim profile``) or paced to the wall clock
(fcb_sim/serve.py).

``SET_PARAM``: the parameters (ids, ranges, meanings) are the protocol's table, ``term.protocol.PARAMS``.
"""

from __future__ import annotations

import json
import math
import random
from collections import deque
from dataclasses import dataclass
from typing import Any

from fcb_sim import params as P
from fcb_sim.errors import UsageError
from fcb_sim.flash_log import FLASH_BYTES, FLASH_US_PER_BYTE, FlashLog, LogVar
from fcb_sim.flight import Calibration as FlightCalibration
from fcb_sim.flight import FlightCore
from fcb_sim.modes import FLIGHT_MODES, ModeChange, ModeConfig, ModeMachine
from fcb_sim.physics import World
from fcb_sim.timing import (
    APP_TIMER_EXTRA_US,
    APP_TIMER_ISR_US,
    COSTS,
    FIGURE14,
    Interference,
    rtc_ticks,
    rtc_us,
    us_to_ticks,
)
from fcb_sim.wireless import WirelessLink
from term.logformat import SCHEME_RICE
from term.protocol import (
    PARAMS,
    PROTOCOL_VERSION,
    SCHEDULERS,
    SENSOR_PATHS,
    Ack,
    Attitude,
    Button,
    Command,
    Compact,
    Decoder,
    Encoder,
    Event,
    EventCode,
    Flag,
    Gains,
    Heartbeat,
    HeartbeatAck,
    Height,
    Hello,
    Joystick,
    LogChunk,
    LogState,
    LogStatus,
    Mode,
    Motion,
    Nak,
    Op,
    Param,
    Profile,
    Role,
    Status,
    WirelessState,
    param_split,
)

TASKS = ("parse", "sensor", "control", "baro", "telemetry", "heartbeat", "logging")
ROUND_ROBIN_ORDER = ("parse", "baro", "telemetry", "heartbeat", "sensor", "control", "logging")
PRIORITY_ORDER = ("control", "sensor", "logging", "parse", "heartbeat", "baro", "telemetry")
CHAIN = frozenset({"control", "sensor", "logging"})  # never held back by the slack rule

SENSOR_PERIOD_US = {"raw": 2500, "dmp": 5000}  # report 4.2: RAW 400 Hz, DMP 200 Hz
# The report's deadline analysis (4.2): in RAW mode a control period at least the sum of the tasks' 99th
# (99.9th) percentile durations, 2987 (3738) µs, is a significant miss. Figure 13 plots the period normalised by
# the set point; DMP mode uses the same normalised thresholds (1.195 and 1.495 times 5000 µs).
WCET99_US = {"raw": 2987, "dmp": round(2987 / 2500 * 5000)}
WCET999_US = {"raw": 3738, "dmp": round(3738 / 2500 * 5000)}
REPORT_MISS_RATE = {"raw": 0.021, "dmp": None}  # Figure 13 shows DMP "far fewer", without a figure
REPORT_MISS_RATE_999 = {"raw": 0.0003, "dmp": None}
BARO_PERIOD_US = 50_000
HEARTBEAT_PERIOD_US = 100_000
UART_BAUD = 115_200
UART_US_PER_BYTE = 10_000_000 / UART_BAUD  # 8N1: ten bits per byte
RX_QUEUE_BYTES = 1024  # bounded: a flood is dropped and counted, it never stalls the loop
TX_BUFFER_BYTES = 1024  # telemetry that would not fit is skipped (commands' answers are always queued)
PARSE_MAX_BYTES = 64  # per parse run, so one run stays short
COMMAND_DEDUPE_US = 2_000_000  # a Command repeated (same id, op, arg) within this is a retry: answered, not redone
BOARD_VERSION = (0, 1)

# --- the cycle-cost model (fcb_sim/timing.py) ---------------------------------------------------------------

# Logging's measured 319 µs was the report's ~18-byte record at 15 µs a byte plus encoding; the model charges the
# encoding part from the fit and 15 µs for every byte actually programmed, so a smaller record costs less.
REPORT_RECORD_BYTES = 18
RICE_ENCODE_EXTRA_US = 40  # bit packing on a Cortex-M0 without a barrel-shift-friendly compiler [ASSUMED]
PARSE_US_BASE = 6  # our frames carry COBS and a CRC-16: a call costs a base plus per byte [ASSUMED]
PARSE_US_PER_BYTE = 4
DOWNLOAD_US_PER_CHUNK = 20  # flash read and frame encode per LogChunk [ASSUMED]


class TaskStats:
    """Per-task durations and periods: running mean and sigma (Welford) over everything, and the latest
    ``keep`` durations for the percentiles."""

    def __init__(self, keep: int = 50_000) -> None:
        self.n = 0
        self.mean = 0.0
        self.m2 = 0.0
        self.pn = 0
        self.pmean = 0.0
        self.pm2 = 0.0
        self.last_start: int | None = None
        self.durations: deque[int] = deque(maxlen=keep)
        self.misses = 0  # periods at least the WCET99 threshold (control only)
        self.misses999 = 0

    def add(self, start: int, dur: int) -> int | None:
        self.n += 1
        d = dur - self.mean
        self.mean += d / self.n
        self.m2 += d * (dur - self.mean)
        self.durations.append(dur)
        period = None
        if self.last_start is not None:
            period = start - self.last_start
            self.pn += 1
            d = period - self.pmean
            self.pmean += d / self.pn
            self.pm2 += d * (period - self.pmean)
        self.last_start = start
        return period

    def percentile(self, q: float) -> float:
        if not self.durations:
            return 0.0
        data = sorted(self.durations)
        return float(data[min(len(data) - 1, int(q * len(data)))])

    def summary(self) -> dict[str, float]:
        sd = math.sqrt(self.m2 / (self.n - 1)) if self.n > 1 else 0.0
        psd = math.sqrt(self.pm2 / (self.pn - 1)) if self.pn > 1 else 0.0
        return {"n": self.n, "mean_us": round(self.mean, 1), "sd_us": round(sd, 1),
                "period_us": round(self.pmean, 1), "period_sd_us": round(psd, 1),
                "p99_us": self.percentile(0.99), "p999_us": self.percentile(0.999), "misses": self.misses}


# --- the board ----------------------------------------------------------------------------------------------


@dataclass
class BoardConfig:
    seed: int = 1
    scheduler: str = "round-robin"  # or "priority"
    sensor_path: str = "auto"  # "auto": RAW path in RAW mode (and HEIGHT entered from RAW), DMP otherwise
    link_timeout_s: float = 0.5
    telemetry_hz: float = 50.0
    log_scheme: str = "rice"
    fixed_point: bool = False  # RAW filter in Q16.16 (and the fixed-point read cost)
    board_id: int = 1
    boot_hello: bool = True
    log_bytes: int = FLASH_BYTES  # the flash log's size (128 KB on the board)
    softdevice: bool = True  # the BLE stack advertises (and takes the CPU for it) whether a phone is there or not
    # A changed stick moves the motors in the parse task that decodes it, not at the next control step (module
    # docstring, "Sticks to motors"); False is the report's firmware, where only the control step does.
    stick_reaction: bool = True
    # A diagnostic, not part of the model: an extra exponential delay of this mean (µs) on every start out of an
    # idle wait, standing for interference the model does not know (bench/profile.py: "residual").
    residual_jitter_us: float = 0.0


CALIBRATED_VARS = ("gx", "gy", "gz", "ax", "ay", "az", "dmp_phi", "dmp_theta", "pressure")
DMP_ANGLE_LSB = P.ANGLE_LSB_PER_RAD  # DMP angles are summed as int16 angles of the lab's template


def _i16(v: float) -> int:
    v = int(round(v))
    return -32768 if v < -32768 else 32767 if v > 32767 else v


class Board:
    """The simulated flight-control board (module docstring)."""

    def __init__(self, config: BoardConfig | None = None, *, world: World | None = None,
                 core: FlightCore | None = None, wireless: WirelessLink | None = None,
                 log_vars: tuple[LogVar, ...] | None = None) -> None:
        self.config = cfg = config or BoardConfig()
        if cfg.scheduler not in ("round-robin", "priority"):
            raise ValueError(f"unknown scheduler {cfg.scheduler!r}")
        if cfg.sensor_path not in ("auto", "raw", "dmp"):
            raise ValueError(f"unknown sensor path {cfg.sensor_path!r}")
        self.world = world if world is not None else World(cfg.seed)
        self.core = core if core is not None else FlightCore(fixed_point=cfg.fixed_point)
        self.wireless = wireless if wireless is not None else WirelessLink()
        mc = ModeConfig(link_timeout_s=cfg.link_timeout_s, panic_level=self.core.panic_ae)
        self.modes = ModeMachine(mc, calibration_names=CALIBRATED_VARS)
        self.modes.listeners.append(self._on_mode_change)
        self.log = FlashLog(size=cfg.log_bytes, scheme=cfg.log_scheme,
                            **({} if log_vars is None else {"variables": log_vars}))
        self.rng = random.Random(cfg.seed ^ 0x5EED)
        self._cost = {name: c.sampler(self.rng) for name, c in COSTS.items()}
        self.now = 0  # µs since boot
        self._present = 0  # the outside world's present: the latest time ``advance`` was asked to reach
        self.encoder = Encoder()
        self.decoder = Decoder()
        self.ble_decoder = Decoder()
        self._rx = bytearray()  # the UART receive queue: bytes in, and bytes still on the wire at its end
        self._rx_wire: deque[tuple[float, int]] = deque()  # bursts still arriving: (last byte in, µs; bytes)
        self._rx_wire_bytes = 0  # bytes at the end of _rx that are still on the wire
        self._rx_wire_free = 0.0  # when the receive line is free (bursts arrive one after another)
        self._ble_rx = bytearray()
        self._tx = bytearray()  # the UART transmit buffer, drained at the baud rate
        self._tx_clock = 0.0  # board time up to which the wire has been busy
        self.rx_overflow = 0  # bytes dropped from a full receive queue
        self.rx_ignored = 0  # UART bytes while the parser reads BLE
        self.tx_dropped = 0  # telemetry frames skipped for a full transmit buffer
        self.last_frame_us: int | None = None  # the last valid frame from the PC (the link timer)
        self.rtt_us: int | None = None  # the last heartbeat round trip (Heartbeat → HeartbeatAck)
        self._hb_sent: tuple[int, int] | None = None  # (counter, time) of the last heartbeat sent
        self._hb_rtt_fresh = False  # whether rtt_us answers the last heartbeat (it is reported in the next)
        self.stats = {name: TaskStats() for name in TASKS}
        self.busy_us = 0
        self._profile_mark = (0, 0)  # (time, busy) when profiling (re)started
        self._busy_mark = (0, 0)  # (time, busy) at the last Status, for cpu_load
        self.cpu_load = 0
        self.misses_reported_at = -10**9
        # timers: name -> next tick (µs); flags set by the ticks
        self._flags = {name: False for name in TASKS}
        # Independent hardware timers started at different moments: their phases are unrelated (a common phase
        # would line every task up on the sensor tick and make each collision systematic).
        # App timers on the 32768 Hz RTC (fcb_sim/timing.py): next expiry in RTC ticks, and in board µs. Started at
        # different moments, their phases are unrelated; their periods are whole ticks, so they also drift past
        # one another (2.5 ms is 82 ticks, 20 ms 655).
        self._next_tk = {"sensor": 0, "baro": self.rng.randrange(1, rtc_ticks(BARO_PERIOD_US)),
                         "telemetry": self.rng.randrange(1, rtc_ticks(20_000)),
                         "heartbeat": self.rng.randrange(1, rtc_ticks(HEARTBEAT_PERIOD_US))}
        self._next = {name: rtc_us(tk) for name, tk in self._next_tk.items()}
        self.ticks_lost = {name: 0 for name in self._next}
        self.irq = Interference(random.Random(cfg.seed ^ 0x150), softdevice=cfg.softdevice)
        self._residual_rng = random.Random(cfg.seed ^ 0x7E5)
        self._timer_isr_end = 0  # when the app_timer interrupt of the last expiry is over
        self._idle = True  # the loop is waiting (no task ran since the last wait)
        self._rr = 0
        self._parse_limit = PARSE_MAX_BYTES
        self._path = self._want_path()
        self._sample_t = None  # time of the previous sensor read, for dt
        self._baro_t: int | None = None
        self._telemetry_n = 0
        self._due_at: dict[str, float] = {}
        self.heartbeats = 0
        self.battery = self.world.battery()
        self.pressure, self.temperature = self.world.baro()
        self.ae = (0, 0, 0, 0)
        self.motors_at_us = 0  # board time at which ``ae`` took effect
        self._sticks_used: tuple[int, int, int, int] | None = None  # what the motors were last computed from
        self.reactions = TaskStats()  # the recomputes at a stick change (their time is in the parse task's)
        self._last_cmd: tuple[int, int, int] | None = None
        self._last_ack: Ack | None = None
        self._last_cmd_us = 0
        self.download_next: int | None = None  # next chunk to send, or None
        self.download_sent = 0
        self._log_full_reported = False
        self._overflow_reported = 0
        self.on_task: Any = None  # optional callback(name, start_us, duration_us) after every task run
        if cfg.boot_hello:
            self._send(Hello(PROTOCOL_VERSION, Role.BOARD, BOARD_VERSION[0], BOARD_VERSION[1], cfg.board_id))
            self._event(EventCode.BOOT, PROTOCOL_VERSION)

    # --- the outside world's calls ------------------------------------------------------------------------

    def uart_receive(self, data: bytes) -> None:
        """Bytes from the PC, reaching the UART at the present: the time ``advance`` was last asked to reach
        (the loop may have run a task past it; the wire does not wait for the task). The UART interrupt queues
        them; a full queue drops and counts."""
        room = RX_QUEUE_BYTES - len(self._rx)
        if len(data) > room:
            self.rx_overflow += len(data) - max(room, 0)
            data = data[: max(room, 0)]
        if not data:
            return
        self._rx += data
        at = min(self.now, self._present)
        self.irq.rx(at, len(data))
        # The bytes take the wire at 115200 baud, after any still arriving: the burst can be parsed once its last
        # byte is in (a pty or a test hands it over at once; the board's UART does not).
        start = max(float(at), self._rx_wire_free)
        self._rx_wire_free = end = start + len(data) * UART_US_PER_BYTE
        self._rx_wire.append((end, len(data)))
        self._rx_wire_bytes += len(data)

    def uart_transmit(self) -> bytes:
        """What has left the UART by now: 115200 baud, 8N1."""
        if not self._tx:
            self._tx_clock = max(self._tx_clock, float(self.now))
            return b""
        start = max(self._tx_clock, 0.0)
        can = int((self.now - start) / UART_US_PER_BYTE)
        if can <= 0:
            return b""
        out = bytes(self._tx[:can])
        del self._tx[:can]
        self._tx_clock = start + len(out) * UART_US_PER_BYTE
        return out

    def ble_connected(self) -> None:
        self.wireless.connected()

    def ble_disconnected(self) -> None:
        """The phone went away: a board flown over BLE must PANIC."""
        self.ble_lost(self.wireless.disconnected())

    def ble_receive(self, data: bytes) -> None:
        """What the phone wrote (through the WirelessLink: ignored before the handover)."""
        self.ble_data(self.wireless.ble_receive(data))

    # The radio (fcb_sim.wireless.BoardRadio) drives the WirelessLink itself and calls these two:

    def ble_data(self, data: bytes) -> None:
        """Parser bytes from BLE that already went through ``wireless.ble_receive`` (the radio's ``on_data``)."""
        room = RX_QUEUE_BYTES - len(self._ble_rx)
        if len(data) > room:
            self.rx_overflow += len(data) - max(room, 0)
            data = data[: max(room, 0)]
        self._ble_rx += data
        self._wireless_events()

    def ble_lost(self, was_started: bool) -> None:
        """The radio lost its phone after calling ``wireless.disconnected()`` (the radio's ``on_disconnect``)."""
        self._ble_rx.clear()
        if was_started and self.modes.flying:
            self.modes.panic(self.now / 1e6, "ble")
        self._wireless_events()

    def next_tick_us(self) -> int:
        """The board time of the next timer interrupt, or of the last byte of a burst on the receive line."""
        t = min(self._next.values())
        if self._rx_wire:
            t = min(t, math.ceil(self._rx_wire[0][0]))
        return t

    def next_event_us(self) -> int:
        """When a real-time driver should next call ``advance``: now if a task is ready to run (the one that
        just ran ends at ``now``), else at the next timer interrupt or the end of a burst still arriving."""
        self._fire_timers()
        ready = (self._pick_priority() is not None if self.config.scheduler == "priority"
                 else any(self._flags.values()))
        self._parse_limit = PARSE_MAX_BYTES
        return self.now if ready else self.next_tick_us()

    @property
    def mode(self) -> Mode:
        return self.modes.mode

    @property
    def path(self) -> str:
        return self._path

    def set_scheduler(self, name: str) -> None:
        if name not in ("round-robin", "priority"):
            raise ValueError(f"unknown scheduler {name!r}")
        self.config.scheduler = name

    def reset_profile(self) -> None:
        self.stats = {name: TaskStats() for name in TASKS}
        self.reactions = TaskStats()
        self._profile_mark = (self.now, self.busy_us)

    # --- the main loop ------------------------------------------------------------------------------------

    def advance(self, until_us: int) -> None:
        """Run the loop until the board clock reaches ``until_us`` (a task running then finishes first)."""
        priority = self.config.scheduler == "priority"
        if until_us > self._present:
            self._present = until_us
        while self.now < until_us:
            self._fire_timers()
            task = self._pick_priority() if priority else self._pick_round_robin()
            if task is None:
                nxt = self.next_tick_us()
                self.now = min(max(nxt, self.now + 1), until_us) if self.now < nxt else self.now + 1
                self._idle = True
                continue
            if self._idle:
                # The loop was waiting: the flag is seen only once the interrupts in progress are over (those that
                # hit a running task are in its measured duration already).
                self._idle = False
                free = self.irq.free_at(self.now, self._timer_isr_end, self._tx_clock, len(self._tx), self.ae)
                if self.config.residual_jitter_us > 0:
                    free += int(self._residual_rng.expovariate(1.0 / self.config.residual_jitter_us))
                if free > self.now:
                    self.now = free
                    continue
            start = self.now
            self._flags[task] = False
            dur = getattr(self, "_task_" + task)()
            dur = max(1, int(dur))
            self.now = start + dur
            self.busy_us += dur
            period = self.stats[task].add(start, dur)
            if task == "control" and period is not None:
                self._check_deadline(period)
            if self.on_task is not None:
                self.on_task(task, start, dur)

    def _fire_timers(self) -> None:
        now = self.now
        nxt = self._next
        at: dict[int, int] = {}  # expiry time -> timers expiring then (one app_timer interrupt serves them all)
        for name, t in nxt.items():
            if now >= t:
                period = rtc_ticks(self._period(name))
                if self._flags[name]:
                    self.ticks_lost[name] += 1
                self._flags[name] = True
                if name == "sensor" and self.config.scheduler == "priority":
                    self._flags["control"] = True  # control first, on the previous sample
                tk = self._next_tk[name]
                missed = (us_to_ticks(now) - tk) // period
                self.ticks_lost[name] += missed
                self._next_tk[name] = tk = tk + (missed + 1) * period
                nxt[name] = rtc_us(tk)
                at[t] = at.get(t, 0) + 1
        for t, n in at.items():
            self._timer_isr_end = max(self._timer_isr_end, t + APP_TIMER_ISR_US + APP_TIMER_EXTRA_US * (n - 1))
        if self._ble_rx or self._rx_arrived():
            self._flags["parse"] = True

    def _rx_arrived(self) -> int:
        """How many bytes of the UART receive queue are in by now (the rest is still on the wire)."""
        wire = self._rx_wire
        while wire and wire[0][0] <= self.now:
            self._rx_wire_bytes -= wire.popleft()[1]
        return len(self._rx) - self._rx_wire_bytes

    def _period(self, name: str) -> int:
        if name == "sensor":
            return SENSOR_PERIOD_US[self._path]
        if name == "baro":
            return BARO_PERIOD_US
        if name == "heartbeat":
            return HEARTBEAT_PERIOD_US
        return max(10_000, int(1e6 / max(0.2, self.config.telemetry_hz)))

    def _pick_round_robin(self) -> str | None:
        order = ROUND_ROBIN_ORDER
        n = len(order)
        for i in range(n):
            name = order[(self._rr + i) % n]
            if self._flags[name]:
                self._rr = (self._rr + i + 1) % n
                return name
        return None

    def _pick_priority(self) -> str | None:
        next_tick = self._next["sensor"]
        for name in PRIORITY_ORDER:
            if not self._flags[name]:
                continue
            if name in CHAIN:
                return name
            if name == "parse":
                # parse only as many bytes as fit before the tick (the rest waits for the next slack)
                room = (next_tick - self.now - PARSE_US_BASE) // PARSE_US_PER_BYTE
                if room >= 1:
                    self._parse_limit = int(min(PARSE_MAX_BYTES, room))
                    return name
                continue
            if self.now + self._budget(name) <= next_tick:
                return name
        return None

    def _budget(self, name: str) -> int:
        """The slack rule's estimate of a task's duration: its 99.9th percentile."""
        if name == "telemetry" and self.download_next is not None:
            return int(COSTS["telemetry"].figure[3])
        return int(COSTS[name].figure[3])

    def _check_deadline(self, period: int) -> None:
        st = self.stats["control"]
        if period >= WCET99_US[self._path]:
            st.misses += 1
            if self.now - self.misses_reported_at >= 10_000_000 and self.modes.flying:
                self.misses_reported_at = self.now
                self._event(EventCode.DEADLINE_MISS, period)
        if period >= WCET999_US[self._path]:
            st.misses999 += 1

    # --- tasks: each returns its duration in µs -----------------------------------------------------------

    def _task_parse(self) -> int:
        link = self.wireless
        if link.reads_uart:
            queue, decoder = self._rx, self.decoder
            limit = min(self._parse_limit, self._rx_arrived())
        else:
            queue, decoder = self._ble_rx, self.ble_decoder
            limit = self._parse_limit
            if self._rx:
                self.rx_ignored += len(self._rx)
                self._rx.clear()
                self._rx_wire.clear()
                self._rx_wire_bytes = 0
        chunk = bytes(queue[:limit])
        self._parse_limit = PARSE_MAX_BYTES
        del queue[: len(chunk)]
        if self.rx_overflow > self._overflow_reported:
            self._event(EventCode.OVERFLOW, self.rx_overflow - self._overflow_reported)
            self._overflow_reported = self.rx_overflow
        cost = PARSE_US_BASE + PARSE_US_PER_BYTE * len(chunk)
        for pkt in decoder.feed(chunk):
            self.last_frame_us = self.now
            self._handle(pkt)
        if self.config.stick_reaction and self._sticks_used is not None and self.modes.sticks() != self._sticks_used:
            cost += self._react(self.now + cost)
        return cost

    def _react(self, at: int) -> int:
        """The sticks changed (the parse task decoded them by board time ``at``): recompute the motor commands
        now from the latest estimate, as the control step would, but without a time step (module docstring,
        "Sticks to motors"). Returns the cost (µs), 0 when it is not done."""
        m, fc = self.modes, self.core
        mode = m.mode
        if mode not in FLIGHT_MODES or int(mode) != fc.mode:
            return 0  # motors off (SAFE, CALIBRATION) or forced (PANIC), or a mode the core has not entered
        path = self._path
        if self.config.scheduler == "priority" and at + COSTS[f"control_{path}"].figure[3] > self._next["sensor"]:
            return 0  # the slack rule: it might not end before the tick; the control step at the tick does it
        cost = self._cost[f"control_{path}"]()
        sticks = m.sticks()
        self._set_motors(fc.control(int(mode), *sticks, 0.0), at + cost)
        self._sticks_used = sticks
        self.reactions.add(at, cost)
        return cost

    def _set_motors(self, ae: tuple[int, int, int, int], at: int) -> None:
        """The motor commands take effect at board time ``at``."""
        self.ae = ae
        self.motors_at_us = at
        self.modes.motor_level = sum(ae) // 4
        self.world.advance_to(at / 1e6)
        self.world.set_motors(*ae)

    def _want_path(self) -> str:
        if self.config.sensor_path != "auto":
            return self.config.sensor_path
        m = self.modes.mode
        if m == Mode.RAW or (m == Mode.HEIGHT and self.modes.height_base == Mode.RAW):
            return "raw"
        return "dmp"

    def _task_sensor(self) -> int:
        t = self.now / 1e6
        w = self.world
        w.advance_to(t)
        gx, gy, gz, ax, ay, az = w.imu()
        dt = SENSOR_PERIOD_US[self._path] / 1e6 if self._sample_t is None else t - self._sample_t
        self._sample_t = t
        fc = self.core
        fc.imu_sample(gx, gy, gz, ax, ay, az, dt)
        cal = self.modes.mode == Mode.CALIBRATION
        sample = {"gx": gx, "gy": gy, "gz": gz, "ax": ax, "ay": ay, "az": az} if cal else None
        if self._path == "dmp":
            q = w.dmp()
            if q is not None:
                fc.dmp_sample(*q)
                if cal:
                    sample["dmp_phi"] = round(fc.dmp_phi * DMP_ANGLE_LSB)
                    sample["dmp_theta"] = round(fc.dmp_theta * DMP_ANGLE_LSB)
            cost = self._cost["sensor_dmp"]()
        else:
            cost = self._cost["sensor_raw_fixed" if self.config.fixed_point else "sensor_raw"]()
        if sample is not None:
            self.modes.calibration_sample(sample)
        if self.config.scheduler == "round-robin":
            self._flags["control"] = True  # data ready: control follows
        return cost

    def _task_control(self) -> int:
        m = self.modes
        now_s = self.now / 1e6
        m.tick(now_s)
        mode = m.mode
        fc = self.core
        dt = SENSOR_PERIOD_US[self._path] / 1e6
        if mode == Mode.PANIC:
            fc.panic_scale = m.panic_motor_level(now_s) / max(1, fc.panic_ae)
        sticks = m.sticks()
        ae = fc.control(int(mode), *sticks, dt)
        if not m.motors_enabled:
            ae = (0, 0, 0, 0)
        self._sticks_used = sticks
        self._set_motors(ae, self.now)
        if self.log.recording:
            self._flags["logging"] = True
        want = self._want_path()
        if want != self._path:
            self._path = want
            self._next_tk["sensor"] = tk = us_to_ticks(self.now) + rtc_ticks(SENSOR_PERIOD_US[want])
            self._next["sensor"] = rtc_us(tk)
            self._sample_t = None
        flying = mode in FLIGHT_MODES
        path = self._path
        return self._cost[f"control_{path}" if flying or mode == Mode.PANIC else f"control_{path}_safe"]()

    def _task_logging(self) -> int:
        fc = self.core
        phi, theta, psi = fc.attitude_centideg()
        row = (self.now, int(self.modes.mode), phi, theta, psi, round(fc.sp), round(fc.sq), round(fc.sr),
               round(fc.sax), round(fc.say), round(fc.saz), *self.ae, round(fc.height * 1000),
               self.pressure, self.battery)
        written = self.log.append(row)
        if self.log.state == LogState.FULL and not self._log_full_reported:
            self._log_full_reported = True
            self._event(EventCode.LOG_FULL, self.log.used)
        base = self._cost["logging"]() - FLASH_US_PER_BYTE * REPORT_RECORD_BYTES
        if self.log.scheme == SCHEME_RICE:
            base += RICE_ENCODE_EXTRA_US
        return max(5, base) + FLASH_US_PER_BYTE * written

    def _task_baro(self) -> int:
        t = self.now / 1e6
        self.world.advance_to(t)
        self.pressure, self.temperature = self.world.baro()
        self.battery = self.world.battery()
        dt = 0.05 if self._baro_t is None else (self.now - self._baro_t) / 1e6
        self._baro_t = self.now
        self.core.baro_sample(self.pressure, dt)
        self.modes.battery = self.battery
        if self.modes.mode == Mode.CALIBRATION:
            self.modes.calibration_sample({"pressure": self.pressure})
        return self._cost["baro"]()

    def _task_heartbeat(self) -> int:
        self.heartbeats += 1
        # The previous heartbeat's round trip rides on this one (0.1 ms units; 0 when its ACK did not come back).
        rtt = min(0xFFFF, max(1, (self.rtt_us or 0) // 100)) if self._hb_rtt_fresh else 0
        counter = self.heartbeats & 0xFFFF
        self._send(Heartbeat(counter, (self.now // 1000) & 0xFFFFFFFF, rtt))
        self._hb_sent, self._hb_rtt_fresh = (counter, self.now), False
        silent = (self.now - self.last_frame_us) / 1e6 if self.last_frame_us is not None else 0.0
        phi, theta, _ = self.core.attitude_centideg()
        self.modes.supervise(self.now / 1e6, link_silent_s=silent, battery=self.battery,
                             phi_cdeg=phi, theta_cdeg=theta)
        self._drain_mode_events()
        return self._cost["heartbeat"]()

    def _task_telemetry(self) -> int:
        self._telemetry_n += 1
        self._drain_mode_events()
        if self.download_next is not None:
            return self._download_step()
        fc = self.core
        if self.wireless.state is WirelessState.STARTED:
            if self.wireless.compact_due():  # as many as fill the notifications between two heartbeats
                phi, theta, psi = fc.attitude_centideg()
                self._send(Compact(int(self.modes.mode), int(self.wireless.state), phi, theta, psi,
                                   self.battery))
            return self._cost["telemetry"]()
        phi, theta, psi = fc.attitude_centideg()
        self._telemetry(Attitude(int(self.modes.mode), _i16(phi), _i16(theta), _i16(psi),
                                 _i16(fc.sp), _i16(fc.sq), _i16(fc.sr)))
        self._telemetry(Motion(_i16(fc.sax), _i16(fc.say), _i16(fc.saz), *self.ae))
        if self._due("height", 50_000):
            self._telemetry(Height(self.pressure, _i16(fc.height * 1000), _i16(fc.setpoint * 1000),
                                   _i16(fc.vz * 1000), self.battery, _i16(self.temperature)))
        if self._due("status", 200_000):
            self._telemetry(self.status())
            g = fc.gains
            self._telemetry(Gains(g.yaw_p, g.p1, g.p2, g.height_p, g.height_d))
        return self._cost["telemetry"]()

    # --- telemetry and packets ----------------------------------------------------------------------------

    def _due(self, name: str, period_us: float) -> bool:
        """Whether a packet sent at its own rate (slower than the telemetry task) is due now."""
        due = self._due_at.get(name, 0.0)
        if self.now < due:
            return False
        self._due_at[name] = max(due + period_us, self.now - period_us / 2)
        return True

    def status(self) -> Status:
        m = self.modes
        flags = Flag(0)
        if m.calibrated:
            flags |= Flag.CALIBRATED
        if m.motors_enabled:
            flags |= Flag.ARMED
        if self.log.recording:
            flags |= Flag.LOGGING
        if self.wireless.is_connected:
            flags |= Flag.BLE_CONNECTED
        if self.wireless.state is WirelessState.STARTED:
            flags |= Flag.WIRELESS_ACTIVE
        if self.battery < m.config.low_battery or m.battery_low_latched:
            flags |= Flag.LOW_BATTERY
        if m.link_timed_out:
            flags |= Flag.LINK_TIMEOUT
        if self._path == "raw":
            flags |= Flag.RAW_SENSORS
        if self.config.fixed_point:
            flags |= Flag.FIXED_POINT
        if self.config.scheduler == "priority":
            flags |= Flag.PRIORITY_SCHEDULER
        if m.mode == Mode.HEIGHT:
            flags |= Flag.HEIGHT_HOLD
        t0, b0 = self._busy_mark
        if self.now > t0:
            self.cpu_load = min(100, round(100 * (self.busy_us - b0) / (self.now - t0)))
        self._busy_mark = (self.now, self.busy_us)
        t = m.trims
        return Status(int(flags), t.roll, t.pitch, t.yaw, t.lift, self.cpu_load, self.log.fill_pct,
                      int(self.wireless.state))

    def _telemetry(self, pkt: Any) -> None:
        """Telemetry is skipped, not queued behind itself, when the UART cannot keep up."""
        if len(self._tx) > TX_BUFFER_BYTES - 20:
            self.tx_dropped += 1
            return
        self._send(pkt)

    def _send(self, pkt: Any) -> None:
        link = self.wireless
        link.send(pkt)
        if link.writes_uart:
            if not self._tx:
                self._tx_clock = max(self._tx_clock, float(self.now))
            self._tx += self.encoder.encode(pkt)

    def _event(self, code: EventCode, arg: int) -> None:
        self._send(Event(int(code), int(arg), (self.now // 1000) & 0xFFFFFFFF))

    def _drain_mode_events(self) -> None:
        for code, arg, _t in self.modes.drain_events():
            self._event(code, arg)

    def _wireless_events(self) -> None:
        for _old, new in self.wireless.take_transitions():
            self._event(EventCode.WIRELESS_STATE, int(new))

    def _on_mode_change(self, change: ModeChange) -> None:
        if change.old == Mode.CALIBRATION and self.modes.calibrated:
            self._apply_calibration()
        if change.new != Mode.SAFE and self.download_next is not None:
            self._end_download()
        self.core.enter_mode(int(change.new), self.modes.lift)

    def _apply_calibration(self) -> None:
        o = self.modes.offsets
        c = self.modes.calibration
        self.core.set_calibration(FlightCalibration(
            gyro=(o["gx"], o["gy"], o["gz"]),
            accel=(o["ax"], o["ay"], o["az"]),
            dmp_phi=o["dmp_phi"] / DMP_ANGLE_LSB if c.counts["dmp_phi"] else 0.0,
            dmp_theta=o["dmp_theta"] / DMP_ANGLE_LSB if c.counts["dmp_theta"] else 0.0,
            pressure=float(o["pressure"]) if c.counts["pressure"] else float(self.pressure),
        ))

    # --- packets from the PC ------------------------------------------------------------------------------

    def _handle(self, pkt: Any) -> None:
        kind = type(pkt)
        if kind is Joystick:
            self.modes.joystick = pkt
            if pkt.buttons & Button.FIRE:
                self.modes.panic(self.now / 1e6, "fire")
                self._drain_mode_events()
        elif kind is Command:
            self._command(pkt)
        elif kind is HeartbeatAck:
            if self._hb_sent is not None and pkt.counter == self._hb_sent[0]:
                self.rtt_us, self._hb_rtt_fresh = self.now - self._hb_sent[1], True
        elif kind is Hello:
            # A terminal (re)connected: its cmd_ids and sequence numbers start afresh, so a first command equal to
            # the last one seen is not a retry, and its sequence jump is not loss.
            self._last_cmd = self._last_ack = None
            self.decoder.reset_sequence()
            self.ble_decoder.reset_sequence()
            self._send(Hello(PROTOCOL_VERSION, Role.BOARD, BOARD_VERSION[0], BOARD_VERSION[1], self.config.board_id))

    def _command(self, cmd: Command) -> None:
        key = (cmd.cmd_id, cmd.op, cmd.arg)
        if key == self._last_cmd and self.now - self._last_cmd_us < COMMAND_DEDUPE_US and self._last_ack:
            self._send(self._last_ack)  # a retry: the first answer was lost; do not do it twice
            return
        after = None
        try:
            status, value, after = self._execute(cmd)
        except Exception:  # a bug must not take the board down: refuse, and keep flying
            status, value = Nak.BAD_ARGUMENT, 0
        ack = Ack(cmd.cmd_id, cmd.op, int(status), int(value))
        self._last_cmd, self._last_ack, self._last_cmd_us = key, ack, self.now
        self._send(ack)
        self._drain_mode_events()
        if after is not None:
            after()

    def _execute(self, cmd: Command) -> tuple[Nak, int, Any]:
        op, arg = cmd.op, cmd.arg
        m = self.modes
        now_s = self.now / 1e6
        if op == Op.MODE:
            if arg == Mode.WIRELESS:
                return self._wireless_start()
            m.tick(now_s)
            reason = m.request(arg, now_s)
            return reason, int(m.mode), None
        if op in _TRIMS:
            return Nak.OK, m.adjust_trim(_TRIMS[op], arg), None
        if op in _GAINS:
            return Nak.OK, round(self.core.adjust_gain(_GAINS[op], arg) * 1000), None
        if op == Op.LOG_START:
            if self.download_next is not None:
                return Nak.LOG_BUSY, 0, None
            reason, _ = self.log.start()
            if reason == Nak.OK:
                self._log_full_reported = False
            return reason, self.log.used, None
        if op == Op.LOG_STOP:
            reason, _ = self.log.stop()
            return reason, self.log.used, None
        if op == Op.LOG_RESET:
            if self.download_next is not None:
                return Nak.LOG_BUSY, 0, None
            return self.log.reset(m.mode == Mode.SAFE), 0, None
        if op == Op.LOG_STATUS:
            return Nak.OK, self.log.used, self._send_log_status
        if op == Op.LOG_DOWNLOAD:
            return self._download_start(arg)
        if op == Op.PROFILE:
            return Nak.OK, len(TASKS), self._send_profile
        if op == Op.WIRELESS:
            if arg == 1:
                return self._wireless_start()
            if arg == 0:
                return Nak.OK, 0, self._wireless_stop
            return Nak.BAD_ARGUMENT, 0, None
        if op == Op.SET_PARAM:
            return self._set_param(*param_split(arg))
        return Nak.UNKNOWN_COMMAND, 0, None

    def _wireless_start(self) -> tuple[Nak, int, Any]:
        if self.modes.mode != Mode.SAFE:
            return Nak.NOT_IN_SAFE, int(self.wireless.state), None
        reason = self.wireless.request_start()
        self._wireless_events()
        return reason, int(self.wireless.state), None

    def _wireless_stop(self) -> None:
        self.wireless.request_stop()
        self._wireless_events()

    def _set_param(self, pid: int, value: int) -> tuple[Nak, int, Any]:
        """``SET_PARAM``: ids, ranges and meanings in ``term.protocol.PARAMS``."""
        try:
            spec = PARAMS[Param(pid)]
        except ValueError:
            return Nak.BAD_ARGUMENT, 0, None
        if not spec.accepts(value):
            return Nak.BAD_ARGUMENT, 0, None
        if spec.safe_only and self.modes.mode != Mode.SAFE:
            return Nak.NOT_IN_SAFE, 0, None
        if spec.param == Param.LINK_TIMEOUT_MS:
            self.config.link_timeout_s = value / 1000
            self.modes.config.link_timeout_s = value / 1000
        elif spec.param == Param.SCHEDULER:
            self.set_scheduler(SCHEDULERS[value])
        elif spec.param == Param.TELEMETRY_HZ:
            self.config.telemetry_hz = float(value)
        elif spec.param == Param.SENSOR_PATH:
            self.config.sensor_path = SENSOR_PATHS[value]
        elif spec.param == Param.LOG_SCHEME:
            if self.log.used:
                return Nak.LOG_BUSY, 0, None
            self.log = FlashLog(size=self.log.flash.size, scheme=value, variables=self.log.variables)
        return Nak.OK, value, None

    # --- log download -------------------------------------------------------------------------------------

    def _log_status(self) -> LogStatus:
        return LogStatus(int(self.log.state), self.log.used, self.log.records, self.log.crc32())

    def _send_log_status(self) -> None:
        self._send(self._log_status())

    def _download_start(self, first: int) -> tuple[Nak, int, Any]:
        if self.modes.mode != Mode.SAFE:
            return Nak.NOT_IN_SAFE, 0, None
        if self.log.recording:
            return Nak.LOG_BUSY, 0, None
        if self.log.used == 0:
            return Nak.LOG_EMPTY, 0, None
        if not 0 <= first < self.log.n_chunks:
            return Nak.BAD_ARGUMENT, self.log.n_chunks, None

        def begin() -> None:
            self.download_next = first
            self.download_sent = 0
            self._send(LogStatus(int(LogState.DOWNLOADING), self.log.used, self.log.records, self.log.crc32()))

        return Nak.OK, self.log.n_chunks, begin

    def _download_step(self) -> int:
        """Fill the transmit buffer with chunks (the wire paces the download); status packets in between."""
        cost = 0
        n = self.log.n_chunks
        while self.download_next is not None and len(self._tx) < TX_BUFFER_BYTES - 20:
            i = self.download_next
            self._send(LogChunk(i, self.log.chunk(i)))
            self.download_sent += 1
            cost += DOWNLOAD_US_PER_CHUNK
            self.download_next = i + 1 if i + 1 < n else None
            if self.download_next is None:
                self._end_download()
        if self._telemetry_n % 10 == 0:
            self._send(self.status())
        return max(cost, 20)

    def _end_download(self) -> None:
        self.download_next = None
        self._send(self._log_status())
        self._event(EventCode.LOG_DONE, self.download_sent)

    def _send_profile(self) -> None:
        for pkt in self.profile_packets():
            self._send(pkt)

    def profile_packets(self) -> list[Profile]:
        out = []
        for i, name in enumerate(TASKS):
            s = self.stats[name].summary()
            out.append(Profile(i, min(65535, round(s["mean_us"])), min(65535, round(s["p99_us"])),
                               min(65535, round(s["p999_us"])), min(2**32 - 1, round(s["period_us"])),
                               min(65535, s["misses"])))
        return out

    def profile(self) -> dict[str, Any]:
        """The board's own profile: per task figures beside the report's (Figure 14), and the control deadline
        misses (periods between control starts at least WCET99, and WCET99.9)."""
        ctl = self.stats["control"]
        periods = max(1, ctl.pn)
        return {
            "path": self._path,
            "scheduler": self.config.scheduler,
            "control_hz": round(1e6 / SENSOR_PERIOD_US[self._path]),
            "deadline_us": WCET99_US[self._path],
            "deadline_999_us": WCET999_US[self._path],
            "deadline_miss_rate": ctl.misses / periods,
            "deadline_miss_rate_999": ctl.misses999 / periods,
            "control_periods": ctl.pn,
            "report_deadline_miss_rate": REPORT_MISS_RATE[self._path],
            "report_deadline_miss_rate_999": REPORT_MISS_RATE_999[self._path],
            "tasks": {name: self.stats[name].summary() for name in TASKS},
            # the motor recomputes at a stick change, done inside parse runs (their time is in parse's too)
            "stick_reactions": self.reactions.summary(),
            "report": report_figures(self._path, self.config.fixed_point),
            "ticks_lost": dict(self.ticks_lost),
            "idle_starts_delayed_by_interrupts": self.irq.delays,
            "interrupt_delay_us_mean": round(self.irq.delay_us / max(1, self.irq.delays), 1),
            "cpu_load_pct": round(100 * (self.busy_us - self._profile_mark[1])
                                  / max(1, self.now - self._profile_mark[0]), 1),
        }


def report_rows(path: str, fixed_point: bool = False) -> dict[str, str]:
    """The Figure 14 row each task is compared with (FULL rows; the logging row was measured in DMP mode)."""
    sensor = "sensor_dmp" if path == "dmp" else "sensor_raw_fixed" if fixed_point else "sensor_raw"
    return {"parse": "parse", "sensor": sensor, "control": f"control_{path}", "baro": "baro",
            "telemetry": "telemetry", "heartbeat": "heartbeat", "logging": "logging"}


def report_figures(path: str, fixed_point: bool = False) -> dict[str, dict[str, Any]]:
    out = {}
    for task, row in report_rows(path, fixed_point).items():
        mean, sd, p99, p999, period, period_sd, n = FIGURE14[row]
        out[task] = {"row": row, "n": n, "mean_us": mean, "sd_us": sd, "p99_us": p99, "p999_us": p999,
                     "period_us": period, "period_sd_us": period_sd}
    return out


_TRIMS = {Op.TRIM_LIFT: "lift", Op.TRIM_ROLL: "roll", Op.TRIM_PITCH: "pitch", Op.TRIM_YAW: "yaw"}
_GAINS = {Op.GAIN_YAW_P: "yaw_p", Op.GAIN_P1: "p1", Op.GAIN_P2: "p2", Op.GAIN_HEIGHT_P: "height_p",
          Op.GAIN_HEIGHT_D: "height_d"}


# --- a scripted pilot over the bytes, for the profile -------------------------------------------------------


class BytePilot:
    """The least PC that flies the board through its UART: joystick at 100 Hz, heartbeat answers, commands.
    Used by ``fcb-sim profile`` (the report profiled with a PC sending random sticks) and by tests."""

    def __init__(self, board: Board, seed: int = 1) -> None:
        self.board = board
        self.encoder = Encoder()
        self.decoder = Decoder()
        self.rng = random.Random(seed)
        self.received: list[Any] = []
        self.acks: dict[int, Ack] = {}
        self.cmd_id = 0
        self.sticks = Joystick(0, 0, 0, 0, 0)
        self.random_sticks = False

    def command(self, op: Op, arg: int = 0) -> int:
        self.cmd_id = (self.cmd_id + 1) & 0xFF
        self.board.uart_receive(self.encoder.encode(Command(self.cmd_id, int(op), arg)))
        return self.cmd_id

    def run(self, seconds: float, joystick_hz: float = 100.0) -> None:
        b = self.board
        step = int(1e6 / joystick_hz)
        end = b.now + int(seconds * 1e6)
        while b.now < end:
            # the PC's clock is not the board's: its frames arrive at an unrelated phase, with some jitter
            b.advance(b.now + self.rng.randrange(0, step // 2))
            if self.random_sticks:
                r = self.rng.randint
                self.sticks = Joystick(r(-32767, 32767), r(-32767, 32767), r(-32767, 32767), r(0, 32767), 0)
            b.uart_receive(self.encoder.encode(self.sticks))
            b.advance(b.now + step // 2)
            self._read()

    def _read(self) -> None:
        for pkt in self.decoder.feed(self.board.uart_transmit()):
            self.received.append(pkt)
            if type(pkt) is Heartbeat:
                self.board.uart_receive(self.encoder.encode(HeartbeatAck(pkt.counter, pkt.board_ms)))
            elif type(pkt) is Ack:
                self.acks[pkt.cmd_id] = pkt
        if len(self.received) > 5000:
            del self.received[:2500]


def run_profile(path: str = "raw", scheduler: str = "round-robin", seconds: float = 30.0, seed: int = 1,
                logging: bool = True, log_scheme: str = "delta8", telemetry_hz: float = 50.0,
                softdevice: bool = True, residual_jitter_us: float = 0.0,
                stick_reaction: bool = True) -> dict[str, Any]:
    """Profile as the report did (4.2): calibrate, enter FULL (DMP path) or RAW, random sticks from the PC,
    logging on; the props are off (motors held at zero in the world, so random sticks cannot crash it)."""
    world = World(seed)
    for i in range(1, 5):
        world.stick_motor(i, 0)  # on the bench without propellers, as a profiling run is done
    # Logging stays on for the whole run (the report logged its profile): a flash large enough to hold it, the
    # same 15 µs per byte.
    log_bytes = max(FLASH_BYTES, int(seconds * 400 * 40) + 4096)
    board = Board(BoardConfig(seed=seed, scheduler=scheduler, sensor_path=path, log_scheme=log_scheme,
                              log_bytes=log_bytes, telemetry_hz=telemetry_hz, softdevice=softdevice,
                              residual_jitter_us=residual_jitter_us, stick_reaction=stick_reaction), world=world)
    board.modes.config.tilt_limit_cdeg = 18000
    pilot = BytePilot(board, seed)
    pilot.command(Op.MODE, Mode.CALIBRATION)
    pilot.run(1.3)
    pilot.command(Op.MODE, Mode.RAW if path == "raw" else Mode.FULL)
    pilot.run(0.2)
    if board.mode not in FLIGHT_MODES:
        raise RuntimeError(f"profile: the board did not arm (mode {board.mode.name})")
    if logging:
        pilot.command(Op.LOG_START)
        pilot.run(0.1)
    board.reset_profile()
    pilot.random_sticks = True
    pilot.run(seconds)
    out = board.profile()
    out.update(seconds=seconds, seed=seed, mode=board.mode.name, log_bytes=board.log.used, log_scheme=log_scheme,
               telemetry_hz=telemetry_hz, softdevice=softdevice, residual_jitter_us=residual_jitter_us,
               stick_reaction=stick_reaction)
    return out


def _pct(x: float | None) -> str:
    return "-" if x is None else f"{100 * x:.2f} %"


def cmd_profile(args: Any) -> int:
    """``fcb-sim profile --mode raw|dmp --scheduler round-robin|priority [--seconds S] [--seed N] [--json]``."""
    if not (math.isfinite(args.seconds) and 1.0 <= args.seconds <= 3600.0):
        raise UsageError(f"--seconds must be between 1 and 3600, got {args.seconds:g}")
    out = run_profile(args.mode, args.scheduler, args.seconds, args.seed,
                      log_scheme=getattr(args, "log_scheme", "delta8"))
    print(f"profile: {args.mode.upper()} path at {out['control_hz']} Hz, {args.scheduler}, "
          f"{args.seconds:g} s simulated, logging on ({out['log_scheme']}); (report, Figure 14) beside")
    print(f"{'task':10s} {'n':>7s} {'mean':>12s} {'sd':>10s} {'p99':>12s} {'p99.9':>12s} "
          f"{'period':>16s} {'period sd':>14s}  (µs)")
    for name, s in out["tasks"].items():
        r = out["report"][name]
        rsd = "?" if r["period_sd_us"] is None else f"{r['period_sd_us']:.0f}"
        print(f"{name:10s} {s['n']:7d} {s['mean_us']:5.0f} ({r['mean_us']:4.0f}) {s['sd_us']:4.0f} ({r['sd_us']:3.0f})"
              f" {s['p99_us']:5.0f} ({r['p99_us']:4.0f}) {s['p999_us']:5.0f} ({r['p999_us']:4.0f})"
              f" {s['period_us']:7.0f} ({r['period_us']:6.0f}) {s['period_sd_us']:6.0f} ({rsd:>5s})")
    print(f"control periods >= {out['deadline_us']} µs (WCET99): {_pct(out['deadline_miss_rate'])}"
          f" (report, round robin: {_pct(out['report_deadline_miss_rate'])}); >= {out['deadline_999_us']} µs"
          f" (WCET99.9): {_pct(out['deadline_miss_rate_999'])} (report: {_pct(out['report_deadline_miss_rate_999'])})")
    r = out["stick_reactions"]
    print(f"stick changes: {r['n']} motor recomputes in the parse task, {r['mean_us']:.0f} µs mean,"
          f" p99 {r['p99_us']:.0f}"
          " (in parse's durations above; the report's firmware waited for the control step)")
    if args.json:
        print(json.dumps(out))
    return 0
