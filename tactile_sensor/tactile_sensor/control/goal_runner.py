"""The one runner every gripper action shares: start, tick at the control rate, finish.

Goal policy: one goal is active; a newer goal of any kind preempts the running one (it ends
aborted with the slot's reason, "preempted by a newer goal" unless the node gave another),
so a manipulation stack can always release what it holds without canceling first; cancel
stops the fingers where they are; a servo hardware error aborts with the decoded reason.

No ROS here: the node adapts a goal handle to a ``GoalLink`` (its token, whether a cancel
was requested, how feedback is published), turns the returned ``Finish`` into succeed /
abort / canceled and a result message, and the controllers' meaning stays in
control/actions.py.
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, replace
from enum import StrEnum

from tactile_sensor.control.actions import ActiveGoal, Fields, Snapshot
from tactile_sensor.control.errors import ControlError
from tactile_sensor.control.grasp import ForceSettler, Outcome, Phase, Step
from tactile_sensor.control.servo_link import ServoLink
from tactile_sensor.control.tactile_force import TactileForce
from tactile_sensor.hardware.errors import DynamixelError, ServoHardwareError

PREEMPTED = "preempted by a newer goal"
REBOOTING = "the servo is being rebooted"
REBOOTED = ("the servo was rebooted while this goal ran, and the reboot's hold replaced its "
            "command; send the goal again")


class GoalSlot:
    """Which goal owns the fingers, and why a goal that lost them ends."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._active: object | None = None
        self.abort_reason = PREEMPTED

    def take_over(self, token: object) -> None:
        with self._lock:
            self._active = token
            self.abort_reason = PREEMPTED

    def superseded(self, token: object) -> bool:
        with self._lock:
            return self._active is not token

    def abort_active(self, reason: str) -> None:
        """End whatever runs (deactivation, reboot) with ``reason``."""
        with self._lock:
            self._active = None
            self.abort_reason = reason

    def release(self, token: object) -> None:
        """``token``'s goal finished by itself: the slot is free, unless taken meanwhile."""
        with self._lock:
            if self._active is token:
                self._active = None


@dataclass(frozen=True)
class GoalLink:
    """One goal as the runner sees its ROS handle."""

    #: Identifies the goal to the slot and to a cancel's stop (the node: the goal handle).
    token: object
    cancel_requested: Callable[[], bool]
    publish_feedback: Callable[[Fields], None]


class GoalStatus(StrEnum):
    SUCCEEDED = "succeeded"
    ABORTED = "aborted"
    CANCELED = "canceled"


@dataclass(frozen=True)
class Finish:
    status: GoalStatus
    message: str
    #: The result's fields; None when the goal was never accepted (an empty result).
    result: Fields | None


@dataclass(frozen=True)
class RunnerTiming:
    control_period_s: float
    feedback_period_s: float
    #: After contact, regulate the force for at most this long [s].
    settle_time_s: float


