"""The stamp and the module output of a ~/reading message, read from its CDR bytes.

Why: the gripper's self-check takes every reading of the driver's 1 kHz record. Taken as a
message object, each costs rclpy a Python object tree (message, Header, Time, three
lists) built in the control loop's thread, 1,000 times a second beside the servo's bus;
the self-check needs two numbers of it. The layout is the one nodes/reading_cdr.py writes
(OMG CDR, XCDR version 1, little-endian, alignment counted from the end of the 4-byte
encapsulation header), which every ROS 2 middleware writes too.
"""

from __future__ import annotations

import struct

from tactile_sensor.nodes.reading_cdr import ENCAPSULATION, NS_PER_S

_HEADER = struct.Struct("<iII")  # stamp sec, stamp nanosec, frame_id's length (with NUL)
_OUTPUT = struct.Struct("<d")
_START = len(ENCAPSULATION)


def stamp_and_output(data: bytes) -> tuple[float, float]:
    """(header stamp [s], module output [V]) of one serialised TactileReading; ValueError
    when the bytes are not one (another encoding, or cut short)."""
    if data[:2] != ENCAPSULATION[:2] or len(data) < _START + _HEADER.size:
        raise ValueError("not a little-endian CDR TactileReading")
    sec, nanosec, length = _HEADER.unpack_from(data, _START)
    at = _START + _HEADER.size + length
    at += -(at - _START) % 8  # voltage, then output: float64, 8-aligned
    if len(data) < at + 16:
        raise ValueError("a TactileReading cut short before its output")
    return sec + nanosec / NS_PER_S, _OUTPUT.unpack_from(data, at + 8)[0]
