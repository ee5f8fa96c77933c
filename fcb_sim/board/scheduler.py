"""The firmware's timers and task flags, and the two ways the main loop picks the next task (docs/board.md).

Timer interrupts only set flags; the loop sees a flag when it next tests it. A tick that comes while its flag
is still set is lost (``ticks_lost``); ticks are never queued. The periodic tasks run from app timers on the
32768 Hz RTC, whose periods are whole ticks (fcb_sim/board/timing.py), started at unrelated phases.

- ``round-robin`` (the report's design): every pass runs each flagged task once, in ``ROUND_ROBIN_ORDER``.
- ``priority`` (the report's proposed fix, 6.1): the most important flagged task first (``PRIORITY_ORDER``);
  control runs first at the sensor tick on the previous sample; a task outside the control chain starts only if
  its 99.9th-percentile duration (``budget``) ends before the next sensor tick, and parse takes only as many
  bytes as fit.

Sans-IO: ``fire(now)`` sets the flags of the timers that expired; ``pick(now, budget)`` names the task to run.
"""

from __future__ import annotations

import random
from collections.abc import Callable

from fcb_sim.board.timing import (
    APP_TIMER_EXTRA_US,
    APP_TIMER_ISR_US,
    PARSE_US_BASE,
    PARSE_US_PER_BYTE,
    SENSOR_PERIOD_US,
    rtc_ticks,
    rtc_us,
    us_to_ticks,
)
from term.core.protocol import BOARD_TASKS

TASKS = BOARD_TASKS  # the Profile packet's ids
ROUND_ROBIN_ORDER = ("parse", "baro", "telemetry", "heartbeat", "sensor", "control", "logging")
PRIORITY_ORDER = ("control", "sensor", "logging", "parse", "heartbeat", "baro", "telemetry")
CHAIN = frozenset({"control", "sensor", "logging"})  # never held back by the slack rule
PARSE_MAX_BYTES = 64  # per parse run, so one run stays short
BARO_PERIOD_US = 50_000
HEARTBEAT_PERIOD_US = 100_000


def timer_period(name: str, path: str, telemetry_hz: float, heartbeat_us: int = HEARTBEAT_PERIOD_US) -> int:
    """A timer's period (µs): the sensor's follows the path (RAW 400 Hz, DMP 200 Hz), telemetry its rate, the
    heartbeat ``heartbeat_us`` (Param.HEARTBEAT_MS)."""
    if name == "sensor":
        return SENSOR_PERIOD_US[path]
    if name == "baro":
        return BARO_PERIOD_US
    if name == "heartbeat":
        return heartbeat_us
    return max(10_000, int(1e6 / max(0.1, telemetry_hz)))


class Scheduler:
    """The timers (sensor, baro, telemetry, heartbeat), the task flags and the choice of the next task.

    ``period(name)`` gives a timer's current period in µs (the sensor's depends on the path, the telemetry's on
    its rate); ``priority`` selects the scheduler."""

    def __init__(self, rng: random.Random, period: Callable[[str], int], *, priority: bool = False,
                 phases: dict[str, int] | None = None) -> None:
        self.period = period
        self.priority = priority
        self.flags = {name: False for name in TASKS}
        # Independent hardware timers started at different moments: their phases are unrelated (a common phase
        # would line every task up on the sensor tick and make each collision systematic). Next expiry in RTC
        # ticks, and in board µs.
        self.next_tk = phases if phases is not None else {
            "sensor": 0, "baro": rng.randrange(1, rtc_ticks(period("baro"))),
            "telemetry": rng.randrange(1, rtc_ticks(20_000)),
            "heartbeat": rng.randrange(1, rtc_ticks(period("heartbeat")))}
        self.next = {name: rtc_us(tk) for name, tk in self.next_tk.items()}
        self._soonest = min(self.next.values())  # the next expiry: most looks find nothing expired
        self.ticks_lost = {name: 0 for name in self.next}
        self.timer_isr_end = 0  # when the app_timer interrupt of the last expiry is over
        self.parse_limit = PARSE_MAX_BYTES
        self._rr = 0

    def fire(self, now: int) -> None:
        """Set the flags of the timers that expired by ``now`` (one app_timer interrupt serves all that expire
        on the same tick)."""
        if now < self._soonest:
            return
        nxt = self.next
        at: dict[int, int] = {}  # expiry time -> timers expiring then
        for name, t in nxt.items():
            if now >= t:
                period = rtc_ticks(self.period(name))
                if self.flags[name]:
                    self.ticks_lost[name] += 1
                self.flags[name] = True
                if name == "sensor" and self.priority:
                    self.flags["control"] = True  # control first, on the previous sample
                tk = self.next_tk[name]
                missed = (us_to_ticks(now) - tk) // period
                self.ticks_lost[name] += missed
                self.next_tk[name] = tk = tk + (missed + 1) * period
                nxt[name] = rtc_us(tk)
                at[t] = at.get(t, 0) + 1
        for t, n in at.items():
            self.timer_isr_end = max(self.timer_isr_end, t + APP_TIMER_ISR_US + APP_TIMER_EXTRA_US * (n - 1))
        self._soonest = min(nxt.values())

    def restart(self, name: str, now: int) -> None:
        """Start timer ``name`` afresh from ``now`` with its current period (the sensor path changed)."""
        self.next_tk[name] = tk = us_to_ticks(now) + rtc_ticks(self.period(name))
        self.next[name] = rtc_us(tk)
        self._soonest = min(self.next.values())

    def next_tick_us(self) -> int:
        return self._soonest

    def pick(self, now: int, budget: Callable[[str], int]) -> str | None:
        """The task to run now, or None; the flag stays set (the loop clears it when the task starts)."""
        return self._pick_priority(now, budget) if self.priority else self._pick_round_robin()

    def _pick_round_robin(self) -> str | None:
        if not any(self.flags.values()):
            return None  # (most looks: the loop waits for the next interrupt)
        order = ROUND_ROBIN_ORDER
        n = len(order)
        for i in range(n):
            name = order[(self._rr + i) % n]
            if self.flags[name]:
                self._rr = (self._rr + i + 1) % n
                return name
        return None

    def _pick_priority(self, now: int, budget: Callable[[str], int]) -> str | None:
        next_tick = self.next["sensor"]
        for name in PRIORITY_ORDER:
            if not self.flags[name]:
                continue
            if name in CHAIN:
                return name
            if name == "parse":
                # parse only as many bytes as fit before the tick (the rest waits for the next slack)
                room = (next_tick - now - PARSE_US_BASE) // PARSE_US_PER_BYTE
                if room >= 1:
                    self.parse_limit = int(min(PARSE_MAX_BYTES, room))
                    return name
                continue
            if now + budget(name) <= next_tick:
                return name
        return None
