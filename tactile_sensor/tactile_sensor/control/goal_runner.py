"""The one runner every gripper action shares: start, tick at the control rate, finish.

Goal policy: one goal is active; a newer goal of any kind preempts the running one (it ends
aborted with the slot's reason, PREEMPTED unless the node gave another),
so a manipulation stack can always release what it holds without canceling first; cancel
stops the fingers where they are; a servo hardware error aborts with the decoded reason.
A goal that ends without success backs off a force above its target (control/back_off.py)
before it answers, so no abort leaves the fingers pressing harder than the goal asked.

Readiness: a goal that acts on the tactile force (a grasp, a move with an effort limit) and
arrives before the forces flow (the driver not started, not yet active, or late under load)
waits for a fresh force, up to the tactile timeout, before its first command; the fingers do
not move meanwhile, and without one it aborts ``tactile_stale`` saying none came. Under load
a goal whose control loop gets no servo sample for the tactile timeout stops the fingers and
aborts ``interrupted`` saying so, instead of commanding on where they were.

Every result message is ``<outcome>: <detail>`` with an ``Outcome`` value as the outcome,
and a message that states the force at the end states the result's ``force`` field.

No ROS here: the node adapts a goal handle to a ``GoalLink`` (its token, whether a cancel
was requested, how feedback is published), turns the returned ``Finish`` into succeed /
abort / canceled and a result message, and the controllers' meaning stays in
control/actions.py.
"""

from __future__ import annotations

import contextlib
import math
import threading
import time
from collections.abc import Callable
from contextlib import AbstractContextManager
from dataclasses import dataclass, replace
from enum import StrEnum

from tactile_sensor.control.actions import ActiveGoal, Fields, Snapshot
from tactile_sensor.control.back_off import BackOff
from tactile_sensor.control.errors import ControlError
from tactile_sensor.control.grasp import Outcome, Phase, ServoCommand, Step
from tactile_sensor.control.hold import ForceSettler
from tactile_sensor.control.servo_link import ServoLink
from tactile_sensor.control.slip_hold import SlipEvent, SlipHold
from tactile_sensor.control.tactile_force import TactileForce, no_first_force_detail
from tactile_sensor.hardware.errors import DynamixelError, ServoHardwareError
from tactile_sensor.hardware.xm430 import ServoState

PREEMPTED = f"{Outcome.PREEMPTED}: a newer goal took over the fingers"
REBOOTING = f"{Outcome.INTERRUPTED}: the servo is being rebooted"
REBOOTED = (f"{Outcome.INTERRUPTED}: the servo was rebooted while this goal ran, and the "
            "reboot's hold replaced its command; send the goal again")
NOT_ACTIVE = f"{Outcome.INACTIVE}: the gripper is not active"
CANCELED = f"{Outcome.CANCELED}: stopped where the fingers were"


def interrupted(reason: str) -> str:
    """The message of a goal ended by the node itself (deactivation, shutdown)."""
    return f"{Outcome.INTERRUPTED}: {reason}"


