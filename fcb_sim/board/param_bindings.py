"""The board's parameters: each row of the protocol's table (``term.core.protocol.PARAMS``) bound to where the board
keeps it (its parts, ``fcb_sim.board.parts.BoardParts``), read and written in the table's units. The table is the one
source of truth: its defaults are the board's (``BoardConfig``, ``constants.Gains``, ``ModeConfig``'s trim steps come
from it; a test checks a fresh board reads them back), its ranges are what ``set_value`` accepts, its ``in_flight``
says what may change outside SAFE.

- ``get_raw(parts, param)`` / ``get_value``: the value in force;
- ``set_raw(parts, param, raw)``: the guards in order (unknown id: ``Nak.UNKNOWN_PARAM``; out of the table's range:
  ``Nak.OUT_OF_RANGE``; a SAFE-only parameter in another mode: ``Nak.NOT_IN_SAFE``; the parameter's own rule: the
  log scheme needs an empty log, ``Nak.LOG_BUSY``; a filter without a fixed-point twin in fixed point,
  ``Nak.BAD_ARGUMENT``; a rule between parameters broken, ``Nak.PARAM_RULE``: ``broken_rule`` names it), then the
  change; the caller reports it (``EventCode.PARAM_CHANGED``);
- ``apply_values(parts, values)``: a preset or a file at boot (SAFE: every guard but the mode's applies; the rules
  are checked on the whole set, after it: a set whose order passes through a broken rule is fine if it ends whole).

An attitude filter or height estimator changed by name is built afresh (the filter converges on the ground in
SAFE; the height estimator is re-anchored at the calibration's pressure).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping

from fcb_sim.board.flash_log import FlashLog
from fcb_sim.board.flight import FlightCore
from fcb_sim.board.parts import BoardParts
from fcb_sim.estimation import has_fixed_point, make_filter
from fcb_sim.estimation.complementary import ComplementaryFilter, ComplementaryFilterQ16
from fcb_sim.estimation.height import make_height_estimator
from fcb_sim.world import constants as P
from term.core.protocol import PARAM_RULES, PARAMS, Mode, Nak, Param, ParamRule, preset_values

Value = float | str | bool
Getter = Callable[[BoardParts], Value]
Setter = Callable[[BoardParts, Value], Nak]


def _gain(name: str) -> tuple[Getter, Setter]:
    def get(b: BoardParts) -> Value:
        return float(getattr(b.core.gains, name))

    def put(b: BoardParts, v: Value) -> Nak:
        setattr(b.core.gains, name, float(v))
        return Nak.OK

    return get, put


def _config(name: str, convert: Callable[[Value], Value] = lambda v: v) -> tuple[Getter, Setter]:
    def get(b: BoardParts) -> Value:
        return getattr(b.config, name)

    def put(b: BoardParts, v: Value) -> Nak:
        setattr(b.config, name, convert(v))
        return Nak.OK

    return get, put


def build_filter(name: str, k_gyro: float, fixed_point: bool) -> object:
    """The RAW path's filter by the table's name; the complementary filter takes the table's K_gyro."""
    if name == "complementary":
        return ComplementaryFilterQ16(k_gyro) if fixed_point else ComplementaryFilter(k_gyro)
    return make_filter(name, fixed_point=fixed_point)


def _refilter(b: BoardParts, name: str, k_gyro: float, fixed: bool) -> Nak:
    if fixed and name != "complementary" and not has_fixed_point(name):
        return Nak.BAD_ARGUMENT  # no fixed-point twin of this filter
    core = b.core
    core.filter = build_filter(name, k_gyro, fixed)  # type: ignore[assignment]
    core.filter_name, core.k_gyro, core.fixed_point = name, k_gyro, fixed
    b.config.fixed_point = fixed
    return Nak.OK


def _k_gyro(b: BoardParts) -> float:
    return b.core.k_gyro


def _set_filter(b: BoardParts, v: Value) -> Nak:
    return _refilter(b, str(v), _k_gyro(b), b.config.fixed_point)


