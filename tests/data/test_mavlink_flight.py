"""``term --sim --mavlink`` with pymavlink as the ground station (tests/support/mavlink_gcs.py): the real simulated
board in its child process, the real TermApp over the serial transport, the endpoint (term/data/mavlink.py) wired
as the command line wires it. What a ground station sees (heartbeat, every parameter with its value, attitude and
height against the simulator's truth) and what it may do (parameter sets and their refusals, arming refused with
the board's reason and accepted, MANUAL_CONTROL only after the handover, its silence as a link loss, the flash
log listed and downloaded byte for byte)."""

from __future__ import annotations

import asyncio
import contextlib
import math
import threading
import time
import zlib
from collections.abc import AsyncIterator, Callable
from pathlib import Path
from typing import Any

import pytest

from term.core.protocol import PARAMS, Mode, Op, Param
from tests.support.waits import until

pytest.importorskip("pymavlink", reason="the mavlink extra (pymavlink) is not installed")

from term.data.mavlink_map import PARAM_BY_MAV, PARAM_NAMES, param_float  # noqa: E402
from tests.support.mavlink_gcs import Gcs  # noqa: E402


class Flight:
    """The app, its pilot, the ground station, the endpoint and the simulator's truth."""

    def __init__(self, app: Any, pilot: Any, gcs: Gcs, endpoint: Any, instructor: Any) -> None:
        self.app, self.pilot, self.gcs, self.endpoint, self.instructor = app, pilot, gcs, endpoint, instructor

    async def wait(self, cond: Callable[[], Any], timeout: float = 20.0, what: str | Callable[[], str] = "") -> None:
        await until(self.pilot, cond, timeout, what=what)

    async def command(self, command: int, *params: float) -> Any:
        """COMMAND_LONG; its COMMAND_ACK."""
        before = len(self.gcs.seen("COMMAND_ACK"))
        p = list(params) + [0.0] * (7 - len(params))
        self.gcs.mav.command_long_send(1, 1, command, 0, *p)
        await self.wait(lambda: len(self.gcs.seen("COMMAND_ACK", lambda m: m.command == command)) > 0
                        and len(self.gcs.seen("COMMAND_ACK")) > before, what=f"COMMAND_ACK of {command}")
        return self.gcs.seen("COMMAND_ACK", lambda m: m.command == command)[-1]

    async def param_set(self, name: str, value: float) -> Any:
        """PARAM_SET; the PARAM_VALUE that answers it."""
        before = len(self.gcs.seen("PARAM_VALUE", lambda m: m.param_id == name))
        self.gcs.mav.param_set_send(1, 1, name.encode(), value, 9)  # MAV_PARAM_TYPE_REAL32
        await self.wait(lambda: len(self.gcs.seen("PARAM_VALUE", lambda m: m.param_id == name)) > before,
                        what=f"PARAM_VALUE {name}")
        return self.gcs.seen("PARAM_VALUE", lambda m: m.param_id == name)[-1]

    def manual(self, x: int = 0, y: int = 0, z: int = 0, r: int = 0) -> None:
        self.gcs.mav.manual_control_send(1, x, y, z, r, 0)

    def stream(self) -> threading.Thread:
        """MANUAL_CONTROL at 20 Hz with ``self.stick`` (x, y, z, r), as a ground station with a joystick sends it,
        until ``self.stick`` is None: on a thread of its own, as a ground station is a process of its own (the
        app's loop, busy drawing, would make gaps a real one does not have)."""
        def run() -> None:
            while (stick := self.stick) is not None:
                self.manual(*stick)
                time.sleep(0.05)

        t = threading.Thread(target=run, name="test gcs sticks", daemon=True)
        t.start()
        return t

    stick: tuple[int, int, int, int] | None = None