class GoalRunner:
    """Runs one goal at a time on a ``ServoLink``, reading a ``TactileForce``."""

    def __init__(self, servo: ServoLink, forces: TactileForce, slot: GoalSlot,
                 timing: RunnerTiming, *,
                 on_hardware_error: Callable[[frozenset[str]], None],
                 log_error: Callable[[str], None],
                 wall_clock: Callable[[], float] = time.time,
                 clock: Callable[[], float] = time.monotonic) -> None:
        self.servo, self.forces, self.slot, self.timing = servo, forces, slot, timing
        self._on_hardware_error, self._log_error = on_hardware_error, log_error
        self._wall, self._clock = wall_clock, clock

    def snapshot(self, step: Step) -> Snapshot:
        force, state = self.forces.latest, self.servo.state
        geometry = self.servo.config.geometry
        velocity = (geometry.opening_rate_m_s(state.velocity_rad_s)
                    if state is not None else math.nan)
        return Snapshot(step, force[0] if force else math.nan, velocity)

    def reboot(self, current_limit_a: float) -> None:
        """Reboot the servo (clears a latched hardware error) and hold where the fingers
        are. The goal running when it starts ends aborted, and so does one started while it
        runs: the reboot's hold overwrites its command, and it would wait for a move that
        never comes (a release once ran into its 10 s timeout that way). Raises the
        servo's DynamixelError."""
        self.slot.abort_active(REBOOTING)
        try:
            self.servo.reboot(current_limit_a)
        finally:
            self.slot.abort_active(REBOOTED)

    def stop(self, token: object) -> None:
        """A cancel's stop, unless the goal lost the fingers already; failures are logged."""
        if self.slot.superseded(token):
            return
        self._stop_logged(token)

    def _stop_logged(self, token: object) -> None:
        try:
            self.servo.stop(token)
        except (DynamixelError, ControlError) as exc:
            self._log_error(f"stop on cancel failed: {exc}")

    def run(self, link: GoalLink, accept: Callable[[], ActiveGoal]) -> Finish:
        """Take the fingers over, accept the goal (``accept`` raises ControlError when it
        is invalid) and run it to its end."""
        servo, token = self.servo, link.token
        self.slot.take_over(token)
        goal: ActiveGoal | None = None

        def finish(step: Step | None, succeeded: bool, message: str) -> Finish:
            status = GoalStatus.SUCCEEDED if succeeded else GoalStatus.ABORTED
            if goal is None:
                return Finish(status, message, None)
            if step is None:  # never started: report where the fingers are
                state = servo.state
                opening = (servo.config.geometry.opening_m(state.position_rad)
                           if state is not None else math.nan)
                step = Step(Phase.IDLE, None, None, message, opening)
            return Finish(status, message, goal.result(self.snapshot(step), message))

        if servo.state is None:
            return finish(None, False, "the gripper is not active")
        try:
            goal = accept()
            if servo.hardware_error:
                raise ServoHardwareError("servo hardware error: "
                                         + ", ".join(sorted(servo.hardware_error)),
                                         servo.hardware_error)
            servo.ensure_torque()
            step = goal.start(self._wall(), servo.state)
            servo.send(step.command, token)
        except (ControlError, DynamixelError) as exc:
            return finish(None, False, str(exc))

        def feedback(step: Step) -> None:
            assert goal is not None
            link.publish_feedback(goal.feedback(self.snapshot(step)))

        period = self.timing.control_period_s
        last_feedback = 0.0
        while not step.finished:
            if link.cancel_requested():
                step = goal.cancel(self._wall(), servo.state)
                if servo.stop_written is not token:  # the cancel callback's stop failed
                    self._stop_logged(token)
                message = "canceled: stopped where the fingers were"
                return Finish(GoalStatus.CANCELED, message,
                              goal.result(self.snapshot(step), message))
            if self.slot.superseded(token):
                # no stop command: the newer goal (or the reboot) owns the servo now
                return finish(goal.cancel(self._wall(), servo.state), False,
                              self.slot.abort_reason)
            servo.await_sample(2 * period)
            if servo.comm_error:
                return finish(step, False, f"servo unreachable: {servo.comm_error}")
            force = self.forces.latest
            step = goal.tick(self._wall(), force[0] if force else None,
                             force[1] if force else None, servo.state)
            if (error := servo.send_safely(step.command, token)) is not None:
                return finish(step, False, f"servo unreachable: {error}")
            now = self._clock()
            if now - last_feedback >= self.timing.feedback_period_s:
                feedback(step)
                last_feedback = now
        settler = goal.settler(step)
        if settler is not None:
            aborted = self._settle(link, settler, step, feedback)
            if aborted is not None:
                return finish(step, False, aborted)
            step = self._at_rest(link, step)
        if step.outcome is Outcome.HARDWARE_ERROR and servo.state is not None:
            self._on_hardware_error(servo.state.hardware_error)
        self.slot.release(token)
        failure = goal.failure(step)
        return finish(step, failure is None, failure or f"{step.outcome}: {step.message}")

    def _at_rest(self, link: GoalLink, step: Step) -> Step:
        """``step`` with the opening the fingers hold once they stop (the servo's Moving
        flag; waited for at most the settle time): the settle's last correction may still
        be under way when it ends, and the answer is to give where the fingers stay (under
        CPU load a late correction once moved them 1.07 mm after the answer)."""
        deadline = self._clock() + self.timing.settle_time_s
        while self._clock() < deadline:
            if link.cancel_requested() or self.slot.superseded(link.token):
                break
            state = self.servo.state
            if state is None or state.hardware_error or not state.moving:
                break
            self.servo.await_sample(2 * self.timing.control_period_s)
        state = self.servo.state
        if state is None:
            return step
        return replace(step, opening_m=self.servo.config.geometry.opening_m(state.position_rad))

    def _settle(self, link: GoalLink, settler: ForceSettler, step: Step,
                feedback: Callable[[Step], None]) -> str | None:
        """Regulate the force onto the target; an abort reason, or None when done.

        Each correction is judged on forces stamped after the fingers stopped from it (the
        servo's Moving flag, and no earlier than its travel time): under CPU load the
        tactile force arrives tens of ms late, and correcting on it again would wind the
        loop up (30 ms late once held 13 N on a 2 N target)."""
        servo, config = self.servo, self.servo.config
        deadline = self._clock() + self.timing.settle_time_s
        period = self.timing.control_period_s
        effective_s: float | None = self._clock()  # the closing's stop: judged like a move
        while self._clock() < deadline:
            if link.cancel_requested() or self.slot.superseded(link.token):
                return None  # the fingers hold where they are; the caller finishes
            servo.await_sample(2 * period)
            state = servo.state
            if servo.comm_error:
                return f"servo unreachable: {servo.comm_error}"
            if state is None or state.hardware_error:
                return None
            if effective_s is not None:
                if self._clock() < effective_s or state.moving:
                    continue
                self.forces.count_after(self._wall())
                effective_s = None
            force = self.forces.mean_since_last_call()
            if force is None:
                continue
            command, settled = settler.command(force, state, config.hold_current_a,
                                               config.stop_velocity_rad_s)
            if settled:
                return None
            if command is None:
                continue
            if (error := servo.send_safely(command, link.token)) is not None:
                return f"servo unreachable: {error}"
            travel_s = abs(command.goal_position_rad - state.position_rad) / max(
                command.profile_velocity_rad_s, 1e-9)
            effective_s = self._clock() + travel_s + period
            feedback(step)
        return None
