"""No request stops a node: each lifecycle node (driver, gripper, model) in its own process
takes every transition id 0-99 and a set of labels, valid or not, in every state, sent
through its real ``~/change_state``; each is done or refused exactly as the state machine
says, and the node answers ``~/get_state`` after each. The same walk sends, in every state,
parameter sets no node may take (wrong type, NaN, out of range, unknown name, a type rclpy
cannot read) and, on the gripper, malformed goals to every action; two ChangeStates sent
at once are one done, one refused. The node then ends with status 0 on SIGTERM. The
recorder, a plain node (no lifecycle, no ~/change_state), refuses the same parameter sets.

One process per node: the shutdown transition, which ends the walk, is taken from
'active' only (from 'unconfigured' and 'inactive' its ids are sent where they are invalid).
"""

from __future__ import annotations

import math
import signal
from pathlib import Path
from typing import Any

import pytest
import rclpy
from action_msgs.msg import GoalStatus
from lifecycle_msgs.srv import ChangeState, GetState
from lone_gripper import lone_gripper
from rcl_interfaces.msg import Parameter, ParameterType, ParameterValue
from rcl_interfaces.srv import SetParameters, SetParametersAtomically
from waiting import PATIENCE_S, wait_until

from tactile_sensor.configurations import config_dir
from tactile_sensor.nodes.action_client import RaceFreeActionClient
from tactile_sensor.nodes.background_spin import BackgroundSpin
from tactile_sensor.nodes.ros_session import ros_session
from tactile_sensor.sim.pty_link import PtyLink

pytestmark = [pytest.mark.ros]

#: Transition id -> the state it leads to, per state (lifecycle_msgs/msg/Transition).
VALID = {
    "unconfigured": {1: "inactive", 5: "finalized"},
    "inactive": {2: "unconfigured", 3: "active", 6: "finalized"},
    "active": {4: "inactive", 7: "finalized"},
    "finalized": {},
}
#: Labels sent in every state -> the state each leads to from where it is valid.
LABELS = {"configure": ("unconfigured", "inactive"), "cleanup": ("inactive", "unconfigured"),
          "activate": ("inactive", "active"), "deactivate": ("active", "inactive"),
          "transition_success": None, "transition_error": None, "on_configure": None,
          "fly": None}
#: The next transition towards a state: (from, to) -> id.
TOWARDS = {("unconfigured", "inactive"): 1, ("unconfigured", "active"): 1,
           ("inactive", "unconfigured"): 2, ("inactive", "active"): 3,
           ("active", "inactive"): 4, ("active", "unconfigured"): 4}


class Lifecycle:
    """The node's lifecycle services, called from the test's one client node."""

    def __init__(self, client: Any, name: str, process: Any) -> None:
        self.node, self.name, self.process = client, name, process
        self._change = client.create_client(ChangeState, f"/{name}/change_state")
        self._get = client.create_client(GetState, f"/{name}/get_state")
        assert self._change.wait_for_service(timeout_sec=PATIENCE_S), process.output()
        assert self._get.wait_for_service(timeout_sec=PATIENCE_S), process.output()
        # The first request of a new client can lose its answer while the middleware
        # matches the reply path: repeat harmless ones (get_state, a refused id) until heard.
        assert self._answer(self._get, GetState.Request(), retry=True)
        assert self._answer(self._change, _request(99), retry=True).success is False

    def _answer(self, client: Any, request: Any, retry: bool = False) -> Any:
        return answer(client, request, self.process, retry)

    def state(self) -> str:
        return self._answer(self._get, GetState.Request()).current_state.label

    def change(self, transition: int | str) -> bool:
        return self._answer(self._change, _request(transition)).success

    def both_at_once(self, transition: int) -> list[bool]:
        futures = [self._change.call_async(_request(transition)) for _ in range(2)]
        assert wait_until(lambda: all(f.done() for f in futures), PATIENCE_S, poll_s=0.002)
        return sorted(f.result().success for f in futures)

    def go(self, state: str) -> None:
        while (now := self.state()) != state:
            assert self.change(TOWARDS[now, state]), (now, state, self.process.output())


