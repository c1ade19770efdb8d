"""Where a one-write stop puts the goal (control/stop.py): pure, fed synthetic samples."""

from __future__ import annotations

import math

import pytest
from hypothesis import given
from hypothesis import strategies as st

from tactile_sensor.control.errors import InvalidRequest
from tactile_sensor.control.stop import stop_position_rad
from tactile_sensor.sim.motor_model import MotorCommand, MotorModel

positions = st.floats(0.0, 2 * math.pi)
speeds = st.floats(-6.0, 6.0)
ages = st.floats(0.0, 0.03)


@given(positions, speeds, ages)
def test_carries_the_sample_forward_at_its_velocity(p, v, age):
    assert stop_position_rad(p, v, age, max_age_s=0.03) == pytest.approx(p + v * age)


@given(positions, st.floats(0.1, 6.0), ages, st.floats(0.0, 0.2))
def test_never_past_the_goal_the_servo_was_heading_for(p, speed, age, ahead):
    for sign in (1.0, -1.0):
        goal = p + sign * ahead
        stop = stop_position_rad(p, sign * speed, age, 0.03, heading_to_rad=goal)
        assert min(p, goal) - 1e-12 <= stop <= max(p, goal) + 1e-12


def test_a_stale_sample_is_not_trusted():
    assert stop_position_rad(1.0, 0.7, 0.031, max_age_s=0.03) is None


def test_a_negative_age_is_treated_as_a_fresh_sample():
    assert stop_position_rad(1.0, 0.7, -0.002, max_age_s=0.03) == 1.0


@pytest.mark.parametrize("args", [
    (math.nan, 0.0, 0.0, 0.03), (1.0, math.inf, 0.0, 0.03), (1.0, 0.0, math.nan, 0.03),
    (1.0, 0.0, 0.0, math.nan)])
def test_non_finite_samples_are_rejected(args):
    with pytest.raises(InvalidRequest, match="not finite"):
        stop_position_rad(*args)


def test_a_negative_max_age_is_rejected():
    with pytest.raises(InvalidRequest, match="negative"):
        stop_position_rad(1.0, 0.0, 0.0, max_age_s=-1.0)


@given(st.floats(0.2, 1.5), st.floats(0.0, 0.03))
def test_the_one_write_stop_halts_a_closing_servo_within_a_pulse(speed, age):
    """On the motor model: close at ``speed``, sample, let ``age`` pass, write the stop with
    the servo's rectangular profile (Profile Acceleration 0): the output stays within one
    encoder pulse of where it was when the stop arrived, and does not move again."""
    pulse = 2 * math.pi / 4096
    motor = MotorModel(math.pi)
    closing = MotorCommand(True, math.pi + 1.0, speed, 0.0, 1.0)
    motor.step(0.2, closing)
    sample = (motor.state.position_rad, motor.state.velocity_rad_s)
    motor.step(age, closing)
    at_arrival = motor.state.position_rad
    goal = stop_position_rad(*sample, age, 0.03, heading_to_rad=math.pi + 1.0)
    stop = MotorCommand(True, goal, 6.0, 0.0, 1.0)
    motor.step(0.001, stop)
    assert abs(motor.state.position_rad - at_arrival) <= pulse
    motor.step(0.2, stop)
    assert abs(motor.state.position_rad - at_arrival) <= pulse
    assert motor.state.velocity_rad_s == 0.0
