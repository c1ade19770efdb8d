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

BENCH = Configuration(
    name="bench",
    description="The paper's compression bench: stage, force gauge and the tactile module.",
    nodes=(
        NodeSpec("bench", "mock_hardware_node", "tactile_sensor.nodes.mock_hardware",
                 "MockHardwareNode", ("physics.yaml", "bench.yaml"), lifecycle=False,
                 mock_only=True, port_parameters=(("adc_link", "adc_port"),)),
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
        NodeSpec("gripper_world", "mock_hardware_node", "tactile_sensor.nodes.mock_hardware",
                 "MockHardwareNode", ("physics.yaml", "gripper.yaml"), lifecycle=False,
                 mock_only=True,
                 port_parameters=(("adc_link", "adc_port"), ("servo_link", "servo_port"))),
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

ARRAY = Configuration(
    name="array",
    description="Modules on four side faces of one skin on the bench, with a three-axis "
                "stage and gauge: normal and shear force (the paper's future work).",
    nodes=(
        replace(BENCH.nodes[0], config_files=("physics.yaml", "bench.yaml", "array.yaml")),
        replace(_MODEL, config_files=(*_MODEL.config_files, "array.yaml")),
        replace(_DRIVER, config_files=(*SENSOR_FILES, "array.yaml")),
    ),
    ports={"adc_port": ("/tmp/tactile_sensor/array_adc",
                        "serial device of the array's ADC (one channel per module)")},
    record_topics=BENCH.record_topics,
)

WRENCH = Configuration(
    name="wrench",
    description="Two modules on each side face of one skin on the bench, with a stage that "
                "presses, shears, tilts and twists and a six-component gauge: force and torque "
                "(the paper's future work).",
    nodes=(
        replace(BENCH.nodes[0], config_files=("physics.yaml", "bench.yaml", "wrench.yaml")),
        replace(_MODEL, config_files=(*_MODEL.config_files, "wrench.yaml")),
        replace(_DRIVER, config_files=(*SENSOR_FILES, "wrench.yaml")),
    ),
    ports={"adc_port": ("/tmp/tactile_sensor/wrench_adc",
                        "serial device of the wrench layout's 8-input ADC (one channel per "
                        "module)")},
    record_topics=BENCH.record_topics,
)

GRIPPER_SHEAR = Configuration(
    name="gripper_shear",
    description="The soft gripper with modules on four side faces of finger A's skin: the "
                "grip and the force along the fingers.",
    nodes=(
        replace(GRIPPER.nodes[0], config_files=(*GRIPPER.nodes[0].config_files,
                                                "gripper_shear.yaml")),
        replace(_MODEL, config_files=(*_MODEL.config_files, "gripper_shear.yaml")),
        replace(GRIPPER.nodes[2], config_files=(*GRIPPER.nodes[2].config_files,
                                                "gripper_shear.yaml")),
        replace(GRIPPER.nodes[3], config_files=(*GRIPPER.nodes[3].config_files,
                                                "gripper_shear.yaml")),
    ),
    ports={"adc_port": ("/tmp/tactile_sensor/gripper_shear_adc",
                        "serial device of finger A's ADC (one channel per module)"),
           "servo_port": ("/tmp/tactile_sensor/gripper_shear_xm430",
                          "serial device of the U2D2 (Dynamixel bus)")},
    record_topics=(*GRIPPER.record_topics, "/gripper_world/object/joint_states"),
)

CONFIGURATIONS = {c.name: c for c in (BENCH, GRIPPER, ARRAY, WRENCH, GRIPPER_SHEAR)}


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
