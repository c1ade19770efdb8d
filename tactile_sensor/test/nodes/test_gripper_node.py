"""Gripper over ROS in separate processes: mock rig (emulated XM430 + mock photoreflector
sharing one gripper world) -> driver -> gripper node -> this test's action client.
"""

from __future__ import annotations

import contextlib
import math
import re
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import rclpy
import yaml
from action_msgs.msg import GoalStatus
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from geometry_msgs.msg import WrenchStamped
from gripper_under_load import GRIPPER_UNDER_LOAD
from lone_gripper import lone_gripper
from rclpy.action import ActionClient, get_action_names_and_types
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64

from tactile_sensor.analysis.finger_rest import rest_onset
from tactile_sensor.configurations import config_dir
from tactile_sensor.control.back_off import SATURATION_BAND
from tactile_sensor.nodes.action_client import RaceFreeActionClient
from tactile_sensor.nodes.background_spin import BackgroundSpin
from tactile_sensor.nodes.ros_session import ros_session
from tactile_sensor.physics.params import PhysicsParams
from tactile_sensor.physics.prediction import load_or_compute_curve
from tactile_sensor.sensing.calibration import Calibration
from tactile_sensor_interfaces.action import Grasp, Release, SelfCheck
from tactile_sensor_interfaces.msg import CalibrationCorrection, TactileReading

CONFIG = config_dir()
# Upper bound of every wait on a condition (a wait ends as soon as its condition holds; a
# busy machine may take long to get there). Never a fixed sleep in place of a condition.
PATIENCE_S = 60.0
MOVED_M = 2e-4  # the fingers have left where they rested (4 encoder pulses)


