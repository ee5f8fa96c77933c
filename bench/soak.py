"""Soak: term's link and the simulator flying for ``--minutes`` through a byte proxy that damages the cable's bytes
both ways, with handovers to BLE and back and a log download every cycle.

The simulator is `fcb-sim serve --pty --ble-hci ...` in a child process (what ``term --sim`` starts); this process
is the terminal without its screen: term's ``Station`` (the cable and the radio, routing, guards, reconnects) and
its ``Model``, the sticks at 100 Hz as the joystick poller sends them, and the log download's ``LogDownloader``
wired as the app wires it. The cable is the real pseudo-terminal behind ``FaultyTransport`` (term/transports/
loopback.py): each byte, either way, has one bit flipped with probability ``--damage`` (default 2 %). The radio
is the real BLE stack (bumble, our bleak backend) and is not damaged: BLE's link layer checks and retransmits
its own packets.

One cycle (about a minute): FULL over the cable (lift up to 60 % of hover: the motors and the whole control loop
run while the craft stays on the floor; gentle stick circles; lift down; SAFE); the
handover (key 8: WIRELESS over the cable, STARTED once the radio's bytes arrive); FULL over BLE while the flash
log records; control back to the cable (WIRELESS off over BLE); the log downloaded over the damaged cable and
checked against the board's CRC-32; the log erased. The board is calibrated once at the start.

Printed (one JSON object on the last line): whether either side crashed; every command sent and its outcome
(acked, failed with its reason, refused by the station with its reason, lost with a dead link, or unresolved:
must be 0); heartbeat gaps (the board's heartbeat counter, merged over both links); handovers; downloads (done
and CRC-checked, failed with their reason); the resident memory of both processes (start after the first cycle,
end, growth per minute); damaged frames. A line per cycle goes to stderr.

With ``--flood`` (issue 36) the simulator's instructor channel is on too, the terminal serves its session live over
Foxglove (``term --foxglove``: term/data/foxglove_server.py behind its door, fed as the app feeds it, with a client
subscribed to every channel beside the flight; ``--no-foxglove`` leaves it out), and a flood process beside the
flight keeps ``--idle`` idle TCP connections open to each of the instructor, the BLE HCI and the Foxglove ports
(more than select() can watch: those a server closes are opened again every 2 s) and logs in with wrong tokens as
fast as one thread can. Printed beside the rest: LINK LOST (on the link in control: the other one's silence while
it is not is the handover's, in ``link_lost``) and PANIC counts (goal 0), the board's and term's resident memory
growth after the first ``--warmup`` minutes (goal at most 2 MB), the bytes the simulator wrote to its log (stderr), and
the flood's own counts, and the live server's (messages its client got, the door's refusals and log lines).

Where a figure misses its goal (issue 36), the soak says why: each long heartbeat gap and each LINK LOST on the
link in control with its time, its step of the cycle, the heartbeats missed and the board's own time across it (as
long as the gap: the board ran and its frames were damaged; one period: the simulator's process was stalled), and
each SIM_LAG (``gaps``); term's event loop lateness (``term_loop_late``); how long after the board's Ack of the
hand-back (over BLE) the damaged cable said DISCONNECTED (``handback_cable_news``: the model no longer waits for it);
term's heap by allocator at each cycle (``term_heap``: pymalloc's objects, glibc's blocks in use and free) and the
app's once-a-minute ``malloc_trim`` (term/core/heap.py, ``heap_trims``). ``--tracemalloc`` traces term's allocations
and prints the call sites that grew between the first cycle after the warm-up and the end (slow: a diagnosis, not
a figure).

``python -m bench.soak [--minutes 10] [--damage 0.02] [--seed 1] [--flood [--idle 1100] [--warmup 5] [--no-foxglove]]
[--tracemalloc]`` (the issue's run: ``python -m bench.soak --minutes 30 --flood``)
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import json
import math
import os
import signal
import socket
import statistics
import subprocess
import sys
import time
from array import array
from collections import Counter
from dataclasses import dataclass, field
from typing import Any

from fcb_sim.board.control import z_to_lift
from term.core.events import FromLink, LinkDown, NotSent
from term.core.heap import PROCESS_HEAP
from term.core.link import CommandAcked, CommandFailed, LinkLost, PacketReceived
from term.core.protocol import (
    Event,
    EventCode,
    Heartbeat,
    Joystick,
    Mode,
    Op,
    Status,
    WirelessState,
)
from term.session.download import RUNNING, LogDownloader
from term.session.model import Model

HOVER_LIFT = z_to_lift(-4.0 * 400**2)  # the stick at which the four motors hover (about 400 of 1000)
STICK_HZ = 100.0
FLY_S = 12.0  # each flight, lift ramps included
FLY_LIFT = 0.6  # of the hover lift: the motors and the control loop run, the craft stays on the floor
STEP_TIMEOUT_S = 8.0


def rss_mb(pid: int | str = "self") -> float | None:
    """Resident memory of a process in MB (Linux /proc), None if unreadable."""
    try:
        with open(f"/proc/{pid}/status", encoding="ascii") as f:
            for line in f:
                if line.startswith("VmRSS:"):
                    return int(line.split()[1]) / 1024
    except OSError:
        return None
    return None


def allocator_mb() -> dict[str, float]:
    """Where this process's heap is (Linux, glibc; empty elsewhere): Python's own arenas in use (pymalloc, the small
    objects), and glibc's heap in use, free inside it (fragments RSS keeps) and mmapped (large blocks). Which of
    them grows tells objects that are kept from memory that is only held."""
    import ctypes
    import tempfile

    out: dict[str, float] = {}
    with contextlib.suppress(Exception), tempfile.TemporaryFile() as f:
        saved = os.dup(2)
        try:
            sys.stderr.flush()
            os.dup2(f.fileno(), 2)
            sys._debugmallocstats()
        finally:
            os.dup2(saved, 2)
            os.close(saved)
        f.seek(0)
        for line in f.read().decode("ascii", "replace").splitlines():
            if line.startswith("# bytes in allocated blocks"):
                out["pymalloc_used_mb"] = round(int(line.split("=")[1].replace(",", "")) / 2**20, 2)
            elif line.startswith("# arenas allocated current"):
                out["pymalloc_arenas_mb"] = int(line.split("=")[1].replace(",", ""))  # (1 MiB each on 3.10+)
    with contextlib.suppress(Exception):
        class MallInfo2(ctypes.Structure):
            _fields_ = [(n, ctypes.c_size_t) for n in ("arena", "ordblks", "smblks", "hblks", "hblkhd", "usmblks",
                                                         "fsmblks", "uordblks", "fordblks", "keepcost")]

        libc = ctypes.CDLL("libc.so.6")
        libc.mallinfo2.restype = MallInfo2
        mi = libc.mallinfo2()
        out |= {"malloc_used_mb": round(mi.uordblks / 2**20, 2), "malloc_free_mb": round(mi.fordblks / 2**20, 2),
                "malloc_mmap_mb": round(mi.hblkhd / 2**20, 2)}
    return out


@dataclass
class Tally:
    """What the soak saw: commands and their outcomes, heartbeats, board events, downloads, memory."""

    t0: float
    pending: dict[tuple[str, int], tuple[str, float]] = field(default_factory=dict)  # (link, cmd_id) -> (what, t)
    sent: int = 0
    acked: int = 0
    failed: Counter[str] = field(default_factory=Counter)
    refused: Counter[str] = field(default_factory=Counter)
    lost_with_link: int = 0
    outcome: dict[tuple[str, int], str] = field(default_factory=dict)  # the latest outcome per (link, cmd_id)
    overwritten: int = 0  # a cmd_id reused while its command was still unresolved
    hb_times: array[float] = field(default_factory=lambda: array("d"))  # (8 B a heartbeat: the bench's own memory
    # is in term's figure, so it keeps no object per heartbeat: 18,000 floats in a list were 0.6 MB in 30 minutes)
    hb_last: int | None = None
    hb_board_ms: int = 0  # the last heartbeat's board time
    handback_acked_at: float | None = None  # when the board acked WIRELESS 0 (over BLE)
    handback_news: list[float] = field(default_factory=list)  # s from that Ack to the cable's DISCONNECTED
    hb_missing: int = 0
    hb_by_link: Counter[str] = field(default_factory=Counter)
    board_events: Counter[str] = field(default_factory=Counter)
    link_lost: Counter[str] = field(default_factory=Counter)
    link_down: Counter[str] = field(default_factory=Counter)
    handovers: Counter[str] = field(default_factory=Counter)
    steps_failed: Counter[str] = field(default_factory=Counter)
    downloads: list[dict[str, Any]] = field(default_factory=list)
    memory: dict[str, list[tuple[float, float]]] = field(default_factory=lambda: {"term": [], "sim": []})
    heap: list[dict[str, float]] = field(default_factory=list)  # term's allocators at each cycle's end
    download: LogDownloader | None = None
    crashes_acked: int = 0
    control: Any = None  # () -> the role of the link in control now (the station's), for ``lost_in_control``
    lost_in_control: int = 0  # LINK LOST on the link flying the craft (the other's silence is the handover's)
    panics: int = 0  # times the board went into PANIC (its mode as term saw it)
    panics_sent: int = 0  # of them asked for by the script (a SAFE that would not come)
    phase: str = "start"  # what the script is doing, for the notable events
    notable: Counter[str] = field(default_factory=Counter)  # link timeouts and long heartbeat gaps, by phase
    gaps: list[dict[str, Any]] = field(default_factory=list)  # the first 100 long heartbeat gaps and LINK LOSTs
    loop_lag: Counter[str] = field(default_factory=Counter)  # term's event loop late by over 0.2 s, by phase
    loop_lag_max_s: float = 0.0

    def on_event(self, ev: Any) -> None:
        now = time.monotonic()
        kind = type(ev)
        if kind is FromLink:
            self._link_event(ev.link, ev.event, now)
        elif kind is NotSent:
            self.refused[f"{ev.what}: {ev.why}"] += 1
        elif kind is LinkDown:
            self.link_down[ev.link] += 1
            for key in [k for k in self.pending if k[0] == ev.link]:
                del self.pending[key]
                self.lost_with_link += 1

    def _link_event(self, link: str, ev: Any, now: float) -> None:
        kind = type(ev)
        if self.download is not None:
            self.download.on_event(ev, now)  # (the model feeds it the LogStatus and LogChunk packets)
        if kind is PacketReceived:
            pkt = ev.packet
            said = self._wireless_said(pkt)
            if said is not None and link != "radio" and self.handback_acked_at is not None:
                if said == WirelessState.DISCONNECTED:  # how long after the Ack the damaged cable said so
                    self.handback_news.append(now - self.handback_acked_at)
                    self.handback_acked_at = None
            if type(pkt) is Heartbeat:
                self.hb_by_link[link] += 1
                if self.hb_last is None or pkt.counter != self.hb_last:
                    if self.hb_last is not None:
                        self.hb_missing += max(0, (pkt.counter - self.hb_last - 1) & 0xFFFF)
                    if self.hb_times and now - self.hb_times[-1] > 0.5:
                        self.notable[f"heartbeat gap over 0.5 s: {self.phase}"] += 1
                        if len(self.gaps) < 100:  # when, how long, over which link, what was missed, and how
                            # far the board's own clock moved (as far as the gap: the board ran and its frames
                            # were lost or late; one period: the simulator's process was stalled)
                            self.gaps.append({"t_s": round(now - self.t0, 1), "phase": self.phase, "link": link,
                                              "ms": round(1000 * (now - self.hb_times[-1])),
                                              "counters_missed": (pkt.counter - self.hb_last - 1) & 0xFFFF,
                                              "board_ms": (pkt.board_ms - self.hb_board_ms) & 0xFFFFFFFF})
                    self.hb_last = pkt.counter
                    self.hb_board_ms = pkt.board_ms
                    self.hb_times.append(now)
            elif type(pkt) is Event:
                try:
                    name = EventCode(pkt.code).name
                except ValueError:
                    name = str(pkt.code)
                self.board_events[name] += 1
                if name in ("LINK_TIMEOUT", "CRASH", "LOW_BATTERY", "TILT_LIMIT", "OVERFLOW", "SIM_LAG"):
                    self.notable[f"{name}: {self.phase}"] += 1
                    if name == "SIM_LAG" and len(self.gaps) < 100:
                        self.gaps.append({"t_s": round(now - self.t0, 1), "phase": self.phase, "sim_lag": pkt.arg})
        elif kind is CommandAcked or kind is CommandFailed:
            if kind is CommandAcked and ev.op == Op.WIRELESS and ev.arg == 0:
                self.handback_acked_at = now  # the board's word over BLE: it writes to the cable from now on
            if self.pending.pop((link, ev.cmd_id), None) is None:
                return
            self.outcome[(link, ev.cmd_id)] = "acked" if kind is CommandAcked else ev.reason
            if kind is CommandAcked:
                self.acked += 1
            else:
                self.failed[ev.reason.split(" (")[0] if ev.nak is None else f"NAK: {ev.reason}"] += 1
        elif kind is LinkLost:
            self.link_lost[link] += 1
            in_control = self.control is None or self.control() == link
            self.lost_in_control += in_control
            if in_control:  # which step of the cycle, and how long the board had been silent
                self.notable[f"LINK LOST on the link in control ({link}): {self.phase}"] += 1
                if len(self.gaps) < 100:
                    self.gaps.append({"t_s": round(now - self.t0, 1), "phase": self.phase, "link": link,
                                      "link_lost_silent_ms": round(1000 * ev.silent_s)})

    @staticmethod
    def _wireless_said(pkt: Any) -> int | None:
        """The handover state a packet from the board states (Status, or Event WIRELESS_STATE), else None."""
        if type(pkt) is Status:
            return int(pkt.wireless)
        if type(pkt) is Event and pkt.code == EventCode.WIRELESS_STATE:
            return int(pkt.arg)
        return None

    def handback_figures(self) -> dict[str, Any]:
        """From the board's Ack of WIRELESS 0 (over BLE) to the cable's first word of DISCONNECTED: before the
        model took the Ack as the board's word, BLE's silence from the Ack on became a BLE LINK LOST in control
        whenever this took longer than the link timeout (0.5 s)."""
        xs = sorted(self.handback_news)
        if not xs:
            return {"n": 0}
        return {"n": len(xs), "median_ms": round(1000 * statistics.median(xs)), "max_ms": round(1000 * xs[-1]),
                "over_500ms": sum(1 for x in xs if x > 0.5)}

    def note_sent(self, link: str, cmd_id: int, what: str) -> None:
        self.sent += 1
        if (link, cmd_id) in self.pending:
            self.overwritten += 1
        self.pending[(link, cmd_id)] = (what, time.monotonic())

    def heartbeat_gaps(self) -> dict[str, Any]:
        t = self.hb_times
        gaps = sorted(b - a for a, b in zip(t, t[1:], strict=False))
        if not gaps:
            return {"received": len(t)}
        return {
            "received": len(t), "by_link": dict(self.hb_by_link), "missing": self.hb_missing,
            "gap_median_ms": round(1000 * statistics.median(gaps), 1),
            "gap_p99_ms": round(1000 * gaps[min(len(gaps) - 1, int(0.99 * len(gaps)))], 1),
            "gap_max_ms": round(1000 * gaps[-1], 1),
            "gaps_over_500ms": sum(1 for g in gaps if g > 0.5),
        }

    def memory_figures(self, warmup_s: float = 0.0) -> dict[str, Any]:
        """Resident memory from the end of the first cycle (imports and buffers warmed up) to the end, and from the
        first sample ``warmup_s`` after the start to the end (``growth_after_warmup_mb``)."""
        out: dict[str, Any] = {}
        for name, xs in self.memory.items():
            late = [(t, m) for t, m in xs if t - self.t0 >= warmup_s]
            after = round(late[-1][1] - late[0][1], 2) if len(late) >= 2 else None
            if len(xs) < 2:
                out[name] = {"samples": len(xs)}
                continue
            (t0, m0), (t1, m1) = xs[0], xs[-1]
            out[name] = {"start_mb": round(m0, 1), "end_mb": round(m1, 1), "max_mb": round(max(m for _, m in xs), 1),
                         "growth_mb": round(m1 - m0, 2),
                         "growth_mb_per_min": round((m1 - m0) / max((t1 - t0) / 60, 1e-9), 3),
                         "growth_after_warmup_mb": after,
                         "per_cycle_mb": [round(b - a, 2) for (_, a), (_, b) in zip(xs, xs[1:], strict=False)]}
        return out


class Soak:
    """The script: fly, hand over, fly over BLE, hand back, download, erase; repeated until the time is up."""

    def __init__(self, station: Any, tally: Tally, model: Model) -> None:
        self.st, self.tally, self.model = station, tally, model
        self.stick = Joystick(0, 0, 0, 0, 0)
        self.lift = 0.0  # 0..1 of HOVER_LIFT
        self.circle = 0.0  # amplitude of the stick circles, 0..1
        self._stick_task: asyncio.Task[None] | None = None
        self.heap = PROCESS_HEAP  # glibc's free pages given back once a minute, as the app does (term/core/heap.py)

    # --- plumbing ---------------------------------------------------------------------------------------------

    def send(self, op: Op, arg: int = 0) -> int | None:
        link = self.st.control()
        cmd_id = self.st.send(op, arg)
        if cmd_id is not None and link is not None:
            self.tally.note_sent(link.role, cmd_id, f"{op.name} {arg}")
        return cmd_id

    async def sticks(self) -> None:
        """The sticks at 100 Hz, as the joystick poller sends them; the links' statistics sampled at 12 Hz, as the
        app's render tick does."""
        t0 = time.monotonic()
        n = 0
        mode = None
        while True:
            n += 1
            if n % 8 == 0:
                self.st.sample()
                self.heap.tick(time.monotonic())  # (the app's render tick does both)
            if self.model.mode != mode:
                mode = self.model.mode
                self.tally.panics += mode == Mode.PANIC
            t = time.monotonic() - t0
            a = self.circle * 1500
            self.stick = Joystick(int(a * math.sin(1.1 * t)), int(a * math.cos(1.1 * t)), 0,
                                  int(self.lift * FLY_LIFT * HOVER_LIFT), 0)
            self.st.set_stick(self.stick)
            before = time.monotonic()
            await asyncio.sleep(1.0 / STICK_HZ)
            late = time.monotonic() - before - 1.0 / STICK_HZ  # term's own loop blocked (its deafness)
            if late > self.tally.loop_lag_max_s:
                self.tally.loop_lag_max_s = late
            if late > 0.2:
                self.tally.loop_lag[self.tally.phase] += 1

    async def until(self, cond: Any, timeout: float = STEP_TIMEOUT_S) -> bool:
        end = time.monotonic() + timeout
        while not cond():
            if time.monotonic() > end:
                return False
            await asyncio.sleep(0.02)
        return True

    async def mode(self, mode: Mode, what: str) -> bool:
        """Ask for ``mode`` until the board says so (a command can fail on the damaged link); False if never. A
        crash the board reports is acknowledged first, as a pilot would after looking at the craft."""
        for _ in range(4):
            ack_crash = getattr(Op, "ACK_CRASH", None)
            if ack_crash is not None and self.tally.board_events.get("CRASH", 0) > self.tally.crashes_acked:
                self.tally.crashes_acked += 1
                self.send(ack_crash)
                await asyncio.sleep(0.3)
            self.send(Op.MODE, int(mode))
            if await self.until(lambda: self.model.mode == mode, 3.0):
                return True
        self.tally.steps_failed[what] += 1
        return False

    async def ramp(self, to: float, seconds: float) -> None:
        start, t0 = self.lift, time.monotonic()
        while (f := (time.monotonic() - t0) / seconds) < 1.0:
            self.lift = start + (to - start) * f
            await asyncio.sleep(0.02)
        self.lift = to

    async def fly(self, where: str, seconds: float = FLY_S) -> None:
        self.tally.phase = f"flying over {where}"
        self.lift, self.circle = 0.0, 0.0
        await asyncio.sleep(0.1)
        if not await self.mode(Mode.FULL, f"FULL over {where}"):
            return
        await self.ramp(1.0, 2.0)
        self.circle = 1.0
        await asyncio.sleep(max(0.0, seconds - 4.0))
        self.circle = 0.0
        await self.ramp(0.0, 2.0)
        if not await self.mode(Mode.SAFE, f"SAFE over {where}"):
            self.send(Op.MODE, int(Mode.PANIC))  # PANIC ends in SAFE by itself
            self.tally.panics_sent += 1
            await self.until(lambda: self.model.mode == Mode.SAFE, 15.0)

    # --- the cycle -------------------------------------------------------------------------------------------

    async def calibrate(self) -> None:
        self.tally.phase = "calibrating"
        self.lift = 0.0
        await self.until(lambda: self.model.mode == Mode.SAFE, 15.0)
        if await self.mode(Mode.CALIBRATION, "CALIBRATION"):
            await self.until(lambda: self.model.mode == Mode.SAFE, 15.0)

    async def handover(self) -> bool:
        self.tally.phase = "handing over to BLE"
        for _ in range(4):
            self.send(Op.WIRELESS, 1)  # key 8, over the cable
            if await self.until(lambda: self.model.over_ble, 4.0):
                self.tally.handovers["to_ble"] += 1
                return True
        self.tally.handovers["to_ble_failed"] += 1
        return False

    async def hand_back(self) -> None:
        self.tally.phase = "handing back to the cable"
        for _ in range(4):
            self.send(Op.WIRELESS, 0)  # the palette's "hand control back to the cable", over BLE
            if await self.until(lambda: self.model.wireless == WirelessState.DISCONNECTED, 4.0):
                self.tally.handovers["back"] += 1
                return
        self.tally.handovers["back_failed"] += 1

    async def download(self) -> None:
        self.tally.phase = "downloading the log"
        t0 = time.monotonic()
        d = LogDownloader(started=t0)
        self.model.download = d  # the model feeds it LogStatus and LogChunk packets, as in the app
        self.tally.download = d
        while d.state == RUNNING and time.monotonic() - t0 < 300:
            now = time.monotonic()
            req = d.poll(now)
            if req is not None:
                d.sent(self.send(req.op, req.arg) if self.st.control() is not None else None, now)
            await asyncio.sleep(0.02)
        self.model.download = None
        self.tally.download = None
        row: dict[str, Any] = {"state": d.state, "s": round(time.monotonic() - t0, 1), "chunks": d.total_chunks,
                               "requests": d.requests}
        if d.state == "done":
            row["crc_ok"] = d.verify() is None
            row["bytes"] = len(d.data())
        else:
            row["reason"] = d.reason
        self.tally.downloads.append(row)

    async def cycle(self) -> None:
        await self.fly("the cable")
        if await self.handover():
            self.send(Op.LOG_START)
            await self.fly("BLE")
            self.send(Op.LOG_STOP)
            await self.hand_back()
        else:
            self.send(Op.LOG_START)
            await asyncio.sleep(3.0)
            self.send(Op.LOG_STOP)
        await asyncio.sleep(0.5)
        await self.download()
        await self.erase()

    async def erase(self) -> None:
        """LOG_RESET until it is done (refused while the board still streams the download's last pass)."""
        self.tally.phase = "erasing the log"
        for _ in range(10):
            link = self.st.control()
            cmd_id = self.send(Op.LOG_RESET)
            if cmd_id is None or link is None:
                await asyncio.sleep(1.0)
                continue
            key = (link.role, cmd_id)
            self.tally.outcome.pop(key, None)
            await self.until(lambda k=key: k in self.tally.outcome, 3.0)
            if self.tally.outcome.get(key) == "acked":
                return
            await asyncio.sleep(0.5)
        self.tally.steps_failed["LOG_RESET"] += 1


