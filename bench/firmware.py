"""The C codec's cost: Cortex-M0 flash and RAM, and the host decode rate beside the Python decoder. Prints one JSON
line (the last); a missing compiler is one line before it, and its figures are null.

- Cortex-M0 (the nRF51822's core; `make -C firmware m0`: Debian's arm-none-eabi-gcc, -mcpu=cortex-m0 -mthumb -Os):
  ``library_*``: the whole library (qp_protocol.o: every encoder, the decoder, CRC, COBS, half floats);
  ``board_*``: what a board links of it (firmware/m0/size_probe.c with --gc-sections: the decoder, the Hello check,
  every encoder through qp_encode, newlib's memset/memcpy). ``board_static_ram_bytes`` is its state (decoder,
  encoder, one packet, one frame); ``codec_stack_bytes`` the deepest stack of a codec call (gcc
  -fcallgraph-info; memset/memcpy's frames are not in it); ``board_ram_bytes`` the sum. Goal: <= 4096 B flash,
  <= 256 B RAM. The report's whole firmware was 52 160 B of text, 244 B of data and 3232 B of bss (report 4.1).
- Host: bench.codec's realistic traffic (one simulated minute, both directions), cut into 32-byte reads, decoded by
  the C decoder (timed inside the C process: firmware/test/qp_runner.c, built -O2) and by term.core.protocol.Decoder.

- The C board (firmware/board/, issue 26): ``cboard_m0_*``: the whole board's nRF51822 image (`make -C firmware
  board-m0`: -Os, float, LTO, --gc-sections; the vector table, the reset handler and hal_m0.c's clock, RTC1 and
  UART0 start included), flash (text + data) and RAM (data + bss; ``cboard_m0_stack_reserved_bytes`` more are kept
  for the stack by the linker script) beside the report's firmware; issue 37's goal: <= 40 KB flash, <= 8 KB RAM
  (what the S110 SoftDevice leaves on a 16 KB part), ``*_margin_bytes`` what is left. ``cboard_m0_boot_*``: the
  image run on the emulated Cortex-M0 from its reset vector until Hello and the BOOT event have left UART0's TXD
  (fcb_sim.hosts.m0boot): the instructions and the emulated milliseconds (16 MHz), null without unicorn;
  ``cboard_m0_safe_cpu_load_pct``: the CPU load the board's own task profile reports (Status) after one emulated
  second in SAFE, its telemetry sent by the blocking UART writes (87 us a byte) and its sensor stubs.
  ``flight_*``: the C board (double, and float as the M0 computes) and the Python board flown in the
  same run, each a whole board over its UART by the scenarios' pilot (fcb_sim.hosts.cboard.fly_board): hover in FULL,
  HEIGHT hold, seeds 1-8, 15 s, figures from 6 s on against the truth: mean attitude rms (deg) and height rms
  (m), and the C board's over the Python board's (goal: within 10 %). Also hover in RAW, for information: the C
  board's fixed-point ikf beside the Python board's float one, which pays the cost model's read and filter time
  before each control step (the C host build's tasks take none), so RAW is not like for like.

Run: `python -m bench.firmware [--seconds S] [--seeds N]`; `--m0-only`: the Cortex-M0 figures alone (seconds).
"""

from __future__ import annotations

import argparse
import json
import platform
import shutil
import subprocess
import tempfile
import time
from pathlib import Path
from typing import Any

from bench.codec import traffic
from term.core import protocol as p
from tests.support.m0_size import REPORT_FIRMWARE_TEXT, _make, _size, m0_sizes

FIRMWARE = Path(__file__).resolve().parent.parent / "firmware"
CHUNK = 32  # bytes per read fed to both decoders


def host_rates(seconds: int, repeats: int = 5) -> dict[str, Any]:
    """Decode rates of the C decoder (inside its own process) and the Python decoder on the same stream."""
    enc = p.Encoder()
    stream = b"".join(enc.encode(pkt) for pkt in traffic(seconds))
    frames = enc.frames
    with tempfile.TemporaryDirectory(prefix="qp-host-") as tmp:
        build = Path(tmp)
        runner = build / "qp_runner"
        _make(build, str(runner))
        proc = subprocess.run([str(runner)], input=f"bench {repeats} {CHUNK} {stream.hex()}\n", capture_output=True,
                              text=True, check=True)
    _, ns, packets = proc.stdout.split()
    assert int(packets) == frames * repeats, (packets, frames)
    c_s = int(ns) / 1e9 / repeats

    slices = [stream[i : i + CHUNK] for i in range(0, len(stream), CHUNK)]
    best = float("inf")
    for _ in range(repeats):
        dec = p.Decoder()
        t0 = time.perf_counter()
        for s in slices:
            dec.feed(s)
        best = min(best, time.perf_counter() - t0)
        assert dec.stats.frames_ok == frames
    return {
        "host_frames": frames,
        "host_bytes": len(stream),
        "c_decode_bytes_per_s": round(len(stream) / c_s),
        "c_decode_frames_per_s": round(frames / c_s),
        "python_decode_frames_per_s": round(frames / best),
        "c_over_python": round(best / c_s, 1),
        "cc": subprocess.run(["cc", "-dumpversion"], capture_output=True, text=True).stdout.strip(),
    }