@pytest.fixture(scope="module")
def calibration_file(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The FEM calibration the model node would publish, as a file for the driver."""
    path = tmp_path_factory.mktemp("cal") / "calibration.json"
    Calibration.from_prediction_curve(load_or_compute_curve(PhysicsParams())).to_file(path)
    return path


def overrides(tmp_path: Path, node: str, **values: object) -> str:
    """A parameter file applied after the configuration's own: a node-specific section of
    a file takes precedence over a global '-p', so test settings go in a file too."""
    path = tmp_path / f"{node}_overrides.yaml"
    path.write_text(yaml.safe_dump({f"/**/{node}": {"ros__parameters": values}}))
    return str(path)


class Rig:
    def __init__(self, spawn, tmp_path: Path, calibration: Path,
                 full_scale_topic: str = "/driver/full_scale_force",
                 world: dict[str, object] | None = None) -> None:
        self.adc = tmp_path / "adc"
        self.servo = tmp_path / "xm430"
        self.control = tmp_path / "xm430.ctl"
        self.mock = spawn(
            "--ros-args", "-r", "__node:=gripper_world",
            "--params-file", str(CONFIG / "physics.yaml"),
            "--params-file", str(CONFIG / "gripper.yaml"),
            "--params-file", overrides(tmp_path, "gripper_world", adc_link=str(self.adc),
                                       servo_link=str(self.servo),
                                       servo_control=str(self.control), seed=3,
                                       **(world or {})),
            module="tactile_sensor.nodes.mock_hardware")
        assert self.mock.wait_for_output("mock gripper ready", 120), self.mock.output()
        self.driver = spawn(
            "--ros-args", "-r", "__node:=driver", "--params-file", str(CONFIG / "sensor.yaml"),
            "--params-file", str(CONFIG / "gripper.yaml"),
            "--params-file", overrides(tmp_path, "driver", port=str(self.adc),
                                       calibration_source="file",
                                       calibration_file=str(calibration), autostart=True),
            module="tactile_sensor.nodes.driver")
        self.gripper = spawn(
            "--ros-args", "-r", "__node:=gripper", "-r", "tactile_wrench:=/driver/wrench",
            "-r", f"tactile_full_scale:={full_scale_topic}",
            "-r", "tactile_reading:=/driver/reading", "-r", "model_predict:=/model/predict",
            "--params-file", str(CONFIG / "gripper.yaml"),
            "--params-file", overrides(tmp_path, "gripper", port=str(self.servo),
                                       autostart=True, **GRIPPER_UNDER_LOAD),
            module="tactile_sensor.nodes.gripper")
        assert self.driver.wait_for_output("active", PATIENCE_S), self.driver.output()
        assert self.gripper.wait_for_output("active", PATIENCE_S), self.gripper.output()

    def inject(self, command: str) -> None:
        with self.control.open("w") as fifo:
            fifo.write(command + "\n")


class Client:
    def __init__(self) -> None:
        self.node = rclpy.create_node("gripper_test_client")
        self.grasp = RaceFreeActionClient(self.node, Grasp, "/gripper/grasp")
        self.release = RaceFreeActionClient(self.node, Release, "/gripper/release")
        #: More action clients a test adds, destroyed with these once the spin stops.
        self.more: list[RaceFreeActionClient] = []
        # (header stamp, force) of every sample: the record, ~/reading; the live ~/wrench
        # skips a backlog a starved driver works off, and a window of it can be empty
        self.force: list[tuple[float, float]] = []
        self.truth: list[tuple[float, float]] = []  # (header stamp, true force)
        self.opening: list[tuple[float, float]] = []
        self.effort: list[float] = []  # the force the gripper heard (nan: none yet)
        self.diagnostics: list[DiagnosticStatus] = []
        self.node.create_subscription(TactileReading, "/driver/reading",
                                      lambda m: self.force.append((_stamp(m), m.force)), 1000)
        self.node.create_subscription(WrenchStamped, "/gripper_world/ground_truth",
                                      lambda m: self.truth.append((_stamp(m),
                                                                   m.wrench.force.z)), 1000)
        self.node.create_subscription(JointState, "/gripper/joint_states", self._joint, 1000)
        self.node.create_subscription(
            DiagnosticArray, "/diagnostics",
            lambda m: self.diagnostics.extend(s for s in m.status if "XM430" in s.name), 100)
        self.executor = rclpy.executors.MultiThreadedExecutor(num_threads=2)
        self.executor.add_node(self.node)
        self.spin = BackgroundSpin(self.executor)
        assert self.grasp.wait_for_server(timeout_sec=PATIENCE_S)
        assert self.release.wait_for_server(timeout_sec=PATIENCE_S)

    def _joint(self, msg: JointState) -> None:
        self.effort.append(msg.effort[0])
        self.opening.append((_stamp(msg), msg.position[0]))

    def send(self, client: ActionClient, goal, feedback=None):
        future = client.send_goal_async(goal, feedback_callback=feedback)
        handle = _wait(future)
        assert handle.accepted
        return handle

    def refusal(self, client: ActionClient, goal) -> str:
        """The reason a goal the gripper cannot run ends with: accepted, then aborted at
        once with the reason in its result, the fingers untouched."""
        handle = self.send(client, goal)
        answer = _wait(handle.get_result_async())
        assert answer.status == GoalStatus.STATUS_ABORTED, answer
        assert math.isnan(answer.result.force) and math.isnan(answer.result.opening)
        return answer.result.message

    def wait_moving_from(self, rest: float) -> None:
        """Until the fingers have left ``rest`` (a goal is under way, not only accepted)."""
        _until(lambda: abs(self.opening[-1][1] - rest) > MOVED_M,
               "the fingers did not start moving")

    def close(self) -> None:
        self.spin.stop()
        # destroy_node() leaves action clients to the garbage collector, which may finalize
        # them in a later test, where Fast DDS can hang waiting for its event thread
        for action_client in (self.grasp, self.release, *self.more):
            action_client.destroy()
        self.node.destroy_node()


def _stamp(msg) -> float:
    return msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9


def _until(condition, what: str, timeout_s: float = PATIENCE_S, poll_s: float = 0.01) -> None:
    deadline = time.monotonic() + timeout_s
    while not condition():
        assert time.monotonic() < deadline, what
        time.sleep(poll_s)


def _wait(future, timeout_s: float = PATIENCE_S):
    _until(future.done, "timed out", timeout_s, poll_s=0.005)
    return future.result()


@contextlib.contextmanager
def connected(rig: Rig):
    """A client, once the gripper hears the tactile force."""
    with ros_session():
        client = Client()
        # the driver tares while the fingers are open and still
        _until(lambda: client.force and math.isfinite(client.force[-1][1]),
               rig.driver.output())
        # ... and the gripper must hear the force too before a grasp starts: a grasp sent
        # while discovery is still going aborts "tactile_stale" (force nan).
        # Its joint states carry the force it heard as the effort (nan before any).
        try:
            _until(lambda: client.effort and math.isfinite(client.effort[-1]),
                   "the gripper hears no force: " + rig.gripper.output())
            yield client
        finally:  # a failed test too: its spinning thread stops before the context ends
            client.close()


@pytest.fixture
def rig(spawn, ros_domain, tmp_path, calibration_file):
    rig = Rig(spawn, tmp_path, calibration_file)
    with connected(rig) as client:
        yield rig, client


def test_goals_the_gripper_cannot_hold_are_refused_one_within_is_reached_and_reported(
        rig, calibration_file):
    """A 1e9 N target was once accepted, and the fingers squeezed 27.9 N until the
    timeout while the sensor read its 6.77 N full scale. The driver's latched full scale
    and max_grasp_force now bound the target; an adaptive hold on this one-module fingertip
    (no shear) is refused too; a result states the force its field holds."""
    devices, client = rig
    full_scale = Calibration.from_file(calibration_file).full_scale_force_n
    assert devices.gripper.wait_for_output(f"tactile full scale {full_scale:.3g} N",
                                           PATIENCE_S), devices.gripper.output()
    ceiling = f"{(1 - SATURATION_BAND) * full_scale:.3g} N"
    sentence = ("invalid_goal: Grasp target force 1e+09 N is above the gripper's "
                f"force ceiling of {ceiling} (the smaller of max_grasp_force 10 N and "
                f"{ceiling}, from where the tactile sensor's readings saturate below its "
                f"{full_scale:.3g} N full scale); request at most {ceiling}.")
    assert client.refusal(client.grasp, Grasp.Goal(target_force=1e9)) == sentence
    assert devices.gripper.wait_for_output(f"grasp goal refused: {sentence}\n", PATIENCE_S), \
        devices.gripper.output()
    sentence = ("invalid_goal: An adaptive hold needs a fingertip that feels shear, "
                "and this gripper has none (shear_sensing is false); use configuration "
                "gripper_shear or hold_mode fixed.")
    assert client.refusal(client.grasp, Grasp.Goal(target_force=2.0,
                                                   hold_mode="adaptive")) == sentence

    feedback_times: list[float] = []
    handle = client.send(client.grasp, Grasp.Goal(target_force=2.0, closing_speed=0.01,
                                                  timeout=10.0),
                         lambda _: feedback_times.append(time.monotonic()))
    result = _wait(handle.get_result_async()).result
    assert result.contact_detected, result.message
    assert result.message.startswith("contact: contact at "), result.message
    assert result.message.endswith(f", settled at {result.force:.2f} N"), result.message
    # hold: let the filter settle on the held force for 0.5 s, then average 0.3 s of it
    # (by the samples' stamps: the window is there once its samples have arrived)
    done = time.time()
    _until(lambda: client.force[-1][0] >= done + 0.8, "the force stream stopped")
    held = [f for t, f in client.force if done + 0.5 <= t < done + 0.8]
    # within the hold's documented 0.3 N (docs/gripper.md; test_gripper_commands holds the
    # same): the settle judges 30 ms means of a force whose noise is correlated over
    # ~0.1 s, so the held force scatters about the target (beside three busy loops, 14
    # grasps held 1.88-2.17 N while their answers said 1.87-2.25 N)
    assert np.mean(held) == pytest.approx(2.0, abs=0.3), (np.mean(held), result.message)
    # streamed along the grasp (feedback_rate 50 Hz), not only at its end; the bound leaves
    # room for a busy machine (rates are for benchmarks/, not for a test)
    gaps = np.diff(feedback_times)
    assert len(feedback_times) > 5 and np.median(gaps) <= 0.2, gaps

    handle = client.send(client.release, Release.Goal(opening=0.0))
    released = _wait(handle.get_result_async()).result
    assert released.success, released.message
    assert released.opening == pytest.approx(0.060, abs=0.001)


def cancel_latency(client, send, trial: int):
    """(result, seconds) of one goal sent by ``send()`` (it closes the fingers) and
    canceled while the fingers move: cancel request sent -> fingers at rest, by the stamps
    of ~/joint_states (``rest_onset``)."""
    rest = client.opening[-1][1]
    handle = send()
    client.wait_moving_from(rest)  # under way, not only accepted
    time.sleep(0.015 * trial)  # cancel at different phases of the 100 Hz loop
    moving_before = client.opening[-1][1]
    canceled_at = time.time()
    cancel = _wait(handle.cancel_goal_async())
    answer = _wait(handle.get_result_async())
    assert cancel.goals_canceling, answer
    _until(lambda: rest_onset(client.opening, canceled_at, hold_s=0.3) is not None,
           "the fingers did not come to rest after the cancel")
    # it was closing (below where it started) and did not open again; a cancel that lands
    # before the fingers' next sample leaves the opening equal (seen beside a busy core)
    assert client.opening[-1][1] <= moving_before < rest
    return answer, rest_onset(client.opening, canceled_at, hold_s=0.3) - canceled_at


def check_latencies(latencies: list[float]) -> None:
    ms = np.array(latencies) * 1e3
    print(f"cancel -> fingers stopped (joint_states stamps), {len(ms)} cancels: median "
          f"{np.median(ms):.0f} ms, max {ms.max():.0f} ms ({np.round(ms).astype(int)})")
    # Stopped by the cancel, not by running on: at 10 mm/s the goals here would still be
    # closing seconds later. Issue #4's 50 ms is a latency, which a busy machine can
    # stretch: benchmarks/bench_gripper_cancel.py measures it, this test does not.
    assert ms.max() < 2000.0, ms


def test_a_grasp_timed_out_at_the_full_scale_backs_off_to_its_target(
        spawn, ros_domain, tmp_path, calibration_file):
    """The crushed object, and its safe end: a grasp accepted before the driver's
    range was known (its target above the full scale, within max_grasp_force) squeezes
    the rod far beyond the target while the sensor reads its full scale. When it times
    out it opens until the reading is below the full scale and the target: the mock
    world's true force ends at or below the target."""
    devices = Rig(spawn, tmp_path, calibration_file, full_scale_topic="/late/full_scale")
    full_scale = Calibration.from_file(calibration_file).full_scale_force_n
    target = 8.0
    with connected(devices) as client:
        rest = client.opening[-1][1]
        # the goal's timeout must come after the fingers saturate the reading: beside a load
        # of 11 they had not within 5 s
        handle = client.send(client.grasp, Grasp.Goal(target_force=target,
                                                      closing_speed=0.01, timeout=10.0))
        client.wait_moving_from(rest)
        # the driver's range arrives while the grasp runs
        latched = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL,
                             reliability=ReliabilityPolicy.RELIABLE)
        client.node.create_publisher(Float64, "/late/full_scale", latched).publish(
            Float64(data=full_scale))
        result = _wait(handle.get_result_async()).result
        done = time.time()
        # by the samples' stamps: under load they arrive late
        _until(lambda: client.truth and client.truth[-1][0] > done + 0.5,
               "no ground truth")
    # the target is beyond the full scale, so the back-off starts only from a saturated
    # reading: within SATURATION_BAND of the full scale (how far into the band depends on how
    # long the fingers had to squeeze: 6.27 N of 6.77 N once beside a busy core). Either the
    # grasp times out closing, or (readings late beside a busy core) its contact stop predicts
    # the target beyond the saturated reading and the hold runs out of settle_time there:
    # both end backed off.
    backed_off = re.fullmatch(r"(?:timeout: no result within 10 s|contact: contact at \S+ N, "
                              r"not settled within settle_time \(5 s\): holding \S+ N at the "
                              r"sensor's full scale); backed off from (\S+) N to "
                              + re.escape(f"{result.force:.2f}") + " N", result.message)
    assert backed_off and float(backed_off[1]) >= (1 - SATURATION_BAND) * full_scale, \
        result.message
    pressed = max(f for t, f in client.truth if t < done)
    after = [f for t, f in client.truth if t > done + 0.2]
    assert pressed > target and max(after) <= target, (pressed, after[:10], result.message)


