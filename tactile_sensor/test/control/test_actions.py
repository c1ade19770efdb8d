"""Each action's meaning (control/actions.py): goal -> controller, step -> feedback/result,
success, and every rejected goal. Goals are plain namespaces shaped like the messages."""

from __future__ import annotations

import math
import re
from dataclasses import replace
from types import SimpleNamespace as NS

import pytest
from hypothesis import given
from hypothesis import strategies as st

from tactile_sensor.control.actions import (
    GoalSettings,
    MoveGoal,
    ParallelMoveGoal,
    Snapshot,
    accept_grasp,
    accept_gripper_command,
    accept_parallel_gripper_command,
    accept_release,
    settings_from_parameters,
)
from tactile_sensor.control.back_off import SATURATION_BAND
from tactile_sensor.control.errors import InvalidConfiguration, InvalidRequest
from tactile_sensor.control.geometry import GripperGeometry
from tactile_sensor.control.grasp import GraspConfig, Outcome, Phase, Step
from tactile_sensor.control.hold import fem_skin_stiffness_n_per_m
from tactile_sensor.control.slip_hold import HoldSettings

G = GripperGeometry()
SETTINGS = GoalSettings(GraspConfig(), joint_name="finger_opening")


def at(opening_m: float, moving: bool = True,
       hardware_error: frozenset[str] = frozenset()) -> NS:
    """A servo sample at this opening, as the controllers read it (ServoReading)."""
    return NS(position_rad=G.position_rad(opening_m), moving=moving,
              hardware_error=hardware_error)


def gripper_command(position: float, max_effort: float) -> NS:
    return NS(command=NS(position=position, max_effort=max_effort))


def parallel(position=(0.01,), velocity=(), effort=(), name=("finger_opening",)) -> NS:
    return NS(command=NS(name=list(name), position=list(position), velocity=list(velocity),
                         effort=list(effort)))


def finished(outcome: Outcome, opening: float = 0.02) -> Step:
    return Step(Phase.DONE, None, outcome, "why", opening)


@given(st.floats(0.002, 0.06), st.floats(0.0, SETTINGS.max_grasp_force_n))
def test_gripper_command_position_is_the_opening_and_effort_the_tactile_limit(pos, effort):
    goal = accept_gripper_command(gripper_command(pos, effort), SETTINGS)
    assert goal.request.opening_m == pos and goal.request.max_effort_n == effort
    step = goal.start(0.0, at(0.061 if pos < 0.06 else 0.03))
    assert step.command.goal_position_rad == pytest.approx(G.position_rad(pos))


@given(st.floats(0.002, 0.06), st.just(0.0) | st.floats(1e-4, 0.2),
       st.floats(0.0, SETTINGS.max_grasp_force_n))
def test_parallel_command_reads_the_joint_state_fields(pos, velocity, effort):
    goal = accept_parallel_gripper_command(parallel([pos], [velocity], [effort]), SETTINGS)
    request = goal.request
    assert request.opening_m == pos and request.max_effort_n == effort
    if velocity > 0:  # the joint's velocity is the opening's rate: twice a finger's speed
        assert request.closing_speed_m_s == pytest.approx(velocity / 2)
    else:
        assert request.closing_speed_m_s == SETTINGS.closing_speed_m_s
    without = accept_parallel_gripper_command(parallel([pos]), SETTINGS).request
    assert without.max_effort_n == 0.0
    assert without.opening_speed_m_s == SETTINGS.opening_speed_m_s


@pytest.mark.parametrize("goal, words", [
    (gripper_command(math.nan, 1.0), "not a number"),
    (gripper_command(0.01, math.nan), "not a number"),
    (gripper_command(0.01, -1.0), "negative"),
    (gripper_command(0.001, 1.0), r"outside the travel \[0.002, 0.06\]"),
    (gripper_command(0.07, 1.0), "outside the travel"),
])
def test_invalid_gripper_commands_are_rejected_with_one_sentence(goal, words):
    with pytest.raises(InvalidRequest, match=words):
        accept_gripper_command(goal, SETTINGS)


