"""control_msgs GripperCommand and ParallelGripperCommand, and the goal policy they share with
Grasp and Release, from clients in other processes (as MoveIt's would be): this test process
(and the ``ros2 action`` CLI where a sourced ROS 2 has it), against the gripper configuration
(``tactile-sensor bringup gripper --no-mock``, which runs on every distribution, wheels
included) on mock devices (emulated XM430 and photoreflector sharing one gripper world with
the 20 mm rod). ``ros2 launch gripper.launch.py`` itself: test_ros2_launch_gripper.py.

Each test starts the configuration once and runs a group of checks against it.
"""

from __future__ import annotations

import math
import statistics
import time
from pathlib import Path

import numpy as np
import pytest
import rclpy
import yaml
from action_msgs.msg import GoalStatus
from control_msgs.action import GripperCommand, ParallelGripperCommand
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from geometry_msgs.msg import WrenchStamped
from gripper_under_load import GRIPPER_UNDER_LOAD
from lifecycle_msgs.msg import Transition
from lifecycle_msgs.srv import ChangeState
from lone_gripper import lone_gripper
from sensor_msgs.msg import JointState
from std_srvs.srv import Trigger

from tactile_sensor.analysis.finger_rest import rest_onset
from tactile_sensor.configurations import config_dir
from tactile_sensor.control.goal_runner import PREEMPTED
from tactile_sensor.nodes.action_client import RaceFreeActionClient
from tactile_sensor.nodes.background_spin import BackgroundSpin
from tactile_sensor.nodes.ros_session import ros_session
from tactile_sensor_interfaces.action import Grasp, Release

CONFIG = config_dir()

ROD_M = 0.020  # config/gripper.yaml rod.diameter
JOINT = "finger_opening"
# Upper bound of every wait on a condition (a wait ends as soon as its condition holds; a
# busy machine may take long to get there). Never a fixed sleep in place of a condition.
PATIENCE_S = 60.0
HELD_STATES = 10  # joint states judged during a force hold
MOVED_M = 2e-4  # the fingers have left where they rested (4 encoder pulses)
CANCEL_FROM_M = 0.04  # each cancel trial starts at this opening (1.9 s from 2 mm) [m]


class Launch:
    """The gripper configuration against mock devices on this test's pseudo-terminals.

    The mock rig runs first, on its own, as real hardware would be plugged in before the
    bringup (the gripper may otherwise try the servo's port before the mock has created it,
    and its configure fails)."""

    def __init__(self, spawn, tmp_path: Path) -> None:
        self.control = tmp_path / "xm430.ctl"
        adc, servo = tmp_path / "adc", tmp_path / "xm430"
        overrides = tmp_path / "overrides.yaml"
        overrides.write_text(yaml.safe_dump({
            "/**/gripper_world": {"ros__parameters": {
                "adc_link": str(adc), "servo_link": str(servo),
                "servo_control": str(self.control), "seed": 3}},
            "/**/gripper": {"ros__parameters": GRIPPER_UNDER_LOAD},
        }))
        self.mock = spawn("--ros-args", "-r", "__node:=gripper_world",
                          "--params-file", str(CONFIG / "physics.yaml"),
                          "--params-file", str(CONFIG / "gripper.yaml"),
                          "--params-file", str(overrides),
                          module="tactile_sensor.nodes.mock_hardware")
        assert self.mock.wait_for_output("mock gripper ready", 120), self.mock.output()
        self.process = spawn("bringup", "gripper", "--no-mock", "--protocol", "idle",
                             "--port", f"adc_port={adc}", "--port", f"servo_port={servo}",
                             "--config", str(overrides), module="tactile_sensor.cli")

    def inject(self, command: str) -> None:
        with self.control.open("w") as fifo:
            fifo.write(command + "\n")

    def output(self) -> str:
        return self.process.output()


