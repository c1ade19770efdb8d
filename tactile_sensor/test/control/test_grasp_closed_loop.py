"""Grasp state machine + Xm430Client + emulator + gripper world in one loop."""

from __future__ import annotations

import sys
import time

import numpy as np
import pytest

from tactile_sensor.control.grasp import GraspController, GraspRequest, Outcome
from tactile_sensor.hardware.xm430 import Xm430Client
from tactile_sensor.hardware.xm430_table import OperatingMode
from tactile_sensor.sim.gripper_world import GripperWorld
from tactile_sensor.sim.skin_response import TabulatedSkin
from tactile_sensor.sim.xm430_emulator import Xm430Emulator


@pytest.fixture(autouse=True)
def _share_the_gil_fairly():
    before = sys.getswitchinterval()
    sys.setswitchinterval(2e-4)
    yield
    sys.setswitchinterval(before)


def run_grasp(tmp_path, rod_diameter_m, forces=None):
    """The grasp's last step and the force held 0.2 s after it; ``forces`` collects the
    force each control tick saw."""
    forces = [] if forces is None else forces
    d = np.linspace(0.0, 0.003, 31)
    force = 7.0 * d / 0.003
    world = GripperWorld(TabulatedSkin(d, force, 2.0 - 0.07 * force, thickness_m=0.005),
                         rod_diameter_m=rod_diameter_m)
    with Xm430Emulator(tmp_path / "xm430", baudrate=1_000_000, world=world) as emu, \
            Xm430Client(str(emu.link.link_path), 1_000_000, 1, timeout_s=5.0) as client:
        client.set_operating_mode(OperatingMode.CURRENT_BASED_POSITION)
        client.set_torque(True)
        controller = GraspController()
        step = controller.start(GraspRequest(2.0, 0.02, 5.0), time.monotonic(),
                                client.read_state())
        while True:
            if step.command is not None:
                c = step.command
                client.command_position(c.goal_position_rad, c.profile_velocity_rad_s,
                                        goal_current_a=c.goal_current_a)
            if step.finished:
                break
            state = client.read_state()
            now = time.monotonic()
            forces.append(world.latest.force_a_n)
            step = controller.tick(now, forces[-1], now, state)
        time.sleep(0.2)
        return step, world.latest.force_a_n


def test_closing_on_the_rod_reaches_the_target_force(tmp_path):
    forces: list[float] = []
    step, held = run_grasp(tmp_path, 0.020, forces)
    assert step.outcome is Outcome.CONTACT
    # Contact at the first tick whose force reached the 2 N target, and held where the
    # fingers were read then (0.088 deg position steps ~ 0.05 N on this skin). How far past
    # 2 N that tick read depends on how long the loop was held up between two ticks (the
    # world moves in real time: at 20 mm/s, 0.1 s is about 4 N): a quiet machine reads
    # within a few tenths, a busy one further, so the bound is the force the tick saw.
    assert forces[-2] < 2.0 <= forces[-1]
    assert 1.8 <= held < max(2.6, forces[-1] + 0.1)


def test_no_rod_ends_at_the_closed_limit(tmp_path):
    step, held = run_grasp(tmp_path, None)
    assert step.outcome is Outcome.CLOSED_LIMIT_WITHOUT_CONTACT and held == 0.0
