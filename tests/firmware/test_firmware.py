"""The C codec (firmware/) against the Python one (term/core/protocol/): generated from the same table and up to date,
the same bytes for the test vectors both ways, the same packets and the same decoder counts for any stream (valid
frames, any slicing, byte by byte, corrupted, inserted and dropped bytes, garbage), under ASan and UBSan; no libc
beyond <string.h>, no static state; the Cortex-M0 build within its budget."""

from __future__ import annotations

import importlib.util
import json
import math
import re
import shutil
import struct
import subprocess
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from term.core import protocol as p
from tests.support.firmware import (
    FIRMWARE,
    NO_ARM,
    ROOT,
    build,
    python_fields,
    python_stats,
    runner,
)

VECTORS = json.loads((ROOT / "tests" / "vectors" / "protocol.json").read_text())


def _generator():  # noqa: ANN202
    spec = importlib.util.spec_from_file_location("gen_c", FIRMWARE / "gen_c.py")
    assert spec and spec.loader
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


# --- generated, committed, self-contained -------------------------------------------------------------------


def test_generated_c_is_up_to_date() -> None:
    for path, text in _generator().outputs().items():
        assert path.read_text() == text, f"{path.relative_to(ROOT)} is stale: run .venv/bin/python firmware/gen_c.py"


def test_every_packet_and_enum_member_is_in_the_header() -> None:
    header = (FIRMWARE / "qp_protocol.h").read_text()
    for spec in p.PACKETS.values():
        assert re.search(rf"#define QP_TYPE_\w+ {spec.type_id:#04x}\n", header)
    for member in p.Nak:
        assert f"QP_NAK_{member.name} = {int(member)}," in header


def test_the_library_includes_nothing_but_three_libc_headers() -> None:
    for name in ("qp_protocol.h", "qp_protocol.c"):
        includes = re.findall(r'^#include [<"]([^>"]+)[>"]', (FIRMWARE / name).read_text(), re.M)
        assert set(includes) <= {"stdint.h", "stddef.h", "string.h", "qp_protocol.h"}, (name, includes)


def test_the_library_has_no_static_state_and_calls_only_string_h(tmp_path: Path) -> None:
    build()
    obj = tmp_path / "qp_protocol.o"
    source = str(FIRMWARE / "qp_protocol.c")
    subprocess.run(["cc", "-std=c99", "-O2", "-fno-stack-protector", "-c", source, "-o", str(obj)], check=True)
    symbols = subprocess.run(["nm", str(obj)], capture_output=True, text=True, check=True).stdout.split("\n")
    kinds = {line.split()[-1]: line.split()[-2] for line in symbols if line.strip()}
    writable = {name for name, kind in kinds.items() if kind in "BbDdCGgSs"}
    assert not writable, f"static state: {writable}"
    undefined = {name for name, kind in kinds.items() if kind == "U"}
    assert undefined <= {"memcpy", "memset"}, undefined


@pytest.fixture(scope="module")
def c_decoder():  # noqa: ANN201
    """The sanitized runner, one process for the module."""
    with runner() as c:
        yield c


# --- the test vectors ---------------------------------------------------------------------------------------


