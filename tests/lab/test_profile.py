"""The profiling bench (fcb_sim/lab/profile.py): the report's profile (4.2) through the board's bytes, beside its
Figure 14 figures and deadline misses; the stick recomputes in the profile; `fcb-sim profile`'s errors."""

from __future__ import annotations

import pytest

from fcb_sim.board.timing import COSTS, residual_jitter_us
from fcb_sim.cli import main
from fcb_sim.lab.profile import run_profile


def test_profile_round_robin_misses_priority_fixes_them_dmp_far_fewer() -> None:
    # The report (4.2): RAW at 400 Hz under round robin, control periods >= WCET99 (2987 µs) in about 2.1 %; the
    # priority scheduler should bring that near zero; DMP has far fewer.
    rr = run_profile("raw", "round-robin", 8.0, seed=2)
    pr = run_profile("raw", "priority", 8.0, seed=2)
    dmp = run_profile("dmp", "round-robin", 8.0, seed=2)
    assert rr["control_periods"] > 3000
    # The modelled mechanisms alone (task collisions, duration tails, interrupts) give about 0.7-1.1 %: below
    # the report, not above it, and far from zero.
    assert 0.004 < rr["deadline_miss_rate"] < 0.021
    assert pr["deadline_miss_rate"] < 0.001 and pr["deadline_miss_rate_999"] == 0
    assert dmp["deadline_miss_rate"] < rr["deadline_miss_rate"] / 3
    for out in (rr, pr):
        t = out["tasks"]
        assert abs(t["sensor"]["mean_us"] - 1001) < 50 and abs(t["control"]["mean_us"] - 113) < 15
        assert abs(t["control"]["period_us"] - 2502.4) < 5 and abs(t["baro"]["period_us"] - 50000) < 500
    assert rr["report"]["control"] == {"row": "control_raw", "n": 9380, "mean_us": 113, "sd_us": 41, "p99_us": 220,
                                       "p999_us": 492, "period_us": 2477, "period_sd_us": 238}
    # The report's RAW sensor read jitters more (period sigma 193 µs) than the model's. With that missing start
    # jitter put back (calibrated on the sensor period alone), the control period and the miss rate come out near
    # the report's: sigma 238 µs within 15 %, 2.1 % within half.
    tau = residual_jitter_us(rr["tasks"]["sensor"]["period_sd_us"], 193)
    assert 90 < tau < 150
    res = run_profile("raw", "round-robin", 8.0, seed=2, residual_jitter_us=tau)
    assert abs(res["tasks"]["sensor"]["period_sd_us"] - 193) < 0.15 * 193
    assert abs(res["tasks"]["control"]["period_sd_us"] - 238) < 0.15 * 238
    assert 0.0105 < res["deadline_miss_rate"] < 0.0315


def test_the_profile_counts_the_recomputes() -> None:
    with_r = run_profile("raw", seconds=2.0, logging=False)
    without = run_profile("raw", seconds=2.0, logging=False, stick_reaction=False)
    r, p, p0 = with_r["stick_reactions"], with_r["tasks"]["parse"], without["tasks"]["parse"]
    assert without["stick_reactions"]["n"] == 0 and r["n"] >= 150  # random sticks at 100 Hz: nearly every frame
    assert abs(r["mean_us"] - COSTS["control_raw"].mean()) < 15  # priced as a control step (Figure 14)
    # the parse runs carry the recomputes: their time minus the recomputes' is the decode time alone
    decode = p["n"] * p["mean_us"] - r["n"] * r["mean_us"]
    assert abs(decode / p["n"] - p0["mean_us"]) < 5 and p["mean_us"] > p0["mean_us"] + 60
    assert with_r["cpu_load_pct"] > without["cpu_load_pct"]


@pytest.mark.parametrize("seconds", ["0.5", "nan", "inf", "-3", "4000"])
def test_profile_refuses_a_bad_duration_in_one_line(seconds: str, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["profile", "--seconds", seconds]) == 2
    err = capsys.readouterr().err
    assert err.startswith("fcb-sim: --seconds must be between 1 and 3600") and err.count("\n") == 1