def test_cancel_stops_the_fingers_promptly(rig):
    """Issue #4: cancel mid-grasp stops the fingers (promptly: benchmarks/
    bench_gripper_cancel.py measures the 50 ms). Measured from the moment the cancel
    request is sent to the first ~/joint_states sample that shows the fingers where they
    came to rest (its stamp is when the servo was read), over several cancels at different
    phases of the control loop. Moving again after the stop (a second stop elsewhere, a
    closing command after the stop) counts as not stopped."""
    devices, client = rig
    devices.inject("rod none")  # nothing to touch: the fingers keep closing until canceled
    latencies = []
    for trial in range(6):  # each grasp closes a few mm more; no release in between
        answer, latency = cancel_latency(
            client, lambda: client.send(client.grasp, Grasp.Goal(
                target_force=1.5, closing_speed=0.01, timeout=10.0)), trial)
        assert "cancel" in answer.result.message, answer.result.message
        latencies.append(latency)
    check_latencies(latencies)


def test_overload_aborts_with_the_decoded_reason_and_torque_off(rig):
    devices, client = rig
    devices.inject("rod none")
    rest = client.opening[-1][1]
    handle = client.send(client.grasp, Grasp.Goal(target_force=1.5, closing_speed=0.005,
                                                  timeout=10.0))
    client.wait_moving_from(rest)  # the fault comes mid-grasp
    devices.inject("fault overload")
    result = _wait(handle.get_result_async()).result
    assert not result.contact_detected
    assert "overload" in result.message, result.message
    _until(lambda: any(s.level == DiagnosticStatus.ERROR and "overload" in s.message
                       for s in client.diagnostics), "no overload diagnostics")
    assert devices.gripper.wait_for_output("torque off", PATIENCE_S), devices.gripper.output()
    # recovery by the ~/reboot service: a new grasp works again
    from std_srvs.srv import Trigger
    reboot = client.node.create_client(Trigger, "/gripper/reboot")
    assert reboot.wait_for_service(timeout_sec=PATIENCE_S)
    answer = _wait(reboot.call_async(Trigger.Request()))
    assert answer.success, answer.message


