"""Gripper node: an XM430 on a rack and pinion, closed until the tactile force says contact.

Wiring only: parameters, the XM430 client (hardware/), the tactile force subscription,
joint states, diagnostics, and four action servers (``ACTIONS``) whose meaning lives in
control/actions.py: ``~/grasp``, ``~/release``, control_msgs ``~/gripper_cmd`` and
``~/parallel_gripper_cmd``. One generic runner executes them all.

Goal policy, the same for every action: invalid goals are rejected before anything moves;
one goal is active; a newer goal of any kind *preempts* the running one (it ends aborted
with "preempted by a newer goal"), so a manipulation stack can always release what it is
grasping without canceling first; cancel stops the fingers where they are; a servo hardware
error aborts with the decoded reason and turns the torque off.
"""

from __future__ import annotations

import math
import sys
import threading
import time
from typing import Any

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import WrenchStamped
from rclpy.action import ActionServer, CancelResponse, GoalResponse
from rclpy.action.server import ServerGoalHandle
from rclpy.callback_groups import MutuallyExclusiveCallbackGroup, ReentrantCallbackGroup
from rclpy.duration import Duration
from rclpy.lifecycle import Node, State, TransitionCallbackReturn
from sensor_msgs.msg import JointState
from std_srvs.srv import Trigger

from tactile_sensor.control.actions import (
    ActiveGoal,
    GoalSettings,
    Snapshot,
    accept_grasp,
    accept_gripper_command,
    accept_parallel_gripper_command,
    accept_release,
)
from tactile_sensor.control.errors import ControlError
from tactile_sensor.control.geometry import GripperGeometry
from tactile_sensor.control.grasp import (
    ForceSettler,
    GraspConfig,
    Outcome,
    Phase,
    ServoCommand,
    Step,
)
from tactile_sensor.control.stop import stop_position_rad
from tactile_sensor.hardware.errors import (
    CommunicationTimeout,
    CorruptPacket,
    DynamixelError,
    ServoHardwareError,
)
from tactile_sensor.hardware.xm430 import ServoState, Xm430Client
from tactile_sensor.hardware.xm430_table import OperatingMode
from tactile_sensor.nodes.lifecycle_main import run_lifecycle_node
from tactile_sensor.nodes.parameters import (
    ParameterError,
    ParamSpec,
    declare_parameters,
    read_parameters,
)
from tactile_sensor_interfaces.action import Grasp, Release

