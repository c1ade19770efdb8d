"""The ADC serial stream (docs/serial-frame.md): encoding, strict decoding, stream parsing.

Protocol version 2 (version 1 is still read). Little-endian. A **data frame** with ``n``
channels is ``11 + 2·n`` bytes::

    0  2   sync        0xA5 0x5A
    2  1   header      high nibble: protocol version (2, or 1); low nibble: channels 1..8
    3  2   seq         uint16, +1 per sampled frame, wraps at 2^16
    5  4   t_us        uint32 device clock [µs] since boot, wraps at 2^32
    9  2n  counts      uint16 raw ADC codes, channel 0 first
    .  2   crc         CRC-16/CCITT-FALSE (poly 0x1021, init 0xFFFF) over header..counts

A version-2 device also sends an **info frame** (header ``0x20``: channel count 0) at start
and every 0.25 s, saying what its codes mean, so firmware and host cannot disagree::

    0  2   sync        0xA5 0x5A
    2  1   header      0x20
    3  1   length L    payload bytes, 9..40
    4  1   adc_bits    resolution of the codes [bit], 1..16
    5  1   channels    channels in every data frame, 1..8
    6  2   vref_mv     uint16 ADC reference (full scale) [mV]
    8  4   period_us   uint32 nominal sample period [µs]
    12 1   name_len    bytes of the board name that follow (0..L-9)
    13 .   board       ASCII board family, e.g. "avr", "rp2040" (bytes after it: reserved)
    4+L 2  crc         CRC-16/CCITT-FALSE over header..payload

A modulated device (version 3: its emitters switched apart from the detectors' pull-ups)
sends each frame's codes twice, emitter on then emitter off (``11 + 4·n`` bytes; ``counts``
holds the ``2·n`` codes in that order, ``t_us`` is the on sample's), and its info frame
(header ``0x30``) appends after the board name::

    .  1   modulation  1: on/off pairs
    .  2   settle_us   uint16 time from an emitter switch to channel 0's sample [µs]
    .  2   read_us     uint16 time between consecutive channels' samples [µs]

Info frames are not numbered (``seq`` counts samples only). The CRC is
``binascii.crc_hqx`` (C speed), so parsing costs a few microseconds per frame. A chunk
that holds a long run of data frames of one kind (a port read after the consumer was
busy, a high rate) is checked and decoded as one numpy array: ``RUN_MIN_FRAMES`` frames
or more, where the array's fixed cost is repaid (about 0.5 us per frame against 4 us).
"""

from __future__ import annotations

import binascii
import struct
from itertools import repeat
from typing import NamedTuple

import numpy as np

from tactile_sensor.hardware.errors import FrameError

SYNC = b"\xa5\x5a"
PROTOCOL_VERSION = 2
MODULATED_VERSION = 3  # on/off pairs from a modulated module
SUPPORTED_VERSIONS = (1, 2, 3)
MAX_CHANNELS = 8
HEADER_SIZE = 9  # sync + header byte + seq + t_us
CRC_SIZE = 2
CRC_INIT = 0xFFFF
SEQ_MODULO = 1 << 16
TIME_MODULO = 1 << 32
INFO_HEADER = PROTOCOL_VERSION << 4  # channel count 0 marks an info frame
MODULATED_INFO_HEADER = MODULATED_VERSION << 4
INFO_HEADERS = (INFO_HEADER, MODULATED_INFO_HEADER)
INFO_FIXED_SIZE = 9  # adc_bits, channels, vref_mv, period_us, name_len
MODULATION_SIZE = 5  # version 3 after the name: modulation, settle_us, read_us
INFO_MAX_PAYLOAD = 40
MAX_ADC_BITS = 16

_HEAD = struct.Struct("<2sBHI")
_CRC = struct.Struct("<H")
_COUNTS = [struct.Struct(f"<{n}H") for n in range(2 * MAX_CHANNELS + 1)]
_INFO = struct.Struct("<BBHIB")
_MODULATION = struct.Struct("<BHH")
_VERSIONS = frozenset(SUPPORTED_VERSIONS)
RUN_MIN_FRAMES = 32  # a run of data frames this long is decoded as one array


