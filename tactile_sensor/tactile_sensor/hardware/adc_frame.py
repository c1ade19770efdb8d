"""The ADC serial frame (docs/serial-frame.md): encoding, strict decoding, stream parsing.

Layout, little-endian, ``11 + 2·n`` bytes for ``n`` channels::

    0  2   sync        0xA5 0x5A
    2  1   header      high nibble: protocol version (1); low nibble: channel count 1..8
    3  2   seq         uint16, +1 per frame, wraps at 2^16
    5  4   t_us        uint32 device clock [µs] since boot, wraps at 2^32
    9  2n  counts      uint16 raw ADC counts, channel 0 first
    .  2   crc         CRC-16/CCITT-FALSE (poly 0x1021, init 0xFFFF) over header..counts

The CRC is ``binascii.crc_hqx`` (C speed), so parsing costs a few microseconds per frame.
"""

from __future__ import annotations

import binascii
import struct
from typing import NamedTuple

from tactile_sensor.hardware.errors import FrameError

SYNC = b"\xa5\x5a"
PROTOCOL_VERSION = 1
MAX_CHANNELS = 8
HEADER_SIZE = 9  # sync + header byte + seq + t_us
CRC_SIZE = 2
CRC_INIT = 0xFFFF
SEQ_MODULO = 1 << 16
TIME_MODULO = 1 << 32

_HEAD = struct.Struct("<2sBHI")
_CRC = struct.Struct("<H")
_COUNTS = [struct.Struct(f"<{n}H") for n in range(MAX_CHANNELS + 1)]


class Frame(NamedTuple):
    """One decoded frame, fields exactly as on the wire (nothing unwrapped)."""

    seq: int
    t_us: int
    counts: tuple[int, ...]


def frame_size(channels: int) -> int:
    """Bytes in a frame carrying ``channels`` channels."""
    return HEADER_SIZE + 2 * channels + CRC_SIZE


def crc16(data: bytes | bytearray | memoryview) -> int:
    """CRC-16/CCITT-FALSE, the frame's checksum (check value 0x29B1 for b'123456789')."""
    return binascii.crc_hqx(data, CRC_INIT)


def encode_frame(seq: int, t_us: int, counts: tuple[int, ...] | list[int]) -> bytes:
    """Bytes of one frame; ``seq`` and ``t_us`` are wrapped to their field widths."""
    n = len(counts)
    if not 1 <= n <= MAX_CHANNELS:
        raise FrameError(
            f"A frame carries 1 to {MAX_CHANNELS} channels, not {n}; pass fewer counts."
        )
    if any(not 0 <= c <= 0xFFFF for c in counts):
        raise FrameError(
            f"ADC counts must fit in 16 bits (0..65535), got {list(counts)}; clip them first."
        )
    body = _HEAD.pack(SYNC, (PROTOCOL_VERSION << 4) | n, seq % SEQ_MODULO,
                      t_us % TIME_MODULO) + _COUNTS[n].pack(*counts)
    return body + _CRC.pack(crc16(body[2:]))


def decode_frame(data: bytes | bytearray) -> Frame:
    """Decode exactly one frame or raise ``FrameError`` saying what is wrong."""
    if len(data) < HEADER_SIZE + 2 + CRC_SIZE:
        raise FrameError(f"A frame is at least {frame_size(1)} bytes, got {len(data)}.")
    if data[:2] != SYNC:
        raise FrameError(f"A frame starts with sync bytes a5 5a, got {bytes(data[:2]).hex(' ')}.")
    version, n = data[2] >> 4, data[2] & 0x0F
    if version != PROTOCOL_VERSION or not 1 <= n <= MAX_CHANNELS:
        raise FrameError(
            f"Header byte 0x{data[2]:02x} is not protocol version {PROTOCOL_VERSION} with "
            f"1..{MAX_CHANNELS} channels; update the firmware or the driver to match."
        )
    size = frame_size(n)
    if len(data) != size:
        raise FrameError(f"A {n}-channel frame is {size} bytes, got {len(data)}.")
    (crc,) = _CRC.unpack_from(data, size - CRC_SIZE)
    if crc != crc16(data[2:size - CRC_SIZE]):
        raise FrameError("The frame's CRC does not match its content (corrupted in transit).")
    _, _, seq, t_us = _HEAD.unpack_from(data, 0)
    return Frame(seq, t_us, _COUNTS[n].unpack_from(data, HEADER_SIZE))


class ParserStats(NamedTuple):
    """Counters of what the parser accepted and threw away since it was made."""

    frames: int
    crc_errors: int
    header_errors: int
    resyncs: int
    bytes_discarded: int


class FrameParser:
    """Incremental frame finder: feed arbitrary chunks, get the valid frames back.

    After garbage it slides byte by byte to the next sync pattern whose header and CRC
    check out, so a corrupted or truncated frame costs only itself. ``channels`` (if
    given) rejects frames with another channel count, one more guard against garbage.
    """

    def __init__(self, channels: int | None = None) -> None:
        if channels is not None and not 1 <= channels <= MAX_CHANNELS:
            raise FrameError(f"channels must be 1..{MAX_CHANNELS} or None, got {channels}.")
        self._channels = channels
        self._buf = bytearray()
        self._in_sync = False
        self.frames = 0
        self.crc_errors = 0
        self.header_errors = 0
        self.resyncs = 0
        self.bytes_discarded = 0

    def stats(self) -> ParserStats:
        return ParserStats(self.frames, self.crc_errors, self.header_errors, self.resyncs,
                           self.bytes_discarded)

    def reset(self) -> None:
        """Forget partial data (after a reconnect the old tail is meaningless)."""
        self.bytes_discarded += len(self._buf)
        self._buf.clear()
        self._in_sync = False

    def _discard(self, n: int) -> None:
        if n <= 0:
            return
        self.bytes_discarded += n
        if self._in_sync:
            self.resyncs += 1
            self._in_sync = False

    def feed(self, data: bytes | bytearray) -> list[Frame]:
        """Append ``data`` and return every complete valid frame now available."""
        buf = self._buf
        buf += data
        out: list[Frame] = []
        end = len(buf)
        i = 0
        want = self._channels
        while True:
            j = buf.find(SYNC, i)
            if j < 0:
                keep = 1 if end > i and buf[end - 1] == SYNC[0] else 0
                self._discard(end - i - keep)
                i = end - keep
                break
            if j > i:
                self._discard(j - i)
            i = j
            if end - j < 3:
                break
            header = buf[j + 2]
            n = header & 0x0F
            if (header >> 4 != PROTOCOL_VERSION or not 1 <= n <= MAX_CHANNELS
                    or (want is not None and n != want)):
                self.header_errors += 1
                self._discard(1)
                i = j + 1
                continue
            size = HEADER_SIZE + 2 * n + CRC_SIZE
            if end - j < size:
                break
            crc_at = j + size - CRC_SIZE
            if buf[crc_at] | (buf[crc_at + 1] << 8) != binascii.crc_hqx(
                    buf[j + 2:crc_at], CRC_INIT):
                self.crc_errors += 1
                self._discard(1)
                i = j + 1
                continue
            _, _, seq, t_us = _HEAD.unpack_from(buf, j)
            out.append(Frame(seq, t_us, _COUNTS[n].unpack_from(buf, j + HEADER_SIZE)))
            self._in_sync = True
            i = j + size
        if i:
            del buf[:i]
        self.frames += len(out)
        return out
