"""``ros2 launch tactile_sensor array.launch.py`` for real: four modules on one mock ADC,
the model latching the array calibration, the driver publishing force.x/y/z (and NaN
torque), poked with the real ``ros2`` command line, and a clean SIGINT; and
``wrench.launch.py``: eight modules, the six-axis bench, torque on the driver's wrench.

The protocol waits for ``/bench/start`` (``config:=`` sets ``protocol.start_delay: -1``);
the shear run itself, recorded and analysed, is test/nodes/test_array_bringup.py.
"""

from __future__ import annotations

import re

import pytest
from ros2_tools import SIGTERM_PATIENCE

pytestmark = [pytest.mark.slow, pytest.mark.flaky(reruns=1, reruns_delay=1)]

# "process has died": ros2 launch's line for a node that ended by a signal or non-zero status
FAULTS = ("Traceback", "never retrieved", "context is invalid", "process has died")


def quiet(output: str) -> list[str]:
    return [line for line in output.splitlines() if "[ERROR]" in line or "[WARN" in line]


def test_array_launch_streams_three_axis_force_from_four_modules(
        spawn, ros2, lifecycle_states, own_processes, tmp_path):
    extra = tmp_path / "extra.yaml"
    extra.write_text("bench:\n  ros__parameters:\n    protocol.start_delay: -1.0\n")
    launch = spawn("ros2", "launch", "tactile_sensor", "array.launch.py", "protocol:=shear",
                   f"config:={extra}", f"adc_port:={tmp_path / 'adc'}", SIGTERM_PATIENCE)
    # a cold cache computes the FEM sweep and grid first: minutes beside a busy core
    assert launch.wait_for_output("[driver]: array calibration from", 120,
                                  while_progressing=True), launch.output()
    states = lifecycle_states({"/driver", "/model"})
    assert states == {"/driver": "active", "/model": "active"}, (states, launch.output())

    reading = ros2("topic", "echo", "--once", "--no-daemon", "/driver/reading",
                   "tactile_sensor_interfaces/msg/TactileReading", timeout_s=60)
    assert reading.returncode == 0, reading
    assert re.search(r"faces:\s*\n- front\s*\n- back\s*\n- left\s*\n- right", reading.stdout), \
        reading.stdout
    outputs = re.search(r"outputs:\s*\n((?:- .*\n){4})", reading.stdout)
    assert outputs is not None, reading.stdout
    wrench = ros2("topic", "echo", "--once", "--no-daemon", "/driver/wrench",
                  "geometry_msgs/msg/WrenchStamped",
                  timeout_s=60)
    assert wrench.returncode == 0 and "frame_id: tactile_sensor" in wrench.stdout, wrench
    # centred windows cannot observe torque: NaN, as force_torque_sensor_broadcaster does
    assert re.search(r"torque:\s*\n\s*x: \.nan\s*\n\s*y: \.nan\s*\n\s*z: \.nan",
                     wrench.stdout), wrench.stdout
    tare = ros2("service", "call", "/driver/tare", "std_srvs/srv/Trigger")
    assert "success=True" in tare.stdout, tare

    before_stop = launch.output()
    assert quiet(before_stop) == [], quiet(before_stop)
    code, seconds = launch.interrupt(group=False)
    output = launch.output()
    # prompt means no node needed ros2 launch's escalation to SIGTERM (SIGTERM_PATIENCE);
    # the time itself is left to a busy machine
    assert code == 0, (code, seconds, output[-3000:])
    assert "failed to terminate" not in launch.output(), (code, seconds, output[-3000:])
    for fault in FAULTS:
        assert fault not in output, output
    assert own_processes() == []


def test_wrench_launch_streams_force_and_torque_from_eight_modules(
        spawn, ros2, lifecycle_states, own_processes, tmp_path):
    extra = tmp_path / "extra.yaml"
    extra.write_text("bench:\n  ros__parameters:\n    protocol.start_delay: -1.0\n")
    launch = spawn("ros2", "launch", "tactile_sensor", "wrench.launch.py",
                   f"config:={extra}", f"adc_port:={tmp_path / 'adc'}", SIGTERM_PATIENCE)
    assert launch.wait_for_output("[driver]: array calibration from", 120,
                                  while_progressing=True), launch.output()
    assert "observes fx, fy, fz, tx, ty, tz" in launch.output(), launch.output()
    states = lifecycle_states({"/driver", "/model"})
    assert states == {"/driver": "active", "/model": "active"}, (states, launch.output())
    joints = ros2("topic", "echo", "--once", "--no-daemon", "/bench/stage/joint_states",
                  "sensor_msgs/msg/JointState", timeout_s=60)
    assert joints.returncode == 0 and "- stage_rz" in joints.stdout, joints
    wrench = ros2("topic", "echo", "--once", "--no-daemon", "/driver/wrench",
                  "geometry_msgs/msg/WrenchStamped", timeout_s=60)
    assert wrench.returncode == 0, wrench
    torque = re.search(r"torque:\s*\n\s*x: (\S+)\s*\n\s*y: (\S+)\s*\n\s*z: (\S+)",
                       wrench.stdout)
    assert torque is not None and ".nan" not in torque.group(0), wrench.stdout
    code, _ = launch.interrupt(group=False)
    output = launch.output()
    assert code == 0, output[-3000:]
    for fault in FAULTS:
        assert fault not in output, output
    assert own_processes() == []
