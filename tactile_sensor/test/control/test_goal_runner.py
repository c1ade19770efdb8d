"""The runner every gripper action shares (control/goal_runner.py), without ROS: a
kinematic in-memory servo closing on a linear skin, sampled by a control-loop thread."""

from __future__ import annotations

import collections
import contextlib
import math
import re
import threading
import time
from dataclasses import replace
from types import SimpleNamespace

import pytest

from tactile_sensor.control.actions import (
    GoalSettings,
    accept_grasp,
    accept_gripper_command,
    accept_release,
)
from tactile_sensor.control.goal_runner import (
    PREEMPTED,
    REBOOTED,
    REBOOTING,
    FirstInput,
    GoalLink,
    GoalRunner,
    GoalSlot,
    GoalStatus,
    RunnerTiming,
    interrupted,
)
from tactile_sensor.control.grasp import GraspConfig, ServoCommand
from tactile_sensor.control.hold import ForceSettler
from tactile_sensor.control.servo_link import ServoLink
from tactile_sensor.control.slip_hold import HoldSettings
from tactile_sensor.control.tactile_force import TactileForce
from tactile_sensor.hardware.errors import CommunicationTimeout, PortLost
from tactile_sensor.hardware.xm430 import ServoState
from tactile_sensor.hardware.xm430_table import RAD_PER_PULSE

CONFIG = GraspConfig()
GEOMETRY = CONFIG.geometry
SETTINGS = GoalSettings(config=CONFIG)
#: Servo time each read advances [s] (the control period).
TICK_S = 0.002


class KinematicServo:
    """Moves at its profile velocity toward the goal, TICK_S per read; ``faults`` raise."""

    def __init__(self, opening_m: float = 0.040) -> None:
        self.position = GEOMETRY.position_rad(opening_m)
        self.goal, self.speed, self.velocity = self.position, 0.0, 0.0
        self.torque, self.bits = True, frozenset[str]()
        self.fail_reads: Exception | None = None
        self.fail_commands: list[Exception] = []
        self.commands: list[float] = []
        #: How many commands were sent when a read first reported error bits.
        self.commands_before_error: int | None = None
        self.reads = 0

    def now(self) -> float:
        """Servo time [s]: TICK_S per read, however late the reads come on a busy machine."""
        return self.reads * TICK_S

    def read_state(self) -> ServoState:
        self.reads += 1
        if self.fail_reads is not None:
            raise self.fail_reads
        if self.bits and self.commands_before_error is None:
            self.commands_before_error = len(self.commands)
        if self.torque and not self.bits:
            step = max(-self.speed * TICK_S, min(self.speed * TICK_S, self.goal - self.position))
            self.position += step
            self.velocity = step / TICK_S
        return ServoState(self.position, self.velocity, 0.2, 12.0, 30.0,
                          abs(self.velocity) > 1e-6, self.bits)

    def command_position(self, position_rad: float, velocity_rad_s: float,
                         acceleration_rad_s2: float = math.inf,
                         goal_current_a: float | None = None) -> None:
        if self.fail_commands:
            raise self.fail_commands.pop(0)
        self.goal, self.speed = position_rad, velocity_rad_s
        self.commands.append(position_rad)

    def set_torque(self, enabled: bool) -> None:
        self.torque = enabled

    def torque_enabled(self) -> bool:
        return self.torque

    def set_operating_mode(self, mode: object) -> None:
        pass

    def set_current_limit_a(self, amps: float) -> None:
        pass

    def reboot(self, wait_s: float = 2.0) -> None:
        self.bits = frozenset()


