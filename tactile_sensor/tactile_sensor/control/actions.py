"""What each gripper action means: goal -> controller, tick -> feedback and result fields.

The gripper node runs every action through one generic runner (one active goal, preemption,
cancel, hardware errors); the interfaces differ only in what this module holds:

* ``Grasp`` (target force, speed, timeout): close until the force; succeeds on contact.
* ``Release`` (opening, 0 = fully open): open; succeeds when opened.
* ``control_msgs/GripperCommand`` (``command.position`` [m], ``command.max_effort`` [N]):
  a move with a tactile force limit (control/move.py); succeeds when the goal is reached,
  or when it stalls (force limit or current limit) and ``allow_stalling`` is true.
* ``control_msgs/ParallelGripperCommand`` (``command``: a JointState of our one joint):
  the same move, reported as a JointState.

Conventions of the control_msgs interfaces: position is the **opening** between the skins
[m], as in ``~/joint_states`` and the URDF; velocity is the opening's rate [m/s] (twice a
finger's speed); effort is the **tactile force** the module measures [N], not motor effort.

Force ceiling: a grasp target, and a move's ``max_effort``, may not exceed
``max_grasp_force`` nor reach the band below the tactile sensor's full scale where readings
saturate (``SATURATION_BAND``; the driver latches the full scale, and until then the
parameter alone applies). There the target may never be seen reached while the fingers
squeeze on: a 6.7 N grasp on the mock read 6.5-6.67 N while the true force rose to 27.9 N
(of a 6.77 N full scale). ``accept`` refuses such a goal in one sentence naming both limits.

Goals are plain objects read by attribute (the ROS goal messages, or anything shaped like
them), and results are dicts of message fields (nested dicts for nested messages): no ROS
import here, so the semantics are tested without ROS. ``accept`` raises InvalidRequest with
one sentence before anything moves.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Any

from tactile_sensor.control.back_off import SATURATION_BAND, BackOff
from tactile_sensor.control.errors import InvalidConfiguration, InvalidRequest
from tactile_sensor.control.geometry import GripperGeometry
from tactile_sensor.control.grasp import (
    BaseController,
    GraspConfig,
    GraspController,
    GraspRequest,
    Outcome,
    ReleaseController,
    ServoReading,
    Step,
)
from tactile_sensor.control.hold import ForceSettler
from tactile_sensor.control.move import MoveController, MoveRequest
from tactile_sensor.control.slip_hold import HoldSettings, SlipHold, SlipHoldConfig

Fields = dict[str, Any]


@dataclass(frozen=True)
class GoalSettings:
    """The node's parameters that goals read (SI units)."""

    config: GraspConfig
    joint_name: str = "finger_opening"
    #: Finger speed of a grasp or a closing move that names none [m/s].
    closing_speed_m_s: float = 0.01
    #: Finger speed of a release or an opening move that names none [m/s].
    opening_speed_m_s: float = 0.02
    timeout_s: float = 10.0
    #: A move within this of its target has reached it [m].
    goal_tolerance_m: float = 0.0005
    #: A move at rest short of its target this long has stalled [s].
    stall_time_s: float = 0.2
    #: A stalled move (force limit or current limit) succeeds (ros2_controllers' meaning).
    allow_stalling: bool = True
    skin_stiffness_n_per_m: float = 2500.0
    #: The most a grasp target or a move's max_effort may ask [N] (``max_grasp_force``).
    max_grasp_force_n: float = 10.0
    #: The tactile sensor's full-scale force [N] as the driver latched it; None until then.
    full_scale_force_n: float | None = None
    #: The hold a goal gets when it asks for none (``hold_mode``, ``hold_time``, ...).
    hold: HoldSettings = field(default_factory=HoldSettings)
    #: The control loop's rate, at which the adaptive hold filters the forces [Hz].
    control_rate_hz: float = 100.0

    def with_full_scale(self, force_n: float) -> GoalSettings:
        """These settings once the driver stated its full scale; InvalidRequest (one
        sentence) for a value no calibration can have."""
        if not (math.isfinite(force_n) and force_n > 0):
            raise InvalidRequest(f"The driver's full-scale force {force_n} N is not a positive "
                                 "number; check its calibration (the gripper keeps "
                                 "max_grasp_force alone as the ceiling).")
        return replace(self, full_scale_force_n=float(force_n))

    @property
    def saturates_from_n(self) -> float | None:
        """Where the tactile readings may be saturated [N]; None while unknown."""
        full = self.full_scale_force_n
        return None if full is None else (1.0 - SATURATION_BAND) * full

    @property
    def force_ceiling_n(self) -> float:
        """The most a goal may ask [N]: max_grasp_force, below the saturation band."""
        saturates = self.saturates_from_n
        return self.max_grasp_force_n if saturates is None else min(
            self.max_grasp_force_n, saturates)

    def check_force(self, what: str, force_n: float) -> None:
        """Refuse a requested force above the ceiling, naming both of its limits."""
        limit, saturates, ceiling = (self.max_grasp_force_n, self.saturates_from_n,
                                     self.force_ceiling_n)
        if force_n <= ceiling:
            return
        if saturates is None:
            raise InvalidRequest(
                f"{what} {force_n:g} N is above max_grasp_force {limit:g} N (the tactile "
                f"sensor's full scale is not known yet); request at most {limit:g} N.")
        raise InvalidRequest(
            f"{what} {force_n:g} N is above the gripper's force ceiling of {ceiling:.3g} N "
            f"(the smaller of max_grasp_force {limit:g} N and {saturates:.3g} N, from where "
            f"the tactile sensor's readings saturate below its {self.full_scale_force_n:.3g}"
            f" N full scale); request at most {ceiling:.3g} N.")


