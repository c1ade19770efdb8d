"""The gripper's URDF (urdf/gripper.urdf.xacro), expanded by xacro and parsed by
urdf_parser_py (urdfdom-py) as robot_state_publisher and MoveIt would read it: joint names
and limits agree with config/gripper.yaml and the gripper node, finger B mimics the opening,
the fingers' gap IS the joint value, and the driver's frame_id is a link."""

from __future__ import annotations

import math
import os
import shutil
from pathlib import Path

import numpy as np
import pytest
import xacro
import yaml
from hypothesis import given
from hypothesis import strategies as st
from urdf_parser_py.urdf import URDF

from tactile_sensor.configurations import config_dir
from tactile_sensor.nodes import driver, gripper

XACRO = Path(__file__).resolve().parents[2] / "urdf" / "gripper.urdf.xacro"


def expand(path: Path = XACRO, **mappings: str) -> URDF:
    mappings.setdefault("config_dir", str(config_dir()))
    return URDF.from_xml_string(xacro.process_file(str(path), mappings=mappings).toxml())


def default(specs: list, name: str) -> object:
    return next(spec.default for spec in specs if spec.name == name)


def geometry_config(directory: Path | None = None) -> dict[str, float]:
    text = ((directory or config_dir()) / "gripper.yaml").read_text()
    return yaml.safe_load(text)["/**"]["ros__parameters"]


ROBOT = expand()
JOINTS = {joint.name: joint for joint in ROBOT.joints}
JOINT_NAME = yaml.safe_load((config_dir() / "gripper.yaml").read_text())[
    "/**/gripper"]["ros__parameters"]["joint_name"]


def test_the_actuated_joint_is_the_node_s_joint_name_with_the_config_s_travel():
    assert JOINT_NAME == default(gripper.SPECS, "joint_name") == "finger_opening"
    joint = JOINTS[JOINT_NAME]
    assert joint.type == "prismatic" and joint.mimic is None
    geometry = geometry_config()
    assert joint.limit.lower == geometry["geometry.closed_opening"]
    assert joint.limit.upper == geometry["geometry.open_opening"]
    # the opening's fastest rate: the XM430's 77 rpm on two racks
    assert joint.limit.velocity == pytest.approx(
        2 * geometry["geometry.pitch_radius"] * 77 * 2 * math.pi / 60)
    assert {j.name for j in ROBOT.joints} == {JOINT_NAME, "finger_b_joint",
                                              "tactile_sensor_joint"}


def test_finger_b_mimics_half_the_opening_within_half_the_travel():
    mimic = JOINTS["finger_b_joint"]
    assert mimic.type == "prismatic"
    assert mimic.mimic.joint == JOINT_NAME
    assert mimic.mimic.multiplier == 0.5 and (mimic.mimic.offset or 0.0) == 0.0
    opening = JOINTS[JOINT_NAME].limit
    assert mimic.limit.lower == opening.lower / 2 and mimic.limit.upper == opening.upper / 2


def link_origin(link: str, opening_m: float) -> np.ndarray:
    """Where ``link``'s origin is in the base frame at this opening (the chain's joints
    have no rotation but the sensor's, which is a leaf)."""
    child_to_joint = {joint.child: joint for joint in ROBOT.joints}
    position = np.zeros(3)
    while link in child_to_joint:
        joint = child_to_joint[link]
        if joint.type == "prismatic":
            value = opening_m * (joint.mimic.multiplier if joint.mimic else 1.0)
            position += np.array(joint.axis) * value
        position += np.array(joint.origin.xyz if joint.origin else [0, 0, 0])
        link = joint.parent
    assert link == ROBOT.get_root() == "gripper_base_link"
    return position


@given(st.floats(0.002, 0.060))
def test_the_gap_between_the_skin_surfaces_is_the_joint_value(opening):
    finger_a, finger_b = link_origin("finger_a", opening), link_origin("finger_b", opening)
    assert finger_b[1] - finger_a[1] == pytest.approx(opening)
    assert finger_a[1] == pytest.approx(-finger_b[1])  # symmetric about the centre line


def test_the_driver_s_frame_id_is_a_link_on_finger_a_with_z_into_the_sensor():
    frame = default(driver.SPECS, "frame_id")
    sensor_yaml = yaml.safe_load((config_dir() / "sensor.yaml").read_text())
    configured = [section["ros__parameters"].get("frame_id")
                  for section in sensor_yaml.values()]
    assert {frame} >= set(filter(None, configured))
    assert frame in {link.name for link in ROBOT.links}
    joint = next(j for j in ROBOT.joints if j.child == frame)
    assert joint.type == "fixed" and joint.parent == "finger_a"
    roll, pitch, yaw = joint.origin.rpy
    assert pitch == 0 and yaw == 0
    z_axis = np.array([0.0, -math.sin(roll), math.cos(roll)])  # R_x(roll) @ z
    # finger A is on -y: pressing it pushes into the sensor, away from finger B
    np.testing.assert_allclose(z_axis, [0.0, -1.0, 0.0], atol=1e-12)
    assert joint.origin.xyz[1] < 0  # behind the skin surface


def test_the_limits_follow_the_config_file_not_a_copy(tmp_path):
    for name in ("gripper.yaml", "physics.yaml"):
        shutil.copy(config_dir() / name, tmp_path / name)
    text = (tmp_path / "gripper.yaml").read_text()
    (tmp_path / "gripper.yaml").write_text(
        text.replace("geometry.open_opening: 0.060", "geometry.open_opening: 0.085"))
    robot = expand(config_dir=str(tmp_path), prefix="left_", joint_name="opening")
    joints = {joint.name: joint for joint in robot.joints}
    assert joints["left_opening"].limit.upper == 0.085
    assert joints["left_finger_b_joint"].mimic.joint == "left_opening"
    assert "left_tactile_sensor" in {link.name for link in robot.links}


def test_the_installed_file_expands_with_its_installed_config():
    for prefix in os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep):
        installed = Path(prefix) / "share" / "tactile_sensor" / "urdf" / "gripper.urdf.xacro"
        if installed.is_file():
            break
    else:
        pytest.fail("urdf/gripper.urdf.xacro is not installed: run 'make setup' and source "
                    "scripts/env.sh")
    robot = URDF.from_xml_string(xacro.process_file(str(installed)).toxml())  # $(find ...)
    assert {j.name for j in robot.joints} == set(JOINTS)
    assert [j.limit.upper for j in robot.joints if j.name == JOINT_NAME] == [
        geometry_config()["geometry.open_opening"]]
