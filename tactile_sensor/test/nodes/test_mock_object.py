"""The mock gripper's object, as its parameters set it: built from the skin's FEM shear path
and published as ground truth, or refused in one sentence before any device opens."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from rclpy.executors import SingleThreadedExecutor
from rclpy.parameter import Parameter
from sensor_msgs.msg import JointState
from waiting import wait_until

from tactile_sensor.nodes.mock_hardware import OBJECT_JOINTS, MockHardwareError, MockHardwareNode
from tactile_sensor.nodes.ros_session import ros_session


@pytest.fixture
def ros(ros_domain: int) -> Iterator[None]:
    with ros_session():
        yield


def start(tmp_path: Path, **values: Any) -> MockHardwareNode:
    overrides = {"world": "gripper", "adc_link": str(tmp_path / "adc"),
                 "servo_link": str(tmp_path / "xm430"), "noise.white": 0.0,
                 "noise.drift": 0.0, **values}
    return MockHardwareNode(parameter_overrides=[Parameter(k, value=v)
                                                 for k, v in overrides.items()])


def test_the_object_is_built_from_the_fem_and_published_once_lifted(ros, tmp_path):
    node = start(tmp_path, **{"object.mass_kg": 0.15, "object.friction_static": 0.8,
                              "object.friction_kinetic": 0.6,
                              "object.load_profile": ["0:0", "1:0.5"],
                              "skin.stiffness_ratio": 1.5})
    executor = SingleThreadedExecutor()
    try:
        held = node.world.held
        assert held is not None and held.spec.load.force_n(2.0) == 0.5
        assert held.stiffness.source.startswith("fem-array:")
        # the FEM skin: about 0.35 N per mm of shear at 1 mm indentation, times the ratio
        assert 300.0 * 1.5 < held.stiffness(0.001) < 400.0 * 1.5
        seen: list[JointState] = []
        node.create_subscription(JointState, "/mock_hardware/object/joint_states",
                                 seen.append, 10)
        executor.add_node(node)
        assert node.emulator.control("object lift") == "object lifted"
        assert wait_until(lambda: (executor.spin_once(timeout_sec=0.05), bool(seen))[1])
        assert tuple(seen[-1].name) == OBJECT_JOINTS
        # nothing holds it (the fingers are open): it falls, and slides over no skin
        assert wait_until(lambda: (executor.spin_once(timeout_sec=0.05),
                                   seen[-1].position[0] > 0.001)[1])
        assert seen[-1].position[1] == 0.0
    finally:
        executor.shutdown()
        node.close_devices()
        node.destroy_node()


@pytest.mark.parametrize(("values", "sentence"), [
    ({"object.load_profile": ["1:nan"]}, "non-finite value"),
    ({"object.load_profile": ["1:inf"], "object.mass_kg": 0.1}, "non-finite value"),
    ({"object.friction_static": 0.0}, "must be a finite friction coefficient > 0"),
    ({"object.friction_kinetic": -0.2, "object.mass_kg": 0.1},
     "must be a finite friction coefficient > 0"),
    ({"object.friction_kinetic": 0.7, "object.mass_kg": 0.1},
     "kinetic friction must not exceed static"),
    ({"object.mass_kg": 0.1, "world": "bench"}, "set world to gripper or object.mass_kg"),
    ({"object.mass_kg": 0.1, "rod.diameter": 0.0}, "give rod.diameter > 0 m"),
    ({"object.mass_kg": -1.0}, "'object.mass_kg' = -1.0 is invalid"),
])
def test_a_bad_object_is_refused_in_one_sentence(ros, tmp_path, values, sentence):
    with pytest.raises(MockHardwareError) as error:
        start(tmp_path, **values)
    assert sentence in str(error.value) and "\n" not in str(error.value)
    assert not (tmp_path / "adc").exists() and not (tmp_path / "xm430").exists()


def test_a_fingertip_that_feels_shear_streams_its_modules_from_the_grid(ros, tmp_path):
    node = start(tmp_path, modules="front,back,left,right", **{"object.mass_kg": 0.1})
    try:
        world = node.world
        assert world.faces == ("front", "back", "left", "right")
        assert world.module_voltages(0.0).shape == (4,)
        # the fingers' forces are the grid's press, as its calibration reads them
        assert world.finger_a.response.source.endswith(":press")
        assert world.fingertip.response.source.startswith("fem-array:")
        assert world.held is not None
    finally:
        node.close_devices()
        node.destroy_node()