M0_FLASH_GOAL, M0_RAM_GOAL = 40 * 1024, 8 * 1024  # issue 37
M0_STACK = 0x800  # QB_STACK in firmware/m0/nrf51822_s110.ld


def cboard_m0_sizes() -> dict[str, Any]:
    """The whole C board's nRF51822 image, linked, its size, and its boot on the emulated Cortex-M0."""
    from fcb_sim.hosts import m0boot

    with tempfile.TemporaryDirectory(prefix="qb-m0-") as tmp:
        build = Path(tmp)
        _make(build, "board-m0")
        elf = build / "m0" / "board.elf"
        text, data, bss = _size(elf)
        boot = m0boot.boot(elf) if m0boot.available() is None else None
        loop = m0boot.run(elf, ms=1000.0) if boot else None
    if boot is None:
        print(f"bench.firmware: no boot figures: {m0boot.available()}")
    elif boot.faults or (loop and loop.faults):
        raise SystemExit(f"bench.firmware: the M0 image did not boot or run: {boot.faults} {loop and loop.faults}")
    loads = [pk.cpu_load for pk in loop.packets if isinstance(pk, p.Status)] if loop else []
    return {"cboard_m0_flash_bytes": text + data, "cboard_m0_ram_bytes": data + bss,
            "cboard_m0_stack_reserved_bytes": M0_STACK,
            "cboard_m0_flash_margin_bytes": M0_FLASH_GOAL - text - data,
            "cboard_m0_ram_margin_bytes": M0_RAM_GOAL - data - bss - M0_STACK,
            "cboard_m0_boot_to_hello_instructions": boot.instructions if boot else None,
            "cboard_m0_boot_to_hello_ms": round(boot.ms, 2) if boot else None,
            "cboard_m0_safe_cpu_load_pct": loads[-1] if loads else None,
            "cboard_m0_share_of_report_firmware_text_pct": round(100 * (text + data) / REPORT_FIRMWARE_TEXT, 1),
            "report_firmware_text_bytes": REPORT_FIRMWARE_TEXT}


def flights(seeds: int = 8, duration: float = 15.0) -> dict[str, Any]:
    """The boards flown side by side (module docstring): mean figures per board and scenario, and the ratios."""
    from fcb_sim.hosts.cboard import fly_board

    out: dict[str, Any] = {"flight_seeds": seeds, "flight_duration_s": duration}
    for scenario, key in (("hover", "full"), ("height-hold", "height"), ("raw-hover", "raw")):
        for kind in ("python", "c", "c-float"):
            runs = [fly_board(kind, scenario, seed, duration) for seed in range(1, seeds + 1)]
            name = kind.replace("-", "_")
            out[f"flight_{key}_{name}_attitude_rms_deg"] = round(sum(r["attitude_rms_deg"] for r in runs) / seeds, 4)
            out[f"flight_{key}_{name}_height_rms_m"] = round(sum(r["height_rms_m"] for r in runs) / seeds, 4)
            out[f"flight_{key}_{name}_wall_s"] = round(sum(r["wall_s"] for r in runs), 2)
            bad = [r for r in runs if r["naks"] or r["mode"] != key.upper()]
            if bad:
                out[f"flight_{key}_{name}_faults"] = bad
        for fig in ("attitude_rms_deg", "height_rms_m"):
            for name in ("c", "c_float"):
                ratio = out[f"flight_{key}_{name}_{fig}"] / max(1e-9, out[f"flight_{key}_python_{fig}"])
                out[f"flight_{key}_{name}_over_python_{fig.split('_')[0]}"] = round(ratio, 3)
    return out


def measure(seconds: int = 60, seeds: int = 8, m0_only: bool = False) -> dict[str, Any]:
    out: dict[str, Any] = {"benchmark": "firmware"}
    if shutil.which("make") is None or shutil.which("cc") is None:
        print("bench.firmware: no C compiler (cc) or make: nothing to measure")
        return {**out, "skipped": "no C compiler"}
    if shutil.which("arm-none-eabi-gcc") is None:
        print("bench.firmware: arm-none-eabi-gcc not installed: no Cortex-M0 sizes (apt-get install gcc-arm-none-eabi)")
        out.update(dict.fromkeys(("library_flash_bytes", "board_flash_bytes", "board_ram_bytes",
                                  "cboard_m0_flash_bytes", "cboard_m0_ram_bytes")))
    else:
        out.update(m0_sizes())
        out.update(cboard_m0_sizes())
    if m0_only:
        return out
    out.update(host_rates(seconds))
    out.update(flights(seeds))
    out["machine"] = platform.machine()
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=int, default=60, help="simulated seconds of traffic (default 60)")
    parser.add_argument("--seeds", type=int, default=8, help="seeds of each flight (default 8)")
    parser.add_argument("--m0-only", action="store_true", help="the Cortex-M0 sizes and boot alone")
    args = parser.parse_args()
    if args.seconds < 1 or args.seeds < 1:
        raise SystemExit("bench.firmware: --seconds and --seeds must be at least 1")
    print(json.dumps(measure(args.seconds, args.seeds, args.m0_only)))


if __name__ == "__main__":
    main()
