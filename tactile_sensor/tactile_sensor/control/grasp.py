"""Grasp and release as pure state machines: inputs each tick, servo commands out.

No I/O and no clock of their own, so the same logic runs in the ROS gripper node, in the
benchmark and under hypothesis. The caller owns the loop:

1. put the servo in current-based position mode with torque on;
2. ``step = controller.start(request, now_s, servo_state)`` and send ``step.command``;
3. every tick: read the servo, take the latest tactile force and its stamp, call
   ``controller.tick(...)``, send ``step.command`` when it is not None, stop when
   ``step.finished``; ``cancel()`` at any time stops the fingers where they are.

Grasp: close at the requested finger speed (mapped to Profile Velocity through the pinion's
pitch radius) toward the closed limit on a leash (each tick's goal ``leash_s`` of travel
ahead) with ``closing_current_a`` as the torque budget; no faster than would build the
missing force in ``approach_time_s``; stop where the force will reach the target, counted
from the force's own stamp (control/guarded_contact.py), and hold there with
``hold_current_a``; the hold itself is control/hold.py's. Abort with a reason on timeout, on
reaching the closed limit without contact, on a hardware error, or when the tactile force
goes stale.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from enum import StrEnum
from typing import Protocol

from tactile_sensor.control.errors import InvalidRequest
from tactile_sensor.control.geometry import GripperGeometry
from tactile_sensor.control.guarded_contact import PositionTrace, force_ahead_n, stop_goal_rad
from tactile_sensor.control.tactile_force import stale_detail


class Outcome(StrEnum):
    """Why a goal finished: every result message starts with one of these and ": " (the
    stable prefix a manipulation stack may parse; listed in docs/gripper.md)."""

    CONTACT = "contact"
    OPENED = "opened"
    TIMEOUT = "timeout"
    CLOSED_LIMIT_WITHOUT_CONTACT = "closed_limit_without_contact"
    HARDWARE_ERROR = "hardware_error"
    TACTILE_STALE = "tactile_stale"
    CANCELED = "canceled"
    #: A position move (control/move.py) stopped by its tactile force limit.
    FORCE_LIMIT = "force_limit"
    #: A position move arrived within the goal tolerance.
    REACHED = "reached_goal"
    #: A position move came to rest short of its goal (the current limit holds it there).
    STALLED = "stalled"
    #: An adaptive hold (control/slip_hold.py) whose force ceiling cannot keep the object.
    SLIPPING = "slipping"
    #: Ends the runner decides rather than a controller (control/goal_runner.py).
    PREEMPTED = "preempted"
    INTERRUPTED = "interrupted"
    SERVO_UNREACHABLE = "servo_unreachable"
    INVALID_GOAL = "invalid_goal"
    INACTIVE = "inactive"

    @property
    def succeeded(self) -> bool:
        return self in (Outcome.CONTACT, Outcome.OPENED, Outcome.REACHED)


class Phase(StrEnum):
    IDLE = "idle"
    CLOSING = "closing"
    OPENING = "opening"
    HOLDING = "holding"
    ABORTED = "aborted"
    DONE = "done"


class ServoReading(Protocol):
    """What the controllers need from a servo sample (hardware.xm430.ServoState fits)."""

    @property
    def position_rad(self) -> float: ...

    @property
    def moving(self) -> bool: ...

    @property
    def hardware_error(self) -> frozenset[str]: ...


@dataclass(frozen=True)
class ServoCommand:
    """Write Goal Current, Profile Velocity and Goal Position (one transaction)."""

    goal_position_rad: float
    profile_velocity_rad_s: float
    goal_current_a: float
    #: Hold where the output is when the write lands, not at ``goal_position_rad`` (the
    #: sample the controller judged, which the fingers may have moved on from by then):
    #: the link carries its freshest sample forward (control/servo_link.py).
    hold_present: bool = False


@dataclass(frozen=True)
class Step:
    """The controller's answer to one input."""

    phase: Phase
    command: ServoCommand | None
    outcome: Outcome | None
    message: str
    opening_m: float
    force_n: float | None = None

    @property
    def finished(self) -> bool:
        return self.outcome is not None