class Client:
    def __init__(self) -> None:
        self.node = rclpy.create_node("manipulation_stack")
        self.actions = {
            "grasp": RaceFreeActionClient(self.node, Grasp, "/gripper/grasp"),
            "release": RaceFreeActionClient(self.node, Release, "/gripper/release"),
            "gripper_cmd": RaceFreeActionClient(self.node, GripperCommand, "/gripper/gripper_cmd"),
            "parallel": RaceFreeActionClient(self.node, ParallelGripperCommand,
                                             "/gripper/parallel_gripper_cmd"),
        }
        self.force: list[tuple[float, float]] = []
        self.joints: list[JointState] = []  # effort: the force the gripper heard (nan: none)
        self.opening: list[tuple[float, float]] = []
        self.diagnostics: list[DiagnosticStatus] = []
        for message_type, topic, callback in (
                (WrenchStamped, "/driver/wrench", self._force),
                (JointState, "/gripper/joint_states", self._joint),
                (DiagnosticArray, "/diagnostics", self._diagnostics)):
            self.node.create_subscription(message_type, topic, callback, 1000)
        self.executor = rclpy.executors.MultiThreadedExecutor(num_threads=2)
        self.executor.add_node(self.node)
        self.spin = BackgroundSpin(self.executor)

    def _force(self, msg: WrenchStamped) -> None:
        self.force.append((time.time(), msg.wrench.force.z))

    def _diagnostics(self, msg: DiagnosticArray) -> None:
        self.diagnostics.extend(s for s in msg.status if "XM430" in s.name)

    def _joint(self, msg: JointState) -> None:
        self.joints.append(msg)
        self.opening.append((_stamp_s(msg), msg.position[0]))

    def send(self, name: str, goal, accepted: bool = True):
        handle = _wait(self.actions[name].send_goal_async(goal))
        assert handle.accepted is accepted, goal
        return handle

    def send_moving(self, name: str, goal):
        """Send a goal and return once the fingers move (under way, not only accepted):
        judged on joint states stamped after the send, since this listener may still be
        taking older ones (beside a busy core it once took the end of the previous goal's
        move for this one's start)."""
        sent = time.time()
        handle = self.send(name, goal)

        def moved() -> bool:
            after = [o for t, o in list(self.opening) if t >= sent]
            return len(after) >= 2 and abs(after[-1] - after[0]) > MOVED_M

        _until(moved, PATIENCE_S, "the fingers did not start moving")
        return handle

    def run(self, name: str, goal, timeout_s: float = PATIENCE_S):
        """(status, result) of a goal run to its end."""
        answer = _wait(self.send(name, goal).get_result_async(), timeout_s)
        return answer.status, answer.result

    def close(self) -> None:
        self.spin.stop()
        for action in self.actions.values():
            action.destroy()  # destroy_node() leaves them to the garbage collector
        self.node.destroy_node()


def _stamp_s(msg: JointState) -> float:
    return msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9


def _until(condition, timeout_s: float, what: str, poll_s: float = 0.01) -> None:
    deadline = time.monotonic() + timeout_s
    while not condition():
        assert time.monotonic() < deadline, what
        time.sleep(poll_s)


def _wait(future, timeout_s: float = PATIENCE_S):
    _until(future.done, timeout_s, "timed out", poll_s=0.005)
    return future.result()


@pytest.fixture
def gripper(spawn, ros_domain, tmp_path):
    launch = Launch(spawn, tmp_path)
    with ros_session():
        client = Client()
        for action in client.actions.values():
            assert action.wait_for_server(timeout_sec=120), launch.output()
        # active: joint states flow (a lifecycle publisher); the driver tared and streams
        _until(lambda: client.joints and client.force, 120, launch.output())
        # ... and the gripper hears the force before a goal starts: its joint states carry
        # the force it heard as the effort (nan before any)
        _until(lambda: math.isfinite(client.joints[-1].effort[0]), PATIENCE_S,
               "the gripper hears no force: " + launch.output())
        yield launch, client
        client.close()
        # no callback of the gripper failed along the way (rclpy logs and carries on)
        assert "Error raised in" not in launch.output(), launch.output()


def command(position: float, max_effort: float) -> GripperCommand.Goal:
    goal = GripperCommand.Goal()
    goal.command.position, goal.command.max_effort = position, max_effort
    return goal


def parallel(position: float, effort: float | None = None, velocity: float | None = None,
             name: str = JOINT) -> ParallelGripperCommand.Goal:
    goal = ParallelGripperCommand.Goal()
    goal.command.name = [name]
    goal.command.position = [position]
    goal.command.effort = [] if effort is None else [effort]
    goal.command.velocity = [] if velocity is None else [velocity]
    return goal


def aborted_why(launch: Launch) -> str:
    """The node's log lines for aborted goals (a control_msgs result carries no message)."""
    return "\n".join(line for line in launch.output().splitlines()
                     if "aborted" in line or "ERROR" in line) or launch.output()[-3000:]


