"""Gripper node: an XM430 on a rack and pinion, closed until the tactile force says contact.

Wiring only: parameters, the XM430 client (hardware/), the tactile force subscription,
the driver's latched full-scale force (the goals' force ceiling), joint states,
diagnostics, the reboot service, the adaptive hold's ``~/slip`` events and five
action servers (``ACTIONS``, served in every lifecycle state): ``~/grasp``, ``~/release``,
control_msgs ``~/gripper_cmd`` and ``~/parallel_gripper_cmd``, and ``~/self_check``
(control/self_check_goal.py), which also reads the driver's module output
(``tactile_reading``), asks the model for its prediction (``model_predict``) and latches
its correction for the driver (``calibration_correction``;
sensing/calibration_correction.py).
What a goal means lives in control/actions.py; the goal policy (one active goal,
preemption, cancel, hardware errors, readiness) in control/goal_runner.py; the servo the
control loop, the goals and a cancel share in control/servo_link.py; the control loop's
thread, fast during a goal and at ``idle_rate`` otherwise, in control/servo_sampler.py.

Idle cost: the executor waits on the actions, services and parameters only. The tactile
subscriptions are in ``TakenByTheLoop``, a callback group the executor never runs, and
the loop takes what waits in them before each servo sample: a 250 Hz force stream cost an
executor round (the wait set of five action servers rebuilt) per message, 0.3 of a core.
``tactile_reading`` (the driver's record, every 1 kHz sample) is subscribed only while a
self-check runs, and taken as bytes: the self-check reads each one's stamp and output.

Goals are accepted and then aborted with the reason in the result when they cannot run
(not active, invalid, the force stale): a rejected goal's reason reached only this node's
log, never the client. The refusal is decided before the goal takes the fingers over, so a
refused goal preempts nothing. The action servers live as long as the node: destroying one
on cleanup raced the executor's wait set ("action server pointer is invalid").
"""

from __future__ import annotations

import math
import sys
import threading
import time
from typing import Any

from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import WrenchStamped
from rclpy.action import ActionServer, CancelResponse, GoalResponse
from rclpy.action.server import ServerGoalHandle
from rclpy.callback_groups import CallbackGroup, ReentrantCallbackGroup
from rclpy.duration import Duration
from rclpy.exceptions import InvalidHandle
from rclpy.lifecycle import State, TransitionCallbackReturn
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from rclpy.serialization import deserialize_message
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64
from std_srvs.srv import Trigger

from tactile_sensor.control.actions import (
    GoalSettings,
    accept_grasp,
    accept_gripper_command,
    accept_parallel_gripper_command,
    accept_release,
    settings_from_parameters,
)
from tactile_sensor.control.errors import ControlError
from tactile_sensor.control.goal_runner import (
    NOT_ACTIVE,
    FirstInput,
    GoalLink,
    GoalRunner,
    GoalSlot,
    GoalStatus,
    RunnerTiming,
    interrupted,
)
from tactile_sensor.control.grasp import Outcome
from tactile_sensor.control.self_check import DriveTrain, SelfCheckFit, SkinPrediction
from tactile_sensor.control.self_check_goal import SelfCheckLinks, accept_self_check
from tactile_sensor.control.servo_link import Poll, ServoLink, call_retrying
from tactile_sensor.control.servo_sampler import ServoSampler
from tactile_sensor.control.slip_hold import SlipEvent as SlipSeen
from tactile_sensor.control.tactile_force import TactileForce
from tactile_sensor.hardware.errors import DynamixelError
from tactile_sensor.hardware.xm430 import Xm430Client
from tactile_sensor.hardware.xm430_health import xm430_health
from tactile_sensor.nodes import calibration_correction_msg, self_check_links
from tactile_sensor.nodes.diagnostics_msg import diagnostic_array
from tactile_sensor.nodes.gripper_parameters import SPECS
from tactile_sensor.nodes.guarded_lifecycle import GuardedLifecycleNode
from tactile_sensor.nodes.lifecycle_main import run_lifecycle_node
from tactile_sensor.nodes.parameters import (
    ParameterError,
    declare_parameters,
    read_parameters,
)
from tactile_sensor.nodes.reading_decode import stamp_and_output
from tactile_sensor_interfaces.action import Grasp, Release, SelfCheck
from tactile_sensor_interfaces.msg import CalibrationCorrection, SlipEvent, TactileReading
from tactile_sensor_interfaces.srv import PredictOutput

