"""``kill -9`` of the recorder node in its own process while messages stream in: ``bag
recover`` and the analysis' reader get back every message the recorder had flushed to disk
before the kill, as an unbroken prefix of what was sent. How long the unflushed tail is
(about the 0.5 s flush period) is ``benchmarks/bench_recording_kill.py``'s to measure: a
busy machine lengthens it, so the test judges what was on disk, not seconds."""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

rclpy = pytest.importorskip("rclpy")

from geometry_msgs.msg import WrenchStamped  # noqa: E402
from rclpy.node import Node  # noqa: E402
from rclpy.qos import QoSProfile, ReliabilityPolicy  # noqa: E402

from tactile_sensor.analysis.bag_reader import TopicSpec, read_recording  # noqa: E402
from tactile_sensor.analysis.errors import BagError  # noqa: E402

pytestmark = [pytest.mark.ros, pytest.mark.slow]
RATE_HZ = 500
SOURCE = Path(__file__).resolve().parents[2]


SPEC = TopicSpec("wrench", "/test/kill", {"force_n": "wrench.force.z"}, "--topic",
                 "WrenchStamped")


def forces_on_disk(bag: Path, copy: Path) -> list[float]:
    """What a reader gets from a copy of the bag the recorder is writing (nothing before its
    first file appears)."""
    if not any(f.stat().st_size for f in bag.glob("*.mcap")):
        return []
    shutil.copytree(bag, copy)
    try:
        recording = read_recording(copy, [SPEC], notify=lambda _note: None)
    except BagError:  # no whole chunk yet
        return []
    return list(recording.series["wrench"].values["force_n"])


def test_a_killed_recorder_keeps_everything_it_had_flushed(ros_domain, spawn, tmp_path):
    context = rclpy.Context()
    rclpy.init(context=context)
    node = Node("kill_test", context=context)
    try:
        pub = node.create_publisher(WrenchStamped, "/test/kill",
                                    QoSProfile(depth=5000,
                                               reliability=ReliabilityPolicy.RELIABLE))
        bag = tmp_path / "bag"
        recorder = spawn("--ros-args", "-p", f"path:={bag}", "-p", "topics:=['/test/kill']",
                         module="tactile_sensor.nodes.recorder")
        deadline = time.monotonic() + 30
        while pub.get_subscription_count() == 0:
            assert time.monotonic() < deadline, recorder.output()
            time.sleep(0.02)
        msg = WrenchStamped()
        start = time.monotonic()
        sent = flushed = 0
        # 500 Hz, paced by the clock, until the bag on disk holds two seconds' worth: the
        # recorder is killed mid-stream, with a tail it has not flushed yet.
        while flushed < 2 * RATE_HZ:
            assert time.monotonic() < start + 120, (sent, flushed, recorder.output())
            msg.wrench.force.z = float(sent)
            pub.publish(msg)
            sent += 1
            if sent % (RATE_HZ // 4) == 0:
                flushed = len(forces_on_disk(bag, tmp_path / f"copy-{sent}"))
            delay = start + sent / RATE_HZ - time.monotonic()
            if delay > 0:
                time.sleep(delay)
        recorder.send_signal(signal.SIGKILL)
        recorder.proc.wait(10)
    finally:
        node.destroy_node()
        context.try_shutdown()
    assert not (bag / "metadata.yaml").exists()
    env = {**os.environ, "PYTHONPATH": str(SOURCE)}
    result = subprocess.run([sys.executable, "-m", "tactile_sensor.cli", "bag", "recover",
                             str(bag)], capture_output=True, text=True, timeout=60, env=env)
    assert result.returncode == 0, result.stderr
    assert "recovered" in result.stdout and "bag_0.mcap" in result.stdout
    notes: list[str] = []
    recording = read_recording(bag, [SPEC], notify=notes.append)
    force = recording.series["wrench"].values["force_n"]
    assert len(notes) == 1 and "recovered" in notes[0]
    # an unbroken prefix of what was sent, with everything that was on disk before the kill
    assert list(force) == [float(i) for i in range(len(force))]
    assert flushed <= len(force) <= sent, (flushed, len(force), sent)
    recovered = bag.with_name("bag-recovered")
    assert (recovered / "metadata.yaml").is_file()
