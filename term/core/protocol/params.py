"""The board's parameter table (``Param``, ``ParamSpec``, ``PARAMS``: name, type, unit, range, default, in flight or
not), the SET_PARAM argument packing and the presets. docs/parameters.md is generated from it.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from enum import IntEnum
from typing import Any

from term.core.protocol.facts import SCHEME_NAMES, Op
from term.core.protocol.numbers import NumberError, check_number, parse_number, shown_text


class Param(IntEnum):
    """Board parameter ids (1..127), one per row of ``PARAMS``: ``SET_PARAM`` (``param_arg``), ``PARAM_GET``,
    ``PARAM_LIST``, ``EventCode.PARAM_CHANGED`` and the ``ParamValue`` packet name them by this number."""

    LINK_TIMEOUT_MS = 1
    SCHEDULER = 2
    TELEMETRY_HZ = 3
    SENSOR_PATH = 4
    LOG_SCHEME = 5
    YAW_P = 6
    P1 = 7
    P2 = 8
    HEIGHT_P = 9
    HEIGHT_D = 10
    HEIGHT_I = 11
    ATTITUDE_FILTER = 12
    K_GYRO = 13
    FIXED_POINT = 14
    HEIGHT_ESTIMATOR = 15
    STICK_REACTION = 16
    QUEUE_RULE = 17
    TRIM_STEP = 18
    LIFT_STEP = 19
    LINK_FAILSAFE_MS = 20
    HEARTBEAT_MS = 21
    CALIBRATION_MS = 22
    PANIC_COUNTDOWN_MS = 23


SCHEDULERS = ("round-robin", "priority")  # Param.SCHEDULER value -> the board's scheduler
SENSOR_PATHS = ("auto", "dmp", "raw")  # Param.SENSOR_PATH value -> the sensor path ("auto" follows the mode)
ATTITUDE_FILTERS = ("complementary", "kalman", "kalman-cov", "qgate", "ikf")  # the RAW path's filter, by name
HEIGHT_ESTIMATORS = ("complementary", "kalman")  # the height estimator: the report's Figure 10, or ours
QUEUE_RULES = ("bounded", "discard-20")  # the receive queue: drop what does not fit; the report's rule
QUEUE_DISCARD_FRAMES = 20  # "discard-20": the whole receive queue goes when this many frames wait in it
PARAM_RAW_BITS = 24  # SET_PARAM and PARAM_CHANGED carry a signed 24-bit raw value under an 8-bit id
_RAW_MAX = (1 << (PARAM_RAW_BITS - 1)) - 1
_KINDS = ("int", "float", "bool", "enum")


@dataclass(frozen=True, slots=True)
class ParamSpec:
    """One board parameter. ``value`` is what a pilot reads and types (a number in ``unit``, a name for an enum, a
    bool); ``raw`` the int32 the wire carries: ``round(value / scale)`` for numbers, the choice's number for an enum
    (``choices[raw - base]``), 0 or 1 for a bool. ``lo``..``hi`` (inclusive, in ``unit``) is what the board accepts;
    ``in_flight`` False: refused (Nak.NOT_IN_SAFE) outside SAFE; ``shorter_in_flight``: outside SAFE it may only
    decrease (Nak.ONLY_SHORTER_IN_FLIGHT: the link timeouts). ``step``: one press of its key (gains, trims)."""

    param: Param
    name: str  # "group.name": ctrl (gains), est (estimators), sched, link, log, trim
    kind: str  # "int", "float", "bool", "enum"
    unit: str
    default: float | str | bool
    doc: str
    lo: float = 0
    hi: float = 0
    scale: float = 1.0
    choices: tuple[str, ...] = ()
    base: int = 0  # the raw number of the first choice
    in_flight: bool = True
    shorter_in_flight: bool = False
    step: float = 0.0

    @property
    def safe_only(self) -> bool:
        return not self.in_flight

    @property
    def nudge(self) -> float:
        """One step of the parameter screen's arrows in flight: ``step``, else the wire's own step."""
        return self.step or self.scale

    @property
    def raw_range(self) -> tuple[int, int]:
        if self.kind == "enum":
            return self.base, self.base + len(self.choices) - 1
        if self.kind == "bool":
            return 0, 1
        return round(self.lo / self.scale), round(self.hi / self.scale)

    def accepts(self, raw: int) -> bool:
        lo, hi = self.raw_range
        return lo <= raw <= hi

    def to_raw(self, value: float | str | bool) -> int:
        """The wire's int for ``value`` (a choice's name for an enum). ValueError (one line) if it is not one, or
        if it is so far out of range that it would not fit the wire (checked before it is scaled)."""
        if self.kind == "enum":
            if value not in self.choices:
                raise ValueError(f"{self.name}: {shown_text(value)} is not one of {', '.join(self.choices)}")
            return self.base + self.choices.index(str(value))
        if self.kind == "bool":
            if not isinstance(value, bool):
                raise ValueError(f"{self.name}: give true or false, got {shown_text(value)}")
            return int(value)
        bad = isinstance(value, bool) or not isinstance(value, int | float)
        if bad or isinstance(value, float) and not math.isfinite(value):
            raise ValueError(f"{self.name}: give a number, got {shown_text(value)}")
        if self.kind == "int" and value != int(value):
            raise ValueError(f"{self.name}: give a whole number, got {shown_text(value)}")
        if not abs(value) <= _RAW_MAX * self.scale:  # exact for any int: nothing huge reaches round()
            raise ValueError(f"{self.name}: {shown_text(value)} does not fit the wire's raw value")
        return round(value / self.scale)

    def check(self, value: Any, given: str | None = None) -> float | str | bool:
        """``value`` (from a file, a parser, the instructor) as this parameter's value: the one strict check every
        surface uses. A number must be finite, inside ``lo..hi`` (before any scaling) and a whole multiple of the
        wire's step (``1e-30`` is not silently 0); an enum one of its choices exactly; a bool a real bool.
        NumberError (a ValueError) of one line naming the parameter and quoting ``given`` (what was typed)."""
        shown = given if given is not None else shown_text(value)
        if self.kind == "enum":
            if not isinstance(value, str) or value not in self.choices:
                raise NumberError(f"{self.name} must be one of {', '.join(self.choices)}, got {shown}")
            return value
        if self.kind == "bool":
            if not isinstance(value, bool):
                raise NumberError(f"{self.name} must be true or false, got {shown}")
            return value
        number = check_number(value, self.name, self.lo, self.hi, integer=self.kind == "int", unit=self.unit,
                              what=shown)
        raw = round(number / self.scale)
        if abs(float(self.from_raw(raw)) - number) > 1e-9 * abs(number):  # 1e-30 is not 0, 0.12345 not 0.1235
            step = self.text(self.scale) if self.kind == "float" else str(self.scale)
            raise NumberError(f"{self.name} goes in steps of {step}, got {shown} (nearest: "
                              f"{self.text(self.from_raw(raw))})")
        return number

    def parse(self, text: str) -> float | str | bool:
        """What a pilot typed (the command line, the parameter screen) as this parameter's value: ASCII only,
        spaces around it allowed, nothing else (``"kalman\\n"``, ``１``, ``1_0`` are refused); then ``check``."""
        shown = shown_text(text)
        if not isinstance(text, str):
            raise NumberError(f"{self.name}: give text, got {shown}")
        t = text.strip(" ")
        if self.kind == "bool":
            word = t.lower() if t.isascii() else t
            if word in ("true", "on", "yes", "1"):
                return True
            if word in ("false", "off", "no", "0"):
                return False
            return self.check(t, shown)
        if self.kind == "enum":
            return self.check(t, shown)
        number = parse_number(t, self.name, self.lo, self.hi, integer=self.kind == "int", unit=self.unit)
        return self.check(number, shown)

    def from_raw(self, raw: int) -> float | str | bool:
        """The value for the wire's ``raw`` (an enum's raw out of its range is shown as its number)."""
        if self.kind == "enum":
            i = raw - self.base
            return self.choices[i] if 0 <= i < len(self.choices) else str(raw)
        if self.kind == "bool":
            return bool(raw)
        if self.kind == "int":
            return int(raw * self.scale)
        return round(raw * self.scale, _decimals(self.scale))  # 99900 * 1e-5 is 0.999, not 0.9990000000000001

    def text(self, value: float | str | bool) -> str:
        """``value`` as the pilot reads it (no unit)."""
        if self.kind == "bool":
            return "true" if value else "false"
        if self.kind == "float" and isinstance(value, int | float):
            return f"{value:.{_decimals(self.scale)}f}".rstrip("0").rstrip(".") if value == value else "nan"
        return str(value)

    def limits_text(self) -> str:
        if self.kind == "enum":
            return ", ".join(self.choices)
        if self.kind == "bool":
            return "true, false"
        return f"{self.text(self.lo)}..{self.text(self.hi)}"


@dataclass(frozen=True, slots=True)
class ParamRule:
    """A rule between two parameters: ``big`` >= ``factor`` × ``small``, compared on their raw values (the two share
    a unit and a scale: a board checks it in integers). Both boards refuse a set that breaks it (``Nak.PARAM_RULE``;
    the Python board's Ack carries the rule's index in ``PARAM_RULES`` as its value) and the terminal says so before
    it sends. ``why``: the reason, as both parameters' docs state it."""

    name: str
    big: Param
    factor: int
    small: Param
    why: str

    def holds(self, values: Mapping[Param, float | str | bool]) -> bool:
        """Whether ``values`` (a parameter's value in its unit, by Param) keep the rule (one missing: it does)."""
        if self.big not in values or self.small not in values:
            return True
        return PARAMS[self.big].to_raw(values[self.big]) >= self.factor * PARAMS[self.small].to_raw(values[self.small])

    def text(self) -> str:
        return f"{PARAMS[self.big].name} ≥ {self.factor} × {PARAMS[self.small].name}"

    def now_text(self, values: Mapping[Param, float | str | bool]) -> str:
        """The two values as they would be, e.g. "50 ms < 2 × 100 ms"."""
        big, small = PARAMS[self.big], PARAMS[self.small]
        unit = f" {big.unit}" if big.unit else ""
        return (f"{big.text(values[self.big])}{unit} < {self.factor} × {small.text(values[self.small])}"
                f"{' ' + small.unit if small.unit else ''}")


