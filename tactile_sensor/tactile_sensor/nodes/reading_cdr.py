"""The driver's ~/reading and ~/wrench and the mock bench's ~/stage/joint_states and
~/gauge/wrench messages as CDR bytes, packed into one reused buffer.

Why: publishing a message object costs rclpy a Python object tree (message, Header, Time,
Wrench, two Vector3) and a field-by-field conversion into a C message on every sample;
publishing bytes (``Publisher.publish(bytes)``, on Jazzy and Kilted alike) hands them to
the middleware as they are. Within one driver configuration the frame id and the faces
(within one bench world the stage's joints) never change, so every message of a topic has
the same length and layout: the template is serialised once, and each sample packs only
its stamp and its numbers into it.

The encoding is the one every ROS 2 middleware writes (OMG CDR, XCDR version 1,
little-endian): a 4-byte encapsulation header, then the fields in order, each aligned to
its own size counted from the end of that header; a string is its uint32 length including
the terminating NUL, its bytes and the NUL; a sequence is its uint32 count and then its
elements. The tests compare it byte for byte with ``rclpy.serialization.serialize_message``
on both distributions.
"""

from __future__ import annotations

import struct
from collections.abc import Sequence

ENCAPSULATION = b"\x00\x01\x00\x00"  # CDR, little-endian, no options
NS_PER_S = 1_000_000_000
_STAMP = struct.Struct("<iI")  # builtin_interfaces/Time: sec, nanosec
_UINT32 = struct.Struct("<I")
_SCALARS = struct.Struct("<ddd?")  # voltage, output, force, contact (packed in a row)
_WRENCH = struct.Struct("<6d")  # force x, y, z, torque x, y, z


class _Template:
    """A message being laid out: its bytes so far, with every position counted from the
    end of the encapsulation header (where CDR's alignment starts)."""

    def __init__(self) -> None:
        self.data = bytearray(ENCAPSULATION)

    def _align(self, size: int) -> None:
        self.data += bytes(-(len(self.data) - len(ENCAPSULATION)) % size)

    def uint32(self, value: int) -> None:
        self._align(4)
        self.data += _UINT32.pack(value)

    def string(self, text: str) -> None:
        encoded = text.encode("utf-8")
        self.uint32(len(encoded) + 1)
        self.data += encoded + b"\x00"

    def header(self, frame_id: str) -> int:
        """std_msgs/Header with a zero stamp; returns where the stamp goes."""
        self._align(4)
        at = len(self.data)
        self.data += bytes(_STAMP.size)
        self.string(frame_id)
        return at

    def float64s(self, count: int) -> int:
        """Room for ``count`` float64 in a row; returns where they go."""
        if count:
            self._align(8)
        at = len(self.data)
        self.data += bytes(8 * count)
        return at

    def sequence(self, count: int) -> int:
        """A float64[] of ``count`` elements; returns where the elements go."""
        self.uint32(count)
        return self.float64s(count)


class ReadingCdr:
    """tactile_sensor_interfaces/TactileReading for one frame id and set of faces."""

    def __init__(self, frame_id: str, faces: Sequence[str] = ()) -> None:
        t = _Template()
        self._stamp_at = t.header(frame_id)
        self._scalars_at = t.float64s(3)  # contact, a bool, follows the doubles directly
        t.data += b"\x00"
        t.uint32(len(faces))
        for face in faces:
            t.string(face)
        self.modules = len(faces)
        self._voltages_at = t.sequence(self.modules)
        self._outputs_at = t.sequence(self.modules)
        self._buffer = t.data
        self._modules = struct.Struct(f"<{self.modules}d")

    def encode(self, stamp_ns: int, voltage_v: float, output_v: float, force_n: float,
               contact: bool, voltages_v: Sequence[float] = (),
               outputs_v: Sequence[float] = ()) -> bytes:
        """The message's bytes; ``voltages_v``/``outputs_v`` hold one value per face."""
        buffer = self._buffer
        _STAMP.pack_into(buffer, self._stamp_at, *divmod(stamp_ns, NS_PER_S))
        _SCALARS.pack_into(buffer, self._scalars_at, voltage_v, output_v, force_n, contact)
        if self.modules:
            self._modules.pack_into(buffer, self._voltages_at, *voltages_v)
            self._modules.pack_into(buffer, self._outputs_at, *outputs_v)
        return bytes(buffer)


class WrenchCdr:
    """geometry_msgs/WrenchStamped for one frame id: force and torque, six float64 in a row
    (Vector3 force then Vector3 torque, both 8-aligned, so no padding between them)."""

    def __init__(self, frame_id: str) -> None:
        t = _Template()
        self._stamp_at = t.header(frame_id)
        self._wrench_at = t.float64s(6)
        self._buffer = t.data

    def encode(self, stamp_ns: int, force_x_n: float, force_y_n: float, force_z_n: float,
               torque_x_nm: float = 0.0, torque_y_nm: float = 0.0,
               torque_z_nm: float = 0.0) -> bytes:
        buffer = self._buffer
        _STAMP.pack_into(buffer, self._stamp_at, *divmod(stamp_ns, NS_PER_S))
        _WRENCH.pack_into(buffer, self._wrench_at, force_x_n, force_y_n, force_z_n,
                          torque_x_nm, torque_y_nm, torque_z_nm)
        return bytes(buffer)


class JointStateCdr:
    """sensor_msgs/JointState for one frame id and set of joints: their positions, with
    velocity and effort empty (a stage that reports where it is, as the mock bench's)."""

    def __init__(self, frame_id: str, names: Sequence[str]) -> None:
        t = _Template()
        self._stamp_at = t.header(frame_id)
        t.uint32(len(names))
        for name in names:
            t.string(name)
        self.names = tuple(names)
        self._positions_at = t.sequence(len(names))
        t.uint32(0)  # velocity[]
        t.uint32(0)  # effort[]
        self._buffer = t.data
        self._positions = struct.Struct(f"<{len(names)}d")

    def encode(self, stamp_ns: int, positions: Sequence[float]) -> bytes:
        """The message's bytes; ``positions`` holds one value per joint."""
        buffer = self._buffer
        _STAMP.pack_into(buffer, self._stamp_at, *divmod(stamp_ns, NS_PER_S))
        self._positions.pack_into(buffer, self._positions_at, *positions)
        return bytes(buffer)
