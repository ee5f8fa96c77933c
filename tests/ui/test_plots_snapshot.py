"""Snapshot of the live plots (issue 14: the native braille widget), fed by the seeded flight of the screens'
snapshots: the same seed always gives the same plots. Update after a deliberate change with
`pytest tests/ui/test_plots_snapshot.py --snapshot-update` and look at the SVG in tests/__snapshots__/."""

from __future__ import annotations

from term.session.model import Model
from tests.support.app_rig import SIZE, app_for, seeded_flight


def test_snapshot_plots(snap_compare) -> None:  # noqa: ANN001
    flight: tuple[Model, float] = seeded_flight()
    app = app_for(flight)

    async def plots(pilot) -> None:  # noqa: ANN001
        await pilot.press("f8")
        app.render_now()
        await pilot.pause()

    assert snap_compare(app, terminal_size=SIZE, run_before=plots)
