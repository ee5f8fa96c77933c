"""The report's two complementary estimators in C (firmware/board/qb_est_comp.c) are the Python board's, bit for bit
on the host: eq. 1 in double (ComplementaryFilter) and in Q16.16 (ComplementaryFilterQ16, libfixmath with the
report's corrected atan2), and Figure 10 (make_height_estimator("complementary")), fed the same hypothesis-drawn
samples through the C board's library (ctypes on its exported functions). Tilts to ±180°, gyro and accelerometer to
their ranges' ends, the atan2 table's every segment, both mirrors. Then `fcb-sim serve --board c --preset report`
flies from the outside: term's app over the pseudo-terminal, on the report's estimators (RAW, HEIGHT)."""

from __future__ import annotations

import ctypes
import math
import shutil
import subprocess
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from fcb_sim.board.parts import BoardConfig
from fcb_sim.errors import UsageError
from fcb_sim.estimation.complementary import ComplementaryFilter, ComplementaryFilterQ16
from fcb_sim.estimation.height import make_height_estimator
from fcb_sim.hosts.cboard import FIRMWARE, CBoard, library_path
from term.core.protocol import PARAMS, Joystick, Mode, Op, Param
from tests.support.served_rig import served

pytestmark = pytest.mark.skipif(shutil.which("cc") is None or shutil.which("make") is None,
                                reason="no C compiler (cc) or make: the C board's tests are skipped")

D = ctypes.c_double
STATE = 512  # bytes: more than either struct (qb_comp_t, qb_hcomp_t)


@pytest.fixture(scope="module")
def lib() -> ctypes.CDLL:
    lib = ctypes.CDLL(str(library_path()))
    vp = ctypes.c_void_p
    lib.qb_comp_init.argtypes = [vp, D, ctypes.c_int]
    lib.qb_comp_reset.argtypes = [vp]
    lib.qb_comp_update.argtypes = [vp, D, D, D, D, D, D, D]
    lib.qb_comp_angles.argtypes = lib.qb_comp_quaternion.argtypes = [vp, ctypes.POINTER(D)]
    lib.qb_hcomp_reset.argtypes = [vp, D]
    lib.qb_hcomp_update_imu.argtypes = [vp, D, D, D, D, D, D, D, D]
    lib.qb_hcomp_update_baro.argtypes = [vp, D, D]
    return lib


_RATE = st.floats(-35.0, 35.0, allow_nan=False)  # rad/s: the gyro's ±2000°/s
_ACC = st.floats(-20.0, 20.0, allow_nan=False)  # m/s²: the accelerometer's ±2 g
_DT = st.sampled_from([0.0025, 0.005, 0.0024963, 0.0100708])  # RAW, DMP, and RTC-measured periods
_SAMPLE = st.tuples(_RATE, _RATE, _RATE, _ACC, _ACC, _ACC, _DT)
# whole tilts: specific force of a given size at any roll and pitch (every atan2 segment and mirror)
_TILT = st.builds(lambda r, p, g, dt: (0.1, -0.2, 0.05, -g * math.sin(p), g * math.sin(r) * math.cos(p),
                                       g * math.cos(r) * math.cos(p), dt),
                  st.floats(-math.pi, math.pi), st.floats(-math.pi / 2, math.pi / 2), st.floats(0.0, 19.0), _DT)


@settings(max_examples=150, deadline=None)
@given(st.booleans(), st.sampled_from([0.999, 0.9, 0.98, 0.5]),
       st.lists(st.one_of(_SAMPLE, _TILT), min_size=1, max_size=60))
def test_eq1_is_the_python_filters_bit_for_bit(lib: ctypes.CDLL, fixed: bool, k_gyro: float,
                                               samples: list[tuple[float, ...]]) -> None:
    py = ComplementaryFilterQ16(k_gyro) if fixed else ComplementaryFilter(k_gyro)
    buf = ctypes.create_string_buffer(STATE)
    lib.qb_comp_init(buf, k_gyro, int(fixed))
    e, q = (D * 3)(), (D * 4)()
    for s in samples:
        py.update(*s)
        lib.qb_comp_update(buf, *s)
        lib.qb_comp_angles(buf, e)
        lib.qb_comp_quaternion(buf, q)
        assert (e[0], e[1], e[2]) == (py.roll, py.pitch, py.yaw), s
        assert tuple(q) == py.quaternion(), s


def _unit(w: float, x: float, y: float, z: float) -> tuple[float, float, float, float]:
    n = math.sqrt(w * w + x * x + y * y + z * z) or 1.0
    return w / n, x / n, y / n, z / n