@pytest.mark.parametrize("goal, words", [
    (parallel(name=["gripper_joint"]), r"joint\(s\) \['gripper_joint'\].*'finger_opening'"),
    (parallel(name=[]), "'finger_opening'"),
    (parallel(name=["finger_opening", "other"]), "'finger_opening'"),
    (parallel(position=[]), "exactly one"),
    (parallel(position=[0.01, 0.02]), "exactly one"),
    (parallel(velocity=[0.01, 0.01]), "at most one"),
    (parallel(effort=[1.0, 1.0]), "at most one"),
    (parallel(position=[math.nan]), "not a number"),
    (parallel(position=[0.1]), "outside the travel"),
    (parallel(effort=[-2.0]), "negative"),
    (parallel(effort=[math.nan]), "not a number"),
    (parallel(velocity=[-0.01]), "positive number"),
    (parallel(velocity=[math.nan]), "positive number"),
    (parallel(velocity=[10.0]), "slower speed"),
])
def test_invalid_parallel_commands_are_rejected_with_one_sentence(goal, words):
    with pytest.raises(InvalidRequest, match=words):
        accept_parallel_gripper_command(goal, SETTINGS)


@pytest.mark.parametrize("goal, words", [
    (NS(target_force=math.nan, closing_speed=0.0, timeout=0.0), "positive"),
    (NS(target_force=-1.0, closing_speed=0.0, timeout=0.0), "positive"),
    (NS(target_force=2.0, closing_speed=-0.01, timeout=0.0), "speed"),
    (NS(target_force=2.0, closing_speed=math.nan, timeout=0.0), "speed"),
    (NS(target_force=2.0, closing_speed=0.0, timeout=-1.0), "timeout"),
])
def test_invalid_grasps_are_rejected_before_they_start(goal, words):
    with pytest.raises(InvalidRequest, match=words):
        accept_grasp(goal, SETTINGS)


@pytest.mark.parametrize("opening", [math.nan, 0.001, 0.07, -0.01])
def test_invalid_releases_are_rejected_before_they_start(opening):
    with pytest.raises(InvalidRequest, match="outside the travel"):
        accept_release(NS(opening=opening), SETTINGS)


FULL = SETTINGS.with_full_scale(6.77)  # the FEM curve's top, as the driver latches it


@pytest.mark.parametrize("settings, goal, accept", [
    (FULL, NS(target_force=1e9, closing_speed=0.0, timeout=0.0), accept_grasp),
    (FULL, NS(target_force=6.77, closing_speed=0.0, timeout=0.0), accept_grasp),
    (FULL, gripper_command(0.01, 7.0), accept_gripper_command),
    (FULL, parallel(effort=[1e9]), accept_parallel_gripper_command),
    (replace(FULL, max_grasp_force_n=3.0), NS(target_force=3.5, closing_speed=0.0,
                                              timeout=0.0), accept_grasp),
])
def test_a_force_beyond_the_ceiling_is_refused_naming_both_limits(settings, goal, accept):
    limit = settings.max_grasp_force_n
    with pytest.raises(InvalidRequest) as refusal:
        accept(goal, settings)
    sentence = str(refusal.value)
    assert "6.77 N full scale" in sentence and f"max_grasp_force {limit:g} N" in sentence
    assert sentence.count(". ") == 0 and sentence.endswith(" N.")