def _address(spec: str) -> tuple[str, int]:
    """``tcp-client:HOST:PORT[#TOKEN]`` (or ``ws:HOST:PORT``) to (host, port)."""
    _, host, port = spec.split("#", 1)[0].split(":")
    return host, int(port)


def flood_main(argv: list[str]) -> int:
    """The flood process (``--flood``): ``--idle`` idle connections to each address kept open, wrong-token logins
    to the first as fast as one thread can, until SIGTERM; its counts as JSON on stdout."""
    import resource

    ap = argparse.ArgumentParser(prog="bench.soak flood")
    ap.add_argument("--idle", type=int, required=True)
    ap.add_argument("addresses", nargs="+")
    a = ap.parse_args(argv)
    soft, hard = resource.getrlimit(resource.RLIMIT_NOFILE)
    want = len(a.addresses) * a.idle + 64
    if soft != resource.RLIM_INFINITY and soft < want:
        resource.setrlimit(resource.RLIMIT_NOFILE, (want if hard == resource.RLIM_INFINITY else min(want, hard), hard))
    stop = []
    signal.signal(signal.SIGTERM, lambda *_: stop.append(1))
    targets = [_address(x) for x in a.addresses]
    idle: dict[tuple[str, int], list[socket.socket]] = {t: [] for t in targets}
    counts: Counter[str] = Counter()
    next_idle = 0.0
    while not stop:
        now = time.monotonic()
        if now >= next_idle:  # the idle flood: those closed by the simulator opened again
            next_idle = now + 2.0
            for t, socks in idle.items():
                alive = []
                for sk in socks:
                    try:
                        said = sk.recv(16, socket.MSG_PEEK | socket.MSG_DONTWAIT)
                        gone = said == b"" or said.startswith(b"HTTP/1.1 503")  # (the Foxglove door's refusal)
                    except BlockingIOError:
                        gone = False
                    except OSError:
                        gone = True
                    if gone:
                        sk.close()
                        counts["idle_closed_by_server"] += 1
                    else:
                        alive.append(sk)
                while len(alive) < a.idle:
                    sk = socket.socket()
                    sk.setblocking(False)
                    try:
                        sk.connect_ex(t)
                    except OSError:
                        sk.close()
                        counts["idle_connect_failed"] += 1
                        break
                    alive.append(sk)
                    counts["idle_opened"] += 1
                idle[t] = alive
        try:  # one wrong-token login
            with socket.create_connection(targets[0], timeout=2.0) as c:
                c.sendall(b'{"kind": "auth", "token": "00000000000000000000000000000000"}\n')
                line = c.makefile("rb").readline()
            why = json.loads(line).get("why", "") if line else ""
            counts["logins"] += 1
            counts["login_refused_" + ("throttled" if "try again" in why else "token" if "token" in why
                                       else "too_many_waiting" if "waiting" in why else "other")] += 1
        except (OSError, ValueError):
            counts["login_errors"] += 1
            time.sleep(0.01)
    print(json.dumps(dict(counts)), flush=True)
    return 0