def _set_k_gyro(b: BoardParts, v: Value) -> Nak:
    return _refilter(b, b.core.filter_name, float(v), b.config.fixed_point)


def _set_fixed(b: BoardParts, v: Value) -> Nak:
    return _refilter(b, b.core.filter_name, _k_gyro(b), bool(v))


def _height_name(b: BoardParts) -> Value:
    return b.core.height_name


def _set_height(b: BoardParts, v: Value) -> Nak:
    core = b.core
    old = core.height_est
    core.height_est = make_height_estimator(str(v))
    carry = getattr(core.height_est, "carry_thrust_model", None)
    if carry is not None and type(old) is type(core.height_est):
        carry(old)  # the craft's thrust model goes on (the C board resets its one estimator, keeping it)
    core.height_name = str(v)
    if core.calibrated:
        core.height_est.reset(core.calibration.pressure)
    core.height = core.vz = 0.0
    return Nak.OK


def _set_scheduler(b: BoardParts, v: Value) -> Nak:
    b.set_scheduler(str(v))
    return Nak.OK


def _set_timeout(b: BoardParts, v: Value) -> Nak:
    b.config.link_timeout_s = b.modes.config.link_timeout_s = float(v) / 1000
    return Nak.OK


def _set_calibration(b: BoardParts, v: Value) -> Nak:
    b.modes.config.calibration_s = float(v) / 1000  # 0: for as long as the pilot holds CALIBRATION
    return Nak.OK


def _set_countdown(b: BoardParts, v: Value) -> Nak:
    b.modes.config.panic_countdown_s = float(v) / 1000
    b.core.panic_hold = v != 0  # the report's PANIC: a fixed level, no descent loop
    return Nak.OK


def _set_failsafe(b: BoardParts, v: Value) -> Nak:
    b.config.link_failsafe_s = b.modes.config.link_failsafe_s = float(v) / 1000
    return Nak.OK


def _set_queue_rule(b: BoardParts, v: Value) -> Nak:
    b.config.queue_rule = str(v)
    b.apply_queue_rule()
    return Nak.OK


def _set_log_scheme(b: BoardParts, v: Value) -> Nak:
    if b.log.used:
        return Nak.LOG_BUSY
    b.log = FlashLog(size=b.log.flash.size, scheme=str(v), variables=b.log.variables)
    b.config.log_scheme = str(v)
    return Nak.OK


def _mode_config(name: str) -> tuple[Getter, Setter]:
    def get(b: BoardParts) -> Value:
        return getattr(b.modes.config, name)

    def put(b: BoardParts, v: Value) -> Nak:
        setattr(b.modes.config, name, int(v))
        return Nak.OK

    return get, put


BINDINGS: dict[Param, tuple[Getter, Setter]] = {
    **{param: _gain(name) for name, param in P.GAIN_PARAMS.items()},
    Param.HEIGHT_I: (lambda b: float(b.core.height_i), lambda b, v: setattr(b.core, "height_i", float(v)) or Nak.OK),
    Param.ATTITUDE_FILTER: (lambda b: b.core.filter_name, _set_filter),
    Param.K_GYRO: (_k_gyro, _set_k_gyro),
    Param.FIXED_POINT: (lambda b: bool(b.config.fixed_point), _set_fixed),
    Param.HEIGHT_ESTIMATOR: (_height_name, _set_height),
    Param.SENSOR_PATH: _config("sensor_path", str),
    Param.SCHEDULER: (lambda b: b.config.scheduler, _set_scheduler),
    Param.STICK_REACTION: _config("stick_reaction", bool),
    Param.LINK_TIMEOUT_MS: (lambda b: round(b.config.link_timeout_s * 1000), _set_timeout),
    Param.LINK_FAILSAFE_MS: (lambda b: round(b.config.link_failsafe_s * 1000), _set_failsafe),
    Param.TELEMETRY_HZ: _config("telemetry_hz", float),
    Param.HEARTBEAT_MS: _config("heartbeat_ms", int),
    Param.CALIBRATION_MS: (lambda b: round(b.modes.config.calibration_s * 1000), _set_calibration),
    Param.PANIC_COUNTDOWN_MS: (lambda b: round(b.modes.config.panic_countdown_s * 1000), _set_countdown),
    Param.QUEUE_RULE: (lambda b: b.config.queue_rule, _set_queue_rule),
    Param.LOG_SCHEME: (lambda b: b.config.log_scheme, _set_log_scheme),
    Param.TRIM_STEP: _mode_config("trim_step"),
    Param.LIFT_STEP: _mode_config("lift_step"),
}


