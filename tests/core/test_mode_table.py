"""The mode table (term/core/protocol/modes.py) is the one place a mode's face is written: the key map, the footer,
the phone's buttons, the banner and FLIGHT_MODES read it (and the board's transitions agree with its flight
column)."""

from __future__ import annotations

from fcb_sim.board.modes import TRANSITIONS, ZERO_LIFT
from term.core.protocol import FLIGHT_MODES, MODE_TABLE, Mode, Op
from term.input.keymap import DEFAULT_KEYMAP
from term.session import phone
from term.ui import app
from term.ui.widgets.mode import STYLE


def test_every_mode_has_one_row_and_no_key_twice() -> None:
    assert set(MODE_TABLE) == set(Mode)
    keys = [k for spec in MODE_TABLE.values() for k in spec.keys]
    assert len(keys) == len(set(keys))


def test_the_key_map_binds_each_modes_keys_to_its_mode() -> None:
    bound = {b.action.name: b for b in DEFAULT_KEYMAP}
    for spec in MODE_TABLE.values():
        if not spec.keys:
            assert spec.action not in bound
            continue
        b = bound[spec.action]
        assert b.keys == spec.keys and b.action.op == Op.MODE and b.action.arg == spec.mode
        assert b.action.description == spec.help


def test_the_footer_the_phone_and_the_banner_read_the_table() -> None:
    for spec in MODE_TABLE.values():
        assert app.FOOTER_LABELS.get(spec.action) == (spec.label if spec.keys else None)
        assert ((spec.label, spec.action) in phone.MODE_BUTTONS) == spec.phone
        assert STYLE[spec.mode] == spec.style
    assert next(iter(app.FOOTER_LABELS)) == "mode_panic"  # the way out first


def test_flight_modes_are_the_tables_and_the_boards() -> None:
    assert FLIGHT_MODES == {m for m, s in MODE_TABLE.items() if s.flight}
    # the board lands every flight mode with zero lift (the transition table's SAFE rows), and only those
    assert FLIGHT_MODES == {t.source for t in TRANSITIONS
                            if t.target == Mode.SAFE and t.trigger == "request" and t.guards == (ZERO_LIFT,)}