def _crc_table() -> np.ndarray:
    """CRC-16/CCITT-FALSE of every byte value, for the table-driven vectorised CRC."""
    table = np.zeros(256, dtype=np.uint16)
    for b in range(256):
        crc = b << 8
        for _ in range(8):
            crc = ((crc << 1) ^ 0x1021) if crc & 0x8000 else crc << 1
        table[b] = crc & 0xFFFF
    return table


_CRC_TABLE = _crc_table()
_RUN_DTYPES = [None] + [np.dtype([("sync", "<u2"), ("header", "u1"), ("seq", "<u2"),
                                  ("t_us", "<u4"), ("counts", "<u2", (n,)), ("crc", "<u2")])
                        for n in range(1, 2 * MAX_CHANNELS + 1)]


def _decode_run(buf: bytearray, start: int, header: int, count: int) -> list[Frame]:
    """The leading valid frames of ``count`` data frames with ``header`` from ``start``:
    decoding stops before the first whose sync, header or CRC is wrong (the caller's
    byte-wise search takes over there)."""
    dtype = _RUN_DTYPES[codes_per_frame(header)]
    frames = np.frombuffer(buf, dtype=dtype, count=count, offset=start)
    raw = np.frombuffer(buf, dtype=np.uint8, count=count * dtype.itemsize,
                        offset=start).reshape(count, dtype.itemsize)
    good = (frames["sync"] == 0x5AA5) & (frames["header"] == header)
    crc = np.full(count, CRC_INIT, dtype=np.uint16)
    for column in raw[:, 2:dtype.itemsize - CRC_SIZE].T:
        crc = (crc << 8) ^ _CRC_TABLE[(crc >> 8) ^ column]
    good &= crc == frames["crc"]
    valid = count if good.all() else int(np.argmin(good))
    run = frames[:valid]
    out = list(map(Frame, run["seq"].tolist(), run["t_us"].tolist(),
                   map(tuple, run["counts"].tolist()), repeat(header >> 4)))
    del frames, raw, run  # release the views: the caller resizes ``buf``
    return out


class Frame(NamedTuple):
    """One decoded data frame, fields exactly as on the wire (nothing unwrapped)."""

    seq: int
    t_us: int
    counts: tuple[int, ...]
    version: int = PROTOCOL_VERSION


class DeviceInfo(NamedTuple):
    """What the device says about its codes. A version-2 device states everything in its
    info frame; for a version-1 stream only ``version`` and ``channels`` are known (from
    the data frames' header) and the rest is None."""

    version: int
    channels: int
    adc_bits: int | None = None
    vref_v: float | None = None
    period_us: int | None = None
    board: str = ""
    modulated: bool = False  # version 3: every frame holds emitter-on then emitter-off codes
    settle_us: int | None = None  # from an emitter switch to channel 0's sample
    read_us: int | None = None  # between consecutive channels' samples

    @property
    def codes(self) -> int:
        """Codes in every data frame: one per channel, or an on/off pair per channel."""
        return 2 * self.channels if self.modulated else self.channels

    @property
    def described(self) -> bool:
        """True when the device stated its resolution and reference (version 2)."""
        return self.adc_bits is not None and self.vref_v is not None

    @property
    def rate_hz(self) -> float | None:
        return 1e6 / self.period_us if self.period_us else None

    def summary(self) -> str:
        """One line for logs and diagnostics."""
        if not self.described:
            return (f"protocol {self.version}, {self.channels} channel(s), resolution and "
                    "reference not stated")
        rate = f"{self.rate_hz:g} Hz" if self.rate_hz else "rate not stated"
        modulated = (f", modulated (emitter on/off, settle {self.settle_us} us)"
                     if self.modulated else "")
        return (f"protocol {self.version}, {self.board or 'unnamed board'}, {self.adc_bits} "
                f"bit, {self.vref_v:g} V, {self.channels} channel(s), {rate}{modulated}")


