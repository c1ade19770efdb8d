"""A node ends with status 0 however many Ctrl-Cs follow the first.

``ros2 launch`` forwards a SIGINT to every node on top of the one the terminal sends the
whole process group, so a node sees two, milliseconds to a second apart. Python resets the
signals it handles to their default action when the interpreter finalizes, before rclpy's
and Fast DDS's objects are torn down (80-300 ms on Jazzy); a SIGINT landing then killed the
node (status -2; ``ros2 launch`` logs "process has died"). A stream of SIGINTs every 10 ms
after the first hits that window every time.
"""

from __future__ import annotations

import os
import signal
import time
from pathlib import Path

import pytest

pytest.importorskip("rclpy")
pytest.importorskip("tactile_sensor_interfaces.msg")

pytestmark = [pytest.mark.ros]

PATIENCE_S = 60.0
REPEAT_S = 0.01  # a SIGINT this often until the node has exited


def interrupt_repeatedly(proc) -> int | None:
    """SIGINT now and every REPEAT_S until ``proc`` exits; its status (None: it never did)."""
    deadline = time.monotonic() + PATIENCE_S
    while proc.poll() is None and time.monotonic() < deadline:
        try:
            os.kill(proc.pid, signal.SIGINT)
        except ProcessLookupError:
            break
        time.sleep(REPEAT_S)
    return proc.wait(5) if proc.poll() is None else proc.returncode


@pytest.mark.parametrize(("module", "argv", "ready"), [
    # the recorder's own main, and a lifecycle node's (nodes/lifecycle_main.py)
    ("tactile_sensor.nodes.recorder", ["-p", "path:={tmp}/bag", "-p", "topics:=['/a']"],
     "Recording to"),
    ("tactile_sensor.nodes.driver", ["-r", "__node:=driver", "-p", "port:={tmp}/adc",
                                     "-p", "autostart:=true"], "does not exist"),
], ids=["recorder", "lifecycle-driver"])
def test_repeated_ctrl_c_ends_the_node_with_status_0(ros_domain, spawn, tmp_path: Path,
                                                     module: str, argv: list[str],
                                                     ready: str) -> None:
    child = spawn("--ros-args", *[a.format(tmp=tmp_path) for a in argv], module=module)
    assert child.wait_for_output(ready, PATIENCE_S), child.output()
    code = interrupt_repeatedly(child.proc)
    assert code == 0, (code, child.output()[-2000:])
    assert "Traceback" not in child.output(), child.output()