def answer(client: Any, request: Any, process: Any, retry: bool = False) -> Any:
    """The service's answer; ``retry`` repeats a request whose answer was lost (only for
    requests that change nothing, or that are refused whatever happened before)."""
    for _ in range(6 if retry else 1):
        future = client.call_async(request)
        if wait_until(future.done, 10.0 if retry else PATIENCE_S, poll_s=0.002):
            return future.result()
        client.remove_pending_request(future)
    raise AssertionError(f"{client.service_name} had no answer (the node still running: "
                         f"{process.proc.poll() is None})\n{process.output()}")


def _request(transition: int | str) -> ChangeState.Request:
    request = ChangeState.Request()
    if isinstance(transition, str):
        request.transition.label = transition
    else:
        request.transition.id = transition
    return request


def _value(kind: int, value: Any = None) -> ParameterValue:
    field = {ParameterType.PARAMETER_DOUBLE: "double_value",
             ParameterType.PARAMETER_STRING: "string_value",
             ParameterType.PARAMETER_INTEGER: "integer_value"}.get(kind)
    return ParameterValue(type=kind, **({field: value} if field else {}))


def bad_parameters(specs: list[Any]) -> list[Parameter]:
    """Values every node refuses, for each of ``specs`` (nodes/parameters.ParamSpec)."""
    double, string = ParameterType.PARAMETER_DOUBLE, ParameterType.PARAMETER_STRING
    unset = ParameterType.PARAMETER_NOT_SET
    params = [Parameter(name="no_such_parameter", value=_value(double, 1.0)),
              Parameter(name="autostart", value=_value(string, "yes")),
              Parameter(name="use_sim_time", value=_value(double, math.nan))]
    for spec in specs:
        kind = type(spec.default)
        values = [_value(unset)]
        if kind is float:
            values += [_value(double, math.nan), _value(double, math.inf),
                       _value(string, "1.0")]
        elif kind is int:
            values += [_value(double, 1.5), _value(string, "1")]
        elif kind is bool:
            values += [_value(ParameterType.PARAMETER_INTEGER, 1), _value(string, "true")]
        else:  # str, list
            values += [_value(double, 1.0)]
        if kind in (int, float) and spec.maximum is not None:
            values.append(_value(double if kind is float else ParameterType.PARAMETER_INTEGER,
                                 kind(spec.maximum * 10 + 1)))
        if kind in (int, float) and spec.minimum is not None:
            values.append(_value(double if kind is float else ParameterType.PARAMETER_INTEGER,
                                 kind(spec.minimum - 1)))
        if kind is str and spec.choices:
            values.append(_value(string, "none_of_the_choices"))
        params += [Parameter(name=spec.name, value=v) for v in values]
    return params


class ParameterFuzz:
    def __init__(self, node: Any, name: str, process: Any, specs: list[Any]) -> None:
        self.process, self.params = process, bad_parameters(specs)
        self._set = node.create_client(SetParameters, f"/{name}/set_parameters")
        self._atomic = node.create_client(SetParametersAtomically,
                                          f"/{name}/set_parameters_atomically")
        assert self._set.wait_for_service(timeout_sec=PATIENCE_S)
        assert self._atomic.wait_for_service(timeout_sec=PATIENCE_S)

    def check(self) -> None:
        """Every bad value refused with a reason; an unreadable type refused whole."""
        unreadable = Parameter(name=self.params[-1].name, value=ParameterValue(type=99))
        results = answer(self._set, SetParameters.Request(
            parameters=[*self.params, unreadable]), self.process, retry=True).results
        assert len(results) == len(self.params) + 1
        for param, result in zip([*self.params, unreadable], results, strict=True):
            assert not result.successful and result.reason, (param, result)
        atomic = answer(self._atomic, SetParametersAtomically.Request(
            parameters=[self.params[-1], unreadable]), self.process, retry=True).result
        assert not atomic.successful and "type 99" in atomic.reason, atomic


def leads_to(state: str, transition: int | str) -> str | None:
    """The state a transition leads to from ``state``; None where it is invalid."""
    if isinstance(transition, int):
        return VALID[state].get(transition)
    edge = LABELS[transition]
    return edge[1] if edge is not None and edge[0] == state else None


