"""Freshness as a property of the model (term.core.freshness): every figure knows the time of the packet behind it, goes
stale after a few of its packet's periods, says when the current link does not carry it, and is shown as a bound
at its field's limit. A property test feeds every field's whole range (its extremes included) through the model
and every panel: no exception, no figure outside its field's range unmarked."""

from __future__ import annotations

import functools
import math

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from term.core.freshness import SOURCES, STALE_FLOOR_S, STALE_PERIODS, Arrivals, age_text, next_age_change
from term.core.link import CommandAcked
from term.core.protocol import (
    SPEC_OF,
    Attitude,
    Compact,
    Compact2,
    Flag,
    Gains,
    Height,
    Mode,
    Motion,
    Op,
    Status,
    WirelessState,
    field_limits,
    field_scale,
    field_spec,
    lift_trim_after,
)
from term.session.model import Model
from term.ui.widgets.base import figure

TELEMETRY = (Attitude, Motion, Height, Status, Gains, Compact, Compact2)


def _attitude(mode: int = Mode.MANUAL, phi: int = 0) -> Attitude:
    return Attitude(int(mode), phi, 0, 0, 0, 0, 0)


def test_each_packet_learns_its_period_and_a_gap_is_not_one() -> None:
    a = Arrivals()
    assert a.limit(Status) == STALE_PERIODS * 0.25  # nothing yet: the assumed period
    for i in range(20):
        a.note(Status(0, 0, 0, 0, 0, 0, 0, 0), 0.2 * i)
    assert math.isclose(a.limit(Status), STALE_PERIODS * 0.2, rel_tol=1e-6)
    a.note(Status(0, 0, 0, 0, 0, 0, 0, 0), 100.0)  # back after a long silence (a handover)
    assert math.isclose(a.limit(Status), STALE_PERIODS * 0.2, rel_tol=1e-6)
    for i in range(20):
        a.note(_attitude(), 0.02 * i)
    assert a.limit(Attitude) == STALE_FLOOR_S  # fast packets: the floor


def _raw(cls: type, name: str, value: float) -> int:
    """``value`` (in the shown unit) in the field's wire unit, whatever the table says it is."""
    return round(value / field_scale(cls, name))


def test_a_figure_goes_stale_with_its_age_and_says_so() -> None:
    m = Model(start=0.0)
    for i in range(10):
        m.apply_packet(Height(101325, _raw(Height, "height", 1.5), 0, 0, 1200, 2500), 0.05 * i)
    r = m.reading("height", 0.5)
    assert math.isclose(r.value, 1.5) and r.unit == "m" and r.fresh and r.mark == "" and r.source == "Height"
    r = m.reading("height", 3.45)
    assert r.stale and r.carried and r.mark == "3 s old" and r.shown
    assert str(figure(r, "+6.2f", " m")) == " +1.50 m" and figure(r, "+6.2f").style == "dim"
    assert not m.reading("ae1", 1.0).known  # never received


