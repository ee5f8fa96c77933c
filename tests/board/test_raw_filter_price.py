"""The RAW filter's price in the board's cost model (fcb_sim/board/timing.py, fcb_sim/lab/opcount.py; docs/board.md,
"The RAW filter's price"): the table is what the filters count, the report's filter adds nothing, and the board charges
the filter that runs."""

from __future__ import annotations

import math

import pytest

from fcb_sim.board.timing import RAW_FILTER_EXTRA_US, RAW_FILTER_OPS, REPORT_RAW_FILTER, raw_filter_us
from fcb_sim.estimation import FILTERS, fixed, has_fixed_point, ikf, ikf_fixed
from fcb_sim.lab import opcount
from fcb_sim.lab.profile import run_profile


def test_the_price_table_is_what_the_filters_count() -> None:
    assert set(RAW_FILTER_OPS) == {(n, fx) for n in FILTERS for fx in (False, True) if not fx or has_fixed_point(n)}
    assert opcount.table() == RAW_FILTER_OPS


def test_counting_leaves_the_filters_as_they_were() -> None:
    real = (fixed.smul, fixed.atan2_corrected, ikf_fixed.mul, ikf_fixed.div, ikf.math)
    opcount.count_ops("ikf", True, n=20)
    opcount.count_ops("ikf", False, n=20)
    assert (fixed.smul, fixed.atan2_corrected, ikf_fixed.mul, ikf_fixed.div, ikf.math) == real
    assert ikf.math is math


def test_ikf_counts_as_its_author_counted() -> None:
    # docs/attitude.md: the fixed-point update is 119 multiplies, 5 divisions and 3 square roots; the predicted
    # output 26 multiplies more (the Euler angles then add their own).
    f = ikf_fixed.InertialKalmanFilterQ()
    data = opcount.samples(201)
    f.update(*data[0], 0.0025)
    with opcount._counting() as counts:
        for s in data[1:]:
            f.update(*s, 0.0025)
        update = dict(counts)
        counts.clear()
        f.quaternion()
        output = dict(counts)
    assert update["mul"] == 119 * 200 and update["div"] == 5 * 200 and update["sqrt"] == 3 * 200
    assert output["mul"] == 26 and "div" not in output and "sqrt" not in output


def test_the_report_filter_adds_nothing_and_ikf_costs_more() -> None:
    for fx in (False, True):
        assert RAW_FILTER_EXTRA_US[(REPORT_RAW_FILTER, fx)] == 0
        assert RAW_FILTER_EXTRA_US[("complementary-0.9", fx)] == 0  # the same arithmetic, another constant
    # ikf in fixed point is the variant cut to fit the M0 (ikf_lite): priced 0.2-0.4 ms a sample, within 20 % of
    # its emulated cost (fcb_sim.hosts.m0emu), so charged its price; float is priced, and costs far more
    assert 200 < raw_filter_us("ikf", True) < 400
    assert 100 < RAW_FILTER_EXTRA_US[("ikf", True)] < 300 and RAW_FILTER_EXTRA_US[("ikf", False)] > 1000
    with pytest.raises(KeyError):
        raw_filter_us("qgate", True)  # float only


def test_the_board_charges_the_filter_that_runs() -> None:
    report = run_profile("raw", seconds=2.0, logging=False)
    ikf_q = run_profile("raw", seconds=2.0, logging=False, filter_name="ikf", fixed_point=True)
    assert report["filter"] == REPORT_RAW_FILTER and abs(report["tasks"]["sensor"]["mean_us"] - 1001) < 50
    extra = ikf_q["tasks"]["sensor"]["mean_us"] - report["tasks"]["sensor"]["mean_us"]
    assert abs(extra - RAW_FILTER_EXTRA_US[("ikf", True)]) < 30
    assert ikf_q["cpu_load_pct"] > report["cpu_load_pct"] + 5