class _CountingClient:
    """A Foxglove client subscribed to every channel that counts what it gets (keeps none: the soak measures
    term's memory)."""

    def __init__(self, url: str) -> None:
        from tests.support.foxglove_client import Client

        class Counting(Client):  # type: ignore[misc]
            count = 0

            def _data(self, msg: bytes) -> None:
                self.count += 1

        self.client = Counting(url)
        self.stop = asyncio.Event()
        self.task: asyncio.Task[None] | None = None
        self.error = ""

    def start(self) -> None:
        self.task = asyncio.create_task(self._run())

    async def _run(self) -> None:
        try:
            await self.client.run(self.stop)
        except Exception as exc:  # (reported, never the soak's end)
            self.error = repr(exc)[:200]

    async def close(self) -> None:
        self.stop.set()
        if self.task is not None:
            with contextlib.suppress(Exception):
                await asyncio.wait_for(self.task, 5.0)


def _live_figures(live: Any, client: _CountingClient | None) -> dict[str, Any] | None:
    if live is None:
        return None
    front = live.front
    return {"messages_to_client": None if client is None else client.client.count,
            "client_error": None if client is None else client.error or None,
            "published": live.published, "errors": live.errors, "accepted": front.accepted,
            "refused": dict(front.refused), "clients_at_end": front.clients, "pending_at_end": front.pending,
            "log_lines": front.refusals.lines}


