"""The C board (firmware/board/) flying fcb_sim's physics: software in the loop, in lockstep.

``CBoard`` offers the surface the Python ``Board`` offers the world and the serve loop (sans-IO, the board's
microsecond clock): ``uart_receive(data)``, ``advance(until_us)``, ``uart_transmit() -> bytes``,
``next_event_us()``, ``starved(until_us)``, ``now``, ``mode``, ``world``, ``config``. Behind it the C board,
built as a shared library (``make -C firmware board``: libqb_host.so in the user's cache, built once per version
of the sources by fcb_sim/cbuild.py) and loaded with ctypes; its hardware layer's host backend
(firmware/board/hal_host.c) calls back here for the sensors and the motors, at the board time of the task, so the
World advances to that instant first: the same seed flies the same flight, as fast as the CPU allows or paced by
``fcb-sim serve``.

What the C board has and has not yet: firmware/board/qb_board.h and docs/firmware.md. Without a C compiler,
``CBoardUnavailable`` says in one line what to install.
"""

from __future__ import annotations

import ctypes
import json
import math
import os
import random
import time
from pathlib import Path
from typing import Any

from fcb_sim import cbuild
from fcb_sim.board.parts import BoardConfig
from fcb_sim.board.timing import rtc_ticks
from fcb_sim.board.wireless import WirelessLink
from fcb_sim.errors import UsageError
from fcb_sim.world.physics import World
from term.core.protocol import PARAM_RULES, PARAMS, PRESETS, Mode, Param

FIRMWARE = cbuild.firmware_dir()
LIBRARY = "libqb_host.so"
NO_CC = "the C board needs a C compiler and make: install them (Debian/Ubuntu: apt-get install gcc make)"

_IMU = ctypes.CFUNCTYPE(None, ctypes.c_uint64, ctypes.POINTER(ctypes.c_int16))
_DMP = ctypes.CFUNCTYPE(ctypes.c_int, ctypes.c_uint64, ctypes.POINTER(ctypes.c_float))
_BARO = ctypes.CFUNCTYPE(None, ctypes.c_uint64, ctypes.POINTER(ctypes.c_int32))
_BATTERY = ctypes.CFUNCTYPE(ctypes.c_int, ctypes.c_uint64)
_MOTORS = ctypes.CFUNCTYPE(None, ctypes.c_uint64, ctypes.POINTER(ctypes.c_uint16))
_IMPACT = ctypes.CFUNCTYPE(ctypes.c_int32, ctypes.c_uint64)

STATE_FIELDS = ("phi", "theta", "psi", "height", "vz", "setpoint", "sp", "sq", "sr", "calibrated",
                "link_timed_out", "crashed", "trim_lift", "motor_level", "battery", "pressure")


class CBoardUnavailable(UsageError):
    """The C board cannot be built here (one line: what to install)."""


def library_path(build_dir: Path | None = None, *, real: str = "double") -> Path:
    """The host library (``make -C firmware board``), built once per version of the sources into the user's cache
    (fcb_sim/cbuild.py) or ``build_dir``. ``real`` "float": the board in float, as the Cortex-M0 build computes
    (``board-float``). CBoardUnavailable (one line) where it cannot be built."""
    if not (FIRMWARE / "board" / "qb_board.c").is_file():
        raise CBoardUnavailable(f"the C board's sources are not in this installation (looked in {FIRMWARE}): "
                                "reinstall quadrupel, or run fcb-sim from a clone of the project")
    target, name = ("board-float", "libqb_host_float.so") if real == "float" else ("board", LIBRARY)
    try:
        return cbuild.build(target, [name], out=build_dir, tools=[os.environ.get("CC", "cc")], missing=NO_CC,
                            what="the C board") / name
    except cbuild.BuildError as e:
        raise CBoardUnavailable(str(e)) from None


def _load(path: Path) -> ctypes.CDLL:
    lib = ctypes.CDLL(str(path))
    u64, vp = ctypes.c_uint64, ctypes.c_void_p
    lib.qbh_size.restype = ctypes.c_size_t
    lib.qbh_set_callbacks.argtypes = [vp, _IMU, _DMP, _BARO, _BATTERY, _MOTORS, _IMPACT]
    lib.qbh_init.argtypes = [vp, ctypes.c_uint16, ctypes.c_double, ctypes.POINTER(ctypes.c_uint32), ctypes.c_int,
                             u64]
    lib.qbh_advance.argtypes = [vp, u64]
    lib.qbh_receive.argtypes = [vp, ctypes.c_char_p, ctypes.c_size_t]
    lib.qbh_transmit.argtypes = [vp, ctypes.c_char_p, ctypes.c_size_t]
    lib.qbh_transmit.restype = ctypes.c_size_t
    lib.qbh_now.argtypes = lib.qbh_next_event_us.argtypes = [vp]
    lib.qbh_now.restype = lib.qbh_next_event_us.restype = u64
    lib.qbh_mode.argtypes = [vp]
    lib.qbh_motors.argtypes = [vp, ctypes.POINTER(ctypes.c_uint16)]
    lib.qbh_state.argtypes = [vp, ctypes.POINTER(ctypes.c_double)]
    lib.qbh_rx_dropped.argtypes = [vp]
    lib.qbh_rx_dropped.restype = ctypes.c_uint32
    lib.qbh_param.argtypes = [vp, ctypes.c_int]
    lib.qbh_param.restype = ctypes.c_int32
    lib.qbh_set_param.argtypes = [vp, ctypes.c_int, ctypes.c_int32]
    lib.qbh_starved.argtypes = [vp, u64, ctypes.c_int]
    return lib


