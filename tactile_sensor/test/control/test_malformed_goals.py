"""Any goal a ROS message can carry is accepted or refused with one sentence: every float
field of every action, NaN, infinities, negatives and huge values included, gives a goal or
a ControlError, never another exception (which would escape the gripper node's goal
callback and stop its executor)."""

from __future__ import annotations

import math
from types import SimpleNamespace as NS

import pytest
from hypothesis import given
from hypothesis import strategies as st

from tactile_sensor.control.actions import (
    GoalSettings,
    accept_grasp,
    accept_gripper_command,
    accept_parallel_gripper_command,
    accept_release,
)
from tactile_sensor.control.errors import ControlError
from tactile_sensor.control.grasp import GraspConfig
from tactile_sensor.control.self_check import DriveTrain
from tactile_sensor.control.self_check_goal import SelfCheckLinks, accept_self_check
from tactile_sensor.control.slip_hold import HoldSettings

SETTINGS = GoalSettings(GraspConfig(), joint_name="finger_opening")
SHEAR = GoalSettings(GraspConfig(), joint_name="finger_opening",
                     hold=HoldSettings(shear_sensing=True))
#: The values a float64 field can hold that a user would not mean.
MALFORMED = [math.nan, math.inf, -math.inf, -1.0, -1e-300, 1e-300, 1e300, -1e300, 0.0,
             1.7976931348623157e308]
floats = st.one_of(st.sampled_from(MALFORMED), st.floats(allow_nan=True,
                                                         allow_infinity=True))
LINKS = SelfCheckLinks(lambda: None, lambda: None, lambda fit, skin: None, DriveTrain(),
                       lambda servo: 0.0, lambda keep: None, lambda: [])


def accepted_or_refused(accept, goal, settings=SETTINGS) -> bool:
    """True: accepted; False: refused with a sentence. Anything else fails the test."""
    try:
        accept(goal, settings)
    except ControlError as exc:
        assert str(exc).strip(), "a refusal without a reason"
        return False
    return True


@given(force=floats, speed=floats, timeout=floats, hold_time=floats,
       mode=st.sampled_from(["", "fixed", "adaptive", "grip", "\x00", "fixed " * 50]))
def test_every_grasp_message_is_accepted_or_refused(force, speed, timeout, hold_time, mode):
    goal = NS(target_force=force, closing_speed=speed, timeout=timeout, hold_mode=mode,
              hold_time=hold_time)
    for settings in (SETTINGS, SHEAR):
        if accepted_or_refused(accept_grasp, goal, settings):
            assert math.isfinite(force) and force > 0


@given(opening=floats)
def test_every_release_message_is_accepted_or_refused(opening):
    if accepted_or_refused(accept_release, NS(opening=opening)):
        assert math.isfinite(opening) and opening >= 0


@given(position=floats, effort=floats)
def test_every_gripper_command_is_accepted_or_refused(position, effort):
    goal = NS(command=NS(position=position, max_effort=effort))
    if accepted_or_refused(accept_gripper_command, goal):
        assert math.isfinite(position) and math.isfinite(effort) and effort >= 0


@given(position=st.lists(floats, max_size=3), velocity=st.lists(floats, max_size=3),
       effort=st.lists(floats, max_size=3),
       name=st.sampled_from([["finger_opening"], [], ["other"], ["finger_opening"] * 2]))
def test_every_parallel_gripper_command_is_accepted_or_refused(position, velocity, effort,
                                                               name):
    goal = NS(command=NS(name=name, position=position, velocity=velocity, effort=effort))
    if accepted_or_refused(accept_parallel_gripper_command, goal):
        assert all(math.isfinite(v) for v in position + velocity + effort)


@given(speed=floats, apply=st.booleans())
def test_every_self_check_message_is_accepted_or_refused(speed, apply):
    goal = NS(closing_speed=speed, apply=apply)

    def accept(goal, settings):
        return accept_self_check(goal, settings, LINKS, 0.002)

    if accepted_or_refused(accept, goal):
        assert math.isfinite(speed) and speed >= 0


@pytest.mark.parametrize("value", [math.nan, math.inf, -1.0, 1e300])
def test_a_malformed_grasp_force_is_refused_naming_the_value(value):
    with pytest.raises(ControlError, match="force"):
        accept_grasp(NS(target_force=value, closing_speed=0.0, timeout=0.0, hold_mode="",
                        hold_time=0.0), SETTINGS)
