"""The simulator's hot path in C: the RAW filter ikf (firmware/board/ikf_f.c in doubles, ikf_q.c in fixed point)
through ctypes.

``library()`` is the host build of firmware/board/ikf_q.c and ctl_q.c (``make -C firmware native``: libikfq.so in
the user's cache, built once per version of the sources by fcb_sim/cbuild.py), or None where it cannot be built
(no C compiler, no make: the pure-Python filter runs, and ``why_not()`` says why in one line;
``QUADRUPEL_PURE_PYTHON=1`` asks for the Python path on purpose). ``NativeIKF`` is
:class:`~fcb_sim.estimation.ikf.InertialKalmanFilter` in C (the same doubles), ``NativeIKFQ``
:class:`~fcb_sim.estimation.ikf_fixed.InertialKalmanFilterQ` (the same integers, formats too):
tests/estimation/test_ikf_native.py feeds both sides the same samples. The Python classes stay the references the C is
tested against.
"""

from __future__ import annotations

import ctypes
import os
import threading
from collections.abc import Sequence
from pathlib import Path

from fcb_sim import cbuild
from fcb_sim.estimation.base import QuaternionAnglesMixin
from fcb_sim.estimation.ikf import InertialKalmanFilter
from fcb_sim.estimation.ikf_fixed import Formats, InertialKalmanFilterQ, to_q
from fcb_sim.estimation.ikf_lite import InertialKalmanFilterQL

LIBRARY = "libikfq.so"
STATE_FIELDS = ("qw", "qx", "qy", "qz", "vx", "vy", "dx", "dy", "pvv", "pvg", "pvd", "pgg", "pgd", "pdd", "bx", "by",
                "bz", "rx", "ry", "rz", "gl0", "gl1", "gl2", "al0", "al1", "al2", "rest_t", "at_rest", "started",
                "phase", "fx", "fy", "fz", "qm0", "qm1", "qm2", "qm3", "rate", "gxh", "gyh")
_LOCK = threading.Lock()
_lib: ctypes.CDLL | None = None
_why: str | None = None


class _Formats(ctypes.Structure):
    _fields_ = [(n, ctypes.c_uint8) for n in ("io", "dt", "quat", "bias", "vel", "drift", "cov")]


class _Params(ctypes.Structure):
    _fields_ = [(n, ctypes.c_double) for n in (
        "q_g0", "k_rot", "drift_init", "drift_noise", "latency", "rest_r", "rest_gyro", "rest_acc", "rest_time",
        "rest_tau", "rest_bias_tau", "bias_max")]


class _Consts(ctypes.Structure):
    _fields_ = [(n, ctypes.c_int32) for n in (
        "qg_shift", "q_g0", "k_rot", "drift_noise", "rest_r", "rest_g2", "rest_a2", "bias_max", "inv_g0",
        "lat_half", "pgg0", "pdd0", "g0_io", "swing_max", "swing_k")] + [("rest_time", ctypes.c_int64)] + [
        (n, ctypes.c_int32) for n in ("dtq", "dt2q", "dthq", "krq", "kbq", "decim", "lite")]


def build(build_dir: Path | None = None) -> Path:
    """The host library (``make native``), built once per version of the sources into the user's cache
    (fcb_sim/cbuild.py) or ``build_dir``. Raises RuntimeError (one line) if it cannot be built."""
    try:
        return cbuild.build("native", [LIBRARY], out=build_dir, tools=[os.environ.get("CC", "cc")],
                            missing="no C compiler (cc) or make: the Python filter runs",
                            what="firmware/board/ikf_q.c") / LIBRARY
    except cbuild.BuildError as e:
        raise RuntimeError(str(e)) from None