def get_value(parts: BoardParts, param: Param) -> Value:
    return BINDINGS[param][0](parts)


def get_raw(parts: BoardParts, param: Param) -> int:
    return PARAMS[param].to_raw(get_value(parts, param))


def broken_rule(parts: BoardParts, param: Param, raw: int) -> int | None:
    """The index in ``PARAM_RULES`` of the first rule ``param`` = ``raw`` would break with the values in force."""
    for i, rule in enumerate(PARAM_RULES):
        if param in (rule.big, rule.small) and not _rule_holds(parts, rule, {param: raw}):
            return i
    return None


def _rule_holds(parts: BoardParts, rule: ParamRule, raws: Mapping[Param, int]) -> bool:
    def raw(p: Param) -> int:
        return raws[p] if p in raws else get_raw(parts, p)

    return raw(rule.big) >= rule.factor * raw(rule.small)


def set_raw(parts: BoardParts, pid: int, raw: int, *, mode_guard: bool = True,
            rule_guard: bool = True) -> tuple[Nak, Param | None]:
    """Set parameter ``pid`` to ``raw`` if every guard passes; (Nak.OK or the reason, the Param if known)."""
    try:
        param = Param(pid)
    except ValueError:
        return Nak.UNKNOWN_PARAM, None
    spec = PARAMS[param]
    if not spec.accepts(raw):
        return Nak.OUT_OF_RANGE, param
    if mode_guard and parts.modes.mode != Mode.SAFE:
        if not spec.in_flight:
            return Nak.NOT_IN_SAFE, param
        if spec.shorter_in_flight and raw > get_raw(parts, param):
            return Nak.ONLY_SHORTER_IN_FLIGHT, param  # a link timeout may not grow (or go off) in flight
    if rule_guard and broken_rule(parts, param, raw) is not None:
        return Nak.PARAM_RULE, param
    return BINDINGS[param][1](parts, spec.from_raw(raw)), param


def apply_values(parts: BoardParts, values: Mapping[Param, Value]) -> list[tuple[Param, Nak]]:
    """Set each parameter (a preset, a file); returns the ones refused, with why."""
    refused = []
    for param, value in values.items():
        nak, _ = set_raw(parts, param, PARAMS[param].to_raw(value), mode_guard=False, rule_guard=False)
        if nak != Nak.OK:
            refused.append((param, nak))
    for rule in PARAM_RULES:  # the whole set keeps the rules, or the table's defaults of the two come back
        if not _rule_holds(parts, rule, {}):
            for p in (rule.big, rule.small):
                BINDINGS[p][1](parts, PARAMS[p].default)
                refused.append((p, Nak.PARAM_RULE))
    return refused


def preset_core(name: str) -> FlightCore:
    """A flight core with preset ``name``'s gains, filter and height estimator (term.core.protocol.PRESETS): the
    scenarios and bench.flight fly the report's board on it without a whole Board."""
    values = preset_values(name)
    gains = P.Gains(**{g: float(values[p]) for g, p in P.GAIN_PARAMS.items()})
    fixed = bool(values[Param.FIXED_POINT])
    core = FlightCore(gains=gains, filter_name=str(values[Param.ATTITUDE_FILTER]), fixed_point=fixed,
                      height_name=str(values[Param.HEIGHT_ESTIMATOR]))
    core.filter = build_filter(str(values[Param.ATTITUDE_FILTER]), float(values[Param.K_GYRO]),  # type: ignore
                               fixed)
    core.k_gyro = float(values[Param.K_GYRO])
    core.height_i = float(values[Param.HEIGHT_I])
    return core
