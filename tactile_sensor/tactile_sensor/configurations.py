"""The bench and gripper configurations, defined once for launch files and the bringup.

Pure data, no rclpy and no launch imports: ``launch/*.launch.py`` turn these into
``LifecycleNode``/``Node`` actions on a robot with a full ROS 2 install, and
``tactile-sensor bringup`` composes the same node classes in one executor where
``launch`` is not installed. Change a configuration here and both follow.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field, replace
from pathlib import Path

PACKAGE = "tactile_sensor"


@dataclass(frozen=True)
class NodeSpec:
    """One node of a configuration."""

    name: str
    executable: str  # console script installed in lib/tactile_sensor (for ros2 run/launch)
    module: str  # python module holding the node class (for the in-process bringup)
    node_class: str
    config_files: tuple[str, ...]  # files under config/, applied in order
    # files under config/ applied after config_files, with mock hardware only: the emulated
    # devices are Python on the same host and answer later than real ones on a busy machine
    mock_config_files: tuple[str, ...] = ()
    lifecycle: bool = True
    mock_only: bool = False  # started only with use_mock_hardware
    remappings: tuple[tuple[str, str], ...] = ()
    # (parameter, launch argument): the node's device path parameters take the port arguments
    port_parameters: tuple[tuple[str, str], ...] = ()


@dataclass(frozen=True)
class Configuration:
    name: str
    description: str
    nodes: tuple[NodeSpec, ...]
    # launch argument -> (default with mock hardware, description)
    ports: dict[str, tuple[str, str]] = field(default_factory=dict)
    record_topics: tuple[str, ...] = ()


SENSOR_FILES = ("sensor.yaml",)

_MODEL = NodeSpec("model", "model_node", "tactile_sensor.nodes.model", "ModelNode",
                  ("physics.yaml", "model.yaml"))
_DRIVER = NodeSpec("driver", "driver_node", "tactile_sensor.nodes.driver", "DriverNode",
                   SENSOR_FILES, port_parameters=(("port", "adc_port"),))


def _mock_hardware(name: str, config_files: tuple[str, ...],
                   *port_parameters: tuple[str, str]) -> NodeSpec:
    """The emulated devices and their world, one plain node started only on mock hardware;
    ``port_parameters``: (its device link parameter, the port argument) pairs."""
    return NodeSpec(name, "mock_hardware_node", "tactile_sensor.nodes.mock_hardware",
                    "MockHardwareNode", config_files, lifecycle=False, mock_only=True,
                    port_parameters=port_parameters)


BENCH = Configuration(
    name="bench",
    description="The paper's compression bench: stage, force gauge and the tactile module.",
    nodes=(
        _mock_hardware("bench", ("physics.yaml", "bench.yaml"), ("adc_link", "adc_port")),
        _MODEL,
        _DRIVER,
    ),
    ports={"adc_port": ("/tmp/tactile_sensor/bench_adc",
                        "serial device of the photoreflector ADC")},
    record_topics=("/driver/reading", "/driver/wrench", "/bench/stage/joint_states",
                   "/bench/gauge/wrench", "/diagnostics", "/calibration_curve"),
)

GRIPPER = Configuration(
    name="gripper",
    description="The paper's soft gripper: XM430 on a rack, tactile module on a fingertip.",
    nodes=(
        _mock_hardware("gripper_world", ("physics.yaml", "gripper.yaml", "gripper_mock.yaml"),
                       ("adc_link", "adc_port"), ("servo_link", "servo_port")),
        _MODEL,
        replace(_DRIVER, config_files=(*SENSOR_FILES, "gripper.yaml")),
        NodeSpec("gripper", "gripper_node", "tactile_sensor.nodes.gripper", "GripperNode",
                 ("gripper.yaml",), mock_config_files=("gripper_mock.yaml",),
                 remappings=(("tactile_wrench", "driver/wrench"),
                             ("tactile_full_scale", "driver/full_scale_force"),
                             ("tactile_reading", "driver/reading"),
                             ("model_predict", "model/predict")),
                 port_parameters=(("port", "servo_port"),)),
    ),
    ports={"adc_port": ("/tmp/tactile_sensor/gripper_adc",
                        "serial device of the photoreflector ADC"),
           "servo_port": ("/tmp/tactile_sensor/gripper_xm430",
                          "serial device of the U2D2 (Dynamixel bus)")},
    record_topics=("/driver/reading", "/driver/wrench", "/gripper/joint_states",
                   "/gripper_world/ground_truth", "/diagnostics", "/calibration_correction"),
)


def _with_layout(base: Configuration, name: str, description: str,
                 ports: dict[str, tuple[str, str]],
                 more_topics: tuple[str, ...] = ()) -> Configuration:
    """``base`` with a module layout: each of its nodes also loads ``<name>.yaml`` (last, so
    that the layout's values win); ``more_topics`` are recorded beside the base's."""
    nodes = tuple(replace(node, config_files=(*node.config_files, f"{name}.yaml"))
                  for node in base.nodes)
    return replace(base, name=name, description=description, nodes=nodes, ports=ports,
                   record_topics=(*base.record_topics, *more_topics))


ARRAY = _with_layout(
    BENCH, "array",
    "Modules on four side faces of one skin on the bench, with a three-axis stage and gauge: "
    "normal and shear force (the paper's future work).",
    {"adc_port": ("/tmp/tactile_sensor/array_adc",
                  "serial device of the array's ADC (one channel per module)")},
)

WRENCH = _with_layout(
    BENCH, "wrench",
    "Two modules on each side face of one skin on the bench, with a stage that presses, "
    "shears, tilts and twists and a six-component gauge: force and torque (the paper's "
    "future work).",
    {"adc_port": ("/tmp/tactile_sensor/wrench_adc",
                  "serial device of the wrench layout's 8-input ADC (one channel per module)")},
)

GRIPPER_SHEAR = _with_layout(
    GRIPPER, "gripper_shear",
    "The soft gripper with modules on four side faces of finger A's skin: the grip and the "
    "force along the fingers.",
    {"adc_port": ("/tmp/tactile_sensor/gripper_shear_adc",
                  "serial device of finger A's ADC (one channel per module)"),
     "servo_port": ("/tmp/tactile_sensor/gripper_shear_xm430",
                    "serial device of the U2D2 (Dynamixel bus)")},
    more_topics=("/gripper_world/object/joint_states",),
)

BEND = Configuration(
    name="bend",
    description="A soft finger bending at its joint, a module clipped over the joint and one "
                "at the fingertip: the joint angle read from the skin outside "
                "(proprioception, the paper's suggested extension).",
    nodes=(
        # the driver fits its calibration on the finger's FEM itself: no model node
        _mock_hardware("bend", ("physics.yaml", "bend.yaml"), ("adc_link", "adc_port")),
        replace(_DRIVER, config_files=(*SENSOR_FILES, "bend.yaml")),
    ),
    ports={"adc_port": ("/tmp/tactile_sensor/bend_adc",
                        "serial device of the finger's ADC (one channel per module)")},
    record_topics=("/driver/reading", "/driver/joint_states", "/driver/wrench",
                   "/bend/joint_states", "/bend/tip/wrench", "/diagnostics"),
)

CONFIGURATIONS = {c.name: c for c in (BENCH, GRIPPER, ARRAY, WRENCH, GRIPPER_SHEAR, BEND)}


def config_dir() -> Path:
    """config/ of the source tree, or of the installed share folder on a robot."""
    source = Path(__file__).resolve().parents[1] / "config"
    if source.is_dir():
        return source
    for prefix in os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep):
        candidate = Path(prefix) / "share" / PACKAGE / "config"
        if candidate.is_dir():
            return candidate
    return source


def config_files(spec: NodeSpec, use_mock: bool) -> tuple[str, ...]:
    """The files a node loads, in order, with or without mock hardware."""
    return spec.config_files + (spec.mock_config_files if use_mock else ())
