"""Hostile values for the board's parameters (issue 23): every surface (the CLI's ``term params set``, a parameter
file, the parameter screen's text, the board's gain keys) parses a number once, strictly, in one place
(``ParamSpec.check`` / ``ParamSpec.parse`` in term/core/protocol/params.py), and refuses in one line naming the field.
"""

from __future__ import annotations

import math
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from fcb_sim.board.board import Board, BoardConfig
from fcb_sim.board.commands import execute
from fcb_sim.board.param_bindings import get_value
from term.core.protocol import GAIN_OPS, PARAM_BY_NAME, PARAMS, Command, Nak, Op, Param, param_arg
from term.session.param_client import ParamError, load_file, parse_text


def _one_line(exc: BaseException, name: str) -> None:
    msg = str(exc)
    assert "\n" not in msg and name in msg and len(msg) < 300, msg


@pytest.mark.parametrize("name", ["ctrl.p1", "ctrl.height_d", "ctrl.yaw_p", "link.timeout_ms", "est.k_gyro"])
@pytest.mark.parametrize("text", ["1e308", "-1e308", "1e999", "9" * 400, "-" + "9" * 400, "nan", "inf", "1e-30",
                                  "１", "1_0", "0x10", "1e", " ", "", "0.4\n", "\x00", "٣", "1,5"])
def test_typed_numbers_are_refused_in_one_line(name: str, text: str) -> None:
    spec = PARAM_BY_NAME[name]
    with pytest.raises(ParamError) as info:
        parse_text(spec, text)
    _one_line(info.value, name)


def test_a_value_finer_than_the_wire_is_refused_not_rounded() -> None:
    spec = PARAM_BY_NAME["ctrl.p1"]
    with pytest.raises(ParamError, match="ctrl.p1"):
        parse_text(spec, "1e-30")
    with pytest.raises(ParamError, match="0.0001"):
        parse_text(spec, "0.12345")
    assert parse_text(spec, "0.45") == 0.45 and parse_text(spec, " 0.4 ") == 0.4
    assert parse_text(PARAM_BY_NAME["est.k_gyro"], "0.999") == 0.999


@pytest.mark.parametrize("text", ["kalman\n", "kalman ", "\tkalman", "ｋalman", "kalman\x00"])
def test_enum_text_must_be_exact(text: str) -> None:
    spec = PARAM_BY_NAME["est.attitude"]
    if text.strip(" ") == "kalman":
        assert parse_text(spec, text) == "kalman"  # spaces a pilot typed around a word are fine
        return
    with pytest.raises(ParamError, match="est.attitude"):
        parse_text(spec, text)


@pytest.mark.parametrize("body", [
    "[ctrl]\np1 = 1e308\n", "[ctrl]\nheight_d = 1e308\n", "[ctrl]\np1 = " + "9" * 400 + "\n",
    "[ctrl]\np1 = -" + "9" * 400 + "\n", "[ctrl]\np1 = 1e-30\n", '[est]\nattitude = "kalman\\n"\n',
    "[ctrl]\np1 = " + "[" * 3000 + "]" * 3000 + "\n", "[ctrl]\np1 = " + "{a=" * 2000 + "1" + "}" * 2000 + "\n",
    "[ctrl]\np1 = nan\n", "[ctrl]\np1 = true\n", "[link]\ntimeout_ms = 500.5\n",
], ids=lambda body: body[:30])
def test_parameter_files_are_refused_in_one_line(tmp_path: Path, body: str) -> None:
    f = tmp_path / "p.toml"
    f.write_text(body)
    with pytest.raises(ParamError) as info:
        load_file(f)
    _one_line(info.value, str(f))


def test_a_good_file_still_loads(tmp_path: Path) -> None:
    f = tmp_path / "p.toml"
    f.write_text('[ctrl]\np1 = 0.45\np2 = 120\n[est]\nattitude = "kalman"\n[link]\ntimeout_ms = 500\n')
    assert load_file(f) == {Param.P1: 0.45, Param.P2: 120.0, Param.ATTITUDE_FILTER: "kalman",
                            Param.LINK_TIMEOUT_MS: 500}


def test_to_raw_never_overflows() -> None:
    for spec in PARAMS.values():
        if spec.kind in ("int", "float"):
            for v in (1e308, -1e308, 10**400):
                with pytest.raises(ValueError):
                    spec.to_raw(v)


@settings(max_examples=300, deadline=None)
@given(st.sampled_from(sorted(PARAM_BY_NAME)), st.one_of(
    st.text(max_size=30), st.floats().map(repr), st.integers().map(str),
    st.from_regex(r"[+-]?[0-9_]{0,400}(\.[0-9]*)?([eE][+-]?[0-9]{1,4})?", fullmatch=True)))
def test_any_typed_text_is_a_value_or_one_line(name: str, text: str) -> None:
    spec = PARAM_BY_NAME[name]
    try:
        value = parse_text(spec, text)
    except ParamError as exc:
        _one_line(exc, name)
        return
    raw = spec.to_raw(value)
    assert spec.accepts(raw)
    if spec.kind in ("int", "float"):
        assert math.isfinite(value) and spec.lo <= value <= spec.hi and spec.from_raw(raw) == value