class Rig:
    """Servo, link, forces and runner, with a control-loop thread sampling the servo and a
    skin of ``stiffness`` N/m around a rod ``rod_m`` wide feeding the tactile force."""

    def __init__(self, rod_m: float = 0.030, stiffness: float = 2500.0,
                 settle_time_s: float = 0.5, force_delay_s: float = 0.0,
                 full_scale_n: float = math.inf) -> None:
        self.client = KinematicServo()
        # The runner's deadlines, and the tactile force's stamps, in the time the servo moves
        # in, not wall time: a busy machine that starves the rig's loop then slows the servo
        # and the sensor alike, as it cannot slow the real ones.
        clock = self._wall = self.client.now
        self.servo = ServoLink(self.client, CONFIG, period_s=TICK_S, retries=0, clock=clock)
        self.forces, self.slot = TactileForce(), GoalSlot()
        self.hardware_errors: list[frozenset[str]] = []
        self.errors: list[str] = []
        self.runner = GoalRunner(self.servo, self.forces, self.slot,
                                 RunnerTiming(TICK_S, TICK_S, settle_time_s),
                                 on_hardware_error=self.hardware_errors.append,
                                 log_error=self.errors.append, wall_clock=self._wall,
                                 clock=clock)
        self.rod_m, self.stiffness = rod_m, stiffness
        #: The sensor reads the true force up to this and saturates there [N].
        self.full_scale_n = full_scale_n
        #: The tactile force arrives this late [s], stamped when it was true (CPU load).
        self.force_delay_s = force_delay_s
        self._in_flight: collections.deque[tuple[float, float]] = collections.deque()
        #: Cleared, the tactile force stops arriving (the driver went silent).
        self.sensing = threading.Event()
        self.sensing.set()
        self.feedback: list[dict] = []
        self.cancel = threading.Event()
        self._running = True
        self._loop = threading.Thread(target=self._control_loop, daemon=True)

    def _control_loop(self) -> None:
        while self._running:
            poll = self.servo.poll()
            now = self._wall()
            if poll.state is not None:
                self._in_flight.append((now, min(self.true_force(poll.state.position_rad),
                                                 self.full_scale_n)))
            while self._in_flight and self._in_flight[0][0] <= now - self.force_delay_s:
                stamp, force = self._in_flight.popleft()
                if self.sensing.is_set():
                    self.forces.add(force, stamp)
            time.sleep(TICK_S)

    def true_force(self, position_rad: float) -> float:
        """Finger A's force: each finger's skin indents by half the gap closed on the rod
        (as in the gripper world)."""
        return self.stiffness * 0.5 * max(self.rod_m - GEOMETRY.opening_m(position_rad), 0.0)

    def __enter__(self) -> Rig:
        self.servo.poll()
        self._loop.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self._running = False
        self._loop.join()

    def link(self, token: object = "goal") -> GoalLink:
        return GoalLink(token, self.cancel.is_set, self.feedback.append)

    def run(self, accept, goal, token: object = "goal"):
        return self.runner.run(self.link(token), lambda: accept(goal, SETTINGS))


def grasp(force_n: float = 2.0, speed: float = 0.02, timeout: float = 5.0):
    return SimpleNamespace(target_force=force_n, closing_speed=speed, timeout=timeout)


def in_thread(call):
    out: dict = {}
    thread = threading.Thread(target=lambda: out.setdefault("end", call()), daemon=True)
    thread.start()
    return thread, out


def closing(rig: Rig):
    """A slow grasp that finds nothing, started in its own thread and past its first
    feedback (the closing loop runs)."""
    thread, out = in_thread(lambda: rig.run(accept_grasp, grasp(speed=0.005)))
    while not rig.feedback:
        assert thread.is_alive(), out
        rig.servo.await_sample(1.0)
    return thread, out


def test_a_grasp_closes_to_contact_settles_and_reports():
    with Rig() as rig:
        end = rig.run(accept_grasp, grasp())
    assert end.status is GoalStatus.SUCCEEDED
    # the message reports the force the result's field carries, and the contact apart
    assert re.fullmatch(r"contact: contact at \d+\.\d\d N, settled at "
                        + re.escape(f"{end.result['force']:.2f}") + " N", end.message)
    assert end.result["contact_detected"] and end.result["force"] >= 1.8
    assert end.result["opening"] < 0.030
    assert rig.feedback and set(rig.feedback[0]) == {"force", "opening", "slip_margin"}
    assert rig.slot.superseded("goal")  # the slot is free again


def test_a_hold_that_runs_out_of_settle_time_says_so():
    """settle_time 0 (hold where contact was found): the grasp succeeds, and its answer says
    the force was not settled instead of "settled at" a force that may be off the target."""
    with Rig(settle_time_s=0.0) as rig:
        end = rig.run(accept_grasp, grasp())
    assert end.status is GoalStatus.SUCCEEDED
    assert re.fullmatch(r"contact: contact at \d+\.\d\d N, not settled within settle_time "
                        r"\(0 s\): holding " + re.escape(f"{end.result['force']:.2f}") + " N",
                        end.message), end.message


def test_a_release_opens():
    with Rig() as rig:
        end = rig.run(accept_release, SimpleNamespace(opening=0.050))
    assert end.status is GoalStatus.SUCCEEDED and end.result["success"]
    assert end.result["opening"] == pytest.approx(0.050, abs=CONFIG.open_tolerance_m)


def test_an_invalid_goal_aborts_with_no_result():
    with Rig() as rig:
        end = rig.run(accept_grasp, grasp(speed=5.0))
    assert end.status is GoalStatus.ABORTED and end.result is None
    assert end.message.startswith("invalid_goal: Grasp speed 5.0 m/s")
    assert rig.client.commands == []


def test_a_gripper_never_sampled_is_not_active():
    rig = Rig()
    end = rig.run(accept_grasp, grasp())
    assert (end.status, end.message, end.result) == (
        GoalStatus.ABORTED, "inactive: the gripper is not active", None)


