"""The safe end of a goal that aborts: never leave the fingers pressing harder than asked.

A goal that ends without success (timeout, cancel, a stall that does not count as success)
stops the fingers where they are, and whatever they press then stays. When the tactile force
there is above the goal's target, or at the sensor's full scale (where the true force is
unknown: the mock world held 27.9 N while the sensor read its 6.77 N full scale), the fingers
open at ``speed_rad_s`` until the tactile force is at or below the target and below the
full scale, then hold where they are. "At the full scale" is within ``SATURATION_BAND`` of
it: the tare's offset and the noise keep a saturated reading below the curve's top, and the
curve is steep there (on the mock gripper, 27.9 N and 9.5 N true force both read 6.5-6.77 N,
single readings down to 6.4 N). So the force judged is the mean of the readings of one
control period, all stamped after the back-off began, and it must be safe for
``confirm_ticks`` periods in a row: one noisy reading once stopped a back-off at 9.5 N.

Opening continuously and stopping at the crossing needs no skin stiffness and works on a
saturated reading, where a force error says nothing about the distance to go. The sensing
delay (10-30 ms under load) lets the fingers travel 0.1-0.3 mm past the crossing at 10 mm/s,
about 0.25-0.75 N on the FEM skin: below the target, the safe side. A hardware error turns
the torque off and leaves nothing to command (docs/gripper.md lists each outcome's end).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from tactile_sensor.control.errors import InvalidRequest
from tactile_sensor.control.geometry import GripperGeometry
from tactile_sensor.control.grasp import ServoCommand, ServoReading

#: A reading within this fraction below the full scale counts as saturated.
SATURATION_BAND = 0.10


@dataclass
class BackOff:
    """When to back off, where to, and when to stop (pure: the runner drives it)."""

    geometry: GripperGeometry
    #: The goal's target force [N] (a grasp's target, a move's max_effort).
    target_force_n: float
    #: The sensor's full-scale force [N]; None while the driver has not stated it.
    full_scale_force_n: float | None
    #: Servo speed while opening [rad/s].
    speed_rad_s: float
    #: Goal current while opening and holding [A].
    current_a: float
    #: Profile velocity of the final hold (a fast profile: the stop is immediate) [rad/s].
    stop_velocity_rad_s: float
    #: Control periods in a row the mean force must be safe before the fingers hold.
    confirm_ticks: int = 3
    _safe: int = 0

    def __post_init__(self) -> None:
        if not (math.isfinite(self.target_force_n) and self.target_force_n > 0):
            raise InvalidRequest(f"BackOff target {self.target_force_n} N must be positive; "
                                 "a goal without a force target has nothing to back off to.")
        for name in ("speed_rad_s", "current_a", "stop_velocity_rad_s"):
            if not getattr(self, name) > 0:
                raise InvalidRequest(f"BackOff.{name} must be positive; fix the gripper "
                                     "configuration.")

    def saturated(self, force_n: float) -> bool:
        """The reading is at the full scale: the true force may be anything above it."""
        full = self.full_scale_force_n
        return full is not None and force_n >= (1.0 - SATURATION_BAND) * full

    def needed(self, force_n: float | None) -> bool:
        """Whether the fingers press harder than the target (or cannot tell)."""
        if force_n is None or not math.isfinite(force_n):
            return False  # no force to judge by: hold (a stale force aborts the goal itself)
        return force_n > self.target_force_n or self.saturated(force_n)

    def opening_command(self) -> ServoCommand:
        """Open toward the open limit (the tick stops the fingers at the crossing)."""
        return ServoCommand(self.geometry.open_position_rad, self.speed_rad_s, self.current_a)

    def tick(self, mean_force_n: float, servo: ServoReading) -> ServoCommand | None:
        """The hold that ends the back-off once the period's mean force has been safe for
        ``confirm_ticks`` periods in a row; None: keep opening."""
        if self.needed(mean_force_n):
            self._safe = 0
            return None
        self._safe += 1
        return self.hold(servo) if self._safe >= self.confirm_ticks else None

    def hold(self, servo: ServoReading) -> ServoCommand:
        """Stay where the fingers are."""
        return ServoCommand(servo.position_rad, self.stop_velocity_rad_s, self.current_a,
                            hold_present=True)

    def time_bound_s(self, servo: ServoReading) -> float:
        """Time to open fully from here at the back-off speed [s]: after it, the fingers
        are at the open limit and press nothing."""
        travel = abs(servo.position_rad - self.geometry.open_position_rad)
        return travel / self.speed_rad_s