def walk(lifecycle: Lifecycle, in_every_state: Any = lambda state: None) -> None:
    """Every id 0-99 and every label in every state; ``in_every_state(state)`` once in each."""
    assert lifecycle.state() == "unconfigured"
    # two at once: one done, the other refused from the state the first left
    assert lifecycle.both_at_once(1) == [False, True]
    assert lifecycle.both_at_once(3) == [False, True]
    assert lifecycle.state() == "active"
    for state in ("unconfigured", "inactive", "active"):
        lifecycle.go(state)
        in_every_state(state)
        for transition in [*range(100), *LABELS]:
            lifecycle.go(state)
            goal = leads_to(state, transition)
            if goal == "finalized":
                continue  # the one way out: taken last, from 'active'
            done = lifecycle.change(transition)
            assert done == (goal is not None), (state, transition, lifecycle.process.output())
            assert lifecycle.state() == (goal or state), (state, transition)
    lifecycle.go("active")
    assert lifecycle.change("shutdown")
    assert lifecycle.state() == "finalized"
    in_every_state("finalized")
    for transition in [*range(100), *LABELS, "shutdown"]:
        assert not lifecycle.change(transition), transition
        assert lifecycle.state() == "finalized"
    assert lifecycle.process.proc.poll() is None


def ends_with_status_0_on_sigterm(process: Any) -> None:
    process.proc.send_signal(signal.SIGTERM)
    assert process.proc.wait(PATIENCE_S) == 0, process.output()[-3000:]
    assert "Traceback" not in process.output(), process.output()


@pytest.fixture
def client(ros_domain):
    with ros_session():
        node = rclpy.create_node("request_fuzz_client")
        executor = rclpy.executors.SingleThreadedExecutor()
        executor.add_node(node)
        spin = BackgroundSpin(executor)
        try:
            yield node
        finally:
            spin.stop()
            node.destroy_node()


def test_the_driver_takes_every_request_in_every_state(spawn, client, tmp_path: Path):
    from tactile_sensor.nodes.driver_parameters import SPECS

    adc = PtyLink(tmp_path / "adc")  # a device that sends nothing: configure needs a port
    adc.open()
    try:
        driver = spawn("--ros-args", "-r", "__node:=driver", "-p", f"port:={adc.link_path}",
                       module="tactile_sensor.nodes.driver")
        lifecycle = Lifecycle(client, "driver", driver)
        params = ParameterFuzz(client, "driver", driver, SPECS)
        walk(lifecycle, lambda state: params.check())
        ends_with_status_0_on_sigterm(driver)
    finally:
        adc.close()


def test_the_model_takes_every_request_in_every_state(spawn, client):
    from tactile_sensor.nodes.model import NODE_SPECS
    from tactile_sensor.nodes.physics_parameters import physics_specs

    model = spawn("--ros-args", "-r", "__node:=model",
                  "--params-file", str(config_dir() / "physics.yaml"),
                  module="tactile_sensor.nodes.model")
    lifecycle = Lifecycle(client, "model", model)
    params = ParameterFuzz(client, "model", model, physics_specs() + NODE_SPECS)
    walk(lifecycle, lambda state: params.check())
    ends_with_status_0_on_sigterm(model)