@contextlib.asynccontextmanager
async def flight(tmp_path: Path, seed: int = 5, address: str | None = None) -> AsyncIterator[Flight]:
    """``term --sim --mavlink`` in the test: pymavlink's ground station (tests/support/mavlink_gcs.py) listening,
    or, with ``address``, whatever listens there."""
    from term.data.mavlink import MavlinkEndpoint
    from term.lessons.instructor import InstructorClient
    from term.session.sim import SimBoard
    from term.transports.serial import SerialTransport
    from term.ui.app import TermApp

    sim = SimBoard(seed=seed, radio=False, instructor=True)
    port = sim.start()
    gcs = Gcs()
    endpoint = MavlinkEndpoint(address or gcs.address, t0=time.monotonic())
    try:
        instructor = InstructorClient(sim.instructor_address)
        await instructor.open()
        app = TermApp(SerialTransport(port), joystick=False, instructor=instructor, mavlink=endpoint,
                      log_directory=tmp_path / "logs")
        async with app.run_test(size=(120, 44)) as pilot:
            f = Flight(app, pilot, gcs, endpoint, instructor)
            await f.wait(lambda: app.model.mode == Mode.SAFE and len(app.model.param_raw) == len(PARAMS),
                         what="the board's Hello and its parameters")
            if address is None:
                gcs.heartbeat()
            yield f
            app.exit()
        await instructor.close()
    finally:
        endpoint.close()
        gcs.close()
        sim.stop()


async def test_a_ground_station_sees_the_heartbeat_every_parameter_and_sets_one(tmp_path: Path) -> None:
    async with flight(tmp_path) as f:
        gcs, model = f.gcs, f.app.model
        await f.wait(lambda: gcs.last("HEARTBEAT") is not None and gcs.last("SYS_STATUS") is not None
                     and gcs.last("BATTERY_STATUS") is not None, what="the once-a-second messages")
        # (a SYS_STATUS sent before the board's first Height says the battery is unknown: 0xFFFF mV, as MAVLink has it)
        await f.wait(lambda: gcs.last("SYS_STATUS").voltage_battery != 0xFFFF, what="a SYS_STATUS with the battery")
        hb = gcs.last("HEARTBEAT")
        assert (hb.type, hb.custom_mode) == (2, Mode.SAFE)  # MAV_TYPE_QUADROTOR, the board's mode
        assert not hb.base_mode & 128  # MAV_MODE_FLAG_SAFETY_ARMED: in SAFE, disarmed
        volts = gcs.last("SYS_STATUS").voltage_battery / 1000
        assert volts == pytest.approx(model.height.battery / 100, abs=0.2) and volts > 10
        # Every parameter, with the value the board holds.
        gcs.mav.param_request_list_send(1, 1)
        await f.wait(lambda: len({m.param_id for m in gcs.seen("PARAM_VALUE")}) == len(PARAMS), what="the list")
        values = {m.param_id: m for m in gcs.seen("PARAM_VALUE")}
        assert set(values) == set(PARAM_NAMES.values())
        for name, m in values.items():
            spec = PARAMS[PARAM_BY_MAV[name].param]
            assert m.param_count == len(PARAMS) and m.param_type == 9
            assert m.param_value == pytest.approx(param_float(spec, model.param_raw[spec.param]), rel=1e-6), name
        # A set the board takes: the answer is its new value, and term's model has it too.
        got = await f.param_set("CTRL_P2", 120.0)
        assert got.param_value == pytest.approx(120.0)
        await f.wait(lambda: model.params.get("ctrl.p2") == 120.0, what="term's model to follow")
        # A float32 carries 0.99 as 0.9900000095...: the set goes to the table's step.
        got = await f.param_set("EST_K_GYRO", 0.99)
        assert got.param_value == pytest.approx(0.99)
        await f.wait(lambda: model.param_raw[Param.K_GYRO] == 99000, what="0.99 in force")
        # Refused by the table (out of range): why, then the value still in force.
        got = await f.param_set("CTRL_P1", 50.0)
        assert got.param_value == pytest.approx(PARAMS[Param.P1].from_raw(model.param_raw[Param.P1]))
        assert any("CTRL_P1 not set: 50 outside 0..10" in t for t in gcs.texts()), gcs.texts()
        # A read by name, and a key in term changes a gain: the ground station hears it.
        gcs.mav.param_request_read_send(1, 1, b"CTRL_YAW_P", -1)
        await f.wait(lambda: len(gcs.seen("PARAM_VALUE", lambda m: m.param_id == "CTRL_YAW_P")) > 1)
        before = PARAMS[Param.YAW_P].from_raw(model.param_raw[Param.YAW_P])
        f.app.send(Op.GAIN_YAW_P, 1)
        await f.wait(lambda: gcs.seen("PARAM_VALUE", lambda m: m.param_id == "CTRL_YAW_P"
                                      and m.param_value == pytest.approx(before + 50.0)), what="the key's change")


