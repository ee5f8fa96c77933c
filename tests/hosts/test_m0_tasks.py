"""The task bodies built for the Cortex-M0 (arm-none-eabi-gcc -mcpu=cortex-m0 -mthumb -Os) and executed under
unicorn (fcb_sim.hosts.m0emu) give the same outputs as the host build on the same recorded inputs; the cycle table
follows the Cortex-M0 TRM. Skipped, with the reason, where arm-none-eabi-gcc or unicorn is absent."""

from __future__ import annotations

import pytest

from fcb_sim.estimation.native import library, why_not
from fcb_sim.hosts import m0emu
from tests.support.imu_data import _rows
from tests.support.paths import EXCERPT


@pytest.fixture(scope="module")
def tasks() -> m0emu.TaskCycles:
    why = m0emu.available()
    if why:
        pytest.skip(why)
    if library() is None:
        pytest.skip(f"no host build: {why_not()}")
    rows = _rows(EXCERPT, 2700)
    return m0emu.run_tasks(rows[:1] + rows[2450:2700])  # the start, then fast hand-held rotation


def test_the_m0_gives_the_host_outputs(tasks: m0emu.TaskCycles) -> None:
    assert tasks.mismatches == []
    assert len(tasks.filter) == len(tasks.control) == 250


def test_the_m0_gives_the_host_outputs_for_the_variant_that_fits() -> None:
    """ikf lite (its gravity part spread over 4 samples, its angles ctlq_angles_lite): the M0's quaternion,
    angles, motor commands and final state are the host build's; no sample costs more than a fifth above the
    mean (the gravity part is spread: the exact twin decimated has a sample at twice its mean)."""
    why = m0emu.available()
    if why:
        pytest.skip(why)
    rows = _rows(EXCERPT, 2700)
    run = m0emu.run_tasks(rows[:1] + rows[2450:2550], decimation=4, lite=True)
    assert run.mismatches == []
    s = run.summary("filter")
    assert s["cycles_max"] < 1.3 * s["cycles_mean"] and s["cycles_max"] < 550 * 16  # 550 µs at 16 MHz


def test_the_steps_cost_what_the_m0_counts(tasks: m0emu.TaskCycles) -> None:
    """Plausible magnitudes: thousands of cycles a step (not a stub returning at once, not a runaway loop), and
    more cycles than instructions (loads, branches and calls take 2 to 4)."""
    for task in ("filter", "control"):
        s = tasks.summary(task)
        assert 1000 < s["instructions_mean"] < s["cycles_mean"] < 2 * s["instructions_mean"], (task, s)
        assert s["cycles_max"] < 100_000


def test_the_cycle_table() -> None:
    """Cortex-M0 TRM Table 3-1 for a few encodings."""
    c = m0emu.thumb_cycles
    assert c(0x1840) == 1  # adds r0, r0, r1
    assert c(0x4348) == 1  # muls r0, r1, r0 (the fast multiplier)
    assert c(0x6808) == 2 and c(0x9801) == 2 and c(0x4801) == 2  # ldr imm, sp-relative, literal
    assert c(0xB510) == 3  # push {r4, lr}
    assert c(0xBD10) == 5  # pop {r4, pc}: 4 + N
    assert c(0xC80C) == 3  # ldmia r0!, {r2, r3}
    assert c(0xE7FE) == 3  # b .
    assert c(0xD0FE) == m0emu.COND_BRANCH  # beq: 1 or 3, settled at the next block
    assert c(0x4770) == 3  # bx lr
    assert c(0xF000) == 4  # bl (first half)
    assert c(0x4687) == 3 and c(0x4680) == 1  # mov pc, r0; mov r8, r0


def test_the_timing_table_is_what_the_m0_runs() -> None:
    """fcb_sim.board.timing.M0_EMULATED_US is a fresh emulation's figures (regenerate them with bench.profile)."""
    why = m0emu.available()
    if why:
        pytest.skip(why)
    from fcb_sim.board.timing import M0_EMULATED_US

    table, run = m0emu.emulated_table()
    assert run.mismatches == []
    assert table == M0_EMULATED_US


def test_the_model_follows_the_emulation_where_they_disagree() -> None:
    from fcb_sim.board.timing import (
        EMULATED_FILTERS,
        FIGURE14,
        M0_EMULATED_US,
        MODEL_TOLERANCE,
        raw_filter_price_us,
        raw_filter_us,
    )

    assert EMULATED_FILTERS[("ikf", True)] == "filter/ikf/lite4"  # what make_filter gives in fixed point
    emulated = M0_EMULATED_US["filter/ikf/lite4"][0]
    model = raw_filter_us("ikf", True)
    expected = emulated if abs(model - emulated) > MODEL_TOLERANCE * emulated else model
    assert raw_filter_price_us("ikf", True) == expected
    assert raw_filter_price_us("complementary", True) == raw_filter_us("complementary", True)  # not emulated
    # the control law: Figure 14's row stays the model while the emulation is within the tolerance of it
    assert abs(M0_EMULATED_US["control_raw"][0] - FIGURE14["control_raw"][0]) <= MODEL_TOLERANCE * 131.0
