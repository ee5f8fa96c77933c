"""The board's timing model: what each task costs on the Cortex-M0, when the timers tick, and the interrupts
that take the CPU from the main loop (report sections 4.2 and 5, Figure 14). ``fcb_sim.board.board`` runs the loop;
how the model was built and what it leaves out: docs/board.md, "The timing model".

- Task durations (``COSTS``): every run of a task costs a draw from a distribution fitted to the report's Figure 14
  row for it (mean, sigma, p99, p99.9): a log-normal body and, with a small probability, a slower run (``Cost``;
  ``fit_cost`` fits them, ``python -m fcb_sim.board.timing`` refits and prints the table). The rows are wall-clock times
  on the board, so they already hold the interrupts that hit a task while it ran.
- The RAW filter (``RAW_FILTER_EXTRA_US``): the RAW rows hold the report's filter; a board running another one pays
  the difference of the two filters' prices, their counted operations (``fcb_sim.lab.opcount``) times cycles on the
  M0 (qfplib's measured float cycles; libfixmath-style fixed point, [ASSUMED]): docs/board.md, "The RAW filter's
  price".
- Timers (``rtc_ticks``): the app_timer on the 32768 Hz RTC1, so a period is a whole number of 30.5 µs ticks and
  the tasks' timers slide past one another (a slow task meets the sensor tick at every phase in turn).
- Interrupts that find the loop idle (``Interference``) delay the start of the task a tick releases: the
  SoftDevice's advertising events, UART interrupts (one per byte at 115200 baud), the motor PWM timer and the
  app_timer's own interrupt. Figures marked [ASSUMED] are estimates, not measurements; the SoftDevice's are
  Nordic's.
- Measuring (``TaskStats``, ``Profiler``): per task durations and periods, and the control periods at least the
  report's WCET99 and WCET99.9 (the deadline misses), beside Figure 14.
"""

from __future__ import annotations

import math
import random
from array import array
from collections import deque
from dataclasses import dataclass
from statistics import NormalDist
from typing import Any

from term.core.protocol import BAUD_RATE, Profile

# --- timers ----------------------------------------------------------------------------------------------------

RTC_HZ = 32_768  # app_timer runs on RTC1, prescaler 0 (the lab template's ble.c: APP_TIMER_PRESCALER 0)


def rtc_ticks(period_us: float) -> int:
    """A period in RTC ticks, rounded as the SDK's APP_TIMER_TICKS does (ROUNDED_DIV)."""
    return max(1, int(period_us * RTC_HZ / 1e6 + 0.5))


