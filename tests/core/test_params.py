"""The parameter table (term/core/protocol/ PARAMS), its wire packing, the terminal's parsing and files
(term/session/param_client.py),
and the board's side (fcb_sim/board/param_bindings.py, the SET_PARAM / PARAM_GET / PARAM_LIST handlers): the board
starts from the table's defaults, refuses with the right reason, reports every change as an event."""

from __future__ import annotations

import math
from pathlib import Path

import pytest
from hypothesis import given
from hypothesis import strategies as st

from fcb_sim.board.board import Board, BoardConfig
from fcb_sim.board.commands import execute
from fcb_sim.board.param_bindings import BINDINGS, build_filter, get_value, preset_core
from fcb_sim.board.uart import Uart
from fcb_sim.estimation.height import make_height_estimator
from term.core.protocol import (
    ATTITUDE_FILTERS,
    HEIGHT_ESTIMATORS,
    PARAMS,
    PRESETS,
    Command,
    Event,
    EventCode,
    Joystick,
    Mode,
    Nak,
    Op,
    Param,
    ParamValue,
    decode_frame,
    encode,
    param_arg,
    param_split,
    preset_values,
)
from term.session.model import Model
from term.session.param_client import ParamError, diff, from_toml, line, load_file, parse_text, spec_by_name, to_toml


def test_every_parameter_is_whole() -> None:
    names = [s.name for s in PARAMS.values()]
    assert len(set(names)) == len(names) and set(PARAMS) == set(Param) and set(BINDINGS) == set(Param)
    for spec in PARAMS.values():
        group, _, key = spec.name.partition(".")
        assert group in ("ctrl", "est", "sched", "link", "log", "trim", "mode") and key, spec.name
        assert spec.kind in ("int", "float", "bool", "enum") and spec.doc
        assert spec.accepts(spec.to_raw(spec.default)), spec.name  # the default is a value the board accepts
        lo, hi = spec.raw_range
        assert -(1 << 23) <= lo <= hi < (1 << 23), spec.name  # fits the 24-bit raw field
        assert spec.from_raw(spec.to_raw(spec.default)) == spec.default


def test_the_issue_asks_for_these_names() -> None:
    for name in ("ctrl.p1", "ctrl.p2", "ctrl.yaw_p", "ctrl.height_p", "ctrl.height_d", "est.attitude", "est.height",
                 "est.k_gyro", "sched.scheduler", "link.timeout_ms", "link.telemetry_hz", "log.scheme",
                 "link.queue_rule", "trim.step", "trim.lift_step"):
        assert spec_by_name(name)


@given(st.sampled_from(list(Param)), st.integers(-(1 << 23), (1 << 23) - 1))
def test_the_packing_round_trips(param: Param, raw: int) -> None:
    arg = param_arg(param, raw)
    assert -(1 << 31) <= arg < (1 << 31) and param_split(arg) == (int(param), raw)
    cmd = Command(1, Op.SET_PARAM, arg)
    assert decode_frame(encode(cmd)) == cmd


def test_presets_name_real_values() -> None:
    assert set(PRESETS) == {"default", "report"}
    for name in PRESETS:
        for p, v in preset_values(name).items():
            assert PARAMS[p].accepts(PARAMS[p].to_raw(v)), (name, p)
    report = preset_values("report")
    assert report[Param.ATTITUDE_FILTER] == "complementary" and report[Param.K_GYRO] == 0.999
    assert report[Param.HEIGHT_ESTIMATOR] == "complementary" and report[Param.SCHEDULER] == "round-robin"
    assert (report[Param.YAW_P], report[Param.P1], report[Param.P2]) == (800.0, 0.4, 111.0)  # Table 1's magnitudes
    with pytest.raises(KeyError):
        preset_values("nope")


@pytest.mark.parametrize("name, text, value", [
    ("ctrl.p1", "0.45", 0.45), ("ctrl.p1", " 1e-1 ", 0.1), ("link.timeout_ms", "750", 750),
    ("est.attitude", "kalman", "kalman"), ("est.fixed_point", "on", True), ("est.fixed_point", "false", False),
])
def test_parse_text(name: str, text: str, value: object) -> None:
    assert parse_text(spec_by_name(name), text) == value


