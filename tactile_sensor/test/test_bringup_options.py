"""The bringup's options, checked before any node starts: one sentence each."""

from __future__ import annotations

import math

import pytest
from hypothesis import given
from hypothesis import strategies as st

from tactile_sensor.configurations import CONFIGURATIONS
from tactile_sensor.nodes.bringup import (
    BringupError,
    check_duration,
    check_protocol,
    per_run_ports,
    protocol_parameters,
    resolve_ports,
)


@pytest.mark.parametrize(("configuration", "spec", "message"), [
    ("bench", "repeatability:cycles=-3", "cycles = -3 in --protocol"),
    ("bench", "compression:depth=inf", "depth = inf in --protocol"),
    ("bench", "compression:rest=-1", "rest = -1.0 in --protocol"),
    ("bench", "speeds:speeds=0.001/-2", "speeds in --protocol"),
    ("bench", "speeds:speeds=0.001/nan", "speeds in --protocol"),
    ("gripper", "grasp:target_force=-1", "target_force in --protocol"),
    ("gripper", "grasp:target_force=nan", "target_force in --protocol"),
    ("gripper", "grasp:closing_speed=0", "closing_speed in --protocol"),
    ("gripper", "grasp:hold=-2", "hold in --protocol"),
    ("gripper", "lift:timeout=inf", "timeout in --protocol"),
])
def test_a_protocol_field_out_of_its_range_is_refused_naming_it(configuration, spec, message):
    with pytest.raises(BringupError, match=message):
        check_protocol(protocol_parameters(configuration, spec), spec)


@pytest.mark.parametrize("configuration", sorted(CONFIGURATIONS))
def test_every_shipped_protocol_passes_the_check(configuration):
    for name in _names(configuration):
        check_protocol(protocol_parameters(configuration, name), name)


def _names(configuration: str) -> list[str]:
    import yaml

    from tactile_sensor.configurations import config_dir

    table = yaml.safe_load((config_dir() / "protocols.yaml").read_text())
    return list(table.get(configuration, {}))


@given(st.floats(allow_nan=True, allow_infinity=True))
def test_a_duration_is_a_positive_finite_number_of_seconds(duration):
    if math.isfinite(duration) and duration > 0:
        check_duration(duration)
    else:
        with pytest.raises(BringupError, match="--duration"):
            check_duration(duration)


def test_real_devices_need_every_port_named_and_the_mock_needs_none():
    gripper = CONFIGURATIONS["gripper"]
    assert set(resolve_ports(gripper, [])) == set(gripper.ports)
    with pytest.raises(BringupError, match="--port servo_port=/dev/"):
        resolve_ports(gripper, ["adc_port=/dev/ttyACM0"], use_mock=False)
    ports = resolve_ports(gripper, ["adc_port=/dev/ttyACM0", "servo_port=/dev/ttyUSB0"],
                          use_mock=False)
    assert ports == {"adc_port": "/dev/ttyACM0", "servo_port": "/dev/ttyUSB0"}
    with pytest.raises(BringupError, match="NAME=PATH"):
        resolve_ports(gripper, ["adc_port="])


def test_the_mocks_devices_go_in_the_runs_own_folder_unless_a_port_names_them(tmp_path):
    gripper = CONFIGURATIONS["gripper"]
    given = ["servo_port=/tmp/mine/xm430"]
    ports = per_run_ports(resolve_ports(gripper, given), given, tmp_path)
    assert ports["servo_port"] == "/tmp/mine/xm430"
    assert ports["adc_port"].startswith(str(tmp_path))
    other = per_run_ports(resolve_ports(gripper, []), [], tmp_path / "other")
    assert not set(other.values()) & set(ports.values())