def test_up_to_the_ceiling_is_accepted_and_zero_effort_stays_position_only():
    saturates = (1 - SATURATION_BAND) * 6.77  # readings from here up may be saturated
    assert FULL.force_ceiling_n == pytest.approx(saturates)
    accept_grasp(NS(target_force=saturates, closing_speed=0.0, timeout=0.0), FULL)
    accept_gripper_command(gripper_command(0.01, 0.0), FULL)
    capped = replace(FULL, max_grasp_force_n=3.0)
    assert capped.force_ceiling_n == 3.0
    accept_grasp(NS(target_force=3.0, closing_speed=0.0, timeout=0.0), capped)
    with pytest.raises(InvalidRequest, match="request at most 3 N"):
        accept_gripper_command(gripper_command(0.01, 3.01), capped)
    with pytest.raises(InvalidRequest, match=re.escape(
            "Effort limit 6.1 N is above the gripper's force ceiling of 6.09 N (the smaller "
            "of max_grasp_force 10 N and 6.09 N, from where the tactile sensor's readings "
            "saturate below its 6.77 N full scale); request at most 6.09 N.")):
        accept_gripper_command(gripper_command(0.01, 6.1), FULL)


def test_until_the_driver_states_its_range_the_parameter_alone_applies():
    assert SETTINGS.full_scale_force_n is None
    accept_grasp(NS(target_force=9.0, closing_speed=0.0, timeout=0.0), SETTINGS)
    with pytest.raises(InvalidRequest, match=re.escape(
            "Grasp target force 1e+09 N is above max_grasp_force 10 N (the tactile sensor's "
            "full scale is not known yet); request at most 10 N.")):
        accept_grasp(NS(target_force=1e9, closing_speed=0.0, timeout=0.0), SETTINGS)


@pytest.mark.parametrize("value", [0.0, -1.0, math.nan, math.inf])
def test_a_full_scale_no_calibration_can_have_is_refused(value):
    with pytest.raises(InvalidRequest, match="not a positive number; check its calibration"):
        SETTINGS.with_full_scale(value)


def test_goals_with_a_force_target_back_off_to_it_position_only_moves_do_not():
    grasp = accept_grasp(NS(target_force=2.0, closing_speed=0.0, timeout=0.0), FULL)
    back_off = grasp.back_off(6.77)
    assert (back_off.target_force_n, back_off.full_scale_force_n) == (2.0, 6.77)
    assert back_off.speed_rad_s == G.finger_speed_to_rad_s(FULL.closing_speed_m_s)
    assert accept_gripper_command(gripper_command(0.01, 3.0), FULL).back_off(
        None).target_force_n == 3.0
    assert accept_gripper_command(gripper_command(0.01, 0.0), FULL).back_off(6.77) is None
    assert accept_release(NS(opening=0.05), FULL).back_off(6.77) is None


def test_zero_means_the_node_s_defaults_for_grasp_and_release():
    grasp = accept_grasp(NS(target_force=2.0, closing_speed=0.0, timeout=0.0), SETTINGS)
    assert grasp.request.speed_m_s == SETTINGS.closing_speed_m_s
    assert grasp.request.timeout_s == SETTINGS.timeout_s
    assert accept_release(NS(opening=0.0), SETTINGS).opening_m == G.open_opening_m


@pytest.mark.parametrize("outcome, allow, succeeded, stalled, reached", [
    (Outcome.REACHED, True, True, False, True),
    (Outcome.REACHED, False, True, False, True),
    (Outcome.FORCE_LIMIT, True, True, True, False),
    (Outcome.FORCE_LIMIT, False, False, True, False),
    (Outcome.STALLED, True, True, True, False),
    (Outcome.STALLED, False, False, True, False),
    (Outcome.TIMEOUT, True, False, False, False),
    (Outcome.HARDWARE_ERROR, True, False, False, False),
    (Outcome.CANCELED, True, False, False, False),
])
def test_move_results_follow_ros2_controllers(outcome, allow, succeeded, stalled, reached):
    settings = replace(SETTINGS, allow_stalling=allow)
    goal = accept_gripper_command(gripper_command(0.002, 2.0), settings)
    step = finished(outcome, 0.019)
    assert goal.succeeded(step) is succeeded
    assert (goal.failure(step) is None) is succeeded
    if outcome in (Outcome.FORCE_LIMIT, Outcome.STALLED) and not allow:
        assert "allow_stalling is false" in goal.failure(step)
    result = goal.result(Snapshot(step, 2.05, -0.001), "why")
    assert result == {"position": 0.019, "effort": 2.05, "stalled": stalled,
                      "reached_goal": reached}
    assert goal.feedback(Snapshot(step, 2.05, -0.001)) == result


