"""Rack-and-pinion finger geometry shared by the controller and the simulated world.

One pinion of ``pitch_radius_m`` drives two racks, so both fingers move symmetrically.
Servo angle is measured from ``open_position_rad`` (fingers fully open) and **positive
rotation closes**: ``opening = open_opening_m - 2 * pitch_radius_m * (angle - open)``.
``opening`` is the gap between the two skin surfaces. A finger's linear speed is
``pitch_radius_m * angular speed``; the gap closes at twice that.
"""

from __future__ import annotations

import math
from dataclasses import dataclass


@dataclass(frozen=True)
class GripperGeometry:
    #: Spur gear GEABPS1.0-28: module 1 mm, 28 teeth -> pitch diameter 28 mm.
    pitch_radius_m: float = 0.014
    #: Servo angle with the fingers fully open (Present Position 2048 = pi rad).
    open_position_rad: float = math.pi
    open_opening_m: float = 0.060
    closed_opening_m: float = 0.002

    def __post_init__(self) -> None:
        if not self.pitch_radius_m > 0:
            raise ValueError("pitch_radius_m must be positive")
        if not 0 <= self.closed_opening_m < self.open_opening_m:
            raise ValueError("need 0 <= closed_opening_m < open_opening_m")

    def opening_m(self, position_rad: float) -> float:
        return self.open_opening_m - 2.0 * self.pitch_radius_m * (
            position_rad - self.open_position_rad)

    def position_rad(self, opening_m: float) -> float:
        return self.open_position_rad + (self.open_opening_m - opening_m) / (
            2.0 * self.pitch_radius_m)

    @property
    def closed_position_rad(self) -> float:
        return self.position_rad(self.closed_opening_m)

    def finger_speed_to_rad_s(self, speed_m_s: float) -> float:
        return speed_m_s / self.pitch_radius_m

    def opening_rate_m_s(self, velocity_rad_s: float) -> float:
        """How fast the opening grows at this servo velocity (closing is positive rotation)."""
        return -2.0 * self.pitch_radius_m * velocity_rad_s