def _bind_parity(lib: ctypes.CDLL) -> ctypes.CDLL:
    """The entry points of the C board's parity with the Python board (issue 37): the queue rule's count, the flash
    log's encoder alone (tests)."""
    vp = ctypes.c_void_p
    lib.qbh_rx_discarded.argtypes = [vp]
    lib.qbh_rx_discarded.restype = ctypes.c_uint32
    lib.qbh_log_encode.argtypes = [vp, ctypes.c_int, ctypes.POINTER(ctypes.c_int64), ctypes.c_size_t, ctypes.c_char_p,
                                   ctypes.c_size_t]
    lib.qbh_log_encode.restype = ctypes.c_size_t
    return lib


def default_phases(seed: int) -> tuple[int, int, int, int]:
    """The timers' first expiries (RTC ticks: sensor, baro, telemetry, heartbeat): unrelated phases, as the
    Python board's scheduler draws them."""
    rng = random.Random(seed ^ 0x5EED)
    return (0, rng.randrange(1, rtc_ticks(50_000)), rng.randrange(1, rtc_ticks(20_000)),
            rng.randrange(1, rtc_ticks(100_000)))


def _config_params(cfg: BoardConfig) -> dict[Param, Any]:
    """The BoardConfig fields that are parameters, where they differ from the table's defaults."""
    values = {Param.SCHEDULER: cfg.scheduler, Param.SENSOR_PATH: cfg.sensor_path,
              Param.TELEMETRY_HZ: round(cfg.telemetry_hz), Param.LOG_SCHEME: cfg.log_scheme,
              Param.FIXED_POINT: bool(cfg.fixed_point), Param.QUEUE_RULE: cfg.queue_rule,
              Param.STICK_REACTION: bool(cfg.stick_reaction),
              Param.LINK_FAILSAFE_MS: round(cfg.link_failsafe_s * 1000)}
    return {p: v for p, v in values.items() if v != PARAMS[p].default}


