"""Codec throughput and resilience on a realistic traffic mix. Prints one JSON line.

The mix is one simulated minute of both directions of a link: joystick at 100 Hz, heartbeats and their ACKs at
10 Hz, the five telemetry packets at their rates, a few commands, and a log download streaming chunks; it is
cut into serial-sized reads (1 to 64 bytes, as pyserial's `read(in_waiting)` returns them) and decoded.
`frames_lost_per_corrupted_byte` flips single bytes far apart in the stream and counts the frames lost.

Run: `python -m bench.codec [--seconds S]`.
"""

from __future__ import annotations

import argparse
import json
import platform
import random
import time

from term.core import protocol as p

# (packet factory, rate in Hz) per second of traffic; the log download uses what the 115200-baud line has left.
_RATES = [
    (lambda i: p.Joystick(i % 2000 - 1000, -i % 700, 0, 12000 + i % 50, 0), 100),
    (lambda i: p.Heartbeat(i & 0xFFFF, i * 100), 10),
    (lambda i: p.HeartbeatAck(i & 0xFFFF, i * 100), 10),
    (lambda i: p.Attitude(5, i % 400 - 200, -i % 300, i % 36000 - 18000, i % 50, -i % 40, 3), 50),
    (lambda i: p.Motion(i % 30, -i % 20, -16384 + i % 100, 400 + i % 9, 398, 402, 400 - i % 7), 50),
    (lambda i: p.Height(101325 - i % 20, 1500 + i % 30, 1500, i % 40 - 20, 1160, 2150), 20),
    (lambda i: p.Status(3, 0, 0, 0, i % 5, 80, 10, 0), 5),
    (lambda i: p.Gains(-800.0, 0.5, 111.0, 2.5, 1.0), 5),
    (lambda i: p.Command(i & 0xFF, p.Op.TRIM_LIFT, 1), 2),
    (lambda i: p.Ack(i & 0xFF, p.Op.TRIM_LIFT, 0, i), 2),
    (lambda i: p.LogChunk(i & 0xFFFF, bytes((i + k) & 0xFF for k in range(12))), 400),
]


def traffic(seconds: int) -> list:
    """Packets in time order for `seconds` of link traffic."""
    timed = []
    for factory, rate in _RATES:
        for i in range(seconds * rate):
            timed.append((i / rate, factory(i)))
    timed.sort(key=lambda tp: tp[0])
    return [pkt for _, pkt in timed]


def serial_reads(stream: bytes, rng: random.Random) -> list[bytes]:
    chunks, i = [], 0
    while i < len(stream):
        n = rng.randint(1, 64)
        chunks.append(stream[i : i + n])
        i += n
    return chunks


def measure(seconds: int = 60, repeats: int = 5, seed: int = 1) -> dict:
    rng = random.Random(seed)
    pkts = traffic(seconds)

    encode_times = []
    for _ in range(repeats):
        enc = p.Encoder()
        t0 = time.perf_counter()
        frames = [enc.encode(pkt) for pkt in pkts]
        encode_times.append(time.perf_counter() - t0)
    stream = b"".join(frames)
    chunks = serial_reads(stream, rng)

    decode_times = []
    for _ in range(repeats):
        dec = p.Decoder()
        t0 = time.perf_counter()
        n = 0
        for chunk in chunks:
            n += len(dec.feed(chunk))
        decode_times.append(time.perf_counter() - t0)
        assert n == len(pkts) and dec.stats.frames_bad == 0

    # The terminal's decoder keeps text between frames (keep_text): on the same clean stream, and on one where the
    # board prints a line before every tenth frame (printf on the UART, no delimiter of its own).
    text_fps = _text_decode_fps(chunks, len(pkts), repeats)
    printed = b"".join((b"dbg: ae=[401,398,402,400] t=%d\n" % i if i % 10 == 0 else b"") + f
                       for i, f in enumerate(frames))
    printf_fps, printf_lost = _printf_decode(serial_reads(printed, rng), len(pkts), repeats)

    # Resilience: flip bytes at least 64 bytes apart, so each corruption is a separate event.
    corrupted = bytearray(stream)
    positions = range(rng.randrange(64), len(corrupted), 997)
    for pos in positions:
        corrupted[pos] ^= rng.randint(1, 255)
    dec = p.Decoder()
    got = sum(len(dec.feed(c)) for c in serial_reads(bytes(corrupted), rng))
    lost_per_byte = (len(pkts) - got) / len(positions)

    best_enc, best_dec = min(encode_times), min(decode_times)
    decode_fps = len(pkts) / best_dec
    return {
        "benchmark": "codec",
        "frames": len(pkts),
        "bytes": len(stream),
        "mean_frame_bytes": round(len(stream) / len(pkts), 2),
        "encode_frames_per_s": round(len(pkts) / best_enc),
        "decode_frames_per_s": round(decode_fps),
        "decode_bytes_per_s": round(len(stream) / best_dec),
        "frames_lost_per_corrupted_byte": round(lost_per_byte, 3),
        "corrupted_bytes": len(positions),
        "uart_1000_fps_core_pct": round(100 * 1000 / decode_fps, 3),
        "decode_keep_text_frames_per_s": round(text_fps),
        "decode_with_printf_frames_per_s": round(printf_fps),
        "printf_frames_lost": printf_lost,
        "python": platform.python_version(),
        "machine": platform.machine(),
    }


def _text_decode_fps(chunks: list[bytes], n_pkts: int, repeats: int) -> float:
    best = float("inf")
    for _ in range(repeats):
        dec = p.Decoder(keep_text=True)
        t0 = time.perf_counter()
        n = sum(len(dec.feed(c)) for c in chunks)
        best = min(best, time.perf_counter() - t0)
        assert n == n_pkts
    return n_pkts / best


def _printf_decode(chunks: list[bytes], n_pkts: int, repeats: int) -> tuple[float, int]:
    """Frames per second and frames lost decoding a stream with a printed line before every tenth frame."""
    best, n = float("inf"), 0
    for _ in range(repeats):
        dec = p.Decoder(keep_text=True)
        t0 = time.perf_counter()
        n = 0
        for c in chunks:
            n += len(dec.feed(c))
            dec.take_text()
        best = min(best, time.perf_counter() - t0)
    return n_pkts / best, n_pkts - n


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=int, default=60, help="simulated seconds of traffic (default 60)")
    args = parser.parse_args()
    print(json.dumps(measure(args.seconds)))


if __name__ == "__main__":
    main()