def broken_rules(values: Mapping[Param, float | str | bool]) -> list[ParamRule]:
    """The rules of ``PARAM_RULES`` that ``values`` break."""
    return [r for r in PARAM_RULES if not r.holds(values)]


def rule_order(values: Mapping[Param, float | str | bool],
               now: Mapping[Param, float | str | bool]) -> list[Param]:
    """The order to set ``values`` one by one over ``now`` (the board's) so that no step breaks a rule the end keeps:
    for each rule, the side that makes room goes first (a longer timeout before a longer heartbeat, a shorter
    heartbeat before a shorter timeout)."""
    order = list(values)
    for rule in PARAM_RULES:
        if rule.big not in values or rule.small not in values or rule.big not in now:
            continue
        grows = PARAMS[rule.big].to_raw(values[rule.big]) >= PARAMS[rule.big].to_raw(now[rule.big])
        first, second = (rule.big, rule.small) if grows else (rule.small, rule.big)
        if order.index(first) > order.index(second):
            order.remove(first)
            order.insert(order.index(second), first)
    return order


def _decimals(scale: float) -> int:
    d = 0
    while d < 9 and abs(round(scale * 10**d) - scale * 10**d) > 1e-9:
        d += 1
    return d


def _p(param: Param, name: str, kind: str, unit: str, default: float | str | bool, doc: str,
       **kw: Any) -> ParamSpec:
    return ParamSpec(param, name, kind, unit, default, doc, **kw)