def test_over_ble_the_pilot_sees_what_the_radio_carries() -> None:
    m = Model(start=0.0, radio_name="ble")
    m.apply_packet(Height(101325, 1500, 0, 0, 1200, 2500), 0.0)
    m.apply_packet(_attitude(phi=1000), 0.0)
    m.apply_packet(Status(0, 0, 0, 0, 0, 0, 0, 0), 0.0)
    m.radio_up = True
    m.apply_packet(Compact(int(Mode.MANUAL), int(WirelessState.STARTED), 500, 0, 0, 1150), 1.0)
    assert m.over_ble
    phi, battery, pressure = m.reading("phi", 1.0), m.reading("battery", 1.0), m.reading("pressure", 70.0)
    assert phi.value == 5.0 and phi.source == "Compact" and battery.value == 11.5 and battery.fresh
    assert pressure.stale and not pressure.carried and not pressure.shown
    assert pressure.mark == "not over BLE (last 70 s ago)" and str(figure(pressure, "6.0f", " Pa")) == "     — Pa"
    # Height is carried over BLE (Compact2): until one comes, the cable's last height is shown as old, not hidden.
    height = m.reading("height", 70.0)
    assert height.stale and height.carried and height.shown and height.mark == "70 s old"
    # Trims: the board's Ack of a trim command carries the new trim, over BLE too.
    m.apply(CommandAcked(7, Op.TRIM_LIFT, 1, 18040), 1.1)
    lift = m.reading("trim_lift", 1.2)
    assert lift.value == 18040 and lift.source == "Ack" and lift.fresh and lift.carried
    roll = m.reading("trim_roll", 1.2)
    assert roll.source == "Status" and roll.stale and not roll.shown  # not carried: not shown as a number
    # Compact2 over BLE: motors (in steps of 4), height, set point, vz, flags and the lift trim, fresh.
    m.apply_packet(Compact2(100, 101, 99, 250, 123, 150, -45, int(Flag.ARMED | Flag.CALIBRATED), 3280), 1.5)
    got = {n: m.reading(n, 1.6) for n in ("ae1", "ae2", "ae3", "ae4", "height", "setpoint", "vz", "flags",
                                            "trim_lift")}
    assert all(r.fresh and r.carried and r.source == "Compact2" for r in got.values()), got
    assert [got[f"ae{i}"].value for i in range(1, 5)] == [400, 404, 396, 1000]
    assert math.isclose(got["height"].value, 1.23) and math.isclose(got["vz"].value, -0.45)
    assert got["trim_lift"].value == 3280 and m.flags == Flag.ARMED | Flag.CALIBRATED
    assert not m.reading("sp", 1.6).shown and not m.reading("cpu_load", 1.6).shown  # still cable-only figures
    # Back on the cable: Status is the freshest again.
    m.apply_packet(Status(0, 0, 0, 0, 18040, 0, 0, int(WirelessState.DISCONNECTED)), 2.0)
    assert not m.over_ble and m.reading("trim_lift", 2.0).source == "Status"


def test_a_value_at_its_fields_limit_is_a_bound() -> None:
    m = Model(start=0.0)
    hi, lo = field_limits(Height, "height")[1], field_limits(Height, "setpoint")[0]  # type: ignore[index]
    m.apply_packet(Height(101325, hi, lo, 0, 1200, 2500), 0.0)
    h, sp = m.reading("height", 0.0), m.reading("setpoint", 0.0)
    assert h.bound == ">" and sp.bound == "<" and m.reading("vz", 0.0).bound == ""
    shown_h, shown_sp = str(figure(h, "+6.2f", " m")), str(figure(sp, "+6.2f", " m"))
    assert shown_h.startswith(">+") and shown_sp.startswith("<-") and shown_h.endswith(" m")
    # rounded toward the limit, so the bound stays true: "> 32.76" for 32.767, never "> 32.77"
    assert h.edge - 0.01 < float(shown_h[1:-2]) <= h.edge and sp.edge <= float(shown_sp[1:-2]) < sp.edge + 0.01
    m.apply_packet(Gains(float("nan"), float("inf"), float("-inf"), 1.0, 2.0), 0.0)
    assert str(figure(m.reading("yaw_p", 0.0), ".4g")) == "?"
    assert str(figure(m.reading("p1", 0.0), ".4g")).startswith(">")
    assert str(figure(m.reading("p2", 0.0), ".4g")).startswith("<")
    assert age_text(0.6) == "<1 s" and age_text(99.9) == "99 s" and age_text(250) == "4 min"
    assert age_text(7200) == "2 h" and next_age_change(3.25) == 0.75 and next_age_change(250) == 50


# --- the property: any telemetry value, through the model and every panel ----------------------------------------


