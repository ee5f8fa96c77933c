"""Scenarios: determinism per seed, metrics, and the `fcb-sim run` command line."""

from __future__ import annotations

import json
import math

import pytest

from fcb_sim.cli import main
from fcb_sim.lab.scenarios import SCENARIOS, run_scenario

_TIMING = {"wall_seconds", "realtime_factor"}


def _strip(m: dict) -> dict:
    return {k: v for k, v in m.items() if k not in _TIMING}


def test_same_seed_same_flight_other_seed_other_flight():
    a = run_scenario("gusts", 8.0, seed=11)
    b = run_scenario("gusts", 8.0, seed=11)
    c = run_scenario("gusts", 8.0, seed=12)
    assert _strip(a) == _strip(b)
    assert _strip(a) != _strip(c)


def test_hover_metrics():
    m = run_scenario("hover", 8.0, seed=1)
    for key in ("sim_seconds", "wall_seconds", "realtime_factor", "attitude_rms_deg", "attitude_max_deg",
                "height_rms_m"):
        assert key in m and math.isfinite(m[key])
    assert m["sim_seconds"] == 8.0
    assert m["attitude_rms_deg"] < 1.0
    assert m["height_rms_m"] < 0.2


@pytest.mark.parametrize("name", ["push", "panic", "motor-stuck", "gusts"])
def test_disturbance_scenarios_run(name):
    m = run_scenario(name, 10.0, seed=3)
    if name == "push":
        assert m["attitude_max_deg"] > 3.0 and 0.0 < m["settle_time_s"] < 3.0
    elif name == "panic":
        assert m["landed"] == 1.0 and 0.0 < m["landing_speed_m_s"] < 2.0
    elif name == "gusts":
        assert 0.3 < m["attitude_rms_deg"] < 3.0  # the gusts tilt it; the loops hold it
    else:
        assert m["attitude_max_deg"] > 1.0


def test_cli_json_last_line(capsys):
    assert main(["run", "--scenario", "hover", "--duration", "8", "--seed", "2", "--json"]) == 0
    lines = capsys.readouterr().out.strip().splitlines()
    obj = json.loads(lines[-1])
    assert obj["scenario"] == "hover" and obj["seed"] == 2 and obj["sim_seconds"] == 8.0


def test_cli_list(capsys):
    assert main(["run", "--list"]) == 0
    out = capsys.readouterr().out
    for name in ("hover", "step-roll", "step-yaw", "height-hold", "gusts"):
        assert name in out
    assert len(out.strip().splitlines()) == len(SCENARIOS)


@pytest.mark.parametrize("argv", [
    ["run", "--scenario", "loop-the-loop"],
    ["run", "--duration", "-3"],
    ["run", "--duration", "nan"],
    ["run", "--duration", "1"],
    ["run", "--scenario", "hover", "--filter", "kalman"],
    ["run", "--scenario", "raw-hover", "--filter", "no-such-filter"],
])
def test_cli_errors_are_one_line_and_exit_2(capsys, argv):
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("fcb-sim: ") and len(err.splitlines()) == 1


def test_raw_mode_reproduces_the_reports_filter_finding():
    # Table 2's K_gyro 0.9 lets the motor vibration through ("twitching"); the flown 0.999 is steady
    table2 = run_scenario("raw-hover", 9.0, seed=6, filter_name="complementary-0.9")
    flown = run_scenario("raw-hover", 9.0, seed=6, filter_name="complementary")
    fixed = run_scenario("raw-hover", 9.0, seed=6, filter_name="complementary", fixed_point=True)
    assert table2["attitude_rms_deg"] > 3 * flown["attitude_rms_deg"]
    assert flown["attitude_rms_deg"] < 1.0 and fixed["attitude_rms_deg"] < 1.0
    assert fixed["filter"] == "complementary (Q16.16)"