# The one parameter table: the board's defaults come from here, the terminal's screen and files, docs/parameters.md.
PARAMS: dict[Param, ParamSpec] = {p.param: p for p in (
    _p(Param.YAW_P, "ctrl.yaw_p", "float", "ae²/LSB", 800.0, "yaw-rate P (Table 1: magnitude of -800)",
       lo=0, hi=5000, scale=0.01, step=50.0),
    _p(Param.P1, "ctrl.p1", "float", "LSB/LSB", 0.4, "roll/pitch angle P1: rate set point per angle error "
       "(Table 1: 0.4)", lo=0, hi=10, scale=0.0001, step=0.05),
    _p(Param.P2, "ctrl.p2", "float", "ae²/LSB", 111.0, "roll/pitch rate P2 (Table 1: magnitude of 111 and -111)",
       lo=0, hi=1000, scale=0.01, step=5.0),
    _p(Param.HEIGHT_P, "ctrl.height_p", "float", "ae²/mm", 400.0, "height P around the set point (HEIGHT)",
       lo=0, hi=5000, scale=0.1, step=10.0),
    _p(Param.HEIGHT_D, "ctrl.height_d", "float", "ae²/(mm/s)", 400.0, "height D on the vertical speed (HEIGHT)",
       lo=0, hi=5000, scale=0.1, step=10.0),
    _p(Param.HEIGHT_I, "ctrl.height_i", "float", "ae²/(mm·s)", 100.0, "height I: takes out the battery's sag "
       "(0: the report's PD)", lo=0, hi=1000, scale=0.1, step=5.0),
    _p(Param.ATTITUDE_FILTER, "est.attitude", "enum", "", "ikf", "RAW path attitude filter: complementary (report "
       "eq. 1, K from est.k_gyro), kalman and kalman-cov (Table 2), qgate, ikf (ours)", choices=ATTITUDE_FILTERS,
       in_flight=False),
    _p(Param.K_GYRO, "est.k_gyro", "float", "", 0.999, "the complementary filter's K_gyro (report: 0.999 flown, "
       "0.9 in Table 2)", lo=0.5, hi=0.99999, scale=0.00001, in_flight=False),
    _p(Param.FIXED_POINT, "est.fixed_point", "bool", "", True, "RAW filter in fixed point: ikf's variant that "
       "fits the Cortex-M0, the report's filters in Q16.16 (qgate has none)", in_flight=False),
    _p(Param.HEIGHT_ESTIMATOR, "est.height", "enum", "", "kalman", "height estimator: complementary (the "
       "report's Figure 10) or kalman (robust to the barometer's spikes)", choices=HEIGHT_ESTIMATORS,
       in_flight=False),
    _p(Param.SENSOR_PATH, "est.sensor_path", "enum", "", "auto", "sensor path: auto follows the mode (RAW in "
       "RAW), dmp, raw", choices=SENSOR_PATHS),
    _p(Param.SCHEDULER, "sched.scheduler", "enum", "", "round-robin", "task scheduler: round-robin (the "
       "report's) or priority", choices=SCHEDULERS),
    _p(Param.STICK_REACTION, "sched.stick_reaction", "bool", "", True, "a changed stick moves the motors in the "
       "parse task (false: only the control step, as the report's firmware)", in_flight=False),
    _p(Param.LINK_TIMEOUT_MS, "link.timeout_ms", "int", "ms", 500, "link silence longer than this in a flight "
       "mode: stage 1 of the failsafe (hold level; only shorter in flight); at least 2 × link.heartbeat_ms (rule "
       "timeout-spans-heartbeats)", lo=50, hi=60000, shorter_in_flight=True, step=50),
    _p(Param.LINK_FAILSAFE_MS, "link.failsafe_ms", "int", "ms", 1000, "stage 1's guard time: the link back within "
       "it gives control back, else PANIC (0: PANIC at once, the report's; only shorter in flight)", lo=0,
       hi=10000, shorter_in_flight=True, step=100),
    _p(Param.TELEMETRY_HZ, "link.telemetry_hz", "float", "Hz", 50.0, "Attitude and Motion rate over the UART "
       "(the report's: 0.52, a run every 1.9 s, Figure 14)", lo=0.1, hi=100, scale=0.01, step=5.0),
    _p(Param.HEARTBEAT_MS, "link.heartbeat_ms", "int", "ms", 100, "the board's Heartbeat period, and its safety "
       "monitor's (the report's: 325, Figure 14); at most half of link.timeout_ms (rule timeout-spans-heartbeats)",
       lo=20, hi=1000, in_flight=False),
    _p(Param.QUEUE_RULE, "link.queue_rule", "enum", "", "bounded", "the receive queue: bounded (what does not "
       "fit is dropped) or discard-20 (the report's: the whole queue goes at 20 frames)", choices=QUEUE_RULES,
       in_flight=False),
    _p(Param.LOG_SCHEME, "log.scheme", "enum", "", "rice", "flash-log compression; needs an empty log (else "
       "Nak.LOG_BUSY)", choices=tuple(SCHEME_NAMES[k] for k in sorted(SCHEME_NAMES)), base=min(SCHEME_NAMES),
       in_flight=False),
    _p(Param.TRIM_STEP, "trim.step", "int", "stick", 256, "roll, pitch and yaw trim per key press (0.8 %)",
       lo=1, hi=4096, step=32),
    _p(Param.LIFT_STEP, "trim.lift_step", "int", "stick", 328, "lift trim per key press (1 %); a quarter of it "
       "while the lift is in 40-60 %, near hover (LIFT_FINE_*)", lo=1, hi=4096, step=32),
    _p(Param.CALIBRATION_MS, "mode.calibration_ms", "int", "ms", 1000, "CALIBRATION averages this long, then "
       "returns to SAFE by itself (0: for as long as the pilot holds it, the report's, section 3.6)", lo=0,
       hi=60000, step=100),
    _p(Param.PANIC_COUNTDOWN_MS, "mode.panic_countdown_ms", "int", "ms", 0, "PANIC: 0 descends at a bounded rate "
       "until the ground is sensed (ours); else holds a level just under hover for this long, then motors off (the "
       "report's countdown, section 3.2)", lo=0, hi=60000, in_flight=False),
)}
PARAM_BY_NAME: dict[str, ParamSpec] = {p.name: p for p in PARAMS.values()}