class CBoard:
    """The C board in its world (module docstring). ``phases`` sets the timers' first expiries (RTC ticks:
    sensor, baro, telemetry, heartbeat), e.g. a Python board's, so both run their tasks on the same ticks;
    ``real`` "float" flies the float build (the Cortex-M0's arithmetic)."""

    def __init__(self, config: BoardConfig | None = None, *, world: World | None = None,
                 phases: tuple[int, int, int, int] | None = None, build_dir: Path | None = None,
                 real: str = "double") -> None:
        self.config = cfg = config or BoardConfig()
        self.world = world if world is not None else World(cfg.seed)
        self.wireless = WirelessLink()  # no radio on the C board: the handover is refused (NO_BLE_CONNECTION)
        self.on_task: Any = None  # the serve loop's hook; the C board's tasks take no board time
        self._lib = lib = _bind_parity(_load(library_path(build_dir, real=real)))
        self._buf = ctypes.create_string_buffer(lib.qbh_size())
        self._h = ctypes.cast(self._buf, ctypes.c_void_p)
        self._crashes_seen = len(self.world.crashes)
        self._callbacks = (_IMU(self._imu), _DMP(self._dmp), _BARO(self._baro), _BATTERY(self._battery),
                           _MOTORS(self._motors), _IMPACT(self._impact))  # kept: C holds only their addresses
        lib.qbh_set_callbacks(self._h, *self._callbacks)
        ph = (ctypes.c_uint32 * 4)(*(phases if phases is not None else default_phases(cfg.seed)))
        lib.qbh_init(self._h, cfg.board_id, cfg.link_timeout_s, ph, int(cfg.boot_hello), 0)
        for param, value in _config_params(cfg).items():  # the config's parameters, as the Python board takes them
            if lib.qbh_set_param(self._h, int(param), PARAMS[param].to_raw(value)):
                raise UsageError(f"the C board cannot run {PARAMS[param].name} = {value!r} (docs/firmware.md)")
        self._apply_preset(cfg.preset)

    def _apply_preset(self, name: str) -> None:
        """The preset's values over the defaults, each through the board's own guards (param_bindings.apply_values);
        one line naming every value the C board cannot run (docs/firmware.md) when any is refused."""
        refused = []
        for param, value in PRESETS[name].items():
            if self._lib.qbh_set_param(self._h, int(param), PARAMS[param].to_raw(value)):
                refused.append(f"{PARAMS[param].name} = {PARAMS[param].text(value)}")
        for rule in PARAM_RULES:  # the whole set keeps the rules, or the two come back to the table's defaults
            big, small = (self._lib.qbh_param(self._h, int(p)) for p in (rule.big, rule.small))
            if big < rule.factor * small:
                for p in (rule.big, rule.small):
                    self._lib.qbh_set_param(self._h, int(p), PARAMS[p].to_raw(PARAMS[p].default))
        if refused:
            raise UsageError(f"the C board cannot run preset {name!r}: {', '.join(refused)} (docs/firmware.md)")

    # --- the hardware layer's callbacks (board time in µs) ---------------------------------------------------

    def _imu(self, t: int, out: Any) -> None:
        self.world.advance_to(t / 1e6)
        for i, v in enumerate(self.world.imu()):
            out[i] = v

    def _dmp(self, t: int, q: Any) -> int:
        self.world.advance_to(t / 1e6)
        got = self.world.dmp()
        if got is None:
            return 0
        for i, v in enumerate(got):
            q[i] = v
        return 1

    def _baro(self, t: int, out: Any) -> None:
        self.world.advance_to(t / 1e6)
        out[0], out[1] = self.world.baro()

    def _battery(self, t: int) -> int:
        self.world.advance_to(t / 1e6)
        return int(self.world.battery())

    def _motors(self, t: int, ae: Any) -> None:
        self.world.advance_to(t / 1e6)
        self.world.set_motors(ae[0], ae[1], ae[2], ae[3])

    def _impact(self, t: int) -> int:
        crashes = self.world.crashes
        if self._crashes_seen < len(crashes):  # the impact the accelerometer would feel
            self._crashes_seen += 1
            return max(1, round(crashes[self._crashes_seen - 1].speed * 1000))
        return 0

    # --- the outside world's calls (fcb_sim.board.board.Board's) ----------------------------------------------------

    @property
    def now(self) -> int:
        return int(self._lib.qbh_now(self._h))

    def advance(self, until_us: int) -> None:
        """Run every task due before board time ``until_us``."""
        self._lib.qbh_advance(self._h, int(until_us))

    def starved(self, until_us: int, *, slip: bool = False) -> None:
        """The real-time driver could not run the board until ``until_us``: not the PC's silence (SIM_LAG)."""
        self._lib.qbh_starved(self._h, int(until_us), int(slip))

    def uart_receive(self, data: bytes) -> None:
        """Bytes from the PC, now: the parser runs at once."""
        if data:
            self._lib.qbh_receive(self._h, bytes(data), len(data))

    def uart_transmit(self) -> bytes:
        """Everything the board has sent since the last call."""
        out = bytearray()
        buf = ctypes.create_string_buffer(4096)
        while n := self._lib.qbh_transmit(self._h, buf, len(buf)):
            out += buf.raw[:n]
        return bytes(out)

    def next_event_us(self) -> int:
        return int(self._lib.qbh_next_event_us(self._h))

    @property
    def mode(self) -> Mode:
        return Mode(self._lib.qbh_mode(self._h))

    @property
    def ae(self) -> tuple[int, int, int, int]:
        out = (ctypes.c_uint16 * 4)()
        self._lib.qbh_motors(self._h, out)
        return out[0], out[1], out[2], out[3]

    @property
    def rx_overflow(self) -> int:
        return int(self._lib.qbh_rx_dropped(self._h))

    @property
    def rx_discarded(self) -> int:
        """Bytes the receive queue's rule threw away (link.queue_rule discard-20)."""
        return int(self._lib.qbh_rx_discarded(self._h))

    def log_encode(self, rows: list[tuple[int, ...]], scheme: int) -> bytes:
        """The C encoder's bytes for ``rows`` in one segment (``flash_log.encode_log``'s twin; it erases this board's
        flash: for tests)."""
        flat = [int(v) for row in rows for v in row]
        arr = (ctypes.c_int64 * max(1, len(flat)))(*flat)
        cap = 256 * 1024
        out = ctypes.create_string_buffer(cap)
        n = self._lib.qbh_log_encode(self._h, int(scheme), arr, len(rows), out, cap)
        return out.raw[:n]

    def state(self) -> dict[str, float]:
        """The figures tests and benches read (``STATE_FIELDS``)."""
        out = (ctypes.c_double * len(STATE_FIELDS))()
        self._lib.qbh_state(self._h, out)
        return dict(zip(STATE_FIELDS, out, strict=True))

    def param_raw(self, param: int) -> int:
        return int(self._lib.qbh_param(self._h, int(param)))