def settings_from_parameters(values: dict[str, Any]) -> GoalSettings:
    """The gripper node's parameter values (named as declared) -> what goals read; raises
    InvalidConfiguration (or ValueError from the geometry) naming the bad parameter."""
    if values["closing_current"] > values["current_limit"]:
        raise InvalidConfiguration(
            f"Parameter 'closing_current' = {values['closing_current']} A exceeds "
            f"'current_limit' = {values['current_limit']} A; lower it.")
    geometry = GripperGeometry(pitch_radius_m=values["geometry.pitch_radius"],
                               open_opening_m=values["geometry.open_opening"],
                               closed_opening_m=values["geometry.closed_opening"])
    config = GraspConfig(geometry=geometry, closing_current_a=values["closing_current"],
                         hold_current_a=values["closing_current"],
                         stale_after_s=values["tactile_timeout"],
                         skin_stiffness_n_per_m=values["skin_stiffness"])
    return GoalSettings(
        config=config, joint_name=values["joint_name"],
        closing_speed_m_s=values["default_closing_speed"],
        opening_speed_m_s=values["release_speed"], timeout_s=values["default_timeout"],
        goal_tolerance_m=values["goal_tolerance"], stall_time_s=values["stall_timeout"],
        allow_stalling=values["allow_stalling"],
        skin_stiffness_n_per_m=values["skin_stiffness"],
        max_grasp_force_n=values["max_grasp_force"],
        hold=HoldSettings(values["hold_mode"], values["hold_time"], values["shear_sensing"],
                          values["slip_bandwidth"]),
        control_rate_hz=values["control_rate"])


@dataclass(frozen=True)
class Snapshot:
    """What feedback and results report: the controller's step and the latest readings."""

    step: Step
    #: Latest tactile force [N]; nan before the first.
    force_n: float
    #: Rate of change of the opening [m/s].
    velocity_m_s: float

    @property
    def opening_m(self) -> float:
        return self.step.opening_m