#: The actions served, as ``~/<name>``: message type and the goal's meaning
#: (control/actions.py). A new interface is one more entry.
ACTIONS: dict[str, tuple[Any, Any]] = {
    "grasp": (Grasp, accept_grasp),
    "release": (Release, accept_release),
}
#: Why the control_msgs actions are not served (None: they are). A ROS 2 without
#: control_msgs still grasps through ~/grasp and ~/release.
CONTROL_MSGS_MISSING: str | None = None
try:
    from control_msgs.action import GripperCommand, ParallelGripperCommand
except ImportError:
    CONTROL_MSGS_MISSING = (
        "control_msgs is not installed, so ~/gripper_cmd and ~/parallel_gripper_cmd are not "
        "served (~/grasp and ~/release are): install ros-<distro>-control-msgs, or run "
        "'make setup', which builds it on the PyPI-wheels path.")
else:
    ACTIONS["gripper_cmd"] = (GripperCommand, accept_gripper_command)
    ACTIONS["parallel_gripper_cmd"] = (ParallelGripperCommand,
                                       accept_parallel_gripper_command)

#: Readings the ``tactile_reading`` subscription holds (1 s of the driver's 1 kHz).
READING_QUEUE_DEPTH = 1000
#: Forces the ``tactile_wrench`` subscription holds: 0.4 s of 250 Hz. A goal's hold reads
#: every one (taken each control tick); idle, the loop takes them every 1 / idle_rate s and
#: needs the newest alone.
FORCE_QUEUE_DEPTH = 100
#: Messages one take keeps at most per subscription and sample (the rest wait for the next).
TAKE_AT_MOST = 1000


class TakenByTheLoop(CallbackGroup):
    """Subscriptions the executor leaves alone: the control loop takes their messages."""

    def can_execute(self, entity: Any) -> bool:
        return False


#: The driver's ~/full_scale_force: latched, so a gripper started later still hears it.
FULL_SCALE_QOS = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL,
                            reliability=ReliabilityPolicy.RELIABLE)


