from __future__ import annotations

import random

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tactile_sensor.hardware.adc_frame import (
    Frame,
    FrameParser,
    crc16,
    decode_frame,
    encode_frame,
    frame_size,
)
from tactile_sensor.hardware.errors import FrameError

counts_st = st.lists(st.integers(0, 0xFFFF), min_size=1, max_size=8).map(tuple)
frame_st = st.builds(Frame, st.integers(0, 0xFFFF), st.integers(0, 0xFFFFFFFF), counts_st)


def test_crc_is_ccitt_false():
    assert crc16(b"123456789") == 0x29B1


def test_layout_matches_the_document():
    data = encode_frame(0x0102, 0x03040506, [0x0A0B])
    assert data[:9] == bytes([0xA5, 0x5A, 0x11, 0x02, 0x01, 0x06, 0x05, 0x04, 0x03])
    assert data[9:11] == bytes([0x0B, 0x0A])
    assert int.from_bytes(data[11:13], "little") == crc16(data[2:11])
    assert len(data) == frame_size(1) == 13


@given(frame_st)
def test_round_trip(frame):
    assert decode_frame(encode_frame(*frame)) == frame


def test_encode_wraps_sequence_and_time():
    assert decode_frame(encode_frame(65537, (1 << 32) + 5, [1])) == Frame(1, 5, (1,))


@pytest.mark.parametrize(("counts", "match"), [([], "1 to 8"), ([0] * 9, "1 to 8"),
                                               ([70000], "16 bits"), ([-1], "16 bits")])
def test_encode_refuses_bad_counts(counts, match):
    with pytest.raises(FrameError, match=match):
        encode_frame(0, 0, counts)


def _corrupt(data: bytes, index: int, value: int) -> bytes:
    out = bytearray(data)
    out[index] = value
    return bytes(out)


GOOD = encode_frame(7, 1234, [100, 200])


@pytest.mark.parametrize(("data", "match"), [
    (GOOD[:10], "at least"),
    (_corrupt(GOOD, 0, 0x00), "sync"),
    (_corrupt(GOOD, 2, 0x22), "version"),
    (_corrupt(GOOD, 2, 0x10), "channels"),
    (GOOD + b"\x00", "bytes, got"),
    (_corrupt(GOOD, 10, GOOD[10] ^ 0x01), "CRC"),
])
def test_decode_says_what_is_wrong(data, match):
    with pytest.raises(FrameError, match=match):
        decode_frame(data)


@given(st.lists(frame_st, min_size=1, max_size=30), st.integers(1, 40))
def test_parser_is_chunking_invariant(frames, chunk):
    stream = b"".join(encode_frame(*f) for f in frames)
    parser = FrameParser()
    got = []
    for i in range(0, len(stream), chunk):
        got += parser.feed(stream[i:i + chunk])
    assert got == frames
    assert parser.stats().bytes_discarded == 0


@settings(max_examples=200)
@given(st.lists(st.tuples(frame_st, st.binary(max_size=40)), min_size=1, max_size=30))
def test_parser_only_accepts_frames_that_were_sent(items):
    stream = b"".join(encode_frame(*f) + junk for f, junk in items)
    sent = [f for f, _ in items]
    got = FrameParser().feed(stream)
    # every accepted frame is one that was sent, in order
    it = iter(sent)
    assert all(any(g == s for s in it) for g in got)
    # a frame followed by garbage is still found (garbage only costs what it overlaps)
    assert got[0] == sent[0]


def test_hundred_thousand_random_bytes_yield_no_bad_frame():
    rng = random.Random(1234)
    frames = [Frame(k & 0xFFFF, k * 1000, (k % 4096,)) for k in range(3000)]
    pieces = []
    garbage_left = 100_000
    for f in frames:
        pieces.append(encode_frame(*f))
        n = min(garbage_left, rng.randint(0, 70))
        pieces.append(rng.randbytes(n))
        garbage_left -= n
    pieces.append(rng.randbytes(garbage_left))
    stream = b"".join(pieces)
    parser = FrameParser(channels=1)
    got = []
    for i in range(0, len(stream), 997):
        got += parser.feed(stream[i:i + 997])
    sent = set(frames)
    assert all(g in sent for g in got)
    # garbage between frames costs no frame, and exactly the garbage is thrown away
    assert got == frames
    stats = parser.stats()
    assert stats.resyncs > 0
    assert stats.bytes_discarded == 100_000


def test_parser_drops_a_truncated_frame_and_recovers():
    a, b, c = (encode_frame(k, k, [k]) for k in range(3))
    parser = FrameParser()
    got = parser.feed(a + b[:7] + c)
    assert [f.seq for f in got] == [0, 2]
    assert parser.crc_errors + parser.header_errors >= 1
    assert parser.resyncs == 1


def test_parser_channel_guard():
    parser = FrameParser(channels=2)
    assert parser.feed(encode_frame(0, 0, [1])) == []
    assert parser.feed(encode_frame(1, 0, [1, 2])) == [Frame(1, 0, (1, 2))]
    with pytest.raises(FrameError, match="channels"):
        FrameParser(channels=9)


def test_parser_keeps_a_split_sync_byte():
    data = encode_frame(5, 6, [7])
    parser = FrameParser()
    assert parser.feed(b"\x00\x01" + data[:1]) == []
    assert parser.feed(data[1:]) == [Frame(5, 6, (7,))]