def test_a_second_goal_preempts_the_first(rig):
    devices, client = rig
    devices.inject("rod none")
    rest = client.opening[-1][1]
    first = client.send(client.grasp, Grasp.Goal(target_force=1.5, closing_speed=0.005,
                                                 timeout=10.0))
    client.wait_moving_from(rest)  # the first is under way, not only accepted
    second = client.send(client.release, Release.Goal(opening=0.0))
    first_result = _wait(first.get_result_async()).result
    assert "preempted" in first_result.message
    assert _wait(second.get_result_async()).result.success


def test_an_unreachable_servo_fails_configure_with_one_sentence(spawn, ros_domain, tmp_path):
    gripper = spawn("--ros-args", "-r", "__node:=gripper", "-p",
                    f"port:={tmp_path / 'no_such_port'}", "-p", "autostart:=true",
                    module="tactile_sensor.nodes.gripper")
    assert gripper.wait_for_output("configure transition failed", PATIENCE_S), \
        gripper.output()
    line = next(line for line in gripper.output().splitlines() if "configure failed" in line)
    assert "no_such_port" in line and "Traceback" not in gripper.output()



def test_an_idle_rate_above_the_control_rate_fails_configure_with_one_sentence(
        spawn, ros_domain, tmp_path):
    gripper = spawn("--ros-args", "-r", "__node:=gripper", "-p",
                    f"port:={tmp_path / 'no_such_port'}", "-p", "autostart:=true",
                    "-p", "idle_rate:=200.0", module="tactile_sensor.nodes.gripper")
    assert gripper.wait_for_output("configure transition failed", PATIENCE_S), \
        gripper.output()
    assert ("configure failed: idle_rate 200 Hz is above control_rate 100 Hz; lower "
            "idle_rate (e.g. 10).") in gripper.output()
    assert "Traceback" not in gripper.output()

