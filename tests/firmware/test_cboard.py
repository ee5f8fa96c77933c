"""The C board's own checks: its unit tests under ASan and UBSan, the whole board linked for the Cortex-M0 within
the size goal, lockstep (the same seed flies the same flight), `fcb-sim serve --pty --board c` and `fcb-sim run
--board c` from the outside, and one line where no C compiler exists."""

from __future__ import annotations

import os
import re
import shutil
import signal
import subprocess
import sys
from pathlib import Path

import pytest

from fcb_sim import cbuild
from fcb_sim.hosts import cboard, m0boot
from tests.support.firmware import NO_ARM, SAN_ENV
from tests.support.paths import EXCERPT

FIRMWARE = cboard.FIRMWARE
HAVE_CC = shutil.which("cc") is not None and shutil.which("make") is not None
needs_cc = pytest.mark.skipif(not HAVE_CC, reason="no C compiler (cc) or make: the C board's tests are skipped")
M0_FLASH_GOAL, M0_RAM_GOAL = 40 * 1024, 8 * 1024  # issue 37: flash log, profile, console, motor test


def _make(tmp_path: Path, *targets: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(["make", "-s", "-C", str(FIRMWARE), f"BUILD={tmp_path}", *targets], capture_output=True,
                          text=True, env=SAN_ENV)


@needs_cc
def test_the_c_boards_unit_tests_pass_under_asan_and_ubsan(tmp_path: Path) -> None:
    proc = _make(tmp_path, "board-test")
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "qb_test: ok (0 failures)" in proc.stdout


@pytest.mark.skipif(shutil.which("arm-none-eabi-gcc") is None, reason=NO_ARM)
def test_the_whole_board_links_for_the_cortex_m0_within_the_goal() -> None:
    """`make board-m0` as fcb_sim builds it (into the build cache: the image tests/hosts/test_m0_boot.py boots is
    this one, linked once for both; the link with LTO costs 4 s of CPU)."""
    elf = cbuild.build("board-m0", [m0boot.ELF], tools=["arm-none-eabi-gcc"], missing=NO_ARM) / m0boot.ELF
    proc = subprocess.run(["arm-none-eabi-size", str(elf)], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    text, data, bss = (int(v) for v in re.search(r"^\s*(\d+)\s+(\d+)\s+(\d+)\s", proc.stdout, re.M).groups())
    assert text + data < M0_FLASH_GOAL and data + bss < M0_RAM_GOAL, proc.stdout


@needs_cc
def test_lockstep_the_same_seed_flies_the_same_flight() -> None:
    a, b = (cboard.fly_board("c", "height-hold", seed=4, duration=8.0) for _ in range(2))
    for m in (a, b):
        m.pop("wall_s")
    assert a == b and a["mode"] == "HEIGHT" and a["naks"] == 0
    assert a["height_rms_m"] < 0.3 and a["attitude_rms_deg"] < 2.0


@needs_cc
def test_fcb_sim_run_board_c_prints_its_figures() -> None:
    out = subprocess.run([sys.executable, "-m", "fcb_sim", "run", "--board", "c", "--scenario", "hover",
                          "--duration", "8", "--json"], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert '"board": "c"' in out.stdout.splitlines()[-1] and "mode: FULL" in out.stdout


@needs_cc
def test_fcb_sim_serve_board_c_prints_its_pty_and_ends_cleanly() -> None:
    proc = subprocess.Popen([sys.executable, "-m", "fcb_sim", "serve", "--pty", "--board", "c"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        assert proc.stdout is not None
        line = proc.stdout.readline()
        assert line.startswith("pty: /dev/") and os.path.exists(line.split()[1])
    finally:
        proc.send_signal(signal.SIGTERM)
        out, err = proc.communicate(timeout=20)
    assert proc.returncode == 0, err
    assert "mode SAFE" in out


def test_without_a_compiler_one_line_says_what_to_install(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(cbuild.shutil, "which", lambda name: None)
    with pytest.raises(cboard.CBoardUnavailable) as err:
        cboard.library_path(tmp_path)
    assert str(err.value) == cboard.NO_CC and "\n" not in str(err.value)


@pytest.mark.parametrize(("argv", "says"), [
    (["term", "--board", "c", "--serial", "/dev/null"], "--board needs --sim"),
    (["fcb_sim", "serve", "--pty", "--board", "c", "--ble-hci", "tcp-server:127.0.0.1:0"], "has no BLE radio yet"),
])
def test_what_the_c_board_cannot_do_is_one_line(argv: list[str], says: str) -> None:
    out = subprocess.run([sys.executable, "-m", *argv], capture_output=True, text=True, timeout=60)
    assert out.returncode == 2 and says in out.stderr and len(out.stderr.strip().splitlines()) == 1, out.stderr


@needs_cc
def test_the_instructor_channel_acts_on_the_c_boards_world_and_cable() -> None:
    """`fcb-sim serve --board c --instructor` as `term --sim --board c` starts it: the truth comes from the physics
    the C board flies, and a cable cut silences its pty (the channel acts on the world and the wire, not the
    board)."""
    import asyncio
    import time

    import serial

    from term.lessons.instructor import InstructorClient, Truth
    from term.session.sim import SimBoard

    cboard.library_path()
    sim = SimBoard(seed=4, instructor=True, extra=["--board", "c"])
    port = sim.start()
    try:
        async def cut() -> list[Truth]:
            got: list[Truth] = []
            client = InstructorClient(sim.instructor_address, on_truth=got.append)
            await client.open()
            async with asyncio.timeout(10):
                while not got:
                    await asyncio.sleep(0.01)
            assert client.send({"do": "cable", "cuts": [[0.0, 0.6]]}) is None
            await asyncio.sleep(0.05)
            await client.close()
            return got

        with serial.Serial(port, 115200, timeout=0.05) as ser:
            assert ser.read(4096)  # the C board talks
            truths = asyncio.run(cut())
            assert truths[0].cable and truths[0].h == pytest.approx(0.0, abs=0.05)  # on the pad
            ser.reset_input_buffer()
            t0 = time.monotonic()
            quiet = ser.read(4096)
            assert time.monotonic() - t0 < 0.3 and quiet == b""
            time.sleep(0.7)
            ser.reset_input_buffer()
            assert ser.read(4096)
    finally:
        sim.stop()


@needs_cc
def test_a_flood_is_dropped_counted_and_said_once() -> None:
    """10 KB at once into the C board's 4 KB receive queue: the rest is dropped, counted, and said in one event
    OVERFLOW (a flood is one event a heartbeat period); the board parses on and answers the retried command."""
    from fcb_sim.board.parts import BoardConfig
    from term.core.protocol import Ack, Command, Decoder, Event, EventCode, Op, encode

    board = cboard.CBoard(BoardConfig(seed=2))
    dec = Decoder()
    board.advance(100_000)
    board.uart_receive(bytes(range(1, 256)) * 40)  # 10200 bytes, no frame in them
    board.advance(200_000)
    board.uart_receive(encode(Command(7, Op.MODE, 0)))  # lost: the flood's tail runs into it (one bad frame)
    board.uart_receive(encode(Command(7, Op.MODE, 0)))  # the terminal's retry
    board.advance(300_000)
    pkts = dec.feed(board.uart_transmit())
    overflows = [p.arg for p in pkts if type(p) is Event and p.code == EventCode.OVERFLOW]
    assert overflows == [10200 - 4096] and board.rx_overflow == 10200 - 4096
    assert [p.status for p in pkts if type(p) is Ack and p.cmd_id == 7] == [0]


def _board_filter_rows() -> list[tuple[float, ...]]:
    """BROAD trial 07's excerpt (still, then fast rotation) at the dts the board measures: 81 and 82 RTC ticks on
    the RAW path's 400 Hz, 0.005 s on the DMP path's 200 Hz."""
    import csv
    import gzip

    path = EXCERPT
    with gzip.open(path, "rt", newline="") as fh:
        rows = [tuple(float(r[k]) for k in ("gx", "gy", "gz", "ax", "ay", "az")) for r in csv.DictReader(fh)]
    dts = (81 / 32768, 82 / 32768, 81 / 32768, 0.005)
    return [(*r, dts[i % len(dts)]) for i, r in enumerate(rows[:3000])]


@needs_cc
def test_the_boards_filter_is_ikf_fixed_bit_for_bit_at_the_boards_dts() -> None:
    """The C board's RAW filter (qb_ikf_*: ikf_q.c set up from the integer table, its dt constants derived from
    each measured dt) and ikf_fixed.py: the same integers after every sample."""
    import ctypes

    from fcb_sim.estimation.ikf_lite import InertialKalmanFilterQL
    from fcb_sim.estimation.native import STATE_FIELDS, python_state

    lib = ctypes.CDLL(str(cboard.library_path()))
    dbl = ctypes.c_double
    lib.qb_ikf_update.argtypes = [ctypes.c_void_p, *([dbl] * 7)]
    lib.ikfq_size.restype = ctypes.c_uint
    f = (ctypes.c_int64 * (lib.ikfq_size() // 8 + 4))()  # qb_ikf_t: an ikfq_t first, then the dt it was set for
    lib.qb_ikf_reset(f)
    py = InertialKalmanFilterQL()  # ikf in fixed point: the variant that fits the M0
    out = (ctypes.c_int64 * len(STATE_FIELDS))()
    for i, s in enumerate(_board_filter_rows()):
        py.update(*s)
        lib.qb_ikf_update(f, *s)
        lib.ikfq_state(f, out)
        c = dict(zip(STATE_FIELDS, out, strict=True))
        assert c == python_state(py), (i, s, {k: (v, c[k]) for k, v in python_state(py).items() if v != c[k]})


def test_the_boards_constants_table_is_what_fcb_sim_native_prints() -> None:
    """qb_flight.c's IKF_CONSTS (ikf's defaults as integers, so the M0 links no double set-up) is still the table
    `python -m fcb_sim.estimation.native --constants 0.0025` prints."""
    from fcb_sim.estimation.native import NativeIKFQL, library, why_not

    if library() is None:
        pytest.skip(f"the C filter is not built here: {why_not()}")
    src = (FIRMWARE / "board" / "qb_flight.c").read_text()
    body = re.search(r"ikfq_consts_t IKF_CONSTS = \{(.*?)\};", src, re.S).group(1)
    table = {k: int(v) for k, v in re.findall(r"\.(\w+) = (-?\d+)", body)}
    assert table == NativeIKFQL().consts(0.0025)
