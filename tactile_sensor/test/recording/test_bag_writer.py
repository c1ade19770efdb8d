"""BagRecorder writes real bags that rosbags, the mcap library and rosbag2 tools can read."""

from __future__ import annotations

import json
import os
import threading
import time
from pathlib import Path

import numpy as np
import pytest
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from mcap.reader import make_reader
from rosbags.highlevel import AnyReader
from rosbags.interfaces import QosDurability
from rosbags.rosbag2 import Reader

from tactile_sensor.recording import BagRecorder, RecordingError, default_typestore
from tactile_sensor.recording.bag_writer import register_package

WRENCH = "geometry_msgs/msg/WrenchStamped"
READING = "tactile_sensor_interfaces/msg/TactileReading"
CURVE = "tactile_sensor_interfaces/msg/CalibrationCurve"
TYPESTORE = default_typestore()

LATCHED_QOS = json.dumps([{
    "history": "keep_last", "depth": 1, "reliability": "reliable",
    "durability": "transient_local", "deadline": {"sec": 0, "nsec": 0},
    "lifespan": {"sec": 0, "nsec": 0}, "liveliness": "automatic",
    "liveliness_lease_duration": {"sec": 0, "nsec": 0},
    "avoid_ros_namespace_conventions": False,
}])


def wrench_cdr(i: int) -> bytes:
    t = TYPESTORE.types
    msg = t[WRENCH](
        header=t["std_msgs/msg/Header"](
            stamp=t["builtin_interfaces/msg/Time"](sec=i // 1000, nanosec=(i % 1000) * 1_000_000),
            frame_id="skin"),
        wrench=t["geometry_msgs/msg/Wrench"](
            force=t["geometry_msgs/msg/Vector3"](x=float(i), y=0.0, z=-float(i)),
            torque=t["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=0.0)))
    return bytes(TYPESTORE.serialize_cdr(msg, WRENCH))


def reading_cdr(i: int) -> bytes:
    t = TYPESTORE.types
    msg = t[READING](
        header=t["std_msgs/msg/Header"](
            stamp=t["builtin_interfaces/msg/Time"](sec=i, nanosec=0), frame_id="skin"),
        voltage=1.5, output=0.01 * i, force=0.1 * i, contact=bool(i % 2),
        faces=[], voltages=np.zeros(0), outputs=np.zeros(0))
    return bytes(TYPESTORE.serialize_cdr(msg, READING))


def curve_cdr() -> bytes:
    t = TYPESTORE.types
    msg = t[CURVE](
        header=t["std_msgs/msg/Header"](
            stamp=t["builtin_interfaces/msg/Time"](sec=1, nanosec=0), frame_id=""),
        output=np.array([0.0, 0.1, 0.2]),
        force=np.array([0.0, 1.0, 3.0]), source="test", rate_g=np.zeros(0),
        rate_tau=np.zeros(0))
    return bytes(TYPESTORE.serialize_cdr(msg, CURVE))


def record_sample(path: Path, storage: str = "mcap", n_wrench: int = 50) -> BagRecorder:
    with BagRecorder(path, storage) as bag:
        bag.add_topic("/driver/wrench", WRENCH)
        bag.add_topic("/driver/reading", READING)
        bag.add_topic("/model/curve", CURVE, LATCHED_QOS)
        bag.write("/model/curve", 1_000_000_000, curve_cdr())
        for i in range(n_wrench):
            bag.write("/driver/wrench", 2_000_000_000 + i * 1_000_000, wrench_cdr(i))
            if i % 10 == 0:
                bag.write("/driver/reading", 2_000_000_000 + i * 1_000_000, reading_cdr(i))
    return bag


@pytest.mark.parametrize("storage", ["mcap", "sqlite3"])
def test_messages_read_back_in_order_with_their_content(tmp_path, storage):
    bag = record_sample(tmp_path / "bag", storage)
    assert bag.counts == {"/driver/wrench": 50, "/driver/reading": 5, "/model/curve": 1}
    forces: list[float] = []
    stamps: list[int] = []
    with AnyReader([tmp_path / "bag"]) as reader:
        assert {c.topic: c.msgtype for c in reader.connections} == {
            "/driver/wrench": WRENCH, "/driver/reading": READING, "/model/curve": CURVE}
        wrench_conns = [c for c in reader.connections if c.topic == "/driver/wrench"]
        for conn, timestamp, raw in reader.messages(connections=wrench_conns):
            msg = reader.deserialize(raw, conn.msgtype)
            forces.append(msg.wrench.force.x)
            stamps.append(timestamp)
        readings = [reader.deserialize(raw, c.msgtype) for c, _, raw in reader.messages(
            connections=[c for c in reader.connections if c.topic == "/driver/reading"])]
    assert forces == [float(i) for i in range(50)]
    assert stamps == sorted(stamps) and len(set(stamps)) == 50
    assert [r.force for r in readings] == pytest.approx([0.0, 1.0, 2.0, 3.0, 4.0])
    assert [r.contact for r in readings] == [False] * 5  # i = 0, 10, 20, ... are even


def test_message_definitions_and_hashes_are_embedded(tmp_path):
    record_sample(tmp_path / "bag")
    with Reader(tmp_path / "bag") as reader:
        conns = {c.topic: c for c in reader.connections}
    reading_def = conns["/driver/reading"].msgdef.data
    assert "float64 voltage" in reading_def and "MSG: std_msgs/Header" in reading_def
    wrench_def = conns["/driver/wrench"].msgdef.data
    assert "MSG: geometry_msgs/Wrench" in wrench_def and "MSG: geometry_msgs/Vector3" in wrench_def
    for conn in conns.values():
        assert conn.digest.startswith("RIHS01_")
    # Where rosidl built our interfaces, its hashes must equal the ones in the bag, or
    # rosbag2 playback would refuse to match types.
    built = [Path(p) / "share/tactile_sensor_interfaces/msg/TactileReading.json"
             for p in os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep) if p]
    built = [p for p in built if p.is_file()]
    if built:
        rosidl_hash = json.loads(built[0].read_text())["type_hashes"][0]["hash_string"]
        assert conns["/driver/reading"].digest == rosidl_hash


def test_mcap_is_readable_by_the_mcap_library_as_ros2(tmp_path):
    """What Foxglove and PlotJuggler need: ros2 profile, ros2msg schemas, cdr channels."""
    record_sample(tmp_path / "bag")
    with (tmp_path / "bag" / "bag_0.mcap").open("rb") as stream:
        reader = make_reader(stream)
        assert reader.get_header().profile == "ros2"
        summary = reader.get_summary()
        assert summary is not None
        schemas = {s.name: s for s in summary.schemas.values()}
        assert set(schemas) == {WRENCH, READING, CURVE}
        assert {s.encoding for s in schemas.values()} == {"ros2msg"}
        assert b"float64[] output" in schemas[CURVE].data
        assert {c.message_encoding for c in summary.channels.values()} == {"cdr"}
        assert summary.statistics.message_count == 56
        messages = list(reader.iter_messages(topics=["/driver/wrench"]))
    assert len(messages) == 50


def test_metadata_yaml_is_complete(tmp_path):
    record_sample(tmp_path / "bag")
    info = yaml.safe_load((tmp_path / "bag" / "metadata.yaml").read_text())[
        "rosbag2_bagfile_information"]
    assert {"version", "storage_identifier", "relative_file_paths", "duration", "starting_time",
            "message_count", "topics_with_message_count", "compression_format",
            "compression_mode", "files", "custom_data", "ros_distro"} <= set(info)
    assert info["storage_identifier"] == "mcap"
    assert info["compression_mode"] == "" and info["compression_format"] == ""
    assert info["message_count"] == 56
    assert info["starting_time"]["nanoseconds_since_epoch"] == 1_000_000_000
    assert info["duration"]["nanoseconds"] == 2_000_000_000 + 49_000_000 - 1_000_000_000
    assert [f["path"] for f in info["files"]] == info["relative_file_paths"] == ["bag_0.mcap"]
    assert (tmp_path / "bag" / "bag_0.mcap").is_file()
    topics = {t["topic_metadata"]["name"]: t for t in info["topics_with_message_count"]}
    assert topics["/driver/wrench"]["message_count"] == 50
    for topic in topics.values():
        meta = topic["topic_metadata"]
        assert {"name", "type", "serialization_format", "offered_qos_profiles",
                "type_description_hash"} <= set(meta)
        assert meta["serialization_format"] == "cdr"
    curve_qos = yaml.safe_load(topics["/model/curve"]["topic_metadata"]["offered_qos_profiles"])
    assert curve_qos[0]["durability"] == 1  # transient local, as the publisher offered


def test_offered_qos_survives_into_the_bag(tmp_path):
    record_sample(tmp_path / "bag")
    with Reader(tmp_path / "bag") as reader:
        conn = next(c for c in reader.connections if c.topic == "/model/curve")
    assert conn.ext.offered_qos_profiles[0].durability == QosDurability.TRANSIENT_LOCAL


def test_concurrent_writers_lose_nothing(tmp_path):
    """write() is called from executor threads; every message must reach the bag."""
    threads, per_thread = 4, 500
    with BagRecorder(tmp_path / "bag") as bag:
        for k in range(threads):
            bag.add_topic(f"/t{k}", WRENCH)

        def produce(k: int) -> None:
            for i in range(per_thread):
                bag.write(f"/t{k}", i * 1000 + k, wrench_cdr(i))

        workers = [threading.Thread(target=produce, args=(k,)) for k in range(threads)]
        for w in workers:
            w.start()
        for w in workers:
            w.join()
    assert bag.counts == {f"/t{k}": per_thread for k in range(threads)}
    assert bag.pending == 0
    with AnyReader([tmp_path / "bag"]) as reader:
        assert sum(1 for _ in reader.messages()) == threads * per_thread


@settings(max_examples=15, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(st.lists(st.tuples(st.sampled_from(["/a", "/b"]), st.integers(0, 2**62),
                          st.binary(max_size=64)), max_size=40))
def test_any_raw_messages_round_trip(tmp_path_factory, messages):
    path = tmp_path_factory.mktemp("prop") / "bag"
    with BagRecorder(path) as bag:
        bag.add_topic("/a", "std_msgs/msg/String")
        bag.add_topic("/b", "std_msgs/String")  # short spelling is accepted
        for topic, stamp, data in messages:
            bag.write(topic, stamp, data)
    with Reader(path) as reader:
        back = [(c.topic, t, bytes(d)) for c, t, d in reader.messages()]
        assert {c.msgtype for c in reader.connections} == {"std_msgs/msg/String"}
    assert sorted(back) == sorted(messages)


def test_closing_after_an_exception_still_finishes_the_bag(tmp_path):
    with pytest.raises(KeyError), BagRecorder(tmp_path / "bag") as bag:
        bag.add_topic("/w", WRENCH)
        bag.write("/w", 5, wrench_cdr(1))
        raise KeyError("caller failed")
    assert (tmp_path / "bag" / "metadata.yaml").is_file()
    with Reader(tmp_path / "bag") as reader:
        assert reader.message_count == 1
    bag.close()  # a second close is harmless


def test_the_first_flush_is_one_period_after_opening(tmp_path, monkeypatch):
    """The writer's flush clock starts when the bag opens: a message written at once is on
    disk after one ``flush_period_s``, not two (its first tick only starts the clock)."""
    from tactile_sensor.recording import rosbag2_writer

    ticks: list[tuple[float, int]] = []  # (time, messages written by then)
    original = rosbag2_writer.Rosbag2Writer.tick

    def tick(self, now_s: float) -> None:
        ticks.append((now_s, self._written))
        original(self, now_s)

    monkeypatch.setattr(rosbag2_writer.Rosbag2Writer, "tick", tick)
    with BagRecorder(tmp_path / "bag", "mcap") as bag:
        bag.add_topic("/driver/wrench", WRENCH)
        bag.write("/driver/wrench", 1_000, wrench_cdr(0))
        deadline = time.monotonic() + 60.0
        while bag.kept < 1 and time.monotonic() < deadline:
            time.sleep(0.01)
        assert bag.kept == 1
    assert ticks and ticks[0][1] == 0  # the clock started before the first message


def test_register_package_finds_nothing_for_a_missing_package():
    assert register_package(default_typestore(), "no_such_interfaces_pkg") == 0


# -- errors a user can cause -------------------------------------------------------------------

def test_existing_path_is_refused(tmp_path):
    (tmp_path / "bag").mkdir()
    with pytest.raises(RecordingError, match="exists already; choose a new path"):
        BagRecorder(tmp_path / "bag")


def test_folder_under_a_file_is_refused(tmp_path):
    (tmp_path / "plain.txt").write_text("x")
    with pytest.raises(RecordingError, match=r"Cannot create bag folder .*choose a folder"):
        BagRecorder(tmp_path / "plain.txt" / "bag").open()


def test_a_folder_nobody_may_write_is_refused_with_the_reason():
    # sysfs refuses new folders to everyone, root included (a chmod 0o500 folder would
    # not stop root): EPERM as root, EACCES as a user; both reach the same error path.
    with pytest.raises(RecordingError, match=r"Cannot create bag folder /sys/tactile_bag "
                       r"\((Operation not permitted|Permission denied)\); choose a folder you "
                       r"can write to\."):
        BagRecorder(Path("/sys/tactile_bag")).open()


def test_unknown_storage_is_refused(tmp_path):
    with pytest.raises(RecordingError, match="Storage 'hdf5' is unknown; use one of mcap"):
        BagRecorder(tmp_path / "bag", "hdf5")


@pytest.mark.parametrize("msgtype", ["geometry_msgs/msg/NoSuchType", "no_pkg/msg/Thing",
                                     "WrenchStamped"])
def test_unknown_message_type_is_refused(tmp_path, msgtype):
    with BagRecorder(tmp_path / "bag") as bag, pytest.raises(
            RecordingError, match="unknown to the recorder; check its spelling"):
        bag.add_topic("/x", msgtype)


def test_bad_qos_text_is_refused(tmp_path):
    with BagRecorder(tmp_path / "bag") as bag, pytest.raises(
            RecordingError, match="not rosbag2 offered_qos_profiles YAML"):
        bag.add_topic("/x", WRENCH, "[{history: keep_last}]")


def test_same_topic_with_another_type_is_refused(tmp_path):
    with BagRecorder(tmp_path / "bag") as bag:
        bag.add_topic("/x", WRENCH)
        bag.add_topic("/x", WRENCH)  # same declaration twice is fine
        with pytest.raises(RecordingError, match="recorded as geometry_msgs/msg/WrenchStamped"):
            bag.add_topic("/x", READING)


def test_writing_an_undeclared_topic_is_refused(tmp_path):
    with BagRecorder(tmp_path / "bag") as bag, pytest.raises(
            RecordingError, match="call add_topic"):
        bag.write("/nope", 0, b"")


def test_writing_before_open_or_after_close_is_refused(tmp_path):
    bag = BagRecorder(tmp_path / "bag")
    with pytest.raises(RecordingError, match="not open"):
        bag.add_topic("/w", WRENCH)
    with bag:
        bag.add_topic("/w", WRENCH)
    with pytest.raises(RecordingError, match="not open for writing"):
        bag.write("/w", 0, wrench_cdr(0))
    with pytest.raises(RecordingError, match="opened already"):
        bag.open()


def test_negative_timestamp_is_refused(tmp_path):
    with BagRecorder(tmp_path / "bag") as bag:
        bag.add_topic("/w", WRENCH)
        with pytest.raises(RecordingError, match=r"outside 0\.\.2\*\*63-1 ns"):
            bag.write("/w", -1, wrench_cdr(0))


def test_storage_failure_is_reported_with_the_fix(tmp_path, monkeypatch):
    """A full disk surfaces as RecordingError on the next write or on close, never silently."""
    from tactile_sensor.recording.storage_files import McapFile

    def disk_full(self, connection, timestamp, data):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(McapFile, "write", disk_full)
    bag = BagRecorder(tmp_path / "bag").open()
    bag.add_topic("/w", WRENCH)
    bag.write("/w", 1, wrench_cdr(0))
    with pytest.raises(RecordingError, match=r"No space left on device.*free disk space"):
        for i in range(10_000):  # the thread fails soon; a later write reports it
            bag.write("/w", 2 + i, wrench_cdr(0))
            time.sleep(0.001)
    with pytest.raises(RecordingError, match="free disk space"):
        bag.close()