def test_without_control_msgs_the_gripper_starts_and_says_which_actions_are_missing(
        spawn, ros_domain, tmp_path):
    """A ROS 2 with no control_msgs (hidden here by a package that refuses to import): the
    node comes up active with ~/grasp and ~/release and one warning naming the fix."""
    hidden = tmp_path / "hide" / "control_msgs"
    hidden.mkdir(parents=True)
    (hidden / "__init__.py").write_text("raise ImportError('control_msgs hidden by the test')\n")
    servo = tmp_path / "xm430"
    emulator = spawn("mock", "xm430", "--link", str(servo), "--baud", "1000000", "--no-world",
                     module="tactile_sensor.cli")
    assert emulator.wait_for_output("xm430: id 1", PATIENCE_S), emulator.output()
    shim = (f"import sys; sys.path.insert(0, {str(hidden.parent)!r}); "
            "from tactile_sensor.nodes.gripper import main; sys.exit(main())")
    # packet_timeout, comm_retries: as Rig's (a busy machine holds the emulator up)
    gripper = spawn(sys.executable, "-c", shim, "--ros-args", "-r", "__node:=gripper",
                    "-p", f"port:={servo}", "-p", "autostart:=true",
                    "-p", "packet_timeout:=0.5", "-p", "comm_retries:=4")
    assert gripper.wait_for_output("active", PATIENCE_S), gripper.output()
    output = gripper.output()
    warnings = [line for line in output.splitlines() if "[WARN]" in line]
    assert len(warnings) == 1 and "control_msgs is not installed" in warnings[0], output
    assert "ros-<distro>-control-msgs" in warnings[0] and "Traceback" not in output
    with ros_session():
        node = rclpy.create_node("probe")
        try:
            grasp = RaceFreeActionClient(node, Grasp, "/gripper/grasp")
            assert grasp.wait_for_server(timeout_sec=PATIENCE_S)
            names = {name for name, _ in get_action_names_and_types(node)}
            assert "/gripper/grasp" in names and "/gripper/gripper_cmd" not in names
            grasp.destroy()
        finally:
            node.destroy_node()



