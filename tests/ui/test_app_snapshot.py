"""Snapshot tests (pytest-textual-snapshot) of the screens, fed by a seeded board: fcb_sim's sans-IO Board and
term's own LinkSession exchange bytes on a simulated clock (no wall clock anywhere), so the same seed always gives
the same screen. Update after a deliberate change with `pytest tests/ui/test_app_snapshot.py --snapshot-update`
and look at the SVGs in tests/__snapshots__/."""

from __future__ import annotations

import pytest

from term.core.protocol import Mode
from term.session.model import Model
from tests.support.app_rig import SIZE, app_for, seeded_flight


@pytest.fixture(scope="module")
def flight() -> tuple[Model, float]:
    return seeded_flight()


def test_the_seeded_flight_is_what_the_screen_claims(flight: tuple[Model, float]) -> None:
    model, _ = flight
    assert model.mode == Mode.FULL
    assert model.motion is not None and model.motion.ae1 > 300
    assert any(e.source == "nak" and "not calibrated" in e.text for e in model.events)
    assert model.link is not None and model.link.frames_bad == 0 and model.link.rtt_mean_ms is not None


def test_profile_task_names_match_the_board() -> None:
    from fcb_sim.board.scheduler import TASKS
    from term.ui.widgets.profile import TASK_NAMES

    assert tuple(TASK_NAMES[i] for i in range(len(TASK_NAMES))) == TASKS


def test_snapshot_main_screen(snap_compare, flight) -> None:  # noqa: ANN001
    assert snap_compare(app_for(flight), terminal_size=SIZE)


def test_snapshot_help(snap_compare, flight) -> None:  # noqa: ANN001
    assert snap_compare(app_for(flight), press=["f1"], terminal_size=SIZE)


def test_snapshot_profile(snap_compare, flight) -> None:  # noqa: ANN001
    assert snap_compare(app_for(flight), press=["f9"], terminal_size=SIZE)


def test_snapshot_panic_is_unmistakable(snap_compare, flight) -> None:  # noqa: ANN001
    from term.core.protocol import Attitude

    model, end = flight
    app = app_for(flight)

    def panic(pilot) -> None:  # noqa: ANN001
        a = model.attitude
        app.model.apply_packet(Attitude(Mode.PANIC, a.phi, a.theta, a.psi, a.sp, a.sq, a.sr), end)
        app.render_now()

    assert snap_compare(app, terminal_size=SIZE, run_before=panic)
    model.apply_packet(Attitude(Mode.FULL, *model.attitude[1:]), end)  # the shared flight back as it was
