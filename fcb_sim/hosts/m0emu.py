"""The board's task bodies executed on an emulated Cortex-M0: instructions and cycles from execution, not a model.

``make -C firmware m0-tasks`` builds firmware/board/ikf_q.c (the RAW filter) and ctl_q.c (the RAW control step)
with arm-none-eabi-gcc -mcpu=cortex-m0 -mthumb -Os, as the board's firmware is built, into an ELF (in the user's
cache: fcb_sim/cbuild.py) whose entry points (firmware/m0/tasks_main.c) run one step on buffers in RAM.
``M0Tasks`` loads it into unicorn (the QEMU CPU behind the ``unicorn`` package, Cortex-M0 model, Thumb code) and
calls one step at a time, counting every executed instruction and its cycles.

Cycles per instruction: ARM, "Cortex-M0 Technical Reference Manual" r0p0 (DDI 0432C), section 3.3, Table 3-1
("Cortex-M0 instruction summary"): data processing 1; MULS 1 (the fast multiplier; 32 with the small one);
LDR/STR of any width 2; LDM/STM 1+N, PUSH 1+N, POP 1+N, POP with PC 4+N (N registers, PC not counted); B<cond>
3 taken, 1 not; B 3; BL 4; BX and BLX 3; ADD or MOV to PC 3; the 32-bit MSR, MRS, DMB, DSB, ISB 4. The
nRF51822 runs code from flash at 16 MHz without wait states [ASSUMED: the nRF51 reference manual gives no wait
states for the flash at 16 MHz; if it had any, every figure here is a lower bound]. Interrupts are not emulated:
these are the cycles of the task's own work, which Figure 14's rows hold together with the interrupts that hit
it (docs/board.md, "Cycles from execution").

fcb_sim.hosts.m0boot runs the whole board's nRF51822 image the same way (this cycle table, :func:`block_cost`),
from its reset vector, with a model of the peripherals it starts.

Needs ``unicorn`` (the bench and test extras, never the flying install) and arm-none-eabi-gcc; ``available()``
says in one line why not, and the callers skip with that line.
"""

from __future__ import annotations

import os
import shutil
import struct
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from fcb_sim import cbuild

ELF = "m0/tasks.elf"
CPU_HZ = 16_000_000
STACK_TOP = 0x2000_8000
RETURN = 0x3000_0000  # a page holding a branch to itself: the emulation stops when a step returns here
NO_ARM = "arm-none-eabi-gcc is not installed (apt-get install gcc-arm-none-eabi): no Cortex-M0 build to emulate"
NO_UNICORN = "the unicorn package is not installed (pip install unicorn; the bench and test extras have it)"


def available() -> str | None:
    """None if the tasks can be built and emulated here, else why not (one line)."""
    try:
        import unicorn  # noqa: F401
    except ImportError:
        return NO_UNICORN
    if shutil.which(os.environ.get("ARM_CC", "arm-none-eabi-gcc")) is None or shutil.which("make") is None:
        return NO_ARM
    return None


def build(build_dir: Path | None = None) -> Path:
    """The M0 ELF (``make m0-tasks``), built once per version of the sources into the user's cache
    (fcb_sim/cbuild.py) or ``build_dir``. RuntimeError (one line) if it cannot be."""
    why = available()
    if why:
        raise RuntimeError(why)
    try:
        return cbuild.build("m0-tasks", [ELF], out=build_dir, tools=[os.environ.get("ARM_CC", "arm-none-eabi-gcc")],
                            missing=NO_ARM, what="the M0 tasks") / ELF
    except cbuild.BuildError as e:
        raise RuntimeError(str(e)) from None


# --- a little ELF32 reader: the loadable segments and the symbols -------------------------------------------

