"""The mock rig's six-axis pieces that need no process: refusals and the stage/gauge sample."""

from __future__ import annotations

import numpy as np
import pytest

from tactile_sensor.nodes.mock_hardware import (
    WRENCH_STAGE_JOINTS,
    stage_and_gauge,
    stage_and_gauge_block,
)
from tactile_sensor.sim.rig_refusals import wrench_refusal


def test_wrench_protocol_needs_the_bench_and_six_modules() -> None:
    assert wrench_refusal("bench", 8) is None
    four = wrench_refusal("bench", 4)
    assert four is not None and "at least 6 modules" in four and "names 4" in four
    gripper = wrench_refusal("gripper", 8)
    assert gripper is not None and "bench world" in gripper


def test_six_axis_world_gives_six_joints_and_six_gauge_components() -> None:
    from tactile_sensor.sim.wrench_world import WrenchBenchWorld

    world = WrenchBenchWorld.__new__(WrenchBenchWorld)
    # shape (..., 6), as the world's own
    world.stage_m = lambda t: np.multiply.outer(t, np.arange(6.0))  # type: ignore[method-assign]
    world.wrench_n = lambda t: np.multiply.outer(t, -np.arange(6.0))  # type: ignore[method-assign]
    position, gauge = stage_and_gauge(world, 2.0)
    assert position == pytest.approx([0, 2, 4, 6, 8, 10])
    assert gauge == pytest.approx((0, -2, -4, -6, -8, -10))
    assert WRENCH_STAGE_JOINTS[3:] == ("stage_rx", "stage_ry", "stage_rz")
    stage, wrench = stage_and_gauge_block(world, np.array([0.0, 1.0, 2.0]))
    assert stage.shape == wrench.shape == (3, 6)
    assert stage[:, 1] == pytest.approx([0, 1, 2])


def test_a_single_module_bench_has_no_lateral_axis_in_a_block() -> None:
    from tactile_sensor.sim.bench_world import BenchWorld

    world = BenchWorld.__new__(BenchWorld)
    world.indentation_m = lambda t: 1e-3 * np.asarray(t)  # type: ignore[method-assign]
    world.force_n = lambda t: 2.0 * np.asarray(t)  # type: ignore[method-assign]
    stage, gauge = stage_and_gauge_block(world, np.array([0.5, 1.0]))
    assert stage == pytest.approx(np.array([[5e-4, 0, 0], [1e-3, 0, 0]]))
    assert gauge == pytest.approx(np.array([[0, 0, 1.0], [0, 0, 2.0]]))
    assert stage_and_gauge(world, 1.0) == ([1e-3, 0.0, 0.0], (0.0, 0.0, 2.0))