def test_both_control_msgs_interfaces_grip_the_rod_by_tactile_force_and_open(gripper):
    launch, client = gripper
    assert client.joints[-1].name == [JOINT]

    status, result = client.run("gripper_cmd", command(0.002, 2.0))
    assert status == GoalStatus.STATUS_SUCCEEDED, aborted_why(launch)  # allow_stalling
    assert result.stalled and not result.reached_goal
    # the force when the answer is given: the skin relaxes under the stop by up to
    # sum(prony_g) / (1 + sum(prony_g)) = 8 % (0.17 N) before the hold restores it, the more
    # the later the answer comes (1.78 N once on a loaded machine, against 1.8 allowed then)
    assert result.effort == pytest.approx(2.0, abs=0.3)
    # the skins meet the 20 mm rod and give a few mm under 2 N
    assert ROD_M - 0.008 < result.position < ROD_M, result.position
    # ~/joint_states: the same joint, opening and effort (the tactile force) while holding
    # (a state read after the result: the last one to arrive may be older). The hold
    # regulates force, not position, and the skin creeps under it (viscoelastic), so the
    # opening goes on closing by a fraction of a millimetre, the more the later the state is
    # read: 0.21 mm once on a loaded machine, against 0.2 mm allowed then. The force is
    # regulated, so it is judged over several states: one state on a loaded machine read
    # 1.69 N while the tactile feedback came late.
    answered_at = time.time()
    first = len(client.joints)

    def states_in_hold() -> list[JointState]:
        return [j for j in client.joints[first:] if _stamp_s(j) >= answered_at][:HELD_STATES]

    _until(lambda: len(states_in_hold()) == HELD_STATES, PATIENCE_S,
           "too few ~/joint_states in the hold")
    held = states_in_hold()
    assert held[0].position[0] == pytest.approx(result.position, abs=5e-4)
    assert statistics.median(j.effort[0] for j in held) == pytest.approx(2.0, abs=0.3)

    status, result = client.run("gripper_cmd", command(0.03, 0.0))
    assert status == GoalStatus.STATUS_SUCCEEDED, aborted_why(launch)
    assert result.reached_goal and not result.stalled
    # the servo's profile arrived; through its drivetrain's friction the output rests its
    # loop's lead short (~0.7 mm of opening on the mock's sources' values)
    assert result.position == pytest.approx(0.03, abs=0.0012)

    status, result = client.run("parallel", parallel(0.002, effort=2.0, velocity=0.02))
    assert status == GoalStatus.STATUS_SUCCEEDED, aborted_why(launch)
    assert result.stalled and not result.reached_goal
    assert list(result.state.name) == [JOINT]
    # as the GripperCommand's above: 2.26 N once on Kilted beside a busy core
    assert result.state.effort[0] == pytest.approx(2.0, abs=0.3)
    assert ROD_M - 0.008 < result.state.position[0] < ROD_M

    status, result = client.run("parallel", parallel(0.03))
    assert status == GoalStatus.STATUS_SUCCEEDED, aborted_why(launch)
    assert result.reached_goal and not result.stalled
    assert result.state.position[0] == pytest.approx(0.03, abs=0.0012)  # as above


@pytest.mark.ros2_tools
def test_the_ros2_action_cli_sends_a_gripper_command(gripper, spawn):
    """The real ros2 CLI as the external client (what a user types first). With
    ``--feedback`` it prints as the fingers move, so the wait lasts while it progresses
    (starting the CLI, discovering the server and the move each take longer on a busy
    machine), and a failure shows the step it stopped at."""
    launch, _ = gripper
    cli = spawn("ros2", "action", "send_goal", "--feedback", "/gripper/gripper_cmd",
                "control_msgs/action/GripperCommand",
                "{command: {position: 0.05, max_effort: 0.0}}")
    assert cli.wait_for_output("Goal finished with status:", PATIENCE_S,
                               while_progressing=True), (cli.output(), aborted_why(launch))
    assert cli.proc.wait(PATIENCE_S) == 0, cli.output()  # and it ends by itself
    output = cli.output()
    assert "reached_goal: true" in output and "status: SUCCEEDED" in output, \
        (output, aborted_why(launch))