@functools.cache  # one strategy per format: Hypothesis checks each new strategy object on its first draw
def _field_values(fmt: str) -> st.SearchStrategy:
    if fmt == "e":
        return st.one_of(st.sampled_from([65504.0, -65504.0, 0.0, math.inf, -math.inf, math.nan]),
                         st.floats(-65504.0, 65504.0, width=16))
    lo, hi = {"B": (0, 0xFF), "h": (-0x8000, 0x7FFF), "H": (0, 0xFFFF), "I": (0, 0xFFFFFFFF),
              "i": (-0x80000000, 0x7FFFFFFF), "b": (-0x80, 0x7F)}[fmt]
    return st.one_of(st.sampled_from([lo, hi, 0]), st.integers(lo, hi))


@functools.cache
def packets() -> st.SearchStrategy:
    """Any telemetry packet, any value in each of its fields."""
    return st.one_of([st.builds(cls, *(_field_values(fs.fmt) for fs in SPEC_OF[cls].fields)) for cls in TELEMETRY])


def _panels() -> list:
    from term.ui.screens.wireless import PhoneTelemetry
    from term.ui.widgets.battery import BatteryGauge
    from term.ui.widgets.controls import ControlsPanel
    from term.ui.widgets.horizon import HeadingTape, Horizon
    from term.ui.widgets.link import LinkPanel
    from term.ui.widgets.mode import ModeBanner
    from term.ui.widgets.motors import MotorBars
    from term.ui.widgets.pressure import PressureIndicator
    from term.ui.widgets.rates import RateGauges

    return [ModeBanner(), Horizon(), HeadingTape(), RateGauges(), MotorBars(), BatteryGauge(), PressureIndicator(),
            ControlsPanel(), LinkPanel(), PhoneTelemetry()]


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(packets(), min_size=1, max_size=6), st.booleans(), st.floats(0.0, 100.0))
def test_any_telemetry_through_the_model_and_every_panel(pkts: list, over_ble: bool, later: float) -> None:
    m = Model(start=0.0, radio_name="ble", radio_up=over_ble)
    for i, pkt in enumerate(pkts):
        m.apply_packet(pkt, 0.01 * i)
    now = 0.01 * len(pkts) + later
    for name, kinds in SOURCES.items():
        r = m.reading(name, now)
        if not r.known:
            continue
        spec = field_spec(kinds[0], name)
        lo, hi = spec.limits  # type: ignore[misc]
        value = r.value
        assert r.bound or (lo * spec.scale <= value <= hi * spec.scale) or (spec.scale < 0), (name, r)
        if isinstance(value, float) and math.isnan(value):
            assert r.bound == "?"
        assert r.fresh == (r.age <= r.limit) and (r.mark == "") == (r.fresh or not r.known)
    for w in _panels():
        text = str(w.render_model(m, now))
        shown = " ".join((text, str(w.border_subtitle or "")))
        for r in w.readings.values():
            if r.shown and r.bound in (">", "<"):
                assert r.bound in text, (type(w).__name__, r)
            if r.stale:
                assert r.mark in shown, (type(w).__name__, r, shown)