def test_a_latched_hardware_error_aborts_before_anything_moves():
    with Rig() as rig:
        rig.client.bits = frozenset({"overload"})
        while rig.servo.hardware_error != rig.client.bits:
            rig.servo.await_sample(1.0)
        end = rig.run(accept_grasp, grasp())
    assert end.status is GoalStatus.ABORTED
    assert end.message == "hardware_error: overload"
    assert end.result["opening"] == pytest.approx(0.040) and rig.client.commands == []


def test_torque_off_is_turned_on_holding_where_the_fingers_are():
    with Rig() as rig:
        rig.client.torque = False
        end = rig.run(accept_release, SimpleNamespace(opening=0.045))
    assert end.status is GoalStatus.SUCCEEDED
    assert rig.client.commands[0] == pytest.approx(GEOMETRY.position_rad(0.040))


def test_cancel_stops_where_the_fingers_are():
    with Rig(rod_m=0.0) as rig:
        thread, out = closing(rig)
        rig.runner.stop("goal")
        rig.cancel.set()
        thread.join()
    end = out["end"]
    assert end.status is GoalStatus.CANCELED
    assert end.message == "canceled: stopped where the fingers were"
    assert rig.servo.stop_written == "goal" and rig.errors == []
    assert end.result["opening"] > GEOMETRY.closed_opening_m


def test_a_failed_cancel_stop_is_written_by_the_goal_and_its_failure_logged():
    with Rig(rod_m=0.0) as rig:
        thread, out = closing(rig)
        rig.client.fail_commands = [PortLost("unplugged")]
        rig.runner.stop("goal")  # the cancel callback's stop fails ...
        rig.cancel.set()
        thread.join()
    assert rig.errors == ["stop on cancel failed: unplugged"]
    assert out["end"].status is GoalStatus.CANCELED
    assert rig.servo.stop_written == "goal"  # ... the goal's loop wrote it


def test_a_newer_goal_preempts_without_a_stop():
    with Rig(rod_m=0.0) as rig:
        thread, out = closing(rig)
        rig.slot.take_over("newer goal")
        rig.runner.stop("goal")  # a cancel of the old goal does not touch the servo now
        thread.join()
    assert (out["end"].status, out["end"].message) == (GoalStatus.ABORTED, PREEMPTED)
    assert rig.servo.stop_written is None


def test_deactivation_aborts_the_running_goal_with_its_reason():
    with Rig(rod_m=0.0) as rig:
        thread, out = closing(rig)
        rig.slot.abort_active(interrupted("the gripper node was deactivated"))
        thread.join()
    assert out["end"].message == "interrupted: the gripper node was deactivated"


def test_an_unreachable_servo_aborts_the_goal():
    with Rig(rod_m=0.0) as rig:
        thread, out = closing(rig)
        rig.client.fail_reads = CommunicationTimeout("no status packet")
        thread.join()
    assert out["end"].status is GoalStatus.ABORTED
    assert out["end"].message == "servo_unreachable: no status packet"


def test_a_command_that_cannot_be_written_aborts_the_goal():
    """A GripperCommand with a force limit sends a slower speed as the force rises."""
    with Rig(rod_m=0.039, stiffness=100.0) as rig:
        thread, out = in_thread(lambda: rig.run(accept_gripper_command, SimpleNamespace(
            command=SimpleNamespace(position=0.010, max_effort=1.0))))
        while len(rig.client.commands) < 1:
            rig.servo.await_sample(1.0)
        rig.client.fail_commands = [PortLost("unplugged")] * 100
        thread.join()
    assert out["end"].status is GoalStatus.ABORTED
    assert out["end"].message == "servo_unreachable: unplugged"


def test_a_hardware_error_while_moving_ends_the_goal_and_is_reported():
    with Rig(rod_m=0.0) as rig:
        thread, out = closing(rig)
        rig.client.bits = frozenset({"overheating"})
        thread.join()
    assert out["end"].status is GoalStatus.ABORTED
    assert out["end"].message == "hardware_error: overheating"
    assert rig.hardware_errors == [frozenset({"overheating"})]


def test_settling_aborts_when_the_servo_is_lost(never_settled):
    with Rig(stiffness=20000.0, settle_time_s=60.0) as rig:
        thread, out = settling(rig)
        rig.client.fail_reads = CommunicationTimeout("no status packet")
        thread.join()
    assert out["end"].message == "servo_unreachable: no status packet"
    assert out["end"].result["contact_detected"]  # lost while settling, after contact