# The link's timings in seconds, from the table (the board's link.timeout_ms and link.heartbeat_ms): the terminal's
# LINK LOST, `fcb-sim serve --link-timeout` and the config file's link_timeout take their default and range here.
LINK_TIMEOUT_S: float = PARAMS[Param.LINK_TIMEOUT_MS].default / 1000
LINK_TIMEOUT_RANGE_S: tuple[float, float] = (PARAMS[Param.LINK_TIMEOUT_MS].lo / 1000,
                                             PARAMS[Param.LINK_TIMEOUT_MS].hi / 1000)
HEARTBEAT_S: float = PARAMS[Param.HEARTBEAT_MS].default / 1000
# The rules between parameters (as data: firmware/gen_c.py can emit them for the C board), each stated in both
# parameters' docs.
PARAM_RULES: tuple[ParamRule, ...] = (
    ParamRule("timeout-spans-heartbeats", Param.LINK_TIMEOUT_MS, 2, Param.HEARTBEAT_MS,
              "the link timeout spans two heartbeat periods: one late heartbeat is no LINK LOST (a timeout under "
              "the period fails safe over and over on a healthy link)"),
)
# The gain keys (u/j, i/k, o/l, t/g, y/h) step these parameters by their ``step``.
GAIN_OPS: dict[int, Param] = {Op.GAIN_YAW_P: Param.YAW_P, Op.GAIN_P1: Param.P1, Op.GAIN_P2: Param.P2,
                              Op.GAIN_HEIGHT_P: Param.HEIGHT_P, Op.GAIN_HEIGHT_D: Param.HEIGHT_D}


