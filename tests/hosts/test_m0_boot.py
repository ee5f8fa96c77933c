"""The C board's nRF51822 image (make -C firmware board-m0) boots: run on the emulated Cortex-M0 from the reset
vector the SoftDevice's MBR hands over to, it starts the clocks, RTC1 and UART0 and sends Hello (this protocol's
version) and the BOOT event out of UART0's TXD; it keeps to the S110 SoftDevice's memory map; and the toolchain
pieces firmware/m0/lean_libs.c replaces still give IEEE 754's answers. The peripheral model refuses what a real
nRF51 would not do (so the boot is not a model that accepts anything). Skipped, with the reason, where
arm-none-eabi-gcc or unicorn is missing."""

from __future__ import annotations

import numpy as np
import pytest

from fcb_sim.hosts import m0boot
from term.core.protocol import PROTOCOL_VERSION, Encoder, Event, EventCode, Heartbeat, Hello, Status

ROLE_BOARD = 1


@pytest.fixture(scope="module")
def image_path():  # type: ignore[no-untyped-def]
    why = m0boot.available()
    if why:
        pytest.skip(why)
    return m0boot.build()


@pytest.fixture(scope="module")
def booted(image_path) -> m0boot.Boot:  # type: ignore[no-untyped-def]
    return m0boot.boot(image_path)


def test_the_image_boots_from_reset_to_its_hello_on_uart0(booted: m0boot.Boot) -> None:
    assert booted.faults == []
    hello, event = booted.packets[:2]
    assert isinstance(hello, Hello) and hello.protocol == PROTOCOL_VERSION and hello.role == ROLE_BOARD
    assert isinstance(event, Event) and event.code == EventCode.BOOT and event.arg == PROTOCOL_VERSION
    # the reset handler ran before main: .bss zeroed (RAM started as 0xA5), .data copied from flash
    assert booted.bss_zeroed is True and booted.data_copied is True


def test_the_vector_table_sits_where_the_softdevice_forwards_the_reset(booted: m0boot.Boot) -> None:
    assert booted.initial_sp == 0x2000_4000  # the top of the 16 KB RAM
    assert booted.reset_vector & 1  # a Thumb address
    assert m0boot.APP_FLASH <= booted.reset_vector & ~1 < m0boot.FLASH_SIZE


def test_the_clocks_rtc1_and_uart0_start_in_order_before_the_first_byte(booted: m0boot.Boot) -> None:
    order = [a for a, _v in booted.writes]

    def first(address: int) -> int:
        return order.index(address)

    assert first(m0boot.CLOCK_TASKS_HFCLKSTART) < first(m0boot.CLOCK_TASKS_LFCLKSTART) < first(m0boot.RTC1_TASKS_START)
    assert (m0boot.CLOCK_LFCLKSRC, m0boot.LFCLK_SYNTH) in booted.writes
    assert first(m0boot.UART0_ENABLE) < first(m0boot.UART0_TASKS_STARTTX) < first(m0boot.UART0_TXD)
    assert (m0boot.UART0_BAUDRATE, m0boot.UART_115200) in booted.writes
    # RTC1 counts the emulated cycles' time: the BOOT event's board time is past 0, within the run's
    assert 0 < booted.packets[1].board_ms <= booted.ms


def test_the_loop_runs_its_timers_and_answers_what_uart0_receives(image_path) -> None:  # type: ignore[no-untyped-def]
    """Past the boot: the loop sleeps until RTC1's compare and wakes for its timers (heartbeats 100 ms apart by the
    RTC's time), and a Hello sent to RXD at 50 ms goes through the receive interrupt's ring, the parser and the
    loop to the board's answering Hello."""
    term_hello = Encoder().encode(Hello(protocol=PROTOCOL_VERSION, role=0, major=0, minor=1, board_id=0))
    run = m0boot.run(image_path, ms=260, rx=[(50.0, term_hello)])
    assert run.faults == []
    beats = [pk.board_ms for pk in run.packets if isinstance(pk, Heartbeat)]
    # 100 ms apart by the RTC's time, give or take the tasks that ran first in the same pass (the blocking UART)
    assert len(beats) >= 2 and all(abs(b - a - 100) <= 3 for a, b in zip(beats, beats[1:], strict=False))
    hellos = [i for i, pk in enumerate(run.packets) if isinstance(pk, Hello)]
    assert len(hellos) == 2  # the boot's, then the answer
    before = [pk.board_ms for pk in run.packets[:hellos[1]] if isinstance(pk, Heartbeat)]
    assert before and before[-1] < 50 < beats[-1]  # the answer came after the terminal's Hello arrived
    assert any(isinstance(pk, Status) and pk.cpu_load > 0 for pk in run.packets)  # the task profile's real load


def test_the_image_keeps_to_the_softdevices_flash_and_ram(image_path) -> None:  # type: ignore[no-untyped-def]
    data = image_path.read_bytes()
    for paddr, blob in m0boot.load_image(data):  # what a programmer writes
        assert m0boot.APP_FLASH <= paddr and paddr + len(blob) <= m0boot.FLASH_SIZE
    _segments, symbols = m0boot.read_elf(data)
    assert symbols["__data_start__"][0] >= m0boot.APP_RAM
    assert symbols["__bss_end__"][0] + 0x800 <= m0boot.RAM + m0boot.RAM_SIZE  # QB_STACK left for the stack


