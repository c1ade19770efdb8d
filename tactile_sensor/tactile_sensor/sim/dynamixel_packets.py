"""Dynamixel Protocol 2.0 framing as pure functions: CRC-16, byte stuffing, build and parse.

Shared by the servo emulator and by tests that talk to it byte by byte. The packet layout is
``FF FF FD 00 | ID | LEN_L LEN_H | INST | [ERR] PARAMS... | CRC_L CRC_H`` where LEN counts
everything after itself (instruction, error, stuffed parameters, CRC) and the CRC covers every
byte before it, after stuffing. Stuffing inserts ``FD`` after any ``FF FF FD`` inside the
instruction/parameter field so the header never appears inside a packet.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import IntEnum

HEADER = b"\xff\xff\xfd\x00"
BROADCAST_ID = 0xFE
MAX_ID = 0xFC
#: Longest packet the parser accepts (LEN field); a real servo's buffer is of this order.
MAX_LENGTH = 1024
ALERT_BIT = 0x80


class Instruction(IntEnum):
    """Instruction codes of Protocol 2.0."""

    PING = 0x01
    READ = 0x02
    WRITE = 0x03
    REG_WRITE = 0x04
    ACTION = 0x05
    FACTORY_RESET = 0x06
    REBOOT = 0x08
    CLEAR = 0x10
    STATUS = 0x55
    SYNC_READ = 0x82
    SYNC_WRITE = 0x83
    FAST_SYNC_READ = 0x8A
    BULK_READ = 0x92
    BULK_WRITE = 0x93
    FAST_BULK_READ = 0x9A


class StatusError(IntEnum):
    """Low seven bits of a status packet's error byte (bit 7 is the hardware Alert)."""

    NONE = 0x00
    RESULT_FAIL = 0x01
    INSTRUCTION = 0x02
    CRC = 0x03
    DATA_RANGE = 0x04
    DATA_LENGTH = 0x05
    DATA_LIMIT = 0x06
    ACCESS = 0x07


def _make_crc_table() -> tuple[int, ...]:
    """CRC-16/BUYPASS (polynomial 0x8005, not reflected, initial value 0)."""
    table = []
    for i in range(256):
        crc = i << 8
        for _ in range(8):
            crc = ((crc << 1) ^ 0x8005) if crc & 0x8000 else (crc << 1)
        table.append(crc & 0xFFFF)
    return tuple(table)


_CRC_TABLE = _make_crc_table()


def crc16(data: bytes | bytearray, crc: int = 0) -> int:
    """Protocol 2.0 CRC of ``data`` (continuing from ``crc``)."""
    for byte in data:
        crc = ((crc << 8) ^ _CRC_TABLE[((crc >> 8) ^ byte) & 0xFF]) & 0xFFFF
    return crc


def stuff(body: bytes) -> bytes:
    """Insert ``FD`` after every ``FF FF FD`` in the instruction/parameter field."""
    out = bytearray()
    for byte in body:
        out.append(byte)
        if byte == 0xFD and len(out) >= 3 and out[-3] == 0xFF and out[-2] == 0xFF:
            out.append(0xFD)
    return bytes(out)


def unstuff(body: bytes) -> bytes:
    """Remove the ``FD`` that :func:`stuff` inserted after ``FF FF FD``."""
    out = bytearray()
    i = 0
    while i < len(body):
        out.append(body[i])
        if (body[i] == 0xFD and len(out) >= 3 and out[-3] == 0xFF and out[-2] == 0xFF
                and i + 1 < len(body) and body[i + 1] == 0xFD):
            i += 1  # skip the stuffed byte
        i += 1
    return bytes(out)


def _frame(servo_id: int, body: bytes) -> bytes:
    if not 0 <= servo_id <= 0xFF:
        raise ValueError(f"servo id {servo_id} is outside 0..255")
    stuffed = stuff(body)
    length = len(stuffed) + 2
    if length > MAX_LENGTH:
        raise ValueError(f"packet length {length} exceeds {MAX_LENGTH}")
    head = HEADER + bytes([servo_id, length & 0xFF, length >> 8])
    crc = crc16(head + stuffed)
    return head + stuffed + bytes([crc & 0xFF, crc >> 8])


def build_instruction(servo_id: int, instruction: int, params: bytes = b"") -> bytes:
    """A complete instruction packet, stuffed and with its CRC."""
    return _frame(servo_id, bytes([instruction]) + bytes(params))


def build_status(servo_id: int, error: int, params: bytes = b"") -> bytes:
    """A complete status packet (instruction 0x55) carrying ``error`` and ``params``."""
    return _frame(servo_id, bytes([Instruction.STATUS, error & 0xFF]) + bytes(params))


@dataclass(frozen=True)
class Packet:
    """One framed packet with a valid CRC; ``params`` are unstuffed.

    For a status packet ``error`` is the error byte and ``params`` follow it; for an
    instruction packet ``error`` is None.
    """

    servo_id: int
    instruction: int
    params: bytes
    error: int | None
    wire_length: int


@dataclass(frozen=True)
class BadCrc:
    """A complete frame whose CRC did not match; what a servo answers with a CRC error."""

    servo_id: int
    instruction: int
    wire_length: int


class PacketParser:
    """Incremental parser: feed bytes as they arrive, get whole packets back.

    Garbage before a header is skipped; a frame with an impossible length is dropped one
    byte at a time so the parser resynchronises on the next real header.
    """

    def __init__(self, max_length: int = MAX_LENGTH) -> None:
        self._buffer = bytearray()
        self._max_length = max_length

    @property
    def pending(self) -> int:
        """Bytes held while waiting for the rest of a packet."""
        return len(self._buffer)

    def reset(self) -> None:
        """Drop a partial packet (a real servo does after an inter-byte timeout)."""
        self._buffer.clear()

    def feed(self, data: bytes) -> list[Packet | BadCrc]:
        self._buffer.extend(data)
        out: list[Packet | BadCrc] = []
        while True:
            start = self._buffer.find(HEADER)
            if start < 0:
                # keep a possible header prefix at the end
                keep = 0
                for n in (3, 2, 1):
                    if self._buffer.endswith(HEADER[:n]):
                        keep = n
                        break
                del self._buffer[: len(self._buffer) - keep]
                return out
            del self._buffer[:start]
            if len(self._buffer) < 7:
                return out
            length = self._buffer[5] | (self._buffer[6] << 8)
            if length < 3 or length > self._max_length:
                del self._buffer[0]
                continue
            total = 7 + length
            if len(self._buffer) < total:
                return out
            frame = bytes(self._buffer[:total])
            del self._buffer[:total]
            servo_id, instruction = frame[4], frame[7]
            if crc16(frame[:-2]) != (frame[-2] | (frame[-1] << 8)):
                out.append(BadCrc(servo_id, instruction, total))
                continue
            body = unstuff(frame[7:-2])
            if instruction == Instruction.STATUS:
                if len(body) < 2:
                    continue
                out.append(Packet(servo_id, instruction, body[2:], body[1], total))
            else:
                out.append(Packet(servo_id, instruction, body[1:], None, total))


def parse_one(data: bytes) -> Packet | BadCrc:
    """Parse exactly one packet from ``data`` (for tests); ValueError if there is none."""
    packets = PacketParser().feed(data)
    if len(packets) != 1:
        raise ValueError(f"expected one packet, found {len(packets)}")
    return packets[0]
