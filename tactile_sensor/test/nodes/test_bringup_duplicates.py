"""A second in-process bringup in a domain is refused in one sentence, before it creates a
node or a device, and the first runs on; the same names in another namespace start."""

from __future__ import annotations

import fcntl
import signal
from pathlib import Path

import pytest
import rclpy
from waiting import PATIENCE_S

from tactile_sensor.configurations import CONFIGURATIONS
from tactile_sensor.nodes.bringup_duplicates import bringup_node_names, running_already
from tactile_sensor.nodes.ros_session import ros_session

pytestmark = [pytest.mark.ros]


def bringup(spawn, *args: str):
    return spawn("bringup", *args, module="tactile_sensor.cli")


def test_a_second_bringup_in_the_domain_is_refused_and_the_first_runs_on(spawn, ros_domain,
                                                                         tmp_path: Path):
    ports = ["--port", f"adc_port={tmp_path / 'adc'}"]
    first = bringup(spawn, "bench", "--protocol", "rest:rest=600", *ports)  # until Ctrl-C
    assert first.wait_for_output("[bringup] protocol 'rest'", 240), first.output()
    second = bringup(spawn, "bench", "--protocol", "rest", "--port",
                     f"adc_port={tmp_path / 'adc2'}")
    assert second.proc.wait(PATIENCE_S) == 2, second.output()
    assert f"runs on this host in ROS domain {ros_domain}" in second.output()
    assert "Traceback" not in second.output()
    assert not (tmp_path / "adc2").exists()  # refused before its mock made a device
    assert first.proc.poll() is None, first.output()
    first.send_signal(signal.SIGINT)
    assert first.proc.wait(PATIENCE_S) == 0, first.output()


def test_a_bringup_whose_lock_is_held_is_refused_at_once(spawn, ros_domain, tmp_path: Path):
    import tempfile

    lock = (Path(tempfile.gettempdir()) / "tactile_sensor"
            / f"bringup-domain{ros_domain}-other.lock")
    lock.parent.mkdir(parents=True, exist_ok=True)
    with lock.open("a") as held:
        fcntl.flock(held, fcntl.LOCK_EX | fcntl.LOCK_NB)
        run = bringup(spawn, "bench", "--namespace", "other", "--protocol", "rest",
                      "--port", f"adc_port={tmp_path / 'adc'}")
        assert run.proc.wait(PATIENCE_S) == 2, run.output()
    assert "another bringup with namespace 'other'" in run.output(), run.output()


def test_the_graph_check_names_what_runs_under_the_bringups_names(ros_domain):
    gripper = CONFIGURATIONS["gripper"]
    names = bringup_node_names(gripper, "", use_mock=True, record=True)
    assert names[0] == "/recorder" and "/driver" in names and "/gripper" in names
    assert bringup_node_names(gripper, "/lab/", use_mock=True, record=False)[0] == "/lab/" + \
        gripper.nodes[0].name
    with ros_session():
        nodes = [rclpy.create_node("driver"), rclpy.create_node("gripper", namespace="/lab")]
        try:
            assert running_already(names, within_s=PATIENCE_S) == ["/driver"]
            assert running_already(["/lab/gripper", "/lab/driver"],
                                   within_s=PATIENCE_S) == ["/lab/gripper"]
            assert running_already(["/elsewhere/driver"], within_s=0.05) == []
        finally:
            for node in nodes:
                node.destroy_node()