async def test_commands_and_the_sticks_only_after_the_handover(tmp_path: Path) -> None:
    from pymavlink.dialects.v20 import common as d

    async with flight(tmp_path, seed=6) as f:
        gcs, app, model, ep = f.gcs, f.app, f.app.model, f.endpoint
        # Before the handover: MANUAL_CONTROL moves nothing and says why; arming is refused with the reason.
        f.manual(z=300)
        await f.wait(lambda: any("MANUAL_CONTROL ignored" in t for t in gcs.texts()), what="the refusal")
        assert model.stick.lift == 0
        ack = await f.command(d.MAV_CMD_COMPONENT_ARM_DISARM, 1)
        assert ack.result == d.MAV_RESULT_DENIED and model.mode == Mode.SAFE
        assert any("has not handed control" in t for t in gcs.texts())
        # The pilot hands over from term (the palette's command), the ground station's stick takes it.
        gcs.heartbeat()
        app.mav.handover()
        await f.wait(lambda: ep.state == "offered")
        f.stick = (0, 0, 0, 0)
        streaming = f.stream()
        await f.wait(lambda: ep.state == "ground station", what="the ground station to take control")
        # FULL needs a calibration first: the board's own refusal, its Nak in result_param2 and its text.
        ack = await f.command(d.MAV_CMD_DO_SET_MODE, 1, Mode.FULL)
        assert ack.result == d.MAV_RESULT_TEMPORARILY_REJECTED and ack.result_param2 == 3  # Nak.NOT_CALIBRATED
        assert any("not calibrated" in t for t in gcs.texts()), gcs.texts()
        # Arming with the lift up: term's own guard refuses, as it would the pilot's key.
        f.stick = (0, 0, 400, 0)
        await f.wait(lambda: model.stick.lift > 10000, what=lambda: f"the stick up {ep.state} {ep.received}")
        ack = await f.command(d.MAV_CMD_COMPONENT_ARM_DISARM, 1)
        assert ack.result == d.MAV_RESULT_DENIED and any("throttle is up" in t for t in gcs.texts())
        # Lift at zero: armed (MANUAL); the heartbeat says so.
        f.stick = (0, 0, 0, 0)
        await f.wait(lambda: model.stick.lift == 0, what=lambda: f"the stick down {ep.state} {ep.received}")
        ack = await f.command(d.MAV_CMD_COMPONENT_ARM_DISARM, 1)
        assert ack.result == d.MAV_RESULT_ACCEPTED
        await f.wait(lambda: model.mode == Mode.MANUAL and gcs.last("HEARTBEAT").custom_mode == Mode.MANUAL
                     and gcs.last("HEARTBEAT").base_mode & 128, what="armed in MANUAL")
        # Out of SAFE a SAFE-only parameter is refused by the board: why, and the old value.
        got = await f.param_set("EST_ATTITUDE", 0.0)
        assert got.param_value == float(model.param_raw[Param.ATTITUDE_FILTER]) != 0.0
        assert any("EST_ATTITUDE not set" in t and "SAFE" in t for t in gcs.texts()), gcs.texts()
        # The ground station goes silent (armed on the pad, lift at zero): term stops feeding the board, whose
        # failsafe holds level (LINK LOST); its sticks back within the guard time give it control again (LINK_REGAINED).
        f.stick = None
        streaming.join()
        await f.wait(lambda: any("LINK LOST" in t for t in gcs.texts()), timeout=10, what="the board's LINK LOST")
        f.stick = (0, 0, 0, 0)
        streaming = f.stream()
        await f.wait(lambda: any("has the link back" in t for t in gcs.texts()), timeout=10, what="LINK_REGAINED")
        assert model.mode == Mode.MANUAL and ep.state == "ground station", [e.text for e in model.events][-8:]
        # Fly on the ground station's stick: up. Attitude and height against the simulator's truth.
        f.stick = (0, 0, 540, 0)  # (a gentle climb: the room has a ceiling at 3 m)
        await f.wait(lambda: f.instructor.truth is not None and f.instructor.truth.h > 0.3, timeout=30,
                     what=lambda: f"a climb {f.instructor.truth} {[e.text for e in model.events][-6:]}")
        truth = f.instructor.truth
        att, alt = gcs.last("ATTITUDE"), gcs.last("ALTITUDE")
        assert truth is not None and model.mode == Mode.MANUAL and not truth.crashes, (truth, model.mode)
        assert math.degrees(att.roll) == pytest.approx(math.degrees(truth.phi), abs=3.0)
        assert math.degrees(att.pitch) == pytest.approx(math.degrees(truth.theta), abs=3.0)
        assert alt.altitude_relative == pytest.approx(truth.h, abs=0.3)
        assert gcs.last("VFR_HUD").alt == pytest.approx(truth.h, abs=0.3)
        servo = gcs.last("SERVO_OUTPUT_RAW")
        assert all(1200 < getattr(servo, f"servo{i}_raw") < 2000 for i in range(1, 5))
        # Silent in the air past the guard time: PANIC, and the handover ends: control is term's again.
        f.stick = None
        streaming.join()
        await f.wait(lambda: model.mode in (Mode.PANIC, Mode.SAFE) and ep.state == "term", timeout=20,
                     what=lambda: f"PANIC and the handback {[e.text for e in model.events][-8:]}")
        assert any("went silent" in e.text for e in model.events)