def _top_growth(before: Any, after: Any, n: int = 15) -> list[str]:
    """The ``n`` call sites whose live allocations grew most between two tracemalloc snapshots, largest first."""
    import tracemalloc

    keep = [tracemalloc.Filter(False, tracemalloc.__file__)]
    stats = after.filter_traces(keep).compare_to(before.filter_traces(keep), "traceback")
    out = []
    for st in sorted(stats, key=lambda x: -x.size_diff)[:n]:
        frames = list(st.traceback)[::-1][:4]  # the allocation first, then its callers
        where = " < ".join(f"{os.path.relpath(f.filename)}:{f.lineno}" for f in frames)
        out.append(f"{st.size_diff / 1024:+.1f} KiB {st.count_diff:+d} blocks: {where}")
    return out


async def soak(minutes: float, damage: float, seed: int, flood: int = 0, warmup: float = 5.0,
               foxglove: bool = True, trace: bool = False) -> dict[str, Any]:
    from term.core.events import CABLE, RADIO
    from term.data.recording import RecordingTransport
    from term.session.config import JOYSTICK_POLICIES
    from term.session.sim import SimBoard
    from term.session.station import Station
    from term.transports.ble import BleTransport
    from term.transports.loopback import Faults, FaultyTransport
    from term.transports.serial import SerialTransport

    sim = SimBoard(seed=seed, radio=True, instructor=bool(flood))
    port = sim.start()
    flooder: subprocess.Popen[str] | None = None
    assert sim.proc is not None
    sim_pid = sim.proc.pid
    t0 = time.monotonic()
    tally = Tally(t0)
    cable = FaultyTransport(SerialTransport(port), Faults(corrupt=damage), Faults(corrupt=damage), seed=seed)
    radio: Any = BleTransport(sim.ble_address, hci=sim.ble_hci, timeout=10.0)
    model = Model(start=t0, link_name=cable.name, radio_name=radio.name)
    live = viewer = None
    on_event: Any = tally.on_event
    cable_link: Any = cable
    if flood and foxglove:  # term --foxglove: the transports tapped and the station's packets, as the app does
        from term.data.foxglove_server import LiveServer

        live = LiveServer("127.0.0.1", 0, t0=t0, start_ns=time.time_ns())
        cable_link = RecordingTransport(cable, live, CABLE, time.monotonic)
        radio = RecordingTransport(radio, live, RADIO, time.monotonic)

        def on_event(ev: Any, _live: Any = live) -> None:
            tally.on_event(ev)
            _live.station_event(ev, time.monotonic())

    st = Station(model, cable=cable_link, radio=radio,
                 cable_session={"link_timeout": 0.5, **JOYSTICK_POLICIES["stream"]},
                 radio_session={"link_timeout": 0.5}, on_event=on_event,
                 on_packet=None if live is None else live.link_packet)
    crash: str | None = None
    cycles = 0
    snap_warm = None  # with ``trace``: tracemalloc's snapshot at the first cycle's end after the warm-up
    stats = None
    s = Soak(st, tally, model)
    tally.control = lambda: getattr(st.control(), "role", None)
    try:
        await st.start()
        s._stick_task = asyncio.create_task(s.sticks())
        await s.until(lambda: model.radio_up and model.mode is not None, 20.0)
        log_start = _log_bytes(sim)
        if live is not None:  # a viewer beside the flight, before the flood (the door lets it in during one too)
            viewer = _CountingClient(live.url)
            viewer.start()
        if flood:  # beside the flight, once the radio's HCI host is attached (a waiting one would queue behind it)
            targets = [sim.instructor_address, sim.ble_hci] + ([f"ws:127.0.0.1:{live.port}"] if live else [])
            flooder = subprocess.Popen([sys.executable, "-m", "bench.soak", "--flood-child", "--idle", str(flood),
                                        *targets], stdout=subprocess.PIPE, text=True)
        await s.calibrate()
        end = t0 + 60 * minutes
        while time.monotonic() < end:
            await s.cycle()
            cycles += 1
            now = time.monotonic()
            tally.memory["term"].append((now, rss_mb() or 0.0))
            tally.memory["sim"].append((now, rss_mb(sim_pid) or 0.0))
            heap = allocator_mb()
            tally.heap.append(heap)
            if trace and snap_warm is None and now - t0 >= 60 * warmup:
                import tracemalloc

                snap_warm = tracemalloc.take_snapshot()
            print(f"cycle {cycles} at {(now - t0) / 60:.1f} min: download {tally.downloads[-1]}, "
                  f"rss term {tally.memory['term'][-1][1]:.1f} MB sim {tally.memory['sim'][-1][1]:.1f} MB; "
                  f"term keeps {len(model.events)} events, {len(model.console)} console lines; heap {heap}",
                  file=sys.stderr, flush=True)
            if sim.proc is None or sim.proc.poll() is not None:
                crash = f"the simulator exited ({None if sim.proc is None else sim.proc.returncode})"
                break
            for link in st.links:
                if link.connection is not None and link.connection.crash is not None:
                    crash = f"term's {link.role} connection crashed: {link.connection.crash!r}"
            if crash:
                break
        await s.until(lambda: not tally.pending, 5.0)  # the last commands' outcomes
        if st.cable is not None and st.cable.connection is not None:
            stats = st.cable.connection.stats
    except Exception as exc:  # the soak reports a crash rather than dying with it
        crash = f"term side: {exc!r}"
    finally:
        if s._stick_task is not None:
            s._stick_task.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await s._stick_task
        if sim.proc is not None and sim.proc.poll() is not None and crash is None:
            crash = f"the simulator exited ({sim.proc.returncode})"
        flooded: dict[str, Any] = {}
        if flooder is not None:
            flooder.send_signal(signal.SIGTERM)
            with contextlib.suppress(Exception):
                out, _ = flooder.communicate(timeout=30)
                flooded = json.loads(out.strip().splitlines()[-1])
        log_bytes = _log_bytes(sim) - log_start if "log_start" in locals() else None
        if viewer is not None:
            await viewer.close()
        live_figures = _live_figures(live, viewer)
        with contextlib.suppress(Exception):
            await st.shutdown()
        if live is not None:
            live.close()
        sim.stop()
    growth = None
    if snap_warm is not None:
        import tracemalloc

        growth = _top_growth(snap_warm, tracemalloc.take_snapshot())
        print("term's allocations that grew after the warm-up:\n  " + "\n  ".join(growth), file=sys.stderr)
    done = [d for d in tally.downloads if d["state"] == "done"]
    return {
        "bench": "soak", "minutes": round((time.monotonic() - t0) / 60, 2), "damage_pct": 100 * damage,
        "seed": seed, "cycles": cycles, "crash": crash,
        "commands": {"sent": tally.sent, "acked": tally.acked, "failed": sum(tally.failed.values()),
                     "failed_reasons": dict(tally.failed), "refused_by_station": dict(tally.refused),
                     "lost_with_a_dead_link": tally.lost_with_link, "id_reused_unresolved": tally.overwritten,
                     "unresolved": len(tally.pending)},
        "heartbeats": tally.heartbeat_gaps(),
        "board_events": dict(tally.board_events),
        "link_lost": dict(tally.link_lost), "link_down": dict(tally.link_down),
        "handovers": dict(tally.handovers), "handback_cable_news": tally.handback_figures(),
        "steps_failed": dict(tally.steps_failed),
        "downloads": {"runs": len(tally.downloads), "done": len(done),
                      "crc_ok": sum(1 for d in done if d.get("crc_ok")),
                      "failed": [d.get("reason") for d in tally.downloads if d["state"] != "done"],
                      "time_mean_s": round(statistics.mean(d["s"] for d in done), 1) if done else None,
                      "bytes_mean": round(statistics.mean(d["bytes"] for d in done)) if done else None},
        "notable": dict(tally.notable), "gaps": tally.gaps,
        "term_loop_late": {"max_ms": round(1000 * tally.loop_lag_max_s), "over_200ms": dict(tally.loop_lag)},
        "LINK_LOST": tally.lost_in_control, "PANIC": tally.panics, "panic_asked_by_soak": tally.panics_sent,
        "heap_trims": s.heap.trims, "sim_log_bytes": log_bytes, "flood": flooded if flood else None,
        "foxglove": live_figures,
        "memory": tally.memory_figures(60 * warmup),
        "tracemalloc_growth_after_warmup": growth,
        "term_heap": {"first_cycle": tally.heap[0] if tally.heap else None,
                      "at_warmup": next((h for (t, _), h in zip(tally.memory["term"], tally.heap, strict=False)
                                         if t - t0 >= 60 * warmup), None),
                      "end": tally.heap[-1] if tally.heap else None},
        "cable": {"bytes_damaged_up": cable.up.stats.bytes_corrupted,
                  "bytes_damaged_down": cable.down.stats.bytes_corrupted,
                  "frames_bad": None if stats is None else stats.frames_bad,
                  "loss_pct_total": None if stats is None else round(stats.loss_pct_total, 2)},
    }


