"""Chunks reach the disk on time, bags split like rosbag2's, and a crash keeps what was
flushed. A "crash" is a copy of the bag folder taken while the writer is still open: the
files as a ``kill -9`` would leave them (Python's buffers and the open chunk not in them)."""

from __future__ import annotations

import shutil
import time
from pathlib import Path

import pytest
import yaml
from rosbags.rosbag2 import Reader

from tactile_sensor.recording import BagRecorder, default_typestore
from tactile_sensor.recording.recovery import recover
from tactile_sensor.recording.rosbag2_writer import Rosbag2Writer, WriterOptions

WRENCH = "geometry_msgs/msg/WrenchStamped"
TYPESTORE = default_typestore()
MSGDEF, _ = TYPESTORE.generate_msgdef(WRENCH, ros_version=2)
DIGEST = TYPESTORE.hash_rihs01(WRENCH)
NEVER = float("inf")


def wrench_cdr(i: int) -> bytes:
    t = TYPESTORE.types
    msg = t[WRENCH](
        header=t["std_msgs/msg/Header"](
            stamp=t["builtin_interfaces/msg/Time"](sec=i, nanosec=0), frame_id="skin"),
        wrench=t["geometry_msgs/msg/Wrench"](
            force=t["geometry_msgs/msg/Vector3"](x=float(i), y=0.0, z=-float(i)),
            torque=t["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=0.0)))
    return bytes(TYPESTORE.serialize_cdr(msg, WRENCH))


def open_writer(path: Path, storage: str = "mcap", **options) -> tuple[Rosbag2Writer, object]:
    writer = Rosbag2Writer(path, storage, WriterOptions(**{"flush_period_s": NEVER, **options}))
    writer.open()
    return writer, writer.add_connection("/w", WRENCH, MSGDEF, DIGEST)


def crash_copy(bag: Path, where: Path) -> Path:
    shutil.copytree(bag, where)
    return where


def stamps_read(path: Path) -> list[int]:
    with Reader(path) as reader:
        return [stamp for _, stamp, _ in reader.messages()]


@pytest.mark.parametrize("storage", ["mcap", "sqlite3"])
def test_a_crash_keeps_every_flushed_message_and_loses_the_rest(tmp_path, storage):
    writer, conn = open_writer(tmp_path / "bag", storage)
    for i in range(100):
        writer.write(conn, 1_000 + i, wrench_cdr(i))
    writer.flush()
    for i in range(100, 150):
        writer.write(conn, 1_000 + i, wrench_cdr(i))
    assert writer.durable_count == 100
    crashed = crash_copy(tmp_path / "bag", tmp_path / "crashed")
    writer.close()
    assert not (crashed / "metadata.yaml").exists()
    result = recover(crashed, tmp_path / "recovered")
    assert result.message_count == 100
    assert stamps_read(result.out) == [1_000 + i for i in range(100)]
    assert stamps_read(tmp_path / "bag") == [1_000 + i for i in range(150)]


def test_tick_flushes_once_the_period_passed_and_not_before(tmp_path):
    writer, conn = open_writer(tmp_path / "bag", flush_period_s=0.5)
    writer.tick(10.0)
    writer.write(conn, 1, wrench_cdr(1))
    writer.tick(10.49)
    assert writer.durable_count == 0
    writer.tick(10.5)
    assert writer.durable_count == 1
    writer.write(conn, 2, wrench_cdr(2))
    writer.tick(10.9)
    assert writer.durable_count == 1
    writer.close()


def test_a_full_chunk_is_written_without_a_flush(tmp_path):
    writer, conn = open_writer(tmp_path / "bag", chunk_bytes=4096)
    for i in range(400):
        writer.write(conn, i, wrench_cdr(i))
    crashed = crash_copy(tmp_path / "bag", tmp_path / "crashed")
    writer.close()
    got = recover(crashed, tmp_path / "recovered").message_count
    assert 300 < got < 400  # every chunk the size closed, not the open one
    assert stamps_read(tmp_path / "recovered") == list(range(got))


@pytest.mark.parametrize("storage", ["mcap", "sqlite3"])
def test_split_by_duration_names_files_like_rosbag2(tmp_path, storage):
    writer, conn = open_writer(tmp_path / "bag", storage, max_bag_duration_s=1.0)
    stamps = [int(0.1e9 * i) for i in range(35)]  # 0 .. 3.4 s
    for i, stamp in enumerate(stamps):
        writer.write(conn, stamp, wrench_cdr(i))
    writer.close()
    suffix = ".mcap" if storage == "mcap" else ".db3"
    names = [f"bag_{i}{suffix}" for i in range(4)]
    info = yaml.safe_load((tmp_path / "bag" / "metadata.yaml").read_text())[
        "rosbag2_bagfile_information"]
    assert info["relative_file_paths"] == names
    assert [f["message_count"] for f in info["files"]] == [10, 10, 10, 5]
    assert info["message_count"] == 35 and info["version"] == 8
    assert info["topics_with_message_count"][0]["topic_metadata"][
        "type_description_hash"] == DIGEST
    assert sorted(p.name for p in (tmp_path / "bag").iterdir()) == [*names, "metadata.yaml"]
    assert stamps_read(tmp_path / "bag") == stamps


def test_split_by_size_after_a_flush_reaches_it(tmp_path):
    writer, conn = open_writer(tmp_path / "bag", max_bag_size_bytes=20_000)
    for i in range(600):
        writer.write(conn, i, wrench_cdr(i))
        if i % 50 == 49:
            writer.flush()
    writer.close()
    files = sorted((tmp_path / "bag").glob("*.mcap"), key=lambda p: int(p.stem.split("_")[1]))
    assert len(files) > 1
    assert all(f.stat().st_size >= 20_000 for f in files[:-1])
    assert stamps_read(tmp_path / "bag") == list(range(600))


def test_the_recorder_makes_the_bag_durable_while_no_message_comes(tmp_path):
    bag = BagRecorder(tmp_path / "bag", options=WriterOptions(flush_period_s=0.05)).open()
    bag.add_topic("/w", WRENCH)
    for i in range(30):
        bag.write("/w", i, wrench_cdr(i))
    deadline = time.monotonic() + 10
    while bag.kept < 30 and time.monotonic() < deadline:  # nothing else is written
        time.sleep(0.01)
    assert bag.kept == 30
    crashed = crash_copy(tmp_path / "bag", tmp_path / "crashed")
    bag.close()
    assert recover(crashed, tmp_path / "recovered").message_count == 30


def test_a_storage_failure_keeps_the_flushed_part_and_says_how_much(tmp_path, monkeypatch):
    from tactile_sensor.recording import RecordingError
    from tactile_sensor.recording.storage_files import McapFile

    bag = BagRecorder(tmp_path / "bag", options=WriterOptions(flush_period_s=0.01)).open()
    bag.add_topic("/w", WRENCH)
    for i in range(20):
        bag.write("/w", i, wrench_cdr(i))
    deadline = time.monotonic() + 10
    while bag.kept < 20 and time.monotonic() < deadline:
        time.sleep(0.01)

    def disk_full(self, connection, timestamp, data):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(McapFile, "write", disk_full)
    with pytest.raises(RecordingError, match=r"20 messages up to the failure are kept"):
        for i in range(10_000):
            bag.write("/w", 100 + i, wrench_cdr(i))
            time.sleep(0.001)
    assert bag.failed_after_s is not None and bag.failed_after_s > 0
    with pytest.raises(RecordingError):
        bag.close()
    assert not (tmp_path / "bag" / "metadata.yaml").exists()
    with pytest.raises(RecordingError, match=r"writing the recovered bag .* free disk space"):
        recover(tmp_path / "bag", tmp_path / "recovered-on-full-disk")
    monkeypatch.undo()
    assert recover(tmp_path / "bag", tmp_path / "recovered").message_count == 20
