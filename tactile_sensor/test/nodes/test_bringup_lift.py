"""The lift protocol refuses, in one sentence and before anything moves, a bringup without
an object or without the in-process mock."""

from __future__ import annotations

from types import SimpleNamespace
from typing import Any

import pytest

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
