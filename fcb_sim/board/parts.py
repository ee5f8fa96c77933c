"""What the board's handlers act on: its start-up settings (``BoardConfig``) and its parts (``BoardParts``).

The command handlers (fcb_sim/board/commands.py), the parameter bindings (fcb_sim/board/param_bindings.py) and the
telemetry builders (fcb_sim/board/telemetry.py) get a ``BoardParts``, never the whole ``Board``: the mode machine, the
flight core, the flash log and its download, the transmit side, the BLE link, the profiler, the scheduler and the UART,
the board's clock, and an event emitter. The Board builds one and owns it; it is the only place a part is replaced
(a new log scheme builds a new ``FlashLog``), so the Board reads its log from here.

This module imports no board module but the flash log's size at run time (the parts' types only for the
checker), so nothing circles back to fcb_sim/board/board.py.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

from fcb_sim.board.flash_log import FLASH_BYTES
from fcb_sim.board.scheduler import HEARTBEAT_PERIOD_US
from term.core.protocol import (
    PARAMS,
    PRESETS,
    QUEUE_DISCARD_FRAMES,
    QUEUE_RULES,
    SCHEDULERS,
    SENSOR_PATHS,
    Event,
    EventCode,
    Param,
)

if TYPE_CHECKING:
    from fcb_sim.board.console import BoardConsole
    from fcb_sim.board.flash_log import Download, FlashLog
    from fcb_sim.board.flight import FlightCore
    from fcb_sim.board.modes import ModeMachine
    from fcb_sim.board.scheduler import Scheduler
    from fcb_sim.board.timing import Profiler
    from fcb_sim.board.transmit import Transmitter
    from fcb_sim.board.uart import Uart
    from fcb_sim.board.wireless import WirelessLink


def _console() -> BoardConsole:
    from fcb_sim.board.console import BoardConsole

    return BoardConsole()


def _default(param: Param) -> Any:
    return PARAMS[param].default


@dataclass
class BoardConfig:
    """The board's start-up settings; those that are parameters default to the protocol's table (PARAMS), and
    ``preset`` (term.core.protocol.PRESETS: "default", "report") sets the ones it names after the rest."""

    seed: int = 1
    scheduler: str = _default(Param.SCHEDULER)  # or "priority"
    sensor_path: str = _default(Param.SENSOR_PATH)  # "auto": RAW path in RAW mode (and HEIGHT from RAW), else DMP
    link_timeout_s: float = _default(Param.LINK_TIMEOUT_MS) / 1000
    link_failsafe_s: float = _default(Param.LINK_FAILSAFE_MS) / 1000  # the failsafe's stage 1 (0: PANIC at once)
    telemetry_hz: float = _default(Param.TELEMETRY_HZ)
    heartbeat_ms: int = _default(Param.HEARTBEAT_MS)  # the Heartbeat's period, and the safety monitor's
    log_scheme: str = _default(Param.LOG_SCHEME)
    fixed_point: bool = _default(Param.FIXED_POINT)  # RAW filter in Q16.16 (and the fixed-point read cost)
    queue_rule: str = _default(Param.QUEUE_RULE)  # "discard-20": the report's parser, the whole queue at 20 frames
    preset: str = "default"
    board_id: int = 1
    boot_hello: bool = True
    log_bytes: int = FLASH_BYTES  # the flash log's size (128 KB on the board)
    softdevice: bool = True  # the BLE stack advertises (and takes the CPU for it) whether a phone is there or not
    # A changed stick moves the motors in the parse task that decodes it, not at the next control step
    # (docs/board.md, "Sticks to motors"); False is the report's firmware, where only the control step does.
    stick_reaction: bool = _default(Param.STICK_REACTION)
    # A diagnostic, not part of the model: an extra exponential delay of this mean (µs) on every start out of an
    # idle wait, standing for interference the model does not know (bench/profile.py: "residual").
    residual_jitter_us: float = 0.0

    def __post_init__(self) -> None:
        if self.scheduler not in SCHEDULERS:
            raise ValueError(f"unknown scheduler {self.scheduler!r}")
        if self.sensor_path not in SENSOR_PATHS:
            raise ValueError(f"unknown sensor path {self.sensor_path!r}")
        if self.queue_rule not in QUEUE_RULES:
            raise ValueError(f"unknown queue rule {self.queue_rule!r}")
        if self.preset not in PRESETS:
            raise ValueError(f"unknown preset {self.preset!r}; known: {', '.join(PRESETS)}")


@dataclass
class BoardParts:
    """The parts the board's handlers act on (module docstring), its clock (µs since boot) and nothing else."""

    config: BoardConfig
    core: FlightCore
    modes: ModeMachine
    log: FlashLog
    download: Download
    tx: Transmitter
    wireless: WirelessLink
    prof: Profiler
    sched: Scheduler
    uart: Uart
    clock: Callable[[], int]
    log_full_reported: bool = False  # LOG_FULL was said for this recording
    overflow_reported: int = 0  # receive-queue bytes dropped that OVERFLOW events have said
    overflow_report_at: int = 0  # board time before which no other OVERFLOW is said
    console: BoardConsole = field(default_factory=lambda: _console())  # qb_log's counts (fcb_sim/board/console.py)

    @property
    def now(self) -> int:
        return self.clock()

    def report_overflow(self, dropped: int) -> None:
        """What the receive queues dropped (``dropped`` bytes since boot) since the last report, at most once per
        heartbeat period: a flood is one event."""
        if dropped > self.overflow_reported and self.now >= self.overflow_report_at:
            self.event(EventCode.OVERFLOW, dropped - self.overflow_reported)
            self.overflow_reported = dropped
            self.overflow_report_at = self.now + HEARTBEAT_PERIOD_US

    def send(self, pkt: Any) -> None:
        """A packet to the PC, through the transmit side (fcb_sim/board/transmit.py)."""
        self.tx.send(pkt, self.clock())

    def event(self, code: EventCode, arg: int) -> None:
        """An Event packet: ``code`` with ``arg``, stamped with the board's clock in ms."""
        now = self.clock()
        self.tx.send(Event(int(code), int(arg), (now // 1000) & 0xFFFFFFFF), now)

    def wireless_events(self) -> None:
        """Report the handover's state changes (Event WIRELESS_STATE)."""
        for _old, new in self.wireless.take_transitions():
            self.event(EventCode.WIRELESS_STATE, int(new))

    def apply_queue_rule(self) -> None:
        """The receive queue's rule (Param.QUEUE_RULE): bounded, or the report's discard at 20 frames."""
        self.uart.discard_at_frames = QUEUE_DISCARD_FRAMES if self.config.queue_rule == "discard-20" else None

    def set_scheduler(self, name: str) -> None:
        if name not in SCHEDULERS:
            raise ValueError(f"unknown scheduler {name!r}")
        self.config.scheduler = name
        self.sched.priority = name == "priority"
