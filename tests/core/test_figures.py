"""Issue 22, one meaning per figure: what the panels print for a value (term/ui/widgets/base.py ``figure`` and the
panels' lines), fast and without the app: no negative zero, gains as the parameter table rounds them."""

from __future__ import annotations

import pytest
from rich.text import Text

from term.core.freshness import Reading
from term.ui.widgets.base import figure
from term.ui.widgets.controls import _gains_line


def fresh(name: str, value: float) -> Reading:
    return Reading(name, value, age=0.0)


@pytest.mark.parametrize("value, spec, unit, want", [
    (-0.3, "+6.0f", "°/s", "    +0°/s"),
    (-0.0, "+6.0f", "°/s", "    +0°/s"),
    (-0.04, "+5.1f", "°", " +0.0°"),
    (-0.004, "+6.2f", " m", " +0.00 m"),
    (-0.004, "6.2f", " m", "  0.00 m"),
    (-0.4, "5d", "", "    0"),
    (-0.06, "+5.1f", "°", " -0.1°"),  # a real negative stays negative
])
def test_no_figure_reads_minus_zero(value: float, spec: str, unit: str, want: str) -> None:
    assert figure(fresh("x", value), spec, unit).plain == want


def test_the_gains_line_rounds_as_the_parameter_table() -> None:
    """P1 0.3999 in the gains line where the events, F11 and `term params list` say 0.4 (a float32 on the wire)."""
    out = Text()
    _gains_line(out, [fresh("yaw_p", 800.0000001), fresh("p1", 0.39990000128746033), fresh("p2", 110.99999237060547),
                      fresh("height_p", 400.0), fresh("height_d", 399.99998)])
    assert out.plain == "gains  yaw P 800  P1 0.4  P2 111  height P 400  D 400\n"


def test_the_set_point_is_shown_only_while_height_hold_is_in_force() -> None:
    """Issue 22: `set pt (HEIGHT mode) +3.40 m` stayed on screen in SAFE and FULL long after HEIGHT ended."""
    from term.core.protocol import Attitude, Height, Mode, field_scale
    from term.session.model import Model
    from term.ui.widgets.pressure import PressureIndicator

    def raw(name: str, value: float) -> int:
        return round(value / field_scale(Height, name))

    m = Model(start=0.0)
    m.apply_packet(Attitude(int(Mode.HEIGHT), 0, 0, 0, 0, 0, 0), 0.0)
    m.apply_packet(Height(101300, raw("height", 3.3), raw("setpoint", 3.4), 0, 1200, 2150), 0.0)
    panel = PressureIndicator()
    assert "+3.40 m" in panel.render_model(m, 0.1).plain
    m.apply_packet(Attitude(int(Mode.SAFE), 0, 0, 0, 0, 0, 0), 0.2)
    m.apply_packet(Height(101300, 0, raw("setpoint", 3.4), 0, 1200, 2150), 0.2)
    text = panel.render_model(m, 0.3).plain
    assert "3.40" not in text and "set pt" in text


def stats(rtt_last: float | None, rtt_mean: float | None, heartbeat_ago: float | None):  # noqa: ANN201
    from term.core.link import LinkStats

    return LinkStats(rtt_last, rtt_mean, rtt_mean, 0.0, 0.0, 100.0, 100.0, 10, 0, 0.01, heartbeat_ago, 1.0, False,
                     1000, 1000, 5, 0, 0, 10, 1)


def test_one_rtt_and_none_for_an_idle_link() -> None:
    """Issue 22: `▶ cable OK, RTT 244 ms`, `cable RTT 79.2 ms` and `link up cable (RTT 27 ms)` on one screen; an RTT
    shown for a silent cable and an idle radio; `RTT 0 ms` over BLE."""
    from term.session.model import Model
    from term.session.phone import link_states
    from term.session.readiness import checks
    from term.session.texts import rtt_text

    assert rtt_text(stats(244.0, 27.4, 0.05)) == "RTT 27 ms"  # the heartbeat's round trip, its recent mean
    assert rtt_text(stats(5.0, 0.2, 0.05)) == "RTT <1 ms"
    assert rtt_text(stats(30.0, 36.0, 2.5)) == "" and rtt_text(stats(None, None, 0.05)) == ""  # idle: none
    m = Model(start=0.0, link_name="cable")
    m.link = stats(244.0, 27.4, 0.05)
    said = [s.state for s in link_states(m)] + [c.text for c in checks(m, 0.0, ()) if c.item == "link"]
    assert all("RTT 27 ms" in s for s in said) and not any("244" in s for s in said), said
    m.link = stats(244.0, 36.0, 3.0)  # the cable silent for 3 s
    said = [s.state for s in link_states(m)] + [c.text for c in checks(m, 0.0, ()) if c.item == "link"]
    assert not any("RTT" in s for s in said), said