@contextlib.contextmanager
def probe(heard: list[JointState], depth: int = 10) -> Iterator[tuple[Any, Any, Any]]:
    """(node, a publisher of the gripper's tactile_wrench, its ~/grasp client) in a session
    of their own; ``heard`` collects the gripper's joint states."""
    with ros_session():
        node = rclpy.create_node("probe")
        try:
            force = node.create_publisher(WrenchStamped, "/tactile_wrench", 10)
            node.create_subscription(JointState, "/gripper/joint_states", heard.append, depth)
            grasp = RaceFreeActionClient(node, Grasp, "/gripper/grasp")
            assert grasp.wait_for_server(timeout_sec=PATIENCE_S)
            yield node, force, grasp
            grasp.destroy()
        finally:
            node.destroy_node()


def publish_force(node: Any, force: Any) -> None:
    """A zero force stamped now, as the driver publishes at rest."""
    msg = WrenchStamped()
    msg.header.stamp = node.get_clock().now().to_msg()
    force.publish(msg)


def test_a_grasp_on_a_stale_tactile_force_is_refused_in_one_sentence(
        spawn, ros_domain, tmp_path):
    """The driver went quiet, as it does while its detector is blind (no force then): a
    grasp is rejected before anything moves, naming why."""
    gripper = lone_gripper(spawn, tmp_path / "xm430", "-p", "autostart:=true")
    assert gripper.wait_for_output("active", PATIENCE_S), gripper.output()
    heard: list[JointState] = []
    with probe(heard) as (node, force, grasp):
        deadline = time.monotonic() + PATIENCE_S
        while not (heard and math.isfinite(heard[-1].effort[0])):  # the gripper heard it
            assert time.monotonic() < deadline, gripper.output()
            publish_force(node, force)
            rclpy.spin_once(node, timeout_sec=0.05)
        stale_since = time.monotonic()
        while time.monotonic() - stale_since < 0.5:  # > tactile_timeout (0.2 s)
            rclpy.spin_once(node, timeout_sec=0.05)
        future = grasp.send_goal_async(Grasp.Goal(target_force=1.0))
        rclpy.spin_until_future_complete(node, future, timeout_sec=PATIENCE_S)
        assert future.done() and future.result().accepted
        result = future.result().get_result_async()
        rclpy.spin_until_future_complete(node, result, timeout_sec=PATIENCE_S)
        assert result.done(), gripper.output()
        answer = result.result()
    assert answer.status == GoalStatus.STATUS_ABORTED
    assert answer.result.message.startswith("tactile_stale: the tactile force is ")
    assert "the sensor is blind or its stream stopped" in answer.result.message
    assert gripper.wait_for_output("grasp goal refused: tactile_stale: the tactile force is ",
                                   PATIENCE_S), gripper.output()


