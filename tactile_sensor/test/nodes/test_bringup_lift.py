"""The lift protocol refuses, in one sentence and before anything moves, a bringup without
an object or without the in-process mock; and runs end to end on the mock."""

from __future__ import annotations

from types import SimpleNamespace
from typing import Any

import pytest
import yaml
from gripper_under_load import GRIPPER_UNDER_LOAD

from tactile_sensor.nodes.bringup_protocols import run_protocol


class Untouchable:
    """A node the refusal must not use: no subscription, no action, no wait."""

    def __getattr__(self, name: str) -> Any:
        raise AssertionError(f"the refused lift used {name}")


class Runner:
    def __init__(self, mock: Any) -> None:
        self.nodes = {"gripper": Untouchable(), "driver": Untouchable(), "gripper_world": mock}
        self.protocol = {"protocol.name": "lift", "protocol.target_force": 2.0}
        self.configuration = None
        self.stopped = False

    def wait(self, seconds: float) -> bool:
        raise AssertionError("the refused lift waited")

    def now(self) -> float:
        return 0.0


@pytest.mark.parametrize(("mock", "names"), [
    (SimpleNamespace(object_spec=None, emulator=object()), "object.mass_kg is 0"),
    (None, "run it on mock hardware"),
])
def test_a_lift_is_refused_before_anything_moves(mock, names, capsys):
    runner = Runner(mock)
    if mock is None:
        del runner.nodes["gripper_world"]
    assert run_protocol(runner, None) == 2
    said = [line for line in capsys.readouterr().err.splitlines() if line.strip()]
    assert len(said) == 1 and names in said[0]


def test_a_lift_through_the_bringup_holds_a_light_object_and_reports_each_phase(spawn,
                                                                                tmp_path):
    """The whole protocol on the one-module gripper (fixed hold): a 100 g object at
    friction 0.8 under a 2 N grip (the least for its weight: 0.61 N) stays put."""
    config = tmp_path / "object.yaml"
    config.write_text(yaml.safe_dump({
        "/**/gripper_world": {"ros__parameters": {"object": {
            "mass_kg": 0.1, "friction_static": 0.8, "friction_kinetic": 0.8}}},
        # the grasp's settle beside a busy core (as the grasp protocol's test gives it)
        "/**/gripper": {"ros__parameters": GRIPPER_UNDER_LOAD}}))
    run = spawn("bringup", "gripper", "--protocol", "lift:hold=0.5", "--config", str(config),
                "--port", f"adc_port={tmp_path / 'adc'}",
                "--port", f"servo_port={tmp_path / 'xm430'}", module="tactile_sensor.cli")
    assert run.proc.wait(timeout=240) == 0, run.output()
    out = run.output()
    assert "Traceback" not in out and "object lifted" in out and "object set down" in out
    # a grasp still holding is canceled before the release, never preempted by it (a WARN)
    assert "goal aborted" not in out, out
    for phase in ("phase grasp", "phase lift and hold", "phase set down and release"):
        assert phase in out, phase
    summary = dict(item.split("=", 1) for item in
                   out.split("lift summary: ", 1)[1].splitlines()[0].split())
    assert summary["dropped"] == "no" and float(summary["slip_mm"]) < 0.5, summary
    assert float(summary["peak_grip_n"]) == pytest.approx(2.0, rel=0.2)
    assert float(summary["least_grip_n"]) == pytest.approx(0.1 * 9.80665 / 1.6, rel=1e-3)