def read_elf(data: bytes) -> tuple[list[tuple[int, bytes, int]], dict[str, tuple[int, int]]]:
    """(vaddr, file bytes, memory size) of each PT_LOAD segment, and {symbol: (address, size)}."""
    if data[:4] != b"\x7fELF" or data[4] != 1 or data[5] != 1:
        raise ValueError("not a 32-bit little-endian ELF")
    phoff, shoff = struct.unpack_from("<II", data, 28)
    phentsize, phnum, shentsize, shnum = struct.unpack_from("<HHHH", data, 42)
    segments = []
    for i in range(phnum):
        ptype, off, vaddr, _paddr, filesz, memsz = struct.unpack_from("<IIIIII", data, phoff + i * phentsize)
        if ptype == 1:
            segments.append((vaddr, data[off:off + filesz], memsz))
    sections = [struct.unpack_from("<IIIIIIIIII", data, shoff + i * shentsize) for i in range(shnum)]
    symbols: dict[str, tuple[int, int]] = {}
    for sh in sections:
        if sh[1] != 2:  # SHT_SYMTAB
            continue
        strtab = sections[sh[6]]
        for j in range(sh[5] // 16):
            name, value, size, _info, _other, _shndx = struct.unpack_from("<IIIBBH", data, sh[4] + j * 16)
            end = data.index(b"\0", strtab[4] + name)
            if name:
                symbols[data[strtab[4] + name:end].decode()] = (value, size)
    return segments, symbols


# --- the cycle table ---------------------------------------------------------------------------------------

COND_BRANCH = -1  # 1 cycle, or 3 when taken: settled when the next block starts


def thumb_cycles(hw: int, hw2: int = 0) -> int:
    """Cycles of one Thumb instruction (first halfword ``hw``) by the Cortex-M0 TRM's Table 3-1 (module
    docstring); ``COND_BRANCH`` for a conditional branch."""
    top5 = hw >> 11
    if top5 in (0b11101, 0b11110, 0b11111):  # 32-bit: BL, or MSR/MRS/barriers
        return 4
    if hw & 0xF800 == 0xE000:  # B
        return 3
    if hw & 0xF000 == 0xD000:
        return 1 if (hw >> 8) & 0xF in (0xE, 0xF) else COND_BRANCH  # UDF, SVC
    if hw & 0xFF00 == 0x4700:  # BX, BLX
        return 3
    if hw & 0xFD00 == 0x4400:  # ADD / MOV with high registers: to PC it is a branch
        return 3 if (hw & 7) | ((hw >> 4) & 8) == 15 else 1
    if hw & 0xF800 == 0x4800 or hw & 0xF000 == 0x5000 or hw & 0xE000 == 0x6000 or hw & 0xE000 == 0x8000:
        return 2  # LDR literal, register offset, immediate (word, byte, halfword), SP relative
    if hw & 0xF000 == 0xC000:  # LDM, STM
        return 1 + bin(hw & 0xFF).count("1")
    if hw & 0xFE00 == 0xB400:  # PUSH (LR counts as a register)
        return 1 + bin(hw & 0x1FF).count("1")
    if hw & 0xFE00 == 0xBC00:  # POP, and with PC a return
        return (4 if hw & 0x100 else 1) + bin(hw & 0xFF).count("1")
    return 1


def block_cost(code: bytes, address: int) -> tuple[int, int, int]:
    """(cycles without its last conditional branch, instructions, that branch's fall-through or 0) of the basic
    block ``code`` at ``address``."""
    cycles = n = i = end = 0
    while i < len(code):
        hw = code[i] | code[i + 1] << 8
        wide = hw >> 11 in (0b11101, 0b11110, 0b11111)
        c = thumb_cycles(hw)
        i += 4 if wide else 2
        n += 1
        if c == COND_BRANCH:
            end = address + i  # its fall-through; the block ends with it
        else:
            cycles += c
    return cycles, n, end


@dataclass
class Run:
    """What one call executed."""

    instructions: int = 0
    cycles: int = 0
    blocks: int = 0
    op_counts: dict[str, int] = field(default_factory=dict)

    @property
    def us(self) -> float:
        return self.cycles * 1e6 / CPU_HZ


class M0Tasks:
    """The task ELF in an emulated Cortex-M0; ``call(name)`` runs one entry point and returns its ``Run``."""

    def __init__(self, elf: Path | None = None) -> None:
        from unicorn import UC_ARCH_ARM, UC_HOOK_BLOCK, UC_MODE_MCLASS, UC_MODE_THUMB, Uc
        from unicorn.arm_const import UC_CPU_ARM_CORTEX_M0

        data = Path(elf or build()).read_bytes()
        segments, self.symbols = read_elf(data)
        uc = Uc(UC_ARCH_ARM, UC_MODE_THUMB | UC_MODE_MCLASS)
        uc.ctl_set_cpu_model(UC_CPU_ARM_CORTEX_M0)
        top = max(v + m for v, _b, m in segments)
        uc.mem_map(0, (top + 0xFFFF) & ~0xFFFF)
        for vaddr, blob, _mem in segments:
            uc.mem_write(vaddr, blob)
        uc.mem_map(STACK_TOP - 0x8000, 0x8000)
        uc.mem_map(RETURN, 0x1000)
        uc.mem_write(RETURN, b"\xfe\xe7")  # b .
        self.uc = uc
        # (block, size) -> (cycles without its last conditional branch, instructions, that branch's fall-through)
        self._costs: dict[tuple[int, int], tuple[int, int, int]] = {}
        self._pending = 0  # fall-through address of a conditional branch that ended the last block
        self._run = Run()
        uc.hook_add(UC_HOOK_BLOCK, self._block)

    def addr(self, symbol: str) -> int:
        return self.symbols[symbol][0]

    def _block_cost(self, address: int, size: int) -> tuple[int, int, int]:
        return block_cost(bytes(self.uc.mem_read(address, size)), address)

    def _block(self, uc: Any, address: int, size: int, _user: Any) -> None:
        run = self._run
        if self._pending:
            run.cycles += 1 if address == self._pending else 3
            self._pending = 0
        cost = self._costs.get((address, size))
        if cost is None:
            cost = self._costs[(address, size)] = self._block_cost(address, size)
        run.cycles += cost[0]
        run.instructions += cost[1]
        run.blocks += 1
        self._pending = cost[2]

    def call(self, name: str, *args: int) -> Run:
        """Run ``name(args...)`` (up to four integer arguments) to its return; its instructions and cycles."""
        from unicorn.arm_const import UC_ARM_REG_LR, UC_ARM_REG_R0, UC_ARM_REG_SP

        uc = self.uc
        for i, a in enumerate(args):
            uc.reg_write(UC_ARM_REG_R0 + i, a & 0xFFFFFFFF)
        uc.reg_write(UC_ARM_REG_SP, STACK_TOP)
        uc.reg_write(UC_ARM_REG_LR, RETURN | 1)
        self._run = run = Run()
        self._pending = 0
        uc.emu_start(self.addr(name) | 1, RETURN, count=50_000_000)
        if self._pending:  # a conditional branch straight to the return address: taken
            run.cycles += 3
            self._pending = 0
        return run

    def write(self, symbol: str, data: bytes, offset: int = 0) -> None:
        self.uc.mem_write(self.addr(symbol) + offset, data)

    def read(self, symbol: str, size: int | None = None, offset: int = 0) -> bytes:
        return bytes(self.uc.mem_read(self.addr(symbol) + offset, size or self.symbols[symbol][1]))


# --- the tasks on recorded data, beside the host build ------------------------------------------------------

GAINS_Q16 = (26214, 111 << 16, 800 << 16)  # P1 0.4, P2 111, yaw P 800 (Table 1, fcb_sim.world.constants.Gains)


@dataclass
class TaskCycles:
    """Per-sample cycles of each task (the filter: ikf's step, its predicted attitude and the angles the law reads;
    the control: the law and the mixing, Figure 14's control row), and every output that differed from the
    host build's."""

    filter: list[int] = field(default_factory=list)
    control: list[int] = field(default_factory=list)
    instructions: dict[str, list[int]] = field(default_factory=lambda: {"filter": [], "control": []})
    mismatches: list[str] = field(default_factory=list)

    def summary(self, task: str) -> dict[str, float]:
        xs = sorted(getattr(self, task))
        n = len(xs)
        mean = sum(xs) / n
        sd = (sum((x - mean) ** 2 for x in xs) / max(1, n - 1)) ** 0.5
        ins = self.instructions[task]
        p99 = xs[min(n - 1, int(0.99 * n))]
        us = 1e6 / CPU_HZ
        return {"n": n, "cycles_mean": round(mean, 1), "cycles_sd": round(sd, 1), "cycles_max": xs[-1],
                "cycles_p99": p99, "instructions_mean": round(sum(ins) / n, 1), "us_mean": round(mean * us, 1),
                "us_p99": round(p99 * us, 1), "us_max": round(xs[-1] * us, 1)}


def run_tasks(samples: list[tuple[float, ...]], seed: int = 1, elf: Path | None = None,
              decimation: int = 1, lite: bool = False) -> TaskCycles:
    """The filter step and the control step on the M0 and on the host, fed the same inputs: ``samples`` are
    (gx, gy, gz, ax, ay, az, dt) rows (rad/s, m/s², s; the first starts the filter), the sticks pseudo-random
    from ``seed``; the filter's gravity part every ``decimation``-th sample; ``lite``: the variant cut to fit
    (ikf_lite.py, its gravity part spread over the decimation, its angles ctlq_angles_lite). Returns each step's
    cycles, and every output that differed (none, or it is a fault)."""
    import ctypes
    import random

    from fcb_sim.estimation.ikf_fixed import to_q
    from fcb_sim.estimation.native import STATE_FIELDS, NativeIKFQ, NativeIKFQL, library
    from fcb_sim.world.constants import RATE_LSB_PER_RAD_S

    lib = library()
    if lib is None:
        raise RuntimeError("the host build of firmware/board is not available (fcb_sim.estimation.native.why_not())")
    m0 = M0Tasks(elf)
    host = (NativeIKFQL if lite else NativeIKFQ)(decimation=decimation)
    angles = lib.ctlq_angles_lite if lite else lib.ctlq_angles
    host.update(*samples[0])  # starts it (the start is no per-sample work)
    host._lib.ikfq_set_dt(host._s, samples[1][6])
    # the M0 sets itself up from the integers alone (ikfq_init_q: no doubles on the board), then takes the host's
    # state after the first sample (one struct layout on both: checked by every output below)
    consts = host.consts(samples[1][6])
    m0.write("tm_formats", bytes(host._fmt))
    m0.write("tm_consts", bytes(_consts_struct(consts)))
    m0.call("tm_filter_init")
    init_state = m0.read("tm_filter")
    m0.write("tm_filter", host.raw_state())
    m0.write("tm_gains", struct.pack("<3i", *GAINS_Q16))
    rng = random.Random(seed)
    out = TaskCycles()
    gains = (ctypes.c_int32 * 3)(*GAINS_Q16)
    ctl_in = (ctypes.c_int32 * 11)()
    ae_host = (ctypes.c_int16 * 4)()
    for i, row in enumerate(samples[1:]):
        g = tuple(to_q(v, 16) for v in row[:3])
        a = tuple(to_q(v, 16) for v in row[3:6])
        q_host = host.step_q(g, a, row[6])  # type: ignore[arg-type]
        m0.write("tm_g", struct.pack("<3i", *g))
        m0.write("tm_a", struct.pack("<3i", *a))
        run = m0.call("tm_filter_step")
        out.filter.append(run.cycles)
        out.instructions["filter"].append(run.instructions)
        q_m0 = struct.unpack("<4i", m0.read("tm_q"))
        phi, theta = ctypes.c_int32(), ctypes.c_int32()
        angles((ctypes.c_int32 * 4)(*q_host), ctypes.byref(phi), ctypes.byref(theta))
        angles_m0 = struct.unpack("<2i", m0.read("tm_angles"))
        if q_m0 != q_host or angles_m0 != (phi.value, theta.value):
            out.mismatches.append(f"filter sample {i}: M0 {q_m0} {angles_m0} host {q_host} {phi, theta}")
        # the control step on that attitude, the sample's rates (gyro LSB, FRD) and random sticks
        rates = [round(row[0] * RATE_LSB_PER_RAD_S), -round(row[1] * RATE_LSB_PER_RAD_S),
                 -round(row[2] * RATE_LSB_PER_RAD_S)]
        r = rng.randint
        sticks = [r(-32767, 32767), r(-32767, 32767), r(-32767, 32767), r(0, 32767)]
        vals = [*q_host, *rates, *sticks]
        ctl_in[:] = vals
        m0.write("tm_in", struct.pack("<11i", *vals))
        run = m0.call("tm_control_step")
        out.control.append(run.cycles)
        out.instructions["control"].append(run.instructions)
        lib.ctlq_law(ctypes.cast(gains, ctypes.c_void_p), ctypes.cast(ctl_in, ctypes.c_void_p), phi, theta, ae_host)
        ae_m0 = struct.unpack("<4h", m0.read("tm_ae"))
        if ae_m0 != tuple(ae_host):
            out.mismatches.append(f"control sample {i}: M0 {ae_m0} host {tuple(ae_host)}")
    if not _same_constants(init_state, host.raw_state()):
        out.mismatches.append("the M0's ikfq_init_q gave other constants than the host's ikfq_init")
    m0.call("tm_filter_export")
    st_m0 = struct.unpack(f"<{len(STATE_FIELDS)}q", m0.read("tm_state"))
    if st_m0 != tuple(host.state().values()):
        out.mismatches.append("filter state after the run differs")
    return out


def _consts_struct(consts: dict[str, int]) -> Any:
    from fcb_sim.estimation.native import _Consts

    return _Consts(**consts)


def _same_constants(a: bytes, b: bytes) -> bool:
    """The constants' bytes of two ikfq_t: qg_shift .. rest_time (offsets 8 .. 80) and dtq .. kbq (104 .. 124);
    the doubles between them are the host's alone."""
    return a[8:80] == b[8:80] and a[104:124] == b[104:124]


EXCERPT = Path(__file__).resolve().parents[2] / "tests" / "fixtures" / "broad_07_fast_rotation_excerpt.csv.gz"
EXCERPT_ROWS = (2450, 2850)  # fast hand-held rotation (the excerpt is 8.5 s still, then moving)


def recorded_samples(path: Path = EXCERPT, rows: tuple[int, int] = EXCERPT_ROWS) -> list[tuple[float, ...]]:
    """(gx, gy, gz, ax, ay, az, dt) of a BROAD trial: its first row (which starts the filter), then ``rows``."""
    import csv
    import gzip

    out: list[tuple[float, ...]] = []
    with gzip.open(path, "rt", newline="") as fh:
        t_prev = None
        for i, row in enumerate(csv.DictReader(fh)):
            t = float(row["t"])
            if t_prev is not None and (i == 1 or rows[0] <= i < rows[1]):
                out.append((*(float(row[k]) for k in ("gx", "gy", "gz", "ax", "ay", "az")), t - t_prev))
            t_prev = t
            if i >= rows[1]:
                break
    return out


DECIMATIONS = (4, 8)  # the exact twin decimated, measured beside it (docs/attitude.md, "Decimation")
LITE = (1, 4, 8)  # the variant cut to fit (ikf_lite), its gravity part spread over N samples; 4 is the default's


def emulated_table(samples: list[tuple[float, ...]] | None = None) -> tuple[dict[str, tuple[float, float]],
                                                                              TaskCycles]:
    """fcb_sim.board.timing.M0_EMULATED_US measured again: (mean, p99) µs of each task, the decimated filters too
    ("filter/ikf/fixed/decimation4": the gravity part every 4th sample) and the lite ones ("filter/ikf/lite4": the
    variant that fits, its gravity part spread over 4 samples); and the exact twin's run itself (the other runs'
    mismatches are added to it)."""
    samples = samples or recorded_samples()
    run = run_tasks(samples)
    f, c = run.summary("filter"), run.summary("control")
    table = {"filter/ikf/fixed": (f["us_mean"], f["us_p99"]), "control_raw": (c["us_mean"], c["us_p99"])}
    for n in DECIMATIONS:
        d = run_tasks(samples, decimation=n)
        run.mismatches += [f"decimation {n}: {m}" for m in d.mismatches]
        s = d.summary("filter")
        table[f"filter/ikf/fixed/decimation{n}"] = (s["us_mean"], s["us_p99"])
    for n in LITE:
        d = run_tasks(samples, decimation=n, lite=True)
        run.mismatches += [f"lite {n}: {m}" for m in d.mismatches]
        s = d.summary("filter")
        table[f"filter/ikf/lite{n}"] = (s["us_mean"], s["us_p99"])
    return table, run


def decimated_cycles(n: int, samples: list[tuple[float, ...]] | None = None, lite: bool = False) -> list[int]:
    """The filter task's cycles sample by sample with the gravity part every ``n``-th (a light, light, ..., heavy
    pattern: what a board charging each sample its own cost sees; ``lite``: its pieces spread over the n)."""
    return run_tasks(samples or recorded_samples(), decimation=n, lite=lite).filter
