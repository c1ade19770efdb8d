"""The control_msgs interfaces the gripper serves have upstream's type hashes, so clients
built against the real package (MoveIt, ros2_controllers) match our server. On the wheels path
the package is ours (wheels_overlay/control_msgs); with a sourced ROS 2 it is the real one."""

from __future__ import annotations

import json
import os
from pathlib import Path

import pytest

#: Measured on upstream control_msgs 6.8.0 (issue: "Runs on the ROS 2 its users run").
UPSTREAM = {
    "msg/GripperCommand":
        "RIHS01_57eb8f326c9889ca8bb34ead82cc94cc09bf6bc5c3b6c09546dca3a00b589890",
    "action/GripperCommand":
        "RIHS01_e17c0e644eccf14bea84a0a93e0977182872c2eb7873ca6694900059b46dbc84",
    "action/ParallelGripperCommand":
        "RIHS01_adfd3c1ebe8abc38ebcc0e454b6423d291d4010dd5697d14eca5b9be4726ae18",
}


def installed_share() -> Path:
    for prefix in os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep):
        share = Path(prefix) / "share" / "control_msgs"
        if (share / "package.xml").is_file():
            return share
    pytest.fail("control_msgs is not installed: run 'make setup' (it builds it on the wheels "
                "path) and source scripts/env.sh")


@pytest.mark.parametrize("interface", sorted(UPSTREAM))
def test_type_hash_equals_upstream(interface):
    description = json.loads((installed_share() / f"{interface}.json").read_text())
    own = {h["type_name"]: h["hash_string"] for h in description["type_hashes"]}
    assert own[f"control_msgs/{interface}"] == UPSTREAM[interface]


def test_the_overlay_is_hidden_from_every_workspace_crawl():
    """A robot's colcon build (and rosdep, through catkin_pkg) must never see our package:
    COLCON_IGNORE one folder above it, so it is found only when setup names it."""
    from catkin_pkg.packages import find_packages

    root = Path(__file__).resolve().parents[3]
    assert (root / "wheels_overlay" / "COLCON_IGNORE").is_file()
    found = {pkg.name for pkg in find_packages(str(root), exclude_paths=[
        str(root / d) for d in (".venv", "build", "install", "log")]).values()}
    assert "control_msgs" not in found
    assert {"tactile_sensor", "tactile_sensor_interfaces"} <= found
