"""The driver's and the mock bench's pre-serialised messages decode, with rclpy's own
deserialiser, to the messages rclpy would have built, and are no longer than rclpy's
serialisation of them (which appends room for the empty float64[] alignment to a TactileReading)."""

from __future__ import annotations

import math

from geometry_msgs.msg import WrenchStamped
from hypothesis import given, settings
from hypothesis import strategies as st
from rclpy.serialization import deserialize_message, serialize_message
from rclpy.time import Time
from sensor_msgs.msg import JointState

from tactile_sensor.nodes.reading_cdr import JointStateCdr, ReadingCdr, WrenchCdr
from tactile_sensor_interfaces.msg import TactileReading

FACES = ("front", "back", "left", "right")
stamps = st.integers(0, 2**31 * 1_000_000_000 - 1)  # builtin_interfaces/Time: int32 s
floats = st.floats(allow_nan=True, allow_infinity=True, width=64)
frame_ids = st.text(st.characters(codec="utf-8", exclude_characters="\x00"), max_size=40)


def same(a: float, b: float) -> bool:
    return a == b or (math.isnan(a) and math.isnan(b))


@settings(deadline=None)  # a loaded machine: the first example also imports the types
@given(frame_id=frame_ids, faces=st.sampled_from([(), FACES[:2], FACES, ("left",) * 3]),
       stamp_ns=stamps, values=st.lists(floats, min_size=11, max_size=11),
       contact=st.booleans())
def test_a_reading_decodes_to_the_message_rclpy_builds(frame_id, faces, stamp_ns, values,
                                                        contact):
    n = len(faces)
    voltages, outputs = values[3:3 + n], values[7:7 + n]
    data = ReadingCdr(frame_id, faces).encode(stamp_ns, *values[:3], contact, voltages,
                                              outputs)
    msg = deserialize_message(data, TactileReading)
    assert msg.header.stamp == Time(nanoseconds=stamp_ns).to_msg()
    assert msg.header.frame_id == frame_id
    assert all(map(same, (msg.voltage, msg.output, msg.force), values[:3]))
    assert msg.contact is contact
    assert list(msg.faces) == list(faces)
    assert all(map(same, msg.voltages, voltages)) and len(msg.voltages) == n
    assert all(map(same, msg.outputs, outputs)) and len(msg.outputs) == n
    assert len(data) <= len(serialize_message(msg))


@settings(deadline=None)
@given(frame_id=frame_ids, stamp_ns=stamps, force=st.lists(floats, min_size=3, max_size=3))
def test_a_wrench_decodes_to_the_message_rclpy_builds(frame_id, stamp_ns, force):
    data = WrenchCdr(frame_id).encode(stamp_ns, *force)
    msg = deserialize_message(data, WrenchStamped)
    assert msg.header.stamp == Time(nanoseconds=stamp_ns).to_msg()
    assert msg.header.frame_id == frame_id
    f, t = msg.wrench.force, msg.wrench.torque
    assert all(map(same, (f.x, f.y, f.z), force))
    assert (t.x, t.y, t.z) == (0.0, 0.0, 0.0)
    # rclpy leaves its padding bytes uninitialised, so only the length compares
    assert len(data) == len(serialize_message(msg))


@settings(deadline=None)
@given(frame_id=frame_ids, stamp_ns=stamps, wrench=st.lists(floats, min_size=6, max_size=6))
def test_a_wrench_with_torque_decodes_to_its_six_numbers(frame_id, stamp_ns, wrench):
    msg = deserialize_message(WrenchCdr(frame_id).encode(stamp_ns, *wrench), WrenchStamped)
    f, t = msg.wrench.force, msg.wrench.torque
    assert all(map(same, (f.x, f.y, f.z, t.x, t.y, t.z), wrench))


def test_the_buffer_is_reused_but_each_message_is_its_own_bytes():
    cdr = ReadingCdr("tactile_sensor")
    first = cdr.encode(1, 1.0, 0.5, 2.0, True)
    second = cdr.encode(2, 3.0, 0.25, 4.0, False)
    assert isinstance(first, bytes) and first != second
    assert deserialize_message(first, TactileReading).force == 2.0


@settings(deadline=None)
@given(frame_id=frame_ids, stamp_ns=stamps,
       names=st.sampled_from([(), ("stage_z",), ("stage_z", "stage_x", "stage_y"),
                              ("stage_z", "stage_x", "stage_y", "stage_rx", "stage_ry",
                               "stage_rz")]),
       values=st.lists(floats, min_size=6, max_size=6))
def test_a_joint_state_decodes_to_the_message_rclpy_builds(frame_id, stamp_ns, names, values):
    positions = values[:len(names)]
    data = JointStateCdr(frame_id, names).encode(stamp_ns, positions)
    msg = deserialize_message(data, JointState)
    assert msg.header.stamp == Time(nanoseconds=stamp_ns).to_msg()
    assert msg.header.frame_id == frame_id
    assert list(msg.name) == list(names)
    assert all(map(same, msg.position, positions)) and len(msg.position) == len(names)
    assert len(msg.velocity) == 0 and len(msg.effort) == 0
    # rclpy reserves alignment room after empty float64[], as for a TactileReading
    assert len(data) <= len(serialize_message(msg))

