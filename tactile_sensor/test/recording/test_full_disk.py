"""A real full disk (a 4 MiB tmpfs): the recorder says so, and the bag is recoverable up to
the failure. Mounting needs root; without it the test is skipped with the reason."""

from __future__ import annotations

import subprocess
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from tactile_sensor.recording import BagRecorder, RecordingError
from tactile_sensor.recording.recovery import recover
from tactile_sensor.recording.rosbag2_writer import WriterOptions

# Mounts a small filesystem image (mkfs and mount run as processes).
pytestmark = pytest.mark.slow


@pytest.fixture
def small_disk(tmp_path: Path) -> Iterator[Path]:
    mount = tmp_path / "disk"
    mount.mkdir()
    done = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=4m", "tmpfs", str(mount)],
                          capture_output=True, text=True)
    if done.returncode != 0:
        pytest.skip(f"cannot mount a 4 MiB tmpfs here ({done.stderr.strip()}); needs root")
    try:
        yield mount
    finally:
        subprocess.run(["umount", str(mount)], check=False)


def test_a_full_disk_is_reported_and_the_bag_is_recoverable_up_to_it(small_disk, tmp_path):
    bag = BagRecorder(small_disk / "bag", options=WriterOptions(flush_period_s=0.02)).open()
    bag.add_topic("/w", "std_msgs/msg/String")
    payload = b"\x00\x01\x00\x00" + (1000).to_bytes(4, "little") + b"x" * 999 + b"\x00"
    written = 0
    with pytest.raises(RecordingError, match=r"No space left on device.*messages up to the "
                                             r"failure are kept.*bag recover"):
        for _ in range(100):  # 100 x 200 kB: five times the disk
            for _ in range(200):
                bag.write("/w", 1_000_000 + written, payload)
                written += 1
            deadline = time.monotonic() + 30  # wait until this batch is on disk (or failed)
            while bag.kept < written and bag.failed_after_s is None:
                assert time.monotonic() < deadline
                time.sleep(0.005)
    kept = bag.kept
    assert 1000 < kept < written and bag.failed_after_s is not None
    with pytest.raises(RecordingError):
        bag.close()
    result = recover(small_disk / "bag", tmp_path / "recovered")
    assert kept <= result.message_count < written
