"""A device's health as diagnostics report it, without ROS: level, one sentence, key values.

The nodes turn a ``Health`` into a diagnostic_msgs/DiagnosticStatus
(nodes/diagnostics_msg.py); the levels are that message's byte values.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from enum import IntEnum


class Level(IntEnum):
    OK = 0
    WARN = 1
    ERROR = 2


@dataclass(frozen=True)
class Health:
    level: Level
    message: str
    #: Key values in report order (strings, as DiagnosticStatus carries them).
    values: dict[str, str] = field(default_factory=dict)