@pytest.mark.parametrize("name, text, words", [
    ("ctrl.p1", "99", "ctrl.p1 must be a number from 0 to 10 LSB/LSB, got \"99\""),
    ("ctrl.p1", "nan", "got \"nan\""), ("ctrl.p1", "inf", "must be a number"), ("ctrl.p1", "-0.1", "from 0"),
    ("ctrl.p1", "abc", "must be a number"), ("ctrl.p1", "", "must be a number"),
    ("link.timeout_ms", "750.5", "a whole number"), ("link.timeout_ms", "10", "from 50 to 60000 ms"),
    ("est.attitude", "kalmann", "(did you mean 'kalman'?)"), ("est.fixed_point", "maybe", "true or false"),
    ("ctrl.p1", "0.4\x00", "must be a number"),
])
def test_bad_values_are_one_line(name: str, text: str, words: str) -> None:
    with pytest.raises(ParamError) as exc:
        parse_text(spec_by_name(name), text)
    assert words in str(exc.value) and "\n" not in str(exc.value)


def test_unknown_names_suggest_the_nearest() -> None:
    with pytest.raises(ParamError, match=r"no parameter 'ctrl\.p11' \(did you mean 'ctrl\.p1'\?\)"):
        spec_by_name("ctrl.p11")


def test_files_round_trip_and_diff(tmp_path: Path) -> None:
    values = preset_values("report")
    path = tmp_path / "report.toml"
    path.write_text(to_toml(values, "the report's board"), encoding="utf-8")
    text = path.read_text(encoding="utf-8")
    assert text.startswith("# the report's board") and "[ctrl]\n" in text and 'attitude = "complementary"' in text
    assert load_file(path) == values
    assert [PARAMS[p].name for p in diff(values, preset_values("default"))] == [
        "ctrl.height_d", "ctrl.height_i", "ctrl.height_p", "est.attitude", "est.fixed_point", "est.height",
        "link.failsafe_ms",
        "link.heartbeat_ms", "link.queue_rule", "link.telemetry_hz", "link.timeout_ms", "log.scheme",
        "mode.calibration_ms",
        "mode.panic_countdown_ms", "sched.stick_reaction"]


@pytest.mark.parametrize("text, words", [
    ("[ctrl]\np11 = 0.4\n", "no parameter 'ctrl.p11' (did you mean 'ctrl.p1'?)"),
    ("[ctrl]\np1 = \"0.4\"\n", "ctrl.p1 must be a number"),
    ("[ctrl]\np1 = 40.0\n", "from 0 to 10"),
    ("[est]\nfixed_point = 1\n", "true or false"),
    ("p1 = 0.4\n", "parameters go in tables"),
    ("[ctrl\n", "not valid TOML"),
    ("[ctrl]\np1 = nan\n", "got nan"),
])
def test_bad_files_are_one_line(tmp_path: Path, text: str, words: str) -> None:
    path = tmp_path / "bad.toml"
    path.write_text(text, encoding="utf-8")
    with pytest.raises(ParamError) as exc:
        load_file(path)
    assert words in str(exc.value) and str(path) in str(exc.value) and "\n" not in str(exc.value)


def test_bad_bytes_and_missing_files(tmp_path: Path) -> None:
    (tmp_path / "b.toml").write_bytes(b"[ctrl]\np1 = \xff\n")
    with pytest.raises(ParamError, match="not UTF-8"):
        load_file(tmp_path / "b.toml")
    with pytest.raises(ParamError, match="cannot read"):
        load_file(tmp_path / "none.toml")
    assert from_toml({}, "x") == {}


def test_the_list_line_marks_what_changed() -> None:
    spec = spec_by_name("ctrl.p1")
    assert line(spec, 0.4).startswith("  ctrl.p1") and "(default 0.4)" in line(spec, 0.4)
    assert line(spec, 0.45).startswith("* ctrl.p1") and "LSB/LSB" in line(spec, 0.45)


# --- the board's side ---------------------------------------------------------------------------------------------


def test_a_fresh_board_reads_the_tables_defaults() -> None:
    board = Board(BoardConfig())
    for p, spec in PARAMS.items():
        assert get_value(board.parts, p) == spec.default, spec.name
    assert board.modes.config.lift_step == PARAMS[Param.LIFT_STEP].default


def test_the_report_preset_boots_the_reports_board() -> None:
    board = Board(BoardConfig(preset="report"))
    for p, v in preset_values("report").items():
        assert get_value(board.parts, p) == v, PARAMS[p].name
    assert type(board.core.height_est).__name__ == "HeightEstimator"  # the Figure 10 complementary estimator
    assert board.core.filter.k_gyro == 0.999 and not board.config.stick_reaction and board.uart.discard_at_frames


