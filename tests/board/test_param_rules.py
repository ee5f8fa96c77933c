"""Rules between parameters (issue 34): the protocol's table holds them as data (``PARAM_RULES``); the Python board
refuses a set that breaks one with ``Nak.PARAM_RULE`` and the rule's index as the Ack's value; a preset keeps them;
both parameters' docs state each rule; the terminal's model names the rule in the refusal it shows."""

from __future__ import annotations

from fcb_sim.board.board import Board, BoardConfig
from fcb_sim.board.commands import execute
from fcb_sim.board.param_bindings import apply_values, get_value
from term.core.link import CommandFailed
from term.core.protocol import (
    PARAM_RULES,
    PARAMS,
    PRESETS,
    Command,
    Mode,
    Nak,
    Op,
    Param,
    broken_rules,
    param_arg,
    preset_values,
)
from term.session.model import Model


def cmd(board: Board, op: Op, arg: int = 0) -> tuple[Nak, int]:
    status, value, after = execute(board.parts, Command(1, op, arg))
    if after is not None:
        after()
    return Nak(status), value


def test_the_link_timeout_spans_two_heartbeats() -> None:
    rule = next(r for r in PARAM_RULES if r.big == Param.LINK_TIMEOUT_MS and r.small == Param.HEARTBEAT_MS)
    assert rule.factor >= 2
    index = PARAM_RULES.index(rule)
    board = Board(BoardConfig(boot_hello=False))  # timeout 500 ms, heartbeat 100 ms
    # the set: 50 ms under a 100 ms heartbeat
    assert cmd(board, Op.SET_PARAM, param_arg(Param.LINK_TIMEOUT_MS, 50)) == (Nak.PARAM_RULE, index)
    assert cmd(board, Op.SET_PARAM, param_arg(Param.LINK_TIMEOUT_MS, 199))[0] == Nak.PARAM_RULE
    assert cmd(board, Op.SET_PARAM, param_arg(Param.LINK_TIMEOUT_MS, 200))[0] == Nak.OK  # 2 x 100: kept
    # the other side of the rule: a heartbeat longer than half the timeout
    assert cmd(board, Op.SET_PARAM, param_arg(Param.HEARTBEAT_MS, 101)) == (Nak.PARAM_RULE, index)
    assert get_value(board.parts, Param.HEARTBEAT_MS) == 100 and get_value(board.parts, Param.LINK_TIMEOUT_MS) == 200
    # in flight too (the timeout may shrink there, never under the rule)
    board.modes.mode = Mode.FULL
    assert cmd(board, Op.SET_PARAM, param_arg(Param.LINK_TIMEOUT_MS, 150))[0] == Nak.PARAM_RULE


def test_a_preset_keeps_the_rules_and_a_set_that_breaks_them_falls_back() -> None:
    for name in PRESETS:
        assert broken_rules(preset_values(name)) == [], name
        board = Board(BoardConfig(preset=name, boot_hello=False))
        values = {p: get_value(board.parts, p) for p in PARAMS}
        assert broken_rules(values) == [], name
    board = Board(BoardConfig(boot_hello=False))
    refused = apply_values(board.parts, {Param.HEARTBEAT_MS: 400, Param.LINK_TIMEOUT_MS: 500})
    assert (Param.LINK_TIMEOUT_MS, Nak.PARAM_RULE) in refused
    assert broken_rules({p: get_value(board.parts, p) for p in PARAMS}) == []
    # a set passing through a broken rule on its way is fine when it ends whole (the order of a file)
    assert apply_values(board.parts, {Param.HEARTBEAT_MS: 400, Param.LINK_TIMEOUT_MS: 900}) == []


def test_both_parameters_docs_state_each_rule() -> None:
    for rule in PARAM_RULES:
        for p in (rule.big, rule.small):
            assert rule.name in PARAMS[p].doc, (rule.name, PARAMS[p].name)


def test_the_terminal_names_the_rule_the_board_refused() -> None:
    model = Model(start=0.0)
    model.params = {s.name: s.default for s in PARAMS.values()}
    arg = param_arg(Param.LINK_TIMEOUT_MS, 50)
    model.apply(CommandFailed(7, Op.SET_PARAM, arg, "breaks a rule between parameters", Nak.PARAM_RULE), 1.0)
    said = model.param_refused["link.timeout_ms"]
    assert "link.timeout_ms ≥ 2 × link.heartbeat_ms" in said and "50 ms < 2 × 100 ms" in said, said
    assert any("link.timeout_ms ≥ 2 × link.heartbeat_ms" in e.text for e in model.events)


def test_a_refused_mode_says_from_which_mode() -> None:
    model = Model(start=0.0)
    model.mode = Mode.MANUAL
    model.apply(CommandFailed(8, Op.MODE, Mode.FULL, "not allowed from the current mode", Nak.INVALID_TRANSITION),
                1.0)
    assert any("NAK mode FULL: not allowed from MANUAL" in e.text for e in model.events), [e.text for e in
                                                                                         model.events]


def test_a_set_of_values_is_sent_in_an_order_that_keeps_the_rules() -> None:
    from term.core.protocol import rule_order

    board = Board(BoardConfig(boot_hello=False))  # timeout 500, heartbeat 100
    now = {p: get_value(board.parts, p) for p in PARAMS}
    for values in ({Param.HEARTBEAT_MS: 400, Param.LINK_TIMEOUT_MS: 900},  # both longer: the timeout first
                   {Param.LINK_TIMEOUT_MS: 120, Param.HEARTBEAT_MS: 50}):  # both shorter: the heartbeat first
        for p in rule_order(values, now):
            assert cmd(board, Op.SET_PARAM, param_arg(p, PARAMS[p].to_raw(values[p])))[0] == Nak.OK, (p, values)
        now = {p: get_value(board.parts, p) for p in PARAMS}