def test_the_slot_frees_only_for_its_own_goal():
    slot = GoalSlot()
    slot.take_over("a")
    slot.take_over("b")
    slot.release("a")
    assert slot.superseded("a") and not slot.superseded("b")
    slot.release("b")
    assert slot.superseded("b")
    slot.abort_active("rebooting")
    assert slot.abort_reason == "rebooting"
    slot.take_over("c")
    assert slot.abort_reason == PREEMPTED


def test_the_answered_opening_is_where_the_fingers_stay():
    """A fast close on a softer skin than the grasp assumes (500 N/m a finger against
    2500) stops short of the force, and the settle moves the fingers on after contact.
    The answer waits for the fingers to stop and gives the opening they hold, not the
    opening at contact."""
    with Rig(settle_time_s=0.5, stiffness=1000.0) as rig:
        end = rig.run(accept_grasp, grasp(speed=0.05))
        stopped_at = GEOMETRY.opening_m(rig.client.commands[-1])
        while rig.client.velocity != 0.0:
            rig.servo.await_sample(1.0)
        held = GEOMETRY.opening_m(rig.client.position)
        contact_stop = next(GEOMETRY.opening_m(c) for c in reversed(rig.client.commands)
                            if GEOMETRY.opening_m(c) > held + 2e-5)
    assert end.status is GoalStatus.SUCCEEDED
    assert contact_stop > held + 2e-5  # the settle moved them on after an earlier stop
    assert held == pytest.approx(stopped_at, abs=2e-5)
    assert end.result["opening"] == pytest.approx(held, abs=2e-5)


@pytest.mark.parametrize("delay_s", [0.0, 0.03])
def test_a_late_tactile_force_still_settles_on_the_target(delay_s):
    """Under CPU load the force arrives tens of ms late. Correcting on it again before it
    shows the previous correction wound the loop up: 30 ms late, a 20 mm/s grasp on 2 N
    held 13.3 N (10 ms: 0 N, the fingers open). Each correction now waits for forces
    stamped after the fingers stopped from it."""
    with Rig(settle_time_s=5.0, force_delay_s=delay_s) as rig:
        end = rig.run(accept_grasp, grasp(force_n=2.0, speed=0.02))
        while rig.client.velocity != 0.0:
            rig.servo.await_sample(1.0)
        held = rig.true_force(rig.client.position)
    assert end.status is GoalStatus.SUCCEEDED, end.message
    assert abs(held - 2.0) <= 0.05 * 2.0 + 1e-6


def test_a_reboot_ends_the_running_goal_and_one_started_during_it():
    """The reboot's hold overwrites whatever a goal commanded meanwhile; a release started
    during an automatic reboot once waited for a move that never came until its 10 s
    timeout. Both goals now end aborted, with a reason that says to send them again."""
    with Rig() as rig:
        entered, go_on = threading.Event(), threading.Event()
        plain_reboot = rig.client.reboot

        def slow_reboot(wait_s: float = 2.0) -> None:
            entered.set()
            go_on.wait(10.0)
            plain_reboot(wait_s)

        rig.client.reboot = slow_reboot
        first, first_out = closing(rig)
        rebooting, _ = in_thread(lambda: rig.runner.reboot(0.6))
        assert entered.wait(10.0)
        first.join()
        rig.feedback.clear()
        second, second_out = in_thread(
            lambda: rig.run(accept_release, SimpleNamespace(opening=0.050), "second"))
        while not rig.feedback:  # the release runs, its command written
            rig.servo.await_sample(1.0)
        go_on.set()
        rebooting.join()
        second.join()
    assert first_out["end"].status is GoalStatus.ABORTED
    assert first_out["end"].message == REBOOTING
    assert second_out["end"].status is GoalStatus.ABORTED
    assert second_out["end"].message == REBOOTED


def saturated_grasp(rig: Rig, target_n: float = 5.0, timeout_s: float = 10.0):
    """A grasp accepted before the driver stated its range: the sensor saturates at
    ``rig.full_scale_n`` below the target, the range arrives while the fingers close, and
    the grasp runs on, pressing ever harder while it reads the full scale. The rig runs on
    servo time: the fingers reach the full scale about 0.63 s after the goal starts (11 mm at
    20 mm/s, from the first command on), before a 0.8 s timeout, however slowly a busy
    machine reads the servo."""
    thread, out = in_thread(lambda: rig.run(accept_grasp, grasp(
        force_n=target_n, speed=0.02, timeout=timeout_s)))
    while not rig.feedback:
        assert thread.is_alive(), out
        rig.servo.await_sample(1.0)
    rig.forces.full_scale_n = rig.full_scale_n
    while not (rig.forces.latest and rig.forces.latest[0] >= rig.full_scale_n):
        assert thread.is_alive(), f"the grasp ended before the full scale: {out}"
        rig.servo.await_sample(1.0)
    return thread, out