_toml_values = st.one_of(st.floats(), st.integers(), st.booleans(), st.text(max_size=10),
                         st.integers(0, 5000).map(lambda n: "[" * n + "]" * n))


@settings(max_examples=200, deadline=None)
@given(st.sampled_from(sorted(PARAM_BY_NAME)), _toml_values)
def test_any_file_value_is_a_value_or_one_line(tmp_path_factory: pytest.TempPathFactory, name: str,
                                               value: object) -> None:
    group, key = name.split(".")
    if isinstance(value, str) and value.startswith("["):
        text = value
    elif isinstance(value, bool):
        text = "true" if value else "false"
    elif isinstance(value, float):
        text = {"nan": "nan", "inf": "inf", "-inf": "-inf"}.get(repr(value), repr(value))
    elif isinstance(value, str):
        text = '"' + value.encode("unicode_escape").decode().replace('"', '\\"') + '"'
    else:
        text = str(value)
    f = tmp_path_factory.mktemp("p") / "p.toml"
    f.write_text(f"[{group}]\n{key} = {text}\n")
    try:
        values = load_file(f)
    except ParamError as exc:
        _one_line(exc, str(f))
        return
    for p, v in values.items():
        assert PARAMS[p].accepts(PARAMS[p].to_raw(v))


# --- the gain keys: one writer with SET_PARAM ------------------------------------------------------------------

@pytest.mark.parametrize("param", sorted(GAIN_OPS.values()))
def test_gain_keys_stop_at_the_tables_range(param: Param) -> None:
    """Enough presses of a gain key passed the limit SET_PARAM enforces (P2 0..1000): now both go through the table's
    range and the same setter, so the keys stop at hi and at lo, and say the value the board holds."""
    board = Board(BoardConfig(boot_hello=False))
    op = next(op for op, p in GAIN_OPS.items() if p == param)
    spec = PARAMS[param]
    for _ in range(3):
        execute(board, Command(1, op, 1_000_000))  # a stepping arg merges many presses into one command
    assert get_value(board, param) == spec.hi
    status, _, _ = execute(board, Command(1, Op.SET_PARAM, param_arg(param, spec.to_raw(spec.hi))))
    assert status == Nak.OK
    for _ in range(3):
        execute(board, Command(1, op, -1_000_000))
    assert get_value(board, param) == spec.lo


# --- the command lines: ASCII digits, no separators ------------------------------------------------------------

@pytest.mark.parametrize("argv", [["--baud", "1_200", "--serial", "/dev/null"], ["--baud", "１２００", "--sim"],
                                  ["--link-timeout", "0.５", "--sim"], ["--seed", "1_0", "--sim"],
                                  ["scan", "--timeout", "３"], ["--lesson", "٣", "--sim"]])
def test_term_options_take_ascii_numbers_only(capsys: pytest.CaptureFixture[str], argv: list[str]) -> None:
    from term.cli.main import main

    code = main(argv)
    err = capsys.readouterr().err
    assert code == 2 and argv[-2 if argv[0] == "scan" else 0] in err and err.count("\n") == 1, err


@pytest.mark.parametrize("argv", [["run", "--duration", "1_0"], ["run", "--seed", "１"],
                                  ["serve", "--pty", "--link-timeout", "0.５"]])
def test_fcb_sim_options_take_ascii_numbers_only(capsys: pytest.CaptureFixture[str], argv: list[str]) -> None:
    from fcb_sim.cli import main

    try:
        code = main(argv)
    except SystemExit as exc:
        code = int(exc.code or 0)
    err = capsys.readouterr().err
    assert code == 2 and "invalid" in err and err.count("\n") == 1, err


@settings(max_examples=300, deadline=None)
@given(st.text(max_size=50) | st.floats().map(repr) | st.integers().map(str)
       | st.from_regex(r"[+-]?[0-9_١１]{0,60}(\.[0-9]*)?([eE][+-]?[0-9]{1,5})?", fullmatch=True))
def test_any_option_text_is_a_number_or_argparses_one_line(text: str) -> None:
    import argparse

    from term.core.protocol.numbers import cli_float, cli_int

    for parse in (cli_float, cli_int):
        try:
            value = parse(text)
        except argparse.ArgumentTypeError as exc:
            assert "\n" not in str(exc) and len(str(exc)) < 100
            continue
        t = text.strip(" ")
        assert t.isascii() and "_" not in t and isinstance(value, int | float)


def test_the_flight_cores_own_gain_step_keeps_the_tables_range_too() -> None:
    from fcb_sim.board.flight import FlightCore

    core = FlightCore()
    assert core.adjust_gain("p2", 1_000_000) == PARAMS[Param.P2].hi
    assert core.adjust_gain("p2", -1_000_000) == PARAMS[Param.P2].lo
