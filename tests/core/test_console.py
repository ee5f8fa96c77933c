"""The console's core: text between frames kept by the terminal's decoder (frames after text not lost), Text
packets split and joined, lines with levels, the rate limit, and hostile text."""

from __future__ import annotations

from hypothesis import given, settings
from hypothesis import strategies as st

import term.core.protocol as p
from term.core.console import BOARD, UART, Console, ConsoleDropped, ConsoleLine, level_of
from term.core.link import LinkSession

FRAMES = [p.Heartbeat(i, 1000 * i) for i in range(1, 6)] + [p.Attitude(0, 1, -2, 3, 0, 0, 0)]
printable = st.text(st.characters(min_codepoint=0x20, max_codepoint=0x7E), min_size=1, max_size=60)


def test_text_before_a_frame_is_text_and_the_frame_is_kept() -> None:
    dec = p.Decoder(keep_text=True)
    hb = p.Heartbeat(7, 8)
    assert dec.feed(b"boot: imu ok\r\n" + p.encode(hb) + b"x=3 y=4\n" + p.encode(hb, 1)) == [hb, hb]
    assert dec.take_text() == b"boot: imu ok\r\nx=3 y=4\n"
    assert dec.stats.frames_bad == 0 and dec.stats.bytes_skipped == 0 and dec.stats.text_bytes == 22


def test_without_keep_text_the_same_bytes_are_skipped_as_the_c_decoder_does() -> None:
    dec = p.Decoder()
    hb = p.Heartbeat(7, 8)
    dec.feed(b"\x00boot: imu ok\r\n" + p.encode(hb))
    assert dec.take_text() == b"" and dec.stats.malformed == 1


def test_a_line_and_then_silence_comes_out_at_once() -> None:
    dec = p.Decoder(keep_text=True)
    dec.feed(p.encode(p.Heartbeat(1, 1)))
    dec.feed(b"ASSERT failed: qb_board.c:120\n")  # longer than a frame: its head at once, the rest at the newline
    assert dec.take_text() == b"ASSERT failed: qb_board.c:120\n"


def test_garbage_is_still_damage_not_text() -> None:
    dec = p.Decoder(keep_text=True)
    dec.feed(p.encode(p.Heartbeat(1, 1)) + b"\x01\x02\xff\xfe\x00")
    assert dec.take_text() == b"" and dec.stats.frames_bad == 1


@settings(max_examples=150, deadline=None)
@given(st.lists(st.tuples(st.sampled_from(FRAMES), st.lists(printable, max_size=2)), min_size=1, max_size=12),
       st.lists(st.integers(1, 40), max_size=30))
def test_text_and_frames_under_any_chunking(items, cuts) -> None:  # noqa: ANN001
    """Lines printed between frames (no delimiter of their own): every frame arrives, every line is kept."""
    enc = p.Encoder()
    stream, want_text, want = b"", b"", []
    for pkt, lines in items:
        text = "".join(line + "\n" for line in lines).encode()
        stream += text + enc.encode(pkt)
        want_text += text
        want.append(pkt)
    dec = p.Decoder(keep_text=True)
    got, pos = [], 0
    for c in cuts:
        got += dec.feed(stream[pos : pos + c])
        pos += c
    got += dec.feed(stream[pos:])
    assert got == want
    assert dec.take_text() == want_text
    assert dec.stats.frames_bad == 0 and dec.stats.seq_gaps == 0


@settings(max_examples=100, deadline=None)
@given(st.binary(max_size=300), st.lists(st.integers(1, 40), max_size=20))
def test_garbage_never_raises_and_gives_no_frame(garbage, cuts) -> None:  # noqa: ANN001
    dec = p.Decoder(keep_text=True)
    pos = 0
    out = []
    for c in cuts:
        out += dec.feed(garbage[pos : pos + c])
        pos += c
    out += dec.feed(garbage[pos:])
    assert out == [] or all(type(x) in p.SPEC_OF for x in out)
    assert set(dec.take_text()) <= set(b"\t\n\r" + bytes(range(0x20, 0x7F)))