@dataclass(frozen=True)
class GraspConfig:
    geometry: GripperGeometry = field(default_factory=GripperGeometry)
    #: Goal Current while closing: the most the fingers may push before contact [A].
    closing_current_a: float = 0.6
    #: Goal Current while holding the object [A].
    hold_current_a: float = 0.6
    #: A tactile force older than this aborts the grasp [s].
    stale_after_s: float = 0.1
    #: Start slowing down at this fraction of the target force (1 disables slowing).
    slowdown_from_fraction: float = 0.5
    #: Never slower than this fraction of the requested speed while closing.
    min_speed_fraction: float = 0.1
    #: Re-command the speed only when it changed by more than this fraction.
    resend_speed_change: float = 0.2
    #: Within this of the closed limit counts as "reached the limit" [m].
    limit_tolerance_m: float = 0.0005
    #: Within this of the requested opening counts as "opened" [m].
    open_tolerance_m: float = 0.0005
    #: Speed used to stop and hold (a fast profile so the stop is immediate) [rad/s].
    stop_velocity_rad_s: float = 6.0
    #: Fingertip skin stiffness the contact stop and the hold assume [N/m] (FEM: 1750 N/m
    #: at touch to 2850 N/m at 3 mm).
    skin_stiffness_n_per_m: float = 2500.0
    #: From a tick's decision to the servo moving on it: one control period, the bus and
    #: the servo's own cycle [s] (docs/gripper.md, "Latency budget").
    command_latency_s: float = 0.012
    #: A force this far over the noise counts as contact when predicting ahead: 2 σ of the
    #: paper's resolution (0.186 N after a 9-point mean at 1 kHz) [N].
    contact_noise_margin_n: float = 0.37
    #: Closing pauses (holds where it is) while the newest force is older than this: a
    #: guarded move does not move blind [s].
    pause_after_s: float = 0.06
    #: Each closing command reaches this much travel ahead of the fingers, renewed every
    #: tick [s of travel at the present speed].
    leash_s: float = 0.05
    #: In contact a grasp closes no faster than would build the missing force in this
    #: time: four times the 12 ms command latency, so a late stop adds at most a quarter of
    #: what is missing [s].
    approach_time_s: float = 0.05

    def __post_init__(self) -> None:
        for name in ("closing_current_a", "hold_current_a", "stale_after_s",
                     "min_speed_fraction", "stop_velocity_rad_s", "skin_stiffness_n_per_m"):
            if not getattr(self, name) > 0:
                raise InvalidRequest(f"GraspConfig.{name} must be positive; fix the "
                                     "gripper configuration.")
        if not (self.command_latency_s >= 0 and self.contact_noise_margin_n >= 0
                and self.pause_after_s > 0 and self.leash_s > 0
                and self.approach_time_s > 0):
            raise InvalidRequest("GraspConfig.command_latency_s and contact_noise_margin_n "
                                 "must be >= 0, pause_after_s, leash_s and approach_time_s "
                                 "> 0; fix the gripper configuration.")
        if not self.command_latency_s >= 0:
            raise InvalidRequest("GraspConfig.command_latency_s must be >= 0; fix the "
                                 "gripper configuration.")
        if not 0 < self.slowdown_from_fraction <= 1:
            raise InvalidRequest("GraspConfig.slowdown_from_fraction must be in (0, 1]; "
                                 "use 1 to disable slowing down.")


@dataclass(frozen=True)
class GraspRequest:
    target_force_n: float
    #: Linear speed of each finger while closing [m/s].
    speed_m_s: float
    timeout_s: float

    def validate(self, max_speed_m_s: float) -> None:
        if not (math.isfinite(self.target_force_n) and self.target_force_n > 0):
            raise InvalidRequest(f"Grasp target force {self.target_force_n} N must be "
                                 "positive; request e.g. 2 N.")
        if not (math.isfinite(self.speed_m_s) and 0 < self.speed_m_s <= max_speed_m_s):
            raise InvalidRequest(f"Grasp speed {self.speed_m_s} m/s must be in "
                                 f"(0, {max_speed_m_s:.3f}] m/s; request a slower speed.")
        if not (math.isfinite(self.timeout_s) and self.timeout_s > 0):
            raise InvalidRequest(f"Grasp timeout {self.timeout_s} s must be positive; "
                                 "request e.g. 10 s.")


def slowed_speed(config: GraspConfig, full_rad_s: float, force_n: float,
                 target_force_n: float) -> float:
    """The full speed, reduced in proportion to the force still missing to the target."""
    start = config.slowdown_from_fraction * target_force_n
    if force_n <= start or config.slowdown_from_fraction >= 1.0:
        return full_rad_s
    fraction = (target_force_n - force_n) / (target_force_n - start)
    return full_rad_s * max(config.min_speed_fraction, min(1.0, fraction))