def held_force(rig: Rig) -> float:
    """The true force once the fingers stopped."""
    while rig.client.velocity != 0.0:
        rig.servo.await_sample(1.0)
    return rig.true_force(rig.client.position)


def test_a_grasp_that_times_out_at_the_full_scale_backs_off_to_its_target():
    """A grasp timed out at the sensor's full scale once held 27.9 N on the mock, four
    times what the sensor reads. It now opens until the reading is below the full scale
    and at most the target, then holds: the true force is as low."""
    with Rig(full_scale_n=3.0) as rig:
        thread, out = saturated_grasp(rig, timeout_s=0.8)
        thread.join()
        held = held_force(rig)
    end = out["end"]
    assert end.status is GoalStatus.ABORTED
    assert end.message == ("timeout: no result within 0.8 s; backed off from 3.00 N to "
                           f"{end.result['force']:.2f} N")
    assert end.result["force"] < 3.0 and held < 3.0 <= 5.0
    assert end.result["opening"] == pytest.approx(GEOMETRY.opening_m(rig.client.position))


def test_a_hold_left_unsettled_at_the_full_scale_backs_off():
    """A grasp accepted before the driver stated its range, whose target turns out to sit in
    the readings' saturated band: once the hold runs out of settle_time reading the full
    scale (the true force unknown above it), the fingers open until the reading is below the
    band, as an aborted goal's would. Below the band an unsettled hold stays where it is
    (``test_a_hold_that_runs_out_of_settle_time_says_so``)."""
    with Rig(settle_time_s=0.0, full_scale_n=2.1) as rig:
        thread, out = in_thread(lambda: rig.run(accept_grasp, grasp(force_n=2.0)))
        while not rig.feedback:
            assert thread.is_alive(), out
            rig.servo.await_sample(1.0)
        rig.forces.full_scale_n = rig.full_scale_n
        thread.join()
        held = held_force(rig)
    end = out["end"]
    assert end.status is GoalStatus.SUCCEEDED and end.result["contact_detected"]
    backed_off = re.fullmatch(r"contact: contact at \d+\.\d\d N, not settled within "
                              r"settle_time \(0 s\): holding (\S+) N at the sensor's full "
                              r"scale; backed off from (\S+) N to "
                              + re.escape(f"{end.result['force']:.2f}") + " N", end.message)
    assert backed_off, end.message
    assert float(backed_off[1]) >= 0.9 * 2.1
    assert end.result["force"] < 0.9 * 2.1 and held < 0.9 * 2.1


def test_a_cancel_above_the_target_backs_off_and_holds():
    with Rig(full_scale_n=3.0) as rig:
        thread, out = saturated_grasp(rig)
        rig.runner.stop("goal")  # the cancel callback's stop ...
        rig.cancel.set()  # ... then the goal's loop sees the cancel
        thread.join()
        held = held_force(rig)
    end = out["end"]
    assert end.status is GoalStatus.CANCELED
    assert end.message == ("canceled: stopped where the fingers were; backed off from "
                           f"3.00 N to {end.result['force']:.2f} N")
    assert held < 3.0


def test_a_hardware_error_above_the_target_commands_nothing_more():
    """Torque is off: the fingers rest where the error left them (docs/gripper.md)."""
    with Rig(full_scale_n=3.0) as rig:
        thread, out = saturated_grasp(rig)
        rig.client.bits = frozenset({"overload"})
        thread.join()
    assert out["end"].message == "hardware_error: overload"
    # nothing once a read has shown the error (counted by the servo itself: the test
    # thread may be preempted for ticks between looking and latching the error)
    assert rig.client.commands_before_error is not None
    assert len(rig.client.commands) == rig.client.commands_before_error


def test_an_abort_below_the_target_stays_where_it_stopped():
    with Rig(rod_m=0.0) as rig:
        end = rig.run(accept_grasp, grasp(speed=0.005, timeout=0.2))
        commands = list(rig.client.commands)
    assert end.message == "timeout: no result within 0.2 s"
    # closing on a leash, then the stop: nothing opens (no back-off)
    assert commands == sorted(commands[:-1]) + commands[-1:]
    assert commands[-1] <= commands[-2]


def backing_off(rig: Rig):
    """A grasp timed out at the full scale, past the back-off's first opening command."""
    thread, out = saturated_grasp(rig, timeout_s=0.8)
    closest = GEOMETRY.opening_m(rig.client.position)
    while thread.is_alive() and not any(GEOMETRY.opening_m(c) > closest + 1e-4
                                        for c in rig.client.commands[-3:]):
        closest = min(closest, GEOMETRY.opening_m(rig.client.position))
        rig.servo.await_sample(1.0)
    return thread, out