@pytest.mark.parametrize("sanitized", [True, False], ids=["asan-ubsan", "plain"])
def test_vectors_encode_to_the_same_bytes_and_decode_to_the_same_fields(sanitized: bool) -> None:
    with runner(sanitized) as c:
        for v in VECTORS:
            pkt = p.from_dict(v["packet"])
            assert c.encode(pkt, v["seq"]).hex() == v["hex"], v["packet"]["type"]
            c.reset()
            got, stats = c.feed(bytes.fromhex(v["hex"]))
            assert got == [{"seq": v["seq"], **python_fields(pkt)}]
            assert stats == (1, 0, 0, 0, 0, len(v["hex"]) // 2)


def test_crc_is_ccitt_false() -> None:
    with runner() as c:
        assert c.ask("crc " + b"123456789".hex()) == [f"crc {0x29B1}"]


def test_half_floats_convert_as_python_does(c_decoder) -> None:  # noqa: ANN001
    halves = range(0x10000)  # every one of them
    (line,) = c_decoder.ask("h2f " + " ".join(f"{h:x}" for h in halves))
    got = [int(b, 16) for b in line.split()[1:]]
    for h, bits in zip(halves, got, strict=True):
        want = struct.unpack("<e", struct.pack("<H", h))[0]
        value = struct.unpack("<f", struct.pack("<I", bits))[0]
        assert value == want or (math.isnan(value) and math.isnan(want)), hex(h)
        assert bits >> 31 == h >> 15  # the sign, zeros and NaNs included


@settings(max_examples=200, suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])
@given(st.lists(st.floats(width=32), min_size=1, max_size=50))
def test_floats_round_to_half_as_python_does(c_decoder, values: list[float]) -> None:  # noqa: ANN001
    (line,) = c_decoder.ask("f2h " + " ".join(f"{struct.unpack('<I', struct.pack('<f', v))[0]:x}" for v in values))
    for v, bits in zip(values, line.split()[1:], strict=True):
        h = int(bits, 16)
        if math.isnan(v):
            assert h & 0x7C00 == 0x7C00 and h & 0x3FF
            continue
        try:
            want = struct.unpack("<H", struct.pack("<e", v))[0]
        except OverflowError:  # Python refuses what a half cannot hold; the C side gives infinity
            want = 0xFC00 if v < 0 else 0x7C00
        assert h == want, (v, hex(h), hex(want))


# --- any stream: the C decoder and the Python decoder agree, frame for frame --------------------------------

_INT = {"B": (0, 0xFF), "b": (-0x80, 0x7F), "H": (0, 0xFFFF), "h": (-0x8000, 0x7FFF), "I": (0, 0xFFFFFFFF),
        "i": (-0x80000000, 0x7FFFFFFF)}


def _field(fmt: str) -> st.SearchStrategy:
    if fmt in _INT:
        return st.integers(*_INT[fmt])
    if fmt == "e":
        return st.floats(width=16, allow_nan=False)
    if fmt.endswith("s"):
        return st.binary(min_size=int(fmt[:-1]), max_size=int(fmt[:-1]))
    raise AssertionError(fmt)


packets = st.one_of([st.builds(s.cls, *[_field(fs.fmt) for fs in s.fields]) for s in p.PACKETS.values()])

# Garbage that passes the framing but not the checks after it: valid COBS pieces of any length, mostly short.
cobs_pieces = st.lists(st.binary(max_size=22), max_size=4).map(
    lambda raws: b"".join(p.cobs_encode(r) + b"\x00" for r in raws))
# A stream: frames (with their own sequence numbers, so gaps happen too) and garbage, in any order.
pieces = st.lists(st.one_of(st.tuples(st.just("frame"), packets, st.integers(0, 255)),
                            st.tuples(st.just("garbage"), st.binary(max_size=30) | cobs_pieces, st.just(0))),
                  max_size=25)
# Damage applied to the whole stream: (kind, where, byte).
damage = st.lists(st.tuples(st.sampled_from(["flip", "insert", "drop"]), st.integers(0, 10_000),
                            st.integers(1, 255)), max_size=4)


def _stream(items: list, harm: list, skip: int) -> bytes:
    data = bytearray()
    for kind, value, seq in items:
        data += p.encode(value, seq) if kind == "frame" else value
    for kind, where, byte in harm:
        if not data:
            break
        i = where % len(data)
        if kind == "flip":
            data[i] ^= byte
        elif kind == "insert":
            data.insert(i, byte & 0xFF)
        else:
            del data[i]
    return bytes(data[skip % (len(data) + 1):] if skip else data)  # start mid-frame too


def _slices(data: bytes, cuts: list[int]) -> list[bytes]:
    points = sorted({c % (len(data) + 1) for c in cuts})
    bounds = [0, *points, len(data)]
    return [data[a:b] for a, b in zip(bounds, bounds[1:], strict=False)]


def _compare(c, slices: list[bytes], resets: set[int] = frozenset()) -> None:  # noqa: ANN001
    """Feed both decoders the same slices; the same packets per slice and the same counts after each."""
    c.reset()
    dec = p.Decoder()
    for i, chunk in enumerate(slices):
        if i in resets:
            dec.reset_sequence()
            assert c.ask("resetseq") == ["ok"]
        want = [python_fields(pkt) for pkt in dec.feed(chunk)]
        got, stats = c.feed(chunk)
        assert [{k: v for k, v in g.items() if k != "seq"} for g in got] == want, chunk.hex()
        assert stats == python_stats(dec), chunk.hex()


