"""Counts the arithmetic one RAW-path attitude filter does per sample, the basis of its price in the board's cost
model (``fcb_sim.board.timing.RAW_FILTER_OPS``; docs/board.md, "The RAW filter's price").

``count_ops(name, fixed_point)`` runs the filter on a deterministic stream of tilting, turning samples and returns
the mean number of each operation per sample: the ``update`` and, for a filter whose state is a quaternion (ikf,
qgate), the angles the control step reads (``quaternion()``, then ``dmp.quaternion_to_euler``: three atan2, the
pitch by eq. 5). Float filters are counted by running them on a ``float`` subclass that counts its arithmetic
(operations between constants alone are not counted: the board's compiler folds them) and through a counting
stand-in for ``math``; fixed-point filters by wrapping their primitives (``fixed.smul``, ``ikf_fixed.mul``, ...).
Additions are counted for float (soft-float calls on the board) and not for fixed point (one instruction), except
the saturating ones. Run ``python -m fcb_sim.lab.opcount`` to print the table; a test keeps timing's copy equal to it.
"""

from __future__ import annotations

import contextlib
import math
import random
from collections import Counter
from collections.abc import Iterator
from typing import Any

from fcb_sim.estimation import (
    FILTERS,
    complementary,
    dmp,
    fixed,
    has_fixed_point,
    ikf,
    ikf_fixed,
    ikf_lite,
    kalman,
    kalman_cov,
    make_filter,
    qgate,
)
from fcb_sim.estimation import base as est_base

QUATERNION_FILTERS = frozenset({"ikf", "qgate"})  # their angles are computed from the quaternion at each read
_COUNT: Counter[str] = Counter()


def _c(op: str, v: float) -> _F:
    _COUNT[op] += 1
    return _F(v)


class _F(float):
    """A float that counts the arithmetic done with it (the result is counted too)."""

    def __add__(self, o: Any) -> _F: return _c("add", float(self) + float(o))  # noqa: E704
    def __radd__(self, o: Any) -> _F: return _c("add", float(o) + float(self))  # noqa: E704
    def __sub__(self, o: Any) -> _F: return _c("add", float(self) - float(o))  # noqa: E704
    def __rsub__(self, o: Any) -> _F: return _c("add", float(o) - float(self))  # noqa: E704
    def __mul__(self, o: Any) -> _F: return _c("mul", float(self) * float(o))  # noqa: E704
    def __rmul__(self, o: Any) -> _F: return _c("mul", float(o) * float(self))  # noqa: E704
    def __truediv__(self, o: Any) -> _F: return _c("div", float(self) / float(o))  # noqa: E704
    def __rtruediv__(self, o: Any) -> _F: return _c("div", float(o) / float(self))  # noqa: E704
    def __neg__(self) -> _F: return _F(-float(self))  # noqa: E704  (a sign bit)
    def __abs__(self) -> _F: return _F(abs(float(self)))  # noqa: E704

    def __pow__(self, o: Any) -> _F:
        if o != 2:
            raise ValueError("only squares are counted")
        return _c("mul", float(self) * float(self))


class _Math:
    """``math`` with sqrt, sin, cos, atan2 and asin counted when their argument is a counted float."""

    def __getattr__(self, name: str) -> Any:
        return getattr(math, name)

    @staticmethod
    def _fn(name: str, *args: float) -> float:
        v = getattr(math, name)(*(float(a) for a in args))
        return _c(name, v) if any(isinstance(a, _F) for a in args) else v

    def sqrt(self, x: float) -> float: return self._fn("sqrt", x)  # noqa: E704
    def sin(self, x: float) -> float: return self._fn("sin", x)  # noqa: E704
    def cos(self, x: float) -> float: return self._fn("cos", x)  # noqa: E704
    def atan2(self, y: float, x: float) -> float: return self._fn("atan2", y, x)  # noqa: E704
    def asin(self, x: float) -> float: return self._fn("asin", x)  # noqa: E704