def test_a_back_off_without_fresh_force_holds_and_says_so():
    with Rig(full_scale_n=3.0) as rig:
        thread, out = backing_off(rig)
        rig.sensing.clear()
        thread.join()
    assert out["end"].message.endswith(" N (stopped: no fresh tactile force)"), out["end"]
    assert rig.client.velocity == 0.0 or rig.client.goal == rig.client.commands[-1]


def test_a_back_off_stops_when_the_servo_fails():
    with Rig(full_scale_n=3.0) as rig:
        thread, out = backing_off(rig)
        rig.client.fail_reads = CommunicationTimeout("no status packet")
        thread.join()
    assert out["end"].message.endswith(" N (stopped: the servo failed)"), out["end"]


def test_a_back_off_yields_to_a_newer_goal():
    with Rig(full_scale_n=3.0) as rig:
        thread, out = backing_off(rig)
        rig.slot.take_over("newer goal")
        thread.join()
    assert out["end"].message.endswith(" N (a newer goal took over)"), out["end"]


def test_a_back_off_whose_first_command_fails_stops_there():
    with Rig(full_scale_n=3.0) as rig:
        thread, out = saturated_grasp(rig, timeout_s=0.8)
        # every command after the closing's fails: the timeout's stop, then the back-off's
        rig.client.fail_commands = [PortLost("unplugged")] * 1000
        thread.join()
    end = out["end"]
    assert end.status is GoalStatus.ABORTED
    assert end.message.startswith("servo_unreachable: unplugged") or end.message.endswith(
        "(stopped: servo unreachable: unplugged)"), end.message


def test_a_servo_unreachable_at_the_start_aborts_the_goal():
    with Rig() as rig:
        rig.client.fail_commands = [PortLost("unplugged")]
        end = rig.run(accept_grasp, grasp())
    assert (end.status, end.message) == (GoalStatus.ABORTED, "servo_unreachable: unplugged")


@pytest.fixture
def never_settled(monkeypatch: pytest.MonkeyPatch) -> None:
    """The hold's regulator never says settled and keeps correcting: on a stiff skin a
    correction overshoots, but a window's mean can still land inside the tolerance by
    chance (settled at 1.96 N once; a contact at 2.01 N on a 2 N target once left the
    hold with nothing to correct for its whole settle_time), and these tests need a hold
    that is still writing corrections. A window judged inside the tolerance moves the
    fingers one pulse closer."""
    command = ForceSettler.command

    def unsettled(self, now_s, servo, current_a, velocity_rad_s):  # type: ignore[no-untyped-def]
        step, settled = command(self, now_s, servo, current_a, velocity_rad_s)
        if settled:
            step = ServoCommand(servo.position_rad + RAD_PER_PULSE, velocity_rad_s, current_a)
        return step, False

    monkeypatch.setattr(ForceSettler, "command", unsettled)


def settling(rig: Rig):
    """A grasp on a skin stiffer than the settler assumes (2500 N/m: on ``stiffness=20000``
    each correction overshoots the error, the other way), with a regulator that never
    settles (``never_settled``); returned once it has made a few corrections."""
    thread, out = in_thread(lambda: rig.run(accept_grasp, grasp(force_n=2.0)))
    while not (rig.forces.latest and rig.forces.latest[0] >= 2.0):
        assert thread.is_alive(), f"the grasp ended before the force: {out}"
        rig.servo.await_sample(1.0)
    corrections = len(rig.client.commands) + 3
    while len(rig.client.commands) < corrections:
        assert thread.is_alive(), f"the grasp ended while settling: {out}"
        rig.servo.await_sample(1.0)
    return thread, out


def test_a_cancel_while_settling_ends_canceled(never_settled):
    with Rig(stiffness=20000.0, settle_time_s=60.0) as rig:
        thread, out = settling(rig)
        rig.runner.stop("goal")
        rig.cancel.set()
        thread.join()
    assert out["end"].status is GoalStatus.CANCELED, out["end"]
    assert out["end"].message.startswith("canceled: stopped where the fingers were")


def test_a_hardware_error_while_settling_ends_the_goal_with_it(never_settled):
    """Torque is off after a hardware error: a grasp that was settling holds nothing, so it
    ends aborted with the error (it once ended succeeded, settled at the relaxed force)."""
    with Rig(stiffness=20000.0, settle_time_s=60.0) as rig:
        thread, out = settling(rig)
        rig.client.bits = frozenset({"overload"})
        thread.join()
    assert (out["end"].status, out["end"].message) == (GoalStatus.ABORTED,
                                                       "hardware_error: overload")
    assert rig.hardware_errors == [frozenset({"overload"})]