def frame_size(channels: int, version: int = PROTOCOL_VERSION) -> int:
    """Bytes in a data frame carrying ``channels`` channels."""
    codes = 2 * channels if version == MODULATED_VERSION else channels
    return HEADER_SIZE + 2 * codes + CRC_SIZE


def codes_per_frame(header: int) -> int:
    """Codes a data frame with this header byte carries (an on/off pair per channel in
    version 3)."""
    n = header & 0x0F
    return 2 * n if header >> 4 == MODULATED_VERSION else n


def crc16(data: bytes | bytearray | memoryview) -> int:
    """CRC-16/CCITT-FALSE, the frame's checksum (check value 0x29B1 for b'123456789')."""
    return binascii.crc_hqx(data, CRC_INIT)


def encode_frame(seq: int, t_us: int, counts: tuple[int, ...] | list[int],
                 version: int = PROTOCOL_VERSION) -> bytes:
    """Bytes of one data frame; ``seq`` and ``t_us`` are wrapped to their field widths. A
    version-3 frame's ``counts`` are the on codes of every channel, then the off codes."""
    n = len(counts)
    if version == MODULATED_VERSION:
        if n % 2:
            raise FrameError(f"A modulated frame carries an on and an off code per channel, "
                             f"got {n} codes; pass the on codes, then the off codes.")
        n //= 2
    if not 1 <= n <= MAX_CHANNELS:
        raise FrameError(
            f"A frame carries 1 to {MAX_CHANNELS} channels, not {n}; pass fewer counts."
        )
    if any(not 0 <= c <= 0xFFFF for c in counts):
        raise FrameError(
            f"ADC counts must fit in 16 bits (0..65535), got {list(counts)}; clip them first."
        )
    if version not in SUPPORTED_VERSIONS:
        raise FrameError(f"Protocol version must be one of {SUPPORTED_VERSIONS}, got {version!r}.")
    body = _HEAD.pack(SYNC, (version << 4) | n, seq % SEQ_MODULO,
                      t_us % TIME_MODULO) + _COUNTS[len(counts)].pack(*counts)
    return body + _CRC.pack(crc16(body[2:]))


def info_problem(adc_bits: int, channels: int, vref_mv: int, period_us: int) -> str | None:
    """Why these info fields cannot describe a stream, or None if they can."""
    if not 1 <= adc_bits <= MAX_ADC_BITS:
        return f"adc_bits {adc_bits} is not 1..{MAX_ADC_BITS}"
    if not 1 <= channels <= MAX_CHANNELS:
        return f"channels {channels} is not 1..{MAX_CHANNELS}"
    if vref_mv == 0:
        return "vref_mv is 0"
    if period_us == 0:
        return "period_us is 0"
    return None


def encode_info(adc_bits: int, channels: int, vref_v: float, period_us: int,
                board: str = "", modulation: tuple[int, int] | None = None) -> bytes:
    """Bytes of one info frame: version 2, or version 3 (a modulated device) when
    ``modulation`` gives its (settle_us, read_us)."""
    vref_mv = round(vref_v * 1000)
    name = board.encode("ascii", "replace")
    if not 0 <= vref_mv <= 0xFFFF or not 0 <= period_us < TIME_MODULO:
        raise FrameError(f"vref_v {vref_v!r} V must be 0.001..65.535 and period_us "
                         f"{period_us!r} must fit in 32 bits.")
    problem = info_problem(adc_bits, channels, vref_mv, period_us)
    if problem:
        raise FrameError(f"Cannot encode the device info: {problem}.")
    extra = b""
    if modulation is not None:
        settle_us, read_us = modulation
        if not (0 <= settle_us <= 0xFFFF and 0 <= read_us <= 0xFFFF):
            raise FrameError(f"settle_us {settle_us!r} and read_us {read_us!r} must fit in "
                             "16 bits.")
        extra = _MODULATION.pack(1, settle_us, read_us)
    room = INFO_MAX_PAYLOAD - INFO_FIXED_SIZE - len(extra)
    if len(name) > room:
        raise FrameError(f"A board name has at most {room} ASCII characters, got {board!r}.")
    payload = _INFO.pack(adc_bits, channels, vref_mv, period_us, len(name)) + name + extra
    header = INFO_HEADER if modulation is None else MODULATED_INFO_HEADER
    body = SYNC + bytes([header, len(payload)]) + payload
    return body + _CRC.pack(crc16(body[2:]))