@settings(max_examples=300, suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])
@given(pieces, damage, st.integers(0, 40), st.lists(st.integers(0, 10_000), max_size=30),
       st.sets(st.integers(0, 30), max_size=2))
def test_c_and_python_decode_any_stream_alike(c_decoder, items, harm, skip, cuts, resets) -> None:  # noqa: ANN001
    _compare(c_decoder, _slices(_stream(items, harm, skip), cuts), resets)


@settings(max_examples=100, suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])
@given(st.lists(packets, min_size=1, max_size=20), st.sampled_from(["flip", "insert", "drop"]), st.integers(0, 10_000),
       st.integers(1, 255), st.lists(st.integers(0, 10_000), max_size=10))
def test_one_damaged_byte_costs_the_c_decoder_at_most_two_frames(  # noqa: ANN201
        c_decoder, sent, kind, where, byte, cuts):  # noqa: ANN001
    """The guarantee itself, on the C side alone: what comes out was sent, in order, and at most two frames are lost."""
    frames = [p.encode(pkt, i) for i, pkt in enumerate(sent)]
    data = _stream([("frame", pkt, i) for i, pkt in enumerate(sent)], [(kind, where, byte)], 0)
    assert data != b"".join(frames)
    c_decoder.reset()
    got = [g for chunk in _slices(data, cuts) for g in c_decoder.feed(chunk)[0]]
    want = [{"seq": i, **python_fields(pkt)} for i, pkt in enumerate(sent)]
    it = iter(want)
    assert all(any(g == w for w in it) for g in got), "a packet that was not sent, or out of order"
    assert len(got) >= len(sent) - 2


@settings(max_examples=100, suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])
@given(pieces, damage, st.integers(0, 40))
def test_byte_at_a_time_decodes_as_python_fed_one_byte_per_call(c_decoder, items, harm, skip) -> None:  # noqa: ANN001
    data = _stream(items, harm, skip)
    c_decoder.reset()
    dec = p.Decoder()
    want = [python_fields(pkt) for i in range(len(data)) for pkt in dec.feed(data[i : i + 1])]
    got, stats = c_decoder.feed(data, by_byte=True)
    assert [{k: v for k, v in g.items() if k != "seq"} for g in got] == want
    assert stats == python_stats(dec)


@settings(max_examples=200, suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])
@given(st.binary(max_size=400), st.lists(st.integers(0, 10_000), max_size=20))
def test_pure_garbage_is_safe_and_counted_alike(c_decoder, garbage, cuts) -> None:  # noqa: ANN001
    _compare(c_decoder, _slices(garbage, cuts))


@pytest.mark.parametrize("slices", [
    [b"\x01" * 100, b"\x01" * 5, b"\x00" + p.encode(p.Joystick(1, 2, 3, 4, 0))],  # an over-long run, then resync
    [b"\x01" * 25 + b"\x00", b"\x01" * 25 + b"\x00"],  # over-long runs inside one slice: malformed once joined
    [b"\x01" * 19, b"\x01\x00"],  # the same run across two slices: discarded, not malformed
    [p.encode(p.Heartbeat(1, 2))[5:] + p.encode(p.Heartbeat(1, 2))] * 2,  # joining mid-frame, then damage
    [p.encode(p.Heartbeat(0, 0), 250), p.encode(p.Heartbeat(0, 0), 3)],  # a sequence gap across the wrap
    [b"\x00" + b"".join(p.cobs_encode(b"\x11" * n) + b"\x00" for n in range(20))],  # valid COBS, every length
], ids=["overlong-resync", "overlong-in-slice", "overlong-across-slices", "joined-mid-frame", "seq-wrap",
        "short-pieces"])
def test_decoder_corner_cases_count_alike(c_decoder, slices: list[bytes]) -> None:  # noqa: ANN001
    _compare(c_decoder, slices)


# --- the Cortex-M0 build ------------------------------------------------------------------------------------


def test_cortex_m0_build_fits_the_budget() -> None:
    build()
    if shutil.which("arm-none-eabi-gcc") is None:
        pytest.skip(NO_ARM)
    from tests.support.m0_size import m0_sizes

    sizes = m0_sizes()
    assert sizes["board_flash_bytes"] <= 4096 and sizes["board_ram_bytes"] <= 256, sizes