def test_every_filter_and_estimator_the_table_names_exists() -> None:
    for name in ATTITUDE_FILTERS:
        assert build_filter(name, 0.99, False) is not None
    for name in HEIGHT_ESTIMATORS:
        assert make_height_estimator(name) is not None
    assert preset_core("report").filter_name == "complementary"


def cmd(board: Board, op: Op, arg: int = 0) -> tuple[Nak, int]:
    status, value, after = execute(board.parts, Command(1, op, arg))
    if after is not None:
        after()
    return status, value


def events(board: Board) -> list[Event]:
    return [p for p in _sent(board) if type(p) is Event]


def _sent(board: Board) -> list[object]:
    from term.core.protocol import Decoder

    board.advance(board.now + 200_000)
    return Decoder().feed(board.uart_transmit())


def test_set_get_list_and_the_change_event() -> None:
    board = Board(BoardConfig(boot_hello=False))
    assert cmd(board, Op.SET_PARAM, param_arg(Param.P1, 4500)) == (Nak.OK, 4500)
    assert board.core.gains.p1 == 0.45 and cmd(board, Op.PARAM_GET, Param.P1) == (Nak.OK, 4500)
    changed = [e for e in events(board) if e.code == EventCode.PARAM_CHANGED]
    assert [param_split(e.arg) for e in changed] == [(Param.P1, 4500)]
    assert cmd(board, Op.GAIN_P1, +1)[0] == Nak.OK  # a gain key steps the same parameter, and says so
    changed = [param_split(e.arg) for e in events(board) if e.code == EventCode.PARAM_CHANGED]
    assert changed == [(Param.P1, 5000)]  # 0.45 + the table's step 0.05
    status, count = cmd(board, Op.PARAM_LIST)
    values = [p for p in _sent(board) if type(p) is ParamValue]
    assert status == Nak.OK and count == len(PARAMS) == len(values)
    assert [v.index for v in values] == list(range(count)) and {v.count for v in values} == {count}
    assert {v.param: v.value for v in values}[Param.P1] == 5000


@pytest.mark.parametrize("param, raw, nak", [
    (99, 1, Nak.UNKNOWN_PARAM),
    (Param.P1, 100_001, Nak.OUT_OF_RANGE),
    (Param.LINK_TIMEOUT_MS, 49, Nak.OUT_OF_RANGE),
    (Param.ATTITUDE_FILTER, len(ATTITUDE_FILTERS), Nak.OUT_OF_RANGE),
])
def test_refusals(param: int, raw: int, nak: Nak) -> None:
    board = Board(BoardConfig(boot_hello=False))
    assert cmd(board, Op.SET_PARAM, param_arg(param, raw))[0] == nak
    assert cmd(board, Op.PARAM_GET, 99)[0] == Nak.UNKNOWN_PARAM


def test_safe_only_parameters_are_refused_in_flight_and_gains_are_not() -> None:
    board = Board(BoardConfig(boot_hello=False))
    board.modes.mode = Mode.FULL  # (as if flying)
    assert cmd(board, Op.SET_PARAM, param_arg(Param.ATTITUDE_FILTER, 0))[0] == Nak.NOT_IN_SAFE
    assert cmd(board, Op.SET_PARAM, param_arg(Param.P2, 12000))[0] == Nak.OK
    assert board.core.filter_name == "ikf" and board.core.gains.p2 == 120.0


def test_the_parameters_own_rules() -> None:
    board = Board(BoardConfig(boot_hello=False))
    qgate = PARAMS[Param.ATTITUDE_FILTER].to_raw("qgate")
    # fixed point is the default (ikf's variant that fits the M0): qgate, float only, needs it off first
    assert cmd(board, Op.SET_PARAM, param_arg(Param.ATTITUDE_FILTER, qgate))[0] == Nak.BAD_ARGUMENT
    assert cmd(board, Op.SET_PARAM, param_arg(Param.FIXED_POINT, 0))[0] == Nak.OK
    assert cmd(board, Op.SET_PARAM, param_arg(Param.ATTITUDE_FILTER, qgate))[0] == Nak.OK
    assert cmd(board, Op.SET_PARAM, param_arg(Param.FIXED_POINT, 1))[0] == Nak.BAD_ARGUMENT  # no fixed-point qgate
    board.log.start()
    board.log.append(tuple(range(len(board.log.variables))))
    delta8 = PARAMS[Param.LOG_SCHEME].to_raw("delta8")
    assert cmd(board, Op.SET_PARAM, param_arg(Param.LOG_SCHEME, delta8))[0] == Nak.LOG_BUSY
    k = PARAMS[Param.K_GYRO].to_raw(0.9)
    comp = PARAMS[Param.ATTITUDE_FILTER].to_raw("complementary")
    assert cmd(board, Op.SET_PARAM, param_arg(Param.ATTITUDE_FILTER, comp))[0] == Nak.OK
    assert cmd(board, Op.SET_PARAM, param_arg(Param.K_GYRO, k))[0] == Nak.OK
    assert board.core.filter.k_gyro == 0.9  # type: ignore[attr-defined]


