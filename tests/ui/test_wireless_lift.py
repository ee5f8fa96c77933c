"""F10's lift slider shows the lift the motors get, the board's lift trim included (issue 34: it read 0 % while the
craft hovered on a 50.6 % lift trim). The real app on the simulated board."""

from __future__ import annotations

from term.core.protocol import STICK_MAX, Op
from term.ui.screens.wireless import LiftSlider, WirelessScreen
from tests.support.served_rig import served


async def test_the_lift_slider_counts_the_lift_trim() -> None:
    async with served() as (app, pilot, until):
        app.send(Op.TRIM_LIFT, 20)  # twenty presses of a (in SAFE the board keeps it; it shows in Status)
        await until(lambda: app.model.status is not None and app.model.status.trim_lift > 0)
        trim = app.model.status.trim_lift
        await pilot.press("f10")
        await until(lambda: isinstance(app.screen, WirelessScreen))
        slider = app.screen.query_one(LiftSlider)
        want = f"{100 * trim / STICK_MAX:.1f}%"
        await until(lambda: want in str(slider.render()))
        assert app.model.stick is None or app.model.stick.lift == 0  # the stick itself is at zero