def test_invalid_goals_are_refused_before_anything_moves(gripper):
    """Each is accepted and aborted at once, its reason in the result where the interface
    has a message (control_msgs results have none: the status and the log say it)."""
    launch, client = gripper
    before = client.opening[-1][1]
    rejected = [
        ("gripper_cmd", command(math.nan, 1.0), "not a number"),
        ("gripper_cmd", command(0.01, math.nan), "not a number"),
        ("gripper_cmd", command(0.01, -1.0), "negative"),
        ("gripper_cmd", command(0.001, 1.0), "outside the travel"),
        ("gripper_cmd", command(0.061, 1.0), "outside the travel"),
        ("parallel", parallel(0.01, name="gripper_joint"), f"this gripper's joint is '{JOINT}'"),
        ("parallel", parallel(math.nan), "not a number"),
        ("parallel", parallel(0.01, effort=-2.0), "negative"),
        ("parallel", parallel(0.07), "outside the travel"),
        ("parallel", parallel(0.01, velocity=-0.01), "positive number"),
        # the force ceiling: max_grasp_force (10 N) and the driver's full scale (6.77 N)
        ("gripper_cmd", command(0.01, 1e9), "Effort limit 1e+09 N is "),
        ("parallel", parallel(0.01, effort=50.0), "Effort limit 50 N is "),
        ("grasp", Grasp.Goal(target_force=-1.0), "must be positive"),
        ("grasp", Grasp.Goal(target_force=math.nan), "must be positive"),
        ("release", Release.Goal(opening=0.07), "outside the travel"),
    ]
    sent_at = time.time()
    for name, goal, words in rejected:
        status, result = client.run(name, goal)
        assert status == GoalStatus.STATUS_ABORTED, (name, goal)
        if hasattr(result, "message"):
            assert result.message.startswith("invalid_goal: ") and words in result.message

    def lines() -> list[str]:
        return [line for line in launch.output().splitlines() if "goal refused" in line]
    _until(lambda: len(lines()) >= len(rejected), PATIENCE_S,  # launch relays logs
           launch.output())
    for line, (_, _, words) in zip(lines(), rejected, strict=True):
        assert words in line, (line, words)
    # nothing moved from the first goal sent until 0.3 s (by the servo's read stamps)
    # after the last was rejected: a goal would move the fingers millimetres in that time
    rejected_at = time.time()
    _until(lambda: client.opening[-1][0] >= rejected_at + 0.3, PATIENCE_S,
           "no ~/joint_states")
    after = [o for t, o in client.opening if t >= sent_at]
    assert after and max(abs(o - before) for o in after) < 2e-4, (before, after)


def test_one_goal_policy_across_all_four_servers(gripper):
    launch, client = gripper
    launch.inject("rod none")
    # a GripperCommand preempts a Grasp ...
    grasp = client.send_moving("grasp", Grasp.Goal(target_force=1.5, closing_speed=0.005))
    move = client.send("gripper_cmd", command(0.045, 0.0))
    answer = _wait(grasp.get_result_async())
    assert answer.status == GoalStatus.STATUS_ABORTED
    assert answer.result.message == PREEMPTED
    assert _wait(move.get_result_async()).result.reached_goal
    # ... and a Grasp preempts a GripperCommand (and finds the rod put back while the
    # fingers are still well clear of it)
    move = client.send_moving("gripper_cmd", command(0.002, 5.0))
    launch.inject(f"rod {ROD_M} 0.0")
    grasp = client.send("grasp", Grasp.Goal(target_force=1.5))
    answer = _wait(move.get_result_async())
    assert answer.status == GoalStatus.STATUS_ABORTED
    assert not answer.result.reached_goal and not answer.result.stalled
    _until(lambda: f"GripperCommand goal aborted: {PREEMPTED}" in launch.output(),
           PATIENCE_S, launch.output())  # launch relays the log
    assert _wait(grasp.get_result_async()).result.contact_detected
    # a ParallelGripperCommand preempts a Release
    release = client.send_moving("release", Release.Goal(opening=0.0))
    status, result = client.run("parallel", parallel(0.04))
    assert status == GoalStatus.STATUS_SUCCEEDED and result.reached_goal
    assert "preempted" in _wait(release.get_result_async()).result.message

    # cancel mid-move stops the fingers (a latency is a benchmark's business: Grasp
    # cancels in benchmarks/bench_gripper_cancel.py; none measures GripperCommand's yet)
    launch.inject("rod none")
    latencies = [cancel_latency(client, command(0.002, 0.0), trial) for trial in range(5)]
    ms = np.array(latencies) * 1e3
    print(f"GripperCommand cancel -> fingers stopped: median {np.median(ms):.0f} ms, "
          f"max {ms.max():.0f} ms ({np.round(ms).astype(int)})")
    # stopped by the cancel, not run on to the 2 mm target (seconds away); a bound a busy
    # machine cannot break, as in test_gripper_node's Grasp cancel
    assert ms.max() < 2000.0, ms