_FLOAT_MODULES = tuple(m for m in (ikf, qgate, complementary, kalman, kalman_cov, est_base, dmp) if hasattr(m, "math"))
_FIXED_OPS = {  # module: the primitives counted there, by the name the price table uses
    fixed: {"smul": "mul", "mul": "mul", "sdiv": "div", "div": "div", "sqrt": "sqrt", "sadd": "sadd",
            "ssub": "sadd", "atan2_corrected": "atan2_correction"},
    ikf_fixed: {"mul": "mul", "div": "div", "sqrt": "sqrt", "_sat": "sat"},
    ikf_lite: {"mul": "mul", "div": "div", "sqrt": "sqrt", "_sat": "sat", "qmul": "qmul"},
}


@contextlib.contextmanager
def _counting() -> Iterator[Counter[str]]:
    """Counting math in the float filters' modules and counting primitives in the fixed-point ones, restored on
    the way out."""
    saved: list[tuple[Any, str, Any]] = []
    try:
        for mod in _FLOAT_MODULES:
            saved.append((mod, "math", mod.math))
            mod.math = _Math()  # type: ignore[assignment]
        for mod, names in _FIXED_OPS.items():
            for fn, op in names.items():
                real = getattr(mod, fn)
                saved.append((mod, fn, real))
                setattr(mod, fn, _counted_call(real, op))
        _COUNT.clear()
        yield _COUNT
    finally:
        for mod, name, value in reversed(saved):
            setattr(mod, name, value)


def _counted_call(fn: Any, op: str) -> Any:
    def call(*args: Any) -> Any:
        _COUNT[op] += 1
        return fn(*args)

    return call


def samples(n: int = 2000, seed: int = 1) -> list[tuple[float, ...]]:
    """(gx, gy, gz, ax, ay, az) at 400 Hz: a body swinging about every axis (up to ±1.5 rad/s), gravity seen in
    the tilted frame plus a little linear acceleration and noise; deterministic."""
    rng = random.Random(seed)
    out = []
    for i in range(n):
        t = i / 400.0
        gx, gy, gz = 1.5 * math.sin(1.3 * t), 1.0 * math.sin(0.7 * t + 1.0), 0.5 * math.sin(0.3 * t)
        roll, pitch = 0.6 * math.sin(0.9 * t), 0.4 * math.sin(0.5 * t + 0.3)
        ax = -9.81 * math.sin(pitch) + rng.gauss(0.0, 0.3)
        ay = 9.81 * math.cos(pitch) * math.sin(roll) + rng.gauss(0.0, 0.3)
        az = 9.81 * math.cos(pitch) * math.cos(roll) + rng.gauss(0.0, 0.3)
        out.append((gx + rng.gauss(0.0, 0.01), gy + rng.gauss(0.0, 0.01), gz + rng.gauss(0.0, 0.01), ax, ay, az))
    return out


def count_ops(name: str, fixed_point: bool = False, n: int = 2000) -> dict[str, float]:
    """Operations per sample (mean over ``n`` samples after the first) of filter ``name``: its update and, for a
    quaternion filter, the angles read from it. Rounded to 0.1."""
    f = make_filter(name, fixed_point=fixed_point, native=False)  # the Python twin: its primitives are counted
    data = samples(n + 1)
    dt = 1.0 / 400.0
    f.update(*data[0], dt)  # the first sample only initialises
    with _counting() as counts:
        for s in data[1:]:
            f.update(*(s if fixed_point else (_F(v) for v in s)), dt)
            if name in QUATERNION_FILTERS:
                q = f.quaternion()
                dmp.quaternion_to_euler(*(_F(v) for v in q))
        totals = dict(counts)
    for attr, value in list(vars(f).items()):  # leave the filter as plain numbers (it is thrown away anyway)
        if isinstance(value, _F):
            setattr(f, attr, float(value))
    return {op: round(c / n, 1) for op, c in sorted(totals.items())}


def table() -> dict[tuple[str, bool], dict[str, float]]:
    """``count_ops`` of every filter, float and (where it has one) fixed point."""
    return {(name, fx): count_ops(name, fx) for name in FILTERS for fx in (False, True)
            if not fx or has_fixed_point(name)}


if __name__ == "__main__":
    for (name, fx), ops in table().items():
        print(f"    ({name!r}, {fx}): {ops},")
