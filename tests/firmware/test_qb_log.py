"""qb_log in C (firmware/board/qb_console.c) against the protocol's Python side: gcc builds it with a harness whose
UART is a buffer (tests/firmware/qb_log_harness.c, under ASan and UBSan); every line's frames are exactly the bytes
``text_packets`` encodes for the same text and level in Python, the small printf formats as Python's % does, a line
is cut at QB_LOG_MAX, and a full queue drops a whole line without spending sequence numbers."""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import pytest

from fcb_sim.board.console import QB_LOG_MAX
from term.core.console import Console
from term.core.protocol import Decoder, Encoder, text_packets

FIRMWARE = Path(__file__).resolve().parents[2] / "firmware"
HARNESS = Path(__file__).with_name("qb_log_harness.c")

pytestmark = pytest.mark.skipif(shutil.which("cc") is None, reason="no C compiler (cc)")


@pytest.fixture(scope="module")
def output(tmp_path_factory: pytest.TempPathFactory) -> list[str]:
    exe = tmp_path_factory.mktemp("qb_log") / "qb_log_harness"
    cmd = ["cc", "-std=c99", "-Wall", "-Wextra", "-Werror", "-pedantic", "-g", "-O1",
           "-fsanitize=address,undefined", "-fno-sanitize-recover=all", "-DIKFQ_DEFAULT_FORMATS",
           "-DIKFQ_LITE_ONLY", f"-I{FIRMWARE}", f"-I{FIRMWARE / 'board'}", str(HARNESS),
           str(FIRMWARE / "board" / "qb_console.c"), str(FIRMWARE / "qp_protocol.c"), "-o", str(exe), "-lm"]
    subprocess.run(cmd, check=True, capture_output=True, text=True, timeout=120)
    run = subprocess.run([str(exe)], check=True, capture_output=True, text=True, timeout=30)
    return run.stdout.splitlines()


LONG = "0123456789" * 7
EXPECTED = [  # (level, the line as Python formats it)
    (2, "hello"),
    (4, "imu: %s after %d tries (%d%%)" % ("timeout", -3, 42)),  # noqa: UP031 (printf, as qb_log is)
    (1, "x=%x c=%c long=%d s=%s" % (0xBEEF, "Q", -1234567, "(null)")),  # noqa: UP031
    (3, LONG[:QB_LOG_MAX]),
    (2, ""),
    (2, "odd %q "),
    None,  # dropped: the queue was full
    (2, "after"),
]


def test_the_frames_are_the_pythons_for_the_same_line(output: list[str]) -> None:
    enc = Encoder()
    for got, want in zip(output, EXPECTED, strict=False):
        if want is None:
            assert got == "-"
            continue
        level, line = want
        assert bytes.fromhex(got) == enc.encode_many(text_packets(line, level)), line
    assert output[len(EXPECTED)] == f"sent {len(EXPECTED) - 1} dropped 1"


def test_the_terminal_reads_the_c_lines(output: list[str]) -> None:
    dec, console = Decoder(keep_text=True), Console()
    lines = []
    for got in output[: len(EXPECTED)]:
        if got != "-":
            for pkt in dec.feed(bytes.fromhex(got)):
                lines += console.feed_packet(pkt, 0.0)
    assert [(x.level, x.text) for x in lines] == [(lv, t.rstrip()) for lv, t in filter(None, EXPECTED)]
    assert dec.stats.frames_bad == 0 and dec.stats.seq_gaps == 0  # the dropped line spent no sequence number
