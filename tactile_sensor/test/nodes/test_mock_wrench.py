"""The mock rig's six-axis pieces that need no process: refusals and the stage/gauge sample."""

from __future__ import annotations

import numpy as np
import pytest

from tactile_sensor.nodes.mock_hardware import (
    WRENCH_STAGE_JOINTS,
    stage_and_gauge,
    wrench_refusal,
)


def test_wrench_protocol_needs_the_bench_and_six_modules() -> None:
    assert wrench_refusal("bench", 8) is None
    four = wrench_refusal("bench", 4)
    assert four is not None and "at least 6 modules" in four and "names 4" in four
    gripper = wrench_refusal("gripper", 8)
    assert gripper is not None and "bench world" in gripper


def test_six_axis_world_gives_six_joints_and_six_gauge_components() -> None:
    from tactile_sensor.sim.wrench_world import WrenchBenchWorld

    world = WrenchBenchWorld.__new__(WrenchBenchWorld)
    world.stage_m = lambda t: np.arange(6.0) * t          # type: ignore[method-assign]
    world.wrench_n = lambda t: -np.arange(6.0) * t        # type: ignore[method-assign]
    position, gauge = stage_and_gauge(world, 2.0)
    assert position == pytest.approx([0, 2, 4, 6, 8, 10])
    assert gauge == pytest.approx((0, -2, -4, -6, -8, -10))
    assert WRENCH_STAGE_JOINTS[3:] == ("stage_rx", "stage_ry", "stage_rz")