def test_lift_trims_flown_over_ble_are_shown_as_the_board_has_them() -> None:
    """Issue 10's +18040: 55 lift-trim presses over BLE (1 % each) while the screen showed the cable's last Status
    (trim +0) and motors 0, unmarked. The board reports each new trim in its Ack; the model shows that (fresh),
    what the second BLE frame carries (motors, height: Compact2) is fresh and the board's, and what BLE does not
    carry (rates, pressure) is not shown as a number."""
    from fcb_sim.board.board import Board, BoardConfig
    from fcb_sim.world.physics import World
    from term.core.link import LinkSession
    from term.session.station import RADIO_SESSION

    board = Board(BoardConfig(seed=1), world=World(1))
    cable, phone = LinkSession(0.0), LinkSession(0.0, **RADIO_SESSION)  # type: ignore[arg-type]
    m = Model(start=0.0, radio_name="ble")
    board.uart_receive(cable.hello())
    presses, shown = 0, []
    t_us = 0
    while t_us < 9_000_000:
        t_us += 1000
        t = t_us / 1e6
        if t_us == 200_000:
            board.ble_connected()
            m.radio_up = True
        elif t_us == 500_000:
            cable.send_command(Op.WIRELESS, 1, t)
        elif t_us == 1_200_000:
            phone.send_command(Op.MODE, Mode.MANUAL, t)
        elif 1_500_000 <= t_us and t_us % 100_000 == 0 and presses < 55:
            phone.send_command(Op.TRIM_LIFT, 1, t)
            presses += 1
        board.advance(t_us)
        for ev in cable.receive(board.uart_transmit(), t) + cable.poll(t):
            m.apply(ev, t)
        for ev in phone.receive(b"".join(board.wireless.notifications()), t) + phone.poll(t):
            m.radio_event(ev, t)
            if type(ev) is CommandAcked and ev.op == Op.TRIM_LIFT:
                shown.append((m.reading("trim_lift", t).value, board.modes.trims.lift))
        board.uart_receive(cable.data_to_send(t))
        board.ble_receive(phone.data_to_send(t))
    assert m.over_ble and m.mode == Mode.MANUAL and len(shown) == 55
    # every press, as the board has it (finer near hover: the protocol's lift_trim_after)
    assert all(a == b for a, b in shown) and shown[-1][1] == lift_trim_after(0, 55, shown[0][1])
    motors, height, rate = m.reading("ae1", t), m.reading("height", t), m.reading("sp", t)
    assert motors.fresh and motors.source == "Compact2" and abs(motors.value - board.ae[0]) <= 2  # steps of 4
    # the board's estimate, less what it climbed since it was sampled (up to a heartbeat period in the BLE batch)
    assert height.fresh and height.source == "Compact2"
    assert abs(height.value - board.core.height) <= abs(board.core.vz) * (height.age + 0.1) + 0.01
    assert not rate.shown and rate.mark.startswith("not over BLE")
    assert m.reading("phi", t).fresh and m.reading("battery", t).fresh  # what the radio carries


def test_over_ble_the_controls_panel_names_what_is_not_carried() -> None:
    """Over BLE the flags are fresh (Compact2) while the CPU load and log fill are not carried: the panel's border
    names those, not the flags."""
    from term.ui.widgets.controls import ControlsPanel

    m = Model(start=0.0, radio_name="ble")
    m.apply_packet(Status(int(Flag.CALIBRATED), 0, 0, 0, 0, 40, 3, 0), 0.0)
    m.apply_packet(Gains(800.0, 0.4, 111.0, 400.0, 400.0), 0.0)
    m.radio_up = True
    m.apply_packet(Compact(int(Mode.MANUAL), int(WirelessState.STARTED), 0, 0, 0, 1150), 5.0)
    m.apply_packet(Compact2(40, 40, 40, 40, 0, 0, 0, int(Flag.CALIBRATED | Flag.ARMED), 0), 5.0)
    w = ControlsPanel()
    text = str(w.render_model(m, 5.1))
    assert "ARMED" in text and "flags" not in str(w.border_subtitle)
    assert str(w.border_subtitle) == "trims, gains, cpu, log: not over BLE (last 5 s ago)"


def test_a_panel_of_two_packets_names_each_age() -> None:
    """Over BLE the pressure panel mixes the cable's pressure (not carried) and Compact2's height: when both are
    old, the border names each figure's age, not only the first."""
    from term.ui.widgets.pressure import PressureIndicator

    m = Model(start=0.0, radio_name="ble")
    m.apply_packet(Height(101325, 100, 0, 0, 1150, 2500), 0.0)
    m.radio_up = True
    m.apply_packet(Compact(int(Mode.MANUAL), int(WirelessState.STARTED), 0, 0, 0, 1150), 8.0)
    m.apply_packet(Compact2(40, 40, 40, 40, 150, 0, 3, 0, 0), 8.0)  # then BLE stalls
    w = PressureIndicator()
    w.render_model(m, 10.5)
    # (in MANUAL the set point is not in force: no figure, so no age for it)
    assert str(w.border_subtitle) == "pressure, temperature: not over BLE (last 10 s ago) · height, vz: 2 s old"