def hardware_error_detail(servo: ServoReading) -> str:
    """The latched hardware-error bits, as the result's detail ("overload")."""
    return ", ".join(sorted(servo.hardware_error))


#: XM430-W210 no-load speed at 12 V (77 rpm) bounds the profile velocity [rad/s].
MAX_SERVO_SPEED_RAD_S = 77.0 * 2.0 * math.pi / 60.0


class BaseController:
    def __init__(self, config: GraspConfig) -> None:
        self.config = config
        self.phase = Phase.IDLE
        self._started_s = 0.0
        self._timeout_s = 0.0

    @property
    def max_speed_m_s(self) -> float:
        return MAX_SERVO_SPEED_RAD_S * self.config.geometry.pitch_radius_m

    def _opening(self, servo: ServoReading) -> float:
        return self.config.geometry.opening_m(servo.position_rad)

    def _stop_command(self, position_rad: float, current_a: float,
                      here: bool = False) -> ServoCommand:
        """A stop at ``position_rad``; ``here``: where the fingers are when it lands."""
        return ServoCommand(position_rad, self.config.stop_velocity_rad_s, current_a,
                            hold_present=here)

    @property
    def newton_per_rad(self) -> float:
        """Force change per radian of the pinion: each finger moves one pitch radius."""
        return self.config.skin_stiffness_n_per_m * self.config.geometry.pitch_radius_m

    def _finish(self, outcome: Outcome, message: str, servo: ServoReading,
                force_n: float | None = None, hold: bool = False,
                stop_at_rad: float | None = None) -> Step:
        """End with ``outcome``; the fingers stop at ``stop_at_rad`` (default: where the
        servo last was)."""
        self.phase = Phase.DONE if outcome.succeeded else Phase.ABORTED
        stop = servo.position_rad if stop_at_rad is None else stop_at_rad
        command = None if outcome is Outcome.HARDWARE_ERROR else self._stop_command(
            stop, self.config.hold_current_a if hold else self.config.closing_current_a,
            here=stop_at_rad is None)
        return Step(self.phase, command, outcome, message, self._opening(servo), force_n)

    def _check_common(self, now_s: float, servo: ServoReading,
                      force_n: float | None) -> Step | None:
        if servo.hardware_error:
            return self._finish(Outcome.HARDWARE_ERROR, hardware_error_detail(servo),
                                servo, force_n)
        if now_s - self._started_s > self._timeout_s:
            return self._finish(Outcome.TIMEOUT, f"no result within {self._timeout_s:g} s",
                                servo, force_n)
        return None

    def cancel(self, now_s: float, servo: ServoReading) -> Step:
        """Stop the fingers where they are."""
        del now_s
        if self.phase not in (Phase.CLOSING, Phase.OPENING):
            return Step(self.phase, None, None, "nothing to cancel", self._opening(servo))
        return self._finish(Outcome.CANCELED, "canceled", servo)


@dataclass(frozen=True)
class LoopLead:
    """The position loop seen while the fingers closed in free air: the profile's lead
    over the output [rad] and the current it drew [A]. Their ratio is the loop's gain
    (A/rad: Position P Gain's, measured rather than assumed), the lead the friction in
    motion needs."""

    lead_rad: float
    current_a: float

    def lead_for_n(self, rack_force_n: float, pitch_radius_m: float) -> float:
        """The lead [rad] over the free one that a rack force needs: its torque at the
        datasheet's torque constant over the loop's gain."""
        if not (self.lead_rad > 0 and self.current_a > 0):
            return 0.0
        gain_a_per_rad = self.current_a / self.lead_rad
        return (rack_force_n * pitch_radius_m / XM430_TORQUE_CONSTANT_NM_PER_A
                / gain_a_per_rad)

    def closing_edge_rad(self, rack_force_n: float, pitch_radius_m: float) -> float:
        """The lead at which the output, at rest under that rack force, moves closed: the
        free lead and the force's, which the gears' load-dependent friction raises by
        1 / (1 - ratio). The free lead is the friction in motion, under that at rest, so
        the estimate falls short of the edge by a pulse or two, never past it."""
        return self.lead_rad + self.lead_for_n(rack_force_n, pitch_radius_m) / (
            1.0 - XM430_LOAD_FRICTION_RATIO)