def test_the_model_refuses_a_uart_or_rtc_that_was_not_started() -> None:
    chip = m0boot.NRF51()
    chip.write(m0boot.RTC1_TASKS_START, 1)
    chip.write(m0boot.UART0_TXD, 0x41)
    assert chip.tx == b"" and len(chip.faults) == 2
    assert "LFCLK" in chip.faults[0] and "not enabled" in chip.faults[1]
    assert chip.read(m0boot.RTC1_COUNTER) == 0
    for address, value in ((m0boot.UART0_ENABLE, 4), (m0boot.UART0_TASKS_STARTTX, 1), (m0boot.UART0_PSELTXD, 14),
                           (m0boot.UART0_BAUDRATE, m0boot.UART_115200)):
        chip.write(address, value)
    chip.write(m0boot.UART0_TXD, 0x41)
    assert "not an output" in chip.faults[-1] and chip.tx == b""
    chip.write(m0boot.GPIO_OUTSET, 1 << 14)
    chip.write(m0boot.GPIO_PIN_CNF + 4 * 14, 3)
    chip.write(m0boot.UART0_TXD, 0x41)
    assert "crystal" in chip.faults[-1] and chip.tx == b""
    chip.write(m0boot.CLOCK_TASKS_HFCLKSTART, 1)
    chip.write(m0boot.UART0_TXD, 0x41)
    assert chip.tx == b"A" and chip.read(m0boot.UART0_EVENTS_TXDRDY) == 0  # still leaving: 10 bit times
    chip.write(m0boot.UART0_TXD, 0x42)
    assert "before the last one left" in chip.faults[-1] and chip.tx == b"A"
    chip.cycles += m0boot.BYTE_CYCLES
    assert chip.read(m0boot.UART0_EVENTS_TXDRDY) == 1


def _bits(x: np.float32) -> int:
    return int(np.float32(x).view(np.uint32))


def _floats(n: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    random = rng.integers(0, 2**32, n, dtype=np.uint64).astype(np.uint32).view(np.float32)
    near = rng.normal(0, 10, n).astype(np.float32)
    edge = np.array([0.0, -0.0, 1.0, -1.0, np.inf, -np.inf, np.nan, 1e-45, -1e-45, 3.4028235e38, 1.1754944e-38],
                    dtype=np.float32)
    return np.concatenate([edge, random, near])


def test_the_lean_float_routines_give_ieee_answers(image_path) -> None:  # type: ignore[no-untyped-def]
    """firmware/m0/lean_libs.c: a - b through the one adder, the comparisons through __gesf2 (numpy's float32 is
    the reference: IEEE 754, round to nearest even)."""
    img = m0boot.M0Image(image_path)
    xs = _floats(150, 1)
    ys = np.random.default_rng(3).permutation(_floats(150, 2))
    pairs = [(a, b) for a, b in zip(xs, ys, strict=True)] + [(a, a) for a in xs[:40]]
    with np.errstate(all="ignore"):
        for a, b in pairs:
            got = img.call("__aeabi_fsub", _bits(a), _bits(b))
            want = np.float32(a) - np.float32(b)
            if np.isnan(want):
                assert np.isnan(np.uint32(got).view(np.float32)), (a, b)
            else:
                assert got == _bits(want), (a, b, hex(got), want)
            for name, op in (("__aeabi_fcmpeq", np.equal), ("__aeabi_fcmplt", np.less),
                             ("__aeabi_fcmple", np.less_equal), ("__aeabi_fcmpge", np.greater_equal),
                             ("__aeabi_fcmpgt", np.greater)):
                assert img.call(name, _bits(a), _bits(b)) == int(op(a, b)), (name, a, b)


def test_the_lean_integer_divisions_give_cs_answers(image_path) -> None:  # type: ignore[no-untyped-def]
    """firmware/m0/lean_libs.c's divisions against Python's integers: C's truncated quotient, the remainder with the
    dividend's sign, INT_MIN / -1 wrapping to INT_MIN as ARM's own does, 0 for a zero divisor (libgcc's too)."""
    img = m0boot.M0Image(image_path)
    rng = np.random.default_rng(4)
    edges = [0, 1, 2, 3, 7, 10, 255, 256, 65535, 65536, 2**31 - 1, 2**31, 2**32 - 2, 2**32 - 1]
    words = edges + [int(x) for x in rng.integers(0, 2**32, 60)] + [int(x) for x in rng.integers(0, 2**12, 30)]
    for n in words:
        for d in edges[1:] + [int(x) for x in rng.integers(1, 2**32, 4)] + [int(x) for x in rng.integers(1, 64, 4)]:
            assert img.call_pair("__aeabi_uidivmod", n, d) == (n // d, n % d), (n, d)
            assert img.call("__aeabi_uidiv", n, d) == n // d, (n, d)
            sn, sd = n - (n >> 31 << 32), d - (d >> 31 << 32)  # the same words as int32
            q = abs(sn) // abs(sd) * (-1 if (sn < 0) != (sd < 0) else 1)
            assert img.call("__aeabi_idiv", n, d) == q & 0xFFFF_FFFF, (sn, sd)
        assert img.call("__aeabi_uidiv", n, 0) == 0 and img.call("__aeabi_idiv", n, 0) == 0