def _log_bytes(sim: Any) -> int:
    """What the simulator has written to its stderr (its log) so far."""
    f = getattr(sim, "_stderr", None)
    try:
        return os.fstat(f.fileno()).st_size if f is not None else 0
    except (OSError, ValueError):
        return 0


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if argv[:1] == ["--flood-child"]:
        return flood_main(argv[1:])
    ap = argparse.ArgumentParser(prog="python -m bench.soak", description=__doc__.splitlines()[0])
    ap.add_argument("--minutes", type=float, default=10.0, help="how long to fly (default 10)")
    ap.add_argument("--damage", type=float, default=0.02, help="probability a cable byte is damaged (default 0.02)")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--flood", action="store_true", help="an idle-connection flood and a login flood beside the flight")
    ap.add_argument("--idle", type=int, default=1100, help="idle connections to each port with --flood (1100)")
    ap.add_argument("--no-foxglove", action="store_true",
                    help="with --flood: the terminal serves no live Foxglove (and its port is not flooded)")
    ap.add_argument("--warmup", type=float, default=5.0,
                    help="minutes before the memory growth is counted (default 5)")
    ap.add_argument("--tracemalloc", action="store_true",
                    help="trace term's allocations and print the call sites that grew after the warm-up (slower)")
    a = ap.parse_args(argv)
    if not 0.1 <= a.minutes <= 24 * 60:
        print("bench.soak: --minutes must be between 0.1 and 1440", file=sys.stderr)
        return 2
    if not 0.0 <= a.damage <= 0.5:
        print("bench.soak: --damage is a probability between 0 and 0.5", file=sys.stderr)
        return 2
    if a.tracemalloc:
        import tracemalloc

        tracemalloc.start(4)
    if not os.path.exists("/proc/self/status"):
        print("bench.soak: memory figures need Linux (/proc)", file=sys.stderr)
    result = asyncio.run(soak(a.minutes, a.damage, a.seed, a.idle if a.flood else 0, a.warmup,
                              foxglove=not a.no_foxglove, trace=a.tracemalloc))
    print(json.dumps(result))
    return 0 if result["crash"] is None else 1


if __name__ == "__main__":
    raise SystemExit(main())