class ActiveGoal:
    """One accepted goal: its controller, and how its feedback and result read."""

    #: How long an adaptive hold runs (0: until a cancel or a newer goal) [s].
    hold_time_s = 0.0
    #: The adaptive hold once it runs.
    hold: SlipHold | None = None

    def __init__(self, settings: GoalSettings, controller: BaseController) -> None:
        self.settings = settings
        self.controller = controller

    def start(self, now_s: float, servo: ServoReading) -> Step:
        raise NotImplementedError

    def tick(self, now_s: float, force_n: float | None, force_stamp_s: float | None,
             servo: ServoReading) -> Step:
        raise NotImplementedError

    def cancel(self, now_s: float, servo: ServoReading) -> Step:
        return self.controller.cancel(now_s, servo)

    def settler(self, step: Step) -> ForceSettler | None:
        """A force regulation to run after ``step`` finished, or None."""
        del step
        return None

    def slip_hold(self, held_n: float | None, servo: ServoReading | None,
                  closing_lead_rad: float | None = None) -> SlipHold | None:
        """The adaptive hold to run after the settle (None: the fixed hold alone), with
        the position loop's lead the settle saw at rest after a close."""
        del held_n, servo, closing_lead_rad
        return None

    def back_off(self, full_scale_force_n: float | None) -> BackOff | None:
        """How an aborted goal backs off a force above its target, given the sensor's full
        scale as known now (None: the goal has no force target)."""
        del full_scale_force_n
        return None

    def succeeded(self, step: Step) -> bool:
        return step.outcome is not None and step.outcome.succeeded

    def failure(self, step: Step) -> str | None:
        """Why a finished step does not succeed (None when it does)."""
        return None if self.succeeded(step) else f"{step.outcome}: {step.message}"

    def feedback(self, snap: Snapshot) -> Fields:
        raise NotImplementedError

    def result(self, snap: Snapshot, message: str) -> Fields:
        raise NotImplementedError


class TactileGoal(ActiveGoal):
    """A goal that closes until a tactile force (Grasp, and the moves): after
    ``settle_after`` the force is regulated onto ``target_force_n``."""

    settle_after: Outcome

    def __init__(self, settings: GoalSettings, controller: GraspController | MoveController,
                 request: GraspRequest | MoveRequest, target_force_n: float,
                 adaptive: bool = False, hold_time_s: float = 0.0) -> None:
        super().__init__(settings, controller)
        self.request, self.target_force_n = request, target_force_n
        self.adaptive, self.hold_time_s = adaptive, hold_time_s
        self.controller: GraspController | MoveController = controller

    def start(self, now_s: float, servo: ServoReading) -> Step:
        return self.controller.start(self.request, now_s, servo)  # type: ignore[arg-type]

    def tick(self, now_s: float, force_n: float | None, force_stamp_s: float | None,
             servo: ServoReading) -> Step:
        return self.controller.tick(now_s, force_n, force_stamp_s, servo)

    def settler(self, step: Step) -> ForceSettler | None:
        if step.outcome is not self.settle_after:
            return None
        return ForceSettler(self.settings.config.geometry, self.target_force_n,
                            loop=getattr(self.controller, "free_loop", None))

    def slip_hold(self, held_n: float | None, servo: ServoReading | None,
                  closing_lead_rad: float | None = None) -> SlipHold | None:
        if not self.adaptive or servo is None:
            return None
        s, geometry = self.settings, self.settings.config.geometry
        config = SlipHoldConfig(
            s.hold.noise, ceiling_n=s.force_ceiling_n,
            newton_per_rad=s.skin_stiffness_n_per_m * geometry.pitch_radius_m,
            closed_position_rad=geometry.closed_position_rad,
            bandwidth_hz=s.hold.bandwidth_hz, control_rate_hz=s.control_rate_hz)
        self.hold = SlipHold(config, held_n or self.target_force_n, servo.position_rad,
                             closing_lead_rad or 0.0)
        return self.hold

    def back_off(self, full_scale_force_n: float | None) -> BackOff | None:
        if self.target_force_n <= 0:
            return None  # a position-only move: no force was asked for
        s = self.settings
        # an adaptive hold may have raised the grip to keep the object: back off only
        # above the ceiling it never passes
        target = s.force_ceiling_n if self.adaptive else self.target_force_n
        return BackOff(s.config.geometry, target, full_scale_force_n,
                       s.config.geometry.finger_speed_to_rad_s(s.closing_speed_m_s),
                       s.config.hold_current_a, s.config.stop_velocity_rad_s)