def malformed_goals() -> dict[str, list[Any]]:
    """Goals every gripper refuses, per action: NaN, infinities, negatives, huge values."""
    from control_msgs.action import GripperCommand, ParallelGripperCommand
    from control_msgs.msg import GripperCommand as Command
    from sensor_msgs.msg import JointState

    from tactile_sensor_interfaces.action import Grasp, Release, SelfCheck

    bad = [math.nan, math.inf, -math.inf, -1.0, 1e300]
    joint = "finger_opening"
    return {
        "grasp": [Grasp.Goal(target_force=v) for v in [*bad, 0.0]]
        + [Grasp.Goal(target_force=1.0, closing_speed=v) for v in bad]
        + [Grasp.Goal(target_force=1.0, timeout=v) for v in bad[:4]]  # 1e300 s: patient
        + [Grasp.Goal(target_force=1.0, hold_time=v) for v in [math.nan, -1.0]]
        + [Grasp.Goal(target_force=1.0, hold_mode="tight")],
        "release": [Release.Goal(opening=v) for v in bad],
        "gripper_cmd": [GripperCommand.Goal(command=Command(position=v)) for v in bad]
        + [GripperCommand.Goal(command=Command(position=0.02, max_effort=v))
           for v in [math.nan, math.inf, -1.0, 1e300]],
        "parallel_gripper_cmd": [
            ParallelGripperCommand.Goal(command=JointState(name=[joint], position=[v]))
            for v in bad] + [
            ParallelGripperCommand.Goal(command=JointState(name=[joint], position=[0.02],
                                                           velocity=[v], effort=[v]))
            for v in [math.nan, -1.0]] + [
            ParallelGripperCommand.Goal(command=JointState(name=["elbow"], position=[0.02])),
            ParallelGripperCommand.Goal(command=JointState(name=[joint]))],
        "self_check": [SelfCheck.Goal(closing_speed=v) for v in bad],
    }


class GoalFuzz:
    def __init__(self, node: Any, process: Any) -> None:
        from control_msgs.action import GripperCommand, ParallelGripperCommand

        from tactile_sensor_interfaces.action import Grasp, Release, SelfCheck

        types = {"grasp": Grasp, "release": Release, "gripper_cmd": GripperCommand,
                 "parallel_gripper_cmd": ParallelGripperCommand, "self_check": SelfCheck}
        self.process = process
        self.goals = malformed_goals()
        self.clients = {name: RaceFreeActionClient(node, types[name], f"/gripper/{name}")
                        for name in self.goals}

    def check(self, state: str) -> None:
        """In every state, every malformed goal is accepted and aborted at once: invalid
        while active, and 'not active' in the other states (the servers live as long as the
        node)."""
        reason = "invalid_goal" if state == "active" else "inactive"
        for name, goals in self.goals.items():
            client = self.clients[name]
            assert client.wait_for_server(timeout_sec=PATIENCE_S), self.process.output()
            for goal in goals:
                future = client.send_goal_async(goal)
                assert wait_until(future.done, PATIENCE_S, poll_s=0.002), (name, goal)
                assert future.result().accepted, (state, name, goal)
                result = future.result().get_result_async()
                assert wait_until(result.done, PATIENCE_S, poll_s=0.002), (name, goal)
                answer = result.result()
                assert answer.status == GoalStatus.STATUS_ABORTED, (state, name, goal)
                message = getattr(answer.result, "message", reason)
                assert message.startswith(reason), (state, name, goal, message)
        assert self.process.proc.poll() is None


def test_the_gripper_takes_every_request_and_goal_in_every_state(spawn, client,
                                                                 tmp_path: Path):
    from tactile_sensor.nodes.gripper_parameters import SPECS

    gripper = lone_gripper(spawn, tmp_path / "xm430")
    lifecycle = Lifecycle(client, "gripper", gripper)
    params = ParameterFuzz(client, "gripper", gripper, SPECS)
    goals = GoalFuzz(client, gripper)

    def in_every_state(state: str) -> None:
        params.check()
        goals.check(state)

    walk(lifecycle, in_every_state)
    output = gripper.output()
    for name in ("grasp", "release", "gripper_cmd", "self_check"):
        assert f"{name} goal refused: invalid_goal:" in output, name
        assert f"{name} goal refused: inactive:" in output, name
    ends_with_status_0_on_sigterm(gripper)


def test_the_recorder_refuses_parameter_sets_it_cannot_take(spawn, client, tmp_path: Path):
    from tactile_sensor.nodes.recorder import PARAMETERS

    recorder = spawn("--ros-args", "-p", f"path:={tmp_path / 'bag'}", "-p", "topics:=['/a']",
                     module="tactile_sensor.nodes.recorder")
    assert recorder.wait_for_output("Recording to", PATIENCE_S), recorder.output()
    ParameterFuzz(client, "recorder", recorder, list(PARAMETERS)).check()
    assert recorder.proc.poll() is None
    ends_with_status_0_on_sigterm(recorder)
