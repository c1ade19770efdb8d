"""A position move with the measured tactile force as its effort limit (pure state machine).

What control_msgs' GripperCommand and ParallelGripperCommand ask of a gripper: go to an
opening; stop early when the effort reaches ``max_effort``. Our effort is the contact force
the tactile module measures on the fingertip [N], not the motor's current: a closing move
stops at the force the object actually feels, whatever the friction in the rack.

* Closing with ``max_effort_n > 0``: the fingers close at the requested speed with
  ``closing_current_a``; from ``slowdown_from_fraction`` of the limit the speed falls in
  proportion to the force still missing (as in a grasp); at the limit the servo holds where
  it is (outcome ``force_limit``). A tactile force older than ``stale_after_s`` aborts
  (``tactile_stale``): a force limit that cannot be seen is no limit.
* ``max_effort_n == 0``, and every opening move: position only. The tactile force never
  stops an opening move (it falls as the fingers open).
* Arrived within ``tolerance_m`` and not moving: ``reached_goal``. At rest short of the goal
  for ``stall_time_s`` (the current limit holds the fingers against the object, as
  ros2_controllers' gripper controllers detect a stall from velocity): ``stalled``, holding.

The same loop as grasp.py: ``start`` then ``tick`` each control period; send ``step.command``
when not None; stop at ``step.finished``; ``cancel`` stops the fingers where they are.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from tactile_sensor.control.errors import InvalidRequest
from tactile_sensor.control.grasp import (
    BaseController,
    GraspConfig,
    Outcome,
    Phase,
    ServoCommand,
    ServoReading,
    Step,
    hardware_error_detail,
    profile_arrived,
    slowed_speed,
)
from tactile_sensor.control.tactile_force import stale_detail


@dataclass(frozen=True)
class MoveRequest:
    #: Target opening between the skins [m] (the joint state's and the URDF's convention).
    opening_m: float
    #: Tactile force limit [N]; 0 = none (position only, under the current limit).
    max_effort_n: float
    #: Each finger's linear speed when the move closes / opens the fingers [m/s].
    closing_speed_m_s: float
    opening_speed_m_s: float
    timeout_s: float
    #: Within this of the target counts as reached [m].
    tolerance_m: float = 0.0005
    #: At rest short of the target this long counts as stalled [s].
    stall_time_s: float = 0.2

    def validate(self, config: GraspConfig, max_speed_m_s: float) -> None:
        """Raise InvalidRequest with one sentence naming the bad field and the fix."""
        g = config.geometry
        if not math.isfinite(self.opening_m):
            raise InvalidRequest(f"Target position {self.opening_m} is not a number; "
                                 "request an opening in metres.")
        if not g.closed_opening_m <= self.opening_m <= g.open_opening_m:
            raise InvalidRequest(
                f"Target position {self.opening_m} m is outside the travel "
                f"[{g.closed_opening_m}, {g.open_opening_m}] m (closed, open); request an "
                "opening inside it.")
        if not math.isfinite(self.max_effort_n):
            raise InvalidRequest(f"Effort limit {self.max_effort_n} is not a number; "
                                 "request a tactile force in newtons, or 0 for none.")
        if self.max_effort_n < 0:
            raise InvalidRequest(f"Effort limit {self.max_effort_n} N is negative; request "
                                 "a tactile force in newtons, or 0 for none.")
        for speed in (self.closing_speed_m_s, self.opening_speed_m_s):
            if not (math.isfinite(speed) and 0 < speed <= max_speed_m_s):
                raise InvalidRequest(f"Finger speed {speed} m/s must be in "
                                     f"(0, {max_speed_m_s:.3f}] m/s; request a slower speed.")
        for name, value in (("timeout", self.timeout_s), ("tolerance", self.tolerance_m),
                            ("stall time", self.stall_time_s)):
            if not (math.isfinite(value) and value > 0):
                raise InvalidRequest(f"Move {name} {value} must be positive; fix the "
                                     "gripper configuration.")


class MoveController(BaseController):
    """Go to an opening; stop and hold at the tactile force limit or when stalled."""

    def __init__(self, config: GraspConfig | None = None) -> None:
        super().__init__(config or GraspConfig())
        self.request: MoveRequest | None = None
        self._limited = False
        self._full_rad_s = self._speed_rad_s = 0.0
        self._target_rad = 0.0
        self._resting_since: float | None = None
        #: The servo sample the last tick judged: a tick on the same sample (the control
        #: loop starved of its turn) learns nothing new about whether the fingers move.
        self._judged: ServoReading | None = None

    def start(self, request: MoveRequest, now_s: float, servo: ServoReading) -> Step:
        request.validate(self.config, self.max_speed_m_s)
        self.request = request
        self._started_s, self._timeout_s = now_s, request.timeout_s
        g = self.config.geometry
        closing = request.opening_m < self._opening(servo)
        self.phase = Phase.CLOSING if closing else Phase.OPENING
        self._limited = closing and request.max_effort_n > 0
        if servo.hardware_error:
            return self._finish(Outcome.HARDWARE_ERROR, hardware_error_detail(servo), servo)
        self._target_rad = g.position_rad(request.opening_m)
        speed = request.closing_speed_m_s if closing else request.opening_speed_m_s
        self._full_rad_s = self._speed_rad_s = g.finger_speed_to_rad_s(speed)
        return Step(self.phase, self._command(), None, self.phase.value, self._opening(servo))

    def _command(self) -> ServoCommand:
        return ServoCommand(self._target_rad, self._speed_rad_s, self.config.closing_current_a)

    def tick(self, now_s: float, force_n: float | None, force_stamp_s: float | None,
             servo: ServoReading) -> Step:
        if self.phase not in (Phase.CLOSING, Phase.OPENING) or self.request is None:
            return Step(self.phase, None, None, "not moving", self._opening(servo), force_n)
        request, opening = self.request, self._opening(servo)
        done = self._check_common(now_s, servo, force_n)
        if done is not None:
            return done
        command = None
        if self._limited:
            fresh = force_n is not None and force_stamp_s is not None
            age = now_s - (force_stamp_s if fresh else self._started_s)  # type: ignore[operator]
            if age > self.config.stale_after_s:
                return self._finish(Outcome.TACTILE_STALE,
                                    stale_detail(age, self.config.stale_after_s, fresh),
                                    servo, force_n)
            if fresh:
                assert force_n is not None
                if force_n >= request.max_effort_n:
                    return self._finish(Outcome.FORCE_LIMIT, f"limit {request.max_effort_n:g} N"
                                        f" reached at {force_n:.2f} N", servo, force_n,
                                        hold=True)
                speed = slowed_speed(self.config, self._full_rad_s, force_n,
                                     request.max_effort_n)
                if abs(speed - self._speed_rad_s) > (self.config.resend_speed_change
                                                     * self._speed_rad_s):
                    self._speed_rad_s = speed
                    command = self._command()
        if not servo.moving and profile_arrived(servo, self.config.geometry,
                                                request.opening_m, request.tolerance_m,
                                                self.config.closing_current_a):
            self.phase = Phase.DONE
            return Step(self.phase, None, Outcome.REACHED,
                        f"reached {opening * 1e3:.1f} mm", opening, force_n)
        fresh_sample, self._judged = servo is not self._judged, servo
        if servo.moving or command is not None:
            self._resting_since = None
        elif self._resting_since is None:
            self._resting_since = now_s
        elif now_s - self._resting_since >= request.stall_time_s and fresh_sample:
            return self._finish(Outcome.STALLED, f"stalled at {opening * 1e3:.1f} mm, "
                                f"{abs(opening - request.opening_m) * 1e3:.1f} mm short of "
                                "the goal", servo, force_n, hold=True)
        return Step(self.phase, command, None, self.phase.value, opening, force_n)