class GraspGoal(TactileGoal):
    settle_after = Outcome.CONTACT

    def __init__(self, settings: GoalSettings, request: GraspRequest, adaptive: bool = False,
                 hold_time_s: float = 0.0) -> None:
        super().__init__(settings, GraspController(settings.config), request,
                         request.target_force_n, adaptive, hold_time_s)

    def feedback(self, snap: Snapshot) -> Fields:
        margin = self.hold.last_margin_n if self.hold is not None else math.nan
        return {"force": snap.force_n, "opening": snap.opening_m, "slip_margin": margin}

    def result(self, snap: Snapshot, message: str) -> Fields:
        friction = self.hold.friction if self.hold is not None else None
        return {"contact_detected": snap.step.outcome in (Outcome.CONTACT, Outcome.SLIPPING),
                "force": snap.force_n, "opening": snap.opening_m, "message": message,
                "friction": math.nan if friction is None else friction}


class ReleaseGoal(ActiveGoal):
    def __init__(self, settings: GoalSettings, opening_m: float) -> None:
        self.release = ReleaseController(settings.config)
        super().__init__(settings, self.release)
        self.opening_m = opening_m
        self.release.check(opening_m, settings.opening_speed_m_s, settings.timeout_s)

    def start(self, now_s: float, servo: ServoReading) -> Step:
        s = self.settings
        return self.release.start(self.opening_m, s.opening_speed_m_s, s.timeout_s, now_s,
                                  servo)

    def tick(self, now_s: float, force_n: float | None, force_stamp_s: float | None,
             servo: ServoReading) -> Step:
        return self.release.tick(now_s, servo)

    def feedback(self, snap: Snapshot) -> Fields:
        return {"opening": snap.opening_m}

    def result(self, snap: Snapshot, message: str) -> Fields:
        return {"opening": snap.opening_m, "success": snap.step.outcome is Outcome.OPENED,
                "message": message}


_STALLS = (Outcome.FORCE_LIMIT, Outcome.STALLED)


class MoveGoal(TactileGoal):
    """GripperCommand's meaning; ParallelGripperCommand reports the same as a JointState."""

    settle_after = Outcome.FORCE_LIMIT

    def __init__(self, settings: GoalSettings, request: MoveRequest) -> None:
        controller = MoveController(settings.config)
        request.validate(settings.config, controller.max_speed_m_s)
        if request.max_effort_n > 0:
            settings.check_force("Effort limit", request.max_effort_n)
        super().__init__(settings, controller, request, request.max_effort_n,
                         settings.hold.mode == "adaptive" and request.max_effort_n > 0,
                         settings.hold.hold_time_s)
        self.request: MoveRequest = request

    def succeeded(self, step: Step) -> bool:
        if step.outcome in _STALLS:
            return self.settings.allow_stalling
        return step.outcome is Outcome.REACHED

    def failure(self, step: Step) -> str | None:
        if step.outcome in _STALLS and not self.settings.allow_stalling:
            return f"{step.outcome}: {step.message} (allow_stalling is false)"
        return super().failure(step)

    def flags(self, snap: Snapshot) -> Fields:
        return {"stalled": snap.step.outcome in _STALLS,
                "reached_goal": snap.step.outcome is Outcome.REACHED}

    def feedback(self, snap: Snapshot) -> Fields:
        return self.result(snap, "")

    def result(self, snap: Snapshot, message: str) -> Fields:
        del message  # control_msgs results carry none: the node logs it
        return {"position": snap.opening_m, "effort": snap.force_n, **self.flags(snap)}