#: XM430-W210 at 12 V: stall torque 3.0 N m at 2.3 A (e-manual) [N m/A].
XM430_TORQUE_CONSTANT_NM_PER_A = 3.0 / 2.3
#: Friction at rest per N m the XM430's gears transmit: the sources' 0.234 (Dynamixel
#: MX-64, Duclusaud et al. 2024, model M4; sim/drivetrain.py). No close measures it
#: (control/self_check.py): it is the servo's constant, as its torque constant is.
XM430_LOAD_FRICTION_RATIO = 0.234


def profile_arrived(servo: ServoReading, geometry: GripperGeometry, opening_m: float,
                    tolerance_m: float, current_limit_a: float) -> bool:
    """The fingers within ``tolerance_m`` of an opening, or the servo's profile there with
    the output short of it by friction alone: a geared servo's output rests its loop's
    lead short of the goal (the friction over the P gain, ~0.9 mm of opening on the
    XM430's sources), drawing the current that friction needs, well under the limit an
    object it stalls on would take it to."""
    if abs(geometry.opening_m(servo.position_rad) - opening_m) <= tolerance_m:
        return True
    trajectory = getattr(servo, "trajectory_position_rad", None)
    current = getattr(servo, "current_a", None)
    return (isinstance(trajectory, float) and isinstance(current, float)
            and abs(geometry.opening_m(trajectory) - opening_m) <= tolerance_m
            and abs(current) < 0.9 * current_limit_a)


def loop_lead_rad(servo: ServoReading) -> float | None:
    """How far the servo's profile leads its output [rad] (None: the sample does not say):
    the position loop's error, which a geared servo's friction needs to turn the output."""
    trajectory = getattr(servo, "trajectory_position_rad", None)
    if not isinstance(trajectory, float):
        return None
    return trajectory - servo.position_rad