def rtc_us(ticks: int) -> int:
    """The first board microsecond at or after an RTC tick count."""
    return -((-ticks * 1_000_000) // RTC_HZ)


def us_to_ticks(t_us: int) -> int:
    """The last RTC tick at or before a board time."""
    return (t_us * RTC_HZ) // 1_000_000


# --- task durations ----------------------------------------------------------------------------------------------

_N = NormalDist()


@dataclass(frozen=True)
class Cost:
    """A task duration: with probability 1 - w a log-normal of mean m0 and sigma s0 (the task's own work), else a
    normal N(m1, s1) (a pre-empted or slow run), in µs, at least 1. ``figure`` is the report's mean, sigma, p99 and
    p99.9 it was fitted to."""

    w: float
    m0: float
    s0: float
    m1: float
    s1: float
    figure: tuple[float, float, float, float]

    def _lognormal(self) -> tuple[float, float]:
        s2 = math.log(1.0 + (self.s0 / self.m0) ** 2)
        return math.log(self.m0) - s2 / 2.0, math.sqrt(s2)

    def sampler(self, rng: random.Random) -> Any:
        mu, sg = self._lognormal()
        w, m1, s1 = self.w, self.m1, self.s1
        lognorm, gauss, rand = rng.lognormvariate, rng.gauss, rng.random

        def sample() -> int:
            if w and rand() < w:
                return max(1, int(gauss(m1, s1) + 0.5))
            return max(1, int(lognorm(mu, sg) + 0.5))

        return sample

    def cdf(self, x: float) -> float:
        tail = self.w * _N.cdf((x - self.m1) / self.s1) if self.s1 > 0 else self.w * (x >= self.m1)
        if x <= 0:
            return tail
        mu, sg = self._lognormal()
        return (1 - self.w) * _N.cdf((math.log(x) - mu) / sg) + tail

    def quantile(self, p: float) -> float:
        lo, hi = 0.0, 4.0 * (self.m0 + 10 * self.s0 + self.m1 + 10 * self.s1) + 1.0
        for _ in range(60):
            mid = (lo + hi) / 2
            lo, hi = (mid, hi) if self.cdf(mid) < p else (lo, mid)
        return (lo + hi) / 2

    def mean(self) -> float:
        return (1 - self.w) * self.m0 + self.w * self.m1

    def sd(self) -> float:
        e2 = (1 - self.w) * (self.s0 ** 2 + self.m0 ** 2) + self.w * (self.s1 ** 2 + self.m1 ** 2)
        return math.sqrt(max(0.0, e2 - self.mean() ** 2))


def fit_cost(figure: tuple[float, float, float, float]) -> Cost:
    """Fit a ``Cost`` to a Figure 14 row: (w, m1, s1) free, the body's (m0, s0) set by the mean and sigma; the
    tail's spread held at least the body's (a pre-empted run varies as much as a plain one), the body's sigma
    at most its mean, and probability
    mass kept around the p99 (a measured p99 lies where samples are: no empty gap below it, which would make the
    model's sample p99 jump between body and tail). Nelder-Mead from a few starts; slow (seconds), so the table
    below holds its results."""
    mean, sd, p99, p999 = figure

    def build(x: list[float]) -> Cost | None:
        w = 1.0 / (1.0 + math.exp(-x[0]))
        m1, s1 = x[1], math.exp(x[2])
        m0 = (mean - w * m1) / (1 - w)
        v0 = (sd * sd + mean * mean - w * (s1 * s1 + m1 * m1)) / (1 - w) - m0 * m0
        if m0 <= 0 or v0 <= 0:
            return None
        return Cost(w, m0, math.sqrt(v0), m1, s1, figure)

    def loss(x: list[float]) -> float:
        c = build(x)
        if c is None:
            return 1e9
        q99 = c.quantile(0.99)
        r1 = (q99 - p99) / sd
        r2 = (c.quantile(0.999) - p999) / sd
        spread = ((c.s0 - c.s1) / c.s0) ** 2 if c.s1 < c.s0 else 0.0
        spread += (c.s0 / c.m0 - 1.0) ** 2 if c.s0 > c.m0 else 0.0  # a log-normal body wider than its mean has
        h = 0.05 * sd  # a tail of its own (thousands of µs), which no row shows
        density = (c.cdf(q99 + h) - c.cdf(q99 - h)) / (2 * h)
        thin = max(0.0, math.log(0.01 / max(1.0, p999 - mean) / max(density, 1e-12)))
        return r1 * r1 + r2 * r2 + spread + 0.01 * thin * thin

    best: tuple[list[float], float] | None = None
    for w in (0.01, 0.03, 0.08):
        for m1 in (p99, (p99 + p999) / 2, p999):
            x0 = [math.log(w / (1 - w)), m1, math.log(max(1.0, 0.3 * (p999 - mean)))]
            x, v = _nelder_mead(loss, x0, [0.5, 0.1 * sd, 0.3], 200)
            if best is None or v < best[1]:
                best = (x, v)
    assert best is not None
    c = build(best[0])
    assert c is not None
    return c


def _nelder_mead(f: Any, x0: list[float], steps: list[float], iters: int) -> tuple[list[float], float]:
    n = len(x0)
    pts = [list(x0)] + [[x0[j] + (steps[j] if j == i else 0.0) for j in range(n)] for i in range(n)]
    vals = [f(p) for p in pts]
    for _ in range(iters):
        order = sorted(range(n + 1), key=vals.__getitem__)
        pts, vals = [pts[i] for i in order], [vals[i] for i in order]
        c = [sum(p[j] for p in pts[:-1]) / n for j in range(n)]
        xr = [2 * c[j] - pts[-1][j] for j in range(n)]
        fr = f(xr)
        if fr < vals[0]:
            xe = [3 * c[j] - 2 * pts[-1][j] for j in range(n)]
            fe = f(xe)
            pts[-1], vals[-1] = (xe, fe) if fe < fr else (xr, fr)
        elif fr < vals[-2]:
            pts[-1], vals[-1] = xr, fr
        else:
            xc = [(c[j] + pts[-1][j]) / 2 for j in range(n)]
            fc = f(xc)
            if fc < vals[-1]:
                pts[-1], vals[-1] = xc, fc
            else:
                pts = [pts[0]] + [[(pts[0][j] + p[j]) / 2 for j in range(n)] for p in pts[1:]]
                vals = [vals[0]] + [f(p) for p in pts[1:]]
    i = min(range(n + 1), key=vals.__getitem__)
    return pts[i], vals[i]


# Figure 14, every row: duration mean, sigma, p99, p99.9 and period mean, sigma (µs), N. Periods marked None are
# printed without a usable unit in the report (Heartbeat Full: "327ms ± 982").
FIGURE14: dict[str, tuple[float, float, float, float, float, float | None, int]] = {
    "parse_safe": (20, 26, 94.7, 332, 1487, 1093, 22832),
    "parse": (26, 44, 250, 345, 1546, 1125, 22525),
    "telemetry_safe": (570, 62, 736, 752, 1_910_000, 301_000, 15),
    "telemetry": (538, 33, 590, 590, 1_918_000, 207_000, 9),
    "control_dmp_safe": (10, 15, 58.7, 320, 4951, 353, 7027),
    "control_dmp": (63, 40, 175, 383, 4937, 386, 7001),
    "control_raw_safe": (11, 18, 60, 320, 2478, 246, 9250),
    "control_raw": (113, 41, 220, 492, 2477, 238, 9380),
    "sensor_dmp_safe": (1979, 145, 2560, 2820, 4949, 245, 6788),
    "sensor_dmp": (1983, 145, 2590, 2820, 4939, 280, 7090),
    "sensor_raw_safe": (1000, 90, 1410, 1590, 2482, 251, 9661),
    "sensor_raw": (1001, 87, 1390, 1570, 2478, 193, 9970),
    "sensor_raw_fixed_safe": (1001, 99, 1410, 1580, 2478, 143, 18713),
    "sensor_raw_fixed": (998, 96, 1410, 1590, 2477, 112, 18576),
    "heartbeat_safe": (21, 7, 48.4, 51.7, 324_000, 242_000, 109),
    "heartbeat": (23, 10, 51.5, 75.4, 327_000, None, 99),
    "baro_safe": (189, 133, 444, 500, 49670, 655, 659),
    "baro": (192, 132, 437, 646, 49532, 2495, 707),
    "logging_safe": (331, 64, 671, 710, 4967, 270, 492),
    "logging": (319, 49, 509, 747, 4965, 259, 497),
}

# The fitted durations (FULL rows unless named "safe": the control step with the motors off). ``fit_cost`` of
# the row, except telemetry: nine samples, so its p99 and p99.9 are only the largest of nine; a plain log-normal.
COSTS: dict[str, Cost] = {
    "parse": Cost(0.0535, 17.4, 17.3, 178.6, 79.5, (26, 44, 250, 345)),
    "telemetry": Cost(0.0, 538.0, 33.0, 538.0, 33.0, (538, 33, 590, 590)),
    "control_dmp": Cost(0.0028, 62.6, 31.8, 209.4, 434.3, (63, 40, 175, 383)),
    "control_raw": Cost(0.0062, 112.4, 33.4, 205.3, 288.6, (113, 41, 220, 492)),
    "control_dmp_safe": Cost(0.0010, 9.7, 10.7, 338.6, 10.1, (10, 15, 58.7, 320)),
    "control_raw_safe": Cost(0.0019, 10.4, 11.4, 326.3, 70.3, (11, 18, 60, 320)),
    "sensor_dmp": Cost(0.0191, 1971.0, 116.5, 2598.1, 136.8, (1983, 145, 2590, 2820)),
    "sensor_raw": Cost(0.0197, 993.1, 65.9, 1391.9, 108.7, (1001, 87, 1390, 1570)),
    "sensor_raw_fixed": Cost(0.0197, 989.7, 75.2, 1412.0, 108.7, (998, 96, 1410, 1590)),
    "heartbeat": Cost(0.0015, 23.0, 8.9, 49.9, 115.4, (23, 10, 51.5, 75.4)),
    "baro": Cost(0.5283, 78.9, 83.0, 293.0, 72.1, (192, 132, 437, 646)),
    "logging": Cost(0.0201, 315.1, 35.7, 508.3, 145.0, (319, 49, 509, 747)),
}

# --- interrupts that find the loop idle ------------------------------------------------------------------------

UART_US_PER_BYTE = 10_000_000 / BAUD_RATE  # 8N1: ten bits a byte
UART_ISR_US = 8  # RXDRDY/TXDRDY handler and queue, through the SoftDevice's interrupt forwarding [ASSUMED]
APP_TIMER_ISR_US = 20  # RTC1 compare, the app_timer list walk, one handler that sets a flag [ASSUMED]
APP_TIMER_EXTRA_US = 6  # each further timer expiring on the same RTC tick [ASSUMED]
PWM_ISR_US = 4  # motor PWM: TIMER2 CC0 every 2.5 ms sets four pins, TIMER1 clears each (lab template) [ASSUMED]
PWM_PERIOD_US = 2500
PWM_MIN_US = 1000  # pulse 1000 + ae µs (ae 0..1000)
ADV_INTERVAL_US = 40_000  # lab template ble.c: APP_ADV_INTERVAL 64 x 0.625 ms, APP_ADV_TIMEOUT 0 (for ever)
ADV_DELAY_MAX_US = 10_000  # Bluetooth Core spec Vol 6 Part B 4.4.2.2: advDelay, pseudo-random 0-10 ms per event
# One advertising event, typical CPU use at interrupt priority 0 (and 2) on the nRF51: radio prepare 76 µs, radio
# start 36, processing after each of the first two packets 50, post-processing 200, then 270 at priority 2 (S130
# SoftDevice Specification v2.0, "BLE advertiser processor usage patterns", Table 1: 682 µs per event; the S110
# used on the board is its peripheral-only sibling). The offsets between them are [ASSUMED]: a 31-byte ADV_IND
# is about 376 µs on air, plus the receive window and the hop, about 560 µs a channel.
SD_ADV_CHUNKS: tuple[tuple[int, int], ...] = ((0, 76), (400, 36), (960, 50), (1520, 50), (2080, 200), (2280, 270))


class Interference:
    """Interrupts as busy intervals on the board's clock. ``free_at(t, ...)`` is when the main loop gets the CPU
    back if it wants it at ``t``: after every interrupt in progress then, and any that chain on directly."""

    def __init__(self, rng: random.Random, *, softdevice: bool = True, first_adv_us: int | None = None) -> None:
        self.rng = rng
        self.softdevice = softdevice
        self._adv_next = rng.randrange(ADV_INTERVAL_US) if first_adv_us is None else first_adv_us
        self._sd: deque[tuple[int, int]] = deque()  # (start, end) of SoftDevice ISRs not yet over
        self._rx: deque[tuple[float, int]] = deque()  # (first ISR, bytes) of receive bursts
        self.delays = 0  # loop starts an interrupt delayed, and by how much in all (µs)
        self.delay_us = 0

    def rx(self, now: int, nbytes: int) -> None:
        """Bytes that reach the UART from now on, one receive interrupt each."""
        if nbytes > 0:
            start = max(float(now), self._rx[-1][0] + self._rx[-1][1] * UART_US_PER_BYTE) if self._rx else now
            self._rx.append((start, nbytes))

    def _sd_until(self, t: int) -> None:
        while self._adv_next <= t + SD_ADV_CHUNKS[-1][0]:
            a = self._adv_next
            self._sd.extend((a + off, a + off + dur) for off, dur in SD_ADV_CHUNKS)
            self._adv_next = a + ADV_INTERVAL_US + self.rng.randrange(ADV_DELAY_MAX_US + 1)

    def free_at(self, t: int, timer_isr_end: int = 0, tx_clock: float = 0.0, tx_bytes: int = 0,
                ae: tuple[int, ...] = ()) -> int:
        t0 = t
        if self.softdevice:
            self._sd_until(t)
        while self._sd and self._sd[0][1] <= t:
            self._sd.popleft()
        while self._rx and self._rx[0][0] + self._rx[0][1] * UART_US_PER_BYTE <= t:
            self._rx.popleft()
        while True:
            end = t
            if timer_isr_end > end:
                end = timer_isr_end
            for a, b in self._sd:
                if a > end:
                    break
                if b > end:
                    end = b
            for start, n in self._rx:
                end = max(end, _byte_isr_end(end, start, n))
            if tx_bytes:
                end = max(end, _byte_isr_end(end, tx_clock + UART_US_PER_BYTE, tx_bytes))
            phase = end % PWM_PERIOD_US
            if phase < PWM_ISR_US:
                end += PWM_ISR_US - phase
            for a in ae:
                off = PWM_MIN_US + max(0, min(1000, a))
                if off <= phase < off + PWM_ISR_US:
                    end += off + PWM_ISR_US - phase
                    break
            if end <= t:
                break
            t = math.ceil(end)
        if t > t0:
            self.delays += 1
            self.delay_us += t - t0
        return t


def residual_jitter_us(model_period_sd: float, report_period_sd: float) -> float:
    """The mean of an exponential start delay that brings a period's sigma from the model's to the report's: each
    start gains a variance tau², a period (the difference of two starts) 2 tau²."""
    return math.sqrt(max(0.0, (report_period_sd ** 2 - model_period_sd ** 2) / 2.0))


def _byte_isr_end(t: float, first: float, n: int) -> float:
    """The end of the per-byte interrupt in progress at ``t`` (interrupts every byte time from ``first``), or t."""
    if t < first:
        return t
    k = int((t - first) // UART_US_PER_BYTE)
    if k >= n:
        return t
    at = first + k * UART_US_PER_BYTE
    return at + UART_ISR_US if t < at + UART_ISR_US else t



# --- costs of our own work (not in Figure 14) ------------------------------------------------------------------

# Logging's measured 319 µs was the report's ~18-byte record at 15 µs a byte plus encoding; the model charges the
# encoding part from the fit and 15 µs for every byte actually programmed, so a smaller record costs less.
REPORT_RECORD_BYTES = 18
RICE_ENCODE_EXTRA_US = 40  # bit packing on a Cortex-M0 without a barrel-shift-friendly compiler [ASSUMED]
PARSE_US_BASE = 6  # our frames carry COBS and a CRC-16: a call costs a base plus per byte [ASSUMED]
PARSE_US_PER_BYTE = 4
DOWNLOAD_US_PER_CHUNK = 20  # flash read and frame encode per LogChunk [ASSUMED]


# --- the RAW path's attitude filter: priced by the filter that runs (docs/board.md, "The RAW filter's price") ----

CPU_HZ = 16_000_000  # the nRF51822's core clock
# The report's RAW rows ("MPU RAW - float/fixed", Figure 14) hold the filter its board flew, at its real cost; a
# board running another filter pays the difference of the two filters' priced cost.
REPORT_RAW_FILTER = "complementary"
# Cycles per operation on the Cortex-M0, which has no FPU, no divide instruction and no 32x32->64 multiply.
# Float: qfplib-M0-full (the report used qfplib, 4.2), its author's cycle counts with call overhead, measured on an
# LPC11U68 Cortex-M0 (quinapalus.com/qfplib-m0-full.html); "add" is fadd 76 / fsub 78; asin is eq. 5 (atan2 and
# sqrt). Fixed: libfixmath's Q16.16 (the report's [5]) and ikf_fixed's primitives, [ASSUMED] from their code paths:
# a rounded, saturated 64-bit product from four 16x16 MULS with carries; a division by repeated 32/32 software
# divisions (1-3, libfixmath's comment) with a software clz; a bit-by-bit square root (2 x 16 iterations); atan2
# is fix16_atan2 (a division, four products) plus the report's correction (a modulo, a search of 18 knots, one
# product and one division); saturating additions test for overflow; plain integer additions are one cycle.
M0_CYCLES_FLOAT: dict[str, float] = {"add": 77, "mul": 62, "div": 83, "sqrt": 67, "sin": 584, "cos": 595,
                                     "atan2": 673, "asin": 673 + 67 + 62 + 77}
M0_CYCLES_FIXED: dict[str, float] = {"add": 1, "mul": 40, "div": 180, "sqrt": 300, "sadd": 8, "sat": 4,
                                     "atan2_correction": 150, "atan2": 180 + 4 * 40 + 20 + 150, "asin": 1000,
                                     "qmul": 12}
# "qmul": ikf_lite's truncated Q2.30 product, inlined: three MULS, four shifts, two halves, two additions [ASSUMED]
# Operations per sample, update and the angles the control step reads (``python -m fcb_sim.lab.opcount`` counts them
# and prints this table; a test keeps the two equal).
RAW_FILTER_OPS: dict[tuple[str, bool], dict[str, float]] = {
    ("complementary", False): {"add": 8.0, "atan2": 2.0, "mul": 7.0, "sqrt": 1.0},
    ("complementary", True): {"atan2_correction": 2.0, "div": 2.0, "mul": 15.0, "sadd": 7.0, "sqrt": 1.0},
    ("complementary-0.9", False): {"add": 8.0, "atan2": 2.0, "mul": 7.0, "sqrt": 1.0},
    ("complementary-0.9", True): {"atan2_correction": 2.0, "div": 2.0, "mul": 15.0, "sadd": 7.0, "sqrt": 1.0},
    ("kalman", False): {"add": 12.0, "atan2": 2.0, "div": 4.0, "mul": 5.0, "sqrt": 1.0},
    ("kalman", True): {"atan2_correction": 2.0, "div": 6.0, "mul": 13.0, "sadd": 11.0, "sqrt": 1.0},
    ("kalman-cov", False): {"add": 12.0, "atan2": 2.0, "mul": 9.0, "sqrt": 1.0},
    ("kalman-cov", True): {"atan2_correction": 2.0, "div": 6.0, "mul": 33.0, "sadd": 35.0, "sqrt": 1.0},
    ("qgate", False): {"add": 110.0, "atan2": 4.0, "cos": 2.0, "div": 6.0, "mul": 161.0, "sin": 2.0, "sqrt": 6.0},
    ("ikf", False): {"add": 122.0, "atan2": 3.0, "cos": 2.0, "div": 5.0, "mul": 165.0, "sin": 2.0, "sqrt": 6.0},
    ("ikf", True): {"add": 12.0, "atan2": 3.0, "div": 1.2, "mul": 37.7, "qmul": 67.5, "sat": 11.2, "sqrt": 1.9},
}


def raw_filter_us(name: str, fixed_point: bool = False) -> float:
    """The priced cost (µs at CPU_HZ) of one sample of RAW filter ``name``: its counted operations times the cycle
    table of its arithmetic. KeyError for a filter (or fixed-point variant) not in RAW_FILTER_OPS."""
    cycles = M0_CYCLES_FIXED if fixed_point else M0_CYCLES_FLOAT
    return sum(n * cycles[op] for op, n in RAW_FILTER_OPS[(name, fixed_point)].items()) * 1e6 / CPU_HZ


# Cycles from execution (fcb_sim.hosts.m0emu; docs/board.md, "Cycles from execution"): the task bodies of
# firmware/board (ikf_q.c, ctl_q.c) built with arm-none-eabi-gcc -mcpu=cortex-m0 -mthumb -Os and executed under an
# emulated Cortex-M0 on BROAD trial 07's excerpt (tests/fixtures: rows 2450-2849, fast hand-held rotation), cycles by
# the Cortex-M0 TRM's table, at CPU_HZ: mean and p99 in µs. "filter/ikf/fixed" is what RAW_FILTER_OPS prices for
# ikf in Q16.16 (the update, the predicted attitude and the angles the control law reads); "control_raw" the
# law and the mixing, Figure 14's control row. bench.profile measures them again and prints both; a test keeps
# this table equal to a fresh emulation.
# "filter/ikf/fixed" is the exact twin (ikf_fixed.py); "filter/ikf/fixed/decimationN" the same with the gravity
# part every N-th sample (docs/attitude.md, "Decimation"): a cheap sample and, every N-th, a full one (the p99).
# "filter/ikf/liteN" is the variant cut to fit (ikf_lite.py), its gravity part in four pieces spread over N
# samples; lite4 is what ikf in fixed point runs (make_filter), so what the board charges for it.
M0_EMULATED_US: dict[str, tuple[float, float]] = {
    "filter/ikf/fixed": (1665.6, 1732.9),
    "control_raw": (131.0, 159.6),
    "filter/ikf/fixed/decimation4": (877.2, 1741.2),
    "filter/ikf/fixed/decimation8": (743.2, 1741.6),
    "filter/ikf/lite1": (841.7, 846.0),
    "filter/ikf/lite4": (364.6, 387.2),
    "filter/ikf/lite8": (285.2, 386.8),
}
EMULATED_FILTERS: dict[tuple[str, bool], str] = {("ikf", True): "filter/ikf/lite4"}
MODEL_TOLERANCE = 0.2  # where the model and the emulation disagree by more, the model follows the emulation


def raw_filter_price_us(name: str, fixed_point: bool = False) -> float:
    """What the board charges for one sample of RAW filter ``name`` (µs): its emulated cost where the priced one
    (``raw_filter_us``) is more than MODEL_TOLERANCE away from it, else the priced one."""
    model = raw_filter_us(name, fixed_point)
    key = EMULATED_FILTERS.get((name, fixed_point))
    if key is None or not M0_EMULATED_US[key][0]:
        return model
    emulated = M0_EMULATED_US[key][0]
    return emulated if abs(model - emulated) > MODEL_TOLERANCE * emulated else model


# What a sample of each filter costs beyond the report's filter in the same arithmetic (µs, whole): added to the
# RAW sensor read's Figure 14 draw. 0 for the report's own filter, so its profile is the report's.
RAW_FILTER_EXTRA_US: dict[tuple[str, bool], int] = {
    key: round(raw_filter_price_us(*key) - raw_filter_us(REPORT_RAW_FILTER, key[1])) for key in RAW_FILTER_OPS}


# --- measuring the loop: durations, periods, deadline misses beside the report's -----------------------------

SENSOR_PERIOD_US = {"raw": 2500, "dmp": 5000}  # report 4.2: RAW 400 Hz, DMP 200 Hz

# The report's deadline analysis (4.2): in RAW mode a control period at least the sum of the tasks' 99th
# (99.9th) percentile durations, 2987 (3738) µs, is a significant miss. Figure 13 plots the period normalised by
# the set point; DMP mode uses the same normalised thresholds (1.195 and 1.495 times 5000 µs).
WCET99_US = {"raw": 2987, "dmp": round(2987 / 2500 * 5000)}
WCET999_US = {"raw": 3738, "dmp": round(3738 / 2500 * 5000)}
REPORT_MISS_RATE = {"raw": 0.021, "dmp": None}  # Figure 13 shows DMP "far fewer", without a figure
REPORT_MISS_RATE_999 = {"raw": 0.0003, "dmp": None}


class DurationHistogram:
    """Task durations (integer µs) in a fixed log-linear histogram, so the percentiles cost bounded memory in a flight
    of any length (a queue of the latest 50 000 per task grew 1.6 MB a minute until full, issue 36). Exact below
    ``EXACT_US`` (one bin per µs: every task of the board's timing model runs shorter, so its figures are the sorted
    list's to the µs); above, ``SUB_BINS`` bins per power of two, a percentile given as its bin's lower edge: less
    than 1/SUB_BINS (1.6 %) under the true value. Over everything since the last reset, as the means are."""

    EXACT_US = 1024
    SUB_BITS = 6
    SUB_BINS = 1 << SUB_BITS
    MAX_EXP = 40  # 2**40 µs (12 days): longer durations share the last bin
    BINS = EXACT_US + SUB_BINS * (MAX_EXP - 9)  # exponents 10..MAX_EXP

    def __init__(self) -> None:
        self.counts = array("Q", bytes(8 * self.BINS))
        self.total = 0

    @classmethod
    def index(cls, us: int) -> int:
        if us < cls.EXACT_US:
            return max(0, us)
        e = us.bit_length() - 1  # 10 and up
        if e > cls.MAX_EXP:
            return cls.BINS - 1
        return cls.EXACT_US + (e - 10) * cls.SUB_BINS + ((us >> (e - cls.SUB_BITS)) & (cls.SUB_BINS - 1))

    @classmethod
    def lower(cls, i: int) -> int:
        """The smallest duration of bin ``i``."""
        if i < cls.EXACT_US:
            return i
        e, sub = divmod(i - cls.EXACT_US, cls.SUB_BINS)
        return (cls.SUB_BINS + sub) << (e + 10 - cls.SUB_BITS)

    def add(self, us: int) -> None:
        self.counts[self.index(us)] += 1
        self.total += 1

    def __len__(self) -> int:
        return self.total

    def percentile(self, q: float) -> float:
        """The duration of rank ``int(q * n)`` (0-based) in sorted order, as ``sorted(d)[int(q * n)]`` was."""
        if not self.total:
            return 0.0
        rank = min(self.total - 1, int(q * self.total))
        seen = 0
        for i, c in enumerate(self.counts):
            seen += c
            if seen > rank:
                return float(self.lower(i))
        return float(self.lower(self.BINS - 1))


class TaskStats:
    """Per-task durations and periods: running mean and sigma (Welford) over everything, and the durations in a
    fixed histogram for the percentiles (``DurationHistogram``): the same size after a minute as after a day."""

    def __init__(self) -> None:
        self.n = 0
        self.mean = 0.0
        self.m2 = 0.0
        self.pn = 0
        self.pmean = 0.0
        self.pm2 = 0.0
        self.last_start: int | None = None
        self.durations = DurationHistogram()
        self.last_us = 0  # the latest duration
        self.misses = 0  # periods at least the WCET99 threshold (control only)
        self.misses999 = 0

    def add(self, start: int, dur: int) -> int | None:
        self.n += 1
        d = dur - self.mean
        self.mean += d / self.n
        self.m2 += d * (dur - self.mean)
        self.durations.add(int(dur))
        self.last_us = dur
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
        return self.durations.percentile(q)

    def summary(self) -> dict[str, float]:
        sd = math.sqrt(self.m2 / (self.n - 1)) if self.n > 1 else 0.0
        psd = math.sqrt(self.pm2 / (self.pn - 1)) if self.pn > 1 else 0.0
        return {"n": self.n, "mean_us": round(self.mean, 1), "sd_us": round(sd, 1),
                "period_us": round(self.pmean, 1), "period_sd_us": round(psd, 1),
                "p99_us": self.percentile(0.99), "p999_us": self.percentile(0.999), "misses": self.misses}


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


class Profiler:
    """What the loop measured since profiling (re)started: per task ``TaskStats``, the motor recomputes at a stick
    change (``reactions``, their time is in the parse task's too), the CPU's busy time, and the control deadline
    misses (periods between control starts at least WCET99 and WCET99.9)."""

    def __init__(self, tasks: tuple[str, ...]) -> None:
        self.tasks = tasks
        self.busy_us = 0
        self.cpu_load = 0  # % busy between the last two ``load`` calls (the Status packet's)
        self._busy_mark = (0, 0)  # (time, busy) at the last ``load``
        self.reset(0)

    PACKETS_REFRESH_US = 500_000

    def reset(self, now: int) -> None:
        self._packets: tuple[int, list[Profile]] | None = None
        self.stats = {name: TaskStats() for name in self.tasks}
        self.reactions = TaskStats()
        self._mark = (now, self.busy_us)

    def ran(self, task: str, start: int, dur: int) -> int | None:
        """A task ran; returns its period (start to start), None for its first run."""
        self.busy_us += dur
        return self.stats[task].add(start, dur)

    def control_period(self, path: str, period: int) -> bool:
        """Count a control period against the deadlines; True if it missed WCET99."""
        st = self.stats["control"]
        if period >= WCET999_US[path]:
            st.misses999 += 1
        if period >= WCET99_US[path]:
            st.misses += 1
            return True
        return False

    def load(self, now: int) -> int:
        """The CPU load (%) since the previous call."""
        t0, b0 = self._busy_mark
        if now > t0:
            self.cpu_load = min(100, round(100 * (self.busy_us - b0) / (now - t0)))
        self._busy_mark = (now, self.busy_us)
        return self.cpu_load

    def summary(self, now: int, path: str, scheduler: str, fixed_point: bool, ticks_lost: dict[str, int],
                irq: Interference) -> dict[str, Any]:
        """Per task figures beside the report's (Figure 14) and the control deadline misses."""
        ctl = self.stats["control"]
        periods = max(1, ctl.pn)
        return {
            "path": path, "scheduler": scheduler, "control_hz": round(1e6 / SENSOR_PERIOD_US[path]),
            "deadline_us": WCET99_US[path], "deadline_999_us": WCET999_US[path],
            "deadline_miss_rate": ctl.misses / periods, "deadline_miss_rate_999": ctl.misses999 / periods,
            "control_periods": ctl.pn, "report_deadline_miss_rate": REPORT_MISS_RATE[path],
            "report_deadline_miss_rate_999": REPORT_MISS_RATE_999[path],
            "tasks": {name: self.stats[name].summary() for name in self.tasks},
            "stick_reactions": self.reactions.summary(),
            "report": report_figures(path, fixed_point),
            "ticks_lost": dict(ticks_lost),
            "idle_starts_delayed_by_interrupts": irq.delays,
            "interrupt_delay_us_mean": round(irq.delay_us / max(1, irq.delays), 1),
            "cpu_load_pct": round(100 * (self.busy_us - self._mark[1]) / max(1, now - self._mark[0]), 1),
        }

    def packets(self, now: int) -> list[Profile]:
        """The Profile packets, one per task in ``tasks`` order; recomputed at most every ``PACKETS_REFRESH_US``
        (a percentile walks a histogram of some 3,000 bins per task: a flood of requests must not cost that each)."""
        if self._packets is not None and now - self._packets[0] < self.PACKETS_REFRESH_US:
            return self._packets[1]
        out = []
        for i, name in enumerate(self.tasks):
            s = self.stats[name].summary()
            out.append(Profile(i, min(65535, round(s["mean_us"])), min(65535, round(s["p99_us"])),
                               min(65535, round(s["p999_us"])), min(2**32 - 1, round(s["period_us"])),
                               min(65535, s["misses"])))
        self._packets = (now, out)
        return out

if __name__ == "__main__":
    for name, row in FIGURE14.items():
        if name.startswith("telemetry"):
            continue
        c = fit_cost(row[:4])
        print(f'    "{name}": Cost({c.w:.4f}, {c.m0:.1f}, {c.s0:.1f}, {c.m1:.1f}, {c.s1:.1f}, {row[:4]}),'
              f"  # p99 {c.quantile(0.99):.0f} p99.9 {c.quantile(0.999):.0f}")