@given(st.text(max_size=80), st.integers(1, 5))
def test_text_packets_join_to_the_line(line, level) -> None:  # noqa: ANN001
    line = line.replace("\n", " ")
    pkts = p.text_packets(line, level)
    assert all(len(p.encode(x)) <= p.MAX_FRAME for x in pkts)
    assert all(x.info & p.TEXT_MORE for x in pkts[:-1]) and not pkts[-1].info & p.TEXT_MORE
    assert b"".join(x.text.rstrip(b"\0") for x in pkts).decode() == line.replace("\0", " ")
    c = Console()
    out = [ln for x in pkts for ln in c.feed_packet(x, 0.0)]
    assert len(out) == 1 and out[0].level == level and out[0].source == BOARD


def test_a_nul_inside_a_line_is_a_space_not_a_cut() -> None:
    """Hypothesis found it: a NUL at a packet's end was taken for padding and the line came back short."""
    line = "00\x80\x80\x80\x80\x80\x800\x80\U00010000\x00\U00010000"
    pkts = p.text_packets(line, 1)
    assert b"".join(x.text.rstrip(b"\0") for x in pkts).decode() == line.replace("\0", " ")


def test_levels_from_words() -> None:
    assert level_of("ASSERT failed: x > 0") == p.LEVEL_ERROR
    assert level_of("HardFault at 0x1234") == p.LEVEL_ERROR
    assert level_of("E: i2c timeout") == p.LEVEL_ERROR
    assert level_of("warning: baro slow") == p.LEVEL_WARNING
    assert level_of("debug: ae=[1,2,3,4]") == p.LEVEL_DEBUG
    assert level_of("x=3 errno_count=0") == p.LEVEL_INFO  # a word inside a word is not one


def test_rate_limit_drops_and_counts_then_says_so() -> None:
    c = Console(rate=10, burst=5)
    out = c.feed_bytes(b"".join(b"line %d\n" % i for i in range(100)), now=0.0)
    assert [x.text for x in out if isinstance(x, ConsoleLine)] == [f"line {i}" for i in range(5)]
    assert c.dropped == 95
    assert out[-1] == ConsoleDropped(95, UART)  # said at once: the board may say nothing more for a long time
    later = c.feed_bytes(b"after\n", now=1.0)  # the bucket refilled
    assert later[0].text == "after" and later[0].dropped == 95 and later[0].source == UART
    assert len(later) == 1  # the drops were counted when they happened, not again


def test_dropped_text_packets_are_counted_as_they_are_dropped() -> None:
    c = Console(rate=1, burst=2)
    said = [ev for i in range(5) for ev in c.feed_packet(p.Text(p.LEVEL_INFO, b"t%d" % i), now=0.0)]
    assert [type(ev) for ev in said] == [ConsoleLine, ConsoleLine] + [ConsoleDropped] * 3
    assert sum(ev.count for ev in said if isinstance(ev, ConsoleDropped)) == c.dropped == 3


def test_hostile_text_cannot_drive_the_terminal_and_long_lines_are_cut() -> None:
    c = Console(max_line=20)
    out = c.feed_bytes(b"\x1b[2J\x1b]0;owned\x07" + b"A" * 100 + b"\nnext\n", now=0.0)
    assert "\x1b" not in out[0].text and "\x07" not in out[0].text
    assert out[0].cut and len(out[0].text) <= 20
    assert out[1].text == "next"
    bad = c.feed_packet(p.Text(p.LEVEL_INFO, b"\xff\xfe\x1b[31mred\x00"), 0.0)
    assert bad[0].text.endswith("[31mred") and "\x1b" not in bad[0].text


def test_the_link_gives_console_lines() -> None:
    s = LinkSession(0.0)
    enc = p.Encoder()
    data = b"hello\n" + enc.encode(p.Heartbeat(1, 1)) + enc.encode_many(p.text_packets("qb_log: ok", p.LEVEL_WARNING))
    lines = [e for e in s.receive(data, 0.1) if type(e).__name__ == "ConsoleLine"]
    assert [(x.text, x.source, x.level) for x in lines] == [("hello", UART, p.LEVEL_INFO),
                                                             ("qb_log: ok", BOARD, p.LEVEL_WARNING)]
    assert s.stats_at(0.1).frames_bad == 0