def _parse_info(payload: bytes | bytearray | memoryview,
                version: int = PROTOCOL_VERSION) -> DeviceInfo | str:
    """The info frame's payload as DeviceInfo, or the reason it is unusable."""
    adc_bits, channels, vref_mv, period_us, name_len = _INFO.unpack_from(payload, 0)
    problem = info_problem(adc_bits, channels, vref_mv, period_us)
    end = INFO_FIXED_SIZE + name_len
    if problem is None and end > len(payload):
        problem = f"board name of {name_len} bytes overruns the {len(payload)}-byte payload"
    if problem is None and version == MODULATED_VERSION:
        if end + MODULATION_SIZE > len(payload):
            problem = "a version-3 info frame lacks its modulation fields after the name"
        elif payload[end] != 1:
            problem = f"modulation {payload[end]} is not 1 (on/off pairs)"
    if problem:
        return problem
    board = bytes(payload[INFO_FIXED_SIZE:end]).decode("ascii", "replace")
    if version == MODULATED_VERSION:
        _, settle_us, read_us = _MODULATION.unpack_from(payload, end)
        return DeviceInfo(version, channels, adc_bits, vref_mv / 1000.0, period_us, board,
                          True, settle_us, read_us)
    return DeviceInfo(PROTOCOL_VERSION, channels, adc_bits, vref_mv / 1000.0, period_us, board)


def decode_frame(data: bytes | bytearray) -> Frame | DeviceInfo:
    """Decode exactly one data or info frame or raise ``FrameError`` saying what is wrong."""
    if len(data) < frame_size(1):
        raise FrameError(f"A frame is at least {frame_size(1)} bytes, got {len(data)}.")
    if data[:2] != SYNC:
        raise FrameError(f"A frame starts with sync bytes a5 5a, got {bytes(data[:2]).hex(' ')}.")
    version, n = data[2] >> 4, data[2] & 0x0F
    if data[2] in INFO_HEADERS:
        length = data[3]
        if not INFO_FIXED_SIZE <= length <= INFO_MAX_PAYLOAD:
            raise FrameError(f"An info frame's payload is {INFO_FIXED_SIZE}..{INFO_MAX_PAYLOAD} "
                             f"bytes, its length byte says {length}.")
        size = 4 + length + CRC_SIZE
    elif version in SUPPORTED_VERSIONS and 1 <= n <= MAX_CHANNELS:
        size = frame_size(n, version)
    else:
        raise FrameError(
            f"Header byte 0x{data[2]:02x} is not protocol version {SUPPORTED_VERSIONS} with "
            f"1..{MAX_CHANNELS} channels (or 0x20/0x30, an info frame); update the "
            "firmware or the driver to match."
        )
    if len(data) != size:
        raise FrameError(f"This frame is {size} bytes, got {len(data)}.")
    (crc,) = _CRC.unpack_from(data, size - CRC_SIZE)
    if crc != crc16(data[2:size - CRC_SIZE]):
        raise FrameError("The frame's CRC does not match its content (corrupted in transit).")
    if data[2] in INFO_HEADERS:
        info = _parse_info(data[4:size - CRC_SIZE], version)
        if isinstance(info, str):
            raise FrameError(f"The device's info frame is unusable: {info}; fix the firmware.")
        return info
    _, _, seq, t_us = _HEAD.unpack_from(data, 0)
    return Frame(seq, t_us, _COUNTS[codes_per_frame(data[2])].unpack_from(data, HEADER_SIZE),
                 version)