def test_parallel_results_are_a_joint_state_of_our_joint():
    goal = accept_parallel_gripper_command(parallel(effort=[2.0]), SETTINGS)
    assert isinstance(goal, ParallelMoveGoal) and isinstance(goal, MoveGoal)
    snap = Snapshot(finished(Outcome.FORCE_LIMIT, 0.0195), 1.98, 0.0)
    state = {"name": ["finger_opening"], "position": [0.0195], "velocity": [0.0],
             "effort": [1.98]}
    assert goal.result(snap, "") == {"state": state, "stalled": True, "reached_goal": False}
    assert goal.feedback(snap) == {"state": state}  # the action's feedback has no flags


def test_a_force_limit_is_settled_onto_the_limit_other_outcomes_are_not():
    goal = accept_gripper_command(gripper_command(0.002, 3.0), SETTINGS)
    settler = goal.settler(finished(Outcome.FORCE_LIMIT))
    assert settler is not None and settler.target_force_n == 3.0
    # the hold moves on the FEM skin's tangent at its target, not the contact stop's value
    assert settler.skin_stiffness_n_per_m == fem_skin_stiffness_n_per_m(3.0)
    assert goal.settler(finished(Outcome.STALLED)) is None
    assert goal.settler(finished(Outcome.REACHED)) is None
    grasp = accept_grasp(NS(target_force=1.5, closing_speed=0.0, timeout=0.0), SETTINGS)
    assert grasp.settler(finished(Outcome.CONTACT)).target_force_n == 1.5
    assert grasp.settler(finished(Outcome.TIMEOUT)) is None


def test_grasp_and_release_results_keep_their_fields():
    grasp = accept_grasp(NS(target_force=2.0, closing_speed=0.0, timeout=0.0), SETTINGS)
    snap = Snapshot(finished(Outcome.CONTACT, 0.0195), 2.01, 0.0)
    assert grasp.result(snap, "contact: contact at 2.2 N, settled at 2.01 N") == {
        "contact_detected": True, "force": 2.01, "opening": 0.0195,
        "message": "contact: contact at 2.2 N, settled at 2.01 N", "friction": math.nan}
    assert grasp.feedback(snap) == {"force": 2.01, "opening": 0.0195,
                                    "slip_margin": math.nan}
    assert grasp.succeeded(snap.step) and grasp.failure(snap.step) is None
    release = accept_release(NS(opening=0.0), SETTINGS)
    snap = Snapshot(finished(Outcome.OPENED, 0.06), math.nan, 0.0)
    assert release.result(snap, "ok") == {"opening": 0.06, "success": True, "message": "ok"}
    timeout = finished(Outcome.TIMEOUT)
    assert release.failure(timeout) == "timeout: why"


def test_each_goal_runs_its_controller_start_tick_cancel():
    for goal in (accept_grasp(NS(target_force=2.0, closing_speed=0.0, timeout=0.0), SETTINGS),
                 accept_release(NS(opening=0.05), SETTINGS),
                 accept_gripper_command(gripper_command(0.002, 2.0), SETTINGS)):
        servo = at(0.03)
        step = goal.start(0.0, servo)
        assert step.command is not None and not step.finished
        assert not goal.tick(0.05, 0.0, 0.04, servo).finished
        assert goal.cancel(0.1, servo).outcome is Outcome.CANCELED