async def test_the_flash_log_is_listed_and_downloaded_byte_for_byte(tmp_path: Path) -> None:
    async with flight(tmp_path, seed=7) as f:
        gcs, app, model = f.gcs, f.app, f.app.model
        app.send(Op.LOG_START)
        await f.pilot.pause(1.5)
        app.send(Op.LOG_STOP)
        await f.wait(lambda: model.log_status is not None or True)
        gcs.mav.log_request_list_send(1, 1, 0, 0xFFFF)
        await f.wait(lambda: gcs.last("LOG_ENTRY") is not None, what="LOG_ENTRY")
        entry = gcs.last("LOG_ENTRY")
        assert entry.num_logs == 1 and entry.id == 1 and entry.size > 100
        assert entry.size == model.log_status.used
        gcs.mav.log_request_data_send(1, 1, 1, 0, 0xFFFFFFFF)
        await f.wait(lambda: sum(m.count for m in gcs.seen("LOG_DATA")) >= entry.size, timeout=60,
                     what="the log's bytes")
        parts = {m.ofs: bytes(m.data[:m.count]) for m in gcs.seen("LOG_DATA")}
        data = b"".join(parts[o] for o in sorted(parts))
        assert len(data) == entry.size
        assert zlib.crc32(data) == model.log_status.crc32  # the board's own CRC-32 of its flash


def _free_udp_port() -> int:
    import socket

    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


async def test_mavproxy_lists_the_parameters_and_shows_the_mode(tmp_path: Path) -> None:
    """MAVProxy, a ground station nobody here wrote (pip install MAVProxy), fed its commands on stdin as a user
    types them: the board's 23 parameters with their values, and the HEARTBEAT's custom mode (the board's mode;
    MAVProxy names a quadrotor's custom modes from ArduCopter's table, docs/mavlink.md)."""
    import shutil
    import sys

    exe = shutil.which("mavproxy.py") or str(Path(sys.executable).with_name("mavproxy.py"))
    if not Path(exe).exists():
        pytest.skip("MAVProxy is not installed (pip install MAVProxy)")
    port = _free_udp_port()
    async with flight(tmp_path, seed=8, address=f"udp:127.0.0.1:{port}") as f:
        proc = await asyncio.create_subprocess_exec(
            sys.executable, exe, f"--master=udpin:127.0.0.1:{port}", "--cmd=param fetch", cwd=tmp_path,
            stdin=asyncio.subprocess.PIPE, stdout=asyncio.subprocess.PIPE, stderr=asyncio.subprocess.STDOUT)
        lines: list[str] = []

        async def read() -> None:
            assert proc.stdout is not None
            while line := await proc.stdout.readline():
                lines.append(line.decode("utf-8", "replace"))

        reader = asyncio.create_task(read())
        try:
            await f.wait(lambda: any("Received 23 parameters" in ln for ln in lines), timeout=60,
                         what=f"MAVProxy's parameter list: {lines[-5:]}")
            assert proc.stdin is not None
            proc.stdin.write(b"param show *\nstatus HEARTBEAT\n")
            await proc.stdin.drain()
            await f.wait(lambda: any("custom_mode" in ln for ln in lines), timeout=20, what="MAVProxy's status")
        finally:
            proc.kill()
            await proc.wait()
            reader.cancel()
        text = "".join(lines)
        model = f.app.model
        for pid, name in PARAM_NAMES.items():
            spec = PARAMS[Param(pid)]
            shown = next(ln for ln in text.splitlines() if ln.startswith(name + " ") or ln.endswith("> " + name)
                         or f" {name} " in f" {ln} ")
            assert float(shown.split()[-1]) == pytest.approx(param_float(spec, model.param_raw[pid]), rel=1e-6)
        assert "type : 2" in text and f"custom_mode : {int(Mode.SAFE)}" in text