class GripperNode(GuardedLifecycleNode):
    def __init__(self, node_name: str = "gripper", **kwargs: Any) -> None:
        super().__init__(node_name, **kwargs)
        declare_parameters(self, SPECS)
        self._values: dict[str, Any] = {}
        self._servo: ServoLink | None = None
        self._runner: GoalRunner | None = None
        self._settings: GoalSettings | None = None
        self._forces = TactileForce()
        self._slot = GoalSlot()
        self._last_diag = 0.0
        self._group = ReentrantCallbackGroup()
        self._taken = TakenByTheLoop()
        self._take_lock = threading.Lock()
        self._entities: list[Any] = []
        self._joint_pub = self._diag_pub = self._slip_pub = None
        self._sampler: ServoSampler | None = None
        self._force_sub: Any = None
        self._reading_sub: Any = None
        self._reading_users = 0
        self._output = self_check_links.LatestOutput()
        self._predict_client: Any = None
        self._correction_pub: Any = None
        #: Each action's goal -> active goal, as configured (None: not configured).
        self._accepts: dict[str, Any] = {}
        self._servers = [self._action_server(name, action_type)
                         for name, action_type in self._action_types().items()]

    @staticmethod
    def _action_types() -> dict[str, Any]:
        return {**{name: action_type for name, (action_type, _) in ACTIONS.items()},
                "self_check": SelfCheck}

    # -- lifecycle -------------------------------------------------------------------------
    def on_configure(self, state: State) -> TransitionCallbackReturn:
        try:
            values = read_parameters(self, SPECS)
            settings = settings_from_parameters(values)
        except (ParameterError, ValueError, ControlError) as exc:
            self.get_logger().error(f"configure failed: {exc}")
            return TransitionCallbackReturn.FAILURE
        period = 1.0 / values["control_rate"]
        if values["idle_rate"] > values["control_rate"]:
            self.get_logger().error(
                f"configure failed: idle_rate {values['idle_rate']:g} Hz is above "
                f"control_rate {values['control_rate']:g} Hz; lower idle_rate (e.g. 10).")
            return TransitionCallbackReturn.FAILURE
        client = Xm430Client(values["port"], values["baud_rate"], values["servo_id"],
                             timeout_s=values["packet_timeout"])
        servo = ServoLink(client, settings.config, period_s=period,
                          retries=values["comm_retries"])
        try:
            # a lost reply to the first ping is a bus fault like any other (comm_retries)
            call_retrying(client.connect, values["comm_retries"])
            servo.prepare(values["current_limit"])
        except DynamixelError as exc:
            client.close()
            self.get_logger().error(f"configure failed: {exc}")
            return TransitionCallbackReturn.FAILURE
        self._values, self._servo, self._settings = values, servo, settings
        self._sampler = ServoSampler(servo, idle_period_s=1.0 / values["idle_rate"],
                                     before=self._take_inputs, after=self._on_sample)
        self._runner = GoalRunner(
            servo, self._forces, self._slot,
            RunnerTiming(period, 1.0 / values["feedback_rate"], values["settle_time"]),
            on_hardware_error=self._on_hardware_error, log_error=self.get_logger().error,
            on_slip=self._on_slip, busy=self._sampler.busy)
        self._joint_pub = self.create_lifecycle_publisher(JointState, "~/joint_states", 10)
        self._diag_pub = self.create_publisher(DiagnosticArray, "/diagnostics", 10)
        self._slip_pub = self.create_publisher(SlipEvent, "~/slip", 10)
        self._force_sub = self.create_subscription(
            WrenchStamped, "tactile_wrench", self._on_force, FORCE_QUEUE_DEPTH,
            callback_group=self._taken)
        self._predict_client = self.create_client(PredictOutput, "model_predict",
                                                  callback_group=self._group)
        self._correction_pub = self.create_publisher(
            CalibrationCorrection, "calibration_correction", FULL_SCALE_QOS)
        links = SelfCheckLinks(
            lambda: self._output.fresh(time.monotonic(), settings.config.stale_after_s),
            self._predict, self._apply_correction,
            DriveTrain(settings.config.geometry, backlash_rad=values["self_check_backlash"],
                       compliance_m_per_n=values["self_check_compliance"]),
            servo.sampled_at, self._output.keep, self._output.kept)
        self._accepts = {**{name: accept for name, (_, accept) in ACTIONS.items()},
                         "self_check": lambda goal, s: accept_self_check(
                             goal, s, links, values["self_check_speed"])}
        self._entities = [
            self._force_sub,
            self.create_subscription(Float64, "tactile_full_scale", self._on_full_scale,
                                     FULL_SCALE_QOS, callback_group=self._group),
            self.create_service(Trigger, "~/reboot", self._on_reboot,
                                callback_group=self._group),
        ]
        if CONTROL_MSGS_MISSING is not None:
            self.get_logger().warning(CONTROL_MSGS_MISSING)
        self.get_logger().info(
            f"configured: XM430 id {values['servo_id']} on {values['port']} at "
            f"{values['baud_rate']} bit/s (firmware {client.firmware_version})")
        return TransitionCallbackReturn.SUCCESS

    def on_activate(self, state: State) -> TransitionCallbackReturn:
        assert self._servo is not None
        try:
            self._servo.hold_here(torque=True)
        except DynamixelError as exc:
            self.get_logger().error(f"activate failed: {exc}")
            return TransitionCallbackReturn.FAILURE
        assert self._sampler is not None
        self._sampler.start()
        return super().on_activate(state)

    def on_deactivate(self, state: State) -> TransitionCallbackReturn:
        self._slot.abort_active(interrupted("the gripper node was deactivated"))
        if self._sampler is not None:
            self._sampler.stop()
        if self._servo is not None and (error := self._servo.torque_off()) is not None:
            self.get_logger().warn(f"torque off failed: {error}")
        return super().on_deactivate(state)

    def on_cleanup(self, state: State) -> TransitionCallbackReturn:
        self._teardown()
        return TransitionCallbackReturn.SUCCESS

    def on_shutdown(self, state: State) -> TransitionCallbackReturn:
        self._slot.abort_active(interrupted("the gripper node is shutting down"))
        self._teardown()
        return TransitionCallbackReturn.SUCCESS

    def _teardown(self) -> None:
        if self._sampler is not None:
            self._sampler.stop()
        self._unsubscribe_readings(everyone=True)
        self._accepts = {}
        for entity in self._entities:
            if hasattr(entity, "topic_name"):
                self.destroy_subscription(entity)
            else:
                self.destroy_service(entity)
        self._entities = []
        self._force_sub = self._reading_sub = None
        if self._predict_client is not None:
            self.destroy_client(self._predict_client)
        if self._correction_pub is not None:
            self.destroy_publisher(self._correction_pub)
        self._predict_client = self._correction_pub = None
        if self._joint_pub is not None:
            self.destroy_lifecycle_publisher(self._joint_pub)
        for publisher in (self._diag_pub, self._slip_pub):
            if publisher is not None:
                self.destroy_publisher(publisher)
        self._joint_pub = self._diag_pub = self._slip_pub = None
        if self._servo is not None:
            self._servo.client.close()  # type: ignore[attr-defined]
        self._servo = self._runner = self._sampler = None

    # -- servo loop (control/servo_sampler.py's thread) --------------------------------------
    def _on_sample(self, poll: Poll) -> None:
        servo = self._servo
        if servo is None:
            return
        if poll.state is None:
            if poll.lost:
                self.get_logger().error(f"servo unreachable: {poll.error}")
            self._publish_diagnostics()
            return
        read_at = self.get_clock().now() - Duration(nanoseconds=int(poll.half_trip_s * 1e9))
        if poll.recovered:
            self.get_logger().info("servo answers again")
        if poll.new_hardware_error:
            self._on_hardware_error(poll.new_hardware_error)
        # effort = the tactile force [N], as in the control_msgs results (docs/gripper.md)
        force, geometry = self._forces.latest, servo.config.geometry
        msg = JointState(name=[self._values["joint_name"]],
                         position=[geometry.opening_m(poll.state.position_rad)],
                         velocity=[geometry.opening_rate_m_s(poll.state.velocity_rad_s)],
                         effort=[force[0] if force else math.nan])
        msg.header.stamp = read_at.to_msg()
        if self._joint_pub is not None:
            self._joint_pub.publish(msg)
        if time.monotonic() - self._last_diag >= 1.0:
            self._publish_diagnostics()

    def _on_hardware_error(self, bits: frozenset[str]) -> None:
        self.get_logger().error(f"servo hardware error: {', '.join(sorted(bits))}; torque off")
        assert self._servo is not None
        if (error := self._servo.torque_off()) is not None:
            self.get_logger().error(f"torque off failed: {error}")
        self._publish_diagnostics(bits)
        if self._values.get("auto_reboot"):
            threading.Thread(target=self._reboot, daemon=True).start()

    def _publish_diagnostics(self, bits: frozenset[str] | None = None) -> None:
        self._last_diag = time.monotonic()
        servo = self._servo
        if self._diag_pub is None or servo is None:
            return
        health = xm430_health(servo.hardware_error if bits is None else bits,
                              servo.comm_error, servo.state)
        self._diag_pub.publish(diagnostic_array(
            f"{self.get_fully_qualified_name()}: XM430",
            f"{self._values.get('port')} id {self._values.get('servo_id')}", health,
            self.get_clock().now().to_msg()))

    # -- tactile ------------------------------------------------------------------------------
    def _take_inputs(self) -> None:
        """What waits in the tactile subscriptions, taken before each servo sample (and as
        a goal is accepted): a goal's tick after the sample sees the newest force."""
        with self._take_lock:
            # taken as bytes: idle, only the newest is worth a message object (the hold's
            # sums are begun afresh by the goal that reads them); a goal gets every one
            raw = _take(self._force_sub, WrenchStamped, raw=True)
            sampler = self._sampler
            if raw and not (sampler is not None and sampler.goal_running):
                raw = raw[-1:]
            forces = [deserialize_message(data, WrenchStamped) for data in raw]
            if forces:
                self._on_force(forces[0], forces[1:])
            # the record's every sample (1 kHz) during a self-check: as bytes, read for
            # its stamp and output alone (nodes/reading_decode.py), no message object each
            readings = _take(self._reading_sub, TactileReading, raw=True)
            now = time.monotonic()
            for data in readings:
                stamp_s, output_v = stamp_and_output(data)
                self._output.add(output_v, now, stamp_s)

    def _on_force(self, msg: WrenchStamped, more: list[WrenchStamped] | None = None) -> None:
        """``msg`` and the ``more`` that came after it: the newest, and the sums the hold
        and the adaptive hold read."""
        total, count, first = msg.wrench.force.z, 1, msg.header.stamp
        shear_x, shear_y = msg.wrench.force.x, msg.wrench.force.y
        for msg in more or ():
            total += msg.wrench.force.z
            shear_x += msg.wrench.force.x
            shear_y += msg.wrench.force.y
            count += 1
        stamp = msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9
        self._forces.add(msg.wrench.force.z, stamp, total, count,
                         first.sec + first.nanosec * 1e-9)
        self._forces.add_wrench(total, shear_x, shear_y, count)

    def _on_slip(self, event: SlipSeen) -> None:
        if self._slip_pub is None:
            return
        msg = SlipEvent(kind=str(event.kind), margin=event.margin_n,
                        friction=event.friction, grip=event.grip_n)
        msg.header.stamp = self.get_clock().now().to_msg()
        self._slip_pub.publish(msg)

    def _subscribe_readings(self) -> None:
        """The module output, for a self-check only: 1 kHz the idle gripper has no use for.
        The self-check pairs every reading by its stamp: a deep queue loses none."""
        with self._take_lock:
            self._reading_users += 1
            if self._reading_sub is None:
                self._reading_sub = self.create_subscription(
                    TactileReading, "tactile_reading", lambda msg: None,
                    READING_QUEUE_DEPTH, callback_group=self._taken)

    def _first_output(self, stale_after_s: float) -> FirstInput:
        """A self-check waits for the module output as a grasp for the force (its
        subscription is new: discovery takes a moment)."""
        def fresh_within(limit_s: float) -> bool:
            return self._output.fresh(time.monotonic(), limit_s) is not None
        return FirstInput(lambda: fresh_within(stale_after_s), lambda: fresh_within(math.inf),
                          ("module output", "tactile_reading", "~/reading"))

    def _unsubscribe_readings(self, everyone: bool = False) -> None:
        """One self-check is done with the readings (``everyone``: all are, teardown); the
        last one destroys the subscription."""
        with self._take_lock:
            self._reading_users = 0 if everyone else max(self._reading_users - 1, 0)
            sub = None
            if self._reading_users == 0:
                sub, self._reading_sub = self._reading_sub, None
        if sub is not None:
            self.destroy_subscription(sub)

    # -- self-check ---------------------------------------------------------------------------
    def _predict(self) -> SkinPrediction:
        return self_check_links.fetch_prediction(self._predict_client, PredictOutput.Request())

    def _apply_correction(self, fit: SelfCheckFit, prediction: SkinPrediction) -> None:
        del prediction  # the factors are against it; the driver scales its own curve
        correction = self_check_links.correction_of(
            fit, self.get_clock().now().nanoseconds * 1e-9)
        self._correction_pub.publish(calibration_correction_msg.to_msg(correction))
        self.get_logger().info(f"self-check applied: {correction.source}")

    def _on_full_scale(self, msg: Float64) -> None:
        settings = self._settings
        if settings is None:
            return
        try:
            self._settings = settings.with_full_scale(msg.data)
        except ControlError as exc:
            self.get_logger().error(str(exc))
            return
        self._forces.full_scale_n = msg.data  # a running goal's back-off reads it here
        if settings.full_scale_force_n != msg.data:
            self.get_logger().info(
                f"tactile full scale {msg.data:.3g} N: goals may ask up to "
                f"{self._settings.force_ceiling_n:.3g} N (max_grasp_force "
                f"{settings.max_grasp_force_n:g} N)")

    # -- actions -----------------------------------------------------------------------------
    def _action_server(self, name: str, action_type: Any) -> ActionServer:
        return ActionServer(
            self, action_type, f"~/{name}",
            lambda handle: self._execute(handle, name, action_type),
            goal_callback=lambda goal: GoalResponse.ACCEPT,
            cancel_callback=self._on_cancel, callback_group=self._group)

    def _refusal(self, name: str, goal: Any) -> str | None:
        """Why ``goal`` cannot run now, in one sentence (None: it may), decided before it
        takes the fingers over."""
        accept, settings = self._accepts.get(name), self._settings
        if (accept is None or settings is None or self._sampler is None
                or not self._sampler.running):
            return (f"{Outcome.INACTIVE}: the gripper is not active; activate it "
                    f"(ros2 lifecycle set {self.get_name()} activate).")
        try:
            accept(goal, settings)
        except ControlError as exc:
            return f"{Outcome.INVALID_GOAL}: {exc}"
        if name != "grasp":
            return None
        self._take_inputs()  # the newest force, not the one the idle loop took last
        stale = self._forces.stale_refusal(time.time(), settings.config.stale_after_s)
        return None if stale is None else f"{Outcome.TACTILE_STALE}: {stale}"

    def _on_cancel(self, goal_handle: ServerGoalHandle) -> CancelResponse:
        """Stop the fingers here and now; the goal's loop then reports it canceled."""
        if self._runner is not None:
            self._runner.stop(goal_handle)
        return CancelResponse.ACCEPT

    def _execute(self, goal_handle: ServerGoalHandle, name: str, action_type: Any) -> Any:
        refusal = self._refusal(name, goal_handle.request)
        runner, settings, accept = self._runner, self._settings, self._accepts.get(name)
        if refusal is None and (runner is None or settings is None or accept is None):
            refusal = NOT_ACTIVE  # deactivated meanwhile
        if refusal is not None:
            goal_handle.abort()
            self.get_logger().error(f"{name} goal refused: {refusal}")
            return _refused(action_type.Result(), refusal)
        link = GoalLink(goal_handle, lambda: goal_handle.is_cancel_requested,
                        lambda fields: goal_handle.publish_feedback(
                            _message(action_type.Feedback, fields)))
        reads_output = action_type is SelfCheck
        first = None
        if reads_output:
            self._subscribe_readings()
            first = self._first_output(settings.config.stale_after_s)
        try:
            end = runner.run(link, lambda: accept(goal_handle.request, settings), first)
        finally:
            if reads_output:
                self._unsubscribe_readings()
        if end.status is GoalStatus.SUCCEEDED:
            goal_handle.succeed()
        elif end.status is GoalStatus.CANCELED:
            goal_handle.canceled()
        else:
            goal_handle.abort()
            self.get_logger().warning(f"{action_type.__name__} goal aborted: {end.message}")
        if end.result is None:
            return action_type.Result()
        return _message(action_type.Result, end.result)

    # -- recovery ----------------------------------------------------------------------------
    def _reboot(self) -> tuple[bool, str]:
        runner = self._runner
        if runner is None:
            return False, "the gripper is not configured"
        try:
            runner.reboot(self._values["current_limit"])
        except DynamixelError as exc:
            self.get_logger().error(f"reboot failed: {exc}")
            return False, str(exc)
        self.get_logger().info("servo rebooted, hardware error cleared, torque on")
        self._publish_diagnostics(frozenset())
        return True, "rebooted; hardware error cleared"

    def _on_reboot(self, request: Trigger.Request, response: Trigger.Response
                   ) -> Trigger.Response:
        response.success, response.message = self._reboot()
        return response