#: The gripper node's parameters as declared (nodes/gripper.py), at their defaults.
PARAMETERS = {
    "geometry.pitch_radius": 0.014, "geometry.open_opening": 0.060,
    "geometry.closed_opening": 0.002, "current_limit": 1.0, "closing_current": 0.6,
    "default_closing_speed": 0.01, "release_speed": 0.02, "default_timeout": 10.0,
    "tactile_timeout": 0.2, "skin_stiffness": 2500.0, "joint_name": "finger_opening",
    "goal_tolerance": 0.0005, "stall_timeout": 0.2, "allow_stalling": True,
    "max_grasp_force": 10.0, "hold_mode": "fixed", "hold_time": 0.0, "shear_sensing": False,
    "slip_bandwidth": 20.0, "control_rate": 100.0}


def test_settings_from_the_node_parameters():
    settings = settings_from_parameters({**PARAMETERS, "closing_current": 0.5,
                                         "geometry.open_opening": 0.05})
    config = settings.config
    assert config.closing_current_a == config.hold_current_a == 0.5
    assert config.geometry.open_opening_m == 0.05 and config.stale_after_s == 0.2
    assert settings == replace(SETTINGS, config=config)
    assert settings_from_parameters({**PARAMETERS, "max_grasp_force": 4.0}
                                    ).max_grasp_force_n == 4.0


def test_a_closing_current_above_the_limit_is_refused_naming_both():
    with pytest.raises(InvalidConfiguration, match=re.escape("'closing_current' = 1.5 A exceeds "
                       "'current_limit' = 1.0 A")):
        settings_from_parameters({**PARAMETERS, "closing_current": 1.5})


def test_a_travel_without_room_is_refused():
    with pytest.raises(ValueError, match="closed_opening_m"):
        settings_from_parameters({**PARAMETERS, "geometry.closed_opening": 0.06})


SHEAR = replace(SETTINGS, hold=HoldSettings(shear_sensing=True))


def test_an_adaptive_hold_without_shear_sensing_is_refused_in_one_sentence():
    goal = NS(target_force=2.0, closing_speed=0.0, timeout=0.0, hold_mode="adaptive",
              hold_time=0.0)
    with pytest.raises(InvalidRequest, match="needs a fingertip that feels shear"):
        accept_grasp(goal, SETTINGS)
    with pytest.raises(InvalidRequest, match="not one of fixed, adaptive"):
        accept_grasp(NS(**{**vars(goal), "hold_mode": "soft"}), SHEAR)
    with pytest.raises(InvalidConfiguration, match="'shear_sensing' is false"):
        settings_from_parameters({**PARAMETERS, "hold_mode": "adaptive"})


def test_an_adaptive_grasp_holds_with_the_slip_hold_and_backs_off_only_above_the_ceiling():
    goal = accept_grasp(NS(target_force=2.0, closing_speed=0.0, timeout=0.0,
                           hold_mode="adaptive", hold_time=3.0), SHEAR)
    assert goal.adaptive and goal.hold_time_s == 3.0
    hold = goal.slip_hold(1.9, at(0.02), 0.03)
    assert hold is not None and hold.grip_n == 1.9
    assert hold._closing_lead_rad == 0.03  # the settle's lead carries into the first raise
    assert goal.slip_hold(1.9, at(0.02))._closing_lead_rad == 0.0
    assert hold.config.ceiling_n == SHEAR.force_ceiling_n
    assert goal.back_off(None).target_force_n == SHEAR.force_ceiling_n
    fixed = accept_grasp(NS(target_force=2.0, closing_speed=0.0, timeout=0.0), SHEAR)
    assert fixed.slip_hold(1.9, at(0.02)) is None
    assert fixed.back_off(None).target_force_n == 2.0


def test_control_msgs_moves_take_the_node_s_hold_mode():
    adaptive = replace(SETTINGS, hold=HoldSettings("adaptive", 2.0, shear_sensing=True))
    move = accept_gripper_command(gripper_command(0.002, 2.0), adaptive)
    assert move.adaptive and move.hold_time_s == 2.0
    assert not accept_gripper_command(gripper_command(0.002, 0.0), adaptive).adaptive
    assert not accept_gripper_command(gripper_command(0.002, 2.0), SETTINGS).adaptive