class GraspController(BaseController):
    """Close until the tactile force reaches the target, then hold.

    Through a geared servo's friction the output trails its profile by the position loop's
    error (about 17 encoder pulses on the XM430's sources: the torque offset and friction
    at 8 A/rad). The grasp learns that lead while closing in free air and puts it on every
    goal: the leash's end and the contact stop are where the output is to be, the goal
    that far ahead. The output then comes to rest a little short of the stop (the friction
    at rest exceeds that in motion), so the hold approaches the target from below."""

    def __init__(self, config: GraspConfig | None = None) -> None:
        super().__init__(config or GraspConfig())
        self.request: GraspRequest | None = None
        self._speed_rad_s = 0.0
        self._trace = PositionTrace()
        self._paused = False
        #: The loop's lead while closing in free air [rad] (0 until seen).
        self.lead_rad = 0.0
        #: That lead and the current it drew (None until seen): the hold's loop gain.
        self.free_loop: LoopLead | None = None

    def start(self, request: GraspRequest, now_s: float, servo: ServoReading) -> Step:
        request.validate(self.max_speed_m_s)
        self.request = request
        self._started_s, self._timeout_s = now_s, request.timeout_s
        self.phase = Phase.CLOSING
        if servo.hardware_error:
            return self._finish(Outcome.HARDWARE_ERROR, hardware_error_detail(servo), servo)
        self._speed_rad_s = self.config.geometry.finger_speed_to_rad_s(request.speed_m_s)
        return Step(self.phase, self._closing_command(servo.position_rad), None, "closing",
                    self._opening(servo))

    def _closing_command(self, position_rad: float, servo: ServoReading | None = None,
                         force_n: float = 0.0) -> ServoCommand:
        """Close on, at most ``leash_s`` of travel past ``position_rad``: a loop that stops
        ticking (a starved machine) leaves the fingers at the leash's end, not on the
        object at full current. Through a geared servo's friction the leash starts at the
        loop's lead: the free close's, and in contact the closing edge at the force felt;
        an output that rests anyway (the edge estimated short) is moved on from its
        profile, one leash a tick."""
        leash = self._speed_rad_s * self.config.leash_s
        lead = self.lead_rad
        if self.free_loop is not None and force_n > 0.0:
            lead = self.free_loop.closing_edge_rad(2.0 * force_n,
                                                   self.config.geometry.pitch_radius_m)
        start = position_rad + lead
        trajectory = getattr(servo, "trajectory_position_rad", None)
        if servo is not None and not servo.moving and isinstance(trajectory, float):
            start = max(start, trajectory)
        goal = min(self.config.geometry.closed_position_rad, start + leash)
        return ServoCommand(goal, self._speed_rad_s, self.config.closing_current_a)

    def tick(self, now_s: float, force_n: float | None, force_stamp_s: float | None,
             servo: ServoReading) -> Step:
        if self.phase is not Phase.CLOSING or self.request is None:
            return Step(self.phase, None, None, "not closing", self._opening(servo), force_n)
        cfg = self.config
        done = self._check_common(now_s, servo, force_n)
        if done is not None:
            return done
        self._trace.add(now_s, servo.position_rad)
        fresh = force_n is not None and force_stamp_s is not None
        age = now_s - (force_stamp_s if fresh else self._started_s)  # type: ignore[operator]
        if age > cfg.stale_after_s:
            return self._finish(Outcome.TACTILE_STALE,
                                stale_detail(age, cfg.stale_after_s, fresh), servo, force_n)
        if not fresh:
            return Step(self.phase, None, None, "waiting for tactile force",
                        self._opening(servo), force_n)
        assert force_n is not None and force_stamp_s is not None
        if age > cfg.pause_after_s:
            return self._pause(servo, force_n)
        lead = loop_lead_rad(servo)
        if (lead is not None and servo.moving and lead > 0.0
                and force_n < cfg.slowdown_from_fraction * self.request.target_force_n):
            # the least lead in motion: a sample taken as the output broke away from rest
            # carries the friction at rest, which a moving close does not need
            current = getattr(servo, "current_a", None)
            if isinstance(current, float) and (self.free_loop is None
                                               or lead < self.free_loop.lead_rad):
                self.free_loop = LoopLead(lead, current)
                self.lead_rad = lead
            elif not isinstance(current, float):
                self.lead_rad = lead
        stop = self._contact_stop(force_n, force_stamp_s, servo)
        if stop is not None:
            return self._finish(Outcome.CONTACT, f"contact at {force_n:.2f} N", servo,
                                force_n, hold=True, stop_at_rad=stop)
        opening = self._opening(servo)
        if self._at_closed_limit(servo):
            return self._finish(Outcome.CLOSED_LIMIT_WITHOUT_CONTACT,
                                f"closed to {opening * 1e3:.1f} mm",
                                servo, force_n)
        speed = self._scheduled_speed(force_n)
        if self._paused or abs(speed - self._speed_rad_s) > (cfg.resend_speed_change
                                                              * self._speed_rad_s):
            self._speed_rad_s, self._paused = speed, False
        # every tick moves the leash on
        return Step(self.phase, self._closing_command(servo.position_rad, servo,
                                                      max(force_n, 0.0)), None, "closing",
                    opening, force_n)

    def _at_closed_limit(self, servo: ServoReading) -> bool:
        """The fingers at the closed limit: there, or (through a geared servo's friction,
        which leaves the output its loop's lead short) at rest with the profile there and
        drawing less than an object it stalls on would take (``profile_arrived``)."""
        g, tolerance = self.config.geometry, self.config.limit_tolerance_m
        if self._opening(servo) <= g.closed_opening_m + tolerance:
            return True
        return not servo.moving and profile_arrived(
            servo, g, g.closed_opening_m, tolerance, self.config.closing_current_a)

    def _pause(self, servo: ServoReading, force_n: float) -> Step:
        """Hold where the fingers are until a fresh force comes (once per pause)."""
        command = None
        if not self._paused:
            self._paused = True
            command = self._stop_command(servo.position_rad, self.config.closing_current_a,
                                         here=True)
        return Step(self.phase, command, None, "paused: waiting for a fresh tactile force",
                    self._opening(servo), force_n)

    def _contact_stop(self, force_n: float, stamp_s: float,
                      servo: ServoReading) -> float | None:
        """Where to stop once the force will reach the target before a stop sent now takes
        effect (None: close on). Counted only in contact (from the slow-down on): in free
        air the travel since a force was sampled adds no force."""
        assert self.request is not None
        target = self.request.target_force_n
        lead = self._stop_lead_rad(target)
        if force_n >= target:
            at_force = self._trace.at(stamp_s)
            if self.free_loop is not None:
                # through a geared servo's friction a goal behind the output throws it
                # open past the band's far edge on one noisy reading: hold where it is
                # (the closing edge ahead of it) and let the hold take an excess off
                return lead + servo.position_rad
            return min(servo.position_rad, stop_goal_rad(force_n, at_force, target,
                                                         self.newton_per_rad))
        if force_n < self.config.slowdown_from_fraction * target:
            return None
        at_force = self._trace.at(stamp_s)
        # the noise margin: a force that is noise in free air predicts no rise
        ahead = force_ahead_n(force_n - self.config.contact_noise_margin_n, at_force,
                              servo.position_rad, self._speed_rad_s, self.newton_per_rad,
                              self.config.command_latency_s)
        if ahead < target:
            return None
        return lead + stop_goal_rad(force_n, at_force, target, self.newton_per_rad)

    def _stop_lead_rad(self, target_n: float) -> float:
        """How far ahead of where the output is to rest the stop's goal goes: the closing
        edge at the target's force (both fingers push it), or the free lead."""
        if self.free_loop is None:
            return self.lead_rad
        return self.free_loop.closing_edge_rad(2.0 * target_n,
                                               self.config.geometry.pitch_radius_m)

    def _scheduled_speed(self, force_n: float) -> float:
        """The requested speed, or slower: the speed at which the missing force would take
        ``approach_time_s`` to build up on the assumed skin. The same time for every target,
        so a 5 N grasp loads as fast as a 1 N one, and a 1 N one as gently."""
        assert self.request is not None
        cfg = self.config
        full = cfg.geometry.finger_speed_to_rad_s(self.request.speed_m_s)
        missing = self.request.target_force_n - force_n
        gentle = missing / (self.newton_per_rad * cfg.approach_time_s)
        return max(cfg.min_speed_fraction * full, min(full, gentle))


