"""The C board's nRF51822 image booted on an emulated Cortex-M0, from its reset vector to its first frames on UART0.

``make -C firmware board-m0`` links the whole board with its vector table, reset handler and the S110 memory map
(firmware/m0/startup_nrf51.c, nrf51822_s110.ld, firmware/board/hal_m0.c). :func:`boot` loads that ELF's flash
image (the load addresses: .data's initial values stay in flash, as a programmer writes them), fills the RAM with
0xA5 (a reset handler that does not zero .bss is seen), and starts the CPU as the SoftDevice's MBR hands over: SP
from the application's vector table word 0, PC from word 1. The instructions run in unicorn (the Cortex-M0 model of
fcb_sim.hosts.m0emu), their cycles counted by the same table; the peripherals the image touches are
:class:`NRF51` below, a register model strict where a real board would fail silently:

- CLOCK: HFCLKSTARTED and LFCLKSTARTED come after their start tasks; LFCLKSRC is recorded.
- RTC1: COUNTER counts 32768 Hz from the emulated cycles (16 MHz) once TASKS_START came with the LFCLK running,
  at PRESCALER + 1 ticks a count; before that it reads 0, as the real one does.
- UART0: a byte written to TXD leaves only when the UART is enabled (ENABLE 4), its transmitter started
  (TASKS_STARTTX), its TXD pin selected and set up in the GPIO as an output driven high, at 115200 baud
  (0x01D7E000), with the 16 MHz crystal running; else the write is a fault and the run stops there, naming it.
  A byte takes 10 bit times (1388 cycles) to leave: TXDRDY reads 1 from then on, and a byte written before is a
  fault. Bytes to receive enter the 6-byte FIFO, RXDRDY raised while one waits, RXD giving the next.
- RTC1's COMPARE0, with its interrupt enabled, is when the loop's sleep (WFE) ends; NVIC and SCB (ISER, ICPR,
  SCR) are recorded. Interrupts are not emulated mid-instruction stream: :meth:`M0Image.run` hands received bytes
  to UART0_IRQHandler at the loop's next sleep (the functions are the board's, their timing is not).
- A write to the SoftDevice's RAM (below 0x20002000) or to flash is a fault.
Any other peripheral register reads what was last written to it (0 at reset).

The bytes from TXD go through term.core.protocol's Decoder. :func:`boot` ends when ``until`` packets have left (the
board sends Hello, then the BOOT event); :func:`run` runs the loop for a given emulated time (the board's timers,
its telemetry and heartbeats, what it answers to bytes sent to it); both stop at a fault, or after
``max_instructions``.
"""

from __future__ import annotations

import struct
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from fcb_sim import cbuild
from fcb_sim.hosts.m0emu import CPU_HZ, NO_ARM, available, block_cost, read_elf
from term.core import protocol as p

ELF = "m0/board.elf"
APP_FLASH = 0x0001_8000  # S110 8.0's MBR and SoftDevice below (firmware/m0/nrf51822_s110.ld)
FLASH_SIZE = 0x0004_0000  # nRF51822-QFAA: 256 KB
RAM, RAM_SIZE = 0x2000_0000, 0x4000  # 16 KB
APP_RAM = 0x2000_2000  # S110 8.0's 8 KB below
PERIPHERALS, PERIPHERALS_SIZE = 0x4000_0000, 0x2_0000
SCS = 0xE000_E000
RTC_HZ = 32768
UART_115200 = 0x01D7_E000
UART_ENABLED = 4
LFCLK_SYNTH = 2