def _load(path: Path) -> ctypes.CDLL:
    lib = ctypes.CDLL(str(path))
    vp, d, i32p, i64p = ctypes.c_void_p, ctypes.c_double, ctypes.POINTER(ctypes.c_int32), ctypes.POINTER(ctypes.c_int64)
    lib.ikfq_size.restype = ctypes.c_uint
    lib.ikff_size.restype = ctypes.c_uint
    lib.ikff_init.argtypes = [vp, ctypes.POINTER(_Params)]
    lib.ikff_reset.argtypes = [vp]
    lib.ikff_update_q.argtypes = [vp, d, d, d, d, d, d, d, ctypes.POINTER(d)]
    lib.ikff_update_q.restype = None
    lib.ikfq_init.argtypes = [vp, ctypes.POINTER(_Formats), ctypes.POINTER(_Params)]
    lib.ikfq_init_q.argtypes = [vp, ctypes.POINTER(_Formats), ctypes.POINTER(_Consts)]
    lib.ikfq_consts.argtypes = [vp, ctypes.POINTER(_Consts)]
    lib.ikfq_reset.argtypes = [vp]
    lib.ikfq_update.argtypes = [vp, d, d, d, d, d, d, d]
    lib.ikfq_update.restype = None
    lib.ikfq_update_q.argtypes = [vp, d, d, d, d, d, d, d, ctypes.POINTER(d)]
    lib.ikfq_update_q.restype = None
    lib.ikfq_predicted.argtypes = [vp, i32p]
    lib.ikfq_run.argtypes = [vp, ctypes.c_int32, ctypes.POINTER(d), ctypes.c_int32, i32p, ctypes.POINTER(d)]
    lib.ikfq_run.restype = None
    lib.ikfq_state.argtypes = [vp, i64p]
    lib.ikfq_set_dt.argtypes = [vp, d]
    lib.ikfq_set_decimation.argtypes = [vp, ctypes.c_int32]
    lib.ikfq_set_lite.argtypes = [vp, ctypes.c_int32]
    lib.ikfq_step.argtypes = [vp, i32p, i32p]
    lib.ctlq_step.argtypes = [vp, vp, ctypes.POINTER(ctypes.c_int16)]
    lib.ctlq_law.argtypes = [vp, vp, ctypes.c_int32, ctypes.c_int32, ctypes.POINTER(ctypes.c_int16)]
    lib.ctlq_angles.argtypes = [ctypes.POINTER(ctypes.c_int32), ctypes.POINTER(ctypes.c_int32),
                                ctypes.POINTER(ctypes.c_int32)]
    lib.ctlq_atan2.argtypes = [ctypes.c_int32, ctypes.c_int32]
    lib.ctlq_atan2.restype = ctypes.c_int32
    lib.ctlq_angles_lite.argtypes = lib.ctlq_angles.argtypes
    lib.ctlq_atan2_q15.argtypes = [ctypes.c_int32, ctypes.c_int32]
    lib.ctlq_atan2_q15.restype = ctypes.c_int32
    return lib


def library() -> ctypes.CDLL | None:
    """The loaded host library, or None (``why_not()`` says why); built and loaded once per process."""
    global _lib, _why
    with _LOCK:
        if _lib is None and _why is None:
            if os.environ.get("QUADRUPEL_PURE_PYTHON"):
                _why = "QUADRUPEL_PURE_PYTHON is set"
            else:
                try:
                    _lib = _load(build())
                except (RuntimeError, OSError) as e:
                    _why = str(e)
        return _lib


def why_not() -> str | None:
    """Why the C path is not in use (None when it is)."""
    library()
    return _why


class NativeIKF(QuaternionAnglesMixin):
    """ikf in doubles, in C (firmware/board/ikf_f.c): InertialKalmanFilter's interface and the same doubles.
    Its parameters (tau, k_rot, latency, ...) are read from the Python instance it was built from."""

    native = True
    _STATE = ("w", "x", "y", "z", "vx", "vy", "dx", "dy", "pvv", "pvg", "pvd", "pgg", "pgd", "pdd", "bx", "by", "bz",
              "rx", "ry", "rz", "gl0", "gl1", "gl2", "al0", "al1", "al2", "rest_t")

    def __init__(self, lib: ctypes.CDLL | None = None, **params: float) -> None:
        lib = lib or library()
        if lib is None:
            raise RuntimeError(f"the C filter is not available: {why_not()}")
        self._lib = lib
        self.reference = p = InertialKalmanFilter(**params)  # validates and holds the parameters; never run
        if p.decimation != 1:
            raise ValueError("ikf_f.c runs the gravity part every sample (decimation 1): use the Python class")
        self._par = _Params(p.q_g0, p.k_rot, p.drift_init, p.drift_noise, p.latency, p.rest_r, p.rest_gyro,
                            p.rest_acc, p.rest_time, p.rest_tau, p.rest_bias_tau, p.bias_max)
        self._buf = ctypes.create_string_buffer(lib.ikff_size())
        self._s = ctypes.cast(self._buf, ctypes.c_void_p)
        self._qbuf = (ctypes.c_double * 4)()
        self._q = (1.0, 0.0, 0.0, 0.0)
        self._update_q = lib.ikff_update_q
        lib.ikff_init(self._s, ctypes.byref(self._par))

    def __getattr__(self, name: str) -> float:
        if name.startswith("_") or name == "reference":
            raise AttributeError(name)
        return getattr(self.reference, name)  # the parameters: tau, k_rot, latency, ...

    def reset(self) -> None:
        self._lib.ikff_reset(self._s)
        self._q = (1.0, 0.0, 0.0, 0.0)

    def update(self, gx: float, gy: float, gz: float, ax: float, ay: float, az: float, dt: float) -> None:
        qb = self._qbuf
        self._update_q(self._s, gx, gy, gz, ax, ay, az, dt, qb)
        self._q = (qb[0], qb[1], qb[2], qb[3])

    def quaternion(self) -> tuple[float, float, float, float]:
        return self._q

    def state(self) -> dict[str, float]:
        """The doubles after the parameters (ikff_t's layout: 12 parameters, then _STATE), by name."""
        v = (ctypes.c_double * (12 + len(self._STATE))).from_buffer_copy(self._buf)
        return dict(zip(self._STATE, v[12:], strict=True))

    @property
    def at_rest(self) -> bool:
        return bool(ctypes.c_int.from_buffer_copy(self._buf, 8 * (12 + len(self._STATE))).value)

    @property
    def bias(self) -> tuple[float, float, float]:
        st = self.state()
        return st["bx"], st["by"], st["bz"]