SPECS = [
    ParamSpec("port", "/dev/ttyUSB0", "serial device of the Dynamixel bus (U2D2)"),
    ParamSpec("baud_rate", 1_000_000, "Dynamixel bus baud rate [bit/s]", minimum=9600,
              maximum=4_500_000),
    ParamSpec("servo_id", 1, "Dynamixel id of the XM430", minimum=0, maximum=252),
    ParamSpec("geometry.pitch_radius", 0.014, "pinion pitch radius [m] (servo angle -> "
              "finger travel)", minimum=0.0, exclusive_minimum=True, maximum=0.2),
    ParamSpec("geometry.open_opening", 0.060, "finger opening at the open limit [m]",
              minimum=0.0, exclusive_minimum=True, maximum=1.0),
    ParamSpec("geometry.closed_opening", 0.002, "finger opening at the closed limit [m]",
              minimum=0.0, maximum=1.0),
    ParamSpec("current_limit", 1.0, "servo current limit and holding current cap [A]",
              minimum=0.0, exclusive_minimum=True, maximum=3.2),
    ParamSpec("closing_current", 0.6, "goal current while closing and holding [A] (<= "
              "current_limit)", minimum=0.0, exclusive_minimum=True, maximum=3.2),
    ParamSpec("default_closing_speed", 0.01, "finger speed when a goal gives 0 [m/s]",
              minimum=0.0, exclusive_minimum=True, maximum=0.2),
    ParamSpec("release_speed", 0.02, "finger speed while releasing [m/s]", minimum=0.0,
              exclusive_minimum=True, maximum=0.2),
    ParamSpec("default_timeout", 10.0, "grasp/release timeout when a goal gives 0 [s]",
              minimum=0.0, exclusive_minimum=True),
    ParamSpec("control_rate", 100.0, "servo sync-read and control loop rate [Hz]",
              minimum=1.0, maximum=1000.0),
    ParamSpec("tactile_timeout", 0.2, "abort a grasp when the tactile force is older "
              "than this [s]", minimum=0.0, exclusive_minimum=True),
    ParamSpec("feedback_rate", 50.0, "action feedback rate [Hz]", minimum=1.0,
              maximum=1000.0),
    ParamSpec("auto_reboot", False, "reboot the servo by itself after a hardware error"),
    ParamSpec("settle_time", 1.0, "after contact, regulate the force onto the target for "
              "at most this long [s] (0 = hold where contact was detected)", minimum=0.0,
              maximum=10.0),
    ParamSpec("skin_stiffness", 2500.0, "fingertip skin stiffness the settling step assumes "
              "[N/m] (FEM: ~7 N over 3 mm)", minimum=1.0),
    ParamSpec("packet_timeout", 0.05, "wait this long for a status packet [s]", minimum=0.001,
              maximum=1.0),
    ParamSpec("comm_retries", 2, "retries of a transaction that timed out or arrived "
              "damaged before the servo counts as unreachable", minimum=0, maximum=10),
    ParamSpec("joint_name", "finger_opening", "name of the finger-opening joint in "
              "~/joint_states, the URDF and ParallelGripperCommand goals"),
    ParamSpec("goal_tolerance", 0.0005, "a GripperCommand within this of its target "
              "position has reached it [m]", minimum=0.0, exclusive_minimum=True,
              maximum=0.01),
    ParamSpec("stall_timeout", 0.2, "a GripperCommand at rest short of its target this "
              "long has stalled [s]", minimum=0.0, exclusive_minimum=True, maximum=10.0),
    ParamSpec("allow_stalling", True, "a stalled GripperCommand (tactile force limit or "
              "current limit) succeeds; false: it aborts"),
]

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


