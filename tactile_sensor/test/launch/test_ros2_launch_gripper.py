"""``ros2 launch tactile_sensor gripper.launch.py`` for real, then docs/install.md's robot
commands and the runtime ones a user types, all with the real ``ros2`` command line:
the grasp line verbatim, a release, ``ros2 param set`` on the driver (a contact threshold
taken at once; refused for a bad combination and for a device parameter),
``ros2 lifecycle set /driver deactivate/activate`` (publishing stops and resumes, checked
in the recording), a tare at rest, and Ctrl-C (SIGINT to the whole process group, as a
terminal sends it). One launch serves every check (a start costs ~10 s).
"""

from __future__ import annotations

import re
import subprocess
import time
from pathlib import Path

import numpy as np
import pytest
from ros2_tools import SIGTERM_PATIENCE
from rosbags.highlevel import AnyReader

pytestmark = [pytest.mark.slow, pytest.mark.flaky(reruns=1, reruns_delay=1)]

#: The page that lists the robot commands, each with the test that runs it.
COMMANDS_PAGE = Path(__file__).resolve().parents[3] / "docs" / "install.md"
# "process has died": ros2 launch's line for a node that ended by a signal or non-zero status
FAULTS = ("Traceback", "never retrieved", "context is invalid", "process has died")


def documented_command(start: str) -> str:
    """The page's command beginning with ``start``, continuation lines joined."""
    lines = COMMANDS_PAGE.read_text().splitlines()
    first = next(i for i, line in enumerate(lines) if line.startswith(start))
    command = []
    for line in lines[first:]:
        command.append(line.rstrip().removesuffix("\\"))
        if not line.rstrip().endswith("\\"):
            return " ".join(command)
    raise AssertionError(f"unterminated command in {COMMANDS_PAGE.name}: {start}")


def header_stamps(bag: Path, topic: str) -> np.ndarray:
    """The topic's header stamps [s], sorted: the bag orders messages by their reception
    time, and a sample the middleware repairs (resent after a loss) is received after later
    ones, although delivered in order."""
    with AnyReader([bag]) as reader:
        connections = [c for c in reader.connections if c.topic == topic]
        stamps = [(m := reader.deserialize(raw, c.msgtype)).header.stamp.sec
                  + m.header.stamp.nanosec * 1e-9
                  for c, _, raw in reader.messages(connections=connections)]
    return np.sort(np.array(stamps))


def test_gripper_launch_with_the_readme_grasp_and_runtime_commands(
        spawn, ros2, lifecycle_states, own_processes, tmp_path):
    bag = tmp_path / "bag"
    launch = spawn("ros2", "launch", "tactile_sensor", "gripper.launch.py", f"record:={bag}",
                   f"adc_port:={tmp_path / 'adc'}", f"servo_port:={tmp_path / 'xm430'}",
                   SIGTERM_PATIENCE)
    assert launch.wait_for_output("[driver]: calibration from", 120,  # a cold FEM cache
                                  while_progressing=True), launch.output()
    states = lifecycle_states({"/driver", "/model", "/gripper"})
    assert set(states.values()) == {"active"} and len(states) == 3, (states, launch.output())
    start = launch.output()
    assert [line for line in start.splitlines() if "[ERROR]" in line or "[WARN" in line] == []

    grasp = subprocess.run(
        ["bash", "-c", documented_command("ros2 action send_goal /gripper/grasp")],
        capture_output=True, text=True, timeout=90)
    assert "Goal finished with status: SUCCEEDED" in grasp.stdout, (grasp, launch.output())
    assert "contact_detected: true" in grasp.stdout, grasp.stdout
    assert "Feedback:" in grasp.stdout
    release = ros2("action", "send_goal", "/gripper/release",
                   "tactile_sensor_interfaces/action/Release", "{opening: 0.0}")
    assert "Goal finished with status: SUCCEEDED" in release.stdout, release
    assert "success: true" in release.stdout

    def param_set(name: str, value: str) -> subprocess.CompletedProcess[str]:
        return ros2("param", "set", "--no-daemon", "--timeout", "10", "/driver", name, value)

    assert "Set parameter successful" in param_set("contact_on_force", "0.8").stdout
    refused = param_set("contact_off_force", "0.9")
    assert "Setting parameter failed" in refused.stderr
    assert "must be below 'contact_on_force' = 0.8" in refused.stderr, refused
    refused = param_set("port", "/dev/ttyUSB9")
    assert "Parameter 'port' is read on configure" in refused.stderr, refused
    assert "changed while running: contact_on_force = 0.8" in launch.output()

    def lifecycle_set(transition: str) -> float:
        result = ros2("lifecycle", "set", "--no-daemon", "--spin-time", "2", "/driver",
                      transition)
        assert "Transitioning successful" in result.stdout, result
        return time.time()

    stopped_at = lifecycle_set("deactivate")
    time.sleep(2.0)
    resumed_at = time.time()
    lifecycle_set("activate")
    tare = ros2("service", "call", "/driver/tare", "std_srvs/srv/Trigger")  # at rest
    assert "success=True" in tare.stdout, tare

    code, seconds = launch.interrupt(group=True)  # Ctrl-C in a terminal
    output = launch.output()
    # prompt means no node needed ros2 launch's escalation to SIGTERM (SIGTERM_PATIENCE);
    # the time itself is left to a busy machine
    assert code == 0, (code, seconds, output[-3000:])
    assert "failed to terminate" not in launch.output(), (code, seconds, output[-3000:])
    for fault in FAULTS:
        assert fault not in output, output
    closed = re.findall(r"\[recorder\]: Closed \S+ with (\d+) messages", output)
    with AnyReader([bag]) as reader:
        assert [str(reader.message_count)] == closed, output[-2000:]

    # ~/reading carries every reading; ~/wrench at publish_rate, the newest only, so a
    # driver behind skips some there (docs/CONTRACTS.md: live and recorded)
    for topic, least in (("/driver/wrench", 1), ("/driver/reading", 100)):
        stamps = header_stamps(bag, topic)
        paused = stamps[(stamps > stopped_at + 0.3) & (stamps < resumed_at)]
        assert paused.size == 0, (topic, paused)  # nothing while inactive
        assert (stamps > resumed_at).sum() >= least, topic  # publishing again
    before = stamps[stamps < stopped_at - 0.5]  # /driver/reading's
    rate = (len(before) - 1) / (before[-1] - before[0])
    assert rate == pytest.approx(1000.0, rel=0.1)  # every sample of the 1 kHz ADC
    assert own_processes() == []
