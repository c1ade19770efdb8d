"""rosbag2 recording without rosbag2: a pure core over ``rosbags`` (no rclpy here)."""

from __future__ import annotations

from .bag_writer import STORAGES, BagRecorder, default_typestore
from .errors import RecordingError

__all__ = ["STORAGES", "BagRecorder", "RecordingError", "default_typestore"]
