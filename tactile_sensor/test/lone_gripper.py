"""The gripper node alone on an emulated XM430 with no world, for the gripper's tests
(conftest.py puts this folder on ``sys.path``): what a test needs that drives the node
itself (its lifecycle, or a tactile force it publishes)."""

from __future__ import annotations

from pathlib import Path

from waiting import PATIENCE_S


def lone_gripper(spawn, servo: Path, *params: str):  # type: ignore[no-untyped-def]
    """Start the emulator on ``servo``, wait until it answers, then the gripper node on
    it with ``params`` (``-p name:=value`` pairs) added; returns the node's process."""
    emulator = spawn("mock", "xm430", "--link", str(servo), "--baud", "1000000", "--no-world",
                     module="tactile_sensor.cli")
    assert emulator.wait_for_output("xm430: id 1", PATIENCE_S), emulator.output()
    # packet_timeout, comm_retries: as the launch files' (a busy machine holds the emulator up)
    return spawn("--ros-args", "-r", "__node:=gripper", "-p", f"port:={servo}",
                 "-p", "packet_timeout:=0.5", "-p", "comm_retries:=4", *params,
                 module="tactile_sensor.nodes.gripper")