def test_a_correction_that_cannot_be_written_aborts_the_settle(never_settled):
    with Rig(stiffness=20000.0, settle_time_s=60.0) as rig:
        thread, out = settling(rig)
        rig.client.fail_commands = [PortLost("unplugged")] * 1000
        thread.join()
    assert (out["end"].status, out["end"].message) == (
        GoalStatus.ABORTED, "servo_unreachable: unplugged")


class ObjectRig(Rig):
    """The rig's rod as a hanging object: finger A's skin carries its load's half, up to mu
    times the grip (sliding: mu times the grip)."""

    def __init__(self, load_n: float, mu: float, **kw) -> None:
        super().__init__(**kw)
        self.load_n, self.mu = load_n, mu
        self.slips: list = []
        self.runner._on_slip = self.slips.append

    def _control_loop(self) -> None:
        while self._running:
            poll = self.servo.poll()
            if poll.state is not None and self.sensing.is_set():
                force = self.true_force(poll.state.position_rad)
                self.forces.add(force, self._wall())
                self.forces.add_wrench(force, min(self.load_n / 2, self.mu * force), 0.0, 1)
            time.sleep(TICK_S)


ADAPTIVE = replace(SETTINGS, hold=HoldSettings(shear_sensing=True), max_grasp_force_n=5.0)


def adaptive(hold_time: float) -> SimpleNamespace:
    return SimpleNamespace(**vars(grasp()), hold_mode="adaptive", hold_time=hold_time)


def test_an_adaptive_grasp_learns_the_friction_and_holds_for_its_hold_time():
    with ObjectRig(load_n=1.8, mu=0.5) as rig:
        end = rig.runner.run(rig.link(), lambda: accept_grasp(adaptive(1.0), ADAPTIVE))
    assert end.status is GoalStatus.SUCCEEDED, end.message
    assert re.fullmatch(r"contact: contact at .* N, settled at .* N; adaptive hold for 1 s "
                        r"\(friction 0\.\d\d\): holding (.*) N", end.message)
    assert 0.3 < end.result["friction"] <= 0.55
    assert rig.slips and rig.slips[0].kind == "learned"
    assert "slip_margin" in rig.feedback[-1] and not math.isnan(rig.feedback[-1]["slip_margin"])
    assert 0.9 / 0.5 <= end.result["force"] <= 5.0


def test_an_adaptive_hold_the_ceiling_cannot_keep_says_slipping_and_holds_there():
    with ObjectRig(load_n=4.4, mu=0.5) as rig:
        end = rig.runner.run(rig.link(), lambda: accept_grasp(adaptive(5.0), ADAPTIVE))
        force = rig.true_force(rig.client.position)
    assert end.status is GoalStatus.ABORTED
    assert re.fullmatch(r"slipping: the object needs \d\.\d\d N of grip at friction 0\.\d\d, "
                        r"above the force ceiling of 5\.00 N; holding at the ceiling",
                        end.message), end.message
    assert [e.kind for e in rig.slips][-1] == "slipping"
    assert force == pytest.approx(5.0, abs=0.15)


def test_an_adaptive_hold_without_tactile_force_ends_stale():
    goal = accept_grasp(adaptive(0.0), ADAPTIVE)
    with ObjectRig(load_n=0.0, mu=0.5) as rig:
        thread, out = in_thread(lambda: rig.runner.run(rig.link(), lambda: goal))
        while goal.hold is None and thread.is_alive():
            rig.servo.await_sample(1.0)
        rig.sensing.clear()
        thread.join(10.0)
    assert out["end"].status is GoalStatus.ABORTED
    assert out["end"].message.startswith("tactile_stale: no tactile force for ")


def patient(stale_after_s: float) -> GoalSettings:
    """The rig's settings with another tactile timeout, given to its servo link as well."""
    return GoalSettings(config=replace(CONFIG, stale_after_s=stale_after_s))


def unheard(settings: GoalSettings = SETTINGS) -> Rig:
    """A rig whose driver publishes nothing yet (until ``sensing`` is set)."""
    rig = Rig()
    rig.servo.config = settings.config
    rig.sensing.clear()
    return rig


def test_a_grasp_sent_before_the_forces_flow_waits_for_the_first_without_moving():
    """Readiness: the driver is not publishing yet when the goal comes. Nothing is commanded
    until a force arrives; then the grasp runs as any other (servo time: 2 s of waiting
    allowed, the forces come after 50 samples)."""
    settings = patient(2.0)
    with unheard(settings) as rig:
        thread, out = in_thread(lambda: rig.runner.run(
            rig.link(), lambda: accept_grasp(grasp(), settings)))
        for _ in range(50):
            rig.servo.await_sample(1.0)
        assert thread.is_alive(), out
        assert rig.client.commands == [] and rig.forces.latest is None
        rig.sensing.set()
        thread.join()
    end = out["end"]
    assert end.status is GoalStatus.SUCCEEDED, end.message
    assert end.message.startswith("contact: contact at ")