def test_a_grasp_sent_before_the_forces_flow_waits_for_the_first_one_without_moving(
        spawn, ros_domain, tmp_path):
    """Readiness (docs/gripper.md): the gripper is active before the driver publishes. A
    grasp then waits up to tactile_timeout for the first force, the fingers still: with none
    it aborts tactile_stale saying so; once forces come it closes."""
    gripper = lone_gripper(spawn, tmp_path / "xm430", "-p", "autostart:=true",
                           "-p", "tactile_timeout:=5.0")
    assert gripper.wait_for_output("active", PATIENCE_S), gripper.output()
    heard: list[JointState] = []
    with probe(heard, depth=100) as (node, force, grasp):
        deadline = time.monotonic() + PATIENCE_S
        while not heard:
            assert time.monotonic() < deadline, gripper.output()
            rclpy.spin_once(node, timeout_sec=0.05)
        rest = heard[-1].position[0]

        def send() -> Any:
            future = grasp.send_goal_async(Grasp.Goal(target_force=1.0, timeout=30.0))
            rclpy.spin_until_future_complete(node, future, timeout_sec=PATIENCE_S)
            assert future.done() and future.result().accepted
            return future.result()

        result = send().get_result_async()
        rclpy.spin_until_future_complete(node, result, timeout_sec=PATIENCE_S)
        assert result.done(), gripper.output()
        message = result.result().result.message
        assert re.fullmatch(r"tactile_stale: no tactile force came within 5\.\d{3} s of "
                            r"the goal \(tactile_timeout 5 s\), so the fingers did not "
                            r"move: .*", message), message
        assert all(abs(m.position[0] - rest) < MOVED_M for m in heard), "moved"
        handle = send()
        waited = len(heard)
        while len(heard) < waited + 10:  # the goal waits: its loop samples meanwhile
            rclpy.spin_once(node, timeout_sec=0.05)
        assert all(abs(m.position[0] - rest) < MOVED_M for m in heard), "moved"
        while abs(heard[-1].position[0] - rest) < MOVED_M:  # forces come: it closes
            assert time.monotonic() < deadline, gripper.output()
            publish_force(node, force)
            rclpy.spin_once(node, timeout_sec=0.01)
        cancel = handle.cancel_goal_async()
        rclpy.spin_until_future_complete(node, cancel, timeout_sec=PATIENCE_S)
    assert "Grasp goal aborted: tactile_stale: no tactile force came within" in \
        gripper.output()