# --- whole boards flown by a scripted pilot over their UART (`fcb-sim run --board`, bench/firmware.py) ---------

BOARD_SCENARIOS = ("hover", "height-hold", "raw-hover")
_PILOT_US = 20_000  # the pilot's joystick at 50 Hz (also keeps the link alive)
_CALIBRATE_AT_US, _ARM_AT_US, _HEIGHT_AT_US, _MEASURE_FROM_US = 200_000, 1_500_000, 5_000_000, 6_000_000


def _pilot_lift(world: World, target_m: float) -> int:
    """The scenarios' pilot (fcb_sim/lab/scenarios.py): a lift stick that flies the true height to ``target_m``."""
    from fcb_sim.board import control as C
    from fcb_sim.world import constants as P

    tr = world.truth
    a = max(-4.0, min(4.0, 2.0 * (target_m - tr.h) + 2.5 * tr.vd))
    ae = P.AE_HOVER_NOMINAL * P.V_REF / max(tr.volts, 1.0) * math.sqrt(max(0.0, 1.0 + a / P.G))
    return max(0, min(32767, round(ae * 32767 / C.LIFT_AE_MAX)))


def fly_board(kind: str, scenario: str = "hover", seed: int = 1, duration: float = 15.0) -> dict[str, Any]:
    """Fly a whole board (``kind`` "python", "c" or "c-float") in its world: calibrate, FULL, take off to 1 m by
    the lift stick; "height-hold" enters HEIGHT at 5 s and lets go of the stick; "raw-hover" flies RAW (the
    on-board filter) instead of FULL. Metrics from 6 s on, on the truth:
    ``attitude_rms_deg`` (tilt), ``height_rms_m`` (against 1 m, or the height HEIGHT was entered at), the final
    mode, and the wall time."""
    from fcb_sim.board.board import Board
    from term.core.protocol import Command, Decoder, Joystick, Op, encode

    if scenario not in BOARD_SCENARIOS:
        raise UsageError(f"unknown board scenario {scenario!r}; choose one of: {', '.join(BOARD_SCENARIOS)}")
    world = World(seed)
    cfg = BoardConfig(seed=seed)
    if kind == "python":
        board: Any = Board(cfg, world=world)
    else:
        board = CBoard(cfg, world=world, real="float" if kind == "c-float" else "double")
    dec = Decoder()
    lift, h_ref, target = 0, 1.0, None
    tilt2 = h2 = 0.0
    n = 0
    naks: list[Any] = []
    t0 = time.perf_counter()
    end_us = int(duration * 1e6)
    for t in range(_PILOT_US, end_us + 1, _PILOT_US):
        board.advance(t)
        for pkt in dec.feed(board.uart_transmit()):
            if type(pkt).__name__ == "Ack" and pkt.status:
                naks.append(pkt)
        if t == _CALIBRATE_AT_US:
            board.uart_receive(encode(Command(1, Op.MODE, int(Mode.CALIBRATION))))
        elif t == _ARM_AT_US:
            arm = Mode.RAW if scenario == "raw-hover" else Mode.FULL
            board.uart_receive(encode(Command(2, Op.MODE, int(arm))))
            target = 1.0
        elif t == _HEIGHT_AT_US and scenario == "height-hold":
            board.uart_receive(encode(Command(3, Op.MODE, int(Mode.HEIGHT))))
            target, h_ref = None, world.truth.h
        if target is not None:
            lift = _pilot_lift(world, target)
        board.uart_receive(encode(Joystick(0, 0, 0, lift, 0)))
        if t >= _MEASURE_FROM_US:
            tr = world.truth
            tilt2 += tr.phi * tr.phi + tr.theta * tr.theta
            h2 += (tr.h - h_ref) ** 2
            n += 1
    n = max(1, n)
    return {"board": kind, "scenario": scenario, "seed": seed, "attitude_rms_deg": math.degrees(math.sqrt(tilt2 / n)),
            "height_rms_m": math.sqrt(h2 / n), "mode": board.mode.name, "naks": len(naks),
            "wall_s": time.perf_counter() - t0}


def cmd_run_board(args: Any) -> int:
    """``fcb-sim run --board python|c --scenario hover|height-hold``: a whole board over its UART."""
    m = fly_board(args.board, args.scenario, args.seed, args.duration)
    for key, value in m.items():
        print(f"{key}: {value:.4g}" if isinstance(value, float) else f"{key}: {value}")
    if args.json:
        print(json.dumps(m))
    return 0