def test_trim_steps_are_the_boards_parameters() -> None:
    board = Board(BoardConfig(boot_hello=False))
    assert cmd(board, Op.SET_PARAM, param_arg(Param.LIFT_STEP, 82))[0] == Nak.OK
    assert cmd(board, Op.TRIM_LIFT, 2) == (Nak.OK, 164)
    assert cmd(board, Op.TRIM_ROLL, -1) == (Nak.OK, -256)


def test_the_reports_queue_rule_discards_at_20_frames() -> None:
    uart = Uart()
    frame = encode(Joystick(0, 0, 0, 0, 0))
    uart.receive(frame * 19, 0)
    assert len(uart.rx) == 19 * len(frame)  # bounded: keeps them
    uart.discard_at_frames = 20
    uart.receive(frame, 0)
    assert not uart.rx and uart.rx_discarded == 20 * len(frame)  # the report's rule: the whole queue goes


def test_the_terminal_model_follows_the_boards_parameters() -> None:
    m = Model()
    m.apply_packet(ParamValue(Param.P1, 4000, 0, 19), 1.0)
    m.apply_packet(Event(EventCode.PARAM_CHANGED, param_arg(Param.P1, 4500), 1000), 2.0)
    assert m.params["ctrl.p1"] == 0.45 and m.events[-1].text.endswith("param ctrl.p1: 0.45 LSB/LSB (default 0.4)")
    for raw in (5000, 5500):  # a gain key held: one line, the latest value, a count
        m.apply_packet(Event(EventCode.PARAM_CHANGED, param_arg(Param.P1, raw), 1000), 3.0)
    assert [e.count for e in m.events] == [3] and "0.55" in m.events[-1].text
    assert m.trim_steps() == (None, None)
    m.apply_packet(ParamValue(Param.LIFT_STEP, 164, 1, 19), 4.0)
    assert m.trim_steps()[0] == 164
    assert not math.isnan(m.params["trim.lift_step"])


def test_the_gain_map_is_the_protocols() -> None:
    """One home for gain op <-> parameter <-> name: GAIN_OPS; the board's Gains fields, its key handlers and its
    parameter bindings all follow it (issue 20)."""
    from dataclasses import fields

    from fcb_sim.board.commands import COMMANDS, GAIN_NAMES
    from fcb_sim.world.constants import GAIN_PARAMS, Gains
    from term.core.protocol import GAIN_OPS, STEP_OPS

    assert set(GAIN_PARAMS) == {f.name for f in fields(Gains)}
    assert set(GAIN_PARAMS.values()) == set(GAIN_OPS.values()) and set(GAIN_OPS) <= STEP_OPS
    assert all(op in COMMANDS for op in GAIN_OPS) and all(p in BINDINGS for p in GAIN_OPS.values())
    board = Board(BoardConfig(boot_hello=False))
    for op, param in GAIN_OPS.items():
        before = get_value(board.parts, param)
        status, value, _after = execute(board.parts, Command(1, op, 1))
        assert status == Nak.OK and get_value(board.parts, param) == before + PARAMS[param].step
        assert value == round(getattr(board.core.gains, GAIN_NAMES[param]) * 1000)


def test_a_value_that_overflows_when_scaled_is_a_param_error_not_an_overflow(tmp_path) -> None:  # noqa: ANN001
    """Issue 21: ``p1 = 1e308`` in a parameter file raised OverflowError (its raw value is infinite) at the
    board's Hello, inside the link's read path."""
    from term.session.param_client import ParamError, load_file

    f = tmp_path / "huge.toml"
    f.write_text("[ctrl]\np1 = 1e308\n", encoding="utf-8")
    with pytest.raises(ParamError, match="ctrl.p1 must be"):
        load_file(f)