def cancel_latency(client: Client, goal, trial: int) -> float:
    """Cancel request sent -> the fingers at rest (``rest_onset``), by stamp, for a goal
    canceled while the fingers move."""
    # each trial from the same opening, far from the goal: one that began where a late
    # cancel had left the fingers, near the goal, ended reached before its own cancel came
    # (seen beside a busy core: the cancel refused, the goal already succeeded)
    status, result = client.run("gripper_cmd", command(CANCEL_FROM_M, 0.0))
    assert status == GoalStatus.STATUS_SUCCEEDED and result.reached_goal, (status, result)
    # where the fingers are once still, by samples stamped from now on: a goal that ended
    # reached (within its tolerance) may leave them creeping on, and the last sample this
    # listener took may be older than that end (seen beside a busy core: "at rest" read
    # 1.4 mm short of where the fingers then stopped)
    waited = time.time()
    _until(lambda: rest_onset(client.opening, waited, hold_s=0.3) is not None, PATIENCE_S,
           "the fingers did not come to rest before the goal")
    rest = client.opening[-1][1]
    handle = client.send_moving("gripper_cmd", goal)
    time.sleep(0.015 * trial)  # different phases of the 100 Hz loop
    moving_before = client.opening[-1][1]
    canceled_at = time.time()
    assert _wait(handle.cancel_goal_async()).goals_canceling
    answer = _wait(handle.get_result_async())
    assert answer.status == GoalStatus.STATUS_CANCELED
    _until(lambda: rest_onset(client.opening, canceled_at, hold_s=0.3) is not None, PATIENCE_S,
           "the fingers did not come to rest after the cancel")
    # it was closing (below where it started) and did not open again; a cancel that lands
    # before the fingers' next sample leaves the opening equal (seen beside a busy core)
    assert client.opening[-1][1] <= moving_before < rest
    return rest_onset(client.opening, canceled_at, hold_s=0.3) - canceled_at


def test_an_overload_mid_move_aborts_with_the_decoded_bits_and_torque_off(gripper):
    launch, client = gripper
    launch.inject("rod none")
    handle = client.send_moving("parallel", parallel(0.002, velocity=0.01))  # mid-move
    launch.inject("fault overload")
    answer = _wait(handle.get_result_async())
    assert answer.status == GoalStatus.STATUS_ABORTED
    assert not answer.result.reached_goal and not answer.result.stalled
    # launch relays the logs: each is waited for
    # one wording of the outcome, the same as a goal aborted at once below
    for logged in ("ParallelGripperCommand goal aborted: hardware_error: overload\n",
                   "servo hardware error: overload; torque off"):
        _until(lambda text=logged: text in launch.output(), PATIENCE_S, launch.output())
    _until(lambda: any(s.level == DiagnosticStatus.ERROR and "overload" in s.message
                       for s in client.diagnostics), PATIENCE_S, "no overload diagnostics")
    # a goal while the error stands is aborted at once, with the reason
    status, result = client.run("gripper_cmd", command(0.05, 0.0))
    assert status == GoalStatus.STATUS_ABORTED and not result.reached_goal
    assert 0.002 < result.position < 0.06  # where the fingers stopped
    _until(lambda: " GripperCommand goal aborted: hardware_error: overload\n"
           in launch.output(), PATIENCE_S, launch.output())  # (not Parallel...)
    reboot = client.node.create_client(Trigger, "/gripper/reboot")
    assert reboot.wait_for_service(timeout_sec=PATIENCE_S)
    assert _wait(reboot.call_async(Trigger.Request())).success
    status, result = client.run("gripper_cmd", command(0.05, 0.0))
    assert status == GoalStatus.STATUS_SUCCEEDED and result.reached_goal


def test_an_inactive_gripper_refuses_goals_naming_the_fix(spawn, ros_domain, tmp_path):
    """Configured but not active (the launch files activate at once, so this runs the node
    alone on an emulated servo, configured through its lifecycle service, as
    ``ros2 lifecycle set /gripper configure`` does)."""
    gripper = lone_gripper(spawn, tmp_path / "xm430")
    with ros_session():
        client = Client()
        change_state = client.node.create_client(ChangeState, "/gripper/change_state")
        assert change_state.wait_for_service(timeout_sec=60), gripper.output()
        request = ChangeState.Request()
        request.transition.id = Transition.TRANSITION_CONFIGURE
        assert _wait(change_state.call_async(request), 60).success, gripper.output()
        assert client.actions["gripper_cmd"].wait_for_server(timeout_sec=PATIENCE_S)
        status, _ = client.run("gripper_cmd", command(0.05, 0.0))
        assert status == GoalStatus.STATUS_ABORTED
        status, result = client.run("grasp", Grasp.Goal(target_force=1.0))
        assert status == GoalStatus.STATUS_ABORTED
        assert result.message == ("inactive: the gripper is not active; activate it "
                                  "(ros2 lifecycle set gripper activate).")
        client.close()
    _until(lambda: "gripper_cmd goal refused: inactive: the gripper is not active; activate it "
           "(ros2 lifecycle set gripper activate)." in gripper.output(), PATIENCE_S,
           gripper.output())