def test_a_grasp_whose_forces_never_come_aborts_stale_before_anything_moves():
    with unheard() as rig:
        end = rig.run(accept_grasp, grasp())
        commands = list(rig.client.commands)
    assert end.status is GoalStatus.ABORTED and commands == []
    assert re.fullmatch(
        r"tactile_stale: no tactile force came within \d\.\d{3} s of the goal "
        r"\(tactile_timeout 0\.1 s\), so the fingers did not move: start and activate the "
        r"driver, check that tactile_wrench is remapped onto its ~/wrench, or send the goal "
        r"again once its data flow", end.message), end.message
    assert end.result is not None and end.result["contact_detected"] is False


def test_a_goal_waiting_for_its_first_force_ends_on_a_cancel_or_a_newer_goal():
    settings = patient(60.0)
    with unheard(settings) as rig:
        thread, out = in_thread(lambda: rig.runner.run(
            rig.link(), lambda: accept_grasp(grasp(), settings)))
        rig.servo.await_sample(1.0)
        rig.cancel.set()
        thread.join()
        assert out["end"].status is GoalStatus.CANCELED
        rig.cancel.clear()
        thread, out = in_thread(lambda: rig.runner.run(
            rig.link("first"), lambda: accept_grasp(grasp(), settings)))
        rig.servo.await_sample(1.0)
        rig.slot.take_over("newer goal")
        thread.join()
        assert out["end"].message == PREEMPTED
        assert rig.client.commands == []


def test_a_release_does_not_wait_for_the_tactile_force():
    """A release must open the fingers whether the sensor works or not."""
    with unheard() as rig:
        end = rig.run(accept_release, SimpleNamespace(opening=0.050))
    assert end.status is GoalStatus.SUCCEEDED, end.message


def test_a_goal_whose_loop_gets_no_servo_sample_stops_the_fingers_and_says_why():
    """Degrade out loud: a starved control loop (no servo sample for the tactile timeout)
    ends the goal with the reason, and the last command is a stop where the fingers are."""
    with Rig(rod_m=0.0) as rig:
        thread, out = closing(rig)
        rig.servo.sample_age_s = lambda: 0.35  # type: ignore[method-assign]
        thread.join()
        stopped_at = rig.client.commands[-1]
        position = rig.client.position
    end = out["end"]
    assert end.status is GoalStatus.ABORTED
    assert end.message == (
        "interrupted: the control loop got no servo sample for 0.350 s (tactile_timeout "
        "0.1 s; the machine is too busy for control_rate 500 Hz), so the fingers were "
        "stopped where they were"), end.message
    assert stopped_at == pytest.approx(position, abs=1e-3)


class CountingBusy:
    """A ``busy`` context that counts how often it was held."""

    def __init__(self) -> None:
        self.entered = self.left = 0

    def __call__(self):
        @contextlib.contextmanager
        def held():
            self.entered += 1
            try:
                yield
            finally:
                self.left += 1
        return held()


def test_the_loop_is_kept_busy_for_exactly_the_goal():
    busy = CountingBusy()
    with Rig() as rig:
        rig.runner = GoalRunner(rig.servo, rig.forces, rig.slot, rig.runner.timing,
                                on_hardware_error=rig.hardware_errors.append,
                                log_error=rig.errors.append, busy=busy,
                                wall_clock=rig.client.now, clock=rig.client.now)
        rig.run(accept_release, SimpleNamespace(opening=0.050))
        rig.run(accept_grasp, grasp(speed=5.0))  # invalid: ends at once, busy released too
    assert (busy.entered, busy.left) == (2, 2)


def test_a_goal_given_its_own_first_input_waits_for_that_and_names_it():
    """The self-check waits for the module output, not the force: named in the sentence."""
    output = FirstInput(lambda: False, lambda: True,
                        ("module output", "tactile_reading", "~/reading"))
    with Rig() as rig:
        end = rig.runner.run(rig.link(), lambda: accept_release(
            SimpleNamespace(opening=0.050), SETTINGS), output)
        assert end.status is GoalStatus.ABORTED and rig.client.commands == []
        assert end.message.startswith(
            "tactile_stale: no fresh module output (the newest is older than that) came "
            "within "), end.message
        assert "check that tactile_reading is remapped onto its ~/reading" in end.message
        came = FirstInput(lambda: True, lambda: True)
        end = rig.runner.run(rig.link(), lambda: accept_release(
            SimpleNamespace(opening=0.050), SETTINGS), came)
    assert end.status is GoalStatus.SUCCEEDED, end.message