def param_arg(param: int, raw: int) -> int:
    """``Command.arg`` for ``Op.SET_PARAM`` (and ``EventCode.PARAM_CHANGED``'s arg): the id (1..127) in the top 8
    bits, the raw value as a signed 24-bit number in the low 24."""
    if not 0 <= int(param) <= 0x7F or not -_RAW_MAX - 1 <= raw <= _RAW_MAX:
        raise ValueError(f"SET_PARAM {param}={raw}: id must be 0..127 and the raw value a signed 24-bit number")
    return (int(param) << PARAM_RAW_BITS) | (raw & ((1 << PARAM_RAW_BITS) - 1))


def param_split(arg: int) -> tuple[int, int]:
    """The (id, raw value) inside a ``SET_PARAM`` arg (the inverse of ``param_arg``)."""
    raw = arg & ((1 << PARAM_RAW_BITS) - 1)
    if raw > _RAW_MAX:
        raw -= 1 << PARAM_RAW_BITS
    return (arg >> PARAM_RAW_BITS) & 0xFF, raw


# The report starts a countdown on entering PANIC (section 3.2) but gives no length; 3.5 s is the fixed-level time
# this project's board held before the rate-bounded descent (fcb_sim/board/flight.py, issue 10.4; DESIGN: "a few
# seconds").
REPORT_PANIC_COUNTDOWN_MS = 3500

