"""The Cortex-M0 build measured: flash and RAM of the codec library and the board probe, the codec's deepest
stack (gcc's call-graph files). The firmware tests and bench.firmware."""

from __future__ import annotations

import re
import subprocess
import tempfile
from pathlib import Path
from typing import Any

from tests.support.paths import FIRMWARE

REPORT_FIRMWARE_TEXT = 52160  # report section 4.1: the lab's whole firmware



ENTRY_POINTS = ("qp_decode", "qp_decode_byte", "qp_encode", "qp_hello_compatible")


def _make(build: Path, *targets: str) -> None:
    proc = subprocess.run(["make", "-s", "-C", str(FIRMWARE), f"BUILD={build}", *targets], capture_output=True,
                          text=True)
    if proc.returncode != 0:
        raise SystemExit(f"bench.firmware: the firmware does not build:\n{proc.stdout}{proc.stderr}")


def _size(path: Path) -> tuple[int, int, int]:
    """(text, data, bss) as arm-none-eabi-size counts them (text includes read-only data)."""
    out = subprocess.run(["arm-none-eabi-size", str(path)], capture_output=True, text=True, check=True).stdout
    text, data, bss = out.splitlines()[1].split()[:3]
    return int(text), int(data), int(bss)


def _deepest_stack(ci_files: list[Path]) -> int:
    """The largest stack any codec entry point can use: its frame plus its deepest chain of callees, from gcc's
    -fcallgraph-info=su files (VCG graphs: nodes with "N bytes", edges caller -> callee)."""
    frame: dict[str, int] = {}
    calls: dict[str, set[str]] = {}
    for path in ci_files:
        for line in path.read_text().splitlines():
            if m := re.match(r'node: \{ title: "([^"]+)" label: "[^"]*\\n(\d+) bytes', line):
                frame[m.group(1)] = int(m.group(2))
            elif m := re.match(r'edge: \{ sourcename: "([^"]+)" targetname: "([^"]+)"', line):
                calls.setdefault(m.group(1), set()).add(m.group(2))

    def depth(fn: str, seen: frozenset[str]) -> int:
        if fn in seen:  # no recursion in the codec; stop if there ever is
            return 0
        below = [depth(c, seen | {fn}) for c in calls.get(fn, ())]
        return frame.get(fn, 0) + max(below, default=0)

    return max(depth(fn, frozenset()) for fn in ENTRY_POINTS)


def m0_sizes() -> dict[str, Any]:
    """Build the Cortex-M0 library and board probe in a temporary directory and measure them."""
    with tempfile.TemporaryDirectory(prefix="qp-m0-") as tmp:
        build = Path(tmp)
        _make(build, "m0")
        m0 = build / "m0"
        lib_text, lib_data, lib_bss = _size(m0 / "qp_protocol.o")
        text, data, bss = _size(m0 / "size_probe.elf")
        stack = _deepest_stack(sorted(m0.glob("size_probe.elf-*.ci")))
    compiler = subprocess.run(["arm-none-eabi-gcc", "-dumpversion"], capture_output=True, text=True).stdout.strip()
    return {
        "library_flash_bytes": lib_text + lib_data,
        "library_static_ram_bytes": lib_data + lib_bss,
        "board_flash_bytes": text + data,
        "board_static_ram_bytes": data + bss,
        "codec_stack_bytes": stack,
        "board_ram_bytes": data + bss + stack,
        "share_of_report_firmware_text_pct": round(100 * (text + data) / REPORT_FIRMWARE_TEXT, 1),
        "arm_gcc": compiler,
    }