class ParallelMoveGoal(MoveGoal):
    def feedback(self, snap: Snapshot) -> Fields:
        return {"state": self.state(snap)}

    def result(self, snap: Snapshot, message: str) -> Fields:
        del message
        return {"state": self.state(snap), **self.flags(snap)}

    def state(self, snap: Snapshot) -> Fields:
        """Our one joint as a JointState: opening [m], its rate [m/s], tactile force [N]."""
        return {"name": [self.settings.joint_name], "position": [snap.opening_m],
                "velocity": [snap.velocity_m_s], "effort": [snap.force_n]}


# -- goal messages -> active goals ------------------------------------------------------------


def accept_grasp(goal: Any, settings: GoalSettings) -> GraspGoal:
    """``Grasp``: 0 speed or timeout, '' hold mode and 0 hold time mean the node's
    default."""
    mode, hold_time_s = settings.hold.resolve(getattr(goal, "hold_mode", ""),
                                              getattr(goal, "hold_time", 0.0))
    request = GraspRequest(target_force_n=goal.target_force,
                           speed_m_s=goal.closing_speed or settings.closing_speed_m_s,
                           timeout_s=goal.timeout or settings.timeout_s)
    request.validate(GraspController(settings.config).max_speed_m_s)
    settings.check_force("Grasp target force", request.target_force_n)
    return GraspGoal(settings, request, mode == "adaptive", hold_time_s)


def accept_release(goal: Any, settings: GoalSettings) -> ReleaseGoal:
    """``Release``: opening 0 means fully open."""
    return ReleaseGoal(settings, goal.opening or settings.config.geometry.open_opening_m)


def _move(settings: GoalSettings, opening_m: float, max_effort_n: float,
          speed_m_s: float | None) -> MoveRequest:
    """A move request; ``speed_m_s`` None = the node's closing or opening speed."""
    return MoveRequest(opening_m=opening_m, max_effort_n=max_effort_n,
                       closing_speed_m_s=speed_m_s or settings.closing_speed_m_s,
                       opening_speed_m_s=speed_m_s or settings.opening_speed_m_s,
                       timeout_s=settings.timeout_s, tolerance_m=settings.goal_tolerance_m,
                       stall_time_s=settings.stall_time_s)


def accept_gripper_command(goal: Any, settings: GoalSettings) -> MoveGoal:
    """``control_msgs/GripperCommand``: ``command.position`` is the opening [m],
    ``command.max_effort`` the tactile force limit [N] (0 = none)."""
    command = goal.command
    return MoveGoal(settings, _move(settings, float(command.position),
                                    float(command.max_effort), None))


def accept_parallel_gripper_command(goal: Any, settings: GoalSettings) -> ParallelMoveGoal:
    """``control_msgs/ParallelGripperCommand``: a JointState naming our one joint;
    ``position[0]`` the opening [m], optional ``velocity[0]`` the opening's speed limit
    [m/s], optional ``effort[0]`` the tactile force limit [N]."""
    command, joint = goal.command, settings.joint_name
    names = list(command.name)
    if names != [joint]:
        raise InvalidRequest(f"The goal is for joint(s) {names}, but this gripper's joint is "
                             f"'{joint}'; name it in command.name.")

    def one(field: str, values: Any, required: bool) -> float | None:
        values = list(values)
        if len(values) > 1 or (required and not values):
            raise InvalidRequest(f"command.{field} has {len(values)} values; give "
                                 f"{'exactly' if required else 'at most'} one for '{joint}'.")
        return float(values[0]) if values else None

    opening = one("position", command.position, True)
    velocity = one("velocity", command.velocity, False)
    effort = one("effort", command.effort, False)
    assert opening is not None
    if velocity is not None and not (math.isfinite(velocity) and velocity >= 0):
        raise InvalidRequest(f"Velocity limit {velocity} m/s must be a positive number (or "
                             "0 / empty for the default speed).")
    speed = 0.5 * velocity if velocity else None  # the opening closes at twice finger speed
    return ParallelMoveGoal(settings, _move(settings, opening,
                                            0.0 if effort is None else effort, speed))

