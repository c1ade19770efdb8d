"""The numpy CDR field reader must agree with rosbags' deserialize_cdr on every message."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from rosbags.typesys import Stores, get_typestore

from tactile_sensor.analysis.cdr_columns import (
    CdrLayoutError,
    decode_columns,
    missing_fields,
    read_strings,
)
from tactile_sensor.analysis.synthetic import writer_typestore

STORE = get_typestore(Stores.ROS2_KILTED)
OURS = writer_typestore()
T = STORE.types

names = st.text(alphabet="abcxyz_/", max_size=12)
floats = st.floats(allow_nan=False, allow_infinity=False, width=64)
joint = st.tuples(
    st.integers(0, 2**31 - 1), st.integers(0, 999_999_999), names,
    st.lists(names, max_size=3), st.lists(floats, max_size=3), st.booleans())


def joint_state(sec, nsec, frame, joint_names, position):
    header = T["std_msgs/msg/Header"](stamp=T["builtin_interfaces/msg/Time"](sec=sec,
                                                                             nanosec=nsec),
                                      frame_id=frame)
    return T["sensor_msgs/msg/JointState"](header=header, name=joint_names,
                                           position=np.array(position, dtype=float),
                                           velocity=np.zeros(0), effort=np.zeros(2))


@settings(max_examples=25, deadline=None)
@given(st.lists(joint, min_size=1, max_size=25))
def test_joint_states_of_mixed_layouts_and_byte_orders_match_rosbags(items):
    raws = [bytes(STORE.serialize_cdr(joint_state(*it[:5]), "sensor_msgs/msg/JointState",
                                      little_endian=it[5])) for it in items]
    paths = ["header.stamp.sec", "header.stamp.nanosec", "position[0]", "position[1]"]
    cols = decode_columns(raws, "sensor_msgs/msg/JointState", STORE.fielddefs, paths)
    for i, raw in enumerate(raws):
        msg = STORE.deserialize_cdr(raw, "sensor_msgs/msg/JointState")
        assert cols["header.stamp.sec"][i] == msg.header.stamp.sec
        assert cols["header.stamp.nanosec"][i] == msg.header.stamp.nanosec
        for k in (0, 1):
            want = msg.position[k] if len(msg.position) > k else np.nan
            np.testing.assert_equal(cols[f"position[{k}]"][i], want)


@settings(max_examples=25, deadline=None)
@given(st.lists(st.tuples(names, floats, floats, st.booleans()), min_size=1, max_size=20))
def test_tactile_readings_match_rosbags(items):
    typ = "tactile_sensor_interfaces/msg/TactileReading"
    header = OURS.types["std_msgs/msg/Header"]
    time = OURS.types["builtin_interfaces/msg/Time"]
    raws = [bytes(OURS.serialize_cdr(OURS.types[typ](
        header=header(stamp=time(sec=7, nanosec=9), frame_id=frame), voltage=v, output=o,
        force=1.0, contact=c, faces=[], voltages=np.zeros(0), outputs=np.zeros(0)), typ))
        for frame, v, o, c in items]
    cols = decode_columns(raws, typ, OURS.fielddefs, ["output", "voltage", "contact"])
    np.testing.assert_array_equal(cols["output"], [it[2] for it in items])
    np.testing.assert_array_equal(cols["voltage"], [it[1] for it in items])
    np.testing.assert_array_equal(cols["contact"], [float(it[3]) for it in items])


def test_truncated_message_is_a_layout_error():
    raw = bytes(STORE.serialize_cdr(joint_state(1, 2, "stage", ["z"], [0.5]),
                                    "sensor_msgs/msg/JointState"))
    with pytest.raises(CdrLayoutError, match="shorter"):
        decode_columns([raw[:20]], "sensor_msgs/msg/JointState", STORE.fielddefs,
                       ["position[0]"])


def test_missing_fields_names_the_absent_path():
    defs = STORE.fielddefs
    assert missing_fields("geometry_msgs/msg/WrenchStamped", defs, ["wrench.force.z"]) == []
    assert missing_fields("sensor_msgs/msg/JointState", defs, ["wrench.force.z"]) == [
        "wrench.force.z"]
    assert missing_fields("sensor_msgs/msg/JointState", defs, ["position[0]"]) == []


@settings(max_examples=25, deadline=None)
@given(st.lists(st.lists(st.tuples(st.sampled_from(["front", "back", "left", "right", ""]),
                                   floats, floats), max_size=4),
                min_size=1, max_size=12))
def test_variable_length_module_arrays_match_rosbags(items):
    """outputs[i], voltages[i], their lengths and the faces of readings whose arrays have
    any length (0 for one module, 4 for an array, mixed in one topic)."""
    typ = "tactile_sensor_interfaces/msg/TactileReading"
    header = OURS.types["std_msgs/msg/Header"]
    time = OURS.types["builtin_interfaces/msg/Time"]
    msgs = [OURS.types[typ](header=header(stamp=time(sec=1, nanosec=2), frame_id="t"),
                            voltage=0.5, output=0.25, force=1.0, contact=False,
                            faces=[m[0] for m in mods],
                            voltages=np.array([m[1] for m in mods], dtype=float),
                            outputs=np.array([m[2] for m in mods], dtype=float))
            for mods in items]
    raws = [bytes(OURS.serialize_cdr(m, typ)) for m in msgs]
    paths = ["len(outputs)", "len(faces)", "output"] + [
        f"{a}[{i}]" for a in ("outputs", "voltages") for i in range(4)]
    cols = decode_columns(raws, typ, OURS.fielddefs, paths)
    for i, (raw, msg) in enumerate(zip(raws, msgs, strict=True)):
        back = OURS.deserialize_cdr(raw, typ)
        assert cols["len(outputs)"][i] == len(back.outputs) == len(msg.outputs)
        assert cols["len(faces)"][i] == len(back.faces)
        assert cols["output"][i] == 0.25
        for k in range(4):
            for name in ("outputs", "voltages"):
                seq = getattr(back, name)
                np.testing.assert_equal(cols[f"{name}[{k}]"][i],
                                        seq[k] if k < len(seq) else np.nan)
        assert read_strings(raw, typ, OURS.fielddefs,
                            [f"faces[{k}]" for k in range(len(back.faces) + 1)]) == [
            *back.faces, None]


def test_sequence_length_paths_are_checked_like_fields():
    defs = OURS.fielddefs
    typ = "tactile_sensor_interfaces/msg/TactileReading"
    assert missing_fields(typ, defs, ["len(outputs)", "outputs[3]", "faces[0]"]) == []
    assert missing_fields("geometry_msgs/msg/WrenchStamped", defs, ["len(outputs)"]) == [
        "len(outputs)"]
