"""Build a launch description from a configuration (robots with a full ROS 2 install).

``launch/bench.launch.py`` and ``launch/gripper.launch.py`` call :func:`build`; the
in-process bringup reads the same :mod:`tactile_sensor.configurations`, so the two never
drift apart. ``launch`` and ``launch_ros`` are imported here only.
"""

from __future__ import annotations

import asyncio
from pathlib import Path
from typing import Any

import yaml
from launch import LaunchContext, LaunchDescription
from launch.actions import (
    DeclareLaunchArgument,
    EmitEvent,
    LogInfo,
    OpaqueCoroutine,
    OpaqueFunction,
    RegisterEventHandler,
)
from launch.events import matches_action
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import LifecycleNode, Node
from launch_ros.event_handlers import OnStateTransition
from launch_ros.events.lifecycle import ChangeState
from lifecycle_msgs.msg import Transition

from tactile_sensor.configurations import PACKAGE, Configuration, config_dir, config_files
from tactile_sensor.nodes.parameter_files import ParameterFileError, check_parameter_file

DEVICE_POLL_S = 0.05  # how often the launch looks for the mock rig's device links


class LaunchArgumentError(RuntimeError):
    """A launch argument cannot work; ``ros2 launch`` prints the message as one line."""


def _truthy(text: str) -> bool:
    return text.strip().lower() in ("true", "1", "yes", "on")


def _protocols(configuration: Configuration) -> dict[str, dict[str, Any]]:
    table = yaml.safe_load((config_dir() / "protocols.yaml").read_text()) or {}
    return table.get(configuration.name, {}) or {}


def build(configuration: Configuration) -> LaunchDescription:
    protocols = _protocols(configuration)
    arguments = [
        DeclareLaunchArgument("use_mock_hardware", default_value="true",
                              description="start mock devices on pseudo-terminals"),
        DeclareLaunchArgument("config", default_value="",
                              description="extra ROS parameter file applied after the defaults"),
        DeclareLaunchArgument("namespace", default_value="",
                              description="namespace of every node"),
        DeclareLaunchArgument("record", default_value="",
                              description="rosbag2 (MCAP) folder to record into; empty = none"),
        DeclareLaunchArgument("protocol", default_value=next(iter(protocols), ""),
                              description="protocol of the mock rig: " + ", ".join(protocols)),
        DeclareLaunchArgument("scenario", default_value="",
                              description="light of the ambient protocol: dark, office, "
                                          "sunlight or shadow; empty = the protocol's"),
    ]
    arguments += [DeclareLaunchArgument(name, default_value=default, description=text)
                  for name, (default, text) in configuration.ports.items()]
    return LaunchDescription([*arguments, OpaqueFunction(
        function=_nodes, args=[configuration, protocols])])


def _nodes(context: LaunchContext, configuration: Configuration,
           protocols: dict[str, dict[str, Any]]) -> list[Any]:
    use_mock = _truthy(LaunchConfiguration("use_mock_hardware").perform(context))
    extra = LaunchConfiguration("config").perform(context)
    namespace = LaunchConfiguration("namespace").perform(context)
    record = LaunchConfiguration("record").perform(context)
    protocol = LaunchConfiguration("protocol").perform(context)
    scenario = LaunchConfiguration("scenario").perform(context)
    ports = {name: LaunchConfiguration(name).perform(context) for name in configuration.ports}
    if protocol and protocol not in protocols:
        raise LaunchArgumentError(f"Unknown protocol '{protocol}'; choose one of "
                                  f"{', '.join(protocols)}.")
    if extra and not Path(extra).is_file():  # launch_ros would only warn and go on without it
        raise LaunchArgumentError(f"config:={extra} does not exist; give the path of a ROS "
                                  "parameter YAML file.")
    if extra:  # rclpy would ignore a parameter no node declares without a word
        try:
            check_parameter_file(Path(extra), configuration)
        except ParameterFileError as exc:
            raise LaunchArgumentError(f"config:={exc}") from None
    protocol_parameters = ({"protocol.name": protocol, **(protocols[protocol] or {})}
                           if protocol else {})
    if scenario:  # the mock refuses a name it does not know, in one sentence
        protocol_parameters["protocol.scenario"] = scenario
    actions: list[Any] = []
    mock: Node | None = None
    if record:
        ns = f"/{namespace.strip('/')}" if namespace.strip("/") else ""
        actions.append(Node(
            package=PACKAGE, executable="recorder_node", name="recorder", namespace=namespace,
            parameters=[{"path": record,
                         "topics": [ns + t for t in configuration.record_topics]}]))
    for spec in configuration.nodes:
        if spec.mock_only and not use_mock:
            continue
        parameters: list[Any] = [str(config_dir() / f) for f in config_files(spec, use_mock)]
        if extra:
            parameters.append(str(Path(extra)))
        parameters.append({param: ports[arg] for param, arg in spec.port_parameters})
        if spec.mock_only:
            parameters.append(protocol_parameters)
        common = dict(package=PACKAGE, executable=spec.executable, name=spec.name,
                      namespace=namespace, parameters=parameters,
                      remappings=list(spec.remappings), output="screen")
        if not spec.lifecycle:
            actions.append(Node(**common))
            if spec.mock_only:
                mock = actions[-1]
            continue
        node = LifecycleNode(**common)
        configure = ChangeState(lifecycle_node_matcher=matches_action(node),
                                transition_id=Transition.TRANSITION_CONFIGURE)
        devices = [ports[arg] for _, arg in spec.port_parameters]
        actions += [
            node,
            # only after configuring: a user's 'ros2 lifecycle set ... deactivate' stays
            RegisterEventHandler(OnStateTransition(
                target_lifecycle_node=node, start_state="configuring", goal_state="inactive",
                entities=[LogInfo(msg=f"{spec.name} configured, activating"),
                          EmitEvent(event=ChangeState(
                              lifecycle_node_matcher=matches_action(node),
                              transition_id=Transition.TRANSITION_ACTIVATE))])),
            OpaqueCoroutine(coroutine=_once_devices_exist, args=[configure, devices, mock])
            if mock is not None and devices else EmitEvent(event=configure),
        ]
    return actions


async def _once_devices_exist(context: LaunchContext, event: ChangeState, devices: list[str],
                              mock: Node) -> None:
    """Emit ``event`` once the mock rig has created ``devices``, so a node never opens a
    port before it exists (which it would report as an unplugged device). If the mock
    process ends first, the event goes out anyway and the node reports what is missing."""
    while mock.return_code is None and not all(Path(d).exists() for d in devices):
        await asyncio.sleep(DEVICE_POLL_S)
    await context.emit_event(event)