# Presets: whole sets of values by name (a value per parameter it changes; the rest keep their defaults).
PRESETS: dict[str, dict[Param, float | str | bool]] = {
    "default": {},  # the team's best: every parameter at its default
    "report": {  # the board of the lab report: Table 1's gains, the complementary filter flown (K_gyro 0.999), the
        # Figure 10 height estimator on the gains it was tuned for (PD, no integral), round robin, the report's
        # queue rule, no stick reaction (only the control step moves the motors), and the link timeout's PANIC at
        # once (no failsafe stage 1)
        Param.YAW_P: 800.0, Param.P1: 0.4, Param.P2: 111.0,
        Param.ATTITUDE_FILTER: "complementary", Param.K_GYRO: 0.999, Param.FIXED_POINT: False,
        Param.HEIGHT_ESTIMATOR: "complementary", Param.HEIGHT_P: 120.0, Param.HEIGHT_D: 320.0, Param.HEIGHT_I: 0.0,
        Param.SCHEDULER: "round-robin", Param.STICK_REACTION: False, Param.QUEUE_RULE: "discard-20",
        Param.LINK_FAILSAFE_MS: 0,
        # the report's telemetry period (1.9 s) and heartbeat period (324-327 ms) of Figure 14, its delta log
        # (section 3.5), calibration for as long as it is held (3.6), PANIC's countdown (3.2; docs/deviations.md)
        # its link timeout is not given: 650 ms is the shortest the rule timeout-spans-heartbeats allows
        Param.TELEMETRY_HZ: 0.52, Param.HEARTBEAT_MS: 325, Param.LINK_TIMEOUT_MS: 650, Param.LOG_SCHEME: "delta8",
        Param.CALIBRATION_MS: 0,
        Param.PANIC_COUNTDOWN_MS: REPORT_PANIC_COUNTDOWN_MS,
    },
}


def preset_values(name: str) -> dict[Param, float | str | bool]:
    """Every parameter's value in preset ``name`` (KeyError, naming the presets, for an unknown one)."""
    if name not in PRESETS:
        raise KeyError(f"unknown preset {name!r}; known: {', '.join(PRESETS)}")
    return {p: PRESETS[name].get(p, spec.default) for p, spec in PARAMS.items()}
