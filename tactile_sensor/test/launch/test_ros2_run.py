"""Every executable under ``ros2 run``, as the README describes for robots without the
launch files: the driver against ``tactile-sensor mock adc`` (started late, so the driver
first reports the missing port and then finds it by retrying), the model, the recorder, the
mock gripper world and the gripper. Ctrl-C (SIGINT to each process group, as a terminal
sends it) ends each within 5 s with status 0, no traceback, and a complete bag."""

from __future__ import annotations

import re

import pytest
from rosbags.highlevel import AnyReader

pytestmark = [pytest.mark.slow, pytest.mark.flaky(reruns=1, reruns_delay=1)]

FAULTS = ("Traceback", "never retrieved", "context is invalid")


def ros2_run(spawn, executable: str, *parameters: str):
    args = [a for p in parameters for a in ("-p", p)]
    return spawn("ros2", "run", "tactile_sensor", executable, "--ros-args", *args)


def test_every_executable_under_ros2_run_works_and_stops_cleanly(
        spawn, ros2, own_processes, tmp_path):
    adc, gadc, servo, bag = (tmp_path / n for n in ("adc", "gadc", "xm430", "bag"))
    driver = ros2_run(spawn, "driver_node", "autostart:=true", f"port:={adc}")
    assert driver.wait_for_output(f"ADC disconnected: {adc} does not exist", 60), \
        driver.output()
    model = ros2_run(spawn, "model_node", "autostart:=true")
    recorder = ros2_run(spawn, "recorder_node", f"path:={bag}", "topics:=['/driver/wrench']")
    mock = spawn("tactile-sensor", "mock", "adc", "--link", str(adc))
    assert driver.wait_for_output(f"ADC connected: receiving frames from {adc}", 60), \
        (driver.output(), mock.output())
    echo = ros2("topic", "echo", "--once", "--no-daemon", "/driver/wrench",
                "geometry_msgs/msg/WrenchStamped", timeout_s=90)
    assert "force:" in echo.stdout and "frame_id: tactile_sensor" in echo.stdout, echo

    world = ros2_run(spawn, "mock_hardware_node", "world:=gripper", f"adc_link:={gadc}",
                     f"servo_link:={servo}")
    assert world.wait_for_output("mock gripper ready", 120), world.output()
    gripper = ros2_run(spawn, "gripper_node", "autostart:=true", f"port:={servo}")
    assert gripper.wait_for_output("[gripper]: active", 60), gripper.output()

    for name, child in (("driver", driver), ("gripper", gripper), ("recorder", recorder),
                        ("model", model), ("mock_hardware", world), ("mock adc", mock)):
        code, seconds = child.interrupt(group=True)
        output = child.output()
        # exits by itself on SIGINT, cleanly (the time is left to a busy machine)
        assert code == 0, (name, code, seconds, output[-2000:])
        for fault in FAULTS:
            assert fault not in output, (name, output)
    closed = re.findall(r"\[recorder\]: Closed \S+ with (\d+) messages", recorder.output())
    with AnyReader([bag]) as reader:
        assert [str(reader.message_count)] == closed, recorder.output()
        assert reader.message_count > 100
    assert own_processes() == []