def _take(subscription: Any, message_type: Any, raw: bool = False) -> list[Any]:
    """The messages waiting in ``subscription`` (None: none), oldest first (``raw``: as
    their serialized bytes)."""
    if subscription is None:
        return []
    taken: list[Any] = []
    try:
        with subscription.handle:
            while len(taken) < TAKE_AT_MOST:
                item = subscription.handle.take_message(message_type, raw)
                if item is None:
                    break
                taken.append(item[0])
    except InvalidHandle:  # destroyed meanwhile (cleanup): nothing more to take
        pass
    return taken


def _refused(result: Any, reason: str) -> Any:
    """A refused goal's result: the reason where the interface has a message, and NaN for
    the measurements it never took (control_msgs results carry no message: the status and
    this node's log say it)."""
    for name in ("force", "opening", "optical_gain", "stiffness", "friction"):
        if hasattr(result, name):
            setattr(result, name, math.nan)
    if hasattr(result, "message"):
        result.message = reason
    if hasattr(result, "outcome"):
        result.outcome = reason.split(":", 1)[0]
    return result


def _message(message_type: Any, fields: dict[str, Any]) -> Any:
    """A message from a dict of its fields (nested dicts for nested messages)."""
    message = message_type()
    for name, value in fields.items():
        if isinstance(value, dict):
            value = _message(type(getattr(message, name)), value)
        setattr(message, name, value)
    return message


#: The GIL switch interval of the gripper process [s]. Its threads (executor, control loop,
#: tactile callbacks, the running goal) each do little per wake-up; with Python's default
#: 5 ms a cancel can wait several intervals for the GIL before its stop reaches the bus.
SWITCH_INTERVAL_S = 1e-3


def main(args: list[str] | None = None) -> int:
    sys.setswitchinterval(SWITCH_INTERVAL_S)
    return run_lifecycle_node(GripperNode, args)


if __name__ == "__main__":
    sys.exit(main())