# register addresses (nRF51 Series Reference Manual v3.0; the same as firmware/board/hal_m0.c's)
CLOCK_TASKS_HFCLKSTART, CLOCK_TASKS_LFCLKSTART = 0x4000_0000, 0x4000_0008
CLOCK_EVENTS_HFCLKSTARTED, CLOCK_EVENTS_LFCLKSTARTED, CLOCK_LFCLKSRC = 0x4000_0100, 0x4000_0104, 0x4000_0518
RTC1_TASKS_START, RTC1_TASKS_STOP, RTC1_COUNTER, RTC1_PRESCALER = 0x4001_1000, 0x4001_1004, 0x4001_1504, 0x4001_1508
UART0_TASKS_STARTRX, UART0_TASKS_STARTTX = 0x4000_2000, 0x4000_2008
UART0_EVENTS_RXDRDY, UART0_EVENTS_TXDRDY, UART0_INTENSET = 0x4000_2108, 0x4000_211C, 0x4000_2304
UART0_ENABLE, UART0_PSELTXD, UART0_PSELRXD = 0x4000_2500, 0x4000_250C, 0x4000_2514
UART0_RXD, UART0_TXD, UART0_BAUDRATE = 0x4000_2518, 0x4000_251C, 0x4000_2524
RTC1_EVENTS_COMPARE0, RTC1_INTENSET, RTC1_CC0 = 0x4001_1140, 0x4001_1304, 0x4001_1540
NVIC_ISER, SCB_SCR = 0xE000_E100, 0xE000_ED10
GPIO, GPIO_OUTSET, GPIO_PIN_CNF = 0x5000_0000, 0x5000_0508, 0x5000_0700  # PIN_CNF[n] at + 4 n; DIR is bit 0
UART0_IRQ, RTC1_IRQ = 2, 17
BYTE_CYCLES = 10 * CPU_HZ // 115200  # a start bit, 8 data bits and a stop bit at 115200 baud: 1388 cycles
RX_FIFO = 6  # the UART's receive FIFO (nRF51 RM, UART: "RXD ... 6 bytes")


def build(build_dir: Path | None = None) -> Path:
    """The board's M0 image (``make board-m0``), built once per version of the sources (fcb_sim/cbuild.py) or into
    ``build_dir``. RuntimeError (one line) if it cannot be."""
    why = available()
    if why:
        raise RuntimeError(why)
    try:
        return cbuild.build("board-m0", [ELF], out=build_dir, tools=["arm-none-eabi-gcc"], missing=NO_ARM,
                            what="the C board's M0 image") / ELF
    except cbuild.BuildError as e:
        raise RuntimeError(str(e)) from None


def load_image(data: bytes) -> list[tuple[int, bytes]]:
    """(physical address, bytes) of each PT_LOAD segment with bytes in the file: what a programmer writes."""
    phoff = struct.unpack_from("<I", data, 28)[0]
    phentsize, phnum = struct.unpack_from("<HH", data, 42)
    out = []
    for i in range(phnum):
        ptype, off, _vaddr, paddr, filesz, _memsz = struct.unpack_from("<IIIIII", data, phoff + i * phentsize)
        if ptype == 1 and filesz:
            out.append((paddr, data[off:off + filesz]))
    return out