_Q = st.builds(_unit, st.floats(0.5, 1.0), *(st.floats(-0.3, 0.3) for _ in range(3)))
_IMU = st.tuples(st.just("imu"), st.tuples(_ACC, _ACC, st.floats(0.0, 20.0), _Q,
                                           st.sampled_from([0.0025, 0.005, 0.0, -0.001])))
_BARO = st.tuples(st.just("baro"), st.tuples(st.floats(95_000.0, 106_000.0) | st.sampled_from([0.0, -5.0]),
                                             st.sampled_from([0.05, 0.0499, 0.0, 0.1])))


@settings(max_examples=150, deadline=None)
@given(st.floats(90_000.0, 110_000.0), st.lists(st.one_of(_IMU, _BARO), min_size=1, max_size=80))
def test_figure_10_is_the_python_estimators_bit_for_bit(lib: ctypes.CDLL, p0: float,
                                                        steps: list[tuple[str, tuple]]) -> None:
    py = make_height_estimator("complementary")
    py.reset(p0)
    buf = ctypes.create_string_buffer(STATE)
    lib.qb_hcomp_reset(buf, p0)
    # the C struct's first eight doubles: p_ref, k_pa_per_m, height, vz, az_earth, baro_raw, baro_height, baro_vz
    view = (D * 8).from_buffer(buf)
    for kind, arg in steps:
        if kind == "imu":
            ax, ay, az, (qw, qx, qy, qz), dt = arg
            py.update_imu(ax, ay, az, qw, qx, qy, qz, dt)
            lib.qb_hcomp_update_imu(buf, ax, ay, az, qw, qx, qy, qz, dt)
        else:
            py.update_baro(*arg)
            lib.qb_hcomp_update_baro(buf, *arg)
        assert tuple(view) == (py.p_ref, py.k_pa_per_m, py.height, py.vz, py.az_earth, py.baro_raw,
                               py.baro_height, py.baro_vz), (kind, arg)


async def test_fcb_sim_serve_board_c_flies_the_report_preset() -> None:
    """`fcb-sim serve --board c --preset report` (refused before): term reads the report's values back, calibrates
    (held by the pilot, the report's), and flies RAW on eq. 1 and HEIGHT on Figure 10."""
    library_path()  # built here, not inside the simulator's start-up time
    async with served(extra=["--board", "c", "--preset", "report"]) as (app, pilot, until):
        m = app.model
        assert m.params[PARAMS[Param.ATTITUDE_FILTER].name] == m.params[PARAMS[Param.HEIGHT_ESTIMATOR].name] == (
            "complementary")
        assert m.params[PARAMS[Param.FIXED_POINT].name] is False and m.params[PARAMS[Param.P2].name] == 111.0
        app.set_stick(Joystick(0, 0, 0, 0, 0))
        app.send(Op.MODE, Mode.CALIBRATION)
        await until(lambda: m.mode == Mode.CALIBRATION, 30.0)
        await pilot.pause(1.2)  # mode.calibration_ms 0: the means for as long as the pilot holds it
        app.send(Op.MODE, Mode.SAFE)
        await until(lambda: m.mode == Mode.SAFE, 30.0)
        app.send(Op.MODE, Mode.RAW)
        await until(lambda: m.mode == Mode.RAW, 30.0)
        app.send(Op.MODE, Mode.HEIGHT)
        await until(lambda: m.mode == Mode.HEIGHT, 30.0)
        assert not [e.text for e in m.events if e.source == "nak"]


def test_a_board_built_without_them_refuses_the_preset_in_one_line(tmp_path: Path) -> None:
    """QB_REPORT_EST=0, as the Cortex-M0 image is built (its flash budget): both values NOT_IMPLEMENTED, the
    preset refused naming them; the same board takes the default preset."""
    make = subprocess.run(["make", "-s", "-C", str(FIRMWARE), f"BUILD={tmp_path}", "CPPFLAGS=-DQB_REPORT_EST=0",
                           "board"], capture_output=True, text=True)
    assert make.returncode == 0, make.stderr
    with pytest.raises(UsageError) as err:
        CBoard(BoardConfig(preset="report"), build_dir=tmp_path)
    assert str(err.value) == ("the C board cannot run preset 'report': est.attitude = complementary, est.height = "
                              "complementary (docs/firmware.md)")
    board = CBoard(BoardConfig(), build_dir=tmp_path)
    assert board.param_raw(Param.ATTITUDE_FILTER) == 4 and board.param_raw(Param.HEIGHT_ESTIMATOR) == 1