def test_a_self_check_on_a_stiffer_skin_and_a_dimmer_emitter_corrects_the_driver(
        spawn, ros_domain, tmp_path, calibration_file):
    """The rod on a skin at 1.15 x the FEM's stiffness read by an emitter at 0.8: from
    2 mm short of the rod, one slow close fits both and latches the correction; the
    driver applies it over its calibration, reads the true force where the close stopped,
    and a grasp after it holds the true force it was asked for."""
    rig = Rig(spawn, tmp_path, calibration_file,
              world={"skin.stiffness_ratio": 1.15, "emitter.output_ratio": 0.8})
    model = spawn("--ros-args", "-r", "__node:=model", "-p", "autostart:=true",
                  "--params-file", str(CONFIG / "physics.yaml"),
                  module="tactile_sensor.nodes.model")
    assert model.wait_for_output("prediction ready", PATIENCE_S), model.output()
    with connected(rig) as client:
        corrections: list[CalibrationCorrection] = []
        client.node.create_subscription(
            CalibrationCorrection, "/calibration_correction", corrections.append,
            QoSProfile(depth=5, durability=DurabilityPolicy.TRANSIENT_LOCAL,
                       reliability=ReliabilityPolicy.RELIABLE))
        check = RaceFreeActionClient(client.node, SelfCheck, "/gripper/self_check")
        client.more.append(check)
        assert check.wait_for_server(timeout_sec=PATIENCE_S)
        # A close the machine starves (a busy core holding the mock, the driver or the
        # gripper for tenths of a second) is refused, not fitted wrong (docs/ambient.md:
        # too_uncertain, tactile_stale); its user closes again, and so does this test.
        for _ in range(3):
            opened = _wait(client.send(client.release, Release.Goal(opening=0.024))
                           .get_result_async()).result
            assert opened.success, opened.message
            end = _wait(client.send(check, SelfCheck.Goal(apply=True)).get_result_async(),
                        2 * PATIENCE_S).result
            if end.outcome == "fitted":
                break
            assert end.outcome in ("too_uncertain", "tactile_stale") and not end.applied, \
                end.message + rig.gripper.output()
        assert end.outcome == "fitted", end.message + rig.gripper.output()
        assert end.stiffness == pytest.approx(1.15, abs=0.03)
        assert end.optical_gain == pytest.approx(0.8, abs=0.03)
        assert end.applied
        _until(lambda: any(c.source.startswith("self_check:") for c in corrections),
               "no correction was latched")
        assert rig.driver.wait_for_output("corrected by self_check:gain=", PATIENCE_S), \
            rig.driver.output()
        # the fingers rest where the close stopped, about 2.4 mm into the skin: 0.3 s of
        # force against 0.3 s of the mock's truth, by their stamps, once both are there
        applied = time.time()
        window = (applied + 0.2, applied + 0.5)
        _until(lambda: client.force[-1][0] >= window[1] and client.truth[-1][0] >= window[1],
               "the force or the truth stopped")
        read = np.mean([f for t, f in client.force if window[0] <= t < window[1]])
        true = np.mean([f for t, f in client.truth if window[0] <= t < window[1]])
        assert true > 3.0 and read == pytest.approx(true, rel=0.04), (read, true)

        opened = _wait(client.send(client.release, Release.Goal(opening=0.024))
                       .get_result_async()).result
        assert opened.success, opened.message
        result = _wait(client.send(client.grasp, Grasp.Goal(
            target_force=3.0, closing_speed=0.01, timeout=10.0)).get_result_async()).result
        assert result.contact_detected, result.message
        done = time.time()
        _until(lambda: client.truth[-1][0] >= done + 0.8, "the truth stopped")
        # the true force held near the target: the hold settles on the driver's force, now
        # read through the correction. One grasp is asked within 10 %: even a calibrated
        # skin holds 19 of 20 grasps within 5 % at 3 N (bench_gripper's hold table, worst
        # -5.1 %; one here held 2.845 N), while with the FEM curve uncorrected this skin
        # would be held at about 4.35 N (+45 %: its output at 0.8, its force at 1.15)
        held = np.mean([f for t, f in client.truth if done + 0.5 <= t < done + 0.8])
        assert held == pytest.approx(3.0, rel=0.10), (held, result.message)