class NRF51:
    """The registers of the nRF51822 the image touches (module docstring). ``cycles`` is the CPU's count, which
    the RTC follows; ``faults`` what a real board would not have done; ``tx`` the bytes that left UART0."""

    def __init__(self) -> None:
        self.regs: dict[int, int] = {}
        self.cycles = 0
        self.rtc_start_cycles: int | None = None
        self.tx = bytearray()
        self.tx_busy_until = 0  # the cycle the byte in TXD has left by
        self.rx: list[int] = []  # bytes in the receive FIFO
        self.faults: list[str] = []
        self.log: list[tuple[int, int]] = []  # (address, value) of every write, in order

    def reg(self, address: int) -> int:
        return self.regs.get(address, 0)

    def counter(self) -> int:
        if self.rtc_start_cycles is None:
            return 0
        ticks = (self.cycles - self.rtc_start_cycles) * RTC_HZ // CPU_HZ
        return ticks // (self.reg(RTC1_PRESCALER) + 1) & 0xFF_FFFF

    def read(self, address: int) -> int:
        if address == RTC1_COUNTER:
            return self.counter()
        if address == UART0_EVENTS_TXDRDY:
            return int(bool(self.reg(address)) and self.cycles >= self.tx_busy_until)
        if address == UART0_RXD:  # the next byte of the FIFO, and RXDRDY again while more wait
            byte = self.rx.pop(0) if self.rx else 0
            if self.rx:
                self.regs[UART0_EVENTS_RXDRDY] = 1
            return byte
        return self.reg(address)

    def receive(self, data: bytes) -> int:
        """Bytes arriving on RXD (those the FIFO has room for; how many it took). Each raises RXDRDY."""
        if self.reg(UART0_ENABLE) != UART_ENABLED or not self.reg(UART0_TASKS_STARTRX):
            return 0
        n = min(len(data), RX_FIFO - len(self.rx))
        self.rx += data[:n]
        if n:
            self.regs[UART0_EVENTS_RXDRDY] = 1
        return n

    def wake_cycles(self) -> int | None:
        """The cycle RTC1's COMPARE0 next matches at (None: not armed to interrupt, or the RTC stopped)."""
        if self.rtc_start_cycles is None or not self.reg(RTC1_INTENSET) & 1 << 16:
            return None
        ahead = (self.reg(RTC1_CC0) - self.counter()) & 0xFF_FFFF or 1 << 24
        per_tick = CPU_HZ * (self.reg(RTC1_PRESCALER) + 1)
        elapsed = (self.cycles - self.rtc_start_cycles) * RTC_HZ
        # the first cycle at which the counter reads CC0
        return self.rtc_start_cycles + -(-((elapsed // per_tick + ahead) * per_tick) // RTC_HZ)

    def write(self, address: int, value: int) -> None:
        self.log.append((address, value))
        if address == CLOCK_TASKS_HFCLKSTART and value:
            self.regs[CLOCK_EVENTS_HFCLKSTARTED] = 1
        elif address == CLOCK_TASKS_LFCLKSTART and value:
            self.regs[CLOCK_EVENTS_LFCLKSTARTED] = 1
        elif address == RTC1_TASKS_START and value:
            if not self.reg(CLOCK_EVENTS_LFCLKSTARTED):
                self.faults.append("RTC1 started before the LFCLK runs: its COUNTER would stay 0")
            elif self.rtc_start_cycles is None:
                self.rtc_start_cycles = self.cycles
        elif address == RTC1_TASKS_STOP and value:
            self.rtc_start_cycles = None
        elif address == UART0_TXD:
            why = self.uart_not_ready()
            if why:
                self.faults.append(f"byte {len(self.tx)} written to UART0 TXD {why}")
                return
            if self.cycles < self.tx_busy_until:
                self.faults.append(f"byte {len(self.tx)} written to TXD before the last one left (no TXDRDY wait)")
                return
            self.tx.append(value & 0xFF)
            self.regs[UART0_EVENTS_TXDRDY] = 1
            self.tx_busy_until = self.cycles + BYTE_CYCLES
            return
        self.regs[address] = value

    def uart_not_ready(self) -> str:
        """Why a byte written to TXD now would not leave at 115200 baud ('' when it would)."""
        if self.reg(UART0_ENABLE) != UART_ENABLED:
            return f"with UART0 not enabled (ENABLE {self.reg(UART0_ENABLE)})"
        if not self.reg(UART0_TASKS_STARTTX):
            return "before TASKS_STARTTX"
        if self.regs.get(UART0_PSELTXD, 0xFFFF_FFFF) > 31:
            return "with no TXD pin selected"
        pin = self.regs[UART0_PSELTXD]
        if not self.reg(GPIO_PIN_CNF + 4 * pin) & 1 or not self.reg(GPIO_OUTSET) >> pin & 1:
            return f"with its pin P0.{pin} not an output driven high (GPIO PIN_CNF, OUTSET)"
        if self.reg(UART0_BAUDRATE) != UART_115200:
            return f"at BAUDRATE {self.reg(UART0_BAUDRATE):#x}, not 115200"
        if not self.reg(CLOCK_EVENTS_HFCLKSTARTED):
            return "on the RC oscillator (the 16 MHz crystal not started: the baud rate is off)"
        return ""


@dataclass
class Boot:
    """What one boot did."""

    packets: list[Any] = field(default_factory=list)
    tx: bytes = b""
    faults: list[str] = field(default_factory=list)
    instructions: int = 0
    cycles: int = 0  # the emulated time (16 MHz), the sleeps' included
    busy_cycles: int = 0  # the cycles the instructions took (the time awake)
    initial_sp: int = 0
    reset_vector: int = 0
    bss_zeroed: bool | None = None  # at qb_m0_main's first instruction (None: never reached)
    data_copied: bool | None = None
    writes: list[tuple[int, int]] = field(default_factory=list)

    @property
    def ms(self) -> float:
        return self.cycles * 1e3 / CPU_HZ


RETURN = RAM  # a branch to itself, in the SoftDevice's RAM (the image never runs there): where call() returns


class M0Image:
    """The image in an emulated nRF51822: flash written from the ELF, RAM filled with 0xA5, :class:`NRF51`'s
    registers, the guards on the SoftDevice's RAM and on flash, the cycle count. :meth:`boot` or :meth:`run` runs
    it from reset, once (a second run would start from the first one's RAM: make another image); :meth:`call` runs
    one of its functions (the toolchain's routines lean_libs.c replaces, checked by the tests)."""

    def __init__(self, elf: Path | None = None) -> None:
        from unicorn import UC_ARCH_ARM, UC_HOOK_BLOCK, UC_HOOK_MEM_WRITE, UC_MODE_MCLASS, UC_MODE_THUMB, Uc
        from unicorn.arm_const import UC_CPU_ARM_CORTEX_M0

        data = Path(elf or build()).read_bytes()
        _segments, self.symbols = read_elf(data)
        self.uc = uc = Uc(UC_ARCH_ARM, UC_MODE_THUMB | UC_MODE_MCLASS)
        uc.ctl_set_cpu_model(UC_CPU_ARM_CORTEX_M0)
        uc.mem_map(0, FLASH_SIZE)
        uc.mem_write(0, b"\xff" * FLASH_SIZE)  # erased flash
        for paddr, blob in load_image(data):
            uc.mem_write(paddr, blob)
        uc.mem_map(RAM, RAM_SIZE)
        uc.mem_write(RAM, b"\xa5" * RAM_SIZE)  # what RAM holds at power-up is not zero
        uc.mem_write(RETURN, b"\xfe\xe7")  # b .
        self.chip = NRF51()
        self.result = Boot()
        self.until = 0
        self._decoder = p.Decoder()
        self._costs: dict[tuple[int, int], tuple[int, int, int]] = {}
        self._pending = 0
        self._asleep = 0  # the WFE's address where the loop went to sleep
        uc.mmio_map(PERIPHERALS, PERIPHERALS_SIZE, self._periph_read, None, self._periph_write, None)
        uc.mmio_map(SCS, 0x1000, self._scs_read, None, self._scs_write, None)
        uc.mmio_map(GPIO, 0x1000, self._gpio_read, None, self._gpio_write, None)
        uc.hook_add(UC_HOOK_MEM_WRITE, self._guarded_write, begin=RAM, end=APP_RAM - 1)
        uc.hook_add(UC_HOOK_MEM_WRITE, self._guarded_write, begin=0, end=FLASH_SIZE - 1)
        uc.hook_add(UC_HOOK_BLOCK, self._block)

    def addr(self, symbol: str) -> int:
        return self.symbols[symbol][0]

    def _stop(self, why: str) -> None:
        self.result.faults.append(why)
        self.uc.emu_stop()

    def _periph_read(self, _uc: Any, offset: int, _size: int, _user: Any) -> int:
        return self.chip.read(PERIPHERALS + offset)

    def _periph_write(self, _uc: Any, offset: int, _size: int, value: int, _user: Any) -> None:
        chip = self.chip
        n = len(chip.tx)
        chip.write(PERIPHERALS + offset, value)
        if chip.faults:
            self._stop(chip.faults.pop())
        elif len(chip.tx) > n:
            self.result.packets += self._decoder.feed(bytes(chip.tx[n:]))
            if self.until and len(self.result.packets) >= self.until:
                self.uc.emu_stop()

    def _scs_read(self, _uc: Any, offset: int, _size: int, _user: Any) -> int:
        return self.chip.read(SCS + offset)

    def _scs_write(self, _uc: Any, offset: int, _size: int, value: int, _user: Any) -> None:
        self.chip.write(SCS + offset, value)

    def _gpio_read(self, _uc: Any, offset: int, _size: int, _user: Any) -> int:
        return self.chip.read(GPIO + offset)

    def _gpio_write(self, _uc: Any, offset: int, _size: int, value: int, _user: Any) -> None:
        self.chip.write(GPIO + offset, value)

    def _guarded_write(self, _uc: Any, _access: int, address: int, size: int, _value: int, _user: Any) -> None:
        from unicorn.arm_const import UC_ARM_REG_PC

        where = "the SoftDevice's RAM" if RAM <= address < APP_RAM else "flash"
        self._stop(f"a {size}-byte write to {where} at {address:#010x} (pc {self.uc.reg_read(UC_ARM_REG_PC):#x})")

    def _block(self, _uc: Any, address: int, size: int, _user: Any) -> None:
        c = (1 if address == self._pending else 3) if self._pending else 0
        cost = self._costs.get((address, size))
        if cost is None:
            cost = self._costs[(address, size)] = block_cost(bytes(self.uc.mem_read(address, size)), address)
        self.chip.cycles += c + cost[0]
        self.result.busy_cycles += c + cost[0]
        self.result.instructions += cost[1]
        self._pending = cost[2]

    def _at_main(self, _uc: Any, _address: int, _size: int, _user: Any) -> None:
        run, uc = self.result, self.uc
        if run.bss_zeroed is not None:
            return
        start, end = self.addr("__bss_start__"), self.addr("__bss_end__")
        run.bss_zeroed = bytes(uc.mem_read(start, end - start)) == bytes(end - start)
        d0, d1, load = self.addr("__data_start__"), self.addr("__data_end__"), self.addr("__data_load__")
        run.data_copied = bytes(uc.mem_read(d0, d1 - d0)) == bytes(uc.mem_read(load, d1 - d0))

    def boot(self, until: int = 2, max_instructions: int = 20_000_000) -> Boot:
        """Run from reset until ``until`` packets have left UART0 (module docstring)."""
        return self.run(until=until, max_instructions=max_instructions)

    def run(self, ms: float | None = None, until: int | None = None, rx: Sequence[tuple[float, bytes]] = (),
            max_instructions: int = 50_000_000) -> Boot:
        """From reset, as the MBR hands over (SP and PC from the application's vector table), until ``until``
        packets have left UART0 or ``ms`` emulated milliseconds have passed; ``rx``: (ms, bytes) to arrive on RXD,
        a byte every 10 bit times from then. Where the loop sleeps (WFE) the time moves on to the next wake-up,
        RTC1's COMPARE0 or a received byte; received bytes enter the FIFO (6 bytes) there and UART0_IRQHandler is
        run as the NVIC would run it (its registers saved around it, SP lowered by an exception frame), if UART0's
        RXDRDY interrupt is enabled. So an interrupt comes at the next sleep, never in the middle of a task: the
        functions are the board's, the interrupt timing is not."""
        from unicorn import UC_HOOK_CODE
        from unicorn.arm_const import UC_ARM_REG_PC, UC_ARM_REG_SP

        uc, run, chip = self.uc, self.result, self.chip
        if run.reset_vector:
            raise RuntimeError("M0Image.run: this image has run already (one run from reset per M0Image)")
        self.until = until or 0
        main = self.addr("qb_m0_main") & ~1
        uc.hook_add(UC_HOOK_CODE, self._at_main, begin=main, end=main)
        for wfe in self._wfe_addresses():
            uc.hook_add(UC_HOOK_CODE, self._at_wfe, begin=wfe, end=wfe)
        end = None if ms is None else round(ms * CPU_HZ / 1000)
        arrivals = sorted((round(t * CPU_HZ / 1000) + i * BYTE_CYCLES, b) for t, data in rx for i, b in enumerate(data))
        run.initial_sp, run.reset_vector = struct.unpack_from("<II", uc.mem_read(APP_FLASH, 8))
        uc.reg_write(UC_ARM_REG_SP, run.initial_sp)
        pc = run.reset_vector
        while True:
            self._asleep = 0
            try:
                uc.emu_start(pc, 0, count=max(1, max_instructions - run.instructions))
            except Exception as e:  # an unmapped access or an invalid instruction: where, in one line
                run.faults.append(f"{e} at pc {uc.reg_read(UC_ARM_REG_PC):#x}")
            if run.faults or (self.until and len(run.packets) >= self.until) or not self._asleep:
                break
            wakes = [c for c in (chip.wake_cycles(), arrivals[0][0] if arrivals else None) if c is not None]
            if not wakes or (end is not None and min(wakes) >= end):
                chip.cycles = max(chip.cycles, end or 0)
                break
            chip.cycles = max(chip.cycles, min(wakes))
            while arrivals and arrivals[0][0] <= chip.cycles and chip.receive(bytes([arrivals[0][1]])):
                arrivals.pop(0)
            if chip.reg(UART0_EVENTS_RXDRDY) and chip.reg(UART0_INTENSET) & 4 and chip.reg(NVIC_ISER) & 1 << UART0_IRQ:
                self._interrupt("UART0_IRQHandler")
            pc = (self._asleep + 2) | 1  # on after the WFE, as the wake-up does
        run.tx, run.cycles, run.writes = bytes(chip.tx), chip.cycles, chip.log
        if not run.faults and (len(run.packets) < self.until or (end is not None and chip.cycles < end)):
            run.faults.append(f"{len(run.packets)} packets, {run.ms:.1f} ms after {run.instructions} instructions "
                              f"(pc {uc.reg_read(UC_ARM_REG_PC):#x})")
        return run

    def _wfe_addresses(self) -> list[int]:
        """Every halfword of the image's code that reads as WFE (0xBF20); a hook there fires only on the ones that
        run, which are WFEs."""
        start, size = self.symbols["qb_m0_main"]
        code = bytes(self.uc.mem_read(start & ~1, size))
        return [(start & ~1) + i for i in range(0, size - 1, 2) if code[i:i + 2] == b"\x20\xbf"]

    def _at_wfe(self, uc: Any, address: int, _size: int, _user: Any) -> None:
        self._asleep = address
        uc.emu_stop()  # before the WFE executes: run() moves the time and resumes after it

    def _interrupt(self, handler: str) -> None:
        from unicorn.arm_const import (
            UC_ARM_REG_LR,
            UC_ARM_REG_PC,
            UC_ARM_REG_R0,
            UC_ARM_REG_R12,
            UC_ARM_REG_SP,
            UC_ARM_REG_XPSR,
        )

        uc = self.uc
        saved_regs = [*range(UC_ARM_REG_R0, UC_ARM_REG_R12 + 1), UC_ARM_REG_SP, UC_ARM_REG_LR, UC_ARM_REG_PC,
                      UC_ARM_REG_XPSR]
        saved = [(r, uc.reg_read(r)) for r in saved_regs]
        uc.reg_write(UC_ARM_REG_SP, uc.reg_read(UC_ARM_REG_SP) - 32)  # the 8 words the hardware stacks
        uc.reg_write(UC_ARM_REG_LR, RETURN | 1)
        uc.emu_start(self.addr(handler) | 1, RETURN, count=100_000)
        for r, v in saved:
            uc.reg_write(r, v)

    def call(self, name: str, *args: int) -> int:
        """``name(args...)`` (up to four 32-bit arguments, the AAPCS's r0-r3; floats as their bits: the image is
        soft-float) run to its return; r0."""
        return self.call_pair(name, *args)[0]

    def call_pair(self, name: str, *args: int) -> tuple[int, int]:
        """:meth:`call`, and r1 beside r0 (a 64-bit result's halves, or the run-time ABI's divmod pair)."""
        from unicorn.arm_const import UC_ARM_REG_LR, UC_ARM_REG_R0, UC_ARM_REG_SP

        uc = self.uc
        for i, a in enumerate(args):
            uc.reg_write(UC_ARM_REG_R0 + i, a & 0xFFFF_FFFF)
        uc.reg_write(UC_ARM_REG_SP, RAM + RAM_SIZE)
        uc.reg_write(UC_ARM_REG_LR, RETURN | 1)
        uc.emu_start(self.addr(name) | 1, RETURN, count=1_000_000)
        return int(uc.reg_read(UC_ARM_REG_R0)), int(uc.reg_read(UC_ARM_REG_R0 + 1))


def boot(elf: Path | None = None, until: int = 2, max_instructions: int = 20_000_000) -> Boot:
    """The image (``make board-m0``, built if need be) run from reset until ``until`` packets have left UART0."""
    return M0Image(elf).boot(until, max_instructions)


def run(elf: Path | None = None, ms: float = 100.0, rx: Sequence[tuple[float, bytes]] = ()) -> Boot:
    """The image run from reset for ``ms`` emulated milliseconds, ``rx`` arriving on RXD (:meth:`M0Image.run`)."""
    return M0Image(elf).run(ms=ms, rx=rx)