class NativeIKFQ(QuaternionAnglesMixin):
    """ikf in fixed point, in C (firmware/board/ikf_q.c): InertialKalmanFilterQ's interface and bits."""

    native = True
    lite = False
    REFERENCE: type[InertialKalmanFilterQ] = InertialKalmanFilterQ

    def __init__(self, formats: Formats | None = None, lib: ctypes.CDLL | None = None, **params: float) -> None:
        self._lib = lib or library()
        if self._lib is None:
            raise RuntimeError(f"the C filter is not available: {why_not()}")
        self.reference = self.REFERENCE(formats, **params)  # validates and holds the parameters; never run
        self.f = self.reference.f
        p = self.reference.ref
        self._fmt = _Formats(*(getattr(self.f, n) for n in ("io", "dt", "quat", "bias", "vel", "drift", "cov")))
        self._par = _Params(p.q_g0, p.k_rot, p.drift_init, p.drift_noise, p.latency, p.rest_r, p.rest_gyro,
                            p.rest_acc, p.rest_time, p.rest_tau, p.rest_bias_tau, p.bias_max)
        self._buf = ctypes.create_string_buffer(self._lib.ikfq_size())
        self._s = ctypes.cast(self._buf, ctypes.c_void_p)
        self._qbuf = (ctypes.c_double * 4)()
        self._q = (1.0, 0.0, 0.0, 0.0)
        self._update_q = self._lib.ikfq_update_q
        self._lib.ikfq_init(self._s, ctypes.byref(self._fmt), ctypes.byref(self._par))
        if p.decimation != 1:
            self._lib.ikfq_set_decimation(self._s, p.decimation)
        if self.lite:
            self._lib.ikfq_set_lite(self._s, 1)

    def reset(self) -> None:
        self._lib.ikfq_reset(self._s)
        self._q = (1.0, 0.0, 0.0, 0.0)

    def update(self, gx: float, gy: float, gz: float, ax: float, ay: float, az: float, dt: float) -> None:
        qb = self._qbuf
        self._update_q(self._s, gx, gy, gz, ax, ay, az, dt, qb)
        self._q = (qb[0], qb[1], qb[2], qb[3])

    def quaternion(self) -> tuple[float, float, float, float]:
        return self._q

    def step_q(self, g: tuple[int, int, int], a: tuple[int, int, int], dt: float) -> tuple[int, int, int, int]:
        """One board step on Q.io samples (ikfq_set_dt, ikfq_step), as the M0 runs it; the predicted quaternion."""
        lib = self._lib
        lib.ikfq_set_dt(self._s, dt)
        lib.ikfq_step(self._s, (ctypes.c_int32 * 3)(*g), (ctypes.c_int32 * 3)(*a))
        q = (ctypes.c_int32 * 4)()
        lib.ikfq_predicted(self._s, q)
        return q[0], q[1], q[2], q[3]

    def run(self, rows: Sequence[Sequence[float]] | memoryview, latencies: Sequence[float]) -> memoryview:
        """Every row (gx, gy, gz, ax, ay, az, dt) through ``update``, and after each the attitude predicted at each
        of ``latencies`` (s), in one call (ikfq_run; scoring a latency grid in one run): n * len(latencies) * 4
        doubles (w, x, y, z), row-major. ``rows``: a sequence of rows, or a C-contiguous buffer of n * 7 doubles
        (a numpy array's memoryview)."""
        m = len(latencies)
        if isinstance(rows, memoryview):
            flat = (ctypes.c_double * (rows.nbytes // 8)).from_buffer_copy(rows)
        else:
            flat = (ctypes.c_double * (7 * len(rows)))(*(v for r in rows for v in r))
        n = len(flat) // 7
        lat = (ctypes.c_int32 * m)(*(to_q(0.5 * x, self.f.dt) for x in latencies))
        out = (ctypes.c_double * (4 * m * n))()
        self._lib.ikfq_run(self._s, n, flat, m, lat, out)
        p = (ctypes.c_int32 * 4)()
        self._lib.ikfq_predicted(self._s, p)
        k = 1.0 / (1 << self.f.quat)
        self._q = (p[0] * k, p[1] * k, p[2] * k, p[3] * k)  # quaternion() at the filter's own latency
        return memoryview(out).cast("B").cast("d")

    CONSTS = ("qg_shift", "q_g0", "k_rot", "drift_noise", "rest_r", "rest_g2", "rest_a2", "bias_max", "inv_g0",
              "lat_half", "pgg0", "pdd0", "g0_io", "swing_max", "swing_k", "rest_time", "dtq", "dt2q", "dthq", "krq",
              "kbq", "decim", "lite")

    def consts(self, dt: float) -> dict[str, int]:
        """The integers ikfq_init and ikfq_set_dt derive (ikfq_consts_t), for a board's table: no doubles there."""
        self._lib.ikfq_set_dt(self._s, dt)
        c = _Consts()
        self._lib.ikfq_consts(self._s, ctypes.byref(c))
        return {n: getattr(c, n) for n in self.CONSTS}

    def init_from_consts(self, consts: dict[str, int]) -> None:
        """ikfq_init_q: the filter set up from the integers alone (as a board without doubles would)."""
        self._lib.ikfq_init_q(self._s, ctypes.byref(self._fmt), ctypes.byref(_Consts(**consts)))

    def raw_state(self) -> bytes:
        """The C struct's bytes (its layout is the M0 build's too: fcb_sim.hosts.m0emu starts from it)."""
        return bytes(self._buf)

    def state(self) -> dict[str, int]:
        """The filter's integers by name (STATE_FIELDS), for comparing with the Python twin."""
        out = (ctypes.c_int64 * len(STATE_FIELDS))()
        self._lib.ikfq_state(self._s, out)
        return dict(zip(STATE_FIELDS, out, strict=True))

    @property
    def at_rest(self) -> bool:
        return bool(self.state()["at_rest"])

    @property
    def bias(self) -> tuple[float, float, float]:
        st, s = self.state(), 1.0 / (1 << self.f.bias)
        return st["bx"] * s, st["by"] * s, st["bz"] * s


class NativeIKFQL(NativeIKFQ):
    """The variant cut to fit the Cortex-M0, in C (ikf_q.c with ``lite`` set): InertialKalmanFilterQL's bits."""

    lite = True
    REFERENCE = InertialKalmanFilterQL


def python_state(f: InertialKalmanFilterQ) -> dict[str, int]:
    """The Python twin's integers in STATE_FIELDS' names."""
    out = {n: getattr(f, n) for n in STATE_FIELDS[:20] if n != "rest_t"}
    out.update(gl0=f.gl[0], gl1=f.gl[1], gl2=f.gl[2], al0=f.al[0], al1=f.al[1], al2=f.al[2], rest_t=f.rest_t,
               at_rest=int(f.at_rest), started=int(f._started))
    out.update({n: getattr(f, n) for n in STATE_FIELDS[29:] if not n.startswith("qm")})
    out.update(qm0=f.qm[0], qm1=f.qm[1], qm2=f.qm[2], qm3=f.qm[3])
    return {n: out[n] for n in STATE_FIELDS}


def constants_c(dt: float = 0.0025) -> str:
    """A C initializer of ikfq_consts_t for the default parameters and formats at ``dt``: ikf in fixed point as
    make_filter gives it (the lite variant, its gravity part spread over 4 samples)."""
    c = NativeIKFQL().consts(dt)
    body = ", ".join(f".{k} = {v}" for k, v in c.items())
    return f"/* fcb_sim.estimation.native.constants_c(dt={dt!r}): ikf's defaults, ikf_fixed.Formats(), ikf_lite */\n" \
           f"static const ikfq_consts_t IKFQ_CONSTS = {{{body}}};"


if __name__ == "__main__":
    import sys

    print(constants_c(float(sys.argv[2]) if len(sys.argv) > 2 and sys.argv[1] == "--constants" else 0.0025))
