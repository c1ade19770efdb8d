"""What a user gets from ``ros2 launch`` for a mistake: a missing device (one error line
naming it, the driver keeps retrying, no traceback) and bad launch arguments (one sentence
each, nothing started)."""

from __future__ import annotations

import subprocess
import time
from pathlib import Path

import pytest
import yaml
from ros2_tools import SIGTERM_PATIENCE

pytestmark = pytest.mark.flaky(reruns=1, reruns_delay=1)

# "process has died": ros2 launch's line for a node that ended by a signal or non-zero status
FAULTS = ("Traceback", "never retrieved", "context is invalid", "process has died")
#: The bench's protocols, in the order the launch file names them (config/protocols.yaml).
BENCH_PROTOCOLS = ", ".join(yaml.safe_load(
    (Path(__file__).resolve().parents[2] / "config" / "protocols.yaml").read_text())["bench"])


def test_a_missing_adc_port_gives_one_error_line_and_the_driver_keeps_retrying(
        spawn, ros_domain, own_processes):
    launch = spawn("ros2", "launch", "tactile_sensor", "bench.launch.py",
                   "use_mock_hardware:=false", "adc_port:=/dev/does-not-exist",
                   SIGTERM_PATIENCE)
    assert launch.wait_for_output("/dev/does-not-exist does not exist", 60), launch.output()
    time.sleep(3.0)  # 15 attempts at the driver's 0.2 s retry interval
    assert launch.proc.poll() is None  # the launch and its nodes keep running
    errors = [line for line in launch.output().splitlines() if "[ERROR]" in line]
    assert len(errors) == 1, errors
    assert "[driver]: ADC disconnected: /dev/does-not-exist does not exist (device " \
           "unplugged?); retrying every 0.2 s" in errors[0]
    code, seconds = launch.interrupt(group=False)
    # prompt means no node needed ros2 launch's escalation to SIGTERM (SIGTERM_PATIENCE);
    # the time itself is left to a busy machine
    assert code == 0, (code, seconds, launch.output()[-2000:])
    assert "failed to terminate" not in launch.output(), (code, seconds, launch.output()[-2000:])
    for fault in FAULTS:
        assert fault not in launch.output()
    assert own_processes() == []


@pytest.mark.parametrize(("argument", "sentence"), [
    ("protocol:=nonsense", f"Unknown protocol 'nonsense'; choose one of {BENCH_PROTOCOLS}."),
    ("config:=/no/such/extra.yaml",
     "config:=/no/such/extra.yaml does not exist; give the path of a ROS parameter YAML file."),
])
def test_a_bad_launch_argument_gives_one_sentence(ros_domain, argument, sentence):
    _refused(argument, sentence)


def test_a_typo_in_a_parameter_file_gives_one_sentence_and_starts_nothing(
        ros_domain, tmp_path):
    typo = tmp_path / "typo.yaml"
    typo.write_text(yaml.safe_dump({"/**/bench": {"ros__parameters": {"noise.whit": 0.01}}}))
    _refused(f"config:={typo}", f"config:={typo} sets 'noise.whit', which node 'bench' does "
                                "not declare; did you mean 'noise.white'?")


def _refused(argument: str, sentence: str) -> None:
    """``ros2 launch`` ends with status 1, one error line holding ``sentence``, no node."""
    result = subprocess.run(["ros2", "launch", "tactile_sensor", "bench.launch.py", argument],
                            capture_output=True, text=True, timeout=60)
    output = result.stdout + result.stderr
    assert result.returncode == 1, output
    assert [line for line in output.splitlines() if sentence in line] != [], output
    assert len([line for line in output.splitlines() if "[ERROR]" in line]) == 1, output
    assert "Traceback" not in output and "process started" not in output, output