class ReleaseController(BaseController):
    """Open to a requested opening."""

    def __init__(self, config: GraspConfig | None = None) -> None:
        super().__init__(config or GraspConfig())
        self.target_opening_m = 0.0

    def start(self, opening_m: float, speed_m_s: float, timeout_s: float, now_s: float,
              servo: ServoReading) -> Step:
        self.check(opening_m, speed_m_s, timeout_s)
        g = self.config.geometry
        self.target_opening_m = opening_m
        self._started_s, self._timeout_s = now_s, timeout_s
        self.phase = Phase.OPENING
        if servo.hardware_error:
            return self._finish(Outcome.HARDWARE_ERROR, hardware_error_detail(servo), servo)
        command = ServoCommand(g.position_rad(opening_m), g.finger_speed_to_rad_s(speed_m_s),
                               self.config.closing_current_a)
        return Step(self.phase, command, None, "opening", self._opening(servo))

    def check(self, opening_m: float, speed_m_s: float, timeout_s: float) -> None:
        """Raise InvalidRequest unless the release can be executed as given."""
        g = self.config.geometry
        if not (math.isfinite(opening_m) and g.closed_opening_m <= opening_m
                <= g.open_opening_m):
            raise InvalidRequest(f"Release opening {opening_m} m is outside the travel "
                                 f"{g.closed_opening_m}..{g.open_opening_m} m; request one "
                                 "inside it.")
        if not (math.isfinite(speed_m_s) and 0 < speed_m_s <= self.max_speed_m_s):
            raise InvalidRequest(f"Release speed {speed_m_s} m/s must be in "
                                 f"(0, {self.max_speed_m_s:.3f}] m/s; request a slower speed.")
        if not (math.isfinite(timeout_s) and timeout_s > 0):
            raise InvalidRequest(f"Release timeout {timeout_s} s must be positive; request "
                                 "e.g. 10 s.")

    def tick(self, now_s: float, servo: ServoReading) -> Step:
        if self.phase is not Phase.OPENING:
            return Step(self.phase, None, None, "not opening", self._opening(servo))
        done = self._check_common(now_s, servo, None)
        if done is not None:
            return done
        opening = self._opening(servo)
        if not servo.moving and profile_arrived(servo, self.config.geometry,
                                                self.target_opening_m,
                                                self.config.open_tolerance_m,
                                                self.config.closing_current_a):
            self.phase = Phase.DONE
            return Step(self.phase, None, Outcome.OPENED, f"opened to {opening * 1e3:.1f} mm",
                        opening)
        return Step(self.phase, None, None, "opening", opening)
