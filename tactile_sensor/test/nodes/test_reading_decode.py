"""The gripper's read of a ~/reading's stamp and output from its bytes agrees with rclpy's
own serialisation of the message, whatever its frame id and faces; bytes that are not one
are refused."""

from __future__ import annotations

import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from rclpy.serialization import serialize_message

from tactile_sensor.nodes.reading_decode import stamp_and_output
from tactile_sensor_interfaces.msg import TactileReading

frame_ids = st.text(st.characters(codec="utf-8", exclude_characters="\x00"), max_size=40)
floats = st.floats(allow_nan=True, allow_infinity=True, width=64)


@settings(deadline=None)  # a loaded machine: the first example also imports the types
@given(frame_id=frame_ids, sec=st.integers(0, 2**31 - 1), nanosec=st.integers(0, 999_999_999),
       voltage=floats, output=floats, faces=st.lists(st.sampled_from(["front", "back"]),
                                                     max_size=4))
def test_the_stamp_and_output_are_those_rclpy_serialised(frame_id, sec, nanosec, voltage,
                                                         output, faces):
    msg = TactileReading(voltage=voltage, output=output, faces=faces,
                         outputs=[1.0] * len(faces), voltages=[2.0] * len(faces))
    msg.header.frame_id, msg.header.stamp.sec, msg.header.stamp.nanosec = frame_id, sec, nanosec
    stamp_s, output_v = stamp_and_output(serialize_message(msg))
    assert stamp_s == sec + nanosec / 1e9
    assert output_v == output or (math.isnan(output) and math.isnan(output_v))


@pytest.mark.parametrize("data", [b"", b"\x00\x00\x00\x00" + bytes(40),
                                  serialize_message(TactileReading())[:20]],
                         ids=["empty", "zero_length_header", "truncated_reading"])
def test_bytes_that_are_no_reading_are_refused(data):
    with pytest.raises(ValueError):
        stamp_and_output(data)
