"""The generated ROS interface reference against the nodes themselves.

Each node is started in-process in every variant its reference lists and configured where
it is a lifecycle node; its endpoints (from the ROS graph) and declared parameters (with
their descriptors and defaults) must be exactly those its reference page lists. The pages
under docs/reference must be the ones the code renders now.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator
from contextlib import ExitStack
from pathlib import Path
from typing import Any

import pytest
from rclpy.action import get_action_server_names_and_types_by_node
from rclpy.lifecycle import TransitionCallbackReturn
from rclpy.node import Node
from rclpy.parameter import Parameter

from tactile_sensor.nodes import interface_reference as ref
from tactile_sensor.nodes.lifecycle_main import declare_autostart
from tactile_sensor.nodes.parameters import ParamSpec
from tactile_sensor.nodes.ros_session import ros_session
from tactile_sensor.sim.xm430_emulator import Xm430Emulator

REFERENCE_DIR = Path(__file__).resolve().parents[3] / "docs" / "reference"
BY_NAME = {node.name: node for node in ref.nodes()}
CASES = [(node.name, variant) for node in ref.nodes() for variant in node.variants]


@pytest.fixture
def ros(ros_domain: int) -> Iterator[None]:
    with ros_session():
        yield


def _overrides(values: dict[str, Any]) -> list[Parameter]:
    return [Parameter(name, value=value) for name, value in values.items()]


def _start(name: str, variant: str, tmp_path: Path, stack: ExitStack) -> Node:
    """The node constructed (and configured) as its executable would run it."""
    values = dict(BY_NAME[name].variants[variant])
    if name == "driver":
        from tactile_sensor.nodes.driver import DriverNode
        node: Node = DriverNode(parameter_overrides=_overrides(
            {"port": str(tmp_path / "no-adc-yet"), **values}))
    elif name == "model":
        from tactile_sensor.nodes.model import ModelNode
        node = ModelNode(parameter_overrides=_overrides(values))
    elif name == "gripper":
        from tactile_sensor.nodes.gripper import GripperNode
        emulator = stack.enter_context(Xm430Emulator(tmp_path / "xm430", baudrate=1_000_000))
        node = GripperNode(parameter_overrides=_overrides(
            {"port": str(emulator.link.link_path), **values}))
    elif name == "mock_hardware":
        from tactile_sensor.nodes.mock_hardware import MockHardwareNode
        node = MockHardwareNode(parameter_overrides=_overrides(
            {"adc_link": str(tmp_path / "adc"), "servo_link": str(tmp_path / "xm430"),
             "protocol.start_delay": -1.0, **values}))
        stack.callback(node.close_devices)
    else:
        from tactile_sensor.nodes.recorder import RecorderNode
        node = RecorderNode(parameter_overrides=_overrides(
            {"path": str(tmp_path / "bag"), "topics": ["/not_published"], **values}))
    stack.callback(node.destroy_node)
    if BY_NAME[name].lifecycle:
        declare_autostart(node)  # as lifecycle_main's executable does
        assert node.trigger_configure() == TransitionCallbackReturn.SUCCESS
        stack.callback(node.trigger_shutdown)
        stack.callback(node.trigger_cleanup)  # the model's cleanup waits for its FEM threads
    return node


def _settled(read: Callable[[], dict[str, list[str]]], expected: dict[str, list[str]],
             timeout_s: float = 10.0) -> dict[str, list[str]]:
    """What the graph shows once it equals ``expected``, or at the timeout (discovery of
    the node's own entities is asynchronous)."""
    deadline = time.monotonic() + timeout_s
    seen = read()
    while seen != expected and time.monotonic() < deadline:
        time.sleep(0.05)
        seen = read()
    return seen


def _own(pairs: list[tuple[str, list[str]]], standard: set[str]) -> dict[str, list[str]]:
    return {name: sorted(types) for name, types in pairs
            if name not in standard and "/_action/" not in name}


def _expected(node: Node, endpoints: list[ref.Endpoint], service: bool = False
              ) -> dict[str, list[str]]:
    resolve = node.resolve_service_name if service else node.resolve_topic_name
    return {resolve(e.name): [e.type] for e in endpoints}


@pytest.mark.parametrize(("name", "variant"), CASES, ids=[f"{n}-{v}" for n, v in CASES])
def test_every_endpoint_of_the_node_is_in_its_reference_and_no_other(
        ros: None, tmp_path: Path, name: str, variant: str) -> None:
    interface = BY_NAME[name]
    with ExitStack() as stack:
        node = _start(name, variant, tmp_path, stack)
        own, ns = node.get_name(), node.get_namespace()
        standard_topics = {node.resolve_topic_name(t) for t in ref.STANDARD_PUBLISHERS}
        standard_services = {node.resolve_service_name(s) for s in ref.STANDARD_SERVICES}
        checks = {
            "publishers": (lambda: _own(node.get_publisher_names_and_types_by_node(own, ns),
                                        standard_topics), False),
            "subscriptions": (lambda: _own(node.get_subscriber_names_and_types_by_node(
                own, ns), standard_topics), False),
            "services": (lambda: _own(node.get_service_names_and_types_by_node(own, ns),
                                      standard_services), True),
            "actions": (lambda: _own(get_action_server_names_and_types_by_node(node, own, ns),
                                     set()), False),
        }
        for kind, (read, service) in checks.items():
            expected = _expected(node, interface.endpoints(kind, variant), service)
            assert _settled(read, expected) == expected, (
                f"{name} ({variant}): its {kind} differ from docs/reference/{name}.md; "
                "update its entry in nodes/interface_reference.py")


def _value(value: Any) -> Any:
    return list(value) if isinstance(value, list | tuple) or hasattr(value, "tolist") else value


@pytest.mark.parametrize("name", list(BY_NAME))
def test_every_parameter_of_the_node_is_in_its_reference_as_declared(
        ros: None, tmp_path: Path, name: str) -> None:
    interface = BY_NAME[name]
    variant = next(iter(interface.variants))
    overridden = set(interface.variants[variant]) | {
        "port", "adc_link", "servo_link", "protocol.start_delay", "path", "topics"}
    with ExitStack() as stack:
        node = _start(name, variant, tmp_path, stack)
        declared = set(node.get_parameters_by_prefix("")) - ref.STANDARD_PARAMETERS
        listed = [spec.name for spec in interface.parameters]
        assert len(listed) == len(set(listed)), f"{name}: a parameter is listed twice"
        unlisted, absent = sorted(declared - set(listed)), sorted(set(listed) - declared)
        assert (unlisted, absent) == ([], []), (
            f"{name}: declared but not in docs/reference/{name}.md: {unlisted}; listed there "
            f"but not declared: {absent}")
        for spec in interface.parameters:
            descriptor = node.describe_parameter(spec.name)
            assert descriptor.description == spec.description, spec.name
            if spec.name not in overridden:
                assert _value(node.get_parameter(spec.name).value) == spec.default, spec.name


def test_the_driver_takes_at_run_time_exactly_the_parameters_its_reference_says(
        ros: None, tmp_path: Path) -> None:
    interface = BY_NAME["driver"]
    with ExitStack() as stack:
        node = _start("driver", "one module", tmp_path, stack)
        for spec in interface.parameters:
            applied = interface.applied[spec.name]
            if applied is ref.Applied.STARTUP:
                continue
            same = node.get_parameter(spec.name).value
            result = node.set_parameters([Parameter(spec.name, value=same)])[0]
            assert result.successful == (applied is ref.Applied.RUNTIME), (
                f"{spec.name}: reference says '{applied.value}', node says {result}")


def test_every_number_with_a_dimension_names_its_unit() -> None:
    missing = [f"{node.name}.{spec.name}" for node in ref.nodes() for spec in node.parameters
               if type(spec.default) is float and "[" not in spec.description]
    assert missing == []


def test_units_come_from_the_description_and_dimensionless_ones_show_none() -> None:
    assert ref.unit_of(ParamSpec("a", 1.0, "serial baud rate [bit/s] of the bus")) == "bit/s"
    assert ref.unit_of(ParamSpec("b", 1.0, "[m] skin width")) == "m"
    assert ref.unit_of(ParamSpec("c", 1, "[1] load steps")) == ""
    assert ref.unit_of(ParamSpec("d", [], "entries like ['/a=pkg/msg/T']")) == ""


def test_the_committed_reference_pages_are_the_ones_the_code_renders() -> None:
    for file_name, text in ref.pages().items():
        path = REFERENCE_DIR / file_name
        assert path.is_file() and path.read_text() == text, (
            f"docs/reference/{file_name} is stale: run 'make docs' (or python -m "
            "tactile_sensor.nodes.interface_reference docs/reference) and commit it")
    extra = {p.name for p in REFERENCE_DIR.glob("*.md")} - set(ref.pages())
    assert extra == set(), f"docs/reference has pages of no node: {sorted(extra)}"


def test_the_generator_without_a_folder_says_how_to_call_it(capsys) -> None:
    assert ref.main([]) == 2
    assert "usage: python -m tactile_sensor.nodes.interface_reference OUTPUT_DIR" in (
        capsys.readouterr().err)
