"""The mock rig under light, heat, an aged emitter and a stiffer skin, as its parameters
set them: the ADC's source carries the scene, and an impossible one is refused in one
sentence before any device opens."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from rclpy.parameter import Parameter

from tactile_sensor.nodes.mock_hardware import MockHardwareError, MockHardwareNode
from tactile_sensor.nodes.ros_session import ros_session


@pytest.fixture
def ros(ros_domain: int) -> Iterator[None]:
    with ros_session():
        yield


def start(tmp_path: Path, **values: Any) -> MockHardwareNode:
    overrides = {"adc_link": str(tmp_path / "adc"), "servo_link": str(tmp_path / "xm430"),
                 "protocol.start_delay": -1.0, "noise.white": 0.0, "noise.drift": 0.0,
                 **values}
    return MockHardwareNode(parameter_overrides=[Parameter(k, value=v)
                                                 for k, v in overrides.items()])


def test_the_scene_reaches_the_adcs_source_and_the_dark_room_is_untouched(ros, tmp_path):
    node = start(tmp_path, **{"ambient.dc_ratio": 0.2, "ambient.steps": ["0.5:0.1"],
                              "skin.stiffness_ratio": 1.15})
    try:
        node.source.start_device_s = 0.0  # steps count from the protocol's start
        t = np.array([0.0, 0.4, 1.0])
        dark = np.asarray(node.world.module_voltages(np.zeros(3)))[:, 0]
        lit = np.asarray(node.adc._source(t))[:, 0]
        rest_drop = 5.0 - dark[0]
        assert lit == pytest.approx(dark - rest_drop * np.array([0.2, 0.2, 0.3]), abs=1e-3)
        assert node.world.block.stiffness_ratio == 1.15
    finally:
        node.close_devices()
        node.destroy_node()


def test_a_scenario_is_stated_against_the_detectors_headroom_after_the_start_delay(
        ros, tmp_path):
    node = start(tmp_path, **{"protocol.scenario": "sunlight", "protocol.start_delay": 2.0})
    try:
        rest = float(np.asarray(node.world.module_voltages(np.zeros(1)))[0, 0])
        lit = float(np.asarray(node.adc._source(np.zeros(1)))[0, 0])
        # 60 % of the room between the rest output and the 0.3 V saturation
        assert lit == pytest.approx(rest - 0.6 * (rest - 0.3), abs=1e-3)
        office = start(tmp_path / "office", **{"protocol.scenario": "office",
                                                "protocol.start_delay": 2.0})
        try:
            assert office.scene.steps == ((2.5, 0.3), (12.5, -0.3))  # protocol seconds
        finally:
            office.close_devices()
            office.destroy_node()
    finally:
        node.close_devices()
        node.destroy_node()


@pytest.mark.parametrize(("values", "sentence"), [
    ({"ambient.flicker_ratio": 0.2, "ambient.flicker_hz": 600.0}, "Nyquist rate 500 Hz"),
    ({"ambient.steps": ["5:-0.3"]}, "negative ratio (-0.3) at 5 s"),
    ({"ambient.steps": ["soon:0.3"]}, "is not 'time:ratio'"),
    ({"ambient.dc_ratio": -0.1}, "'ambient.dc_ratio' = -0.1 is invalid"),
    ({"ambient.dc_ratio": float("nan")}, "expected a finite number"),
    ({"emitter.output_ratio": 2.0}, "'emitter.output_ratio' = 2.0 is invalid"),
    ({"modules": "front,back,left,right", "skin.stiffness_ratio": 1.2},
     "applies to a single-module skin"),
    ({"protocol.scenario": "fog"}, "'protocol.scenario' = 'fog' is invalid"),
    ({"protocol.scenario": "office", "ambient.dc_ratio": 0.1},
     "protocol.scenario 'office' sets the light itself"),
])
def test_an_impossible_scene_is_refused_in_one_sentence(ros, tmp_path, values, sentence):
    with pytest.raises(MockHardwareError) as error:
        start(tmp_path, **values)
    assert sentence in str(error.value) and "\n" not in str(error.value)
    assert not (tmp_path / "adc").exists()  # no device opened


def test_a_refused_rig_can_still_be_destroyed(ros, tmp_path):
    """The context's shutdown destroys every node it made, the refused one too (Kilted):
    closing its devices must find nothing to close, or the context stays up for the next."""
    with pytest.raises(MockHardwareError) as error:
        start(tmp_path, **{"ambient.dc_ratio": -0.1})
    node = error.traceback[-1].frame.f_locals["self"]
    node.destroy_node()  # raised AttributeError ('_stop') before