class ParserStats(NamedTuple):
    """Counters of what the parser accepted and threw away since it was made."""

    frames: int
    crc_errors: int
    header_errors: int
    resyncs: int
    bytes_discarded: int
    info_frames: int = 0
    info_errors: int = 0  # info frames with a valid CRC but impossible content
    last_info_error: str = ""



def _frame_size(buf: bytearray, j: int, end: int, want: int | None) -> int | None:
    """Bytes of the frame whose sync is at ``j``: 0 when its header is not one this host
    reads (or not the channel count it expects), None when the bytes that tell are not
    here yet."""
    header = buf[j + 2]
    n = header & 0x0F
    if n and n <= MAX_CHANNELS and (header >> 4) in _VERSIONS and (want is None or n == want):
        # a data frame (the common case); version 3 holds on/off pairs
        return HEADER_SIZE + (4 * n if header >> 4 == MODULATED_VERSION else 2 * n) + CRC_SIZE
    if header in INFO_HEADERS:
        if end - j < 4:
            return None
        length = buf[j + 3]
        return 4 + length + CRC_SIZE if INFO_FIXED_SIZE <= length <= INFO_MAX_PAYLOAD else 0
    return 0

class FrameParser:
    """Incremental frame finder: feed arbitrary chunks, get the valid frames back.

    ``feed`` returns data frames (``Frame``) and info frames (``DeviceInfo``) in stream
    order. After garbage it slides byte by byte to the next sync pattern whose header and
    CRC check out, so a corrupted or truncated frame costs only itself. ``channels`` (if
    given) rejects data frames with another channel count, one more guard against garbage.
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
        self.info_frames = 0
        self.info_errors = 0
        self.last_info_error = ""

    def stats(self) -> ParserStats:
        return ParserStats(self.frames, self.crc_errors, self.header_errors, self.resyncs,
                           self.bytes_discarded, self.info_frames, self.info_errors,
                           self.last_info_error)

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

    def feed(self, data: bytes | bytearray) -> list[Frame | DeviceInfo]:
        """Append ``data`` and return every complete valid frame now available."""
        buf = self._buf
        buf += data
        out: list[Frame | DeviceInfo] = []
        end = len(buf)
        i = 0
        frames = 0
        want = self._channels
        run_from = 0  # where a run of frames may be decoded as one array again
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
            size = _frame_size(buf, j, end, want)
            if size is None:
                break
            if not size:
                self.header_errors += 1
                self._discard(1)
                i = j + 1
                continue
            if end - j < size:
                break
            if header not in INFO_HEADERS and j >= run_from and end - j >= RUN_MIN_FRAMES * size:
                count = (end - j) // size
                run = _decode_run(buf, j, header, count)
                if len(run) < count:  # broken off: not again for a run's length
                    run_from = j + (len(run) + RUN_MIN_FRAMES) * size
                if run:
                    out += run
                    frames += len(run)
                    self._in_sync = True
                    i = j + len(run) * size
                    continue
            crc_at = j + size - CRC_SIZE
            if buf[crc_at] | (buf[crc_at + 1] << 8) != binascii.crc_hqx(
                    buf[j + 2:crc_at], CRC_INIT):
                self.crc_errors += 1
                self._discard(1)
                i = j + 1
                continue
            if header in INFO_HEADERS:
                info = _parse_info(buf[j + 4:crc_at], header >> 4)
                if isinstance(info, str):
                    self.info_errors += 1
                    self.last_info_error = info
                else:
                    self.info_frames += 1
                    out.append(info)
            else:
                _, _, seq, t_us = _HEAD.unpack_from(buf, j)
                out.append(Frame(seq, t_us, _COUNTS[codes_per_frame(header)].unpack_from(
                    buf, j + HEADER_SIZE), header >> 4))
                frames += 1
            self._in_sync = True
            i = j + size
        if i:
            del buf[:i]
        self.frames += frames
        return out