class GripperNode(Node):
    def __init__(self, node_name: str = "gripper", **kwargs: Any) -> None:
        super().__init__(node_name, **kwargs)
        declare_parameters(self, SPECS)
        self._values: dict[str, Any] = {}
        self._client: Xm430Client | None = None
        self._config: GraspConfig | None = None
        self._settings: GoalSettings | None = None
        self._state: ServoState | None = None
        #: The control loop's latest sample, when the servo took it (monotonic [s]) and half
        #: that read's round trip (how long a packet takes to reach the servo) [s].
        self._sample: tuple[ServoState, float, float] | None = None
        self._comm_error = ""
        self._hw_error: frozenset[str] = frozenset()
        self._force: tuple[float, float] | None = None  # (force [N], stamp [s])
        self._goal_lock = threading.Lock()
        # Orders goal commands against the stop of a cancel: once a goal's stop is written,
        # no command of that goal's loop may follow it and restart the fingers.
        self._command_lock = threading.Lock()
        self._halted: ServerGoalHandle | None = None
        self._stop_written: ServerGoalHandle | None = None
        #: The goal last written and when (monotonic [s]): a sample older than the last
        #: command does not tell how the output moves now.
        self._heading_to_rad: float | None = None
        self._commanded_at = 0.0
        self._active_goal: ServerGoalHandle | None = None
        self._abort_reason = "preempted by a newer goal"
        self._last_diag = 0.0
        self._state_event = threading.Event()
        self._group = ReentrantCallbackGroup()
        self._loop_group = MutuallyExclusiveCallbackGroup()
        self._entities: list[Any] = []
        self._joint_pub = self._diag_pub = self._timer = None
        self._force_sub: Any = None
        self._force_sum, self._force_count = 0.0, 0

    # -- lifecycle -------------------------------------------------------------------------
    def on_configure(self, state: State) -> TransitionCallbackReturn:
        try:
            values = read_parameters(self, SPECS)
            if values["closing_current"] > values["current_limit"]:
                raise ParameterError(
                    f"Parameter 'closing_current' = {values['closing_current']} A exceeds "
                    f"'current_limit' = {values['current_limit']} A; lower it.")
            geometry = GripperGeometry(
                pitch_radius_m=values["geometry.pitch_radius"],
                open_opening_m=values["geometry.open_opening"],
                closed_opening_m=values["geometry.closed_opening"])
            config = GraspConfig(geometry=geometry,
                                 closing_current_a=values["closing_current"],
                                 hold_current_a=values["closing_current"],
                                 stale_after_s=values["tactile_timeout"])
            settings = goal_settings(config, values)
        except (ParameterError, ValueError, ControlError) as exc:
            self.get_logger().error(f"configure failed: {exc}")
            return TransitionCallbackReturn.FAILURE
        client = Xm430Client(values["port"], values["baud_rate"], values["servo_id"],
                             timeout_s=values["packet_timeout"])
        try:
            client.connect()
            self._retrying(lambda: self._prepare_servo(client, values))
        except DynamixelError as exc:
            client.close()
            self.get_logger().error(f"configure failed: {exc}")
            return TransitionCallbackReturn.FAILURE
        self._values, self._client, self._config = values, client, config
        self._settings = settings
        self._joint_pub = self.create_lifecycle_publisher(JointState, "~/joint_states", 10)
        self._diag_pub = self.create_publisher(DiagnosticArray, "/diagnostics", 10)
        self._force_sub = self.create_subscription(
            WrenchStamped, "tactile_wrench", self._on_force, 100, callback_group=self._group)
        self._entities = [
            self._force_sub,
            *(self._action_server(name, action_type, accept)
              for name, (action_type, accept) in ACTIONS.items()),
            self.create_service(Trigger, "~/reboot", self._on_reboot,
                                callback_group=self._group),
        ]
        if CONTROL_MSGS_MISSING is not None:
            self.get_logger().warning(CONTROL_MSGS_MISSING)
        self.get_logger().info(
            f"configured: XM430 id {values['servo_id']} on {values['port']} at "
            f"{values['baud_rate']} bit/s (firmware {client.firmware_version})")
        return TransitionCallbackReturn.SUCCESS

    @staticmethod
    def _prepare_servo(client: Xm430Client, values: dict[str, Any]) -> None:
        client.set_torque(False)
        client.set_operating_mode(OperatingMode.CURRENT_BASED_POSITION)
        client.set_current_limit_a(values["current_limit"])

    def on_activate(self, state: State) -> TransitionCallbackReturn:
        assert self._client is not None
        try:
            self._retrying(lambda: self._hold_here(torque=True))
        except DynamixelError as exc:
            self.get_logger().error(f"activate failed: {exc}")
            return TransitionCallbackReturn.FAILURE
        self._timer = self.create_timer(1.0 / self._values["control_rate"], self._loop,
                                        callback_group=self._loop_group)
        return super().on_activate(state)

    def on_deactivate(self, state: State) -> TransitionCallbackReturn:
        self._abort_active("the gripper node was deactivated")
        if self._timer is not None:
            self.destroy_timer(self._timer)
            self._timer = None
        if self._client is not None:
            try:
                self._client.set_torque(False)
            except DynamixelError as exc:
                self.get_logger().warn(f"torque off failed: {exc}")
        return super().on_deactivate(state)

    def on_cleanup(self, state: State) -> TransitionCallbackReturn:
        self._teardown()
        return TransitionCallbackReturn.SUCCESS

    def on_shutdown(self, state: State) -> TransitionCallbackReturn:
        self._abort_active("the gripper node is shutting down")
        self._teardown()
        return TransitionCallbackReturn.SUCCESS

    def _teardown(self) -> None:
        if self._timer is not None:
            self.destroy_timer(self._timer)
            self._timer = None
        for entity in self._entities:
            if isinstance(entity, ActionServer):
                entity.destroy()
            elif hasattr(entity, "topic_name"):
                self.destroy_subscription(entity)
            else:
                self.destroy_service(entity)
        self._entities = []
        self._force_sub = None
        if self._joint_pub is not None:
            self.destroy_lifecycle_publisher(self._joint_pub)
        if self._diag_pub is not None:
            self.destroy_publisher(self._diag_pub)
        self._joint_pub = self._diag_pub = None
        if self._client is not None:
            self._client.close()
        self._client = None

    # -- servo loop (timer) ------------------------------------------------------------------
    def _retrying(self, call: Any) -> Any:
        """A lost or damaged status packet is retried: one bad packet on a busy bus must not
        abort a grasp. Hardware errors and anything else pass straight through."""
        retries = self._values.get("comm_retries", 2)
        for attempt in range(retries + 1):
            try:
                return call()
            except (CommunicationTimeout, CorruptPacket):
                if attempt == retries:
                    raise
        raise AssertionError("unreachable")

    def _loop(self) -> None:
        client = self._client
        if client is None:
            return
        try:
            before = time.monotonic()
            state = self._retrying(client.read_state)
            after = time.monotonic()
            # the servo sampled its state between request and reply: stamp the middle
            half = 0.5 * (after - before)
            read_at = self.get_clock().now() - Duration(nanoseconds=int(half * 1e9))
        except DynamixelError as exc:
            if not self._comm_error:
                self.get_logger().error(f"servo unreachable: {exc}")
            self._comm_error = str(exc)
            self._publish_diagnostics()
            return
        if self._comm_error:
            self.get_logger().info("servo answers again")
        self._comm_error = ""
        self._state = state
        self._sample = (state, after - half, half)
        self._state_event.set()
        if state.hardware_error and state.hardware_error != self._hw_error:
            self._on_hardware_error(state.hardware_error)
        self._hw_error = state.hardware_error
        assert self._config is not None
        # effort = the tactile force [N], as in the control_msgs results (docs/gripper.md)
        force = self._force
        geometry = self._config.geometry
        msg = JointState(name=[self._values["joint_name"]],
                         position=[geometry.opening_m(state.position_rad)],
                         velocity=[geometry.opening_rate_m_s(state.velocity_rad_s)],
                         effort=[force[0] if force else math.nan])
        msg.header.stamp = read_at.to_msg()
        if self._joint_pub is not None:
            self._joint_pub.publish(msg)
        if time.monotonic() - self._last_diag >= 1.0:
            self._publish_diagnostics()

    def _on_hardware_error(self, bits: frozenset[str]) -> None:
        self.get_logger().error(f"servo hardware error: {', '.join(sorted(bits))}; torque off")
        assert self._client is not None
        try:
            self._client.set_torque(False)
        except DynamixelError as exc:
            self.get_logger().error(f"torque off failed: {exc}")
        self._publish_diagnostics(bits)
        if self._values.get("auto_reboot"):
            threading.Thread(target=self._reboot, daemon=True).start()

    def _publish_diagnostics(self, bits: frozenset[str] | None = None) -> None:
        self._last_diag = time.monotonic()
        if self._diag_pub is None:
            return
        bits = self._hw_error if bits is None else bits
        status = DiagnosticStatus(name=f"{self.get_fully_qualified_name()}: XM430",
                                  hardware_id=f"{self._values.get('port')} id "
                                  f"{self._values.get('servo_id')}")
        if bits:
            status.level = DiagnosticStatus.ERROR
            status.message = "hardware error: " + ", ".join(sorted(bits))
        elif self._comm_error:
            status.level, status.message = DiagnosticStatus.ERROR, self._comm_error
        else:
            status.level, status.message = DiagnosticStatus.OK, "ready"
        state = self._state
        if state is not None:
            status.values = [KeyValue(key=k, value=v) for k, v in (
                ("position_rad", f"{state.position_rad:.4f}"),
                ("current_a", f"{state.current_a:.3f}"),
                ("input_voltage_v", f"{state.input_voltage_v:.1f}"),
                ("temperature_c", f"{state.temperature_c:.0f}"),
                ("hardware_error", ",".join(sorted(bits)) or "none"))]
        array = DiagnosticArray(status=[status])
        array.header.stamp = self.get_clock().now().to_msg()
        self._diag_pub.publish(array)

    # -- commands ---------------------------------------------------------------------------
    def _send(self, command: ServoCommand | None,
              goal_handle: ServerGoalHandle | None = None) -> None:
        """Write a goal's command, unless that goal has been stopped by a cancel."""
        client = self._client
        if command is None or client is None:
            return
        with self._command_lock:
            if goal_handle is not None and self._halted is goal_handle:
                return
            self._retrying(lambda: client.command_position(
                command.goal_position_rad, command.profile_velocity_rad_s,
                goal_current_a=command.goal_current_a))
            self._heading_to_rad = command.goal_position_rad
            self._commanded_at = time.monotonic()

    def _hold_here(self, torque: bool = False) -> None:
        assert self._client is not None and self._config is not None
        state = self._client.read_state()
        self._state = state
        if torque:
            self._client.set_torque(True)
        self._client.command_position(state.position_rad, self._config.stop_velocity_rad_s,
                                      goal_current_a=self._config.hold_current_a)
        self._heading_to_rad = state.position_rad
        self._commanded_at = time.monotonic()

    def _stop(self, goal_handle: ServerGoalHandle) -> None:
        """Stop the fingers where they are now, in ONE write when the control loop's last
        sample is fresh (its position carried forward by velocity x age; see control/stop.py),
        else read the servo first. Later commands of this goal are dropped."""
        client, config = self._client, self._config
        assert client is not None and config is not None
        with self._command_lock:
            self._halted = goal_handle
            goal = None
            sample = self._sample
            if (sample is not None and not sample[0].hardware_error
                    and sample[1] > self._commanded_at):
                state, sampled_at, half = sample
                period = 1.0 / self._values["control_rate"]
                # where the output will be when the write reaches the servo
                lands_at = time.monotonic() + min(half, 0.5 * period)
                goal = stop_position_rad(
                    state.position_rad, state.velocity_rad_s, lands_at - sampled_at,
                    max_age_s=3.0 * period, heading_to_rad=self._heading_to_rad)
            if goal is None:
                state = self._retrying(client.read_state)
                goal = state.position_rad
            self._retrying(lambda: client.command_position(
                goal, config.stop_velocity_rad_s, goal_current_a=config.hold_current_a))
            self._heading_to_rad = goal
            self._commanded_at = time.monotonic()
            self._stop_written = goal_handle

    # -- tactile ------------------------------------------------------------------------------
    def _on_force(self, msg: WrenchStamped) -> None:
        # At 1 kHz one executor round per message costs more than the message: take what
        # else is already waiting and keep only the newest.
        sub = self._force_sub
        total, count = msg.wrench.force.z, 1
        if sub is not None:
            with sub.handle:
                for _ in range(256):
                    item = sub.handle.take_message(WrenchStamped, False)
                    if item is None:
                        break
                    msg = item[0]
                    total += msg.wrench.force.z
                    count += 1
        stamp = msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9
        self._force = (msg.wrench.force.z, stamp)
        with self._goal_lock:
            self._force_sum += total
            self._force_count += count

    def _mean_force_since_last_call(self) -> float | None:
        """Mean of the forces received since the previous call (the settler's input: one
        tick's samples averaged, so it acts on the force rather than on its noise)."""
        with self._goal_lock:
            total, count = self._force_sum, self._force_count
            self._force_sum, self._force_count = 0.0, 0
        return total / count if count else None

    # -- actions -----------------------------------------------------------------------------
    def _action_server(self, name: str, action_type: Any, accept: Any) -> ActionServer:
        return ActionServer(
            self, action_type, f"~/{name}",
            lambda handle: self._execute(handle, action_type, accept),
            goal_callback=lambda goal: self._on_goal(name, goal, accept),
            cancel_callback=self._on_cancel, callback_group=self._group)

    def _on_goal(self, name: str, goal: Any, accept: Any) -> GoalResponse:
        """Invalid goals are rejected before anything moves, with one sentence."""
        if self._settings is None or self._timer is None:
            self.get_logger().error(f"{name} goal rejected: the gripper is not active; "
                                    f"activate it (ros2 lifecycle set {self.get_name()} "
                                    "activate).")
            return GoalResponse.REJECT
        try:
            accept(goal, self._settings)
        except ControlError as exc:
            self.get_logger().error(f"{name} goal rejected: {exc}")
            return GoalResponse.REJECT
        return GoalResponse.ACCEPT

    def _on_cancel(self, goal_handle: ServerGoalHandle) -> CancelResponse:
        """Stop the fingers here and now; the goal's loop then reports it canceled."""
        if not self._superseded(goal_handle) and self._client is not None:
            try:
                self._stop(goal_handle)
            except (DynamixelError, ControlError) as exc:
                self.get_logger().error(f"stop on cancel failed: {exc}")
        return CancelResponse.ACCEPT

    def _take_over(self, goal_handle: ServerGoalHandle) -> None:
        with self._goal_lock:
            self._active_goal = goal_handle
            self._abort_reason = "preempted by a newer goal"

    def _superseded(self, goal_handle: ServerGoalHandle) -> bool:
        with self._goal_lock:
            return self._active_goal is not goal_handle

    def _abort_active(self, reason: str) -> None:
        with self._goal_lock:
            self._active_goal = None
            self._abort_reason = reason

    def _snapshot(self, step: Step) -> Snapshot:
        force, state, config = self._force, self._state, self._config
        assert config is not None
        velocity = (config.geometry.opening_rate_m_s(state.velocity_rad_s)
                    if state is not None else math.nan)
        return Snapshot(step, force[0] if force else math.nan, velocity)

    def _execute(self, goal_handle: ServerGoalHandle, action_type: Any, accept: Any) -> Any:
        """The loop every action shares: start, tick at the control rate, finish."""
        self._take_over(goal_handle)
        goal: ActiveGoal | None = None

        def finish(step: Step | None, succeeded: bool, message: str) -> Any:
            if succeeded:
                goal_handle.succeed()
            else:
                goal_handle.abort()
                self.get_logger().warning(f"{action_type.__name__} goal aborted: {message}")
            if goal is None:  # deactivated between acceptance and execution
                return action_type.Result()
            if step is None:  # never started: report where the fingers are
                opening = (self._config.geometry.opening_m(self._state.position_rad)
                           if self._config and self._state else math.nan)
                step = Step(Phase.IDLE, None, None, message, opening)
            return _message(action_type.Result, goal.result(self._snapshot(step), message))

        if self._state is None or self._client is None or self._settings is None:
            return finish(None, False, "the gripper is not active")
        try:
            goal = accept(goal_handle.request, self._settings)
            if self._hw_error:
                raise ServoHardwareError("servo hardware error: "
                                         + ", ".join(sorted(self._hw_error)), self._hw_error)
            if not self._retrying(self._client.torque_enabled):
                self._retrying(lambda: self._hold_here(torque=True))
            step = goal.start(time.time(), self._state)
            self._send(step.command, goal_handle)
        except (ControlError, DynamixelError) as exc:
            return finish(None, False, str(exc))

        def feedback(step: Step) -> None:
            goal_handle.publish_feedback(
                _message(action_type.Feedback, goal.feedback(self._snapshot(step))))

        period = 1.0 / self._values["control_rate"]
        feedback_period = 1.0 / self._values["feedback_rate"]
        last_feedback = 0.0
        while not step.finished:
            if goal_handle.is_cancel_requested:
                step = goal.cancel(time.time(), self._state)
                if self._stop_written is not goal_handle:  # the cancel callback's stop failed
                    try:
                        self._stop(goal_handle)
                    except (DynamixelError, ControlError) as exc:
                        self.get_logger().error(f"stop on cancel failed: {exc}")
                goal_handle.canceled()
                return _message(action_type.Result, goal.result(
                    self._snapshot(step), "canceled: stopped where the fingers were"))
            if self._superseded(goal_handle):
                # no stop command: the newer goal (or the reboot) owns the servo now
                return finish(goal.cancel(time.time(), self._state), False, self._abort_reason)
            self._state_event.clear()
            self._state_event.wait(2 * period)
            if self._comm_error:
                return finish(step, False, f"servo unreachable: {self._comm_error}")
            force = self._force
            step = goal.tick(time.time(), force[0] if force else None,
                             force[1] if force else None, self._state)
            if not self._send_safely(step.command, goal_handle):
                return finish(step, False, f"servo unreachable: {self._comm_error}")
            now = time.monotonic()
            if now - last_feedback >= feedback_period:
                feedback(step)
                last_feedback = now
        settler = goal.settler(step)
        if settler is not None:
            aborted = self._settle(goal_handle, settler, step, feedback, period)
            if aborted is not None:
                return finish(step, False, aborted)
        if step.outcome is Outcome.HARDWARE_ERROR:
            self._on_hardware_error(self._state.hardware_error)
        with self._goal_lock:
            if self._active_goal is goal_handle:
                self._active_goal = None
        failure = goal.failure(step)
        return finish(step, failure is None, failure or f"{step.outcome}: {step.message}")

    def _settle(self, goal_handle: ServerGoalHandle, settler: ForceSettler, step: Step,
                feedback: Any, period: float) -> str | None:
        """Regulate the force onto the target; an abort reason, or None when done."""
        assert self._config is not None
        deadline = time.monotonic() + self._values["settle_time"]
        self._mean_force_since_last_call()
        while time.monotonic() < deadline:
            if goal_handle.is_cancel_requested or self._superseded(goal_handle):
                return None  # the fingers hold where they are; the caller finishes
            self._state_event.clear()
            self._state_event.wait(2 * period)
            state, force = self._state, self._mean_force_since_last_call()
            if self._comm_error:
                return f"servo unreachable: {self._comm_error}"
            if state is None or state.hardware_error:
                return None
            if force is None:
                continue
            command, settled = settler.command(force, state, self._config.hold_current_a,
                                               self._config.stop_velocity_rad_s)
            if settled:
                return None
            if not self._send_safely(command, goal_handle):
                return f"servo unreachable: {self._comm_error}"
            feedback(step)
        return None

    def _send_safely(self, command: ServoCommand | None,
                     goal_handle: ServerGoalHandle | None = None) -> bool:
        try:
            self._send(command, goal_handle)
        except ServoHardwareError:
            return True  # the loop reports it through the state's hardware_error
        except DynamixelError as exc:
            self._comm_error = str(exc)
            return False
        return True

    # -- recovery ----------------------------------------------------------------------------
    def _reboot(self) -> tuple[bool, str]:
        client = self._client
        if client is None:
            return False, "the gripper is not configured"
        try:
            client.reboot()
            self._retrying(lambda: self._prepare_servo(client, self._values))
            self._hw_error = frozenset()
            self._retrying(lambda: self._hold_here(torque=True))
        except DynamixelError as exc:
            self.get_logger().error(f"reboot failed: {exc}")
            return False, str(exc)
        self.get_logger().info("servo rebooted, hardware error cleared, torque on")
        self._publish_diagnostics(frozenset())
        return True, "rebooted; hardware error cleared"

    def _on_reboot(self, request: Trigger.Request, response: Trigger.Response
                   ) -> Trigger.Response:
        self._abort_active("the servo is being rebooted")
        response.success, response.message = self._reboot()
        return response


def goal_settings(config: GraspConfig, values: dict[str, Any]) -> GoalSettings:
    """The parameters the goals read (control/actions.py)."""
    return GoalSettings(
        config=config, joint_name=values["joint_name"],
        closing_speed_m_s=values["default_closing_speed"],
        opening_speed_m_s=values["release_speed"], timeout_s=values["default_timeout"],
        goal_tolerance_m=values["goal_tolerance"], stall_time_s=values["stall_timeout"],
        allow_stalling=values["allow_stalling"],
        skin_stiffness_n_per_m=values["skin_stiffness"])


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


def main(args: list[str] | None = None) -> None:
    sys.setswitchinterval(SWITCH_INTERVAL_S)
    run_lifecycle_node(GripperNode, args)


if __name__ == "__main__":
    main()