class GoalSlot:
    """Which goal owns the fingers, and why a goal that lost them ends."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._active: object | None = None
        self.abort_reason = PREEMPTED

    def take_over(self, token: object) -> None:
        self._hand_over(token, PREEMPTED)

    def superseded(self, token: object) -> bool:
        with self._lock:
            return self._active is not token

    def abort_active(self, reason: str) -> None:
        """End whatever runs (deactivation, reboot) with ``reason``."""
        self._hand_over(None, reason)

    def _hand_over(self, token: object | None, reason: str) -> None:
        """The fingers to ``token`` (None: to nobody); the goal that had them ends with
        ``reason``."""
        with self._lock:
            self._active = token
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
class FirstInput:
    """An input a goal waits for before it moves (readiness): whether the newest is fresh,
    whether any came, and its name, topic and source for the refusal's sentence."""

    fresh: Callable[[], bool]
    heard: Callable[[], bool]
    named: tuple[str, str, str] = ("tactile force", "tactile_wrench", "~/wrench")


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
                 on_slip: Callable[[SlipEvent], None] = lambda event: None,
                 busy: Callable[[], AbstractContextManager[object]] = contextlib.nullcontext,
                 wall_clock: Callable[[], float] = time.time,
                 clock: Callable[[], float] = time.monotonic) -> None:
        """``busy()`` is held while a goal runs: the node's control loop samples at the
        control rate inside it (control/servo_sampler.py) and idles outside."""
        self.servo, self.forces, self.slot, self.timing = servo, forces, slot, timing
        self._on_hardware_error, self._log_error = on_hardware_error, log_error
        self._on_slip, self._busy = on_slip, busy
        self._wall, self._clock = wall_clock, clock

    def snapshot(self, step: Step, force_n: float | None = None) -> Snapshot:
        """The goal's state now; ``force_n`` replaces the newest tactile force (a settled
        hold reports the mean it settled on)."""
        force, state = self.forces.latest, self.servo.state
        geometry = self.servo.config.geometry
        velocity = (geometry.opening_rate_m_s(state.velocity_rad_s)
                    if state is not None else math.nan)
        if force_n is None:
            force_n = force[0] if force else math.nan
        return Snapshot(step, force_n, velocity)

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

    def _owner(self, token: object) -> Callable[[], bool]:
        """Whether ``token``'s goal still has the fingers, asked as its command is written."""
        return lambda: not self.slot.superseded(token)

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

    def run(self, link: GoalLink, accept: Callable[[], ActiveGoal],
            first_input: FirstInput | None = None) -> Finish:
        """Take the fingers over, accept the goal (``accept`` raises ControlError when it
        is invalid) and run it to its end. ``first_input``: what the goal waits for before
        it moves, instead of the tactile force (the self-check: the module output)."""
        self.slot.take_over(link.token)
        with self._busy():
            return self._run(link, accept, first_input)

    def _run(self, link: GoalLink, accept: Callable[[], ActiveGoal],
             first_input: FirstInput | None) -> Finish:
        if self.servo.state is None:
            return self._finish(None, None, False, NOT_ACTIVE)
        goal: ActiveGoal | None = None
        try:
            goal = accept()
            waited = self._await_first_input(link, goal, first_input)
            if waited is not None:
                return waited
            step = self._start(link, goal)
        except ControlError as exc:
            return self._finish(goal, None, False, f"{Outcome.INVALID_GOAL}: {exc}")
        except ServoHardwareError as exc:
            return self._finish(goal, None, False, f"{Outcome.HARDWARE_ERROR}: "
                                + ", ".join(sorted(exc.bits)))
        except DynamixelError as exc:
            return self._finish(goal, None, False, f"{Outcome.SERVO_UNREACHABLE}: {exc}")
        driven = self._drive(link, goal, step)
        if isinstance(driven, Finish):
            return driven
        return self._conclude(link, goal, driven)

    def _await_first_input(self, link: GoalLink, goal: ActiveGoal,
                           first_input: FirstInput | None) -> Finish | None:
        """Before a goal that acts on the tactile force moves anything: wait for a fresh
        force, up to the tactile timeout (readiness; docs/gripper.md). None once one came
        (or the goal needs none); else how the goal ends, the fingers where they were."""
        stale_after = self.servo.config.stale_after_s
        if first_input is None:
            if goal.back_off(self.forces.full_scale_n) is None:
                return None  # no force target: a release, a position-only move
            first_input = FirstInput(
                lambda: self._wall() - self.forces.latest[1] <= stale_after,  # type: ignore[index]
                lambda: self.forces.latest is not None)
        started = self._clock()
        while True:
            heard = first_input.heard()
            if heard and first_input.fresh():
                return None
            if link.cancel_requested():
                return self._finish(goal, None, GoalStatus.CANCELED, CANCELED)
            if self.slot.superseded(link.token):
                return self._finish(goal, None, False, self.slot.abort_reason)
            waited = self._clock() - started
            if waited > stale_after:
                return self._finish(goal, None, False, f"{Outcome.TACTILE_STALE}: "
                                    + no_first_force_detail(waited, stale_after, heard,
                                                            *first_input.named))
            self.servo.await_sample(2 * self.timing.control_period_s)

    def _starved(self, link: GoalLink, goal: ActiveGoal) -> Finish | None:
        """A goal whose control loop has had no servo sample for the tactile timeout (a
        starved machine) stops the fingers there and says so; None while samples come."""
        age, bound = self.servo.sample_age_s(), self.servo.config.stale_after_s
        if age <= bound:
            return None
        self._stop_logged(link.token)
        step = goal.cancel(self._wall(), self.servo.state)
        step, tail = self._safe_end(link, goal, step)
        return self._finish(
            goal, step, False,
            f"{Outcome.INTERRUPTED}: the control loop got no servo sample for {age:.3f} s "
            f"(tactile_timeout {bound:g} s; the machine is too busy for control_rate "
            f"{1.0 / self.timing.control_period_s:g} Hz), so the fingers were stopped "
            "where they were", tail)

    def _start(self, link: GoalLink, goal: ActiveGoal) -> Step:
        """The goal's first command sent, on a servo without a latched hardware error."""
        servo = self.servo
        if servo.hardware_error:
            raise ServoHardwareError(", ".join(sorted(servo.hardware_error)),
                                     servo.hardware_error)
        servo.ensure_torque()
        step = goal.start(self._wall(), servo.state)
        servo.send(step.command, link.token)
        return step

    def _drive(self, link: GoalLink, goal: ActiveGoal, step: Step) -> Step | Finish:
        """Tick the goal at the control rate until its step is finished (that step), or
        until a cancel, a newer goal or the servo ends it (the Finish)."""
        servo, token = self.servo, link.token
        period = self.timing.control_period_s
        last_feedback = 0.0
        while not step.finished:
            if link.cancel_requested():
                return self._canceled(link, goal)
            if self.slot.superseded(token):
                # no stop command: the newer goal (or the reboot) owns the servo now
                return self._finish(goal, goal.cancel(self._wall(), servo.state), False,
                                    self.slot.abort_reason)
            servo.await_sample(2 * period)
            if servo.comm_error:
                return self._finish(goal, step, False,
                                    f"{Outcome.SERVO_UNREACHABLE}: {servo.comm_error}")
            if (starved := self._starved(link, goal)) is not None:
                return starved
            force = self.forces.latest
            step = goal.tick(self._wall(), force[0] if force else None,
                             force[1] if force else None, servo.state)
            if (error := servo.send_safely(step.command, token, self._owner(token))) is not None:
                return self._finish(goal, step, False, f"{Outcome.SERVO_UNREACHABLE}: {error}")
            now = self._clock()
            if now - last_feedback >= self.timing.feedback_period_s:
                self._feedback(link, goal, step)
                last_feedback = now
        return step

    def _conclude(self, link: GoalLink, goal: ActiveGoal, step: Step) -> Finish:
        """After the goal's last tick: settle the force it holds, if it holds one, and back
        off a force above its target if it failed."""
        servo, token = self.servo, link.token
        tail, held_n = "", None
        settler = goal.settler(step)
        if settler is not None:
            aborted, settled = self._settle(link, settler, step,
                                            lambda s: self._feedback(link, goal, s))
            if aborted is not None:
                return self._finish(goal, step, False, aborted)
            if link.cancel_requested() and not self.slot.superseded(token):
                return self._canceled(link, goal)
            step = self._at_rest(link, step)
            held_n = settler.judged_n  # the pooled mean, settled or not: not one reading
            # a hold that ran out of settle_time says so: its force may be off the target
            tail = (", settled at {force:.2f} N" if settled else
                    f", not settled within settle_time ({self.timing.settle_time_s:g} s): "
                    "holding {force:.2f} N")
            hold = None
            if not settled and self._reads_full_scale(goal):
                # the target lies beyond what the sensor reads (a goal accepted before the
                # driver stated its range): the true force may be anything above it
                tail = tail.format(force=self.snapshot(step).force_n)
                step, backed_off = self._safe_end(link, goal, step)
                tail += " at the sensor's full scale" + backed_off
            else:
                hold = goal.slip_hold(held_n, servo.state, settler.closing_lead_rad)
            if hold is not None:
                tail = tail.format(force=self.snapshot(step, held_n).force_n)
                ended = self._adaptive(link, goal, hold, step)
                if isinstance(ended, Finish):
                    return ended
                tail, held_n = tail + ended, None
        if step.outcome is Outcome.HARDWARE_ERROR and servo.state is not None:
            self._on_hardware_error(servo.state.hardware_error)
        failure = goal.failure(step)
        if failure is not None:
            step, backed_off = self._safe_end(link, goal, step)
            tail += backed_off
        self.slot.release(token)
        return self._finish(goal, step, failure is None,
                            failure or f"{step.outcome}: {step.message}", tail,
                            held_n if failure is None else None)

    def _finish(self, goal: ActiveGoal | None, step: Step | None, status: GoalStatus | bool,
                message: str, tail: str = "", force_n: float | None = None) -> Finish:
        """``tail`` ends the message with the result's force: ``{force}`` in it is
        formatted with the very value the result's field carries (``force_n`` when given,
        else the newest tactile force)."""
        if isinstance(status, bool):
            status = GoalStatus.SUCCEEDED if status else GoalStatus.ABORTED
        if goal is None:
            return Finish(status, message, None)
        if step is None:  # never started: report where the fingers are
            state = self.servo.state
            opening = (self.servo.config.geometry.opening_m(state.position_rad)
                       if state is not None else math.nan)
            step = Step(Phase.IDLE, None, None, message, opening)
        snap = self.snapshot(step, force_n)
        message += tail.format(force=snap.force_n)
        return Finish(status, message, goal.result(snap, message))

    def _canceled(self, link: GoalLink, goal: ActiveGoal) -> Finish:
        step = goal.cancel(self._wall(), self.servo.state)
        if self.servo.stop_written is not link.token:  # the cancel callback's stop failed
            self._stop_logged(link.token)
        step, tail = self._safe_end(link, goal, step)
        return self._finish(goal, step, GoalStatus.CANCELED, CANCELED, tail)

    def _feedback(self, link: GoalLink, goal: ActiveGoal, step: Step) -> None:
        link.publish_feedback(goal.feedback(self.snapshot(step)))

    def _reads_full_scale(self, goal: ActiveGoal) -> bool:
        back_off, latest = goal.back_off(self.forces.full_scale_n), self.forces.latest
        return back_off is not None and latest is not None and back_off.saturated(latest[0])

    def _safe_end(self, link: GoalLink, goal: ActiveGoal, step: Step) -> tuple[Step, str]:
        """Back off a force above the goal's target after it ended without success (no
        hardware error: torque is off; no stale force: nothing to judge by); the step with
        the opening where the fingers stay, and the message's tail ("" when nothing was
        done)."""
        servo, latest = self.servo, self.forces.latest
        back_off = goal.back_off(self.forces.full_scale_n)
        state = servo.state
        if (back_off is None or latest is None or state is None or servo.comm_error
                or state.hardware_error
                or step.outcome in (Outcome.HARDWARE_ERROR, Outcome.TACTILE_STALE)
                or not back_off.needed(latest[0]) or self.slot.superseded(link.token)):
            return step, ""
        start_force = latest[0]
        end = self._back_off(link, back_off, state)
        state = servo.state
        if state is not None:
            step = replace(step, opening_m=servo.config.geometry.opening_m(state.position_rad))
        return step, (f"; backed off from {start_force:.2f} N to {{force:.2f}} N" + end)

    def _back_off(self, link: GoalLink, back_off: BackOff, state: ServoState) -> str:
        """Open until the forces stamped after the start are safe, then hold; "" when it
        got there, else why it stopped short (appended to the message)."""
        servo, period = self.servo, self.timing.control_period_s
        # its own token: a cancel's stop of the goal must not block the back-off's commands
        mover = object()
        started_wall, started = self._wall(), self._clock()
        self.forces.count_after(started_wall)
        deadline = started + back_off.time_bound_s(state) + 1.0
        sent_at = last_fresh = started
        owns = self._owner(link.token)
        if servo.send_safely(back_off.opening_command(), mover, owns) is not None:
            return f" (stopped: servo unreachable: {servo.comm_error})"
        while True:
            if self.slot.superseded(link.token):
                return " (a newer goal took over)"
            servo.await_sample(2 * period)
            state_now = servo.state
            if servo.comm_error or state_now is None or state_now.hardware_error:
                return " (stopped: the servo failed)"
            now, mean = self._clock(), self.forces.mean_since_last_call()
            if mean is not None:
                last_fresh = now
                hold = back_off.tick(mean, state_now)
                if hold is not None:
                    servo.send_safely(hold, mover, owns)
                    self._await_rest()
                    return ""
            if now - last_fresh > servo.config.stale_after_s or now > deadline:
                servo.send_safely(back_off.hold(state_now), mover, owns)
                self._await_rest()
                return (" (stopped: no fresh tactile force)" if now <= deadline
                        else " (stopped: fully open)")
            if not state_now.moving and now - sent_at > 3 * period:
                # a cancel's stop halted the opening: resume it
                servo.send_safely(back_off.opening_command(), mover, owns)
                sent_at = now

    def _await_rest(self) -> None:
        """Until the servo's Moving flag clears after a hold (at most the settle time)."""
        deadline = self._clock() + self.timing.settle_time_s
        while self._clock() < deadline:
            self.servo.await_sample(2 * self.timing.control_period_s)
            state = self.servo.state
            if state is None or state.hardware_error or not state.moving:
                return

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

    def _adaptive(self, link: GoalLink, goal: ActiveGoal, hold: SlipHold,
                  step: Step) -> Finish | str:
        """Run the slip-aware hold for the goal's hold time (0: until a cancel or a newer
        goal); the message's tail when it ran out, else how the goal ends."""
        aborted, slipping = self._hold_adaptive(link, goal, hold, step)
        if aborted is not None:
            return self._finish(goal, step, False, aborted)
        if slipping is not None:
            self.slot.release(link.token)
            return self._finish(goal, replace(step, outcome=Outcome.SLIPPING), False,
                                f"{Outcome.SLIPPING}: {slipping}")
        if self.slot.superseded(link.token):
            return self._finish(goal, goal.cancel(self._wall(), self.servo.state), False,
                                self.slot.abort_reason)
        if link.cancel_requested():
            return self._canceled(link, goal)
        learned = ("friction not learned (no load to probe)" if hold.friction is None
                   else f"friction {hold.friction:.2f}")
        return (f"; adaptive hold for {goal.hold_time_s:g} s ({learned}): holding "
                "{force:.2f} N")

    def _hold_adaptive(self, link: GoalLink, goal: ActiveGoal, hold: SlipHold,
                       step: Step) -> tuple[str | None, str | None]:
        """(an abort reason or None, the slipping sentence or None); both None when the
        hold time ran out, a cancel came or a newer goal took the fingers over."""
        servo, config, period = self.servo, self.servo.config, self.timing.control_period_s
        start = last_fresh = last_feedback = self._clock()
        self.forces.wrench_means_since_last_call()  # what came before the hold
        while goal.hold_time_s <= 0 or self._clock() - start < goal.hold_time_s:
            if link.cancel_requested() or self.slot.superseded(link.token):
                return None, None
            servo.await_sample(2 * period)
            state, now = servo.state, self._clock()
            if servo.comm_error:
                return f"{Outcome.SERVO_UNREACHABLE}: {servo.comm_error}", None
            if state is None:
                return None, None
            if state.hardware_error:
                self._on_hardware_error(state.hardware_error)
                return (f"{Outcome.HARDWARE_ERROR}: " + ", ".join(sorted(state.hardware_error)),
                        None)
            means = self.forces.wrench_means_since_last_call()
            if means is None:
                if now - last_fresh > config.stale_after_s:
                    return (f"{Outcome.TACTILE_STALE}: no tactile force for "
                            f"{now - last_fresh:.3f} s while holding", None)
                continue
            last_fresh = now
            held = hold.update(now, *means, state.position_rad, state.moving)
            if held.goal_rad is not None:
                command = ServoCommand(held.goal_rad, config.stop_velocity_rad_s,
                                       config.hold_current_a)
                if (error := servo.send_safely(command, link.token,
                                               self._owner(link.token))) is not None:
                    return f"{Outcome.SERVO_UNREACHABLE}: {error}", None
            if held.event is not None:
                self._on_slip(held.event)
            if held.slipping is not None:
                return None, held.slipping
            if now - last_feedback >= self.timing.feedback_period_s:
                self._feedback(link, goal, step)
                last_feedback = now
        return None, None

    def _settle(self, link: GoalLink, settler: ForceSettler, step: Step,
                feedback: Callable[[Step], None]) -> tuple[str | None, bool]:
        """Regulate the force onto the target: (an abort reason or None, settled?).

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
                return None, False  # the fingers hold where they are; the caller finishes
            servo.await_sample(2 * period)
            state = servo.state
            if servo.comm_error:
                return f"{Outcome.SERVO_UNREACHABLE}: {servo.comm_error}", False
            if state is None:
                return None, False
            if state.hardware_error:  # torque is off: the grasp holds nothing any more
                self._on_hardware_error(state.hardware_error)
                return (f"{Outcome.HARDWARE_ERROR}: " + ", ".join(sorted(state.hardware_error)),
                        False)
            if effective_s is not None:
                if self._clock() < effective_s or state.moving:
                    continue
                self.forces.count_after(self._wall())
                effective_s = None
            settler.add(*self.forces.sum_since_last_call(), self._clock())
            command, settled = settler.command(self._clock(), state, config.hold_current_a,
                                               config.stop_velocity_rad_s)
            if settled:
                return None, True
            if command is None:
                continue
            if (error := servo.send_safely(command, link.token,
                                           self._owner(link.token))) is not None:
                return f"{Outcome.SERVO_UNREACHABLE}: {error}", False
            travel_s = abs(command.goal_position_rad - state.position_rad) / max(
                command.profile_velocity_rad_s, 1e-9)
            effective_s = self._clock() + travel_s + period
            feedback(step)
        return None, False
