"""The report's board flies (issue 13): the "report" preset's flight core (fcb_sim.board.param_bindings.preset_core:
Table 1, the complementary filter with K_gyro 0.999, the Figure 10 height estimator on its PD gains) closes the HEIGHT
loop on the Figure 10 estimator and hovers in RAW on the report's filter. The figures beside the default preset's are
bench.flight's (report_*); here each flight must hold, with the parts the preset names really in the loop."""

from __future__ import annotations

from fcb_sim.board.param_bindings import preset_core
from fcb_sim.estimation.complementary import ComplementaryFilter
from fcb_sim.estimation.height import HeightEstimator, HeightKalman
from fcb_sim.lab.scenarios import Sim, fly_core, height_hold
from term.core.protocol import Mode


def test_height_hold_on_the_figure_10_estimator() -> None:
    core = preset_core("report")
    assert type(core.height_est) is HeightEstimator and core.height_i == 0.0  # Figure 10, PD only
    assert (core.gains.height_p, core.gains.height_d) == (120.0, 320.0)
    m = height_hold(1, 15.0, Sim(1, core=core))
    assert m["height_rms_m"] < 0.35, m["height_rms_m"]  # bench.flight: 0.13-0.22 m over seeds 1-3 (default 0.07-0.1)
    assert type(preset_core("default").height_est) is HeightKalman


def test_raw_hover_on_the_reports_filter() -> None:
    core = preset_core("report")
    assert type(core.filter) is ComplementaryFilter and core.filter.k_gyro == 0.999
    m = fly_core(1, 12.0, core, Mode.RAW)
    assert m["attitude_rms_deg"] < 1.0, m["attitude_rms_deg"]  # bench.flight: 0.3-0.4 deg over seeds 1-3
