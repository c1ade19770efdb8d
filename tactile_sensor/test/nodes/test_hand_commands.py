"""``tactile-sensor grasp | release | tare`` against a running ``bringup gripper --protocol
idle``, each command its own process, as a newcomer types them in a second shell."""

from __future__ import annotations

import pytest
import yaml
from gripper_under_load import GRIPPER_UNDER_LOAD


def command(spawn, *args: str):  # type: ignore[no-untyped-def]
    return spawn(*args, module="tactile_sensor.cli")


def finished(run, timeout_s: float = 120.0) -> tuple[int, str]:  # type: ignore[no-untyped-def]
    code = run.proc.wait(timeout=timeout_s)
    return code, run.output()


def test_a_newcomer_grasps_tares_and_releases_by_hand(spawn, ros_domain, tmp_path):
    config = tmp_path / "load.yaml"
    config.write_text(yaml.safe_dump({"/**/gripper": {"ros__parameters": GRIPPER_UNDER_LOAD}}))
    up = command(spawn, "bringup", "gripper", "--protocol", "idle", "--config", str(config),
                 "--port", f"adc_port={tmp_path / 'adc'}",
                 "--port", f"servo_port={tmp_path / 'xm430'}")
    assert up.wait_for_output("running", 240), up.output()

    code, out = finished(command(spawn, "tare"))
    assert code == 0 and "tared: baseline" in out, out
    code, out = finished(command(spawn, "grasp", "1.5"))
    assert code == 0 and "succeeded: contact" in out and "force " in out, out
    assert "Traceback" not in out
    # a goal the gripper refuses: the command says so and fails, the fingers keep holding
    code, out = finished(command(spawn, "grasp", "100"))
    assert code == 1 and "refused: invalid_goal: Grasp target force 100 N is above" in out, out
    code, out = finished(command(spawn, "release"))
    assert code == 0 and "succeeded: opening" in out, out
    assert up.proc.poll() is None, up.output()  # the bringup stays up for the next command


@pytest.mark.parametrize(("args", "message"), [
    (["grasp", "-1"], "finite number > 0 N"),
    (["grasp", "nan"], "finite number > 0 N"),
    (["grasp", "strong"], "must be a number of N"),
    (["release", "--opening", "-0.01"], "finite number >= 0 m"),
])
def test_a_bad_number_is_refused_in_one_sentence(spawn, ros_domain, args, message):
    code, out = finished(command(spawn, *args))
    assert code == 2 and message in out and "Traceback" not in out, out


@pytest.mark.parametrize("verb", ["grasp 1.5", "release", "tare", "self-check"])
def test_with_no_gripper_running_a_command_says_so(spawn, ros_domain, verb):
    code, out = finished(command(spawn, *verb.split()))
    said = [line for line in out.splitlines() if "answers on" in line]
    assert code == 1 and len(said) == 1 and f"ROS domain {ros_domain}" in said[0], out
    assert "bringup gripper --protocol idle" in said[0] and "Traceback" not in out
